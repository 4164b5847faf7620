//! Our Dynamixel packets against an independent implementation: ROBOTIS' own Python SDK
//! (PyPI `dynamixel-sdk`, pinned in scripts/setup-python-env), through
//! tests/python/dynamixel_check.py.
//!
//! - Every instruction packet we write (ping, read, write, sync write of goal positions and
//!   of torque enable, sync read; Protocol 1.0 and 2.0) is byte for byte the packet the SDK's
//!   own methods (`ping`, `readTx`, `writeTxOnly`, `GroupSyncWrite`, `GroupSyncRead`) write.
//! - Every status packet we build is accepted by the SDK's `rxPacket` with the same id,
//!   error and parameters; every status packet the SDK builds (its `addStuffing` and
//!   `txPacket`: CRC or checksum) is parsed by ours to the same fields. The cases include
//!   parameters that need byte stuffing, and 200 random ones from a fixed seed.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use joint_bridge::serial::{Decoded, dynamixel1 as d1, dynamixel2 as d2};
use serde_json::{Value as Json, json};

const WORKSPACE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/..");

fn python() -> PathBuf {
    match std::env::var_os("BIPED_PYTHON") {
        Some(p) => PathBuf::from(p),
        None => {
            let p = Path::new(WORKSPACE).join(".venv/bin/biped-python");
            assert!(
                p.exists(),
                "{} does not exist: run scripts/setup-python-env (it installs dynamixel-sdk), or set BIPED_PYTHON",
                p.display()
            );
            p
        }
    }
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

fn unhex(s: &str) -> Vec<u8> {
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
        .collect()
}

fn sdk(cases: &[Json]) -> Vec<Json> {
    let mut child = Command::new(python())
        .arg(Path::new(WORKSPACE).join("tests/python/dynamixel_check.py"))
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(serde_json::to_string(cases).unwrap().as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "dynamixel_check.py failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Vec<Json> = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v.len(), cases.len());
    v
}

/// A small deterministic generator (xorshift), so the random cases are the same every run.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn byte(&mut self) -> u8 {
        (self.next() >> 24) as u8
    }
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
}

#[test]
fn instruction_packets_equal_the_sdks() {
    let mut cases = Vec::new();
    let mut ours = Vec::new();
    let mut rng = Rng(0x5eed_1234_abcd_0001);
    for id in [0u8, 1, 7, 200, 252] {
        ours.push(d2::ping(id));
        cases.push(json!({"proto": 2, "op": "ping", "args": {"id": id}}));
        ours.push(d2::read(id, 132, 4));
        cases.push(
            json!({"proto": 2, "op": "read", "args": {"id": id, "address": 132, "length": 4}}),
        );
        ours.push(d2::write(id, 64, &[1]));
        cases.push(
            json!({"proto": 2, "op": "write", "args": {"id": id, "address": 64, "data": [1]}}),
        );
    }
    for id in [0u8, 1, 18, 253] {
        ours.push(d1::ping(id));
        cases.push(json!({"proto": 1, "op": "ping", "args": {"id": id}}));
        ours.push(d1::read(id, 36, 2));
        cases.push(
            json!({"proto": 1, "op": "read", "args": {"id": id, "address": 36, "length": 2}}),
        );
        ours.push(d1::write(id, 30, &[0x00, 0x02]));
        cases.push(
            json!({"proto": 1, "op": "write", "args": {"id": id, "address": 30, "data": [0, 2]}}),
        );
    }
    for _ in 0..50 {
        // A robot's worth of servos at random goal positions (no FF FF FD in them: see the
        // module doc of dynamixel_check.py on the SDK's stuffing).
        let n = 1 + rng.below(20) as usize;
        let ids: Vec<u8> = (0..n).map(|k| (k as u8) * 3 + 1).collect();
        let goals: Vec<(u8, i32)> = ids.iter().map(|&id| (id, rng.below(4096) as i32)).collect();
        ours.push(d2::sync_write_goal_positions(&goals));
        let values: Vec<Json> = goals
            .iter()
            .map(|&(id, g)| json!([id, g.to_le_bytes()]))
            .collect();
        cases.push(json!({"proto": 2, "op": "sync_write", "args": {"address": 116, "length": 4, "values": values}}));
        ours.push(d2::sync_read(132, 4, &ids));
        cases.push(json!({"proto": 2, "op": "sync_read", "args": {"address": 132, "length": 4, "ids": ids}}));
        let goals1: Vec<(u8, u16)> = ids.iter().map(|&id| (id, rng.below(1024) as u16)).collect();
        ours.push(d1::sync_write_goal_positions(&goals1));
        let values: Vec<Json> = goals1
            .iter()
            .map(|&(id, g)| json!([id, g.to_le_bytes()]))
            .collect();
        cases.push(json!({"proto": 1, "op": "sync_write", "args": {"address": 30, "length": 2, "values": values}}));
        let on = rng.below(2) == 1;
        ours.push(d2::sync_write_torque(&ids, on));
        let values: Vec<Json> = ids.iter().map(|&id| json!([id, [u8::from(on)]])).collect();
        cases.push(json!({"proto": 2, "op": "sync_write", "args": {"address": 64, "length": 1, "values": values}}));
        ours.push(d1::sync_write_torque(&ids, on));
        cases.push(json!({"proto": 1, "op": "sync_write", "args": {"address": 24, "length": 1, "values": values}}));
    }
    for (c, o) in cases.iter_mut().zip(&ours) {
        c["ours"] = json!(hex(o));
    }
    let answers = sdk(&cases);
    for ((c, a), o) in cases.iter().zip(&answers).zip(&ours) {
        assert_eq!(a["sdk"].as_str().unwrap(), hex(o), "case {c}");
    }
}

