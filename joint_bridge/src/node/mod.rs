//! The `joint_bridge` ROS 2 node: a thin wrapper over the joint_bridge library.
//!
//! Subscribes `joint_commands` (sensor_msgs/msg/JointState, positions by URDF joint name);
//! drives the backend through the bridge (URDF limits, velocity limits, servo-sag
//! compensation, watchdog); publishes `joint_states` (sensor_msgs/msg/JointState, every driven
//! joint) at each tick (`rate_hz`, or each command while commands come: `tick_on_command`) —
//! except with the `sim` backend, whose simulator publishes the measured `joint_states`
//! itself.
//!
//! Parameters: `robot_description_file` (URDF; empty for the built-in robot), `backend`
//! (`mock`, `sim` or `serial`), `rate_hz` (100), `tick_on_command` (true: on the monotonic
//! clock a command ticks the bridge as it comes, see below), `watchdog_timeout_s` (0.25),
//! `watchdog_action` (`hold` or `limp`), `start_ramp_s` (the move from the measured pose to
//! the first command, 2 s), `acceleration_limit_rad_s2` (every joint, 100),
//! `default_velocity_rad_s` (joints the URDF leaves without a speed limit, 2), `max_tick_s`
//! (the longest time one tick moves the joints for, 0.05 s), `estop_follow_s` (how long an
//! e-stop keeps following the commands while the planner brakes the walk along its path,
//! 0.4 s; 0: hold at once), `sag_compensation_kp` (the servos' stiffness in N·m/rad for the
//! sag compensation; 0 = off), `gyro_damping_nm_s_per_rad` (damp the body's roll and pitch
//! with the legs on the floor from `imu/data`, sensor_msgs/msg/Imu in the base link's frame,
//! as this much more servo derivative gain would; needs `sag_compensation_kp`; 0 = off),
//! `sim_wait_s` (how long the `sim` backend waits for the
//! simulator, 10 s), `lockstep_wait_s`, the serial board's `protocol`, `port`, `baud`,
//! `calibration_file`, `reply_timeout_s`, `retry_first_s`, `retry_max_s`, and the read-only
//! `joint_states_measured` (whether `joint_states` carries measured positions or, for
//! backends that cannot measure, the commanded ones).
//!
//! Services: `~/estop` and `~/reset` (std_srvs/srv/Trigger: hold and ignore commands, then
//! take them again) and `~/set_torque` (std_srvs/srv/SetBool), answered between ticks.
//!
//! `~/holding` (std_msgs/msg/Bool, latched): true while an operator hold (e-stop, torque off,
//! inactive) ignores joint commands; the planner pauses its walk meanwhile.
//!
//! A managed (lifecycle) node: `~/get_state`, `~/change_state`, `~/get_available_transitions`
//! (lifecycle_msgs/srv) and `~/transition_event`; inactive holds with torque on and ignores
//! commands, shutdown holds then turns the torque off and ends the node. With `autostart`
//! (true) the node configures and activates itself at start; with `autostart:=false` it waits
//! unconfigured (torque off) for a lifecycle manager.
//!
//! With a serial board the node also publishes `/diagnostics`
//! (diagnostic_msgs/msg/DiagnosticArray, once a second): the board's state and wire
//! counters (timeouts, corrupted replies, reconnections, servo error bits).
//!
//! On the monotonic clock, with `tick_on_command` (the default), each command ticks the
//! bridge as it comes (no sooner than half a period after the last tick), and without
//! commands the bridge ticks by itself at `rate_hz` (from one and a half periods after the
//! last command, or a period for a slower sender, clear of its next command): a planner's
//! command reaches the servos a DDS hop after it was sent, not
//! up to a period later at the bridge's own tick, and two timers' phases never put two
//! commands in one tick and none in the next ([`crate::pacing`]). `false`: the bridge ticks
//! at `rate_hz` alone and takes what came at each tick.
//!
//! With `use_sim_time` the bridge ticks on `/clock`, in lockstep: tick t waits (up to
//! `lockstep_wait_s` of wall time) for the `joint_commands` stamped t, so a lockstep simulator
//! gets the answer to every tick computed from that tick's command. A command stamped for a
//! tick still to come (a gait planner with `plan_ahead`, or one quicker than `/clock`) is
//! held until that tick (up to 1 s ahead, 64 commands; stamped further ahead, as by a peer
//! on another clock, it is taken at once). The node's thread wakes for a command (or a body
//! rate) only while a tick waits for it; what comes between ticks waits in its reader (keep
//! last 10) and is taken, in the order it came, when the next `/clock` comes.

mod lifecycle;
mod serial_setup;
mod sim_link;

use std::collections::BTreeMap;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use crate::managed::ManagedState;
use crate::{
    Backend, Backoff, BridgeConfig, Event, GyroDamping, JointBridge, JointSpec, Lifecycle,
    MockBackend, Operator, SagCompensation, TickPacing, TimeoutAction,
};
use biped_msgs::msg::{
    BoolMsg, DiagnosticArray, DiagnosticStatus, Header, Imu, JointState, KeyValue,
};
use biped_msgs::srv::{SetBool, SetBoolRequest, Trigger, TriggerRequest, TriggerResponse};
use ik_solver::BipedModel;
use node_runtime::{Host, NodeSetup, RosNode, Tick, TickSource};
use ros2_client::ParameterValue;
use smol::future::FutureExt as _;

