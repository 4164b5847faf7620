//! The `joint_bridge` ROS 2 node: a thin wrapper over the joint_bridge library.
//!
//! Subscribes `joint_commands` (sensor_msgs/msg/JointState, positions by URDF joint name);
//! drives the backend through the bridge (URDF limits, velocity limits, watchdog); publishes
//! `joint_states` (sensor_msgs/msg/JointState, every driven joint) at `rate_hz`.
//!
//! Parameters: `robot_description_file` (URDF; empty for the built-in robot), `backend`
//! (`mock` or `serial`), `rate_hz` (100), `watchdog_timeout_s` (0.25), `watchdog_action`
//! (`hold` or `limp`), `start_ramp_s` (the move from the measured pose to the first
//! command), the serial board's `protocol`, `port`, `baud`, `calibration_file`,
//! `reply_timeout_s`, `retry_first_s`, `retry_max_s`, and the read-only
//! `joint_states_measured` (whether `joint_states` carries measured positions or, for
//! backends that cannot measure, the commanded ones).
//!
//! With a serial board the node also publishes `/diagnostics`
//! (diagnostic_msgs/msg/DiagnosticArray, once a second): the board's state and wire
//! counters (timeouts, corrupted replies, reconnections, servo error bits).

use std::collections::BTreeMap;
use std::process::ExitCode;
use std::sync::atomic::Ordering;

use anyhow::Context as _;
use biped_msgs::msg::{DiagnosticArray, DiagnosticStatus, Header, JointState, KeyValue};
use biped_msgs::ros::{self, NodeSetup, RosNode, Ticker};
use ik_solver::BipedModel;
use joint_bridge::serial::{Calibration, Protocol, SerialBackend, SerialConfig};
use joint_bridge::{
    Backend, Backoff, BridgeConfig, Event, JointBridge, JointSpec, Lifecycle, MockBackend,
    TimeoutAction,
};
use ros2_client::ParameterValue;

const PARAMS: [&str; 13] = [
    "robot_description_file",
    "backend",
    "rate_hz",
    "watchdog_timeout_s",
    "watchdog_action",
    "start_ramp_s",
    "protocol",
    "port",
    "baud",
    "calibration_file",
    "reply_timeout_s",
    "retry_first_s",
    "retry_max_s",
];

/// The serial settings, checked.
struct SerialParams {
    protocol: String,
    port: String,
    baud: u32,
    calibration_file: String,
    reply_timeout_s: f64,
    retry_first_s: f64,
    retry_max_s: f64,
}

