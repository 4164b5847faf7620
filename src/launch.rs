//! `biped launch`: the fleet as separate processes (or, `--composed`, the pipeline in one:
//! `biped compose`), supervised.
//!
//! Starts `gait_planner`, `ik_solver`, `joint_bridge` and `robot_state_publisher` (the
//! node binaries beside this one), and with `--backend sim` also `sim_bridge` (MuJoCo), each with `--ros-args` for the
//! namespace, the parameter files and the robot, and its output in a log file. Runs until
//! Ctrl-C or SIGTERM; then asks every node to stop (SIGINT, as `ros2 launch` does), waits,
//! and kills what is left. Nodes also stop by themselves if the launcher disappears, so none
//! is orphaned.
//!
//! A node that dies (killed, crashed) is restarted with backoff ([`Respawn`]) while the
//! others run on: the joint bridge holds the joints on its watchdog meanwhile, so a real
//! robot is not dropped. A node that fails right at the launch (a bad parameter) stops the
//! fleet, naming its log; so does one that keeps dying.
//!
//! With the simulator every node runs on simulated time (`use_sim_time`), the simulator in
//! lockstep with the joint bridge; the defaults are `config/sim.yaml` (built in), which a
//! `--params` file overrides.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::Context;
use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;

/// The simulator's defaults as a ROS 2 parameter file (config/sim.yaml).
pub const SIM_PARAMS_YAML: &str = include_str!("../config/sim.yaml");

/// The nodes that find the legs in the URDF and so take a `leg_map_file` parameter
/// (robot_state_publisher needs only the tree).
const NODES_WITH_LEGS: [&str; 4] = ["gait_planner", "ik_solver", "joint_bridge", "sim_bridge"];

/// What to launch.
#[derive(Debug, Clone)]
pub struct LaunchOptions {
    /// Joint bridge backend: `mock`, `sim` or `serial`.
    pub backend: String,
    /// Robot URDF, or the built-in robot.
    pub robot: Option<PathBuf>,
    /// Leg map (the leg joints by name), for every node that finds the legs.
    pub leg_map: Option<PathBuf>,
    /// ROS 2 parameter file for every node (after the built-in defaults).
    pub params: Option<PathBuf>,
    /// Namespace of every node.
    pub namespace: String,
    /// Folder for the nodes' logs.
    pub log_dir: PathBuf,
    /// Extra `-p name:=value` per node: `(node, assignment)`.
    pub node_params: Vec<(String, String)>,
    /// Extra environment variables of the nodes.
    pub env: Vec<(String, String)>,
    /// The serial board, with `--backend serial`.
    pub serial: SerialArgs,
    /// Restarting nodes that die ([`Respawn`]); `None`: any node's exit stops the fleet.
    pub respawn: Option<Respawn>,
    /// Run the nodes `biped compose` can run ([`crate::compose::COMPOSABLE`]: the control
    /// pipeline, and the simulator with `--backend sim`, as simulators host their robot's
    /// controllers) in one process ([`COMPOSED`]) instead of one process each;
    /// robot_state_publisher stays apart, as the ROS tool it stands in for.
    pub composed: bool,
}

/// Every node the fleet may run, in start order (`sim_bridge` only with the sim backend): the
/// simulator last, so that a walk command sent before it starts is taken on simulated time.
pub const FLEET_NODES: [&str; 5] = [
    "joint_bridge",
    "ik_solver",
    "gait_planner",
    "robot_state_publisher",
    "sim_bridge",
];

/// The name of the process that runs the composed nodes (its log: `composed.log`).
pub const COMPOSED: &str = "composed";

/// True for a node `biped compose` runs.
fn composable(node: &str) -> bool {
    crate::compose::node_run(node).is_some()
}

/// When `biped launch` restarts a node that died (killed, crashed): after `first_delay_s`,
/// doubled for each death that comes within `quick_s` of the node's (re)start, up to
/// `max_delay_s`; after `give_up_after` such quick deaths in a row it stops the fleet. A node
/// that fails by itself (non-zero exit status) within `quick_s` of the launch (a bad
/// parameter, a missing file) is not restarted either: the fleet stops, naming its log. A node that ends cleanly (exit status
/// 0, e.g. the joint bridge after a lifecycle `shutdown`) is left stopped.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Respawn {
    /// Delay before the first restart (s).
    pub first_delay_s: f64,
    /// Longest delay (s).
    pub max_delay_s: f64,
    /// A death this soon after a (re)start counts as quick (s).
    pub quick_s: f64,
    /// Quick deaths in a row before giving up.
    pub give_up_after: u32,
}

