//! The ROS 2 pipeline's latency: from a gait tick to its joint command arriving at the joint
//! bridge, two DDS hops (`/gait/ankle_targets` → IK → `/joint_commands`), at 100 Hz and at
//! 1 kHz; and the same two hops with an rclpy relay (`benches/pipeline_relay.py`) in place of
//! our `ik_solver` node, so that only the relay differs.
//!
//! This process plays both ends on one ros2-client node: it publishes the ankle targets of a
//! planned walk (biped_msgs/msg/AnkleTargets) at the rate with the send time in
//! `header.stamp`, and subscribes to sensor_msgs/msg/JointState on `/joint_commands`, whose
//! header the relay copies. Latency = arrival in the subscriber (after deserialisation) −
//! stamp, on one clock; lost = sent − received, matched by stamp. The relay is the real
//! `ik_solver` node binary beside this executable (build it first:
//! `cargo build --release --workspace`), or the rclpy relay on `.venv/bin/biped-python`
//! (`scripts/setup-python-env`; `BIPED_PYTHON` overrides).
//!
//! Nothing leaves the machine: the process re-executes itself inside a private network
//! namespace with only loopback (`unshare -n`, root), on its own ROS_DOMAIN_ID with
//! ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, and refuses to run if it sees another interface.
//!
//! ```sh
//! cargo build --release --workspace
//! cargo bench --bench pipeline                 # prints the table and the BENCHMARKS.md section
//! cargo bench --bench pipeline -- --write      # also writes that section into BENCHMARKS.md
//! ```
//!
//! Options: `--n-100hz N` (3000), `--n-1khz N` (10000), `--only ik_solver|rclpy`, `--write`,
//! `--cpu-affinity CPU[,CPU...]` (bind the bench and the relay to these CPUs: on a machine
//! whose idle CPUs are slow to wake, one CPU saves a cross-CPU wake-up per hop),
//! `--wait-idle` (before each run, wait up to 2 min until the machine is idle, and do a run
//! that other processes disturbed anyway, over 20 % of a core on average or half a core in
//! some 0.5 s, again, up to three times: on a shared machine a compile next door shows in
//! p99 and max; the table has a column for the CPU other processes used either way),
//! `--cpu-dma-latency-us US` (hold a CPU latency request during the runs, as a node's
//! `cpu_dma_latency_us` parameter does: 0 keeps idle CPUs polling instead of halting),
//! `--thread-priority P` (run the bench's and the relay's threads under SCHED_FIFO at
//! priority P, as a node's `thread_priority` parameter does; the rclpy relay inherits it),
//! `--solve-on-node-thread` (the ik_solver with its `solve_on_receive` parameter false: each
//! message handed by the DDS thread that received it to the node's own thread, one thread
//! wake-up more a message; the default solves on receive, and `--solve-on-receive`, which
//! said so before it was the default, is still taken),
//! `--in-reader` (each command time-stamped on the DDS thread that receives it, in its
//! reader, instead of after that thread has woken the subscriber's: where a `joint_bridge`
//! driving hardware with `tick_on_command` false finds it, since it then takes commands on
//! its own control tick and never waits for one; by default a command wakes its thread as it
//! comes, as without this option),
//! `--dump DIR` (each run's latencies, one CSV per relay and rate, in the order sent).
//! A benchmark, not a test: it is not part of `cargo test` or `scripts/test`.

mod common;

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, mpsc};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::{Context as _, anyhow, bail};
use biped_msgs::RosMessage;
use biped_msgs::msg::{AnkleTargets, Header, JointState, Point, Time};
use common::{
    Proc, bin_dir, check_only_loopback, lock_version, machine, machine_cpu, proc_cpu_time,
    warn_if_stale,
};
use gait_planner::{GaitParams, GaitPlanner, WalkRequest};
use ik_solver::BipedModel;
use node_runtime::RosArgs;
use ros2_client::qos::History;
use ros2_client::{NodeName, NodeOptions, Publisher};

/// Set in the re-executed process, inside the private network namespace.
/// Our own DDS domain (the namespace is private anyway).
const DOMAIN_ID: &str = "97";
/// The heading of this benchmark's section in BENCHMARKS.md.
const SECTION: &str = "## ROS 2 pipeline latency";

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("pipeline bench: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Relay {
    IkSolver,
    Rclpy,
}

impl Relay {
    fn name(self) -> &'static str {
        match self {
            Relay::IkSolver => "ik_solver",
            Relay::Rclpy => "rclpy",
        }
    }
    fn label(self) -> &'static str {
        match self {
            Relay::IkSolver => "`ik_solver` node (Rust, ros2-client + RustDDS)",
            Relay::Rclpy => "rclpy relay (Python, Fast DDS)",
        }
    }
}