fn in_range(name: &str, v: f64, lo: f64, hi: f64, unit: &str) -> anyhow::Result<f64> {
    if (lo..=hi).contains(&v) {
        Ok(v)
    } else {
        anyhow::bail!("parameter `{name}` = {v} is out of range [{lo}, {hi}] {unit}")
    }
}

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("joint_bridge: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run() -> anyhow::Result<()> {
    let setup = NodeSetup::from_env("joint_bridge")?;
    if !setup.own_args.is_empty() {
        anyhow::bail!(
            "unexpected arguments {:?}; the node takes only --ros-args (see the README)",
            setup.own_args
        );
    }
    ros::check_known(&setup.params, &PARAMS)?;
    let robot_file = setup.str_param("robot_description_file", "")?;
    let backend_name = setup.str_param("backend", "mock")?;
    let rate_hz = setup.f64_param("rate_hz", 100.0)?;
    let timeout_s = setup.f64_param("watchdog_timeout_s", 0.25)?;
    let action_name = setup.str_param("watchdog_action", "hold")?;
    if !(1.0..=1000.0).contains(&rate_hz) {
        anyhow::bail!("parameter `rate_hz` = {rate_hz} is out of range [1, 1000] Hz");
    }
    if !(timeout_s > 0.0 && timeout_s <= 60.0) {
        anyhow::bail!("parameter `watchdog_timeout_s` = {timeout_s} is out of range (0, 60] s");
    }
    let action: TimeoutAction = action_name
        .parse()
        .map_err(|e: String| anyhow::anyhow!("parameter `watchdog_action`: {e}"))?;
    let start_ramp_s = in_range(
        "start_ramp_s",
        setup.f64_param("start_ramp_s", 2.0)?,
        0.0,
        60.0,
        "s",
    )?;
    let serial = SerialParams {
        protocol: setup.str_param("protocol", "dynamixel2")?,
        port: setup.str_param("port", "/dev/ttyUSB0")?,
        baud: {
            let b = in_range(
                "baud",
                setup.f64_param("baud", 1_000_000.0)?,
                300.0,
                12e6,
                "baud",
            )?;
            if b.fract() != 0.0 {
                anyhow::bail!("parameter `baud` = {b} is not a whole number");
            }
            b as u32
        },
        calibration_file: setup.str_param("calibration_file", "")?,
        reply_timeout_s: in_range(
            "reply_timeout_s",
            setup.f64_param("reply_timeout_s", 0.01)?,
            1e-4,
            1.0,
            "s",
        )?,
        retry_first_s: in_range(
            "retry_first_s",
            setup.f64_param("retry_first_s", 0.5)?,
            0.01,
            60.0,
            "s",
        )?,
        retry_max_s: in_range(
            "retry_max_s",
            setup.f64_param("retry_max_s", 5.0)?,
            0.01,
            600.0,
            "s",
        )?,
    };
    let model = BipedModel::from_file_or_default(&robot_file, None)
        .with_context(|| format!("robot_description_file `{robot_file}`"))?;
    let mut joints = JointSpec::from_robot(model.robot());
    let mut not_driven = Vec::new();
    let (backend, reconnect): (Box<dyn Backend>, Option<Backoff>) = match backend_name.as_str() {
        "mock" => (Box::new(MockBackend::default()), None),
        "serial" => {
            let protocol: Protocol = serial
                .protocol
                .parse()
                .map_err(|e: String| anyhow::anyhow!("parameter `protocol`: {e}"))?;
            if serial.calibration_file.is_empty() {
                anyhow::bail!(
                    "parameter `calibration_file` is empty: the serial backend needs the joints' calibration (see config/calibration_{protocol}.yaml)"
                );
            }
            let calibration =
                Calibration::from_file(std::path::Path::new(&serial.calibration_file))?;
            if calibration.protocol != protocol {
                anyhow::bail!(
                    "calibration_file `{}` is for protocol {}, but parameter `protocol` is {protocol}",
                    serial.calibration_file,
                    calibration.protocol
                );
            }
            if let Some(unknown) = calibration
                .joints
                .keys()
                .find(|n| !joints.iter().any(|j| &j.name == *n))
            {
                anyhow::bail!(
                    "calibration_file `{}`: joint `{unknown}` is not a movable joint of robot `{}`",
                    serial.calibration_file,
                    model.robot().name()
                );
            }
            // Drive the calibrated joints; the others have no servo on this board.
            not_driven = joints
                .iter()
                .filter(|j| !calibration.joints.contains_key(&j.name))
                .map(|j| j.name.clone())
                .collect();
            joints.retain(|j| calibration.joints.contains_key(&j.name));
            let backend = SerialBackend::new(SerialConfig {
                port: serial.port.clone(),
                baud: serial.baud,
                calibration,
                reply_timeout_s: serial.reply_timeout_s,
            });
            (
                Box::new(backend),
                Some(Backoff {
                    first_s: serial.retry_first_s,
                    max_s: serial.retry_max_s.max(serial.retry_first_s),
                }),
            )
        }
        other => anyhow::bail!("parameter `backend` = `{other}`: not available (mock, serial)"),
    };
    let measured = backend_name == "serial"
        && serial
            .protocol
            .parse::<Protocol>()
            .is_ok_and(Protocol::measures);
    let names: Vec<String> = joints.iter().map(|j| j.name.clone()).collect();
    let mut bridge = JointBridge::new(
        backend,
        joints,
        BridgeConfig {
            watchdog_timeout_s: timeout_s,
            on_timeout: action,
            start_ramp_s,
            reconnect,
        },
    );

    let declared = BTreeMap::from([
        (
            "robot_description_file".to_string(),
            ParameterValue::String(robot_file.clone()),
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
            "joint_states_measured".to_string(),
            ParameterValue::Boolean(measured),
        ),
        (
            "start_ramp_s".to_string(),
            ParameterValue::Double(start_ramp_s),
        ),
        (
            "protocol".to_string(),
            ParameterValue::String(serial.protocol.clone()),
        ),
        (
            "port".to_string(),
            ParameterValue::String(serial.port.clone()),
        ),
        (
            "baud".to_string(),
            ParameterValue::Integer(i64::from(serial.baud)),
        ),
        (
            "calibration_file".to_string(),
            ParameterValue::String(serial.calibration_file.clone()),
        ),
        (
            "reply_timeout_s".to_string(),
            ParameterValue::Double(serial.reply_timeout_s),
        ),
        (
            "retry_first_s".to_string(),
            ParameterValue::Double(serial.retry_first_s),
        ),
        (
            "retry_max_s".to_string(),
            ParameterValue::Double(serial.retry_max_s),
        ),
    ]);
    let check = |name: &str, _: &ParameterValue| -> Result<(), String> {
        if name == "use_sim_time" {
            Ok(())
        } else {
            Err(format!(
                "{name} is read at start-up; restart the node to change it"
            ))
        }
    };
    let mut ros = RosNode::start(setup, &declared, Some(Box::new(check)))?;
    let stop = ros::shutdown_flag()?;
    let sub = ros.subscription::<JointState>("joint_commands")?;
    let publisher = ros.publisher::<JointState>("joint_states")?;
    let diagnostics = ros.publisher::<DiagnosticArray>("/diagnostics")?;
    let executor = ros.executor()?;

    if !not_driven.is_empty() {
        ros.info(&format!(
            "not in the calibration, not driven: {}",
            not_driven.join(", ")
        ));
    }
    let what = if backend_name == "serial" {
        format!(
            "{} on {} at {} baud",
            serial.protocol, serial.port, serial.baud
        )
    } else {
        backend_name.clone()
    };
    match bridge.start() {
        Ok(()) => {}
        // A serial board retries with backoff (port absent, board unpowered...).
        Err(e) if backend_name == "serial" => ros.error(&format!(
            "backend {what}: {e}; retrying every {}..{} s",
            serial.retry_first_s, serial.retry_max_s
        )),
        Err(e) => anyhow::bail!("backend {backend_name}: {e}"),
    }
    let states_are = if measured {
        "measured positions".to_string()
    } else {
        format!("commanded positions (the {what} backend cannot measure)")
    };
    let status = if bridge.state() == Lifecycle::Active {
        "active"
    } else {
        "not connected yet (retrying)"
    };
    ros.info(&format!(
        "ready: backend {what} {status}, {} joints, {rate_hz} Hz, watchdog {timeout_s} s ({action_name}), start ramp {start_ramp_s} s; joint_states carries {states_are}",
        names.len()
    ));
    let t0 = std::time::Instant::now();
    let report = |events: Vec<Event>| {
        for e in events {
            match e {
                Event::Resumed => ros.info(&e.to_string()),
                Event::BackendFailed(_) | Event::RetryFailed { .. } => ros.error(&e.to_string()),
                Event::Reconnected => ros.info(&e.to_string()),
                _ => ros.warn(&e.to_string()),
            }
        }
    };
    smol::block_on(executor.run(async {
        let mut ticker = Ticker::new(rate_hz);
        let mut last_diagnostics_s = f64::NEG_INFINITY;
        let mut last_read_error: Option<(String, f64)> = None;
        while !stop.load(Ordering::SeqCst) {
            ticker.next().await;
            loop {
                match sub.take() {
                    Ok(Some((cmd, _))) => {
                        report(bridge.command(t0.elapsed().as_secs_f64(), &cmd.name, &cmd.position))
                    }
                    Ok(None) => break,
                    Err(e) => {
                        ros.warn(&format!(
                            "joint_commands: unreadable message dropped: {e:?}"
                        ));
                        break;
                    }
                }
            }
            let (reading, events) = bridge.tick(t0.elapsed().as_secs_f64());
            report(events);
            match reading {
                Ok(r) => {
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
                        ros.error(&format!("publish joint_states: {e:?}"));
                    }
                }
                // While the bridge retries a failed backend, the retries say why.
                Err(_) if bridge.state() == Lifecycle::Error => {}
                Err(e) => {
                    // Once per second at most while it keeps failing the same way.
                    let now = t0.elapsed().as_secs_f64();
                    let text = e.to_string();
                    if last_read_error
                        .as_ref()
                        .is_none_or(|(m, at)| *m != text || now - at >= 1.0)
                    {
                        ros.error(&format!("backend read: {text}"));
                        last_read_error = Some((text, now));
                    }
                }
            }
            let now = t0.elapsed().as_secs_f64();
            if now - last_diagnostics_s >= 1.0
                && let Some(d) = bridge.backend().diagnostics()
            {
                last_diagnostics_s = now;
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
                    ros.error(&format!("publish diagnostics: {e:?}"));
                }
            }
        }
    }));
    if let Err(e) = bridge.stop() {
        ros.error(&format!("torque off failed: {e}"));
    }
    ros.info("shutting down: torque off");
    Ok(())
}
