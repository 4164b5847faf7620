//! `biped`: the commands users run. `biped walk` walks the robot in MuJoCo with the ROS 2
//! fleet and measures it; `biped launch` runs the fleet; `biped plan` plans a walk offline;
//! `biped check-robot` checks a user's own robot; `biped record` and `biped replay` write and
//! play rosbag2 bags.
//!
//! The top layer (README, "What is where"): it uses the core libraries (ik_solver,
//! gait_planner, sim_bridge, walk_eval for the walk's measures) and the middleware edge
//! (node_runtime, biped_msgs); nothing depends on it.

mod bag;
mod check_robot;
mod compose;
mod launch;
mod plan;
mod plots;
mod walk;

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::{Parser, Subcommand};
use gait_planner::{GaitParams, GaitPlanner, WalkRequest};
use ik_solver::{BipedModel, LegRoleMap};

#[derive(Debug, Parser)]
#[command(
    name = "biped",
    version,
    about = "A statically stable biped walk for small humanoids (ROS 2 node fleet and tools)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, clap::Args)]
struct RobotArgs {
    /// Robot URDF. Default: the built-in 20-DOF robot (config/biped.urdf).
    #[arg(long, value_name = "URDF")]
    robot: Option<PathBuf>,
    /// YAML naming the leg joints (`left:`/`right:` with hip_roll, hip_pitch, knee,
    /// ankle_pitch, ankle_roll and optional hip_yaw), for URDFs whose legs are not found by
    /// their axes.
    #[arg(long, value_name = "YAML")]
    leg_map: Option<PathBuf>,
    /// ROS 2 parameter file with a `gait_planner:` section. Default: built-in defaults
    /// (the same as config/gait.yaml).
    #[arg(long, value_name = "YAML")]
    params: Option<PathBuf>,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Start the ROS 2 fleet (gait_planner, ik_solver, joint_bridge) as separate processes
    /// until Ctrl-C or SIGTERM.
    Launch {
        /// Joint bridge backend.
        #[arg(long, default_value = "mock", value_parser = ["mock", "sim", "serial"])]
        backend: String,
        /// Robot URDF. Default: the built-in robot.
        #[arg(long, value_name = "URDF")]
        robot: Option<PathBuf>,
        /// YAML naming the leg joints (as for `biped plan --leg-map`); passed to every node
        /// as its `leg_map_file` parameter.
        #[arg(long, value_name = "YAML")]
        leg_map: Option<PathBuf>,
        /// ROS 2 parameter file for every node (e.g. config/gait.yaml).
        #[arg(long, value_name = "YAML")]
        params: Option<PathBuf>,
        /// Namespace of the nodes.
        #[arg(long, default_value = "/")]
        ns: String,
        /// Folder for the nodes' log files.
        #[arg(long, value_name = "DIR", default_value = "out/launch")]
        log_dir: PathBuf,
        #[command(flatten)]
        serial: launch::SerialArgs,
        /// Seconds before a node that died is restarted (doubled for each death soon after
        /// a restart, up to 30 s).
        #[arg(long, value_name = "S", default_value_t = 1.0, value_parser = respawn_delay)]
        respawn_delay: f64,
        /// Do not restart nodes: any node's exit stops the fleet.
        #[arg(long)]
        no_respawn: bool,
        /// Run gait_planner, ik_solver and joint_bridge (and sim_bridge with `--backend
        /// sim`) in one process (`biped compose`): messages between them are delivered
        /// in-process, every topic stays on DDS for other peers. Restarted as one.
        #[arg(long)]
        composed: bool,
    },
    /// Run fleet nodes in one process, as ROS 2's component container: `[--executor
    /// single|per-node] --node <name> [--ros-args ...]` for each (gait_planner, ik_solver,
    /// joint_bridge, sim_bridge), each with the arguments its own binary takes. Messages
    /// between them are delivered in-process; every topic stays on DDS for other peers. All
    /// on one thread (`single`, the default) or each on its own (`per-node`). Until Ctrl-C
    /// or SIGTERM, or until one node ends (which stops the others).
    Compose {
        /// `--node <name> [--ros-args ...]`, repeated.
        #[arg(
            trailing_var_arg = true,
            allow_hyphen_values = true,
            value_name = "--node NAME ARGS"
        )]
        args: Vec<String>,
    },
    /// Walk the robot in MuJoCo: the ROS 2 fleet and the simulator in lockstep on simulated
    /// time (DDS on this host unless ROS_AUTOMATIC_DISCOVERY_RANGE says otherwise); writes
    /// report.json and pictures. Exits non-zero if the robot fell.
    Walk {
        /// Number of steps (swings before the closing half step).
        #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..=10_000))]
        steps: u32,
        /// Walk at this velocity: `vx,vy,wz` as cmd_vel's Twist has them (m/s forward, m/s
        /// left, rad/s counter-clockwise; REP-103), sent in the walk command and scaled into
        /// the step limits. Default: straight ahead at the full step.
        #[arg(long, value_name = "VX,VY,WZ", allow_hyphen_values = true, value_parser = plan::parse_twist)]
        twist: Option<gait_planner::Velocity>,
        /// Robot URDF. Default: the built-in robot.
        #[arg(long, value_name = "URDF")]
        robot: Option<PathBuf>,
        /// YAML naming the leg joints (as for `biped plan --leg-map`); passed to every node
        /// as its `leg_map_file` parameter.
        #[arg(long, value_name = "YAML")]
        leg_map: Option<PathBuf>,
        /// ROS 2 parameter file for every node (gait_planner, sim_bridge, joint_bridge
        /// sections; over the built-in config/sim.yaml).
        #[arg(long, value_name = "YAML")]
        params: Option<PathBuf>,
        /// A MuJoCo scene of the robot to simulate instead of building it from the URDF
        /// (which still gives the kinematics); needs --joint-map.
        #[arg(long, value_name = "MJCF", requires = "joint_map")]
        mjcf: Option<PathBuf>,
        /// YAML mapping the URDF's joints, links and soles to the scene's names.
        #[arg(long, value_name = "YAML", requires = "mjcf")]
        joint_map: Option<PathBuf>,
        /// Output folder: report.json, pictures, logs/.
        #[arg(long, value_name = "DIR", default_value = "out/walk")]
        out: PathBuf,
        /// Pace the simulation at real time (default: as fast as the fleet answers).
        #[arg(long)]
        real_time: bool,
        /// Simulated seconds the robot stands before the walk starts.
        #[arg(long, default_value_t = 1.0)]
        settle: f64,
        /// Record the walk's topics into this rosbag2 bag folder (MCAP; must not exist).
        #[arg(long, value_name = "DIR")]
        bag: Option<PathBuf>,
        /// Stop anywhere, measured: at these instants (simulated seconds from the walk's
        /// start, comma-separated) call the joint bridge's `~/estop` (std_srvs/Trigger, as
        /// an operator would); after 2.5 s call `~/reset` and the walk goes on. report.json's
        /// `stops` gives, per stop, how far each loaded sole and the base moved while held.
        #[arg(long, value_name = "S,...", value_delimiter = ',')]
        estop_at: Vec<f64>,
        /// Stop anywhere along the plan, measured: at these instants call the gait planner's
        /// `~/pause` (std_srvs/SetBool true: the walk comes to rest along its path within
        /// `pause_brake_time_s`); after 2.5 s `~/pause` false and the walk goes on.
        /// report.json's `stops` measures each as for --estop-at. Not with --estop-at.
        #[arg(
            long,
            value_name = "S,...",
            value_delimiter = ',',
            conflicts_with = "estop_at"
        )]
        pause_at: Vec<f64>,
        /// Run gait_planner, ik_solver, joint_bridge and sim_bridge in one process (`biped
        /// compose`): the lockstep tick's hops are in-process (the simulator starts paused
        /// and is released by its `~/pause` once the walk command is in); every topic is on
        /// DDS as without it.
        #[arg(long)]
        composed: bool,
        /// The gait planner a tick ahead of `/clock` (its `plan_ahead` parameter), even over
        /// a `--params` file that says otherwise; without a flag it is ahead too
        /// (`config/sim.yaml`): tick k's targets go out at `/clock` k - 1 and the joint bridge
        /// holds them until tick k, so the lockstep tick waits for one hop instead of three.
        /// The same walk (the joints get the same targets at the same ticks); the planner
        /// hears commands and the bridge's hold a tick earlier in its plan.
        #[arg(long, conflicts_with = "plan_on_time")]
        plan_ahead: bool,
        /// The gait planner on time (`plan_ahead` false): tick k's targets go out at `/clock`
        /// k, and the lockstep tick waits for the planner, the IK and the joint bridge.
        #[arg(long)]
        plan_on_time: bool,
    },
    /// Record topics into a rosbag2 bag (Jazzy format, MCAP or sqlite3) until Ctrl-C,
    /// SIGTERM or --duration.
    ///
    /// Types that can be recorded: builtin_interfaces/msg/Time, std_msgs/msg/{Header,
    /// String}, geometry_msgs/msg/{Point, Point32, Polygon, PolygonStamped, Pose,
    /// PoseStamped, PoseWithCovariance, PointStamped, Quaternion, Twist,
    /// TwistWithCovariance, Vector3}, nav_msgs/msg/Odometry, sensor_msgs/msg/JointState,
    /// rosgraph_msgs/msg/Clock, rcl_interfaces/msg/Log, diagnostic_msgs/msg/{DiagnosticArray,
    /// DiagnosticStatus, KeyValue}, biped_msgs/msg/{GaitPhase, AnkleTargets, WalkCommand}.
    Record {
        /// The bag folder to create (must not exist).
        dir: PathBuf,
        /// Topics to record (e.g. /joint_commands /cmd_vel).
        #[arg(long, num_args = 1.., required_unless_present = "all", conflicts_with = "all")]
        topics: Vec<String>,
        /// Record every topic whose type is known (see `biped record --help`).
        #[arg(long)]
        all: bool,
        /// Stop after this many seconds.
        #[arg(long, value_name = "S")]
        duration: Option<f64>,
        /// Storage format.
        #[arg(long, default_value = "mcap", value_parser = ["mcap", "sqlite3"])]
        storage: String,
    },
    /// Play a rosbag2 bag (ours, ROS 2's or the rosbags library's) onto DDS with its
    /// recorded timing and QoS.
    Replay {
        /// The bag folder.
        dir: PathBuf,
        /// Speed factor.
        #[arg(long, default_value_t = 1.0)]
        rate: f64,
        /// Play again from the start until Ctrl-C.
        #[arg(long = "loop")]
        repeat: bool,
        /// Play only these topics.
        #[arg(long, num_args = 1..)]
        topics: Vec<String>,
        /// Skip this many seconds of the bag's start.
        #[arg(long, value_name = "S", default_value_t = 0.0)]
        start_offset: f64,
        /// Publish a recorded topic under another name: FROM:=TO (repeatable).
        #[arg(long, value_name = "FROM:=TO")]
        remap: Vec<String>,
        /// First wait up to this many seconds for every topic to have a subscriber.
        #[arg(long, value_name = "S", default_value_t = 0.0)]
        wait_for_subscribers: f64,
        /// Then wait this many seconds before the first message, and on until no subscriber
        /// has appeared for 1 s (at most 5 s more): DDS discovery between our nodes and a
        /// new publisher takes up to ~4 s, and what is sent before it is lost to them.
        #[arg(long, value_name = "S", default_value_t = 5.0)]
        delay: f64,
    },
    /// Check your own robot: read its URDF (and leg map, scene) as the fleet will, print
    /// what was found (legs, joint roles, axis signs, offsets, soles, mass, CoM, limits), the
    /// gait defaults derived for it and whether a short plan passes the stability check, and
    /// draw the legs as an SVG. Exits 1 listing every problem found.
    CheckRobot {
        /// The robot's URDF.
        urdf: PathBuf,
        /// YAML naming the leg joints, for URDFs whose legs are not found by their axes.
        #[arg(long, value_name = "YAML")]
        leg_map: Option<PathBuf>,
        /// ROS 2 parameter file with a `gait_planner:` section (default: derived from the robot).
        #[arg(long, value_name = "YAML")]
        params: Option<PathBuf>,
        /// A MuJoCo scene of the robot (with --joint-map).
        #[arg(long, value_name = "XML", requires = "joint_map")]
        mjcf: Option<PathBuf>,
        /// The scene's joint map to the URDF's names (with --mjcf).
        #[arg(long, value_name = "YAML", requires = "mjcf")]
        joint_map: Option<PathBuf>,
        /// Where to draw the legs.
        #[arg(long, value_name = "FILE", default_value = "robot_legs.svg")]
        svg: PathBuf,
    },
    /// Plan a walk offline; write it as CSV (one row per control tick) and pictures.
    Plan {
        /// Number of steps (swings before the closing half step).
        #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..=10_000))]
        steps: u32,
        #[command(flatten)]
        robot: RobotArgs,
        /// Walk at this velocity instead of straight ahead at the full step: `vx,vy,wz` as
        /// cmd_vel's Twist has them (m/s forward, m/s left, rad/s counter-clockwise; REP-103).
        /// Scaled into the step limits (with a warning) as the gait_planner node does.
        #[arg(long, value_name = "VX,VY,WZ", allow_hyphen_values = true, value_parser = plan::parse_twist)]
        twist: Option<gait_planner::Velocity>,
        /// Where to write the CSV.
        #[arg(long, value_name = "FILE")]
        csv: PathBuf,
        /// Folder for the pictures (SVG). Default: the CSV's folder.
        #[arg(long, value_name = "DIR")]
        plots: Option<PathBuf>,
        /// Write no pictures.
        #[arg(long, conflicts_with = "plots")]
        no_plots: bool,
        /// Plan with the fastest timing the checks allow (shift, step and crouch durations
        /// found by time scaling the parameter file's walk against the joint speed limits
        /// and the ZMP margin, then verified by the check walks), and print it. A planning
        /// answer, not a physics one: `biped walk` tells whether the robot keeps up.
        #[arg(long)]
        fastest: bool,
        /// Plan the fastest walk the checks allow: the step lengths and hip heights left at 0
        /// in the parameter file are searched (0.25-0.45 x leg, hip pitch 0.65-0.85 x leg
        /// above the ankle), each at its fastest timing as `--fastest` finds it (the
        /// durations are searched whatever the file says); prints every walk tried and plans
        /// the fastest. Foot lift, margins and brake time stay the file's. A planning
        /// answer, as `--fastest`'s.
        #[arg(long, conflicts_with = "fastest")]
        fastest_walk: bool,
        /// With `--fastest` or `--fastest-walk`: write the parameters found as a ROS 2
        /// parameter file, for `biped walk --params` or the node's `--params-file`.
        #[arg(long, value_name = "YAML")]
        write_params: Option<PathBuf>,
    },
}

