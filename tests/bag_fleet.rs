//! rosbag2 record and replay against the running fleet, checked by independent tools:
//!
//! - `biped record` of the walking fleet (MCAP with `--all`, stopped by Ctrl-C; sqlite3 with
//!   `--topics`, stopped by `--duration`): each bag is read by `rosbags` (Jazzy typestore)
//!   and by `mcap` + `mcap-ros2-support` or rclpy (tests/python/bag_check.py --strict):
//!   every message decodes; counts, topics, types, time range and QoS agree with
//!   metadata.yaml; the RIHS01 hashes equal rosbags' and rosidl's.
//! - `biped replay` of bags written by `rosbags` (standing in for `ros2 bag record`), MCAP
//!   and sqlite3, with /cmd_vel and /joint_commands, into gait_planner + joint_bridge: the
//!   planner walks, the bridge moves the joint, and every message arrives, in order, at its
//!   recorded offset up to the replay's own reported lateness + 50 ms (Fast DDS's reception
//!   stamps, on loopback; the millisecond figures are benchmarks/bag_replay's).
//!
//! Each scenario runs in a private network namespace (tests/python/bag_peer.py).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{bin_dir, json_of, python, python_in_netns, root};
use serde_json::{Value, json};

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("biped-bag-fleet-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Runs a bag_peer.py scenario in a new network namespace; returns its JSON.
fn peer(scenario: &str, path: &Path, domain_id: u32) -> Value {
    json_of(
        python_in_netns("bag_peer.py", domain_id)
            .arg(scenario)
            .arg(bin_dir())
            .arg(path),
        &format!("bag_peer {scenario}"),
    )
}

/// bag_check.py --strict on a bag: its JSON summary (the test fails on any failure).
fn check(bag: &Path) -> Value {
    let out = Command::new(python())
        .arg(root().join("tests/python/bag_check.py"))
        .arg(bag)
        .arg("--strict")
        .output()
        .unwrap();
    let v: Value = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "bag_check output is not JSON ({e}): {}",
            String::from_utf8_lossy(&out.stderr)
        )
    });
    assert!(
        out.status.success() && v["ok"] == true,
        "{}: {:#}",
        bag.display(),
        v["failures"]
    );
    v
}

fn topic<'a>(summary: &'a Value, name: &str) -> &'a Value {
    let t = &summary["topics"][name];
    assert!(t.is_object(), "no {name} in {:#}", summary["topics"]);
    t
}