#[derive(Debug)]
struct Opts {
    n_100hz: usize,
    n_1khz: usize,
    relays: Vec<Relay>,
    write: bool,
    wait_idle: bool,
    /// `--cpu-affinity`: the CPUs the bench and the relay are bound to.
    cpus: Option<Vec<usize>>,
    /// `--cpu-dma-latency-us`: a CPU latency request held during the runs.
    latency_us: Option<u32>,
    /// `--thread-priority`: the SCHED_FIFO priority of the bench's and the relay's threads.
    priority: Option<u8>,
    /// `--dump`: where each run's latencies go, one CSV per relay and rate.
    dump: Option<PathBuf>,
    /// The ik_solver solves on the DDS thread that receives each message (its
    /// `solve_on_receive` parameter, true by default; `--solve-on-node-thread` sets false).
    solve_on_receive: bool,
    /// `--in-reader`: commands time-stamped on the DDS thread that receives them.
    in_reader: bool,
}

impl Opts {
    fn parse(args: impl IntoIterator<Item = String>) -> anyhow::Result<Self> {
        let mut o = Opts {
            n_100hz: 3000,
            n_1khz: 10_000,
            relays: vec![Relay::IkSolver, Relay::Rclpy],
            write: false,
            wait_idle: false,
            cpus: None,
            latency_us: None,
            priority: None,
            dump: None,
            solve_on_receive: true,
            in_reader: false,
        };
        let mut it = args.into_iter();
        while let Some(a) = it.next() {
            let mut value = || it.next().ok_or_else(|| anyhow!("{a} needs a value"));
            match a.as_str() {
                // `cargo bench` passes --bench to harness-less benches.
                "--bench" => {}
                "--write" => o.write = true,
                "--wait-idle" => o.wait_idle = true,
                "--solve-on-receive" => o.solve_on_receive = true,
                "--solve-on-node-thread" => o.solve_on_receive = false,
                "--in-reader" => o.in_reader = true,
                "--n-100hz" => o.n_100hz = value()?.parse().context("--n-100hz")?,
                "--n-1khz" => o.n_1khz = value()?.parse().context("--n-1khz")?,
                "--cpu-affinity" => {
                    // The parameter's own parsing and checks, on the list as YAML.
                    let list = value()?;
                    let yaml = serde_norway::from_str(&format!("[{list}]"))
                        .with_context(|| format!("--cpu-affinity {list}"))?;
                    o.cpus = node_runtime::affinity::cpu_affinity_of(&yaml)?;
                }
                "--cpu-dma-latency-us" => o.latency_us = Some(common::latency_arg(&value()?)?),
                "--thread-priority" => {
                    // The parameter's own parsing and checks.
                    let p = value()?;
                    let yaml = serde_norway::from_str(&p)
                        .with_context(|| format!("--thread-priority {p}"))?;
                    o.priority = Some(node_runtime::priority::thread_priority_of(&yaml)?);
                }
                "--dump" => o.dump = Some(PathBuf::from(value()?)),
                "--only" => {
                    o.relays = match value()?.as_str() {
                        "ik_solver" => vec![Relay::IkSolver],
                        "rclpy" => vec![Relay::Rclpy],
                        other => bail!("--only {other}: expected ik_solver or rclpy"),
                    }
                }
                other => bail!(
                    "unknown argument `{other}` (options: --n-100hz N, --n-1khz N, --only ik_solver|rclpy, --write, --wait-idle, --cpu-affinity CPU[,CPU...], --cpu-dma-latency-us US, --thread-priority P, --solve-on-node-thread, --in-reader, --dump DIR)"
                ),
            }
        }
        if o.n_100hz == 0 || o.n_1khz == 0 {
            bail!("message counts must be at least 1");
        }
        Ok(o)
    }
}

