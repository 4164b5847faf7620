//! Serial wire benchmark: bytes and time on the wire per control cycle for the default
//! robot's ten leg joints (config/calibration_<protocol>.yaml), and the highest control rate
//! each protocol sustains.
//!
//! For each protocol the joint bridge's serial backend drives the test board emulator
//! (tests/support) over a pseudo-terminal for `CYCLES` control cycles (goal positions out,
//! and for Dynamixel the positions read back), counting the bytes both ways. From the
//! bytes per cycle: the time on a real wire at common baud rates (8N1: 10 bits per byte,
//! no servo return delay) and the control rate that wire allows; from the clock: the cycle
//! rate the software reaches over the pty, until the emulator has every goal packet (a pty
//! has no baud rate, so this is the ceiling of our code and the emulator, not of a wire).
//!
//! Run: `cargo bench -p joint_bridge --bench serial_wire`
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

#[path = "../tests/support/mod.rs"]
mod support;

use std::path::Path;
use std::time::Instant;

use joint_bridge::serial::{Calibration, Protocol, SerialBackend, SerialConfig};
use joint_bridge::{Backend, JointSpec};

const CYCLES: usize = 3000;

fn main() {
    // `cargo bench` passes --bench; nothing to parse.
    let model = ik_solver::BipedModel::from_urdf_str(ik_solver::DEFAULT_URDF, None).unwrap();
    println!(
        "| protocol | bytes out / cycle | bytes in / cycle | wire time per cycle at 57.6k / 115.2k / 1M / 3M baud (ms) | wire-limited rate at those bauds (Hz) | measured over the pty (cycles/s, median of 3) |"
    );
    println!("|---|---|---|---|---|---|");
    for p in Protocol::ALL {
        let path = format!(
            "{}/../config/calibration_{p}.yaml",
            env!("CARGO_MANIFEST_DIR")
        );
        let cal = Calibration::from_file(Path::new(&path)).unwrap();
        let joints: Vec<JointSpec> = JointSpec::from_robot(model.robot())
            .into_iter()
            .filter(|j| cal.joints.contains_key(&j.name))
            .collect();
        let dir = support::temp_dir(&format!("bench-{p}"));
        let dev = dir.join("ttyBENCH");
        let servos: Vec<(u8, f64)> = cal.joints.values().map(|j| (j.id, j.zero)).collect();
        let board = support::Board::new(p, &dev, &servos);
        let mut rates = Vec::new();
        let mut per_cycle = (0.0, 0.0);
        for _ in 0..3 {
            let mut b = SerialBackend::new(SerialConfig {
                port: dev.display().to_string(),
                baud: 1_000_000,
                calibration: cal.clone(),
                reply_timeout_s: 0.1,
            });
            b.configure(&joints).unwrap();
            b.activate().unwrap();
            let before = b.counters();
            let goals_before = board.with(|s| s.goals.len());
            let start = Instant::now();
            for k in 0..CYCLES {
                // A slow sine on every joint, within the limits.
                let t = k as f64 * 0.01;
                let q: Vec<f64> = joints
                    .iter()
                    .map(|j| {
                        let mid = 0.5 * (j.lower_rad + j.upper_rad);
                        mid + 0.2 * (t + mid).sin()
                    })
                    .collect();
                b.write(t, &q).unwrap();
                b.read(t).unwrap();
            }
            // Boards without replies: the cycle is done when the board has it, not when it
            // is in the pty's buffer.
            assert!(board.wait_until(|s| s.goals.len() >= goals_before + CYCLES));
            let elapsed = start.elapsed().as_secs_f64();
            let after = b.counters();
            assert_eq!(
                after.timeouts, before.timeouts,
                "{p}: timeouts in the bench"
            );
            per_cycle = (
                (after.bytes_sent - before.bytes_sent) as f64 / CYCLES as f64,
                (after.bytes_received - before.bytes_received) as f64 / CYCLES as f64,
            );
            rates.push(CYCLES as f64 / elapsed);
            b.deactivate().unwrap();
        }
        drop(board);
        rates.sort_by(f64::total_cmp);
        let bytes = per_cycle.0 + per_cycle.1;
        let bauds = [57_600.0, 115_200.0, 1_000_000.0, 3_000_000.0];
        let times: Vec<String> = bauds
            .iter()
            .map(|b| format!("{:.2}", bytes * 10.0 / b * 1e3))
            .collect();
        let wire_rates: Vec<String> = bauds
            .iter()
            .map(|b| format!("{:.0}", b / (bytes * 10.0)))
            .collect();
        println!(
            "| {p} | {:.1} | {:.1} | {} | {} | {:.0} |",
            per_cycle.0,
            per_cycle.1,
            times.join(" / "),
            wire_rates.join(" / "),
            rates[1]
        );
    }
}