use lifecycle::LifecycleServices;
use serial_setup::{SerialParams, in_range};
use sim_link::{SimLink, SimLinkHandle};

/// The default of `estop_follow_s`: long enough for the gait planner's pause brake
/// (`pause_brake_time_s`, at most 0.25 s for the timings `biped plan --fastest` finds) plus
/// a few ticks for `~/holding` to reach it.
const ESTOP_FOLLOW_S: f64 = 0.4;

const PARAMS: [&str; 17] = [
    "autostart",
    "tick_on_command",
    "robot_description_file",
    "leg_map_file",
    "backend",
    "rate_hz",
    "watchdog_timeout_s",
    "watchdog_action",
    "sag_compensation_kp",
    "gyro_damping_nm_s_per_rad",
    "sim_wait_s",
    "lockstep_wait_s",
    "start_ramp_s",
    "acceleration_limit_rad_s2",
    "default_velocity_rad_s",
    "max_tick_s",
    "estop_follow_s",
];

/// Runs the node with `setup` (its arguments and parameters) on `host` until the host
/// stops: alone in its process (the `joint_bridge` binary) or composed with others in one.
pub async fn run(setup: NodeSetup, host: Host) -> anyhow::Result<()> {
    setup.only_ros_args()?;
    let known: Vec<&str> = PARAMS
        .iter()
        .chain(&serial_setup::PARAMS)
        .copied()
        .collect();
    node_runtime::check_known(&setup.params, &known)?;
    let robot_file = setup.str_param("robot_description_file", "")?;
    let leg_map_file = setup.str_param("leg_map_file", "")?;
    let backend_name = setup.str_param("backend", "mock")?;
    let autostart = setup.bool_param("autostart", true)?;
    let rate_hz = setup.f64_param("rate_hz", 100.0)?;
    let timeout_s = setup.f64_param("watchdog_timeout_s", 0.25)?;
    let action_name = setup.str_param("watchdog_action", "hold")?;
    let kp = setup.f64_param("sag_compensation_kp", 0.0)?;
    let gyro_damping = setup.f64_param("gyro_damping_nm_s_per_rad", 0.0)?;
    let sim_wait_s = setup.f64_param("sim_wait_s", 10.0)?;
    let lockstep_wait_s = setup.f64_param("lockstep_wait_s", 0.5)?;
    let tick_on_command = setup.bool_param("tick_on_command", true)?;
    if !(1.0..=1000.0).contains(&rate_hz) {
        anyhow::bail!("parameter `rate_hz` = {rate_hz} is out of range [1, 1000] Hz");
    }
    if !(timeout_s > 0.0 && timeout_s <= 60.0) {
        anyhow::bail!("parameter `watchdog_timeout_s` = {timeout_s} is out of range (0, 60] s");
    }
    if !(kp.is_finite() && (0.0..=1e4).contains(&kp)) {
        anyhow::bail!(
            "parameter `sag_compensation_kp` = {kp} is out of range [0, 10000] N·m/rad (0 = off)"
        );
    }
    if !(gyro_damping.is_finite() && (0.0..=100.0).contains(&gyro_damping)) {
        anyhow::bail!(
            "parameter `gyro_damping_nm_s_per_rad` = {gyro_damping} is out of range [0, 100] N·m·s/rad (0 = off)"
        );
    }
    if gyro_damping > 0.0 && kp == 0.0 {
        anyhow::bail!(
            "parameter `gyro_damping_nm_s_per_rad` = {gyro_damping} needs the servos' stiffness: set `sag_compensation_kp`"
        );
    }
    for (name, v) in [
        ("sim_wait_s", sim_wait_s),
        ("lockstep_wait_s", lockstep_wait_s),
    ] {
        if !(v > 0.0 && v <= 600.0) {
            anyhow::bail!("parameter `{name}` = {v} is out of range (0, 600] s");
        }
    }
    let action: TimeoutAction = action_name
        .parse()
        .map_err(|e: String| anyhow::anyhow!("parameter `watchdog_action`: {e}"))?;
    if !["mock", "sim", "serial"].contains(&backend_name.as_str()) {
        anyhow::bail!(
            "parameter `backend` = `{backend_name}`: not available (mock, sim or serial)"
        );
    }
    let start_ramp_s = in_range(
        "start_ramp_s",
        setup.f64_param("start_ramp_s", 2.0)?,
        0.0,
        60.0,
        "s",
    )?;
    let acceleration_rad_s2 = in_range(
        "acceleration_limit_rad_s2",
        setup.f64_param("acceleration_limit_rad_s2", 100.0)?,
        0.1,
        1e5,
        "rad/s²",
    )?;
    let default_velocity_rad_s = in_range(
        "default_velocity_rad_s",
        setup.f64_param("default_velocity_rad_s", 2.0)?,
        0.01,
        100.0,
        "rad/s",
    )?;
    let max_tick_s = in_range(
        "max_tick_s",
        setup.f64_param("max_tick_s", 0.05)?,
        0.001,
        1.0,
        "s",
    )?;
    let estop_follow_s = in_range(
        "estop_follow_s",
        setup.f64_param("estop_follow_s", ESTOP_FOLLOW_S)?,
        0.0,
        2.0,
        "s",
    )?;
    let serial = SerialParams::from_setup(&setup)?;
    let model = BipedModel::from_parameter_files(&robot_file, &leg_map_file)?;
    let mut joints = JointSpec::from_robot(model.robot());
    let sim = backend_name == "sim";
    let serial_board = if backend_name == "serial" {
        Some(serial.backend(model.robot().name(), &mut joints)?)
    } else {
        None
    };
    let names: Vec<String> = joints.iter().map(|j| j.name.clone()).collect();
    let measured = sim || (serial_board.is_some() && serial.measures());
    let what = if serial_board.is_some() {
        serial.describe()
    } else {
        backend_name.clone()
    };

    let mut declared = BTreeMap::from([
        (
            "robot_description_file".to_string(),
            ParameterValue::String(robot_file.clone()),
        ),
        (
            "leg_map_file".to_string(),
            ParameterValue::String(leg_map_file.clone()),
        ),
        (
            "backend".to_string(),
            ParameterValue::String(backend_name.clone()),
        ),
        ("rate_hz".to_string(), ParameterValue::Double(rate_hz)),
        (
            "watchdog_timeout_s".to_string(),
            ParameterValue::Double(timeout_s),
        ),
        (
            "watchdog_action".to_string(),
            ParameterValue::String(action_name.clone()),
        ),
        (
            "sag_compensation_kp".to_string(),
            ParameterValue::Double(kp),
        ),
        (
            "gyro_damping_nm_s_per_rad".to_string(),
            ParameterValue::Double(gyro_damping),
        ),
        ("sim_wait_s".to_string(), ParameterValue::Double(sim_wait_s)),
        (
            "tick_on_command".to_string(),
            ParameterValue::Boolean(tick_on_command),
        ),
        (
            "lockstep_wait_s".to_string(),
            ParameterValue::Double(lockstep_wait_s),
        ),
        (
            "joint_states_measured".to_string(),
            ParameterValue::Boolean(measured),
        ),
        (
            "start_ramp_s".to_string(),
            ParameterValue::Double(start_ramp_s),
        ),
        (
            "acceleration_limit_rad_s2".to_string(),
            ParameterValue::Double(acceleration_rad_s2),
        ),
        (
            "default_velocity_rad_s".to_string(),
            ParameterValue::Double(default_velocity_rad_s),
        ),
        ("max_tick_s".to_string(), ParameterValue::Double(max_tick_s)),
        (
            "estop_follow_s".to_string(),
            ParameterValue::Double(estop_follow_s),
        ),
        ("autostart".to_string(), ParameterValue::Boolean(autostart)),
    ]);
    declared.extend(serial.declared());
    let mut ros = RosNode::start(
        &host,
        setup,
        &declared,
        Some(node_runtime::read_at_startup()),
    )?;
    let stop = host.stop_flag();
    let sub = ros.subscription::<JointState>("joint_commands")?;
    let mut ticks = TickSource::new(&mut ros, rate_hz)?;
    let simulated = ticks.simulated();
    let mut reconnect: Option<Backoff> = None;
    let mut not_driven = Vec::new();
    let (backend, link, states_pub): (Box<dyn Backend>, Option<SimLinkHandle>, _) =
        match serial_board {
            Some((board, backoff, skipped)) => {
                reconnect = Some(backoff);
                not_driven = skipped;
                (
                    Box::new(board),
                    None,
                    Some(ros.publisher::<JointState>("joint_states")?),
                )
            }
            None if sim => {
                let (link, handle) = SimLink::new(
                    ros.publisher::<JointState>("sim/joint_commands")?,
                    ros.subscription::<JointState>("joint_states")?,
                    simulated,
                );
                (Box::new(link), Some(handle), None)
            }
            None => (
                Box::new(MockBackend::default()),
                None,
                Some(ros.publisher::<JointState>("joint_states")?),
            ),
        };
    let diagnostics = ros.publisher::<DiagnosticArray>("/diagnostics")?;
    // Latched: whether an operator hold ignores joint commands (the planner pauses its walk).
    let holding_pub = ros.latched_publisher::<BoolMsg>("~/holding")?;
    let holding_sent = std::cell::Cell::new(None::<bool>);
    let operator = OperatorServices::new(&mut ros)?;
    let lifecycle = LifecycleServices::new(
        &mut ros,
        if autostart {
            ManagedState::Active
        } else {
            ManagedState::Unconfigured
        },
    )?;
    let mut bridge = JointBridge::new(
        backend,
        joints.clone(),
        BridgeConfig {
            watchdog_timeout_s: timeout_s,
            on_timeout: action,
            start_ramp_s,
            reconnect,
            default_velocity_rad_s,
            acceleration_rad_s2,
            max_tick_s,
            estop_follow_s,
        },
    );
    let base_frame = model.robot().links()[model.robot().root()].name.clone();
    let imu = if gyro_damping > 0.0 {
        bridge =
            bridge.with_gyro_damping(GyroDamping::new(model.clone(), gyro_damping, kp, &joints)?);
        Some(ros.subscription::<Imu>("imu/data")?)
    } else {
        None
    };
    if kp > 0.0 {
        bridge = bridge.with_sag_compensation(SagCompensation::new(model, kp, &joints)?);
    }
    let executor = ros.executor()?;

    if !not_driven.is_empty() {
        ros.info(&format!(
            "not in the calibration, not driven: {}",
            not_driven.join(", ")
        ));
    }
    if !autostart {
        // Unconfigured, torque off: the lifecycle manager configures and activates.
        bridge.hold(Operator::Inactive);
    } else {
        let mut started = bridge.start();
        if link.is_some() {
            // The simulator may start after this node (or on its thread, composed): wait for
            // its first joint_states without holding the thread.
            let deadline = Instant::now() + Duration::from_secs_f64(sim_wait_s);
            while started.is_err() && Instant::now() < deadline && !stop.load(Ordering::SeqCst) {
                smol::Timer::after(Duration::from_millis(10)).await;
                started = bridge.start();
            }
            if started.is_err() && stop.load(Ordering::SeqCst) {
                // Stopped while waiting: nothing was started, nothing to turn off.
                ros.info("shutting down before the simulator answered");
                return Ok(());
            }
        }
        match started {
            Ok(()) => {}
            // A serial board retries with backoff (port absent, board unpowered...).
            Err(e) if reconnect.is_some() => ros.error(&format!(
                "backend {what}: {e}; retrying every {}..{} s",
                serial.retry_first_s, serial.retry_max_s
            )),
            Err(e) if link.is_some() => {
                anyhow::bail!("backend {backend_name}: {e}, in {sim_wait_s} s (sim_wait_s)")
            }
            Err(e) => anyhow::bail!("backend {backend_name}: {e}"),
        }
    }
    let compensation = match (kp > 0.0, gyro_damping > 0.0) {
        (true, true) => format!(
            "sag compensation for {kp} N·m/rad servos, gyro damping {gyro_damping} N·m·s/rad from imu/data"
        ),
        (true, false) => format!("sag compensation for {kp} N·m/rad servos"),
        _ => "no sag compensation".to_string(),
    };
    let states = if sim {
        "the simulator publishes the measured joint_states".to_string()
    } else if measured {
        "joint_states carries measured positions".to_string()
    } else {
        format!("joint_states carries commanded positions (the {what} backend cannot measure)")
    };
    let status = if !autostart {
        "unconfigured (autostart false: waiting for configure on ~/change_state)"
    } else if bridge.state() == Lifecycle::Active {
        "active"
    } else {
        "not connected yet (retrying)"
    };
    let clock = match (simulated, tick_on_command) {
        (true, _) => "on /clock (lockstep)",
        (false, true) => {
            "on the monotonic clock, and at each command as it comes (tick_on_command)"
        }
        (false, false) => "on the monotonic clock (tick_on_command false)",
    };
    ros.info(&format!(
        "ready: backend {what} {status}, {} joints, {rate_hz} Hz {clock}, watchdog {timeout_s} s ({action_name}), start ramp {start_ramp_s} s, {compensation}; {states}",
        names.len()
    ));
    let report = |events: Vec<Event>| {
        for e in events {
            match e {
                Event::Resumed | Event::Reconnected | Event::GyroDamping(true) => {
                    ros.info(&e.to_string())
                }
                Event::BackendFailed(_) | Event::RetryFailed { .. } => ros.error(&e.to_string()),
                _ => ros.warn(&e.to_string()),
            }
        }
    };
    let last_diagnostics = std::cell::Cell::new(None::<Instant>);
    // `~/holding` when it changed: where the operator's and the lifecycle's calls are served.
    let say_holding = |bridge: &JointBridge<Box<dyn Backend>>| {
        let holding = bridge.operator().is_some();
        if holding_sent.get() != Some(holding) {
            match holding_pub.publish(BoolMsg { data: holding }) {
                Ok(()) => holding_sent.set(Some(holding)),
                Err(e) => {
                    ros.error_throttled("publish holding", &format!("publish ~/holding: {e}"))
                }
            }
        }
    };
    // One control period at t: watchdog, write, read back, publish.
    let do_tick = |bridge: &mut JointBridge<Box<dyn Backend>>, t_s: f64| {
        operator.serve(&ros, bridge, &say_holding);
        lifecycle.serve(&ros, bridge);
        say_holding(bridge);
        let (reading, events) = bridge.tick(t_s);
        report(events);
        if let Some(link) = &link
            && bridge.state() != Lifecycle::Active
            && simulated
            && let Err(e) = link.answer_without_command(t_s)
        {
            ros.error(&format!("sim link: {e}"));
        }
        match (reading, &states_pub) {
            (Ok(r), Some(publisher)) => {
                let msg = JointState {
                    header: Header {
                        stamp: ros.node.time_now().into(),
                        frame_id: String::new(),
                    },
                    name: names.clone(),
                    position: r.positions_rad,
                    velocity: r.velocities_rad_s.unwrap_or_default(),
                    effort: Vec::new(),
                };
                if let Err(e) = publisher.publish(msg) {
                    ros.error_throttled(
                        "publish joint_states",
                        &format!("publish joint_states: {e}"),
                    );
                }
            }
            (Ok(_), None) => {}
            // While the bridge retries a failed backend, the retries say why; unconfigured,
            // there is nothing to read.
            (Err(_), _) if matches!(bridge.state(), Lifecycle::Error | Lifecycle::Unconfigured) => {
            }
            (Err(e), _) => ros.error_throttled("backend read", &format!("backend read: {e}")),
        }
        // Once a second, for backends that have diagnostics (the serial boards).
        if last_diagnostics
            .get()
            .is_none_or(|t| t.elapsed() >= Duration::from_secs(1))
            && let Some(d) = bridge.backend().diagnostics()
        {
            last_diagnostics.set(Some(Instant::now()));
            let msg = DiagnosticArray {
                header: Header {
                    stamp: ros.node.time_now().into(),
                    frame_id: String::new(),
                },
                status: vec![DiagnosticStatus {
                    level: d.level.as_byte(),
                    name: d.name,
                    message: d.message,
                    hardware_id: d.hardware_id,
                    values: d
                        .values
                        .into_iter()
                        .map(|(key, value)| KeyValue { key, value })
                        .collect(),
                }],
            };
            if let Err(e) = diagnostics.publish(msg) {
                ros.error_throttled("publish diagnostics", &format!("publish diagnostics: {e}"));
            }
        }
    };
    // The body rate of an imu/data message, in the base link's frame (an IMU elsewhere is
    // refused, said once: its rate would need the transform between the frames).
    let said_frame = std::cell::Cell::new(false);
    let body_rate = |m: &Imu| -> Option<nalgebra::Vector3<f64>> {
        if !m.header.frame_id.is_empty() && m.header.frame_id != base_frame {
            if !said_frame.replace(true) {
                ros.error(&format!(
                    "imu/data in frame `{}` ignored: gyro damping needs the body rate in the base link's frame `{base_frame}`",
                    m.header.frame_id
                ));
            }
            return None;
        }
        let w = &m.angular_velocity;
        Some(nalgebra::Vector3::new(w.x, w.y, w.z))
    };
    let t0 = Instant::now();
    executor
        .run(async {
            if !simulated {
                // On the monotonic clock: a tick at each command as it comes (with
                // `tick_on_command`), and by itself at the rate without them (`TickPacing`).
                let mut pacing = TickPacing::new(rate_hz, tick_on_command, 0.0);
                let at = |s: f64| t0 + Duration::from_secs_f64(s.max(0.0));
                while !stop.load(Ordering::SeqCst) && !lifecycle.finalized() {
                    let own_due = at(pacing.own_tick_due_s());
                    let command_from = pacing.command_tick_from_s();
                    let command = async {
                        if command_from == f64::INFINITY {
                            return std::future::pending().await;
                        }
                        if command_from > t0.elapsed().as_secs_f64() {
                            node_runtime::wait::sleep_until(at(command_from)).await;
                        }
                        match sub.async_take().await {
                            Ok((m, _)) => Some(Some(m)),
                            Err(e) => {
                                ros.warn(&format!(
                                    "joint_commands: unreadable message dropped: {e:?}"
                                ));
                                Some(None)
                            }
                        }
                    }
                    .or(async {
                        node_runtime::wait::sleep_until(own_due).await;
                        None
                    })
                    .await;
                    let by_command = match command {
                        // An unreadable message: wait again.
                        Some(None) => continue,
                        Some(Some(_)) => true,
                        None => false,
                    };
                    let t = t0.elapsed().as_secs_f64();
                    if let Some(Some(cmd)) = command {
                        report(bridge.command(t, &cmd.name, &cmd.position));
                    }
                    while let Some(cmd) = ros.take_next(&sub, "joint_commands") {
                        report(bridge.command(t, &cmd.name, &cmd.position));
                    }
                    // The newest body rate, timed on arrival (the IMU's clock is not ours).
                    while let Some(m) = imu.as_ref().and_then(|s| ros.take_next(s, "imu/data")) {
                        if let Some(w) = body_rate(&m) {
                            bridge.set_body_rate(t, w);
                        }
                    }
                    do_tick(&mut bridge, t);
                    pacing.ticked(t, by_command);
                }
                return;
            }
            // Lockstep on /clock: tick t runs when the command stamped t (or later) has come, or
            // after lockstep_wait_s of wall time without it (then the watchdog decides).
            enum Wake {
                Tick(Option<Tick>),
                Command(Option<JointState>),
                Imu(Imu),
            }
            let mut pending: Option<(f64, Instant)> = None;
            let mut clock_s = 0.0;
            let mut newest_command_s = f64::NEG_INFINITY;
            let mut early = EarlyCommands::default();
            // With gyro damping, tick t also waits for the body rate stamped t (published by the
            // simulator with the state of t, before /clock), so the run stays deterministic, as
            // long as the IMU publishes: one silent for more than GYRO_MAX_AGE_S (or never heard)
            // does not hold the clock.
            let mut newest_imu_s = f64::NEG_INFINITY;
            let wait = Duration::from_secs_f64(lockstep_wait_s);
            // A body rate heard: the gyro damping's (even in a frame it cannot use, said once:
            // not waited for then).
            let imu_in =
                |bridge: &mut JointBridge<Box<dyn Backend>>, newest_imu_s: &mut f64, m: &Imu| {
                    let t = m.header.stamp.as_secs_f64();
                    *newest_imu_s = newest_imu_s.max(t);
                    if let Some(w) = body_rate(m) {
                        bridge.set_body_rate(t, w);
                    }
                };
            // A command heard at tick `now_s`: taken, or held for its tick.
            let command_in = |bridge: &mut JointBridge<Box<dyn Backend>>,
                              early: &mut EarlyCommands,
                              newest_command_s: &mut f64,
                              now_s: f64,
                              cmd: JointState| {
                let stamp_s = cmd.header.stamp.as_secs_f64();
                if let Some((stamp_s, cmd)) = early.offer(now_s, stamp_s, cmd) {
                    *newest_command_s = newest_command_s.max(stamp_s);
                    report(bridge.command(now_s, &cmd.name, &cmd.position));
                }
            };
            // Every body rate and command waiting in the readers, at tick `now_s`.
            let take_waiting = |bridge: &mut JointBridge<Box<dyn Backend>>,
                                early: &mut EarlyCommands,
                                newest_command_s: &mut f64,
                                newest_imu_s: &mut f64,
                                now_s: f64| {
                while let Some(m) = imu.as_ref().and_then(|s| ros.take_next(s, "imu/data")) {
                    imu_in(bridge, newest_imu_s, &m);
                }
                while let Some(cmd) = ros.take_next(&sub, "joint_commands") {
                    command_in(bridge, early, newest_command_s, now_s, cmd);
                }
            };
            while !stop.load(Ordering::SeqCst) && !lifecycle.finalized() {
                // A command or body rate wakes this thread only while a tick waits for it:
                // otherwise (a planner ahead of /clock sends tick t's command before tick t)
                // it waits in its reader, taken when the tick comes (`take_waiting`), and
                // only the reader's DDS thread wakes for it.
                let for_command = pending.is_some();
                let for_imu = pending.is_some_and(|(p, _)| imu_due(imu.is_some(), newest_imu_s, p));
                let wake = async {
                    if !for_command {
                        return std::future::pending().await;
                    }
                    Wake::Command(match sub.async_take().await {
                        Ok((m, _)) => Some(m),
                        Err(e) => {
                            ros.warn(&format!(
                                "joint_commands: unreadable message dropped: {e:?}"
                            ));
                            None
                        }
                    })
                }
                .or(async {
                    match &imu {
                        Some(sub) if for_imu => loop {
                            match sub.async_take().await {
                                Ok((m, _)) => break Wake::Imu(m),
                                Err(e) => ros
                                    .warn(&format!("imu/data: unreadable message dropped: {e:?}")),
                            }
                        },
                        _ => std::future::pending().await,
                    }
                })
                .or(async { Wake::Tick(ticks.next().await) })
                .await;
                match wake {
                    Wake::Command(Some(cmd)) => {
                        command_in(&mut bridge, &mut early, &mut newest_command_s, clock_s, cmd)
                    }
                    Wake::Imu(m) => imu_in(&mut bridge, &mut newest_imu_s, &m),
                    Wake::Command(None) | Wake::Tick(None) => {}
                    Wake::Tick(Some(tick)) => {
                        let t = tick.sim_time.map_or(0.0, |s| s.as_secs_f64());
                        if tick.repeat {
                            // What came meanwhile, as it came (a paused simulator's repeats).
                            take_waiting(
                                &mut bridge,
                                &mut early,
                                &mut newest_command_s,
                                &mut newest_imu_s,
                                clock_s,
                            );
                            // The simulator says tick t again (waiting, paused or held at
                            // its `~/run_until`): an operator's call is answered now and acts
                            // from the next tick (a held simulator waits for the answer). A
                            // hold it starts or ends is said on `~/holding` before the answer:
                            // the gait planner hears it before the next tick's `/clock`,
                            // however far ahead of it the planner runs (its `plan_ahead`).
                            operator.serve(&ros, &mut bridge, &say_holding);
                            if pending.is_none()
                                && let Some(link) = &link
                                && let Err(e) = link.resend()
                            {
                                ros.error(&format!("sim link: {e}"));
                            }
                            continue;
                        }
                        // A tick still waiting for its command when the next comes: run it now.
                        if let Some((p, _)) = pending.take() {
                            do_tick(&mut bridge, p);
                        }
                        if t < clock_s {
                            // The clock went back (the simulation restarted): what was held
                            // was for the old run.
                            early = EarlyCommands::default();
                        }
                        clock_s = t;
                        // The commands that came early for this tick act now.
                        while let Some((stamp_s, cmd)) = early.due(t) {
                            newest_command_s = newest_command_s.max(stamp_s);
                            report(bridge.command(t, &cmd.name, &cmd.position));
                        }
                        // Then what came since the last tick, in its readers (after the held
                        // ones, which came before it).
                        take_waiting(
                            &mut bridge,
                            &mut early,
                            &mut newest_command_s,
                            &mut newest_imu_s,
                            t,
                        );
                        pending = Some((t, Instant::now()));
                    }
                }
                if let Some((p, since)) = pending
                    && ((newest_command_s >= p - 1e-9 && !imu_due(imu.is_some(), newest_imu_s, p))
                        || since.elapsed() >= wait)
                {
                    pending = None;
                    do_tick(&mut bridge, p);
                }
            }
        })
        .await;
    if let Err(e) = bridge.stop() {
        ros.error(&format!("torque off failed: {e}"));
    }
    ros.info("shutting down: torque off");
    Ok(())
}

