//! Replay timing: how far from its recorded time each message of a replayed bag arrives at
//! a subscriber, for `biped replay` and for a straightforward Python replayer.
//!
//! The bags (rosbag2, MCAP, written by `rosbags` through `tests/python/bag_make.py`): one
//! sensor_msgs/msg/JointState stream of 12 joints (names, positions, velocities, efforts),
//! recorded QoS reliable, volatile, keep last 10, every message's `header.stamp` equal to its
//! recorded time: 100 Hz for 10 s (1000 messages) and 1 kHz for 5 s (5000 messages).
//!
//! Each bag is played by
//! - `biped replay` (the `biped` binary beside this executable: `target/release/biped`,
//!   built by `cargo bench` with the bench), and by
//! - the comparison, `tests/python/bag_bench.py play`: rosbags' Reader + an rclpy publisher
//!   of the recorded CDR bytes, `time.sleep` until each message's due time: the
//!   `ros2 bag play`-like baseline one can build without rosbag2 (not on PyPI),
//!
//! into an rclpy subscriber (`tests/python/bag_bench.py receive`, Fast DDS) that keeps, per
//! message, Fast DDS's reception time stamp. Timing error = |arrival − recorded − offset|,
//! offset = the median of arrival − recorded over the run (the shift between the bag's times
//! and the play's, plus the typical transport delay); lost = messages of the bag that never
//! arrived.
//! Both replayers wait until the subscriber has matched, then `--delay` (1 s: the subscriber
//! is Fast DDS, which answers a new participant at once; `biped replay`'s default 5 s is for
//! our RustDDS nodes), then play.
//!
//! Also per run: the replayer's own worst lateness (how late it published a message after its
//! due time, as it reports it), its CPU (user + system, over the time messages arrived; 100 % =
//! one core) and what other processes used meanwhile (the machine's busy time, elapsed × CPUs
//! − idle, minus the replayer's, the receiver's and this process's CPU time; interrupts are
//! in it, mostly our own loopback traffic): a run disturbed by, say, a compile next door
//! shows there.
//!
//! Nothing leaves the machine: the process re-executes itself inside a private network
//! namespace with only loopback (`unshare -n`, root), ROS_DOMAIN_ID=81,
//! ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, and refuses to run if it sees another interface.
//!
//! ```sh
//! cargo bench --bench bag_replay      # under a minute; prints a Markdown table
//! ```
//!
//! Options: `--only biped|python`, `--delay S` (1), `--deserialize` (the Python replayer
//! deserializes the messages beforehand and publishes rclpy messages instead of bytes),
//! `--keep` (keep the bags, the logs and each run's arrivals, `[stamp, received, source]` in
//! ns, in the scratch folder it names).
//! A benchmark, not a test: it is not part of `cargo test` or `scripts/test`.

mod common;

use std::collections::HashSet;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use anyhow::{Context as _, anyhow, bail};
use common::{
    Proc, bin_dir, check_only_loopback, lock_version, machine, machine_cpu, proc_cpu_time,
    warn_if_stale,
};
use serde_json::{Value, json};

/// Set in the re-executed process, inside the private network namespace.
/// Our own DDS domain (the namespace is private anyway).
const DOMAIN_ID: &str = "81";
const TOPIC: &str = "/joint_states";
const JOINTS: [&str; 12] = [
    "l_hip_yaw",
    "l_hip_roll",
    "l_hip_pitch",
    "l_knee",
    "l_ankle_pitch",
    "l_ankle_roll",
    "r_hip_yaw",
    "r_hip_roll",
    "r_hip_pitch",
    "r_knee",
    "r_ankle_pitch",
    "r_ankle_roll",
];
/// The bags' first recorded time (any value: only the spacing matters).
const T0_NS: i64 = 1_700_000_000_000_000_000;
/// The streams: rate (Hz) and length (s).
const STREAMS: [(u32, u32); 2] = [(100, 10), (1000, 5)];

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("bag_replay bench: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Replayer {
    Biped,
    Python,
}

