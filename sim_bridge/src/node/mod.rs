//! The `sim_bridge` ROS 2 node: the robot in MuJoCo, driven over DDS like a servo board.
//!
//! - subscribes `sim/joint_commands` (sensor_msgs/msg/JointState, servo targets by URDF joint
//!   name; the joint_bridge node's `sim` backend sends them; a message without names turns
//!   the torque off, the next one with names turns it back on);
//! - publishes, every `1 / clock_rate_hz` of simulated time: `joint_states`
//!   (sensor_msgs/msg/JointState, measured positions and velocities of every joint),
//!   `sim/base_pose` (geometry_msgs/msg/PoseStamped, ground truth of the base link in
//!   `world_frame`), `sim/cop` (geometry_msgs/msg/PointStamped, the centre of pressure of the
//!   floor contact forces, when the floor carries the robot), `sim/support_polygon`
//!   (geometry_msgs/msg/PolygonStamped, the convex hull of the loaded soles), the ground
//!   truth again as the TF edge `world_frame` → `<base link>_gt` on `/tf`
//!   (tf2_msgs/msg/TFMessage: beside the fleet's `odom` → base link, to compare),
//!   `sim/markers` (visualization_msgs/msg/MarkerArray: the measured centre of pressure and
//!   support polygon, for RViz and Foxglove), `imu/data` (sensor_msgs/msg/Imu: what an IMU
//!   at the base link's origin reads, in the base link's frame: orientation, angular
//!   velocity, specific force, +9.81 m/s² up standing still; exact, covariances 0 =
//!   unknown, REP-145), and `/clock` (rosgraph_msgs/msg/Clock). In this order: `joint_states`
//!   and `imu/data` (what the fleet's nodes act on), `/clock`, then the rest (stamped: a
//!   reader keys them by their stamp, not by the `/clock` before them);
//! - reports a fall once on `sim/fall` (std_msgs/msg/String, the reason) and `/rosout`;
//! - serves `~/pause` (std_srvs/srv/SetBool, as Gazebo's pause and unpause of physics):
//!   `true` stops simulated time where it is (`/clock` and the states are sent again every
//!   50 ms, the servos hold their targets), `false` lets it run on. With `start_paused` the
//!   simulation waits at t = 0 for the first `false` (`biped walk --composed` starts it so,
//!   then releases it once the walk command is in).
//! - with `wait_for_run_until`, reads `~/run_until` (rosgraph_msgs/msg/Clock, latched): the
//!   simulation steps only while t is before the newest time received (as Gazebo's
//!   `run_to_sim_time`), waiting at t = 0 for the first; held there, `/clock` and the states
//!   are sent again every 50 ms, and the nodes serve their services at those repeats.
//!   `biped walk --estop-at`/`--pause-at` holds simulated time so while its service calls
//!   are answered: each stop lands at the same simulated instant however loaded the machine.
//!
//! Time: with `lockstep` (default) the simulation steps to t + 1/clock_rate_hz only once the
//! joint_bridge has answered tick t (a `sim/joint_commands` stamped t or later; while waiting,
//! `/clock` and the states are sent again every 50 ms so late peers catch up). Every node on
//! `use_sim_time` then computes exactly what it would in real time, whatever the machine's
//! load: the run is deterministic. `real_time_factor` paces the simulation against the wall
//! clock (1 = real time; 0 = as fast as the fleet answers). After a stall (the fleet late to
//! answer) a paced simulation makes up at most 50 ms and then goes on at its pace, behind
//! the wall clock: it never runs faster than its pace for long, as a robot could not.
//!
//! Parameters: `robot_description_file` (URDF; empty for the built-in robot), `mjcf_file` and
//! `joint_map_file` (a MuJoCo scene of the robot and its map to the URDF's names, instead of
//! building the simulation from the URDF; the scene then owns its physics and servos), `lockstep`
//! (true), `real_time_factor` (1.0), `clock_rate_hz` (100), `world_frame` (`world`),
//! `start_paused` (false), `wait_for_run_until` (false), `command_delay_s` (0: the servos
//! act on a command that much simulated time after it comes, at its physics step, as a
//! robot's servo bus and driver delay it; [`crate::DelayLine`]), and the
//! simulator settings of [`sim_bridge::SimConfig`] (`kp_nm_per_rad`, `kv_nm_s_per_rad`,
//! `torque_limit_nm` (0 = each joint's URDF effort), `armature_kg_m2`, `timestep_s`,
//! `friction`, `fall_tilt_deg`, `fall_height_drop_m`). The robot starts standing on the floor
//! at zero joint angles (straight legs), servos on.