/// The operator's services, answered between ticks: `~/estop` (std_srvs/srv/Trigger: hold
/// where the joints come to rest, ignore commands until `~/reset`), `~/reset` (Trigger) and
/// `~/set_torque` (std_srvs/srv/SetBool: off goes limp and ignores commands; on holds the
/// measured pose and takes commands again).
struct OperatorServices {
    estop: ros2_client::Server<TriggerRequest, TriggerResponse>,
    reset: ros2_client::Server<TriggerRequest, TriggerResponse>,
    torque: ros2_client::Server<SetBoolRequest, TriggerResponse>,
}

impl OperatorServices {
    fn new(ros: &mut RosNode) -> anyhow::Result<Self> {
        Ok(Self {
            estop: ros.service::<Trigger>("~/estop")?,
            reset: ros.service::<Trigger>("~/reset")?,
            torque: ros.service::<SetBool>("~/set_torque")?,
        })
    }

    /// Answers every request waiting, acting on the bridge; logs each answer (a warning when
    /// done, an error when refused). `said_hold` says what the call changed (the bridge's hold)
    /// before the answer goes out: a caller that acts on the answer acts after it.
    fn serve<B: Backend>(
        &self,
        ros: &RosNode,
        bridge: &mut JointBridge<B>,
        said_hold: &dyn Fn(&JointBridge<B>),
    ) {
        let answer = |outcome: Result<String, String>| {
            let (success, message) = match outcome {
                Ok(m) => {
                    ros.warn(&m);
                    (true, m)
                }
                Err(m) => {
                    ros.error(&m);
                    (false, m)
                }
            };
            TriggerResponse { success, message }
        };
        while let Ok(Some((id, _))) = self.estop.receive_request() {
            bridge.estop();
            let said = if bridge.estop_following() {
                "emergency stop: the walk brakes along its path (joint commands followed until they come to rest), then holds; joint commands ignored until ~/reset"
            } else {
                "emergency stop: holding where the joints come to rest; joint commands ignored until ~/reset"
            };
            let a = answer(Ok(said.into()));
            said_hold(bridge);
            let _ = self.estop.send_response(id, a);
        }
        while let Ok(Some((id, _))) = self.reset.receive_request() {
            let outcome = if bridge.release_estop() {
                Ok("emergency stop released: joint commands taken again".into())
            } else {
                Err("reset: no emergency stop was on".into())
            };
            said_hold(bridge);
            let _ = self.reset.send_response(id, answer(outcome));
        }
        while let Ok(Some((id, req))) = self.torque.receive_request() {
            let on = req.data;
            let outcome = match bridge.set_torque(on) {
                Ok(()) if on => {
                    Ok("torque on: holding the measured pose; joint commands taken again".into())
                }
                Ok(()) => Ok(
                    "torque off on request: joint commands ignored until ~/set_torque true".into(),
                ),
                Err(e) => Err(format!("set_torque {on} refused: {e}")),
            };
            said_hold(bridge);
            let _ = self.torque.send_response(id, answer(outcome));
        }
    }
}