impl Replayer {
    fn name(self) -> &'static str {
        match self {
            Replayer::Biped => "biped",
            Replayer::Python => "python",
        }
    }
    fn label(self, deserialize: bool) -> &'static str {
        match (self, deserialize) {
            (Replayer::Biped, _) => "`biped replay` (Rust, RustDDS)",
            (Replayer::Python, false) => "Python: rosbags + rclpy, CDR bytes (Fast DDS)",
            (Replayer::Python, true) => "Python: rosbags + rclpy, messages (Fast DDS)",
        }
    }
}

#[derive(Debug)]
struct Opts {
    replayers: Vec<Replayer>,
    delay_s: f64,
    deserialize: bool,
    keep: bool,
}

impl Opts {
    fn parse(args: impl IntoIterator<Item = String>) -> anyhow::Result<Self> {
        let mut o = Opts {
            replayers: vec![Replayer::Biped, Replayer::Python],
            delay_s: 1.0,
            deserialize: false,
            keep: false,
        };
        let mut it = args.into_iter();
        while let Some(a) = it.next() {
            let mut value = || it.next().ok_or_else(|| anyhow!("{a} needs a value"));
            match a.as_str() {
                // `cargo bench` passes --bench to harness-less benches.
                "--bench" => {}
                "--deserialize" => o.deserialize = true,
                "--keep" => o.keep = true,
                "--delay" => {
                    o.delay_s = value()?.parse().context("--delay")?;
                    if !(0.0..=60.0).contains(&o.delay_s) {
                        bail!("--delay {}: expected 0 to 60 s", o.delay_s);
                    }
                }
                "--only" => {
                    o.replayers = match value()?.as_str() {
                        "biped" => vec![Replayer::Biped],
                        "python" => vec![Replayer::Python],
                        other => bail!("--only {other}: expected biped or python"),
                    }
                }
                other => bail!(
                    "unknown argument `{other}` (options: --only biped|python, --delay S, --deserialize, --keep)"
                ),
            }
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

    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let biped = bin_dir()?.join("biped");
    if !biped.is_file() {
        bail!(
            "{} not built: run `cargo build --release` first",
            biped.display()
        );
    }
    warn_if_stale(&biped, &root, &["src", "msgs/src"], "cargo build --release");
    let python = std::env::var_os("BIPED_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join(".venv/bin/biped-python"));
    if !python.exists() {
        bail!(
            "no rclpy at {}: run scripts/setup-python-env",
            python.display()
        );
    }
    let scratch =
        std::env::temp_dir().join(format!("biped-bench-bag-replay-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&scratch);
    std::fs::create_dir_all(&scratch)?;

    let tools = Tools {
        root: root.clone(),
        python,
        biped,
        scratch: scratch.clone(),
    };
    let outcome = (|| -> anyhow::Result<(Vec<RunResult>, String)> {
        let mut results = Vec::new();
        let mut versions = String::new();
        for (rate_hz, seconds) in STREAMS {
            let n = (rate_hz * seconds) as usize;
            let bag = make_bag(&tools, rate_hz, n)?;
            for &replayer in &opts.replayers {
                let (r, v) = run_one(&tools, &opts, replayer, &bag, rate_hz, seconds, n)?;
                eprintln!(
                    "[{}] {rate_hz} Hz: median {:.3} ms, p99 {:.3} ms, max {:.3} ms, lost {}/{n}, \
                     sent at most {:.3} ms late; replayer CPU {}, other processes {}",
                    replayer.name(),
                    r.median_ms,
                    r.p99_ms,
                    r.max_ms,
                    r.lost,
                    r.sent_late_ms.unwrap_or(f64::NAN),
                    pct(r.replayer_cpu),
                    pct(r.others_cpu),
                );
                results.push(r);
                versions = v;
            }
        }
        Ok((results, versions))
    })();
    if opts.keep {
        eprintln!("kept the bags, logs and arrivals in {}", scratch.display());
    } else {
        let _ = std::fs::remove_dir_all(&scratch);
    }
    let (results, versions) = outcome?;

    println!(
        "\n{}; release build; ros2-client {}, RustDDS {}; {versions}; --delay {} s.\n",
        machine(),
        lock_version(&root, "ros2-client"),
        lock_version(&root, "rustdds"),
        opts.delay_s
    );
    println!("{}", table(&results, opts.deserialize));
    Ok(())
}

/// Where things are.
#[derive(Debug)]
struct Tools {
    root: PathBuf,
    python: PathBuf,
    biped: PathBuf,
    scratch: PathBuf,
}

impl Tools {
    fn script(&self, name: &str) -> PathBuf {
        self.root.join("tests/python").join(name)
    }
}

/// The bag of one stream: `n` JointState messages at `rate_hz`, written by rosbags.
fn make_bag(tools: &Tools, rate_hz: u32, n: usize) -> anyhow::Result<PathBuf> {
    let period_ns = 1_000_000_000 / i64::from(rate_hz);
    let messages: Vec<Value> = (0..n as i64)
        .map(|i| {
            let t = T0_NS + i * period_ns;
            let s = i as f64 * period_ns as f64 * 1e-9;
            let phase = |j: usize| std::f64::consts::TAU * 0.5 * s + j as f64;
            let position: Vec<f64> = (0..JOINTS.len()).map(|j| 0.3 * phase(j).sin()).collect();
            let velocity: Vec<f64> = (0..JOINTS.len())
                .map(|j| 0.3 * std::f64::consts::PI * phase(j).cos())
                .collect();
            let effort: Vec<f64> = (0..JOINTS.len()).map(|j| 0.1 * phase(j).sin()).collect();
            json!({"topic": TOPIC, "t_ns": t, "msg": {
                "header": {"stamp": {"sec": t / 1_000_000_000, "nanosec": t % 1_000_000_000},
                           "frame_id": "base_link"},
                "name": JOINTS, "position": position, "velocity": velocity, "effort": effort}})
        })
        .collect();
    let spec = json!({
        "topics": [{"name": TOPIC, "type": "sensor_msgs/msg/JointState",
                    "qos": {"reliability": "reliable", "durability": "volatile",
                            "history": "keep_last", "depth": 10}}],
        "messages": messages,
    });
    let spec_path = tools.scratch.join(format!("spec_{rate_hz}hz.json"));
    std::fs::write(&spec_path, spec.to_string())?;
    let bag = tools.scratch.join(format!("joint_states_{rate_hz}hz"));
    let out = Command::new(&tools.python)
        .arg(tools.script("bag_make.py"))
        .arg(&bag)
        .args(["--storage", "mcap", "--topic-type-hash", "--spec"])
        .arg(&spec_path)
        .output()
        .context("running bag_make.py")?;
    if !out.status.success() {
        bail!("bag_make.py: {}", String::from_utf8_lossy(&out.stderr));
    }
    Ok(bag)
}

fn wall_ns() -> i64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as i64)
}

/// CPU times at one instant (system clock, ns): the machine, the replayer, the receiver, us.
#[derive(Debug, Clone, Copy)]
struct Sample {
    wall_ns: i64,
    /// The machine's idle time and CPU count.
    idle: (Duration, u32),
    replayer: Duration,
    receiver: Duration,
    own: Duration,
}

/// Samples CPU times every 100 ms until stopped.
fn sampler(
    replayer: u32,
    receiver: u32,
    stop: Arc<AtomicBool>,
) -> std::thread::JoinHandle<Vec<Sample>> {
    std::thread::spawn(move || {
        let (rp, rc) = (replayer.to_string(), receiver.to_string());
        let mut samples = Vec::new();
        while !stop.load(Ordering::SeqCst) {
            let t = wall_ns();
            if let (Some(idle), Some(replayer), Some(receiver), Some(own)) = (
                machine_cpu().map(|m| (m.idle, m.cpus)),
                proc_cpu_time(&rp),
                proc_cpu_time(&rc),
                proc_cpu_time("self"),
            ) {
                samples.push(Sample {
                    wall_ns: t,
                    idle,
                    replayer,
                    receiver,
                    own,
                });
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        samples
    })
}

/// The replayer's and the other processes' CPU (% of a core) between the first and the last
/// sample inside [from_ns, to_ns].
fn cpu_over(samples: &[Sample], from_ns: i64, to_ns: i64) -> (Option<f64>, Option<f64>) {
    let inside: Vec<&Sample> = samples
        .iter()
        .filter(|s| (from_ns..=to_ns).contains(&s.wall_ns))
        .collect();
    let (Some(a), Some(b)) = (inside.first(), inside.last()) else {
        return (None, None);
    };
    let dt = (b.wall_ns - a.wall_ns) as f64 * 1e-9;
    if dt < 0.5 {
        return (None, None);
    }
    let replayer = b.replayer.saturating_sub(a.replayer);
    let ours = replayer + b.receiver.saturating_sub(a.receiver) + b.own.saturating_sub(a.own);
    let busy = Duration::from_secs_f64(dt * f64::from(b.idle.1))
        .saturating_sub(b.idle.0.saturating_sub(a.idle.0));
    let others = busy.saturating_sub(ours);
    (
        Some(100.0 * replayer.as_secs_f64() / dt),
        Some(100.0 * others.as_secs_f64() / dt),
    )
}

#[derive(Debug, Clone)]
struct RunResult {
    replayer: Replayer,
    rate_hz: u32,
    messages: usize,
    lost: usize,
    duplicates: usize,
    median_ms: f64,
    p99_ms: f64,
    max_ms: f64,
    sent_late_ms: Option<f64>,
    replayer_cpu: Option<f64>,
    others_cpu: Option<f64>,
}

/// One replay of one bag into a fresh receiver. Returns the result and the receiver's
/// versions line.
fn run_one(
    tools: &Tools,
    opts: &Opts,
    replayer: Replayer,
    bag: &Path,
    rate_hz: u32,
    seconds: u32,
    n: usize,
) -> anyhow::Result<(RunResult, String)> {
    let tag = format!("{}-{rate_hz}hz", replayer.name());
    let limit = Duration::from_secs(u64::from(seconds) + 60);
    let mut receiver = Proc::spawn(
        Command::new(&tools.python)
            .arg(tools.script("bag_bench.py"))
            .args(["receive", TOPIC, &n.to_string(), "--timeout"])
            .arg((limit.as_secs() + 30).to_string()),
        &format!("receiver-{tag}"),
        &tools.scratch,
    )?;
    let lines = receiver.lines();
    let ready: Value = lines
        .recv_timeout(Duration::from_secs(30))
        .ok()
        .and_then(|l| serde_json::from_str(&l).ok())
        .ok_or_else(|| anyhow!("the receiver did not start; {}", receiver.stderr_tail()))?;
    let versions = ready["versions"].as_str().unwrap_or("?").to_owned();

    let delay = opts.delay_s.to_string();
    let mut cmd = match replayer {
        Replayer::Biped => {
            let mut c = Command::new(&tools.biped);
            c.arg("replay").arg(bag);
            c
        }
        Replayer::Python => {
            let mut c = Command::new(&tools.python);
            c.arg(tools.script("bag_bench.py")).arg("play").arg(bag);
            if opts.deserialize {
                c.arg("--deserialize");
            }
            c
        }
    };
    cmd.args(["--wait-for-subscribers", "10", "--delay", &delay]);
    let mut player = Proc::spawn(&mut cmd, &format!("replayer-{tag}"), &tools.scratch)?;
    let player_out = player.lines();
    let stop = Arc::new(AtomicBool::new(false));
    let sampling = sampler(player.pid(), receiver.pid(), stop.clone());
    let status = player.wait(limit);
    stop.store(true, Ordering::SeqCst);
    let samples = sampling.join().unwrap_or_default();
    let Some(status) = status else {
        bail!(
            "the replayer did not finish within {} s; {}",
            limit.as_secs(),
            player.stderr_tail()
        );
    };
    if !status.success() {
        bail!("the replayer failed ({status}); {}", player.stderr_tail());
    }
    let player_stdout: Vec<String> = player_out.try_iter().collect();
    let sent_late_ms = sent_late_ms(replayer, &player_stdout);

    // The receiver ends by itself once it has every message; give it a moment, then Ctrl-C.
    if receiver.wait(Duration::from_secs(3)).is_none() {
        receiver.interrupt();
    }
    let arrivals: Value = std::iter::from_fn(|| lines.recv_timeout(Duration::from_secs(5)).ok())
        .filter_map(|l| serde_json::from_str::<Value>(&l).ok())
        .find(|v| v.get("arrivals").is_some())
        .ok_or_else(|| anyhow!("no arrivals from the receiver; {}", receiver.stderr_tail()))?;
    if opts.keep {
        std::fs::write(
            tools.scratch.join(format!("arrivals-{tag}.json")),
            arrivals.to_string(),
        )?;
    }
    let arrivals: Vec<(i64, i64)> = arrivals["arrivals"]
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(|x| Some((x[0].as_i64()?, x[1].as_i64()?)))
                .collect()
        })
        .unwrap_or_default();

    let period_ns = 1_000_000_000 / i64::from(rate_hz);
    let recorded: HashSet<i64> = (0..n as i64).map(|i| T0_NS + i * period_ns).collect();
    let mut seen = HashSet::new();
    let mut duplicates = 0;
    let mut deltas = Vec::with_capacity(n);
    for &(stamp, received) in &arrivals {
        if !recorded.contains(&stamp) {
            bail!("a message with a stamp not in the bag arrived: {stamp}");
        }
        if !seen.insert(stamp) {
            duplicates += 1;
            continue;
        }
        deltas.push(received - stamp);
    }
    if deltas.is_empty() {
        bail!("no message arrived; {}", player.stderr_tail());
    }
    let errors = timing_errors_ms(&deltas);
    let first = arrivals.iter().map(|a| a.1).min().unwrap_or(0);
    let last = arrivals.iter().map(|a| a.1).max().unwrap_or(0);
    let (replayer_cpu, others_cpu) = cpu_over(&samples, first, last);
    Ok((
        RunResult {
            replayer,
            rate_hz,
            messages: n,
            lost: n - seen.len(),
            duplicates,
            median_ms: common::percentile(&errors, 0.5),
            p99_ms: common::percentile(&errors, 0.99),
            max_ms: errors.last().copied().unwrap_or(f64::NAN),
            sent_late_ms,
            replayer_cpu,
            others_cpu,
        },
        versions,
    ))
}

/// The replayer's own report of its worst lateness (ms).
fn sent_late_ms(replayer: Replayer, stdout: &[String]) -> Option<f64> {
    match replayer {
        // "replayed N messages from DIR in T s (1 pass), 0 skipped, at most X ms late"
        Replayer::Biped => stdout.iter().find_map(|l| {
            let (_, rest) = l.split_once(", at most ")?;
            rest.strip_suffix(" ms late")?.parse().ok()
        }),
        Replayer::Python => stdout
            .iter()
            .find_map(|l| serde_json::from_str::<Value>(l).ok()?["max_late_ms"].as_f64()),
    }
}

/// |arrival − recorded − offset| (ms), offset = the median of arrival − recorded; sorted.
fn timing_errors_ms(deltas_ns: &[i64]) -> Vec<f64> {
    let mut d = deltas_ns.to_vec();
    d.sort_unstable();
    let offset = d[d.len() / 2];
    let mut e: Vec<f64> = d.iter().map(|x| (x - offset).abs() as f64 * 1e-6).collect();
    e.sort_by(f64::total_cmp);
    e
}

fn pct(v: Option<f64>) -> String {
    v.map_or_else(|| "?".into(), |c| format!("{c:.0} %"))
}

fn table(results: &[RunResult], deserialize: bool) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| replayer | stream | median | p99 | max | lost | sent late, max | replayer CPU | other processes' CPU |"
    );
    let _ = writeln!(s, "|---|---|---:|---:|---:|---:|---:|---:|---:|");
    for r in results {
        let mut lost = r.lost.to_string();
        if r.duplicates > 0 {
            let _ = write!(lost, " ({} duplicated)", r.duplicates);
        }
        let _ = writeln!(
            s,
            "| {} | {} Hz × {} | {:.3} ms | {:.3} ms | {:.3} ms | {} | {} | {} | {} |",
            r.replayer.label(deserialize),
            r.rate_hz,
            r.messages,
            r.median_ms,
            r.p99_ms,
            r.max_ms,
            lost,
            r.sent_late_ms
                .map_or_else(|| "?".into(), |x| format!("{x:.3} ms")),
            pct(r.replayer_cpu),
            pct(r.others_cpu),
        );
    }
    s
}