#[test]
fn status_packets_are_understood_both_ways() {
    let mut rng = Rng(0x5eed_1234_abcd_0002);
    let mut statuses: Vec<(u8, u8, u8, Vec<u8>)> = vec![
        // Byte stuffing: FF FF FD inside the parameters, at the start, the end, twice.
        (2, 1, 0, vec![0xFF, 0xFF, 0xFD, 0x00]),
        (2, 3, 0, vec![0x00, 0xFF, 0xFF, 0xFD]),
        (2, 4, 0x80, vec![0xFF, 0xFF, 0xFD, 0xFF, 0xFF, 0xFD, 0x12]),
        (2, 5, 0, vec![]),
        (1, 5, 0x24, vec![]),
        (1, 1, 0, vec![0xFF, 0xFF, 0x00]),
    ];
    for _ in 0..200 {
        let proto = 1 + rng.below(2) as u8;
        let id = rng.below(if proto == 2 { 253 } else { 254 }) as u8;
        // The SDK's parser refuses error bytes with bit 7 in 1.0 (bit 7 is unused there).
        let error = if proto == 2 {
            rng.byte()
        } else {
            rng.byte() & 0x7F
        };
        let n = rng.below(12) as usize;
        let params = (0..n)
            .map(|_| match rng.below(4) {
                0 => 0xFF,
                1 => 0xFD,
                _ => rng.byte(),
            })
            .collect();
        statuses.push((proto, id, error, params));
    }
    let cases: Vec<Json> = statuses
        .iter()
        .map(|(proto, id, error, params)| {
            let ours = if *proto == 2 {
                d2::status_packet(*id, *error, params)
            } else {
                d1::status_packet(*id, *error, params)
            };
            json!({"proto": proto, "op": "status", "args": {"id": id, "error": error, "params": params}, "ours": hex(&ours)})
        })
        .collect();
    let answers = sdk(&cases);
    for ((proto, id, error, params), a) in statuses.iter().zip(&answers) {
        // The SDK accepts ours.
        let parsed = &a["parsed"];
        assert_eq!(parsed["result"], json!(0), "SDK refused our status {a}");
        assert_eq!(parsed["id"], json!(id), "{a}");
        assert_eq!(parsed["error"], json!(error), "{a}");
        assert_eq!(parsed["params"], json!(params), "{a}");
        // Ours parses the SDK's.
        let theirs = unhex(a["sdk"].as_str().unwrap());
        if *proto == 2 {
            let Decoded::Packet { value, used } = d2::decode_status(&theirs) else {
                panic!("ours refused the SDK's status {a}")
            };
            assert_eq!(
                (value.id, value.error, &value.params, used),
                (*id, *error, params, theirs.len())
            );
            // And both build the same bytes.
            assert_eq!(theirs, d2::status_packet(*id, *error, params));
        } else {
            let Decoded::Packet { value, used } = d1::decode_status(&theirs) else {
                panic!("ours refused the SDK's status {a}")
            };
            assert_eq!(
                (value.id, value.code, &value.params, used),
                (*id, *error, params, theirs.len())
            );
            assert_eq!(theirs, d1::status_packet(*id, *error, params));
        }
    }
}
