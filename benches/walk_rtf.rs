//! Real-time factor (simulated seconds per wall-clock second) of the simulated walk:
//!
//! 1. bare physics: MuJoCo stepping the default robot at 1 kHz, servo targets held;
//! 2. the walk played in-process: the planned joint targets (sag-compensated) set every
//!    10 ms tick, plus the walk measures, no middleware;
//! 3. `biped walk`: the whole fleet (gait_planner, ik_solver, joint_bridge, sim_bridge as
//!    separate processes, DDS over loopback) in lockstep, simulated time only advancing once
//!    the joint bridge has answered each 10 ms tick (the gait planner a tick ahead of
//!    `/clock`, the default); its own report's figure (from the first `/clock` on: process
//!    start-up and discovery excluded);
//! 4. `biped walk --plan-on-time`: the four processes with the gait planner on time (the
//!    tick waits for the planner, the IK and the joint bridge; the same walk);
//! 5. `biped walk --composed`: the same with gait_planner, ik_solver, joint_bridge and
//!    sim_bridge in one process (`biped compose`, in-process delivery between them).
//!
//! For the two fleets, also the messaging work of one tick, from the walk's report
//! (`work_per_tick`): CPU time and context switches of every process of the run, UDP
//! datagrams sent in its private network namespace; and each process's share.
//!
//! `cargo build --release --workspace && cargo bench --bench walk_rtf` (the fleet runs in a
//! private network namespace: root, `unshare -n`). Prints two Markdown tables.
//! `-- --thread-priority P`: the fleets' nodes under real-time scheduling (their
//! `thread_priority` parameter, given to every node in a `--params` file; `biped walk` runs its
//! recorder at that priority too). `-- --params FILE`: a parameter file of one's own for both
//! fleets' walks instead, e.g. the shipped `config/realtime.yaml` (no per-node
//! `cpu_affinity`: `biped compose` refuses it).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

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
    // `cargo bench` passes `--bench`.
    let mut priority = None;
    let mut given_params: Option<PathBuf> = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--bench" => {}
            "--thread-priority" => {
                let p = args.next().unwrap_or_default();
                let value = serde_norway::from_str(&p).unwrap_or(serde_norway::Value::Null);
                match node_runtime::priority::thread_priority_of(&value) {
                    Ok(p) => priority = Some(p),
                    Err(e) => {
                        eprintln!("--thread-priority: {e}");
                        return ExitCode::FAILURE;
                    }
                }
            }
            "--params" => match args.next().map(PathBuf::from) {
                Some(file) if file.is_file() => given_params = Some(file),
                other => {
                    eprintln!("--params: {other:?} is not a file");
                    return ExitCode::FAILURE;
                }
            },
            other => {
                eprintln!(
                    "unknown argument `{other}` (options: --thread-priority P, --params FILE)"
                );
                return ExitCode::FAILURE;
            }
        }
    }
    if priority.is_some() && given_params.is_some() {
        eprintln!(
            "--thread-priority and --params: one or the other (put thread_priority in the file)"
        );
        return ExitCode::FAILURE;
    }
    // Every node's parameter, through the one parameter file `biped walk` gives them all.
    let generated = priority.map(|p| {
        let file = std::env::temp_dir().join(format!("biped-rtf-{}.yaml", std::process::id()));
        std::fs::write(
            &file,
            format!("/**:\n  ros__parameters:\n    thread_priority: {p}\n"),
        )
        .expect("a parameter file in the temporary directory");
        file
    });
    let params = generated.as_ref().or(given_params.as_ref());
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
    // (variant, its runs' reports).
    let mut fleets: Vec<(&str, Vec<serde_json::Value>)> = Vec::new();
    for (what, extra) in [
        (
            "`biped walk`: the fleet over DDS in lockstep, the planner a tick ahead",
            &[][..],
        ),
        (
            "`biped walk --plan-on-time`: the same, the planner on time",
            &["--plan-on-time"][..],
        ),
        (
            "`biped walk --composed`: the four nodes in one process, in lockstep",
            &["--composed"][..],
        ),
    ] {
        let mut reports = Vec::new();
        for run in 0..RUNS {
            let out = std::env::temp_dir().join(format!("biped-rtf-{}-{run}", std::process::id()));
            let status = Command::new("unshare")
                .args(["-n", "sh", "-c", "ip link set lo up && exec \"$@\"", "sh"])
                .arg(&biped)
                .args(["walk", "--steps", &STEPS.to_string(), "--out"])
                .arg(&out)
                .args(extra)
                .args(
                    params
                        .iter()
                        .flat_map(|f| [std::ffi::OsStr::new("--params"), f.as_os_str()]),
                )
                .env("ROS_DOMAIN_ID", "90")
                .stdout(std::process::Stdio::null())
                .status()
                .expect("unshare runs (root needed)");
            if !status.success() {
                eprintln!("biped walk failed; logs in {}", out.join("logs").display());
                return ExitCode::FAILURE;
            }
            let report: serde_json::Value = serde_json::from_str(
                &std::fs::read_to_string(out.join("report.json")).expect("report.json"),
            )
            .expect("report is JSON");
            reports.push(report);
            let _ = std::fs::remove_dir_all(&out);
        }
        fleets.push((what, reports));
    }
    if let Some(file) = &generated {
        let _ = std::fs::remove_file(file);
    }
    let realtime = match (priority, &given_params) {
        (Some(p), _) => {
            format!("; the fleets' nodes under SCHED_FIFO at priority {p} (`thread_priority`)")
        }
        (None, Some(file)) => format!("; every node's parameters from `{}`", file.display()),
        (None, None) => String::new(),
    };
    println!(
        "Measured {} on {}.\n\n{} steps ({plan_s:.1} s of walk), median of {RUNS} runs, 1 kHz \
         physics, 100 Hz control{realtime}\n",
        common::today(),
        common::machine(),
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
    // The median over the runs of a report's number at `path`.
    let m = |reports: &[serde_json::Value], path: &str| {
        median(
            reports
                .iter()
                .map(|r| r.pointer(path).and_then(|v| v.as_f64()).unwrap_or(f64::NAN))
                .collect(),
        )
    };
    for (what, reports) in &fleets {
        let rtf = m(reports, "/real_time_factor");
        println!(
            "| {what} | {rtf:.1}x | {:.3} ms | {:.2} |",
            10.0 / rtf,
            rtf / bare
        );
    }
    println!(
        "\nWhat one tick cost the machine (`report.json`'s `work_per_tick`, from the first \
         `/clock` to the end; every process of the run: the nodes, robot_state_publisher and \
         `biped walk` with its recorder), median of {RUNS} runs:\n"
    );
    println!("| what runs | CPU time | context switches | UDP datagrams |");
    println!("|---|---:|---:|---:|");
    for (what, reports) in &fleets {
        println!(
            "| {what} | {:.3} ms | {:.1} | {:.1} |",
            m(reports, "/work_per_tick/cpu_ms"),
            m(reports, "/work_per_tick/context_switches"),
            m(reports, "/work_per_tick/udp_datagrams"),
        );
    }
    // Where the CPU time goes: each process's share (`work_per_tick.by_process`).
    let mut names: Vec<String> = fleets
        .iter()
        .flat_map(|(_, reports)| reports.iter())
        .filter_map(|r| r.pointer("/work_per_tick/by_process")?.as_object())
        .flat_map(|o| o.keys().cloned())
        .collect();
    names.sort();
    names.dedup();
    println!(
        "\nEach process's CPU time and context switches a tick (`work_per_tick.by_process`), \
         median of {RUNS} runs:\n"
    );
    println!("| process | four processes (ahead) | planner on time | composed |");
    println!("|---|---:|---:|---:|");
    for name in &names {
        let cell = |reports: &[serde_json::Value]| {
            let cpu = m(reports, &format!("/work_per_tick/by_process/{name}/cpu_ms"));
            let cs = m(
                reports,
                &format!("/work_per_tick/by_process/{name}/context_switches"),
            );
            if cpu.is_nan() {
                "-".to_owned()
            } else {
                format!("{cpu:.3} ms, {cs:.1}")
            }
        };
        println!(
            "| {name} | {} | {} | {} |",
            cell(&fleets[0].1),
            cell(&fleets[1].1),
            cell(&fleets[2].1)
        );
    }
    ExitCode::SUCCESS
}
