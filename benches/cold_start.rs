//! Cold starts against a ROS 2 tool: how long from the fleet's start until a Fast DDS peer
//! (rclpy) started at the same instant has seen every node and fleet endpoint, and from a
//! `ros2 topic pub --once -w 1 /cmd_vel` to the first phase of the walk. Each start runs
//! tests/python/cold_start_peer.py in a fresh private network namespace (nothing leaves the
//! machine) while busy threads load the cores, as tests/cold_start.rs does; the test asserts
//! that nothing is missed, this reports the times.
//!
//! ```sh
//! cargo build --profile test --workspace --bins
//! cargo bench --bench cold_start                          # 20 starts of target/debug's nodes
//! cargo bench --bench cold_start -- --bin-dir DIR --starts 12 --load 2
//! ```
//!
//! `--bin-dir` runs other node binaries, e.g. built without `patches/rustdds` (comment out
//! its `[patch.crates-io]` line, `cargo build --profile test --bins --target-dir
//! target/unpatched -p gait_planner -p ik_solver -p joint_bridge`), for the comparison in
//! BENCHMARKS.md. A benchmark, not a test: not part of `cargo test` or `scripts/test`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

#[path = "../tests/common/mod.rs"]
mod test_common;

use std::path::PathBuf;
use std::process::ExitCode;

use test_common::cold_start::{
    Load, cmd_vel_to_walk_s, cold_start, everything_seen_s, problems, secs,
};

/// The `q` quantile (nearest rank) of `v`, sorted here.
fn quantile(v: &mut [f64], q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    let rank = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len());
    v[rank - 1]
}

fn summary(v: &mut [f64]) -> String {
    if v.is_empty() {
        return "-".into();
    }
    format!(
        "{:.2} / {:.2} / {:.2} s",
        quantile(v, 0.5),
        quantile(v, 0.9),
        quantile(v, 1.0)
    )
}

fn main() -> ExitCode {
    let mut starts = 20usize;
    let mut load = 2usize;
    let mut bin_dir: Option<PathBuf> = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--starts" => starts = args.next().and_then(|v| v.parse().ok()).unwrap_or(starts),
            "--load" => load = args.next().and_then(|v| v.parse().ok()).unwrap_or(load),
            "--bin-dir" => bin_dir = args.next().map(PathBuf::from),
            "--bench" => {}
            other => {
                eprintln!(
                    "unknown argument `{other}` (options: --starts N, --load N, --bin-dir DIR)"
                );
                return ExitCode::FAILURE;
            }
        }
    }
    let bin = bin_dir.unwrap_or_else(|| test_common::root().join("target/debug"));
    for node in ["gait_planner", "ik_solver", "joint_bridge"] {
        if !bin.join(node).is_file() {
            eprintln!(
                "no {node} in {}: build the nodes first (cargo build --profile test --workspace --bins)",
                bin.display()
            );
            return ExitCode::FAILURE;
        }
    }
    let _load = Load::new(load);
    let (mut seen, mut walk) = (Vec::new(), Vec::new());
    let mut missed = 0;
    for k in 0..starts {
        let v = cold_start(&bin, 94);
        let p = problems(&v);
        if let Some(t) = everything_seen_s(&v) {
            seen.push(t);
        }
        if let Some(t) = cmd_vel_to_walk_s(&v) {
            walk.push(t);
        }
        if !p.is_empty() {
            missed += 1;
        }
        eprintln!(
            "start {}/{starts}: everything seen after {}, walk {} after the /cmd_vel {}",
            k + 1,
            secs(everything_seen_s(&v)),
            secs(cmd_vel_to_walk_s(&v)),
            p.join("; ")
        );
    }
    let walked = walk.len();
    println!(
        "| nodes | starts | busy threads | something missed | peer saw everything (median / p90 / max) | --once /cmd_vel walked | /cmd_vel to walk (median / p90 / max) |"
    );
    println!("|---|---:|---:|---:|---|---:|---|");
    println!(
        "| {} | {starts} | {load} | {missed} | {} | {walked} | {} |",
        bin.display(),
        summary(&mut seen),
        summary(&mut walk)
    );
    ExitCode::SUCCESS
}