use std::collections::{BTreeMap, HashMap};
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use crate::{JointMap, Sim, SimConfig};
use anyhow::Context as _;
use biped_msgs::msg::{
    Clock, ColorRGBA, Header, Imu, JointState, Marker, MarkerArray, Point, Point32, PointStamped,
    Polygon, PolygonStamped, Pose, PoseStamped, StringMsg, TFMessage, Time, Transform,
    TransformStamped,
};
use biped_msgs::srv::SetBool;
use ik_solver::LegRoleMap;
use node_runtime::{Host, NodeSetup, Publisher, RosNode, coalesce_sends};
use ros2_client::ParameterValue;

const SIM_PARAMS: [&str; 8] = [
    "kp_nm_per_rad",
    "kv_nm_s_per_rad",
    "torque_limit_nm",
    "armature_kg_m2",
    "timestep_s",
    "friction",
    "fall_tilt_deg",
    "fall_height_drop_m",
];
const NODE_PARAMS: [&str; 11] = [
    "robot_description_file",
    "leg_map_file",
    "mjcf_file",
    "joint_map_file",
    "lockstep",
    "real_time_factor",
    "clock_rate_hz",
    "world_frame",
    "start_paused",
    "wait_for_run_until",
    "command_delay_s",
];

/// The simulator settings from the node's parameters (defaults: [`SimConfig::default`]).
fn sim_config(setup: &NodeSetup) -> anyhow::Result<SimConfig> {
    let d = SimConfig::default();
    let torque_limit = setup.f64_param("torque_limit_nm", 0.0)?;
    let cfg = SimConfig {
        kp_nm_per_rad: setup.f64_param("kp_nm_per_rad", d.kp_nm_per_rad)?,
        kv_nm_s_per_rad: setup.f64_param("kv_nm_s_per_rad", d.kv_nm_s_per_rad)?,
        torque_limit_nm: (torque_limit != 0.0).then_some(torque_limit),
        armature_kg_m2: setup.f64_param("armature_kg_m2", d.armature_kg_m2)?,
        timestep_s: setup.f64_param("timestep_s", d.timestep_s)?,
        friction: setup.f64_param("friction", d.friction)?,
        fall_tilt_deg: setup.f64_param("fall_tilt_deg", d.fall_tilt_deg)?,
        fall_height_drop_m: setup.f64_param("fall_height_drop_m", d.fall_height_drop_m)?,
        settle_s: 0.0,
    };
    cfg.validate()
        .map_err(|e| anyhow::anyhow!("parameter {e}"))?;
    Ok(cfg)
}

/// `sim/markers`: the measured centre of pressure (a red sphere, deleted while the floor
/// does not carry the robot) and the measured support polygon (a yellow line), on the floor.
fn measured_markers(header: &Header, cop: Option<[f64; 2]>, polygon: &[[f64; 2]]) -> MarkerArray {
    const Z_M: f64 = 0.003;
    let cop = match cop {
        Some([x, y]) => Marker::sphere(
            header,
            "measured_cop",
            0,
            Point { x, y, z: Z_M },
            0.01,
            ColorRGBA::rgba(0.9, 0.1, 0.1, 1.0),
        ),
        None => Marker::delete(header, "measured_cop", 0),
    };
    let support = Marker::closed_line(
        header,
        "measured_support_polygon",
        0,
        polygon,
        Z_M,
        0.002,
        ColorRGBA::rgba(0.95, 0.85, 0.1, 1.0),
    );
    MarkerArray {
        markers: vec![cop, support],
    }
}

/// The node's publishers.
struct Outputs {
    joint_states: Publisher<JointState>,
    base_pose: Publisher<PoseStamped>,
    cop: Publisher<PointStamped>,
    support: Publisher<PolygonStamped>,
    fall: Publisher<StringMsg>,
    clock: Publisher<Clock>,
    tf: Publisher<TFMessage>,
    markers: Publisher<MarkerArray>,
    imu: Publisher<Imu>,
    world_frame: String,
    /// The IMU's frame: the base link.
    base_frame: String,
    /// The ground truth's child frame on `/tf`: the base link's name + `_gt`.
    ground_truth_frame: String,
}