impl Respawn {
    /// Restarts after `first_delay_s`, doubling to 30 s; quick: 3 s; gives up after 5.
    pub fn with_delay(first_delay_s: f64) -> Self {
        Self {
            first_delay_s,
            max_delay_s: 30.0_f64.max(first_delay_s),
            quick_s: 3.0,
            give_up_after: 5,
        }
    }
}

/// What the supervisor does about a node that exited.
#[derive(Debug, Clone, PartialEq)]
pub enum OnExit {
    /// Start it again after this long (s).
    Restart {
        /// The delay (s).
        after_s: f64,
    },
    /// Leave it stopped; the others run on.
    Leave,
    /// Stop the fleet, saying why.
    StopFleet(String),
}

/// How a node ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Exit {
    /// Exit status 0: it ended on purpose.
    Clean,
    /// A non-zero exit status: it failed (a bad parameter, a panic).
    Failed,
    /// Killed by a signal (`kill -9`, the OOM killer, a crash).
    Killed,
}

impl Exit {
    /// How a process ended.
    pub fn of(status: std::process::ExitStatus) -> Self {
        use std::os::unix::process::ExitStatusExt as _;
        if status.success() {
            Self::Clean
        } else if status.signal().is_some() {
            Self::Killed
        } else {
            Self::Failed
        }
    }
}

/// One node's life under supervision: pure (time passed in), so the policy is tested
/// without processes.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeLife {
    started_s: f64,
    restarts: u32,
    quick_deaths: u32,
}

impl NodeLife {
    /// A node first started at `t_s`.
    pub fn new(t_s: f64) -> Self {
        Self {
            started_s: t_s,
            restarts: 0,
            quick_deaths: 0,
        }
    }

    /// The node exited at `t_s`, as `how`: what to do.
    pub fn exited(&mut self, policy: &Respawn, t_s: f64, how: Exit) -> OnExit {
        if how == Exit::Clean {
            return OnExit::Leave;
        }
        let quick = t_s - self.started_s < policy.quick_s;
        if quick && self.restarts == 0 && how == Exit::Failed {
            return OnExit::StopFleet(format!(
                "failed {:.1} s after the launch",
                t_s - self.started_s
            ));
        }
        if quick {
            self.quick_deaths += 1;
        } else {
            self.quick_deaths = 0;
        }
        if self.quick_deaths >= policy.give_up_after {
            return OnExit::StopFleet(format!(
                "died {} times in a row within {} s of a restart; not restarted again",
                self.quick_deaths, policy.quick_s
            ));
        }
        let after_s =
            (policy.first_delay_s * 2f64.powi(self.quick_deaths as i32)).min(policy.max_delay_s);
        OnExit::Restart { after_s }
    }

    /// The node was started again at `t_s`.
    pub fn restarted(&mut self, t_s: f64) {
        self.started_s = t_s;
        self.restarts += 1;
    }

    /// How many times it was restarted.
    pub fn restarts(&self) -> u32 {
        self.restarts
    }
}

/// `--backend serial`: the board (passed to joint_bridge as parameters of the same names).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct SerialArgs {
    /// Serial protocol: dynamixel2, dynamixel1, maestro or ssc32.
    #[arg(long, value_parser = ["dynamixel2", "dynamixel1", "maestro", "ssc32"])]
    pub protocol: Option<String>,
    /// Serial device, e.g. /dev/ttyUSB0.
    #[arg(long, value_name = "DEV")]
    pub port: Option<PathBuf>,
    /// Baud rate.
    #[arg(long, value_name = "N")]
    pub baud: Option<u32>,
    /// Calibration file. Default: `config/calibration_<protocol>.yaml`.
    #[arg(long, value_name = "FILE")]
    pub calibration: Option<PathBuf>,
}

/// The joint_bridge parameters for a serial board.
fn serial_args(o: &LaunchOptions) -> anyhow::Result<Vec<String>> {
    let s = &o.serial;
    let (Some(protocol), Some(port), Some(baud)) = (&s.protocol, &s.port, s.baud) else {
        anyhow::bail!("--backend serial needs --protocol, --port and --baud");
    };
    let calibration = match &s.calibration {
        Some(c) => absolute(c)?,
        None => absolute(Path::new(&format!("config/calibration_{protocol}.yaml")))?,
    };
    Ok([
        format!("protocol:={protocol}"),
        format!("port:={}", port.display()),
        format!("baud:={baud}"),
        format!("calibration_file:={}", calibration.display()),
    ]
    .into_iter()
    .flat_map(|p| ["-p".to_string(), p])
    .collect())
}

