//! Cold starts against a real ROS 2 Jazzy peer (rclpy with Fast DDS), on a busy machine:
//! the fleet's nodes, an rclpy observer and a `ros2 topic pub --once -w 1 /cmd_vel`
//! stand-in all start at the same instant (tests/python/cold_start_peer.py), each start in a
//! fresh private network namespace (nothing leaves the machine). Every time, the observer
//! must see every node and every fleet endpoint, and the one `/cmd_vel` must start the walk
//! (the planner's `/gait/phase` leaves `idle`).
//!
//! The test counts its own failures over all the starts and is never retried
//! (.config/nextest.toml): an intermittent miss is what it is there to catch.
//! `BIPED_COLD_STARTS` sets the number of starts (default 20), `BIPED_COLD_START_LOAD` the
//! number of busy-looping threads kept running meanwhile (default 2, one per core of the CI
//! machines):
//!
//! ```sh
//! BIPED_COLD_STARTS=20 cargo test --test cold_start -- --nocapture
//! ```
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use common::{bin_dir, in_netns, python, root};
use serde_json::Value;

fn env_count(name: &str, default: usize) -> usize {
    match std::env::var(name) {
        Ok(v) => v
            .trim()
            .parse()
            .unwrap_or_else(|_| panic!("{name}={v}: not a count")),
        Err(_) => default,
    }
}

/// Threads that keep the CPUs busy until dropped.
struct Load {
    stop: Arc<AtomicBool>,
    threads: Vec<std::thread::JoinHandle<()>>,
}

impl Load {
    fn new(threads: usize) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let threads = (0..threads)
            .map(|_| {
                let stop = stop.clone();
                std::thread::spawn(move || {
                    let mut x = 0u64;
                    while !stop.load(Ordering::Relaxed) {
                        x = std::hint::black_box(
                            x.wrapping_mul(6364136223846793005).wrapping_add(1),
                        );
                    }
                })
            })
            .collect();
        Self { stop, threads }
    }
}

impl Drop for Load {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

/// One cold start in a new network namespace: what the peer recorded.
fn cold_start(domain_id: u32) -> Value {
    let out = in_netns("exec \"$@\"", domain_id)
        .arg(python())
        .arg(root().join("tests/python/cold_start_peer.py"))
        .arg(bin_dir())
        .output()
        .expect("unshare runs (root needed for a private network namespace)");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "cold start peer failed: {stderr}");
    serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("cold start peer output is not JSON ({e}): {stderr}"))
}

/// What went wrong in one cold start (empty: nothing).
fn problems(v: &Value) -> Vec<String> {
    let mut p = Vec::new();
    for (what, seen) in [
        ("node", &v["nodes_seen_s"]),
        ("endpoint", &v["endpoints_seen_s"]),
    ] {
        for (name, t) in seen.as_object().unwrap() {
            if t.is_null() {
                p.push(format!("the peer never saw {what} {name}"));
            }
        }
    }
    if v["cmd_vel_published_s"].is_null() {
        p.push(format!(
            "the --once publisher never matched a /cmd_vel subscriber: {}",
            v["pub_once_stderr"]
        ));
    } else if v["walk_started"] != true {
        p.push(format!(
            "the /cmd_vel published at {:.2} s did not start the walk",
            v["cmd_vel_published_s"].as_f64().unwrap()
        ));
    }
    for (node, exit) in v["exits"].as_object().unwrap() {
        if exit["returncode"] != 0 {
            p.push(format!(
                "{node} exited with {}: {}",
                exit["returncode"], exit["stderr_tail"]
            ));
        }
    }
    p
}

#[test]
fn a_fast_dds_peer_started_with_the_fleet_sees_every_node_and_its_one_cmd_vel_walks() {
    let starts = env_count("BIPED_COLD_STARTS", 20);
    let _load = Load::new(env_count("BIPED_COLD_START_LOAD", 2));
    let mut failed = Vec::new();
    for k in 0..starts {
        let v = cold_start(93);
        let p = problems(&v);
        let last_seen = v["nodes_seen_s"]
            .as_object()
            .unwrap()
            .values()
            .chain(v["endpoints_seen_s"].as_object().unwrap().values())
            .filter_map(Value::as_f64)
            .fold(0.0, f64::max);
        eprintln!(
            "cold start {}/{starts}: everything seen after {last_seen:.2} s, /cmd_vel published at {}, walk started at {}{}",
            k + 1,
            v["cmd_vel_published_s"],
            v["walk_started_s"],
            if p.is_empty() {
                String::new()
            } else {
                format!(": {} (logs in {})", p.join("; "), v["log_dir"])
            }
        );
        if !p.is_empty() {
            failed.push(format!("start {}: {}", k + 1, p.join("; ")));
        }
    }
    assert!(
        failed.is_empty(),
        "{} of {starts} cold starts failed:\n{}",
        failed.len(),
        failed.join("\n")
    );
}