/// Commands stamped for a tick still to come (a planner publishing ahead with its
/// `plan_ahead`, or a planner → IK chain quicker than the simulator's `/clock`), held until
/// that tick: tick t acts on the commands stamped t or before, however the messages raced,
/// so a lockstep run stays deterministic. A command stamped more than
/// [`EarlyCommands::HORIZON_S`] ahead (a peer on another clock) is taken at once; with
/// [`EarlyCommands::MAX_HELD`] held, a new one pushes the oldest out to be taken at once (the
/// queue is bounded, and the commands still act in the order of their stamps).
#[derive(Debug, Default)]
struct EarlyCommands {
    /// Held commands with their stamps (s), in arrival order.
    held: std::collections::VecDeque<(f64, JointState)>,
}

impl EarlyCommands {
    /// How far ahead of the current tick a command is held for its tick (s).
    const HORIZON_S: f64 = 1.0;
    /// At most this many commands held.
    const MAX_HELD: usize = 64;

    /// A command stamped `stamp_s` received while the bridge is at tick `now_s`: the command
    /// to take now with its stamp (this one, or the oldest held when the queue is full), or
    /// `None` when it is held for its tick. The same command again (sent anew at each repeat
    /// of a tick while a simulator waits or is paused) is held once.
    fn offer(&mut self, now_s: f64, stamp_s: f64, cmd: JointState) -> Option<(f64, JointState)> {
        let ahead_s = stamp_s - now_s;
        if ahead_s <= 1e-9 || ahead_s > Self::HORIZON_S {
            return Some((stamp_s, cmd));
        }
        if self.held.back().is_some_and(|(_, last)| *last == cmd) {
            return None;
        }
        let out = if self.held.len() >= Self::MAX_HELD {
            self.held.pop_front()
        } else {
            None
        };
        self.held.push_back((stamp_s, cmd));
        out
    }