impl Outputs {
    /// Publishes the state at the simulator's present time: the IMU and the joint states,
    /// then `/clock`, then the ground truth and the contact topics.
    fn publish(&self, ros: &RosNode, sim: &Sim, t: Time) {
        let header = |frame: &str| Header {
            stamp: t,
            frame_id: frame.to_owned(),
        };
        // (topic, error): one throttle per topic, so a failing topic does not hold back the
        // error of another.
        let mut failed = Vec::new();
        let mut check = |what: &str, r: Result<(), String>| {
            if let Err(e) = r {
                failed.push((what.to_owned(), e));
            }
        };
        // Each burst goes to each reader process as one datagram (RustDDS's
        // `coalesce_sends`; BENCHMARKS.md, "One datagram per reader process a tick"): what the
        // fleet acts on, sent at once, then the observers' topics.
        coalesce_sends(|| self.publish_for_the_fleet(sim, t, &header, &mut check));
        coalesce_sends(|| self.publish_for_observers(ros, sim, &header, &mut check));
        for (what, e) in failed {
            ros.error_throttled(&format!("publish {what}"), &format!("publish {what}: {e}"));
        }
    }

    /// The IMU and the joint states, then `/clock`.
    fn publish_for_the_fleet(
        &self,
        sim: &Sim,
        t: Time,
        header: &dyn Fn(&str) -> Header,
        check: &mut dyn FnMut(&str, Result<(), String>),
    ) {
        // The IMU first: only the joint bridge reads it, so the burst's datagram to the
        // joint bridge, the lockstep's next hop, is the first gathered and the first sent.
        let imu = sim.imu();
        check(
            "imu/data",
            self.imu
                .publish(Imu {
                    header: header(&self.base_frame),
                    orientation: (&imu.orientation).into(),
                    angular_velocity: (&imu.angular_velocity_rad_s).into(),
                    linear_acceleration: (&imu.specific_force_m_s2).into(),
                    // Ground truth: no error, but no covariance claimed either (0: unknown).
                    ..Imu::default()
                })
                .map_err(|e| e.to_string()),
        );
        check(
            "joint_states",
            self.joint_states
                .publish(JointState {
                    header: header(""),
                    name: sim.joint_names().to_vec(),
                    position: sim.joint_positions_rad(),
                    velocity: sim.joint_velocities_rad_s(),
                    effort: Vec::new(),
                })
                .map_err(|e| e.to_string()),
        );
        // `/clock` after what the fleet's nodes act on (a node ticking on it has that tick's
        // joint states and IMU) and before the ground truth and the observers' topics: in
        // lockstep the next tick starts a few sends earlier (four processes 9 % faster,
        // BENCHMARKS.md, "/clock before the observers' topics"). Their readers key them by
        // stamp.
        check(
            "/clock",
            self.clock
                .publish(Clock { clock: t })
                .map_err(|e| e.to_string()),
        );
    }

    /// The ground truth, the contacts and their markers.
    fn publish_for_observers(
        &self,
        ros: &RosNode,
        sim: &Sim,
        header: &dyn Fn(&str) -> Header,
        check: &mut dyn FnMut(&str, Result<(), String>),
    ) {
        let base = sim.base_pose();
        let contacts = sim.contacts();
        check(
            "sim/base_pose",
            self.base_pose
                .publish(PoseStamped {
                    header: header(&self.world_frame),
                    pose: Pose::from(&base),
                })
                .map_err(|e| e.to_string()),
        );
        check(
            "/tf",
            self.tf
                .publish(TFMessage {
                    transforms: vec![TransformStamped {
                        header: header(&self.world_frame),
                        child_frame_id: self.ground_truth_frame.clone(),
                        transform: Transform::from(&base),
                    }],
                })
                .map_err(|e| e.to_string()),
        );
        if let Some([x, y]) = contacts.cop_world_m {
            check(
                "sim/cop",
                self.cop
                    .publish(PointStamped {
                        header: header(&self.world_frame),
                        point: Point { x, y, z: 0.0 },
                    })
                    .map_err(|e| e.to_string()),
            );
        }
        check(
            "sim/support_polygon",
            self.support
                .publish(PolygonStamped {
                    header: header(&self.world_frame),
                    polygon: Polygon {
                        points: contacts
                            .support_polygon
                            .iter()
                            .map(|p| Point32 {
                                x: p[0] as f32,
                                y: p[1] as f32,
                                z: 0.0,
                            })
                            .collect(),
                    },
                })
                .map_err(|e| e.to_string()),
        );
        // Built only while someone looks: the markers are for viewers alone.
        if self.markers.subscription_count(ros) > 0 {
            check(
                "sim/markers",
                self.markers
                    .publish(measured_markers(
                        &header(&self.world_frame),
                        contacts.cop_world_m,
                        &contacts.support_polygon,
                    ))
                    .map_err(|e| e.to_string()),
            );
        }
    }
}