impl LaunchOptions {
    /// The nodes of this launch, in start order: the simulator last, so that a walk command
    /// sent before it starts is taken on simulated time.
    /// Composed, the process of [`COMPOSED`] stands for all the nodes it runs.
    pub fn nodes(&self) -> Vec<&'static str> {
        let mut n = self.separate_nodes();
        if self.composed {
            n.retain(|node| !composable(node));
            n.insert(0, COMPOSED);
        }
        n
    }

    /// The nodes the process of [`COMPOSED`] runs, in start order.
    pub fn composed_nodes(&self) -> Vec<&'static str> {
        let mut n = self.separate_nodes();
        n.retain(|node| composable(node));
        n
    }

    /// The nodes of this launch, each as its own process.
    fn separate_nodes(&self) -> Vec<&'static str> {
        FLEET_NODES
            .into_iter()
            .filter(|&node| node != "sim_bridge" || self.backend == "sim")
            .collect()
    }
}

struct Running {
    name: &'static str,
    child: Option<Child>,
    log: PathBuf,
    life: NodeLife,
    /// Restart due at this time (s since the launch).
    restart_at_s: Option<f64>,
}

/// A running fleet: stopped (SIGINT, then killed after 5 s) when dropped.
pub struct Fleet {
    running: Vec<Running>,
    options: LaunchOptions,
    defaults_file: Option<PathBuf>,
    t0: Instant,
}

impl std::fmt::Debug for Fleet {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Fleet")
            .field(
                "nodes",
                &self.running.iter().map(|r| r.name).collect::<Vec<_>>(),
            )
            .finish()
    }
}

fn node_binary(name: &str) -> anyhow::Result<PathBuf> {
    let exe = std::env::current_exe().context("cannot locate the biped executable")?;
    let dir = exe.parent().context("the biped executable has no folder")?;
    let path = dir.join(name);
    if path.is_file() {
        Ok(path)
    } else {
        anyhow::bail!(
            "node binary {} not found; build the whole workspace (cargo build --workspace)",
            path.display()
        )
    }
}

fn absolute(p: &Path) -> anyhow::Result<PathBuf> {
    std::fs::canonicalize(p).with_context(|| format!("{} not found", p.display()))
}

impl Fleet {
    /// Checks the options and prepares the log folder; starts nothing yet.
    pub fn new(options: LaunchOptions) -> anyhow::Result<Self> {
        if !["mock", "sim", "serial"].contains(&options.backend.as_str()) {
            anyhow::bail!(
                "--backend {}: not available (mock, sim or serial)",
                options.backend
            );
        }
        let s = &options.serial;
        if options.backend == "serial" {
            serial_args(&options)?;
        } else if s.protocol.is_some()
            || s.port.is_some()
            || s.baud.is_some()
            || s.calibration.is_some()
        {
            anyhow::bail!("--protocol, --port, --baud and --calibration are for --backend serial");
        }
        if !options.namespace.starts_with('/') {
            anyhow::bail!("--ns {}: a namespace starts with /", options.namespace);
        }
        std::fs::create_dir_all(&options.log_dir)
            .with_context(|| format!("cannot create log folder {}", options.log_dir.display()))?;
        let defaults_file = if options.backend == "sim" {
            let p = options.log_dir.join("sim_defaults.yaml");
            std::fs::write(&p, SIM_PARAMS_YAML)
                .with_context(|| format!("cannot write {}", p.display()))?;
            Some(absolute(&p)?)
        } else {
            None
        };
        Ok(Self {
            running: Vec::new(),
            options,
            defaults_file,
            t0: Instant::now(),
        })
    }

    fn ros_args(&self, node: &str) -> anyhow::Result<Vec<String>> {
        let o = &self.options;
        let mut args = vec![
            "--ros-args".to_string(),
            "-r".into(),
            format!("__ns:={}", o.namespace),
        ];
        for p in self.defaults_file.iter().chain(&o.params) {
            args.push("--params-file".into());
            args.push(absolute(p)?.display().to_string());
        }
        if let Some(r) = &o.robot {
            args.push("-p".into());
            args.push(format!(
                "robot_description_file:={}",
                absolute(r)?.display()
            ));
        }
        if let Some(m) = o
            .leg_map
            .as_ref()
            .filter(|_| NODES_WITH_LEGS.contains(&node))
        {
            args.push("-p".into());
            args.push(format!("leg_map_file:={}", absolute(m)?.display()));
        }
        if node == "joint_bridge" {
            args.push("-p".into());
            args.push(format!("backend:={}", o.backend));
            if o.backend == "serial" {
                args.extend(serial_args(o)?);
            }
        }
        for (n, assignment) in &o.node_params {
            if n == node {
                args.push("-p".into());
                args.push(assignment.clone());
            }
        }
        Ok(args)
    }

