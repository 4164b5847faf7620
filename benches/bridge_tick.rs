//! From a joint command to the joint bridge's tick that acts on it, on the monotonic clock
//! (a real robot's case): the `joint_bridge` node (mock backend, 100 Hz) fed joint commands
//! at 100 Hz on a drift-free schedule of the bench's own, as a planner would send them, with
//! `tick_on_command` true (each command ticks the bridge as it comes) and false (the bridge
//! ticks at its own rate and takes what came), three launches of each, alternated: each
//! launch puts the bridge's own timer at another phase to the sender's.
//!
//! Latency = the bench taking the first `joint_states` after a command − the command's send
//! time, one clock (two DDS hops and the bridge's tick, plus whatever the command waited in
//! the bridge's reader for a tick). Per command period (from one send to the next): how many
//! `joint_states` came, that is bridge ticks: one each is a step of the joints per planner
//! tick; none, then two, is a step skipped, then doubled.
//!
//! ```sh
//! cargo build --release --workspace
//! cargo bench --bench bridge_tick              # prints a Markdown table
//! cargo bench --bench bridge_tick -- --n 2000  # commands per launch (default 1000)
//! cargo bench --bench bridge_tick -- --sender-hz 50  # commands at another rate than the bridge's
//! ```
//!
//! Nothing leaves the machine: the process re-executes itself in a private network namespace
//! with only loopback (`unshare -n`, root), ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::path::PathBuf;
use std::process::{Command, ExitCode};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, mpsc};
use std::time::{Duration, Instant};

use anyhow::{Context as _, anyhow, bail};
use biped_msgs::RosMessage as _;
use biped_msgs::msg::{Header, JointState};
use node_runtime::RosArgs;
use ros2_client::qos::History;
use ros2_client::{NodeName, NodeOptions};

/// Our own DDS domain (the namespace is private anyway).
const DOMAIN_ID: &str = "94";
/// The bridge's rate, and the sender's unless `--sender-hz` says otherwise.
const RATE_HZ: f64 = 100.0;
/// Launches of each setting.
const LAUNCHES: usize = 3;

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("bridge_tick bench: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// One launch's figures.
struct Launch {
    on_command: bool,
    /// Command → next joint_states (ms), sorted.
    latency_ms: Vec<f64>,
    /// Command periods with no, one, and two or more bridge ticks.
    ticks: [usize; 3],
    /// Intervals between consecutive bridge ticks (ms), sorted.
    tick_interval_ms: Vec<f64>,
}

fn run() -> anyhow::Result<()> {
    let (n, sender_hz) = parse_args()?;
    if !common::in_netns() {
        return common::reexec_in_netns(DOMAIN_ID);
    }
    common::check_only_loopback()?;
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let exe = common::bin_dir()?.join("joint_bridge");
    if !exe.is_file() {
        bail!(
            "node binary {} not built: run `cargo build --release --workspace` first",
            exe.display()
        );
    }
    common::warn_if_stale(
        &exe,
        &root,
        &["joint_bridge/src", "node_runtime/src"],
        "cargo build --release --workspace",
    );

    let dds = |what: &'static str| move |e: &dyn std::fmt::Debug| anyhow!("{what}: {e:?}");
    let context = node_runtime::context_from_env()?;
    let mut node = context
        .new_node(
            NodeName::new("/", "bridge_tick_bench").map_err(|e| dds("node name")(&e))?,
            NodeOptions::new().enable_rosout(false),
        )
        .map_err(|e| dds("node")(&e))?;
    let qos = node_runtime::qos::default();
    let none = RosArgs::default();
    let topic = |node: &mut ros2_client::Node, name: &str| {
        node.create_topic(
            &node_runtime::topic_name(&none, "/", name)?,
            JointState::message_type_name(),
            &qos,
        )
        .map_err(|e| dds("topic")(&e))
    };
    let commands = topic(&mut node, "/joint_commands")?;
    let states = topic(&mut node, "/joint_states")?;
    let publisher = node
        .create_publisher::<JointState>(&commands, None)
        .map_err(|e| dds("publisher")(&e))?;
    // Keeps up to 1000: a stall of this process must not lose a tick from the count.
    let subscription = node
        .create_subscription::<JointState>(
            &states,
            Some(qos.clone().history(History::KeepLast { depth: 1000 })),
        )
        .map_err(|e| dds("subscription")(&e))?;
    let spinner = node.spinner().map_err(|e| dds("spinner")(&e))?;
    std::thread::spawn(move || smol::block_on(spinner.spin()));

    // Each joint_states as it is taken: when (since `start`) and its joint names.
    let start = Instant::now();
    let stop = Arc::new(AtomicBool::new(false));
    let (tx, rx) = mpsc::channel::<(Duration, Vec<String>)>();
    let receiver = {
        let stop = stop.clone();
        std::thread::spawn(move || {
            node_runtime::wait::block_on(async {
                let mut bound = node_runtime::WaitBound::every(Duration::from_millis(100));
                while !stop.load(Ordering::SeqCst) {
                    if let Some(Ok((msg, _))) = bound.within(subscription.async_take()).await {
                        let _ = tx.send((start.elapsed(), msg.name));
                    }
                }
            })
        })
    };

    let scratch =
        std::env::temp_dir().join(format!("biped-bench-bridge-tick-{}", std::process::id()));
    std::fs::create_dir_all(&scratch).with_context(|| scratch.display().to_string())?;
    let mut launches = Vec::new();
    for _ in 0..LAUNCHES {
        for on_command in [true, false] {
            let mut bridge = start_bridge(&exe, on_command, &scratch)?;
            let r = measure(&publisher, &rx, start, n, sender_hz, on_command);
            bridge.interrupt();
            launches.push(r.with_context(|| {
                format!("tick_on_command {on_command}; {}", bridge.stderr_tail())
            })?);
        }
    }
    stop.store(true, Ordering::SeqCst);
    let _ = receiver.join();
    let _ = std::fs::remove_dir_all(&scratch);

    println!(
        "\nMeasured {} on {}; release build; `joint_bridge` (mock backend, rate_hz {RATE_HZ}), \
         {n} commands a launch at {sender_hz} Hz after 2 s of warm-up.\n",
        common::today(),
        common::machine(),
    );
    println!(
        "| `tick_on_command` | launch | command → joint_states: median | p90 | p99 | max | command periods with no tick / one / two or more | between ticks: p10 / p90 |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|");
    for (i, l) in launches.iter().enumerate() {
        let p = |q: f64| common::percentile(&l.latency_ms, q);
        println!(
            "| {} | {} | {:.3} ms | {:.3} ms | {:.3} ms | {:.3} ms | {} / {} / {} | {:.1} / {:.1} ms |",
            l.on_command,
            i / 2 + 1,
            p(0.5),
            p(0.9),
            p(0.99),
            l.latency_ms.last().copied().unwrap_or(f64::NAN),
            l.ticks[0],
            l.ticks[1],
            l.ticks[2],
            common::percentile(&l.tick_interval_ms, 0.1),
            common::percentile(&l.tick_interval_ms, 0.9),
        );
    }
    Ok(())
}

/// `--n N` (commands a launch, default 1000), `--sender-hz HZ` (default the bridge's rate).
fn parse_args() -> anyhow::Result<(usize, f64)> {
    let (mut n, mut sender_hz) = (1000, RATE_HZ);
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().ok_or_else(|| anyhow!("{a} needs a value"));
        match a.as_str() {
            "--bench" => {}
            "--n" => n = common::positive_count(&a, &value()?)?,
            "--sender-hz" => {
                let v = value()?;
                sender_hz = v
                    .parse()
                    .ok()
                    .filter(|&hz: &f64| (1.0..=1000.0).contains(&hz))
                    .ok_or_else(|| anyhow!("--sender-hz `{v}` is not a rate from 1 to 1000 Hz"))?;
            }
            other => bail!("unknown argument `{other}` (options: --n N, --sender-hz HZ)"),
        }
    }
    Ok((n, sender_hz))
}