fn run() -> anyhow::Result<()> {
    let opts = Opts::parse(std::env::args().skip(1))?;
    if !common::in_netns() {
        return common::reexec_in_netns(DOMAIN_ID);
    }
    check_only_loopback()?;
    // Before DDS starts a thread: they all inherit it, as does the rclpy relay's process.
    if let Some(cpus) = &opts.cpus {
        node_runtime::affinity::bind_this_thread(cpus)?;
    }
    // Likewise inherited by every thread and the rclpy relay's process (its threads too).
    if let Some(priority) = opts.priority {
        node_runtime::priority::run_this_thread_realtime(priority)?;
    }
    // The whole machine's, so the rclpy relay's runs have it too; held until the bench ends.
    let _latency = opts
        .latency_us
        .map(node_runtime::CpuLatencyRequest::hold)
        .transpose()?;
    if let Some(dir) = &opts.dump {
        std::fs::create_dir_all(dir).with_context(|| format!("--dump {}", dir.display()))?;
    }

    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let bins = bin_dir()?;
    let model = BipedModel::from_urdf_str(ik_solver::DEFAULT_URDF, None)?;
    let targets = walk_targets(&model)?;
    let leg_joints: Vec<String> = model.leg_joints().map(|(_, j)| j.name.clone()).collect();
    let clock = StampClock::new();
    let rates = [(100.0, opts.n_100hz), (1000.0, opts.n_1khz)];

    // The relays' stderr files.
    let scratch = std::env::temp_dir().join(format!("biped-bench-pipeline-{}", std::process::id()));
    std::fs::create_dir_all(&scratch).with_context(|| scratch.display().to_string())?;
    let mut results = Vec::new();
    let mut versions = Vec::new();
    for &relay in &opts.relays {
        let what = format!("{} relay", relay.name());
        let mut child = match relay {
            Relay::IkSolver => {
                let exe = bins.join("ik_solver");
                if !exe.is_file() {
                    bail!(
                        "node binary {} not built: run `cargo build --release --workspace` first",
                        exe.display()
                    );
                }
                warn_if_stale(
                    &exe,
                    &root,
                    &["ik_solver/src", "msgs/src"],
                    "cargo build --release --workspace",
                );
                let mut cmd = Command::new(&exe);
                cmd.arg("--ros-args");
                if let Some(cpus) = &opts.cpus {
                    // It would inherit the bench's binding too; the parameter is what a user
                    // would set.
                    cmd.args(["-p", &format!("cpu_affinity:={cpus:?}")]);
                }
                if let Some(us) = opts.latency_us {
                    // The bench holds it already (the request is the machine's): the node
                    // holds it as a user would set it.
                    cmd.args(["-p", &format!("cpu_dma_latency_us:={us}")]);
                }
                // Given either way: the figures say which, whatever the node's default.
                cmd.args([
                    "-p",
                    &format!("solve_on_receive:={}", opts.solve_on_receive),
                ]);
                if let Some(priority) = opts.priority {
                    // Inherited as well; the parameter is what a user would set.
                    cmd.args(["-p", &format!("thread_priority:={priority}")]);
                }
                Proc::spawn(&mut cmd, &what, &scratch)?
            }
            Relay::Rclpy => {
                let python = std::env::var_os("BIPED_PYTHON")
                    .map(PathBuf::from)
                    .unwrap_or_else(|| root.join(".venv/bin/biped-python"));
                if !python.exists() {
                    bail!(
                        "no rclpy at {}: run scripts/setup-python-env (or --only ik_solver)",
                        python.display()
                    );
                }
                Proc::spawn(
                    Command::new(&python)
                        .arg(root.join("benches/pipeline_relay.py"))
                        .args(&leg_joints),
                    &what,
                    &scratch,
                )?
            }
        };
        eprintln!("[{}] started, pid {}", relay.name(), child.pid());
        let outcome = session(
            relay,
            &mut child,
            &rates,
            &targets,
            leg_joints.len(),
            clock,
            &opts,
        );
        let stdout = child.interrupt_and_read();
        match outcome {
            Ok(mut r) => results.append(&mut r),
            Err(e) => return Err(e.context(child.stderr_tail())),
        }
        if relay == Relay::Rclpy {
            versions.push(stdout.lines().next().unwrap_or_default().trim().to_owned());
        }
    }

    let _ = std::fs::remove_dir_all(&scratch);
    println!("\n{}", table(&results));
    let section = section(&opts, &root, &results, &versions);
    if opts.write {
        let path = root.join("BENCHMARKS.md");
        write_section(&path, &section)?;
        println!("wrote the section \"{SECTION}\" of {}", path.display());
    } else {
        println!("--- section for BENCHMARKS.md (written with -- --write) ---\n\n{section}");
    }
    Ok(())
}

/// The ankle targets of every tick of a planned 6-step walk, as the gait_planner node sends
/// them (stamps filled in when sent).
fn walk_targets(model: &BipedModel) -> anyhow::Result<Vec<AnkleTargets>> {
    let plan =
        GaitPlanner::new(model.clone(), GaitParams::default())?.plan(WalkRequest::Steps(6))?;
    let frame = model.robot().links()[model.robot().root()].name.clone();
    let p = |v: &nalgebra::Vector3<f64>| Point {
        x: v.x,
        y: v.y,
        z: v.z,
    };
    Ok(plan
        .iter()
        .map(|s| AnkleTargets {
            header: Header {
                stamp: Time::default(),
                frame_id: frame.clone(),
            },
            left_ankle: p(&s.targets[0].ankle_in_hip_m),
            right_ankle: p(&s.targets[1].ankle_in_hip_m),
            left_foot_yaw: s.targets[0].foot_yaw_rad,
            right_foot_yaw: s.targets[1].foot_yaw_rad,
            pelvis: p(&s.base_world.translation.vector),
        })
        .collect())
}

/// Wall-clock nanoseconds as a header stamp would carry them, advanced by the monotonic
/// clock so that both ends read one clock that cannot jump.
#[derive(Debug, Clone, Copy)]
struct StampClock {
    t0: Instant,
    base_ns: i64,
}

impl StampClock {
    fn new() -> Self {
        let since = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .unwrap_or_default();
        Self {
            t0: Instant::now(),
            base_ns: since.as_nanos() as i64,
        }
    }
    fn now_ns(&self) -> i64 {
        self.base_ns + self.t0.elapsed().as_nanos() as i64
    }
}