    /// A node's `--ros-args`, restarted `restart` times.
    fn node_args(&self, name: &str, restart: u32) -> anyhow::Result<Vec<String>> {
        let mut args = self.ros_args(name)?;
        if restart > 0 && name == "gait_planner" {
            // Restarted mid-walk, the planner must not stand the robot up from wherever it
            // is: it holds the measured pose until the robot stands (gait_planner README).
            args.extend(["-p".to_string(), "stand_at_start:=false".to_string()]);
        }
        Ok(args)
    }

    /// Starts one node's process (or [`COMPOSED`]'s), its output to its log (appended to on a restart, so the
    /// output before a crash is kept).
    fn start_process(&self, name: &'static str, restart: u32) -> anyhow::Result<(Child, PathBuf)> {
        use std::io::Write as _;
        let bin = if name == COMPOSED {
            std::env::current_exe().context("cannot locate the biped executable")?
        } else {
            node_binary(name)?
        };
        let log = self.options.log_dir.join(format!("{name}.log"));
        let mut file = if restart == 0 {
            std::fs::File::create(&log)
        } else {
            std::fs::File::options().append(true).open(&log)
        }
        .with_context(|| format!("cannot open {}", log.display()))?;
        if restart > 0 {
            writeln!(file, "=== biped launch: {name} restarted ({restart}) ===")
                .with_context(|| format!("cannot write {}", log.display()))?;
        }
        let err = file.try_clone()?;
        let args = if name == COMPOSED {
            let mut args = vec!["compose".to_string()];
            if self.options.backend == "serial" {
                // The joint bridge waits on the serial bus for its servos' answers: on its
                // own thread, so that the planner and the IK do not wait with it.
                args.extend(["--executor".to_string(), "per-node".to_string()]);
            }
            for node in self.options.composed_nodes() {
                args.extend(["--node".to_string(), node.to_string()]);
                args.extend(self.node_args(node, restart)?);
            }
            args
        } else {
            self.node_args(name, restart)?
        };
        let child = Command::new(&bin)
            .args(args)
            .envs(self.options.env.iter().map(|(k, v)| (k, v)))
            .env(
                node_runtime::LAUNCH_PARENT_ENV,
                std::process::id().to_string(),
            )
            .stdin(Stdio::null())
            .stdout(file)
            .stderr(err)
            .spawn()
            .with_context(|| format!("cannot start {}", bin.display()))?;
        Ok((child, log))
    }

    fn now_s(&self) -> f64 {
        self.t0.elapsed().as_secs_f64()
    }

    /// Starts one node.
    pub fn spawn(&mut self, name: &'static str) -> anyhow::Result<()> {
        let (child, log) = self.start_process(name, 0)?;
        println!(
            "started {name} (pid {}), log: {}",
            child.id(),
            log.display()
        );
        self.running.push(Running {
            name,
            child: Some(child),
            log,
            life: NodeLife::new(self.now_s()),
            restart_at_s: None,
        });
        Ok(())
    }

    /// Starts every node of the options, in order.
    pub fn spawn_all(&mut self) -> anyhow::Result<()> {
        for name in self.options.nodes() {
            self.spawn(name)?;
        }
        Ok(())
    }

    /// The first node that exited, with its status and log.
    pub fn failed(&mut self) -> Option<String> {
        for r in &mut self.running {
            if let Some(c) = &mut r.child
                && let Ok(Some(status)) = c.try_wait()
            {
                return Some(format!(
                    "{} exited ({status}); see {}",
                    r.name,
                    r.log.display()
                ));
            }
        }
        None
    }

