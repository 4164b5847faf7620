//! Real-time factor (simulated seconds per wall-clock second) of the simulated walk:
//!
//! 1. bare physics: MuJoCo stepping the default robot at 1 kHz, servo targets held;
//! 2. the walk played in-process: the planned joint targets (sag-compensated) set every
//!    10 ms tick, plus the walk measures, no middleware;
//! 3. `biped walk`: the whole fleet (gait_planner, ik_solver, joint_bridge, sim_bridge as
//!    separate processes, DDS over loopback) in lockstep, simulated time only advancing once
//!    every node has answered each 10 ms tick; its own report's figure (from the first
//!    `/clock` on: process start-up and discovery excluded);
//! 4. `biped walk --composed`: the same with gait_planner, ik_solver, joint_bridge and
//!    sim_bridge in one process (`biped compose`, in-process delivery between them).
//!
//! For the two fleets, also the messaging work of one tick: UDP datagrams (the network
//! namespace's counters), context switches and CPU time (of every process of the run, from
//! `getrusage` of the reaped children), from a 10-step walk less a 2-step one.
//!
//! `cargo build --release --workspace && cargo bench --bench walk_rtf` (the fleet runs in a
//! private network namespace: root, `unshare -n`). Prints two Markdown tables.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::PathBuf;
use std::process::{Command, ExitCode};
use std::time::Instant;

use gait_planner::{GaitParams, GaitPlanner, WalkRequest};
use ik_solver::{BipedModel, DEFAULT_URDF};
use sim_bridge::{Sim, SimConfig};
use walk_eval::{Interpolation, PlayOptions, run_plan};

const STEPS: u32 = 10;
const RUNS: usize = 3;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn bin_dir() -> PathBuf {
    let mut dir = std::env::current_exe()
        .ok()
        .and_then(|e| e.parent().map(PathBuf::from))
        .unwrap_or_default();
    if dir.ends_with("deps") {
        dir.pop();
    }
    dir
}

fn main() -> ExitCode {
    // `cargo bench` passes `--bench`; nothing to parse.
    let model = BipedModel::from_urdf_str(DEFAULT_URDF, None).expect("built-in robot");
    let plan = GaitPlanner::new(model, GaitParams::default())
        .expect("default gait")
        .plan(WalkRequest::Steps(STEPS))
        .expect("plan");
    let plan_s = plan.last().map_or(0.0, |s| s.t_s) - plan[0].t_s;

    // 1. Bare physics.
    let mut bare = Vec::new();
    for _ in 0..RUNS {
        let mut sim = Sim::from_urdf_str(DEFAULT_URDF, None, &SimConfig::default()).expect("sim");
        sim.stand(&plan[0].joints_rad).expect("stand");
        let t = Instant::now();
        sim.step(plan_s).expect("step");
        bare.push(plan_s / t.elapsed().as_secs_f64());
    }
    // 2. The plan played in-process.
    let mut played = Vec::new();
    for _ in 0..RUNS {
        let mut sim = Sim::from_urdf_str(DEFAULT_URDF, None, &SimConfig::default()).expect("sim");
        let options = PlayOptions {
            compensate: true,
            interpolation: Interpolation::Hold,
            tail_s: 0.0,
        };
        let t = Instant::now();
        let report = run_plan(&mut sim, &plan, &options).expect("play");
        assert!(report.fell.is_none(), "the walk fell: {:?}", report.fell);
        played.push(sim.time_s() / t.elapsed().as_secs_f64());
    }
    // 3. The fleet in lockstep.
    let biped = bin_dir().join("biped");
    if !bin_dir().join("sim_bridge").is_file() {
        eprintln!(
            "node binaries not built in {}: run `cargo build --release --workspace` first",
            bin_dir().display()
        );
        return ExitCode::FAILURE;
    }
    // (variant, its runs: real-time factor and messaging work per tick).
    let mut fleets: Vec<(&str, Vec<Walked>)> = Vec::new();
    for (what, extra) in [
        ("`biped walk`: the fleet over DDS in lockstep", &[][..]),
        (
            "`biped walk --composed`: the four nodes in one process, in lockstep",
            &["--composed"][..],
        ),
    ] {
        let mut runs = Vec::new();
        for run in 0..RUNS {
            // A short walk and the full one: the difference is the work of the extra ticks,
            // without start-up, discovery and shutdown.
            let Some(short) = walk(&biped, SHORT_STEPS, extra, run) else {
                return ExitCode::FAILURE;
            };
            let Some(full) = walk(&biped, STEPS, extra, run) else {
                return ExitCode::FAILURE;
            };
            runs.push(Walked {
                rtf: full.rtf,
                work: full.work.per_tick_over(&short.work),
            });
        }
        fleets.push((what, runs));
    }
    println!(
        "{} steps ({plan_s:.1} s of walk), median of {RUNS} runs, 1 kHz physics, 100 Hz control\n",
        STEPS
    );
    println!("| what runs | real-time factor | wall time per 10 ms tick | of bare physics |");
    println!("|---|---:|---:|---:|");
    let bare = median(bare);
    for (what, rtf) in [
        ("bare physics (MuJoCo, targets held)", bare),
        (
            "plan played in-process (targets every tick, measures)",
            median(played),
        ),
    ] {
        println!(
            "| {what} | {rtf:.1}x | {:.3} ms | {:.2} |",
            10.0 / rtf,
            rtf / bare
        );
    }
    for (what, runs) in &fleets {
        let rtf = median(runs.iter().map(|r| r.rtf).collect());
        println!(
            "| {what} | {rtf:.1}x | {:.3} ms | {:.2} |",
            10.0 / rtf,
            rtf / bare
        );
    }
    println!(
        "\nThe messaging work of one 10 ms tick (all processes of the run: the nodes, \
         robot_state_publisher and `biped walk`'s recorder), from a {STEPS}-step walk less a \
         {SHORT_STEPS}-step one (start-up, discovery and shutdown cancel out), median of {RUNS}:\n"
    );
    println!("| what runs | UDP datagrams | context switches | CPU time |");
    println!("|---|---:|---:|---:|");
    for (what, runs) in &fleets {
        let m = |f: fn(&TickWork) -> f64| median(runs.iter().map(|r| f(&r.work)).collect());
        println!(
            "| {what} | {:.1} | {:.1} | {:.3} ms |",
            m(|w| w.datagrams),
            m(|w| w.context_switches),
            m(|w| w.cpu_s) * 1e3
        );
    }
    ExitCode::SUCCESS
}

