//! What the DDS bench binaries share: running inside a private network namespace (nothing
//! leaves the machine), finding the workspace's binaries, and reading /proc and Cargo.lock.
#![allow(dead_code)]

use std::io::{BufRead as _, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant, SystemTime};

use anyhow::{Context as _, anyhow, bail};

/// Set in the re-executed bench: it runs inside its network namespace.
pub const IN_NETNS: &str = "BIPED_BENCH_IN_NETNS";

/// Whether this process is the one inside the namespace.
pub fn in_netns() -> bool {
    std::env::var_os(IN_NETNS).is_some()
}

/// Runs this executable again, with the same arguments, in a new network namespace with only
/// loopback (multicast on), on `domain_id`, discovery restricted to this host.
pub fn reexec_in_netns(domain_id: &str) -> anyhow::Result<()> {
    let exe = std::env::current_exe().context("own executable")?;
    let status = Command::new("unshare")
        .args([
            "-n",
            "sh",
            "-c",
            "ip link set lo up && ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo && exec \"$0\" \"$@\"",
        ])
        .arg(&exe)
        .args(std::env::args_os().skip(1))
        .env(IN_NETNS, "1")
        .env("ROS_DOMAIN_ID", domain_id)
        .env("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        .env_remove("ROS_LOCALHOST_ONLY")
        .env_remove(node_runtime::LAUNCH_PARENT_ENV)
        .status()
        .context("unshare -n (root is needed for a private network namespace)")?;
    if !status.success() {
        bail!("the benchmark in its network namespace failed ({status})");
    }
    Ok(())
}

/// Refuses to run DDS where it could reach a real network: only `lo` may exist.
pub fn check_only_loopback() -> anyhow::Result<()> {
    let dev = std::fs::read_to_string("/proc/net/dev").context("/proc/net/dev")?;
    let others: Vec<&str> = dev
        .lines()
        .skip(2)
        .filter_map(|l| l.split(':').next().map(str::trim))
        .filter(|n| *n != "lo")
        .collect();
    if !others.is_empty() {
        bail!("network interfaces other than loopback are visible ({others:?}): not running");
    }
    Ok(())
}

/// The folder of the workspace's binaries: this executable's, without `deps/`.
pub fn bin_dir() -> anyhow::Result<PathBuf> {
    let exe = std::env::current_exe()?;
    let mut dir = exe
        .parent()
        .ok_or_else(|| anyhow!("executable without a folder"))?
        .to_path_buf();
    if dir.ends_with("deps") {
        dir.pop();
    }
    Ok(dir)
}

pub fn newest_mtime(dir: &Path) -> Option<SystemTime> {
    let mut newest = None;
    for e in std::fs::read_dir(dir).ok()?.flatten() {
        let p = e.path();
        let t = if p.is_dir() {
            newest_mtime(&p)
        } else {
            e.metadata().ok().and_then(|m| m.modified().ok())
        };
        newest = newest.max(t);
    }
    newest
}

/// CPU time (user + system, all threads) a process has used, from `/proc/PID/stat`.
pub fn proc_cpu_time(pid: &str) -> Option<Duration> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    let rest: Vec<&str> = stat.rsplit_once(") ")?.1.split_whitespace().collect();
    let ticks: u64 = rest.get(11)?.parse::<u64>().ok()? + rest.get(12)?.parse::<u64>().ok()?;
    // USER_HZ is 100 on Linux.
    Some(Duration::from_millis(ticks * 10))
}

/// Machine-wide CPU times since boot, from the first lines of `/proc/stat`.
pub struct MachineCpu {
    /// user + nice + system, over all CPUs. Interrupt and softirq time is left out: in our
    /// DDS benches it is mostly the bench's own loopback traffic.
    pub busy: Duration,
    /// idle + iowait, over all CPUs. The busy fields are sampled at the scheduler tick, which
    /// overstates work that wakes up with the timer (a 1 kHz stream showed 40 % of a core
    /// more than all processes together used); idle time is measured (tickless kernels), so
    /// for such loads busy = elapsed × CPUs − idle is the better figure.
    pub idle: Duration,
    /// The number of CPUs listed.
    pub cpus: u32,
}