/// Sends `n` commands at `sender_hz` (after 2 s of warm-up) and reads what the bridge answered.
fn measure(
    publisher: &ros2_client::Publisher<JointState>,
    rx: &mpsc::Receiver<(Duration, Vec<String>)>,
    start: Instant,
    n: usize,
    sender_hz: f64,
    on_command: bool,
) -> anyhow::Result<Launch> {
    // The bridge's joint_states name its joints: what a command must name.
    let names = loop {
        match rx.recv_timeout(Duration::from_secs(20)) {
            Ok((_, names)) if !names.is_empty() => break names,
            Ok(_) => {}
            Err(_) => bail!("no joint_states from the bridge within 20 s"),
        }
    };
    let period = Duration::from_secs_f64(1.0 / sender_hz);
    let warm_up = (2.0 * sender_hz) as usize;
    let t0 = Instant::now();
    let mut sent = Vec::with_capacity(n);
    for k in 0..warm_up + n {
        let due = t0 + period * k as u32;
        if let Some(wait) = due.checked_duration_since(Instant::now()) {
            std::thread::sleep(wait);
        }
        let msg = JointState {
            header: Header::default(),
            name: names.clone(),
            position: vec![0.0; names.len()],
            velocity: Vec::new(),
            effort: Vec::new(),
        };
        let at = start.elapsed();
        publisher
            .publish(msg)
            .map_err(|e| anyhow!("publish joint_commands: {e:?}"))?;
        if k >= warm_up {
            sent.push(at);
        }
    }
    std::thread::sleep(period * 5);
    let first = sent[0];
    let ticks: Vec<Duration> = rx
        .try_iter()
        .map(|(t, _)| t)
        .filter(|&t| t >= first)
        .collect();
    if ticks.len() < n / 2 {
        bail!(
            "{} joint_states for {n} commands: the bridge did not take them",
            ticks.len()
        );
    }
    let mut latency_ms = Vec::with_capacity(n);
    let mut per_period = [0usize; 3];
    for (k, &s) in sent.iter().enumerate() {
        let i = ticks.partition_point(|&t| t < s);
        if let Some(&t) = ticks.get(i) {
            latency_ms.push((t - s).as_secs_f64() * 1e3);
        }
        if let Some(&next) = sent.get(k + 1) {
            let j = ticks.partition_point(|&t| t < next);
            per_period[(j - i).min(2)] += 1;
        }
    }
    latency_ms.sort_by(f64::total_cmp);
    let mut tick_interval_ms: Vec<f64> = ticks
        .windows(2)
        .map(|w| (w[1] - w[0]).as_secs_f64() * 1e3)
        .collect();
    tick_interval_ms.sort_by(f64::total_cmp);
    Ok(Launch {
        on_command,
        latency_ms,
        ticks: per_period,
        tick_interval_ms,
    })
}

/// Starts the joint_bridge node (mock backend, at the rate) with `tick_on_command`.
fn start_bridge(
    exe: &std::path::Path,
    on_command: bool,
    scratch: &std::path::Path,
) -> anyhow::Result<common::Proc> {
    common::Proc::spawn(
        Command::new(exe)
            .args(["--ros-args", "-p", "backend:=mock"])
            .args(["-p", &format!("rate_hz:={RATE_HZ:?}")])
            .args(["-p", &format!("tick_on_command:={on_command}")]),
        &format!("joint_bridge-{on_command}"),
        scratch,
    )
}
