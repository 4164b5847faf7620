//! The `ik_solver` ROS 2 node: a thin wrapper over the ik_solver library.
//!
//! Subscribes `gait/ankle_targets` (biped_msgs/msg/AnkleTargets); for each message solves
//! both legs with the closed-form IK and publishes `joint_commands`
//! (sensor_msgs/msg/JointState: the leg joints by URDF name, positions in rad, the
//! targets' stamp). A target with NaN or infinity is refused with a warning naming the field
//! (nothing is published for it, so the joint bridge keeps its pose); an unreachable target
//! or a joint limit is clamped and reported (at most once a second per kind).
//!
//! Parameters: `robot_description_file` (URDF path; empty for the built-in robot),
//! `leg_map_file`, `solve_on_receive` (bool, default true: each message is solved and its
//! command published on the DDS thread that received it, one thread wake-up a message
//! instead of two; false: that thread wakes the node's own thread to do it, as an rclcpp
//! executor would; no effect composed with other nodes in one process). All read at start.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use crate::{AnkleTarget, BipedModel};
use anyhow::Context as _;
use biped_msgs::msg::{AnkleTargets, JointState};
use nalgebra::Vector3;
use node_runtime::{Host, NodeSetup, RosNode, Said};
use ros2_client::ParameterValue;

const ROBOT_PARAM: &str = "robot_description_file";
const LEG_MAP_PARAM: &str = "leg_map_file";
const SOLVE_ON_RECEIVE_PARAM: &str = "solve_on_receive";
const TARGETS_TOPIC: &str = "gait/ankle_targets";

/// Solves one message into a joint command; `Err` names the non-finite field.
fn solve(
    model: &BipedModel,
    names: &[String],
    dofs: &[usize],
    msg: &AnkleTargets,
    q: &mut [f64],
) -> Result<(JointState, Vec<String>), String> {
    let left = AnkleTarget {
        ankle_in_hip_m: Vector3::new(msg.left_ankle.x, msg.left_ankle.y, msg.left_ankle.z),
        foot_yaw_rad: msg.left_foot_yaw,
    };
    let right = AnkleTarget {
        ankle_in_hip_m: Vector3::new(msg.right_ankle.x, msg.right_ankle.y, msg.right_ankle.z),
        foot_yaw_rad: msg.right_foot_yaw,
    };
    let issues = model
        .solve_legs(&left, &right, q)
        .map_err(|e| format!("ankle targets refused: {e}"))?;
    let js = JointState {
        header: msg.header.clone(),
        name: names.to_vec(),
        position: dofs.iter().map(|&d| q[d]).collect(),
        velocity: Vec::new(),
        effort: Vec::new(),
    };
    Ok((js, issues.iter().map(|i| i.to_string()).collect()))
}

/// The node's work on each message, wherever it runs (the node's thread, or the DDS
/// thread with `solve_on_receive`).
struct Solver {
    model: BipedModel,
    names: Vec<String>,
    dofs: Vec<usize>,
    publisher: node_runtime::Publisher<JointState>,
    q: Vec<f64>,
    last_report: BTreeMap<String, Instant>,
}

impl Solver {
    /// Solves `msg` and publishes its command; `say` gets what is to be logged (a
    /// joint-limit or reach issue at most once a second per kind, not once per tick).
    fn handle(&mut self, msg: &AnkleTargets, say: &mut dyn FnMut(Said)) {
        match solve(&self.model, &self.names, &self.dofs, msg, &mut self.q) {
            Ok((js, issues)) => {
                for issue in issues {
                    let key: String = issue.split(':').next().unwrap_or_default().to_owned();
                    let due = self
                        .last_report
                        .get(&key)
                        .is_none_or(|t| t.elapsed() > Duration::from_secs(1));
                    if due {
                        say(Said::Warn(issue));
                        self.last_report.insert(key, Instant::now());
                    }
                }
                if let Err(e) = self.publisher.publish(js) {
                    say(Said::Error {
                        key: "publish joint_commands",
                        text: format!("publish joint_commands: {e}"),
                    });
                }
            }
            Err(why) => say(Said::Warn(why)),
        }
    }
}

/// Runs the node with `setup` (its arguments and parameters) on `host` until the host
/// stops: alone in its process (the `ik_solver` binary) or composed with others in one.
pub async fn run(setup: NodeSetup, host: Host) -> anyhow::Result<()> {
    setup.only_ros_args()?;
    node_runtime::check_known(
        &setup.params,
        &[ROBOT_PARAM, LEG_MAP_PARAM, SOLVE_ON_RECEIVE_PARAM],
    )?;
    let robot_file = setup.str_param(ROBOT_PARAM, "")?;
    let leg_map_file = setup.str_param(LEG_MAP_PARAM, "")?;
    let solve_on_receive = setup.bool_param(SOLVE_ON_RECEIVE_PARAM, true)?;
    let model = BipedModel::from_parameter_files(&robot_file, &leg_map_file)?;
    // The leg joints, left then right, hip to foot.
    let (names, dofs): (Vec<String>, Vec<usize>) = model
        .leg_joints()
        .map(|(_, j)| (j.name.clone(), j.dof))
        .unzip();

    let declared = BTreeMap::from([
        (
            ROBOT_PARAM.to_string(),
            ParameterValue::String(robot_file.clone()),
        ),
        (
            LEG_MAP_PARAM.to_string(),
            ParameterValue::String(leg_map_file.clone()),
        ),
        (
            SOLVE_ON_RECEIVE_PARAM.to_string(),
            ParameterValue::Boolean(solve_on_receive),
        ),
    ]);
    let check = |name: &str, _: &ParameterValue| -> Result<(), String> {
        if [ROBOT_PARAM, LEG_MAP_PARAM, SOLVE_ON_RECEIVE_PARAM].contains(&name) {
            Err(node_runtime::read_at_startup_only(name))
        } else {
            Ok(())
        }
    };
    let composed = host.is_composed();
    let mut ros = RosNode::start(&host, setup, &declared, Some(Box::new(check)))?;
    let stop = host.stop_flag();
    let sub = ros.subscription::<AnkleTargets>(TARGETS_TOPIC)?;
    let publisher = ros.publisher::<JointState>("joint_commands")?;
    let executor = ros.executor()?;
    ros.info(&format!(
        "ready: robot {}, solving {} leg joints{}",
        model.robot().name(),
        names.len(),
        match (solve_on_receive, composed) {
            (false, _) => " on the node's thread (solve_on_receive false)",
            (true, false) => " on the DDS thread that receives each message",
            (true, true) => " (solve_on_receive: no effect composed, messages come in-process)",
        }
    ));
    let q = vec![0.0; model.robot().dof_count()];
    let mut solver = Solver {
        model,
        names,
        dofs,
        publisher,
        q,
        last_report: BTreeMap::new(),
    };

    // With `solve_on_receive` the DDS thread solves and publishes, and this thread logs
    // what it says.
    let result = executor
        .run(ros.serve(
            sub,
            TARGETS_TOPIC,
            &stop,
            solve_on_receive && !composed,
            move |msg, say| solver.handle(&msg, say),
        ))
        .await
        .context("the solver: no more joint commands");
    ros.info("shutting down");
    result
}