/// `--respawn-delay`: a finite number of seconds in [0.1, 60].
fn respawn_delay(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .parse()
        .map_err(|e| format!("`{s}` is not a number of seconds: {e}"))?;
    if (0.1..=60.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!("{v} s is out of range [0.1, 60] s"))
    }
}

fn load_model(args: &RobotArgs) -> anyhow::Result<BipedModel> {
    model_of(
        args.robot.as_deref(),
        leg_map_of(args.leg_map.as_deref())?.as_ref(),
    )
}

/// The leg map of a `--leg-map` file (none: legs found by their axes).
pub(crate) fn leg_map_of(path: Option<&std::path::Path>) -> anyhow::Result<Option<LegRoleMap>> {
    Ok(path.map(LegRoleMap::from_yaml_file).transpose()?)
}

/// The robot of a `--robot` URDF (none: the built-in robot) with its leg map.
pub(crate) fn model_of(
    robot: Option<&std::path::Path>,
    role_map: Option<&LegRoleMap>,
) -> anyhow::Result<BipedModel> {
    match robot {
        Some(p) => BipedModel::from_urdf_file(p, role_map)
            .with_context(|| format!("robot {}", p.display())),
        None => {
            BipedModel::from_urdf_str(ik_solver::DEFAULT_URDF, role_map).context("built-in robot")
        }
    }
}