/// Runs the node with `setup` (its arguments and parameters) on `host` until the host
/// stops: alone in its process (the `sim_bridge` binary) or composed with others in one.
pub async fn run(setup: NodeSetup, host: Host) -> anyhow::Result<()> {
    setup.only_ros_args()?;
    let known: Vec<&str> = SIM_PARAMS.iter().chain(&NODE_PARAMS).copied().collect();
    node_runtime::check_known(&setup.params, &known)?;
    let robot_file = setup.str_param("robot_description_file", "")?;
    let leg_map_file = setup.str_param("leg_map_file", "")?;
    let role_map = LegRoleMap::from_file_or_none(&leg_map_file)
        .with_context(|| format!("leg_map_file `{leg_map_file}`"))?;
    let lockstep = match setup.params.get("lockstep") {
        None => true,
        Some(v) => v
            .as_bool()
            .ok_or_else(|| anyhow::anyhow!("parameter `lockstep` = {v:?}: not a boolean"))?,
    };
    let rtf = setup.f64_param("real_time_factor", 1.0)?;
    let rate_hz = setup.f64_param("clock_rate_hz", 100.0)?;
    let world_frame = setup.str_param("world_frame", "world")?;
    let mut paused = setup.bool_param("start_paused", false)?;
    let gated = setup.bool_param("wait_for_run_until", false)?;
    if !(rtf.is_finite() && (0.0..=1000.0).contains(&rtf)) {
        anyhow::bail!(
            "parameter `real_time_factor` = {rtf} is out of range [0, 1000] (0 = as fast as possible)"
        );
    }
    if !(1.0..=1000.0).contains(&rate_hz) {
        anyhow::bail!("parameter `clock_rate_hz` = {rate_hz} is out of range [1, 1000] Hz");
    }
    let cfg = sim_config(&setup)?;
    let urdf = if robot_file.is_empty() {
        ik_solver::DEFAULT_URDF.to_owned()
    } else {
        std::fs::read_to_string(&robot_file)
            .with_context(|| format!("robot_description_file `{robot_file}`"))?
    };
    let mjcf_file = setup.str_param("mjcf_file", "")?;
    let map_file = setup.str_param("joint_map_file", "")?;
    let mut sim = match (mjcf_file.is_empty(), map_file.is_empty()) {
        (true, true) => Sim::from_urdf_str(&urdf, role_map.as_ref(), &cfg).with_context(|| {
            format!("robot_description_file `{robot_file}`, leg_map_file `{leg_map_file}`")
        })?,
        (false, false) => {
            let map = JointMap::from_yaml_file(&map_file)
                .with_context(|| format!("joint_map_file `{map_file}`"))?;
            Sim::from_mjcf_file(&mjcf_file, &map, &urdf, role_map.as_ref(), &cfg).with_context(
                || {
                    format!(
                        "mjcf_file `{mjcf_file}` with joint_map_file `{map_file}`, robot_description_file `{robot_file}`, leg_map_file `{leg_map_file}`"
                    )
                },
            )?
        }
        _ => anyhow::bail!(
            "parameters `mjcf_file` = `{mjcf_file}` and `joint_map_file` = `{map_file}`: give both (a scene and its map to the URDF's names) or neither"
        ),
    };
    let cfg = sim.config().clone();
    let period_ns = (1e9 / rate_hz).round() as i64;
    let steps_per_tick = (period_ns as f64 * 1e-9 / cfg.timestep_s).round() as u64;
    if steps_per_tick == 0
        || (steps_per_tick as f64 * cfg.timestep_s * 1e9 - period_ns as f64).abs() > 1.0
    {
        anyhow::bail!(
            "parameter `clock_rate_hz` = {rate_hz}: its period must be a whole number of physics steps of timestep_s = {} s",
            cfg.timestep_s
        );
    }
    let step_ns = period_ns / steps_per_tick as i64;
    let command_delay_s = setup.f64_param("command_delay_s", 0.0)?;
    let delay_steps = (command_delay_s / cfg.timestep_s).round();
    if !(0.0..=1.0).contains(&command_delay_s)
        || (delay_steps * cfg.timestep_s - command_delay_s).abs() > 1e-9
    {
        anyhow::bail!(
            "parameter `command_delay_s` = {command_delay_s}: must be from 0 to 1 s and a whole number of physics steps of timestep_s = {} s",
            cfg.timestep_s
        );
    }
    let mut delay_line = crate::DelayLine::new(delay_steps as i64 * step_ns);
    let names: Vec<String> = sim.joint_names().to_vec();
    let robot = sim.biped().robot();
    let base_frame = robot.links()[robot.root()].name.clone();
    let ground_truth_frame = format!("{base_frame}_gt");
    sim.stand(&vec![0.0; names.len()])?;

    let mut declared: BTreeMap<String, ParameterValue> = BTreeMap::from([
        (
            "robot_description_file".into(),
            ParameterValue::String(robot_file.clone()),
        ),
        (
            "leg_map_file".into(),
            ParameterValue::String(leg_map_file.clone()),
        ),
        (
            "mjcf_file".into(),
            ParameterValue::String(mjcf_file.clone()),
        ),
        (
            "joint_map_file".into(),
            ParameterValue::String(map_file.clone()),
        ),
        ("lockstep".into(), ParameterValue::Boolean(lockstep)),
        ("real_time_factor".into(), ParameterValue::Double(rtf)),
        ("clock_rate_hz".into(), ParameterValue::Double(rate_hz)),
        (
            "world_frame".into(),
            ParameterValue::String(world_frame.clone()),
        ),
        ("start_paused".into(), ParameterValue::Boolean(paused)),
        ("wait_for_run_until".into(), ParameterValue::Boolean(gated)),
        (
            "command_delay_s".into(),
            ParameterValue::Double(command_delay_s),
        ),
    ]);
    for (k, v) in [
        ("kp_nm_per_rad", cfg.kp_nm_per_rad),
        ("kv_nm_s_per_rad", cfg.kv_nm_s_per_rad),
        ("torque_limit_nm", cfg.torque_limit_nm.unwrap_or(0.0)),
        ("armature_kg_m2", cfg.armature_kg_m2),
        ("timestep_s", cfg.timestep_s),
        ("friction", cfg.friction),
        ("fall_tilt_deg", cfg.fall_tilt_deg),
        ("fall_height_drop_m", cfg.fall_height_drop_m),
    ] {
        declared.insert(k.into(), ParameterValue::Double(v));
    }
    let mut ros = RosNode::start(
        &host,
        setup,
        &declared,
        Some(node_runtime::read_at_startup()),
    )?;
    let stop = host.stop_flag();
    let commands = ros.subscription::<JointState>("sim/joint_commands")?;
    let pause_srv = ros.service::<SetBool>("~/pause")?;
    // Latched: the newest bound holds for a peer that joins late, and a bound sent before
    // this node started is not lost.
    let run_until = if gated {
        Some(ros.latched_subscription::<Clock>("~/run_until")?)
    } else {
        None
    };
    let out = Outputs {
        joint_states: ros.publisher::<JointState>("joint_states")?,
        base_pose: ros.publisher::<PoseStamped>("sim/base_pose")?,
        cop: ros.publisher::<PointStamped>("sim/cop")?,
        support: ros.publisher::<PolygonStamped>("sim/support_polygon")?,
        fall: ros.publisher::<StringMsg>("sim/fall")?,
        clock: ros.publisher::<Clock>("/clock")?,
        tf: ros.publisher::<TFMessage>("/tf")?,
        markers: ros.publisher::<MarkerArray>("sim/markers")?,
        imu: ros.publisher::<Imu>("imu/data")?,
        world_frame,
        base_frame,
        ground_truth_frame,
    };
    let executor = ros.executor()?;
    let index: HashMap<String, usize> = names
        .iter()
        .enumerate()
        .map(|(i, n)| (n.clone(), i))
        .collect();
    ros.info(&format!(
        "ready: robot {} in MuJoCo from {} ({} joints, {:.3} kg, servos kp {} N·m/rad: joint_bridge's sag_compensation_kp should match), {} Hz clock, {}, {}, {}",
        sim.biped().robot().name(),
        if mjcf_file.is_empty() {
            "the URDF".to_string()
        } else {
            format!("the scene {mjcf_file}")
        },
        names.len(),
        sim.total_mass_kg(),
        cfg.kp_nm_per_rad,
        rate_hz,
        if lockstep {
            "lockstep with the joint_bridge"
        } else {
            "free-running"
        },
        if rtf > 0.0 {
            format!("{rtf}x real time")
        } else {
            "as fast as possible".into()
        },
        if delay_line.delay_ns() > 0 {
            format!(
                "the servos act on a command {} ms after it comes (command_delay_s)",
                delay_line.delay_ns() as f64 / 1e6
            )
        } else {
            "the servos act on a command as it comes".into()
        }
    ));

    /// Simulated time a paced simulation makes up after a stall, at most (s).
    const MAX_CATCH_UP_S: f64 = 0.05;
    let mut t_ns: i64 = 0;
    let mut newest_answer_ns = i64::MIN;
    let mut reported_fall = false;
    let mut unknown_reported = std::collections::HashSet::new();
    // A command acting on the servos: its targets (names the robot lacks reported once), or
    // torque off when it names no joint.
    let mut apply = |sim: &mut Sim, cmd: JointState| {
        if cmd.name.is_empty() {
            if sim.torque_on() {
                ros.warn("torque off (an empty sim/joint_commands)");
            }
            sim.set_torque(false);
            return;
        }
        if cmd.name.len() != cmd.position.len() {
            ros.warn(&format!(
                "sim/joint_commands with {} names and {} positions ignored",
                cmd.name.len(),
                cmd.position.len()
            ));
            return;
        }
        let mut targets = sim.targets_rad().to_vec();
        for (n, &p) in cmd.name.iter().zip(&cmd.position) {
            match index.get(n) {
                Some(&i) => targets[i] = p,
                None => {
                    if unknown_reported.insert(n.clone()) {
                        ros.warn(&format!(
                            "sim/joint_commands: unknown joint `{n}` ignored (reported once)"
                        ));
                    }
                }
            }
        }
        match sim.set_targets(&targets) {
            Ok(()) => {
                if !sim.torque_on() {
                    sim.set_torque(true);
                    ros.info("torque on");
                }
            }
            Err(e) => ros.warn(&format!("sim/joint_commands refused: {e}")),
        }
    };
    let mut last_publish = Instant::now();
    let mut inbox: Option<JointState> = None;
    // With `wait_for_run_until`: the simulation steps only while t is before this (ns);
    // before the first `~/run_until`, it waits at t = 0.
    let mut run_until_ns = if gated { 0 } else { i64::MAX };
    // The wall time of simulated time 0 at the pace; moved later after a stall.
    let mut wall0 = Instant::now();
    out.publish(&ros, &sim, Time::from_nanos(t_ns));
    let mut bound = node_runtime::WaitBound::every(Duration::from_millis(50));
    let result: anyhow::Result<()> = executor
        .run(async {
            while !stop.load(Ordering::SeqCst) {
                while let Ok(Some((id, req))) = pause_srv.receive_request() {
                    let said = match (paused, req.data) {
                        (false, true) => format!("paused at t = {:.3} s", t_ns as f64 * 1e-9),
                        (true, false) => {
                            // A paced simulation goes on at its pace from now.
                            if rtf > 0.0 {
                                let since = Duration::from_secs_f64(t_ns as f64 * 1e-9 / rtf);
                                wall0 = Instant::now().checked_sub(since).unwrap_or(wall0);
                            }
                            format!("running from t = {:.3} s", t_ns as f64 * 1e-9)
                        }
                        (true, true) => {
                            format!("already paused at t = {:.3} s", t_ns as f64 * 1e-9)
                        }
                        (false, false) => {
                            format!("already running, t = {:.3} s", t_ns as f64 * 1e-9)
                        }
                    };
                    paused = req.data;
                    ros.answer_said(&pause_srv, "~/pause", id, said);
                }
                while let Some(c) = run_until
                    .as_ref()
                    .and_then(|s| ros.take_next(s, "~/run_until"))
                {
                    run_until_ns = c.clock.to_nanos();
                }
                let held = t_ns >= run_until_ns;
                // Commands: received now, acting `command_delay_s` later (at once without it); the
                // newest targets win.
                let mut incoming: Vec<JointState> = inbox.take().into_iter().collect();
                while let Some(cmd) = ros.take_next(&commands, "sim/joint_commands") {
                    incoming.push(cmd);
                }
                for cmd in incoming {
                    newest_answer_ns = newest_answer_ns.max(cmd.header.stamp.to_nanos());
                    if let Some(early) = delay_line.push(t_ns, cmd) {
                        apply(&mut sim, early);
                    }
                }
                while let Some(cmd) = delay_line.pop_due(t_ns) {
                    apply(&mut sim, cmd);
                }
                let answered = !lockstep || newest_answer_ns >= t_ns;
                let due = rtf == 0.0
                    || wall0.elapsed().as_secs_f64() * rtf >= (t_ns + period_ns) as f64 * 1e-9;
                if answered && due && !paused && !held {
                    // The tick's physics steps, a command that falls due inside them acting from
                    // its step on.
                    let mut done = 0;
                    while done < steps_per_tick {
                        let at_ns = t_ns + done as i64 * step_ns;
                        while let Some(cmd) = delay_line.pop_due(at_ns) {
                            apply(&mut sim, cmd);
                        }
                        let to_next = delay_line.next_due_ns().map_or(u64::MAX, |due_ns| {
                            ((due_ns - at_ns + step_ns - 1) / step_ns) as u64
                        });
                        let n = to_next.clamp(1, steps_per_tick - done);
                        sim.physics_steps(n)?;
                        done += n;
                    }
                    t_ns += period_ns;
                    if rtf > 0.0 {
                        let behind_s = wall0.elapsed().as_secs_f64() * rtf - t_ns as f64 * 1e-9;
                        if behind_s > MAX_CATCH_UP_S {
                            wall0 += Duration::from_secs_f64((behind_s - MAX_CATCH_UP_S) / rtf);
                        }
                    }
                    out.publish(&ros, &sim, Time::from_nanos(t_ns));
                    last_publish = Instant::now();
                    if !reported_fall && let Some(f) = sim.fallen() {
                        reported_fall = true;
                        let msg = format!("the robot fell at t = {:.3} s: {}", f.t_s, f.reason);
                        ros.error(&msg);
                        if let Err(e) = out.fall.publish(StringMsg { data: msg }) {
                            ros.error_throttled(
                                "publish sim/fall",
                                &format!("publish sim/fall: {e}"),
                            );
                        }
                    }
                    continue;
                }
                if (!answered || paused || held)
                    && last_publish.elapsed() >= Duration::from_millis(50)
                {
                    // Still waiting for tick t's answer, paused or held at `~/run_until`: say t
                    // again (a late peer catches up; a node serves its services at a repeat).
                    out.publish(&ros, &sim, Time::from_nanos(t_ns));
                    last_publish = Instant::now();
                }
                // Wait for a command, or for the wall clock when pacing (the parked thread's own
                // deadline, no async-io timer); otherwise (in lockstep, for the answer; paused;
                // held) at most 50 ms, on one deadline kept across the ticks.
                let pace = (rtf > 0.0 && answered && !paused && !held).then(|| {
                    Duration::from_secs_f64(
                        ((t_ns + period_ns) as f64 * 1e-9 / rtf - wall0.elapsed().as_secs_f64())
                            .clamp(0.0, 0.05),
                    )
                });
                use smol::future::FutureExt as _;
                inbox = async { commands.async_take().await.ok().map(|(cmd, _)| cmd) }
                    .or(async {
                        match pace {
                            Some(wait) => {
                                node_runtime::wait::sleep_until(Instant::now() + wait).await;
                            }
                            None => {
                                bound.fired().await;
                            }
                        }
                        None
                    })
                    .or(async {
                        // Held: a new bound wakes the loop at once.
                        match (&run_until, held) {
                            (Some(sub), true) => {
                                if let Ok((c, _)) = sub.async_take().await {
                                    run_until_ns = c.clock.to_nanos();
                                }
                                None
                            }
                            _ => std::future::pending().await,
                        }
                    })
                    .await;
            }
            Ok(())
        })
        .await;
    ros.info("shutting down");
    result
}
