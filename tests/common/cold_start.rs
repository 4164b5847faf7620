//! One cold start of the fleet beside a real ROS 2 Jazzy peer, and what the cold-start test
//! (tests/cold_start.rs) and bench (benches/cold_start.rs) read from it.
//!
//! tests/python/cold_start_peer.py starts the fleet's nodes, an rclpy observer and a
//! `ros2 topic pub --once -w 1 /cmd_vel` stand-in at the same instant, in a fresh private
//! network namespace, and records when the observer saw each node and endpoint and whether
//! the one `/cmd_vel` started the walk.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use serde_json::Value;

use super::{json_of, python_in_netns};

/// Threads that keep the CPUs busy until dropped: a cold start on a loaded machine.
pub struct Load {
    stop: Arc<AtomicBool>,
    threads: Vec<std::thread::JoinHandle<()>>,
}

impl Load {
    pub fn new(threads: usize) -> Self {
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

/// A count from the environment variable `name`, or `default`.
pub fn env_count(name: &str, default: usize) -> usize {
    match std::env::var(name) {
        Ok(v) => v
            .trim()
            .parse()
            .unwrap_or_else(|_| panic!("{name}={v}: not a count")),
        Err(_) => default,
    }
}

/// One cold start of the node binaries in `bin_dir`, in a new network namespace: what the
/// peer recorded.
pub fn cold_start(bin_dir: &Path, domain_id: u32) -> Value {
    json_of(
        python_in_netns("cold_start_peer.py", domain_id).arg(bin_dir),
        "cold start peer",
    )
}

/// Seconds from the start until the peer had seen every node and fleet endpoint; `None` if
/// it missed one.
pub fn everything_seen_s(v: &Value) -> Option<f64> {
    v["nodes_seen_s"]
        .as_object()?
        .values()
        .chain(v["endpoints_seen_s"].as_object()?.values())
        .try_fold(0.0_f64, |last, t| t.as_f64().map(|t| last.max(t)))
}

/// Seconds from the one `/cmd_vel` to the first phase of the walk; `None` if it did not
/// start the walk.
pub fn cmd_vel_to_walk_s(v: &Value) -> Option<f64> {
    if v["walk_started"] != true {
        return None;
    }
    Some(v["walk_started_s"].as_f64()? - v["cmd_vel_published_s"].as_f64()?)
}

/// `Some` seconds to two decimals, `None` as "never".
pub fn secs(t: Option<f64>) -> String {
    t.map_or_else(|| "never".to_owned(), |t| format!("{t:.2} s"))
}

/// What went wrong in one cold start (empty: nothing).
pub fn problems(v: &Value) -> Vec<String> {
    let mut p = Vec::new();
    for (what, seen) in [
        ("node", &v["nodes_seen_s"]),
        ("endpoint", &v["endpoints_seen_s"]),
    ] {
        for (name, t) in seen.as_object().into_iter().flatten() {
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
            v["cmd_vel_published_s"].as_f64().unwrap_or(f64::NAN)
        ));
    }
    for (node, exit) in v["exits"].as_object().into_iter().flatten() {
        if exit["returncode"] != 0 {
            p.push(format!(
                "{node} exited with {}: {}",
                exit["returncode"], exit["stderr_tail"]
            ));
        }
    }
    p
}