#[test]
fn a_recorded_fleet_bag_is_read_by_two_independent_readers() {
    let dir = scratch("record");
    let v = peer("record", &dir, 72);
    assert_eq!(v["flow"], true, "the fleet never flowed: {v:#}");
    assert_eq!(
        v["walked"], true,
        "the fleet did not walk while recorded: {v:#}"
    );
    let all = &v["record_all"];
    assert_eq!(
        all["returncode"], 0,
        "biped record (Ctrl-C) failed: {all:#}"
    );
    assert!(
        all["stdout"].as_str().unwrap().contains("recorded "),
        "{all:#}"
    );
    let sql = &v["record_sqlite"];
    assert_eq!(
        sql["ended_by_duration"], true,
        "biped record --duration did not end by itself: {sql:#}"
    );

    // MCAP, every topic, cut by Ctrl-C.
    let mcap = check(Path::new(v["bags"]["mcap"].as_str().unwrap()));
    assert_eq!(mcap["storage"], "mcap");
    assert_eq!(mcap["readers"], json!(["rosbags", "mcap"]));
    for (name, ty) in [
        ("/joint_commands", "sensor_msgs/msg/JointState"),
        ("/joint_states", "sensor_msgs/msg/JointState"),
        ("/gait/phase", "biped_msgs/msg/GaitPhase"),
        ("/gait/ankle_targets", "biped_msgs/msg/AnkleTargets"),
        ("/walk_command", "biped_msgs/msg/WalkCommand"),
        ("/cmd_vel", "geometry_msgs/msg/Twist"),
    ] {
        let t = topic(&mcap, name);
        assert_eq!(t["type"], ty, "{name}");
        assert!(
            t["hash"].as_str().unwrap().starts_with("RIHS01_"),
            "{name}: {t}"
        );
    }
    // The fleet publishes at 100 Hz; a walk of one step takes well over 5 s.
    for name in ["/joint_commands", "/gait/phase", "/joint_states"] {
        let n = topic(&mcap, name)["count"].as_u64().unwrap();
        assert!(n > 500, "{name}: only {n} messages");
    }
    assert_eq!(topic(&mcap, "/walk_command")["count"], 1);
    // Types outside our own table, described from the installed .msg files (the checker
    // compared their hashes with rosbags' and rosidl's, and both readers decoded them): the
    // peer's IMU at 20 Hz and the nodes' parameter events.
    assert_eq!(topic(&mcap, "/imu")["type"], "sensor_msgs/msg/Imu");
    assert!(topic(&mcap, "/imu")["count"].as_u64().unwrap() > 20);
    assert_eq!(
        topic(&mcap, "/parameter_events")["type"],
        "rcl_interfaces/msg/ParameterEvent"
    );
    // Replayed from the bag alone, the IMU messages arrive intact, in order.
    let replay = &v["imu_replay"];
    assert_eq!(replay["returncode"], 0, "{replay:#}");
    let got = v["imu_replayed"].as_array().unwrap();
    assert_eq!(
        got.len() as u64,
        topic(&mcap, "/imu")["count"].as_u64().unwrap(),
        "{replay:#}"
    );
    for w in got.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        assert_eq!(b["sec"].as_i64().unwrap(), a["sec"].as_i64().unwrap() + 1);
        let az = 9.81 + 0.001 * b["sec"].as_f64().unwrap();
        assert!((b["az"].as_f64().unwrap() - az).abs() < 1e-12, "{b}");
        assert_eq!(b["frame"], "imu_link");
        assert_eq!(b["cov0"], -1.0);
    }
    // The QoS the fleet's publishers offer: reliable, volatile.
    let q = &topic(&mcap, "/joint_commands")["qos"][0];
    assert_eq!(q["reliability"], "reliable", "{q}");
    assert_eq!(q["durability"], "volatile", "{q}");

    // sqlite3, chosen topics, ended by --duration.
    let db = check(Path::new(v["bags"]["sqlite3"].as_str().unwrap()));
    assert_eq!(db["storage"], "sqlite3");
    assert_eq!(db["readers"], json!(["rosbags", "rclpy"]));
    let names: Vec<_> = db["topics"].as_object().unwrap().keys().cloned().collect();
    assert_eq!(
        names,
        [
            "/cmd_vel",
            "/gait/phase",
            "/joint_commands",
            "/walk_command"
        ]
    );
    // 12 s at 100 Hz, less discovery: how much discovery takes depends on the machine's
    // load (seconds when busy), so the floor only catches a recorder that stopped early; the
    // ceiling catches duplicates.
    let n = topic(&db, "/joint_commands")["count"].as_u64().unwrap();
    assert!(
        (300..=1250).contains(&n),
        "12 s at 100 Hz, less discovery: {n}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

const T0_NS: i64 = 1_700_000_000_000_000_000;
const LEG_JOINTS: [&str; 10] = [
    "l_hip_roll",
    "l_hip_pitch",
    "l_knee",
    "l_ankle_pitch",
    "l_ankle_roll",
    "r_hip_roll",
    "r_hip_pitch",
    "r_knee",
    "r_ankle_pitch",
    "r_ankle_roll",
];
/// The left knee goes from 0 to this over the bag (0.075 rad/s: within every limit).
const KNEE_END_RAD: f64 = 0.3;

/// A rosbags-written bag: /joint_commands every 20 ms for 4 s (the left knee ramping),
/// /cmd_vel "walk at 2 cm/s" at 0.5 s and "stop" at 3.5 s.
fn make_bag(dir: &Path, storage: &str) -> PathBuf {
    let qos = json!({"reliability": "reliable", "durability": "volatile", "history": "keep_last", "depth": 10});
    let mut messages = Vec::new();
    for i in 0..=200 {
        let t = T0_NS + i * 20_000_000;
        let mut position = vec![0.0; LEG_JOINTS.len()];
        position[2] = KNEE_END_RAD * i as f64 / 200.0;
        messages.push(json!({"topic": "/joint_commands", "t_ns": t, "msg": {
            "header": {"stamp": {"sec": t / 1_000_000_000, "nanosec": t % 1_000_000_000}, "frame_id": "bag"},
            "name": LEG_JOINTS, "position": position}}));
    }
    for (t, x) in [(500_000_000, 0.02), (3_500_000_000, 0.0)] {
        messages.push(json!({"topic": "/cmd_vel", "t_ns": T0_NS + t, "msg": {"linear": {"x": x}}}));
    }
    messages.sort_by_key(|m| m["t_ns"].as_i64().unwrap());
    let spec = json!({
        "topics": [
            {"name": "/joint_commands", "type": "sensor_msgs/msg/JointState", "qos": qos},
            {"name": "/cmd_vel", "type": "geometry_msgs/msg/Twist", "qos": qos},
        ],
        "messages": messages,
    });
    let spec_path = dir.join(format!("spec_{storage}.json"));
    std::fs::write(&spec_path, spec.to_string()).unwrap();
    let bag = dir.join(format!("rosbags_{storage}"));
    let out = Command::new(python())
        .arg(root().join("tests/python/bag_make.py"))
        .arg(&bag)
        .args(["--storage", storage, "--spec"])
        .arg(&spec_path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "bag_make: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    bag
}

/// How far each message arrived from its recorded time, after the one constant shift
/// between the two clocks (the median of arrival − recorded): the worst, in ms.
fn worst_timing_error_ms(recorded_ns: &[i64], arrived_ns: &[i64]) -> f64 {
    assert_eq!(recorded_ns.len(), arrived_ns.len());
    let mut d: Vec<i64> = arrived_ns
        .iter()
        .zip(recorded_ns)
        .map(|(a, r)| a - r)
        .collect();
    d.sort_unstable();
    let shift = d[d.len() / 2];
    d.iter()
        .map(|x| ((x - shift) as f64 * 1e-6).abs())
        .fold(0.0, f64::max)
}

/// What loopback delivery may add to the replay's own lateness before a test calls it a
/// defect (ms): generous for a busy 2-core machine, tiny against a recorded spacing error.
const DELIVERY_ALLOWANCE_MS: f64 = 50.0;

/// The "at most X ms late" of `biped replay`'s summary line.
fn replay_own_lateness_ms(stdout: &str) -> Option<f64> {
    let line = stdout.lines().find(|l| l.starts_with("replayed "))?;
    let before = line.strip_suffix(" ms late")?;
    let value = before.rsplit(' ').next()?.parse::<f64>().ok()?;
    value.is_finite().then_some(value)
}

fn replay_into_the_fleet(storage: &str, domain_id: u32) {
    let dir = scratch(&format!("replay-{storage}"));
    let bag = make_bag(&dir, storage);
    let v = peer("replay", &bag, domain_id);
    assert_eq!(v["states_flowing"], true, "{v:#}");
    let r = &v["replay"];
    assert_eq!(r["returncode"], 0, "biped replay failed: {r:#}");
    assert!(
        r["stdout"]
            .as_str()
            .unwrap()
            .contains("replayed 203 messages"),
        "{r:#}"
    );

    // Every message arrived, in order, with its recorded spacing.
    let cmds = v["arrivals"]["/joint_commands"].as_array().unwrap();
    let stamps: Vec<i64> = cmds.iter().map(|c| c["stamp"].as_i64().unwrap()).collect();
    let recorded: Vec<i64> = (0..=200).map(|i| T0_NS + i * 20_000_000).collect();
    assert_eq!(
        stamps, recorded,
        "joint commands lost, repeated or reordered"
    );
    let vel = v["arrivals"]["/cmd_vel"].as_array().unwrap();
    assert_eq!(
        vel.iter()
            .map(|c| c["x"].as_f64().unwrap())
            .collect::<Vec<_>>(),
        [0.02, 0.0]
    );
    let mut all: Vec<(i64, i64)> = cmds
        .iter()
        .zip(&recorded)
        .map(|(c, r)| (*r, c["recv_ns"].as_i64().unwrap()))
        .collect();
    all.push((T0_NS + 500_000_000, vel[0]["recv_ns"].as_i64().unwrap()));
    all.push((T0_NS + 3_500_000_000, vel[1]["recv_ns"].as_i64().unwrap()));
    all.sort();
    let (rec, arr): (Vec<i64>, Vec<i64>) = all.into_iter().unzip();
    // The timing: each message arrives at its recorded offset, up to what the replay itself
    // reports as its lateness (a stall of this shared machine delays the replay's sleep and
    // the replay says so) plus a delivery allowance no working loopback needs. A replay that
    // ignores the recorded spacing (all at once, the wrong rate, early sends) is seconds off.
    // The millisecond accuracy is a benchmark figure: benches/bag_replay.rs, BENCHMARKS.md.
    let stdout = r["stdout"].as_str().unwrap();
    let own_late_ms = replay_own_lateness_ms(stdout)
        .unwrap_or_else(|| panic!("the replay's summary gives no lateness: {stdout}"));
    let worst = worst_timing_error_ms(&rec, &arr);
    eprintln!(
        "{storage}: worst arrival {worst:.2} ms off the recorded time; the replay's own account: at most {own_late_ms:.1} ms late"
    );
    assert!(
        worst < own_late_ms + DELIVERY_ALLOWANCE_MS,
        "a replayed message was {worst:.2} ms off its recorded time, more than the replay's own \
         lateness ({own_late_ms:.1} ms) + {DELIVERY_ALLOWANCE_MS} ms: {}",
        stdout.lines().next().unwrap_or_default()
    );

    // The fleet acted: the planner walked on /cmd_vel, the bridge followed the knee.
    let phases = v["phases"].as_array().unwrap();
    assert!(
        phases.iter().any(|p| p != "idle"),
        "the planner never left idle: {phases:?}"
    );
    let last = &v["states_after"][0];
    let names: Vec<&str> = last["name"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_str().unwrap())
        .collect();
    let knee = names
        .iter()
        .position(|n| *n == "l_knee")
        .expect("l_knee in joint_states");
    let got = last["position"][knee].as_f64().unwrap();
    assert!(
        (got - KNEE_END_RAD).abs() < 1e-3,
        "l_knee ended at {got} rad, commanded {KNEE_END_RAD}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_rosbags_mcap_bag_replays_into_the_fleet_with_its_timing() {
    replay_into_the_fleet("mcap", 73);
}

#[test]
fn a_rosbags_sqlite3_bag_replays_into_the_fleet_with_its_timing() {
    replay_into_the_fleet("sqlite3", 74);
}

/// Every topic a simulated walk publishes (TF, markers, odometry, the URDF, the simulator's
/// ground truth, ...), recorded by `biped walk --bag`, then replayed by `biped replay` into
/// an rclpy node subscribed to each with its type: every message that arrives decodes in
/// rclpy and equals one the bag holds (decoded by rclpy from the bag as rosbags reads it),
/// the latched topics (`robot_description`, `/tf_static`) arrive once to a subscriber that
/// was there before the replay, and all but a few of the rest arrive.
#[test]
fn a_walks_bag_of_every_fleet_topic_replays_into_rclpy_with_each_type_intact() {
    let dir = scratch("replay-all");
    common::biped_walk_ok(
        82,
        &dir.join("out"),
        &["--steps", "1", "--bag", dir.join("bag").to_str().unwrap()],
    );
    let v = peer("replay_all", &dir.join("bag"), 83);
    assert_eq!(v["replay"]["returncode"], 0, "{:#}", v["replay"]);
    assert!(
        v["undecodable"].as_array().unwrap().is_empty(),
        "{:#}",
        v["undecodable"]
    );
    let topics = v["topics"].as_object().unwrap();
    let mut types = std::collections::BTreeSet::new();
    for (name, t) in topics {
        let recorded: Vec<&str> = t["recorded"]
            .as_array()
            .unwrap()
            .iter()
            .map(|m| m.as_str().unwrap())
            .collect();
        let received: Vec<&str> = t["received"]
            .as_array()
            .unwrap()
            .iter()
            .map(|m| m.as_str().unwrap())
            .collect();
        if recorded.is_empty() {
            continue;
        }
        types.insert(t["type"].as_str().unwrap().to_owned());
        // Each message received is one recorded (as many times as it was recorded).
        let mut left: std::collections::HashMap<&str, usize> = std::collections::HashMap::new();
        for m in &recorded {
            *left.entry(m).or_default() += 1;
        }
        for m in &received {
            let n = left
                .get_mut(m)
                .unwrap_or_else(|| panic!("{name}: received a message the bag does not hold: {m}"));
            assert!(*n > 0, "{name}: received more copies of {m} than recorded");
            *n -= 1;
        }
        if t["latched"] == true {
            assert_eq!(received.len(), recorded.len(), "{name}: latched");
        } else {
            assert!(
                received.len() * 100 >= recorded.len() * 95,
                "{name}: {} of {} messages arrived",
                received.len(),
                recorded.len()
            );
        }
    }
    for ty in [
        "tf2_msgs/msg/TFMessage",
        "visualization_msgs/msg/MarkerArray",
        "nav_msgs/msg/Odometry",
        "std_msgs/msg/String",
        "sensor_msgs/msg/JointState",
        "sensor_msgs/msg/Imu",
        "geometry_msgs/msg/PolygonStamped",
        "rcl_interfaces/msg/Log",
        "biped_msgs/msg/GaitPhase",
    ] {
        assert!(types.contains(ty), "no {ty} replayed: {types:?}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_timing_measure_sees_a_late_message() {
    // The measure itself: a message 6 ms late is seen as 6 ms off.
    assert_eq!(
        worst_timing_error_ms(&[0, 10_000_000, 20_000_000], &[5, 10_000_005, 20_000_005]),
        0.0
    );
    let e = worst_timing_error_ms(&[0, 10_000_000, 20_000_000], &[0, 10_000_000, 26_000_000]);
    assert!((e - 6.0).abs() < 1e-9, "{e}");
}

#[test]
fn the_replays_own_lateness_is_read_from_its_summary() {
    let out = "replayed 203 messages from /tmp/b in 4.2 s (1 pass), 0 skipped, at most 12.5 ms late\n  /cmd_vel: 2\n";
    assert_eq!(replay_own_lateness_ms(out), Some(12.5));
    assert_eq!(
        replay_own_lateness_ms("replayed 3 messages, at most NaN ms late"),
        None
    );
    assert_eq!(replay_own_lateness_ms("  /cmd_vel: 2"), None);
}