    /// One round of supervision under `policy`: a node that exited is restarted when its
    /// delay has passed, or left stopped, or (returned) the reason to stop the fleet. The
    /// other nodes run on meanwhile; the joint bridge's watchdog holds the joints while a
    /// command source is away.
    pub fn supervise(&mut self, policy: &Respawn) -> Option<String> {
        let now = self.now_s();
        for k in 0..self.running.len() {
            let r = &mut self.running[k];
            if let Some(c) = &mut r.child
                && let Ok(Some(status)) = c.try_wait()
            {
                r.child = None;
                let (name, log) = (r.name, r.log.display().to_string());
                match r.life.exited(policy, now, Exit::of(status)) {
                    OnExit::Restart { after_s } => {
                        eprintln!(
                            "biped launch: {name} exited ({status}); restarting it in {after_s:.1} s; see {log}"
                        );
                        r.restart_at_s = Some(now + after_s);
                    }
                    OnExit::Leave => {
                        println!("{name} ended ({status}); not restarted");
                    }
                    OnExit::StopFleet(why) => {
                        return Some(format!("{name} exited ({status}), {why}; see {log}"));
                    }
                }
            }
            let r = &self.running[k];
            if r.child.is_none()
                && let Some(at) = r.restart_at_s
                && now >= at
            {
                let (name, n) = (r.name, r.life.restarts() + 1);
                match self.start_process(name, n) {
                    Ok((child, log)) => {
                        println!(
                            "restarted {name} (pid {}, restart {n}), log: {}",
                            child.id(),
                            log.display()
                        );
                        let r = &mut self.running[k];
                        r.child = Some(child);
                        r.restart_at_s = None;
                        r.life.restarted(now);
                    }
                    Err(e) => return Some(format!("{name} could not be restarted: {e:#}")),
                }
            }
        }
        None
    }

    /// The running processes' names (a node's, or [`COMPOSED`]) and ids.
    pub fn named_pids(&self) -> Vec<(&'static str, u32)> {
        self.running
            .iter()
            .filter_map(|r| r.child.as_ref().map(|c| (r.name, c.id())))
            .collect()
    }

    /// Asks every node to stop (SIGINT), waits up to 5 s, kills what is left.
    pub fn stop(&mut self, verbose: bool) {
        for r in &mut self.running {
            if let Some(c) = &mut r.child
                && matches!(c.try_wait(), Ok(None))
                && let Ok(pid) = i32::try_from(c.id())
            {
                let _ = kill(Pid::from_raw(pid), Signal::SIGINT);
            }
        }
        let deadline = Instant::now() + Duration::from_secs(5);
        for r in self.running.drain(..).collect::<Vec<_>>().iter_mut() {
            let Some(c) = &mut r.child else { continue };
            loop {
                match c.try_wait() {
                    Ok(Some(status)) => {
                        if verbose {
                            println!("{} stopped ({status})", r.name);
                        }
                        break;
                    }
                    Ok(None) if Instant::now() < deadline => {
                        std::thread::sleep(Duration::from_millis(50))
                    }
                    _ => {
                        eprintln!("{} did not stop within 5 s: killed", r.name);
                        let _ = c.kill();
                        let _ = c.wait();
                        break;
                    }
                }
            }
        }
    }
}

impl Drop for Fleet {
    fn drop(&mut self) {
        self.stop(false);
    }
}

/// Refuses discovery OFF for a fleet of processes (`biped launch`, `biped walk`): its nodes
/// would never find each other, nor would any tool find them.
pub fn refuse_discovery_off(range: node_runtime::DiscoveryRange) -> anyhow::Result<()> {
    if range == node_runtime::DiscoveryRange::Off {
        anyhow::bail!(
            "ROS_AUTOMATIC_DISCOVERY_RANGE=OFF: the fleet's nodes would never find each other, \
             nor would any tool find them (OFF discovers nothing, as in ROS 2); unset it or use \
             LOCALHOST"
        );
    }
    Ok(())
}