/// Waits until the machine has been nearly idle (under 10 % of one core busy) for 3 s, at
/// most `max`.
fn wait_idle(max: Duration) {
    let start = Instant::now();
    let mut quiet_since: Option<Instant> = None;
    let mut last_note = Instant::now();
    while start.elapsed() < max {
        let (Some(b0), t0) = (machine_cpu().map(|m| m.busy), Instant::now()) else {
            return;
        };
        std::thread::sleep(Duration::from_millis(500));
        let Some(b1) = machine_cpu().map(|m| m.busy) else {
            return;
        };
        let busy = (b1 - b0).as_secs_f64() / t0.elapsed().as_secs_f64();
        if busy < 0.10 {
            let since = *quiet_since.get_or_insert(t0);
            if since.elapsed() >= Duration::from_secs(3) {
                eprintln!(
                    "machine idle after {:.0} s of waiting",
                    start.elapsed().as_secs_f64()
                );
                return;
            }
        } else {
            quiet_since = None;
            if last_note.elapsed() > Duration::from_secs(15) {
                eprintln!(
                    "waiting for the machine to be idle: {:.0} % of a core busy",
                    busy * 100.0
                );
                last_note = Instant::now();
            }
        }
    }
    eprintln!(
        "warning: the machine did not become idle within {:.0} s; measuring anyway",
        max.as_secs_f64()
    );
}

/// A joint command as it arrived.
#[derive(Debug, Clone, Copy)]
struct Arrival {
    stamp_ns: i64,
    arrived_ns: i64,
    positions: usize,
}

#[derive(Debug, Clone)]
struct RunResult {
    relay: Relay,
    rate_hz: f64,
    sent: usize,
    lost: usize,
    duplicates: usize,
    wrong_size: usize,
    median_us: f64,
    /// Messages that took over twice the median.
    over_twice_median: usize,
    p99_us: f64,
    max_us: f64,
    achieved_hz: f64,
    relay_cpu_pct: Option<f64>,
    others_cpu_pct: Option<f64>,
    others_peak_pct: Option<f64>,
}

impl RunResult {
    /// Other processes took over 20 % of a core on average, or over half a core in some
    /// 0.5 s window.
    fn disturbed(&self) -> bool {
        self.others_cpu_pct.unwrap_or(0.0) > 20.0 || self.others_peak_pct.unwrap_or(0.0) > 50.0
    }
    /// How disturbed, to keep the least disturbed attempt.
    fn disturbance(&self) -> f64 {
        self.others_peak_pct.unwrap_or(0.0) + self.others_cpu_pct.unwrap_or(0.0)
    }
}

/// Samples, every 0.5 s, the CPU other processes use (the machine's user + system time
/// minus this process's and the relay's) and keeps the highest window.
struct OthersSampler {
    stop: Arc<AtomicBool>,
    thread: std::thread::JoinHandle<Option<f64>>,
}

impl OthersSampler {
    fn start(relay_pid: u32) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let thread = std::thread::spawn(move || {
            let pid = relay_pid.to_string();
            let sample = || {
                Some((
                    Instant::now(),
                    machine_cpu().map(|m| m.busy)?,
                    proc_cpu_time("self")?,
                    proc_cpu_time(&pid)?,
                ))
            };
            let mut peak: Option<f64> = None;
            let mut prev = sample();
            while !flag.load(Ordering::SeqCst) {
                std::thread::sleep(Duration::from_millis(500));
                let cur = sample();
                if let (Some(a), Some(b)) = (prev, cur) {
                    let ours = (b.2.saturating_sub(a.2)) + (b.3.saturating_sub(a.3));
                    let others = b.1.saturating_sub(a.1).saturating_sub(ours);
                    let pct = 100.0 * others.as_secs_f64() / (b.0 - a.0).as_secs_f64();
                    peak = Some(peak.map_or(pct, |p: f64| p.max(pct)));
                }
                prev = cur;
            }
            peak
        });
        Self { stop, thread }
    }
    fn finish(self) -> Option<f64> {
        self.stop.store(true, Ordering::SeqCst);
        self.thread.join().ok().flatten()
    }
}