pub fn machine_cpu() -> Option<MachineCpu> {
    let stat = std::fs::read_to_string("/proc/stat").ok()?;
    let mut lines = stat.lines();
    let cpu: Vec<u64> = lines
        .next()?
        .split_whitespace()
        .skip(1)
        .filter_map(|x| x.parse().ok())
        .collect();
    let cpus = lines
        .filter(|l| l.starts_with("cpu") && l.as_bytes().get(3).is_some_and(u8::is_ascii_digit))
        .count();
    // USER_HZ is 100 on Linux.
    let ticks = |t: u64| Duration::from_millis(t * 10);
    Some(MachineCpu {
        busy: ticks(cpu.first()? + cpu.get(1)? + cpu.get(2)?),
        idle: ticks(cpu.get(3)? + cpu.get(4)?),
        cpus: u32::try_from(cpus).ok()?,
    })
}

/// The machine for a benchmark table: CPU model, CPUs, memory, kernel.
pub fn machine() -> String {
    let cpus = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(0);
    let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let model = cpuinfo
        .lines()
        .find(|l| l.starts_with("model name"))
        .and_then(|l| l.split_once(':'))
        .map(|(_, m)| m.trim().to_owned())
        .unwrap_or_else(|| "?".into());
    let kernel = std::fs::read_to_string("/proc/sys/kernel/osrelease").unwrap_or_default();
    let mem_gib = std::fs::read_to_string("/proc/meminfo")
        .unwrap_or_default()
        .lines()
        .find(|l| l.starts_with("MemTotal:"))
        .and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
        .map(|kb| format!("{:.0} GiB", kb / 1024.0 / 1024.0))
        .unwrap_or_else(|| "?".into());
    format!(
        "{model}, {cpus} CPUs (`nproc`), {mem_gib}, Linux {}; {}",
        kernel.trim(),
        node_runtime::cpu_latency::idle_cpus(Path::new("/sys"))
    )
}

pub fn lock_version(root: &Path, krate: &str) -> String {
    let lock = std::fs::read_to_string(root.join("Cargo.lock")).unwrap_or_default();
    let needle = format!("name = \"{krate}\"\nversion = \"");
    lock.find(&needle)
        .and_then(|i| lock[i + needle.len()..].split('"').next())
        .unwrap_or("?")
        .to_owned()
}

/// Warns when `exe` is older than the newest file in `sources` (folders under `root`).
pub fn warn_if_stale(exe: &Path, root: &Path, sources: &[&str], rebuild: &str) {
    let built = std::fs::metadata(exe).and_then(|m| m.modified()).ok();
    let newest = sources
        .iter()
        .filter_map(|d| newest_mtime(&root.join(d)))
        .max();
    if let (Some(b), Some(s)) = (built, newest)
        && s > b
    {
        eprintln!(
            "warning: {} is older than its sources: rebuild with `{rebuild}`",
            exe.display()
        );
    }
}

/// Today's date (`date +%F`), for a benchmark table's heading.
pub fn today() -> String {
    Command::new("date")
        .arg("+%F")
        .output()
        .ok()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_owned())
        .unwrap_or_else(|| "?".into())
}