/// Runs the fleet until interrupted. Returns an error if a node failed, or, before any
/// node starts, if the DDS environment is unusable: a `ROS_DOMAIN_ID` or
/// `ROS_AUTOMATIC_DISCOVERY_RANGE` that is not one (each node would refuse it and be
/// restarted in a loop), or `ROS_AUTOMATIC_DISCOVERY_RANGE=OFF` (the nodes, separate
/// processes, would never find each other, and no tool would find them).
pub fn launch(o: &LaunchOptions) -> anyhow::Result<()> {
    let (_, range) = node_runtime::ros_environment().context("biped launch")?;
    refuse_discovery_off(range)?;
    let stop = Arc::new(AtomicBool::new(false));
    {
        let s = stop.clone();
        ctrlc::set_handler(move || s.store(true, Ordering::SeqCst))
            .context("cannot catch Ctrl-C")?;
    }
    let mut fleet = Fleet::new(o.clone())?;
    fleet.spawn_all()?;
    println!("fleet running in namespace {}; Ctrl-C to stop", o.namespace);
    let mut failed: Option<String> = None;
    while !stop.load(Ordering::SeqCst) && failed.is_none() {
        std::thread::sleep(Duration::from_millis(100));
        failed = match &o.respawn {
            Some(policy) => fleet.supervise(policy),
            None => fleet.failed(),
        };
    }
    match &failed {
        Some(why) => eprintln!("biped launch: {why}; stopping the other nodes"),
        None => println!("stopping the fleet"),
    }
    fleet.stop(true);
    match failed {
        Some(why) => anyhow::bail!(why),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const POLICY: Respawn = Respawn {
        first_delay_s: 1.0,
        max_delay_s: 5.0,
        quick_s: 3.0,
        give_up_after: 3,
    };

    #[test]
    fn a_node_killed_mid_walk_is_restarted_after_the_first_delay_every_time() {
        let mut life = NodeLife::new(0.0);
        // Up 60 s, killed: back after 1 s; up 10 s again, killed again: 1 s again.
        assert_eq!(
            life.exited(&POLICY, 60.0, Exit::Killed),
            OnExit::Restart { after_s: 1.0 }
        );
        life.restarted(61.0);
        assert_eq!(
            life.exited(&POLICY, 71.0, Exit::Killed),
            OnExit::Restart { after_s: 1.0 }
        );
        assert_eq!(life.restarts(), 1);
    }

    #[test]
    fn a_node_that_keeps_dying_waits_longer_each_time_then_stops_the_fleet() {
        let mut life = NodeLife::new(0.0);
        assert_eq!(
            life.exited(&POLICY, 20.0, Exit::Killed),
            OnExit::Restart { after_s: 1.0 }
        );
        life.restarted(21.0);
        // Dies 1 s after each restart: 2 s, 4 s, then the third quick death gives up.
        assert_eq!(
            life.exited(&POLICY, 22.0, Exit::Killed),
            OnExit::Restart { after_s: 2.0 }
        );
        life.restarted(24.0);
        assert_eq!(
            life.exited(&POLICY, 25.0, Exit::Killed),
            OnExit::Restart { after_s: 4.0 }
        );
        life.restarted(29.0);
        assert_eq!(
            life.exited(&POLICY, 30.0, Exit::Killed),
            OnExit::StopFleet(
                "died 3 times in a row within 3 s of a restart; not restarted again".into()
            )
        );
    }

    #[test]
    fn the_delay_is_capped_and_a_long_run_forgives_the_quick_deaths() {
        let policy = Respawn {
            give_up_after: 10,
            ..POLICY
        };
        let mut life = NodeLife::new(0.0);
        let mut t = 10.0;
        let mut delays = Vec::new();
        assert_eq!(
            life.exited(&policy, t, Exit::Killed),
            OnExit::Restart { after_s: 1.0 }
        );
        for _ in 0..4 {
            t += 1.0;
            life.restarted(t);
            t += 0.5;
            match life.exited(&policy, t, Exit::Killed) {
                OnExit::Restart { after_s } => delays.push(after_s),
                other => panic!("{other:?}"),
            }
        }
        assert_eq!(delays, [2.0, 4.0, 5.0, 5.0]);
        // Up for 3 s or more: the next death is not quick, the delay back to the first.
        life.restarted(t + 5.0);
        assert_eq!(
            life.exited(&policy, t + 8.0, Exit::Killed),
            OnExit::Restart { after_s: 1.0 }
        );
    }

    #[test]
    fn a_node_killed_right_after_the_launch_is_restarted() {
        // Killed, not failed: restarted, after twice the first delay (a quick death).
        let mut life = NodeLife::new(0.0);
        assert_eq!(
            life.exited(&POLICY, 0.4, Exit::Killed),
            OnExit::Restart { after_s: 2.0 }
        );
    }

    #[test]
    fn a_failure_at_the_launch_stops_the_fleet_and_a_clean_exit_is_left_alone() {
        let mut life = NodeLife::new(0.0);
        assert_eq!(
            life.exited(&POLICY, 0.4, Exit::Failed),
            OnExit::StopFleet("failed 0.4 s after the launch".into())
        );
        let mut life = NodeLife::new(0.0);
        assert_eq!(life.exited(&POLICY, 0.4, Exit::Clean), OnExit::Leave);
        assert_eq!(life.exited(&POLICY, 100.0, Exit::Clean), OnExit::Leave);
    }
}