/// One relay: our node's ends, discovery, then a run at each rate.
fn session(
    relay: Relay,
    child: &mut Proc,
    rates: &[(f64, usize)],
    targets: &[AnkleTargets],
    joints: usize,
    clock: StampClock,
    opts: &Opts,
) -> anyhow::Result<Vec<RunResult>> {
    let (wait, dump) = (opts.wait_idle, opts.dump.as_deref());
    let dds = |what: &str| {
        let what = what.to_owned();
        move |e: &dyn std::fmt::Debug| anyhow!("{what}: {e:?}")
    };
    let context = node_runtime::context_from_env()?;
    let mut node = context
        .new_node(
            NodeName::new("/", "pipeline_bench").map_err(|e| dds("node name")(&e))?,
            NodeOptions::new().enable_rosout(false),
        )
        .map_err(|e| dds("node")(&e))?;
    let qos = node_runtime::qos::default();
    let none = RosArgs::default();
    let targets_topic = node
        .create_topic(
            &node_runtime::topic_name(&none, "/", "/gait/ankle_targets")?,
            AnkleTargets::message_type_name(),
            &qos,
        )
        .map_err(|e| dds("topic")(&e))?;
    let commands_topic = node
        .create_topic(
            &node_runtime::topic_name(&none, "/", "/joint_commands")?,
            JointState::message_type_name(),
            &qos,
        )
        .map_err(|e| dds("topic")(&e))?;
    let publisher = node
        .create_publisher::<AnkleTargets>(&targets_topic, None)
        .map_err(|e| dds("publisher")(&e))?;
    // The measuring end keeps up to 1000 commands (the fleet's 10 elsewhere): a stall of this
    // process must not count as a loss of the pipeline. History is not part of QoS matching.
    let subscription = node
        .create_subscription::<JointState>(
            &commands_topic,
            Some(qos.clone().history(History::KeepLast { depth: 1000 })),
        )
        .map_err(|e| dds("subscription")(&e))?;
    let spinner = node.spinner().map_err(|e| dds("spinner")(&e))?;
    let spin_thread = std::thread::spawn(move || smol::block_on(spinner.spin()));

    // The joint bridge's end: time-stamps each arrival as soon as it is taken. It waits as
    // the fleet's nodes do (node_runtime::wait): parked, one timer for the stop check. With
    // --in-reader, on the DDS thread that receives it instead, and no thread of ours waits.
    let stop = Arc::new(AtomicBool::new(false));
    let (tx, rx) = mpsc::channel::<Arrival>();
    let arrival = move |msg: JointState, arrived_ns: i64| Arrival {
        stamp_ns: msg.header.stamp.to_nanos(),
        arrived_ns,
        positions: msg.position.len(),
    };
    let (receiver, in_reader) = if opts.in_reader {
        let handler = move |received: node_runtime::Received<JointState>| match received {
            Ok((msg, _)) => {
                let arrived_ns = clock.now_ns();
                let _ = tx.send(arrival(msg, arrived_ns));
            }
            Err(e) => eprintln!("joint_commands: unreadable message: {e:?}"),
        };
        (
            None,
            Some(node_runtime::OnReceive::new(subscription, handler)),
        )
    } else {
        let stop = stop.clone();
        let thread = std::thread::spawn(move || {
            node_runtime::wait::block_on(async {
                let mut bound = node_runtime::WaitBound::every(Duration::from_millis(100));
                while !stop.load(Ordering::SeqCst) {
                    match bound.within(subscription.async_take()).await {
                        Some(Ok((msg, _))) => {
                            let arrived_ns = clock.now_ns();
                            let _ = tx.send(arrival(msg, arrived_ns));
                        }
                        Some(Err(e)) => eprintln!("joint_commands: unreadable message: {e:?}"),
                        None => {}
                    }
                }
            })
        });
        (Some(thread), None)
    };

    let result = (|| -> anyhow::Result<Vec<RunResult>> {
        let t = Instant::now();
        wait_for_round_trip(&publisher, targets, clock, &rx, child)?;
        eprintln!(
            "[{}] first joint command back after {:.1} s",
            relay.name(),
            t.elapsed().as_secs_f64()
        );
        let mut out = Vec::new();
        let mut k = 0;
        for &(rate_hz, n) in rates {
            // With --wait-idle: a quiet machine first, and a run that other processes
            // disturbed anyway (see RunResult::disturbed) is done again, up to three times in all;
            // the least disturbed one counts.
            let attempts = if wait { 3 } else { 1 };
            let mut best: Option<RunResult> = None;
            for attempt in 1..=attempts {
                if wait {
                    wait_idle(Duration::from_secs(120));
                }
                let r = measure(
                    relay, rate_hz, n, &publisher, targets, &mut k, clock, &rx, child, joints, dump,
                )?;
                eprintln!(
                    "[{}] {} Hz: median {:.3} ms, p99 {:.3} ms ({} over twice the median), max {:.3} ms, lost {}/{}; other processes {:.0} % of a core, peak {:.0} %",
                    relay.name(),
                    rate_hz,
                    r.median_us / 1e3,
                    r.p99_us / 1e3,
                    r.over_twice_median,
                    r.max_us / 1e3,
                    r.lost,
                    r.sent,
                    r.others_cpu_pct.unwrap_or(f64::NAN),
                    r.others_peak_pct.unwrap_or(f64::NAN),
                );
                let disturbed = r.disturbed();
                if best
                    .as_ref()
                    .is_none_or(|b| r.disturbance() < b.disturbance())
                {
                    best = Some(r);
                }
                if !disturbed {
                    break;
                }
                if attempt < attempts {
                    eprintln!("[{}] disturbed by other processes: again", relay.name());
                }
            }
            out.extend(best);
        }
        Ok(out)
    })();

    stop.store(true, Ordering::SeqCst);
    if let Some(thread) = receiver {
        let _ = thread.join();
    }
    drop(in_reader);
    node.stop_spinner();
    let _ = spin_thread.join();
    result
}

