//! `biped launch`: the fleet as separate processes, supervised.
//!
//! Starts `gait_planner`, `ik_solver` and `joint_bridge` (the node binaries beside this
//! one), each with `--ros-args` for the namespace, the parameter file and the robot, and its
//! output in a log file. Runs until Ctrl-C or SIGTERM, or until a node exits on its own;
//! then asks every node to stop (SIGINT, as `ros2 launch` does), waits, and kills what is
//! left. Nodes also stop by themselves if the launcher disappears, so none is orphaned.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::Context;
use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;

/// What to launch.
#[derive(Debug, Clone)]
pub struct LaunchOptions {
    /// `mock` or `serial` (the simulator comes with its issue).
    pub backend: String,
    /// Robot URDF, or the built-in robot.
    pub robot: Option<PathBuf>,
    /// ROS 2 parameter file for every node.
    pub params: Option<PathBuf>,
    /// Namespace of every node.
    pub namespace: String,
    /// Folder for the nodes' logs.
    pub log_dir: PathBuf,
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
    /// Calibration file. Default: config/calibration_<protocol>.yaml.
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

struct Running {
    name: &'static str,
    child: Child,
    log: PathBuf,
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

fn ros_args(o: &LaunchOptions, node: &str) -> anyhow::Result<Vec<String>> {
    let mut args = vec![
        "--ros-args".to_string(),
        "-r".into(),
        format!("__ns:={}", o.namespace),
    ];
    if let Some(p) = &o.params {
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
    if node == "joint_bridge" {
        args.push("-p".into());
        args.push(format!("backend:={}", o.backend));
        if o.backend == "serial" {
            args.extend(serial_args(o)?);
        }
    }
    Ok(args)
}

fn absolute(p: &Path) -> anyhow::Result<PathBuf> {
    std::fs::canonicalize(p).with_context(|| format!("{} not found", p.display()))
}

fn interrupt(children: &mut [Running], signal: Signal) {
    for r in children.iter_mut() {
        if matches!(r.child.try_wait(), Ok(None))
            && let Ok(pid) = i32::try_from(r.child.id())
        {
            let _ = kill(Pid::from_raw(pid), signal);
        }
    }
}

/// Runs the fleet until interrupted. Returns an error if a node failed.
pub fn launch(o: &LaunchOptions) -> anyhow::Result<()> {
    if o.backend == "serial" {
        serial_args(o)?;
    } else if o.serial.protocol.is_some()
        || o.serial.port.is_some()
        || o.serial.baud.is_some()
        || o.serial.calibration.is_some()
    {
        anyhow::bail!("--protocol, --port, --baud and --calibration are for --backend serial");
    }
    if o.backend != "mock" && o.backend != "serial" {
        anyhow::bail!(
            "--backend {}: not available yet (mock; the sim and serial backends come with their issues)",
            o.backend
        );
    }
    if !o.namespace.starts_with('/') {
        anyhow::bail!("--ns {}: a namespace starts with /", o.namespace);
    }
    let stop = Arc::new(AtomicBool::new(false));
    {
        let s = stop.clone();
        ctrlc::set_handler(move || s.store(true, Ordering::SeqCst))
            .context("cannot catch Ctrl-C")?;
    }
    std::fs::create_dir_all(&o.log_dir)
        .with_context(|| format!("cannot create log folder {}", o.log_dir.display()))?;
    let mut running: Vec<Running> = Vec::new();
    for name in ["joint_bridge", "ik_solver", "gait_planner"] {
        let bin = node_binary(name)?;
        let log = o.log_dir.join(format!("{name}.log"));
        let file = std::fs::File::create(&log)
            .with_context(|| format!("cannot create {}", log.display()))?;
        let err = file.try_clone()?;
        let child = Command::new(&bin)
            .args(ros_args(o, name)?)
            .env(
                biped_msgs::ros::LAUNCH_PARENT_ENV,
                std::process::id().to_string(),
            )
            .stdin(Stdio::null())
            .stdout(file)
            .stderr(err)
            .spawn();
        match child {
            Ok(child) => {
                println!(
                    "started {name} (pid {}), log: {}",
                    child.id(),
                    log.display()
                );
                running.push(Running { name, child, log });
            }
            Err(e) => {
                interrupt(&mut running, Signal::SIGINT);
                anyhow::bail!("cannot start {}: {e}", bin.display());
            }
        }
    }
    println!("fleet running in namespace {}; Ctrl-C to stop", o.namespace);

    let mut failed: Option<String> = None;
    while !stop.load(Ordering::SeqCst) && failed.is_none() {
        std::thread::sleep(Duration::from_millis(100));
        for r in &mut running {
            if let Ok(Some(status)) = r.child.try_wait() {
                failed = Some(format!(
                    "{} exited ({status}); see {}",
                    r.name,
                    r.log.display()
                ));
            }
        }
    }
    match &failed {
        Some(why) => eprintln!("biped launch: {why}; stopping the other nodes"),
        None => println!("stopping the fleet"),
    }
    interrupt(&mut running, Signal::SIGINT);
    let deadline = Instant::now() + Duration::from_secs(5);
    for r in &mut running {
        loop {
            match r.child.try_wait() {
                Ok(Some(status)) => {
                    println!("{} stopped ({status})", r.name);
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
    match failed {
        Some(why) => anyhow::bail!(why),
        None => Ok(()),
    }
}
