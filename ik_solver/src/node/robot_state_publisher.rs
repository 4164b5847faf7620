//! The `robot_state_publisher` ROS 2 node: the robot's URDF and link frames for RViz,
//! Foxglove and tf2, as ROS's robot_state_publisher offers them, for any URDF.
//!
//! - publishes the URDF text on `robot_description` (std_msgs/msg/String; reliable,
//!   transient local, depth 1: a subscriber that joins later still gets it);
//! - publishes the fixed joints' frames once on `/tf_static` (tf2_msgs/msg/TFMessage,
//!   transient local), stamped with the node's time at start;
//! - subscribes `joint_states` (sensor_msgs/msg/JointState) and publishes, for each, the
//!   frames of the movable joints it names on `/tf`, stamped with the joint state's stamp.
//!   Names the URDF does not have are ignored; a NaN or infinite position is never sent
//!   (that joint's frame is left out and the joint named in a warning, at most once a
//!   second); a state whose names and positions differ in length is refused with a warning.
//!
//! Parameters: `robot_description_file` (URDF path; empty for the built-in robot),
//! `frame_prefix` (put before every link name in the frames, e.g. `robot1/`; default empty),
//! `publish_on_receive` (bool, default true: each joint state's frames are computed and
//! published on the DDS thread that received it, one thread wake-up a message instead of
//! two; false: that thread wakes the node's own thread to do it). All read at start.

use std::process::ExitCode;

use anyhow::Context as _;
use biped_msgs::msg::{Header, JointState, StringMsg, TFMessage, Time, TransformStamped};
use ik_solver::{FrameTransform, FrameTree, RobotModel};
use node_runtime::{Host, NodeSetup, RosNode, Said};
use ros2_client::ParameterValue;

const ROBOT_PARAM: &str = "robot_description_file";
const PREFIX_PARAM: &str = "frame_prefix";
const ON_RECEIVE_PARAM: &str = "publish_on_receive";
const STATES_TOPIC: &str = "joint_states";

fn main() -> ExitCode {
    node_runtime::node_main("robot_state_publisher", run)
}

/// The frames as a TF message, each stamped `stamp`, link names prefixed.
fn tf_message(frames: &[FrameTransform<'_>], stamp: Time, prefix: &str) -> TFMessage {
    TFMessage {
        transforms: frames
            .iter()
            .map(|f| TransformStamped {
                header: Header {
                    stamp,
                    frame_id: format!("{prefix}{}", f.parent),
                },
                child_frame_id: format!("{prefix}{}", f.child),
                transform: (&f.transform).into(),
            })
            .collect(),
    }
}

/// The node's work on each joint state, wherever it runs (the node's thread, or the DDS
/// thread with `publish_on_receive`).
struct Frames {
    tree: FrameTree,
    prefix: String,
    publisher: node_runtime::Publisher<TFMessage>,
}

impl Frames {
    /// Publishes the frames of the movable joints `state` names on `/tf`; `say` gets what
    /// is to be logged.
    fn handle(&self, state: &JointState, say: &mut dyn FnMut(Said)) {
        match self.tree.moving(&state.name, &state.position) {
            Ok((frames, skipped)) => {
                if !skipped.non_finite.is_empty() {
                    say(Said::Error {
                        key: "non-finite",
                        text: format!(
                            "joint_states: non-finite positions {:?}: those frames are not sent",
                            skipped.non_finite
                        ),
                    });
                }
                if frames.is_empty() {
                    return;
                }
                let msg = tf_message(&frames, state.header.stamp, &self.prefix);
                if let Err(e) = self.publisher.publish(msg) {
                    say(Said::Error {
                        key: "publish /tf",
                        text: format!("publish /tf: {e:?}"),
                    });
                }
            }
            Err(e) => say(Said::Error {
                key: "joint_states",
                text: format!("joint_states: {e}"),
            }),
        }
    }
}

async fn run(setup: NodeSetup, host: Host) -> anyhow::Result<()> {
    setup.only_ros_args()?;
    node_runtime::check_known(
        &setup.params,
        &[ROBOT_PARAM, PREFIX_PARAM, ON_RECEIVE_PARAM],
    )?;
    let robot_file = setup.str_param(ROBOT_PARAM, "")?;
    let prefix = setup.str_param(PREFIX_PARAM, "")?;
    let on_receive = setup.bool_param(ON_RECEIVE_PARAM, true)? && !host.is_composed();
    let urdf = if robot_file.is_empty() {
        ik_solver::DEFAULT_URDF.to_owned()
    } else {
        std::fs::read_to_string(&robot_file)
            .with_context(|| format!("{ROBOT_PARAM} `{robot_file}`: cannot read it"))?
    };
    let tree = FrameTree::new(
        RobotModel::from_urdf_str(&urdf)
            .with_context(|| format!("{ROBOT_PARAM} `{robot_file}`"))?,
    );

    let declared = [
        (ROBOT_PARAM, ParameterValue::String(robot_file.clone())),
        (PREFIX_PARAM, ParameterValue::String(prefix.clone())),
        (ON_RECEIVE_PARAM, ParameterValue::Boolean(on_receive)),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    let mut ros = RosNode::start(
        &host,
        setup,
        &declared,
        Some(node_runtime::read_at_startup()),
    )?;
    let stop = host.stop_flag();
    let description_pub = ros.latched_publisher::<StringMsg>("robot_description")?;
    let static_pub = ros.latched_publisher::<TFMessage>("/tf_static")?;
    let tf_pub = ros.publisher::<TFMessage>("/tf")?;
    let sub = ros.subscription::<JointState>(STATES_TOPIC)?;
    let executor = ros.executor()?;

    description_pub
        .publish(StringMsg { data: urdf })
        .map_err(|e| anyhow::anyhow!("publish robot_description: {e:?}"))?;
    let fixed = tree.fixed();
    static_pub
        .publish(tf_message(&fixed, ros.node.time_now().into(), &prefix))
        .map_err(|e| anyhow::anyhow!("publish /tf_static: {e:?}"))?;
    ros.info(&format!(
        "ready: robot {}, {} links, {} fixed and {} movable joints{}",
        tree.model().name(),
        tree.model().links().len(),
        fixed.len(),
        tree.model().dof_count(),
        if on_receive {
            ", frames published on the DDS thread that receives each joint state"
        } else {
            ", frames published on the node's thread"
        }
    ));
    let frames = Frames {
        tree,
        prefix,
        publisher: tf_pub,
    };

    let result = executor
        .run(
            ros.serve(sub, STATES_TOPIC, &stop, on_receive, move |state, say| {
                frames.handle(&state, say)
            }),
        )
        .await;
    ros.info("shutting down");
    Ok(result?)
}