/// Publishes one message every 50 ms until a joint command comes back: both hops are then
/// discovered and matched.
fn wait_for_round_trip(
    publisher: &Publisher<AnkleTargets>,
    targets: &[AnkleTargets],
    clock: StampClock,
    rx: &mpsc::Receiver<Arrival>,
    child: &mut Proc,
) -> anyhow::Result<()> {
    let start = Instant::now();
    for k in 0.. {
        if child.exited() {
            bail!("the relay exited before answering");
        }
        if start.elapsed() > Duration::from_secs(30) {
            bail!("no joint command came back within 30 s");
        }
        let mut msg = targets[k % targets.len()].clone();
        msg.header.stamp = Time::from_nanos(clock.now_ns());
        publisher
            .publish(msg)
            .map_err(|e| anyhow!("publish: {e:?}"))?;
        if rx.recv_timeout(Duration::from_millis(50)).is_ok() {
            return Ok(());
        }
    }
    Ok(())
}

/// Sends `n` messages at `rate_hz` on a drift-free schedule; returns the stamps sent.
fn send_at_rate(
    publisher: &Publisher<AnkleTargets>,
    targets: &[AnkleTargets],
    k: &mut usize,
    rate_hz: f64,
    n: usize,
    clock: StampClock,
) -> anyhow::Result<(Vec<i64>, Duration)> {
    let period = Duration::from_secs_f64(1.0 / rate_hz);
    let start = Instant::now();
    let mut stamps = Vec::with_capacity(n);
    let mut last = i64::MIN;
    for i in 0..n {
        let due = start + period.mul_f64(i as f64);
        let now = Instant::now();
        if due > now {
            std::thread::sleep(due - now);
        }
        let mut msg = targets[*k % targets.len()].clone();
        *k += 1;
        let stamp = clock.now_ns().max(last + 1);
        last = stamp;
        msg.header.stamp = Time::from_nanos(stamp);
        publisher
            .publish(msg)
            .map_err(|e| anyhow!("publish: {e:?}"))?;
        stamps.push(stamp);
    }
    Ok((stamps, start.elapsed()))
}

/// Drains arrivals until none came for `quiet`.
fn drain(rx: &mpsc::Receiver<Arrival>, quiet: Duration) {
    while rx.recv_timeout(quiet).is_ok() {}
}

#[allow(clippy::too_many_arguments)]
fn measure(
    relay: Relay,
    rate_hz: f64,
    n: usize,
    publisher: &Publisher<AnkleTargets>,
    targets: &[AnkleTargets],
    k: &mut usize,
    clock: StampClock,
    rx: &mpsc::Receiver<Arrival>,
    child: &mut Proc,
    joints: usize,
    dump: Option<&Path>,
) -> anyhow::Result<RunResult> {
    // Warm-up at the rate (half a second, at least 100 messages), not counted.
    let warmup = ((rate_hz * 0.5) as usize).max(100);
    send_at_rate(publisher, targets, k, rate_hz, warmup, clock)?;
    drain(rx, Duration::from_millis(300));

    let sampler = OthersSampler::start(child.pid());
    let cpu0 = child.cpu_time();
    let own0 = proc_cpu_time("self");
    let busy0 = machine_cpu().map(|m| m.busy);
    let t0 = Instant::now();
    let (stamps, send_time) = send_at_rate(publisher, targets, k, rate_hz, n, clock)?;
    // Every command back, or 2 s after the last send.
    let mut arrived: HashMap<i64, Arrival> = HashMap::with_capacity(n);
    let sent: std::collections::HashSet<i64> = stamps.iter().copied().collect();
    let mut duplicates = 0;
    let mut wrong_size = 0;
    let deadline = Instant::now() + Duration::from_secs(2);
    while arrived.len() < n {
        let left = deadline.saturating_duration_since(Instant::now());
        let Ok(a) = rx.recv_timeout(left) else { break };
        if !sent.contains(&a.stamp_ns) {
            continue;
        }
        if a.positions != joints {
            wrong_size += 1;
        }
        if arrived.insert(a.stamp_ns, a).is_some() {
            duplicates += 1;
        }
    }
    let wall = t0.elapsed();
    let others_peak = sampler.finish();
    let cpu1 = child.cpu_time();
    let pct = |d: Duration| 100.0 * d.as_secs_f64() / wall.as_secs_f64();
    let cpu = match (cpu0, cpu1) {
        (Some(a), Some(b)) => Some(pct(b - a)),
        _ => None,
    };
    // Everything the machine ran minus this process and the relay.
    let others = match (
        busy0,
        machine_cpu().map(|m| m.busy),
        own0,
        proc_cpu_time("self"),
        cpu0,
        cpu1,
    ) {
        (Some(b0), Some(b1), Some(o0), Some(o1), Some(c0), Some(c1)) => {
            let ours = (o1 - o0) + (c1 - c0);
            Some(pct((b1 - b0).saturating_sub(ours)))
        }
        _ => None,
    };
    if child.exited() {
        bail!("the relay exited during the {rate_hz} Hz run");
    }
    if let Some(dir) = dump {
        // In the order sent; a lost message's latency is empty.
        let mut csv = String::from("message,stamp_ns,latency_us\n");
        for (i, stamp) in stamps.iter().enumerate() {
            let _ = write!(csv, "{i},{stamp},");
            if let Some(a) = arrived.get(stamp) {
                let _ = write!(csv, "{:.3}", (a.arrived_ns - a.stamp_ns) as f64 / 1e3);
            }
            csv.push('\n');
        }
        let path = dir.join(format!("{}-{rate_hz}hz.csv", relay.name()));
        std::fs::write(&path, csv).with_context(|| format!("writing {}", path.display()))?;
    }
    let mut lat: Vec<f64> = arrived
        .values()
        .map(|a| (a.arrived_ns - a.stamp_ns) as f64 / 1e3)
        .collect();
    lat.sort_by(f64::total_cmp);
    let pct = |p: f64| common::percentile(&lat, p);
    let median = pct(0.5);
    let over_twice_median = lat.iter().filter(|&&l| l > 2.0 * median).count();
    Ok(RunResult {
        relay,
        rate_hz,
        sent: n,
        lost: n - arrived.len(),
        duplicates,
        wrong_size,
        median_us: median,
        over_twice_median,
        p99_us: pct(0.99),
        max_us: lat.last().copied().unwrap_or(f64::NAN),
        achieved_hz: n as f64 / send_time.as_secs_f64(),
        relay_cpu_pct: cpu,
        others_cpu_pct: others,
        others_peak_pct: others_peak,
    })
}