    /// The next held command due at tick `now_s` (stamped at or before it), in arrival order.
    fn due(&mut self, now_s: f64) -> Option<(f64, JointState)> {
        let i = self.held.iter().position(|(s, _)| *s <= now_s + 1e-9)?;
        self.held.remove(i)
    }
}

/// Whether a lockstep tick at `tick_s` still waits for the body rate: gyro damping is on
/// (`subscribed`), the IMU is publishing (its newest rate, stamped `newest_imu_s`, at most
/// [`joint_bridge::GYRO_MAX_AGE_S`] older than the tick) and the rate of this tick has not
/// come yet.
fn imu_due(subscribed: bool, newest_imu_s: f64, tick_s: f64) -> bool {
    subscribed
        && newest_imu_s < tick_s - 1e-9
        && tick_s - newest_imu_s <= crate::GYRO_MAX_AGE_S + 1e-9
}

#[cfg(test)]
mod tests {
    use super::{EarlyCommands, imu_due};
    use biped_msgs::msg::JointState;

    fn cmd(position: f64) -> JointState {
        JointState {
            name: vec!["knee".into()],
            position: vec![position],
            ..JointState::default()
        }
    }

    fn position(c: Option<(f64, JointState)>) -> Option<f64> {
        c.map(|(_, c)| c.position[0])
    }