/// The p-quantile of sorted values (nearest rank); NaN for none.
pub fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let rank = ((p * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    sorted[rank - 1]
}

/// The microseconds of a `--cpu-dma-latency-us` argument, checked as the node parameter's.
pub fn latency_arg(value: &str) -> anyhow::Result<u32> {
    let yaml = serde_norway::from_str(value)
        .map_err(|e| anyhow!("--cpu-dma-latency-us `{value}`: {e}"))?;
    Ok(node_runtime::cpu_latency::cpu_dma_latency_of(&yaml)?)
}

/// The arguments of a bench that takes a count and a CPU latency request: `--n N` (default
/// `default`) and `--cpu-dma-latency-us US` (hold a CPU latency request while it runs, as a
/// node's `cpu_dma_latency_us` parameter does); cargo's `--bench` is ignored. A bad or unknown
/// argument is an error naming it.
#[derive(Debug)]
pub struct CountArgs {
    /// `--n`.
    pub n: usize,
    /// `--cpu-dma-latency-us`, held while this lives.
    pub latency: Option<node_runtime::CpuLatencyRequest>,
}

/// The value `v` of a count argument `flag` (`--n`), a positive integer.
pub fn positive_count(flag: &str, v: &str) -> anyhow::Result<usize> {
    v.parse()
        .ok()
        .filter(|&n| n > 0)
        .ok_or_else(|| anyhow!("{flag} `{v}` is not a positive count"))
}

/// Parses [`CountArgs`] and holds the latency request if one is given.
pub fn count_args(default: usize) -> anyhow::Result<CountArgs> {
    let mut n = default;
    let mut latency = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().ok_or_else(|| anyhow!("{a} needs a value"));
        match a.as_str() {
            "--bench" => {}
            "--n" => n = positive_count(&a, &value()?)?,
            "--cpu-dma-latency-us" => {
                let us = latency_arg(&value()?)?;
                latency = Some(node_runtime::CpuLatencyRequest::hold(us)?);
            }
            other => bail!("unknown argument `{other}` (options: --n N, --cpu-dma-latency-us US)"),
        }
    }
    Ok(CountArgs { n, latency })
}

/// A child process of a bench (a node, a recorder, a relay) with its stderr in a file;
/// killed when dropped.
pub struct Proc {
    child: Child,
    what: String,
    stderr_path: PathBuf,
}

impl Proc {
    pub fn spawn(cmd: &mut Command, what: &str, scratch: &Path) -> anyhow::Result<Self> {
        let stderr_path = scratch.join(format!("{what}.stderr"));
        let child = cmd
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(std::fs::File::create(&stderr_path)?)
            .spawn()
            .with_context(|| format!("starting the {what}"))?;
        Ok(Self {
            child,
            what: what.to_owned(),
            stderr_path,
        })
    }
    pub fn pid(&self) -> u32 {
        self.child.id()
    }
    /// Its stdout, line by line, on a channel (read by a thread: the pipe never fills).
    pub fn lines(&mut self) -> mpsc::Receiver<String> {
        let (tx, rx) = mpsc::channel();
        if let Some(out) = self.child.stdout.take() {
            std::thread::spawn(move || {
                for line in BufReader::new(out).lines().map_while(Result::ok) {
                    if tx.send(line).is_err() {
                        break;
                    }
                }
            });
        }
        rx
    }
    /// Waits for it to exit, at most `limit`; None if it is still running.
    pub fn wait(&mut self, limit: Duration) -> Option<std::process::ExitStatus> {
        let end = Instant::now() + limit;
        loop {
            if let Ok(Some(s)) = self.child.try_wait() {
                return Some(s);
            }
            if Instant::now() >= end {
                return None;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }
    /// SIGINT (as Ctrl-C), then killed if still there after 10 s.
    pub fn interrupt(&mut self) {
        let pid = nix::unistd::Pid::from_raw(self.pid() as i32);
        let _ = nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGINT);
        if self.wait(Duration::from_secs(10)).is_none() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
    /// SIGINT as [`Proc::interrupt`], then what it wrote on stdout (empty if [`Proc::lines`]
    /// took it).
    pub fn interrupt_and_read(&mut self) -> String {
        self.interrupt();
        let mut out = String::new();
        if let Some(mut s) = self.child.stdout.take() {
            let _ = std::io::Read::read_to_string(&mut s, &mut out);
        }
        out
    }
    /// Whether it has exited.
    pub fn exited(&mut self) -> bool {
        !matches!(self.child.try_wait(), Ok(None))
    }
    /// CPU time (user + system) it has used so far, or None if unreadable.
    pub fn cpu_time(&self) -> Option<Duration> {
        proc_cpu_time(&self.pid().to_string())
    }
    pub fn stderr_tail(&self) -> String {
        let s = std::fs::read_to_string(&self.stderr_path).unwrap_or_default();
        let lines: Vec<&str> = s.lines().collect();
        format!(
            "{}'s stderr ends:\n{}",
            self.what,
            lines[lines.len().saturating_sub(20)..].join("\n")
        )
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}
