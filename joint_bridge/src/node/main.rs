//! The `joint_bridge` ROS 2 node: a thin wrapper over the joint_bridge library.
//!
//! Subscribes `joint_commands` (sensor_msgs/msg/JointState, positions by URDF joint name);
//! drives the backend through the bridge (URDF limits, velocity limits, watchdog); publishes
//! `joint_states` (sensor_msgs/msg/JointState, every driven joint) at `rate_hz`.
//!
//! Parameters: `robot_description_file` (URDF; empty for the built-in robot), `backend`
//! (`mock`; the simulator and serial boards come next), `rate_hz` (100), `watchdog_timeout_s`
//! (0.25), `watchdog_action` (`hold` or `limp`), and the read-only `joint_states_measured`
//! (whether `joint_states` carries measured positions or, for backends that cannot measure,
//! the commanded ones).

use std::collections::BTreeMap;
use std::process::ExitCode;
use std::sync::atomic::Ordering;

use anyhow::Context as _;
use biped_msgs::msg::{Header, JointState};
use biped_msgs::ros::{self, NodeSetup, RosNode, Ticker};
use ik_solver::BipedModel;
use joint_bridge::{BridgeConfig, Event, JointBridge, JointSpec, MockBackend, TimeoutAction};
use ros2_client::ParameterValue;

const PARAMS: [&str; 5] = [
    "robot_description_file",
    "backend",
    "rate_hz",
    "watchdog_timeout_s",
    "watchdog_action",
];

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
    let backend = match backend_name.as_str() {
        "mock" => MockBackend::default(),
        other => anyhow::bail!("parameter `backend` = `{other}`: not available (mock)"),
    };
    let model = BipedModel::from_file_or_default(&robot_file, None)
        .with_context(|| format!("robot_description_file `{robot_file}`"))?;
    let joints = JointSpec::from_robot(model.robot());
    let names: Vec<String> = joints.iter().map(|j| j.name.clone()).collect();
    let mut bridge = JointBridge::new(
        backend,
        joints,
        BridgeConfig {
            watchdog_timeout_s: timeout_s,
            on_timeout: action,
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
            ParameterValue::Boolean(false),
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
    let executor = ros.executor()?;

    bridge
        .start()
        .map_err(|e| anyhow::anyhow!("backend {backend_name}: {e}"))?;
    ros.info(&format!(
            "ready: backend {backend_name} active, {} joints, {rate_hz} Hz, watchdog {timeout_s} s ({action_name}); joint_states carries commanded positions (the {backend_name} backend cannot measure)",
            names.len()
        ),
    );
    let t0 = std::time::Instant::now();
    let report = |events: Vec<Event>| {
        for e in events {
            match e {
                Event::Resumed => ros.info(&e.to_string()),
                Event::BackendFailed(_) => ros.error(&e.to_string()),
                _ => ros.warn(&e.to_string()),
            }
        }
    };
    smol::block_on(executor.run(async {
        let mut ticker = Ticker::new(rate_hz);
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
                Err(e) => ros.error(&format!("backend read: {e}")),
            }
        }
    }));
    if let Err(e) = bridge.stop() {
        ros.error(&format!("torque off failed: {e}"));
    }
    ros.info("shutting down: torque off");
    Ok(())
}