fn table(results: &[RunResult]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| relay | rate | messages | median | p99 | over 2 × median | max | lost | relay CPU | other processes' CPU, mean / peak |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for r in results {
        let mut lost = r.lost.to_string();
        if r.duplicates > 0 {
            let _ = write!(lost, " ({} duplicated)", r.duplicates);
        }
        if r.wrong_size > 0 {
            let _ = write!(lost, " ({} with a wrong joint count)", r.wrong_size);
        }
        let _ = writeln!(
            s,
            "| {} | {} Hz | {} | {:.3} ms | {:.3} ms | {:.1} % | {:.3} ms | {} | {} | {} |",
            r.relay.label(),
            r.rate_hz,
            r.sent,
            r.median_us / 1e3,
            r.p99_us / 1e3,
            100.0 * r.over_twice_median as f64 / (r.sent - r.lost).max(1) as f64,
            r.max_us / 1e3,
            lost,
            r.relay_cpu_pct
                .map(|c| format!("{c:.0} %"))
                .unwrap_or_else(|| "?".into()),
            match (r.others_cpu_pct, r.others_peak_pct) {
                (Some(m), Some(p)) => format!("{m:.0} % / {p:.0} %"),
                (Some(m), None) => format!("{m:.0} %"),
                _ => "?".into(),
            },
        );
    }
    s
}

/// `text` as lines of at most `width` characters (words are not split).
fn wrap(text: &str, width: usize) -> String {
    let mut out = String::new();
    let mut line = String::new();
    for word in text.split_whitespace() {
        if !line.is_empty() && line.chars().count() + 1 + word.chars().count() > width {
            out.push_str(&line);
            out.push('\n');
            line.clear();
        }
        if !line.is_empty() {
            line.push(' ');
        }
        line.push_str(word);
    }
    out.push_str(&line);
    out.push('\n');
    out
}