fn load_params(args: &RobotArgs) -> anyhow::Result<GaitParams> {
    Ok(match &args.params {
        Some(p) => GaitParams::from_ros_yaml_file(p)?,
        None => GaitParams::default(),
    })
}

/// FROM:=TO.
fn parse_remap(s: &str) -> anyhow::Result<(String, String)> {
    match s.split_once(":=") {
        Some((from, to)) if from.starts_with('/') && to.starts_with('/') && to.len() > 1 => {
            Ok((from.to_string(), to.to_string()))
        }
        _ => anyhow::bail!("--remap '{s}': expected /from:=/to (absolute topic names)"),
    }
}

fn check_topic_names(names: &[String]) -> anyhow::Result<()> {
    for n in names {
        if !n.starts_with('/') || n.len() < 2 || n.contains(char::is_whitespace) {
            anyhow::bail!("topic '{n}': expected an absolute topic name such as /joint_commands");
        }
    }
    Ok(())
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Record {
            dir,
            topics,
            all,
            duration,
            storage,
        } => {
            check_topic_names(&topics)?;
            if let Some(d) = duration.filter(|d| !(d.is_finite() && *d > 0.0)) {
                anyhow::bail!("--duration {d}: must be a positive number of seconds");
            }
            let storage = bag::storage::StorageKind::from_id(&storage)
                .with_context(|| format!("--storage {storage}"))?;
            let stop = node_runtime::shutdown_flag()?;
            let context = node_runtime::context_from_env()?;
            let opts = bag::record::RecordOptions {
                dir: dir.clone(),
                topics,
                all,
                duration_s: duration,
                storage,
                progress_period_s: 5.0,
            };
            let s = bag::record::record(&context.domain_participant(), &opts, &stop)?;
            println!(
                "recorded {} messages in {:.1} s into {}",
                s.total,
                s.elapsed_s,
                dir.display()
            );
            for (topic, n) in &s.counts {
                println!("  {topic}: {n}");
            }
            for (topic, why) in &s.skipped {
                println!("  not recorded: {topic}: {why}");
            }
            Ok(())
        }
        Command::Replay {
            dir,
            rate,
            repeat,
            topics,
            start_offset,
            remap,
            wait_for_subscribers,
            delay,
        } => {
            check_topic_names(&topics)?;
            let remaps = remap
                .iter()
                .map(|r| parse_remap(r))
                .collect::<anyhow::Result<Vec<_>>>()?;
            for (v, name) in [
                (wait_for_subscribers, "--wait-for-subscribers"),
                (delay, "--delay"),
            ] {
                if !(v.is_finite() && (0.0..=3600.0).contains(&v)) {
                    anyhow::bail!("{name} {v}: must be within [0, 3600] s");
                }
            }
            let stop = node_runtime::shutdown_flag()?;
            let context = node_runtime::context_from_env()?;
            let opts = bag::replay::ReplayOptions {
                dir: dir.clone(),
                rate,
                repeat,
                topics,
                start_offset_s: start_offset,
                remaps,
                wait_for_subscribers_s: wait_for_subscribers,
                delay_s: delay,
                progress_period_s: 5.0,
            };
            let s = bag::replay::replay(&context.domain_participant(), &opts, &stop)?;
            let sent: u64 = s.sent.values().sum();
            println!(
                "replayed {sent} messages from {} in {:.1} s ({} pass{}), {} skipped, at most {:.1} ms late",
                dir.display(),
                s.elapsed_s,
                s.passes,
                if s.passes == 1 { "" } else { "es" },
                s.skipped,
                s.max_late_s * 1e3
            );
            for (topic, n) in &s.sent {
                println!("  {topic}: {n}");
            }
            Ok(())
        }
        Command::Launch {
            backend,
            robot,
            leg_map,
            params,
            ns,
            log_dir,
            serial,
            respawn_delay,
            no_respawn,
            composed,
        } => launch::launch(&launch::LaunchOptions {
            backend,
            robot,
            leg_map,
            params,
            namespace: ns,
            log_dir,
            node_params: Vec::new(),
            env: Vec::new(),
            serial,
            respawn: (!no_respawn).then(|| launch::Respawn::with_delay(respawn_delay)),
            composed,
        }),
        Command::Compose { args } => compose::compose(&args),
        Command::Walk {
            steps,
            twist,
            robot,
            leg_map,
            params,
            mjcf,
            joint_map,
            out,
            real_time,
            settle,
            bag,
            estop_at,
            pause_at,
            composed,
            plan_ahead,
            plan_on_time,
        } => {
            if !(settle.is_finite() && (0.0..=60.0).contains(&settle)) {
                anyhow::bail!("--settle {settle}: must be within [0, 60] s");
            }
            let instants = |flag: &str, mut at: Vec<f64>| -> anyhow::Result<Vec<f64>> {
                if let Some(bad) = at.iter().find(|t| !(t.is_finite() && **t >= 0.0)) {
                    anyhow::bail!(
                        "{flag} {bad}: each instant must be a finite number of seconds >= 0"
                    );
                }
                at.sort_by(f64::total_cmp);
                Ok(at)
            };
            let estop_at_s = instants("--estop-at", estop_at)?;
            let pause_at_s = instants("--pause-at", pause_at)?;
            let outcome = walk::walk(&walk::WalkOptions {
                steps,
                velocity: twist,
                robot,
                leg_map,
                params,
                scene: mjcf.zip(joint_map),
                out,
                real_time,
                settle_s: settle,
                tail_s: 2.0,
                stall_s: 30.0,
                bag,
                estop_at_s,
                pause_at_s,
                composed,
                plan_ahead: if plan_on_time {
                    Some(false)
                } else {
                    plan_ahead.then_some(true)
                },
            })?;
            let r = &outcome.report;
            let m = &r.measured;
            println!(
                "walked {:.3} m forward and {:.3} m left of {:.3} m and {:.3} m planned in {:.2} s ({:.3} m/s forward); max tilt {:.2}°, heading drift {:.2}°, foot slip {:.1} mm, CoP inside {:.1}%; {:.1}x real time",
                m.distance_m,
                m.left_m,
                m.planned_distance_m,
                m.planned_left_m,
                r.walk_duration_s,
                r.speed_m_s,
                m.max_tilt_deg,
                m.heading_drift_deg,
                m.max_foot_slip_m * 1e3,
                m.cop_inside_fraction * 100.0,
                r.real_time_factor
            );
            if let (Some(sole), Some(sole_late), Some(base)) = (
                r.stop_anywhere_worst_sole_m,
                r.stop_anywhere_worst_sole_late_m,
                r.stop_anywhere_worst_base_late_m,
            ) {
                println!(
                    "{} {}: a loaded sole moved at most {:.2} mm from the call ({:.2} mm from 0.5 s on), the base {:.2} mm from 0.5 s to {} s after the call",
                    r.stops.len(),
                    match r.stops.first().map(|s| s.kind) {
                        Some(walk::report::StopKind::Pause) => "pauses",
                        _ => "e-stops",
                    },
                    sole * 1e3,
                    sole_late * 1e3,
                    base * 1e3,
                    walk::report::ESTOP_WINDOW_S
                );
            }
            for f in &outcome.files {
                println!("wrote {}", f.display());
            }
            if let Some(f) = &m.fell {
                anyhow::bail!(
                    "the robot fell at {:.2} s into the walk, in phase {}: {}",
                    f.t_s,
                    f.phase,
                    f.reason
                );
            }
            Ok(())
        }
        Command::CheckRobot {
            urdf,
            leg_map,
            params,
            mjcf,
            joint_map,
            svg,
        } => {
            let mut problems = Vec::new();
            let leg_map = match leg_map
                .as_deref()
                .map(LegRoleMap::from_yaml_file)
                .transpose()
            {
                Ok(m) => m,
                Err(e) => {
                    problems.push(e.to_string());
                    None
                }
            };
            let params = match params.as_deref().map(GaitParams::from_ros_yaml_file) {
                None => GaitParams::default(),
                Some(Ok(p)) => p,
                Some(Err(e)) => {
                    problems.push(e.to_string());
                    GaitParams::default()
                }
            };
            let req = check_robot::CheckRequest {
                urdf,
                leg_map,
                scene: mjcf.zip(joint_map),
                params,
                svg,
            };
            let mut outcome = check_robot::check(&req)?;
            problems.append(&mut outcome.problems);
            print!("{}", outcome.report);
            if problems.is_empty() {
                println!("no problems found");
                return Ok(());
            }
            for p in &problems {
                eprintln!("problem: {p}");
            }
            anyhow::bail!("{} problem(s) with {}", problems.len(), req.urdf.display())
        }
        Command::Plan {
            steps,
            robot,
            twist,
            csv,
            plots,
            no_plots,
            fastest,
            fastest_walk,
            write_params,
        } => {
            let model = load_model(&robot)?;
            let mut params = load_params(&robot)?;
            if write_params.is_some() && !fastest && !fastest_walk {
                anyhow::bail!(
                    "--write-params writes what --fastest or --fastest-walk found; give one of them"
                );
            }
            if fastest_walk {
                let started = std::time::Instant::now();
                let w = gait_planner::timing::fastest_walk(
                    &model,
                    &GaitParams {
                        shift_duration_s: 0.0,
                        step_duration_s: 0.0,
                        crouch_duration_s: 0.0,
                        ..params.clone()
                    },
                )?;
                for t in &w.trials {
                    match &t.outcome {
                        Ok((speed, d)) => println!(
                            "  step {:.3} m, hip height {:.3} m: {speed:.4} m/s planned (shift {:.3} s, step {:.3} s, crouch {:.3} s)",
                            t.step_length_m,
                            t.hip_height_m,
                            d.shift_duration_s,
                            d.step_duration_s,
                            d.crouch_duration_s
                        ),
                        Err(e) => println!(
                            "  step {:.3} m, hip height {:.3} m: refused: {e}",
                            t.step_length_m, t.hip_height_m
                        ),
                    }
                }
                let p = &w.params;
                println!(
                    "fastest walk: step {:.3} m, hip height {:.3} m, shift {:.3} s, step {:.3} s, crouch {:.3} s: {:.4} m/s planned; {} walks tried in {:.1} s",
                    p.step_length_m,
                    p.hip_height_m,
                    p.shift_duration_s,
                    p.step_duration_s,
                    p.crouch_duration_s,
                    w.speed_m_s,
                    w.trials.len(),
                    started.elapsed().as_secs_f64()
                );
                eprintln!(
                    "note: the fastest walk the planning checks allow; `biped walk --params` tells whether the robot keeps up (BENCHMARKS.md, \"Walking faster\"). Not for hardware before that."
                );
                params = w.params;
            }
            if fastest {
                let started = std::time::Instant::now();
                let f = gait_planner::timing::fastest_timing(&model, &params)?;
                let t = f.timing;
                println!(
                    "fastest timing: {}; found in {:.2} s ({} checked planners)",
                    f.describe(),
                    started.elapsed().as_secs_f64(),
                    f.checks
                );
                // What pausing anywhere costs: the same search without the brake bound.
                let free =
                    gait_planner::timing::fastest_timing_with_brake(&model, &params, None)?.timing;
                let period =
                    |t: &gait_planner::timing::Timing| t.shift_duration_s + t.step_duration_s;
                println!(
                    "pausing anywhere within {:.2} s costs {:.0} % of the speed: without it, shift {:.3} s, step {:.3} s",
                    f.max_pause_brake_s.unwrap_or_default(),
                    (1.0 - period(&free) / period(&t)) * 100.0,
                    free.shift_duration_s,
                    free.step_duration_s
                );
                let torque = if params.servo_damping_nm_s_per_rad > 0.0
                    || params.servo_armature_kg_m2 > 0.0
                {
                    "the servos' torque budget"
                } else {
                    "no torque budget (servo_damping_nm_s_per_rad and servo_armature_kg_m2 unset)"
                };
                eprintln!(
                    "note: the fastest timing the planning checks allow (joint speed limits, ZMP margin, pausing within the brake time, {torque}); the joint bridge's e-stop keeps to the path (BENCHMARKS.md, \"An e-stop that keeps to the path\"), but the servos lag and the measured CoP runs ahead of the plan's ZMP at these speeds (\"Walking faster\"). Not for hardware yet."
                );
                params = f.params;
            }
            let params_file = match &write_params {
                Some(file) => Some((
                    file,
                    format!(
                        "# Written by `biped plan {}` for {}: a planning answer; try it in simulation first\n# (`biped walk --params {}`).\n{}",
                        if fastest_walk {
                            "--fastest-walk"
                        } else {
                            "--fastest"
                        },
                        model.robot().name(),
                        file.display(),
                        params.to_ros_yaml_string()?
                    ),
                )),
                None => None,
            };
            let mut planner = GaitPlanner::new(model, params)?;
            if let Some(auto) = planner.auto_timing_summary() {
                println!("{auto}");
            }
            if let Some(v) = twist {
                plan::apply_twist(&mut planner, v)?;
            }
            let samples = planner.plan(WalkRequest::Steps(steps))?;
            plan::write_csv_file(&csv, planner.model().robot(), &samples)?;
            if let Some((file, text)) = params_file {
                std::fs::write(file, text)
                    .with_context(|| format!("writing {}", file.display()))?;
                println!("wrote {}", file.display());
            }
            let mut summary = plan::PlanSummary::of(&samples);
            summary.files.push(csv.clone());
            if !no_plots {
                let dir =
                    plots.unwrap_or_else(|| csv.parent().map(PathBuf::from).unwrap_or_default());
                summary
                    .files
                    .extend(plots::write_plots(&dir, &planner, &samples)?);
            }
            let c = planner.config();
            let stride = planner.stride();
            println!(
                "planned {steps} steps of {:.3} m forward, {:.3} m left for {}: {} ticks at {} Hz, {:.2} s, base moved {:.3} m forward, {:.3} m left, minimum CoM margin {:.4} m (required {:.4} m), minimum ZMP margin {:.4} m (required {:.4} m); a pause (~/pause) comes to rest within {:.2} s",
                stride.forward_m,
                stride.left_m,
                planner.model().robot().name(),
                summary.rows,
                c.control_rate_hz,
                summary.duration_s,
                summary.distance_m,
                summary.left_m,
                summary.min_margin_m,
                c.min_com_margin_m,
                summary.min_zmp_margin_m,
                c.min_zmp_margin_m,
                c.pause_brake_time_s
            );
            for f in &summary.files {
                println!("wrote {}", f.display());
            }
            Ok(())
        }
    }
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("biped: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
