//! `biped launch`: the fleet as separate processes, supervised.
//!
//! Starts `gait_planner`, `ik_solver`, `joint_bridge` and `robot_state_publisher` (the
//! node binaries beside this one), and with `--backend sim` also `sim_bridge` (MuJoCo), each with `--ros-args` for the
//! namespace, the parameter files and the robot, and its output in a log file. Runs until
//! Ctrl-C or SIGTERM, or until a node exits on its own; then asks every node to stop
//! (SIGINT, as `ros2 launch` does), waits, and kills what is left. Nodes also stop by
//! themselves if the launcher disappears, so none is orphaned.
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
    pub fn nodes(&self) -> Vec<&'static str> {
        let mut n = vec![
            "joint_bridge",
            "ik_solver",
            "gait_planner",
            "robot_state_publisher",
        ];
        if self.backend == "sim" {
            n.push("sim_bridge");
        }
        n
    }
}

struct Running {
    name: &'static str,
    child: Child,
    log: PathBuf,
}

/// A running fleet: stopped (SIGINT, then killed after 5 s) when dropped.
pub struct Fleet {
    running: Vec<Running>,
    options: LaunchOptions,
    defaults_file: Option<PathBuf>,
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

    /// Starts one node.
    pub fn spawn(&mut self, name: &'static str) -> anyhow::Result<()> {
        let bin = node_binary(name)?;
        let log = self.options.log_dir.join(format!("{name}.log"));
        let file = std::fs::File::create(&log)
            .with_context(|| format!("cannot create {}", log.display()))?;
        let err = file.try_clone()?;
        let child = Command::new(&bin)
            .args(self.ros_args(name)?)
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
        println!(
            "started {name} (pid {}), log: {}",
            child.id(),
            log.display()
        );
        self.running.push(Running { name, child, log });
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
            if let Ok(Some(status)) = r.child.try_wait() {
                return Some(format!(
                    "{} exited ({status}); see {}",
                    r.name,
                    r.log.display()
                ));
            }
        }
        None
    }

    /// Asks every node to stop (SIGINT), waits up to 5 s, kills what is left.
    pub fn stop(&mut self, verbose: bool) {
        for r in &mut self.running {
            if matches!(r.child.try_wait(), Ok(None))
                && let Ok(pid) = i32::try_from(r.child.id())
            {
                let _ = kill(Pid::from_raw(pid), Signal::SIGINT);
            }
        }
        let deadline = Instant::now() + Duration::from_secs(5);
        for r in self.running.drain(..).collect::<Vec<_>>().iter_mut() {
            loop {
                match r.child.try_wait() {
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
                        let _ = r.child.kill();
                        let _ = r.child.wait();
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

/// Runs the fleet until interrupted. Returns an error if a node failed.
pub fn launch(o: &LaunchOptions) -> anyhow::Result<()> {
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
        failed = fleet.failed();
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