fn section(opts: &Opts, root: &Path, results: &[RunResult], versions: &[String]) -> String {
    let paragraphs = [
        "From a gait tick to its joint command arriving at the joint bridge: two DDS hops, \
         `/gait/ankle_targets` (biped_msgs/msg/AnkleTargets) → IK → `/joint_commands` \
         (sensor_msgs/msg/JointState). The bench process (`benches/pipeline.rs`) plays both \
         ends on one ros2-client node: it publishes the ankle targets of a planned 6-step walk \
         at the rate, with the send time in `header.stamp`, and subscribes to the joint \
         commands, whose stamp the relay copies. Latency = arrival in the subscriber (after \
         deserialisation) − stamp, on one clock; lost = sent − received, by stamp. \"At the \
         joint bridge\" means in its DDS reader: the `joint_bridge` node ticks at each command \
         as it comes (`tick_on_command`; with it false, at its own control tick, up to one \
         period later: `cargo bench --bench bridge_tick`)."
            .to_owned(),
        "In the middle, either the real `ik_solver` node (release build) or an rclpy relay \
         (`benches/pipeline_relay.py`: the same topics and QoS, copies the header, the 10 leg \
         joint names with as many positions, no IK; the closed-form IK of both legs takes \
         about 0.3 µs, see above), so only the relay differs. The relay's QoS is the fleet's, \
         reliable, volatile, keep last 10, as is the publisher's; the measuring subscriber \
         keeps up to 1000 so that a stall of the bench itself cannot count as a loss."
            .to_owned(),
        format!(
            "Every DDS participant runs in one private network namespace with only loopback \
             (`unshare -n`), ROS_DOMAIN_ID={DOMAIN_ID}, ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST. \
             After discovery (the first round trip) and a warm-up (1 s at 100 Hz, 0.5 s at \
             1 kHz, not counted): {} messages at 100 Hz, {} at 1 kHz. Relay CPU: the relay \
             process's user + system time during the run over the run's wall time (100 % = one \
             core). Other processes' CPU: what the rest of the machine used meanwhile (user + \
             system time of all processes minus the bench's and the relay's), on average over \
             the run and in its busiest 0.5 s: it shows a run disturbed by, say, a compile next \
             door (the machine is shared). `--wait-idle` waits for a quiet machine before each \
             run and repeats a disturbed one (over 20 % of a core on average or half a core at \
             peak), up to three times, keeping the least disturbed.",
            opts.n_100hz, opts.n_1khz
        ),
    ];
    let mut s = String::new();
    let _ = writeln!(s, "{SECTION}\n");
    for p in &paragraphs {
        s.push_str(&wrap(p, 95));
        s.push('\n');
    }
    let _ = writeln!(s, "Rerun (as root; about 2 min on a quiet machine):\n");
    let _ = writeln!(s, "```sh");
    let _ = writeln!(s, "cargo build --release --workspace");
    let _ = writeln!(s, "cargo bench --bench pipeline -- --wait-idle --write");
    let _ = writeln!(s, "```\n");
    let bound = match &opts.cpus {
        None => String::new(),
        Some(cpus) => format!(
            "; the bench and the relay bound to CPU {cpus:?} (`--cpu-affinity`; the ik_solver \
             by its `cpu_affinity` parameter, the rclpy relay by inheriting the bench's)"
        ),
    };
    let latency = match opts.latency_us {
        None => String::new(),
        Some(us) => format!(
            "; a CPU latency request of {us} µs held (`--cpu-dma-latency-us`: the bench holds \
             it, the ik_solver by its `cpu_dma_latency_us` parameter)"
        ),
    };
    let realtime = match opts.priority {
        None => String::new(),
        Some(p) => format!(
            "; every thread of the bench and of the relay under SCHED_FIFO at priority {p} \
             (`--thread-priority`: the ik_solver by its `thread_priority` parameter, the rclpy \
             relay by inheriting the bench's)"
        ),
    };
    let in_reader = if opts.in_reader {
        "; each command time-stamped in the bench's DDS reader, on the thread that received \
         it (`--in-reader`: where a hardware `joint_bridge` with `tick_on_command` false takes \
         it at its tick), not after \
         a thread of the bench woke for it"
    } else {
        ""
    };
    let on_receive = if opts.solve_on_receive {
        "; the ik_solver solving on the DDS thread that receives each message (its \
         `solve_on_receive` parameter's default)"
    } else {
        "; the ik_solver solving on its own thread, woken by the DDS thread that receives \
         each message (`--solve-on-node-thread`: its `solve_on_receive` false)"
    };
    let measured = format!(
        "Measured {} on {}; release build{bound}{latency}{realtime}{on_receive}{in_reader}; ros2-client {}, RustDDS {}{}.",
        common::today(),
        machine(),
        lock_version(root, "ros2-client"),
        lock_version(root, "rustdds"),
        versions
            .iter()
            .filter(|v| !v.is_empty())
            .map(|v| format!("; {v}"))
            .collect::<String>()
    );
    s.push_str(&wrap(&measured, 95));
    s.push('\n');
    s.push_str(&table(results));
    let slow: Vec<String> = results
        .iter()
        .filter(|r| r.achieved_hz < 0.98 * r.rate_hz)
        .map(|r| {
            format!(
                "{} at {} Hz sent at {:.0} Hz only",
                r.relay.name(),
                r.rate_hz,
                r.achieved_hz
            )
        })
        .collect();
    if !slow.is_empty() {
        let _ = writeln!(s, "\nThe sender fell behind: {}.", slow.join("; "));
    }
    s
}

/// Replaces this benchmark's section of `path` (from its heading to the next heading of
/// level 1 or 2), or appends it; other sections are kept. Creates the file if absent.
fn write_section(path: &Path, section: &str) -> anyhow::Result<()> {
    let old = std::fs::read_to_string(path).unwrap_or_default();
    let new = if old.trim().is_empty() {
        format!("# Benchmarks\n\n{section}")
    } else {
        let lines: Vec<&str> = old.split_inclusive('\n').collect();
        match lines.iter().position(|l| l.trim_end() == SECTION) {
            Some(start) => {
                let end = lines[start + 1..]
                    .iter()
                    .position(|l| l.starts_with("## ") || l.starts_with("# "))
                    .map(|i| start + 1 + i)
                    .unwrap_or(lines.len());
                let mut out: String = lines[..start].concat();
                out.push_str(section);
                if end < lines.len() {
                    out.push('\n');
                    out.push_str(&lines[end..].concat());
                }
                out
            }
            None => format!("{}\n\n{section}", old.trim_end()),
        }
    };
    std::fs::write(path, new).with_context(|| format!("writing {}", path.display()))
}