    #[test]
    fn a_command_for_a_tick_still_to_come_waits_for_it() {
        let mut early = EarlyCommands::default();
        // At tick 1.00: the commands stamped 1.00 (and a late one, 0.99) act at once.
        assert_eq!(position(early.offer(1.0, 1.0, cmd(0.1))), Some(0.1));
        assert_eq!(position(early.offer(1.0, 0.99, cmd(0.2))), Some(0.2));
        // Stamped 1.01 and 1.02: held, nothing due at 1.00.
        assert_eq!(position(early.offer(1.0, 1.01, cmd(0.3))), None);
        assert_eq!(position(early.offer(1.0, 1.02, cmd(0.4))), None);
        assert!(early.due(1.0).is_none());
        // Said again (a paused simulator's repeats): held once, however often.
        for _ in 0..100 {
            assert_eq!(position(early.offer(1.0, 1.02, cmd(0.4))), None);
        }
        assert_eq!(early.held.len(), 2);
        // Tick 1.01 takes the one stamped 1.01 only; tick 1.02 the other.
        assert_eq!(
            early.due(1.01).map(|(s, c)| (s, c.position[0])),
            Some((1.01, 0.3))
        );
        assert!(early.due(1.01).is_none());
        assert_eq!(
            early.due(1.02).map(|(s, c)| (s, c.position[0])),
            Some((1.02, 0.4))
        );
        assert!(early.due(5.0).is_none());
    }