/// Steps of the short walk whose work is subtracted.
const SHORT_STEPS: u32 = 2;

/// What a run of `biped walk` cost: totals, or per tick.
#[derive(Debug, Clone, Copy)]
struct TickWork {
    /// Simulated 10 ms ticks.
    ticks: f64,
    /// UDP datagrams sent in the run's network namespace.
    datagrams: f64,
    /// Voluntary and involuntary context switches of every process of the run.
    context_switches: f64,
    /// User and system CPU time of every process of the run (s).
    cpu_s: f64,
}

impl TickWork {
    /// The work per tick of the ticks `self` ran beyond `short`.
    fn per_tick_over(&self, short: &TickWork) -> TickWork {
        let ticks = self.ticks - short.ticks;
        TickWork {
            ticks: 1.0,
            datagrams: (self.datagrams - short.datagrams) / ticks,
            context_switches: (self.context_switches - short.context_switches) / ticks,
            cpu_s: (self.cpu_s - short.cpu_s) / ticks,
        }
    }
}

/// A finished walk: its real-time factor and what it cost (in total, or per tick).
struct Walked {
    rtf: f64,
    work: TickWork,
}

/// Context switches and CPU time (s) of the reaped children of this process so far.
fn children_usage() -> (f64, f64) {
    use nix::sys::resource::{UsageWho, getrusage};
    let u = getrusage(UsageWho::RUSAGE_CHILDREN).expect("getrusage");
    let secs = |t: nix::sys::time::TimeVal| t.tv_sec() as f64 + t.tv_usec() as f64 * 1e-6;
    (
        (u.voluntary_context_switches() + u.involuntary_context_switches()) as f64,
        secs(u.user_time()) + secs(u.system_time()),
    )
}

/// Runs `biped walk --steps steps` (plus `extra`) in a private network namespace, and reads
/// its report and the namespace's UDP counters when it ends. `None` (and why, on stderr) if
/// the walk failed.
fn walk(biped: &std::path::Path, steps: u32, extra: &[&str], run: usize) -> Option<Walked> {
    let out = std::env::temp_dir().join(format!("biped-rtf-{}-{run}-{steps}", std::process::id()));
    let snmp = out.with_extension("snmp");
    let before = children_usage();
    let status = Command::new("unshare")
        .args([
            "-n",
            "sh",
            "-c",
            // The namespace's UDP counters after the walk (it is gone once the shell ends).
            "ip link set lo up && \"$@\"; rc=$?; grep '^Udp:' /proc/net/snmp > \"$SNMP\"; exit $rc",
            "sh",
        ])
        .arg(biped)
        .args(["walk", "--steps", &steps.to_string(), "--out"])
        .arg(&out)
        .args(extra)
        .env("ROS_DOMAIN_ID", "90")
        .env("SNMP", &snmp)
        .stdout(std::process::Stdio::null())
        .status()
        .expect("unshare runs (root needed)");
    let after = children_usage();
    if !status.success() {
        eprintln!("biped walk failed; logs in {}", out.join("logs").display());
        return None;
    }
    let report: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("report.json")).expect("report.json"),
    )
    .expect("report is JSON");
    let rtf = report["real_time_factor"].as_f64().unwrap_or(0.0);
    let ticks = report["simulated_s"].as_f64().unwrap_or(0.0) / 0.01;
    let datagrams = out_datagrams(&std::fs::read_to_string(&snmp).expect("UDP counters"));
    let _ = std::fs::remove_dir_all(&out);
    let _ = std::fs::remove_file(&snmp);
    Some(Walked {
        rtf,
        work: TickWork {
            ticks,
            datagrams,
            context_switches: after.0 - before.0,
            cpu_s: after.1 - before.1,
        },
    })
}

/// `OutDatagrams` of the `Udp:` lines of `/proc/net/snmp` (a header line, then values).
fn out_datagrams(snmp: &str) -> f64 {
    let mut lines = snmp
        .lines()
        .map(|l| l.split_whitespace().collect::<Vec<_>>());
    let (Some(names), Some(values)) = (lines.next(), lines.next()) else {
        panic!("no Udp: lines in /proc/net/snmp: {snmp:?}");
    };
    let i = names
        .iter()
        .position(|n| *n == "OutDatagrams")
        .expect("OutDatagrams in /proc/net/snmp");
    values[i].parse().expect("a count")
}