    #[test]
    fn a_command_far_ahead_is_taken_at_once_and_a_full_queue_gives_up_its_oldest() {
        let mut early = EarlyCommands::default();
        // Stamped on another clock (the wall clock's seconds since 1970): not a tick to come.
        assert_eq!(position(early.offer(1.0, 1.7e9, cmd(0.5))), Some(0.5));
        assert_eq!(position(early.offer(1.0, 2.0 + 1e-6, cmd(0.6))), Some(0.6));
        // The queue is bounded: the 65th early command pushes the oldest out, taken at once.
        for i in 0..EarlyCommands::MAX_HELD {
            let c = cmd(i as f64);
            assert!(early.offer(1.0, 1.01 + i as f64 * 1e-3, c).is_none());
        }
        let out = early.offer(1.0, 1.5, cmd(0.7));
        assert_eq!(out.map(|(s, c)| (s, c.position[0])), Some((1.01, 0.0)));
        assert_eq!(early.held.len(), EarlyCommands::MAX_HELD);
        assert_eq!(early.held.back().map(|(s, _)| *s), Some(1.5));
    }

    #[test]
    fn a_tick_waits_for_the_body_rate_only_while_the_imu_publishes() {
        // Publishing every 10 ms: tick 1.00 waits until the rate of 1.00 has come.
        assert!(imu_due(true, 0.99, 1.0));
        assert!(!imu_due(true, 1.0, 1.0));
        // Never heard, or silent for more than 0.05 s: the clock is not held.
        assert!(!imu_due(true, f64::NEG_INFINITY, 1.0));
        assert!(!imu_due(true, 0.94, 1.0));
        assert!(imu_due(true, 0.95, 1.0));
        // Gyro damping off: never.
        assert!(!imu_due(false, 0.99, 1.0));
    }
}
