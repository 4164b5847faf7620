//! The `sim` backend of the joint_bridge node: the MuJoCo sim_bridge node, reached over DDS.
//!
//! | call | what goes over the wire |
//! |---|---|
//! | `configure` | the simulator's latest `joint_states` (an error until the first arrives: the node retries up to `sim_wait_s` without holding its thread); returns those positions |
//! | `activate` | nothing: the simulated servos hold their pose from the start |
//! | `write(t, q)` | publishes `sim/joint_commands` (sensor_msgs/msg/JointState, every driven joint, stamped t on simulated time, with the wall clock otherwise) |
//! | `read(t)` | the latest `joint_states` the simulator published (`measured: true`) |
//! | `deactivate` | publishes an empty `sim/joint_commands` (no names): the simulator's torque-off |
//!
//! The simulator publishes `joint_states` itself, so the node does not.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::{SystemTime, UNIX_EPOCH};

use crate::{Backend, BackendError, JointSpec, Reading};
use biped_msgs::msg::{Header, JointState, Time};
use node_runtime::{Publisher, Subscription};

const NAME: &str = "sim";

fn io(why: impl Into<String>) -> BackendError {
    BackendError::Io {
        backend: NAME.into(),
        why: why.into(),
    }
}

/// The stamp of a command for tick `t_s`: `t_s` itself on simulated time, else the wall clock.
fn stamp(sim_time: bool, t_s: f64) -> Time {
    if sim_time {
        Time::from_nanos((t_s * 1e9).round() as i64)
    } else {
        let now = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .unwrap_or_default();
        Time::from_nanos(now.as_nanos() as i64)
    }
}

/// The command side, shared by the link (owned by the bridge) and the node's handle.
struct Sender {
    commands: Publisher<JointState>,
    last_sent: Option<JointState>,
}

impl Sender {
    fn send(&mut self, msg: JointState) -> Result<(), BackendError> {
        self.last_sent = Some(msg.clone());
        self.commands
            .publish(msg)
            .map_err(|e| io(format!("publish sim/joint_commands: {e}")))
    }
}

/// The node's handle on a [`SimLink`] owned by the bridge: lockstep answers outside the
/// bridge's writes.
#[derive(Clone)]
pub struct SimLinkHandle {
    sender: Arc<Mutex<Sender>>,
    sim_time: bool,
}

impl SimLinkHandle {
    fn with<R>(
        &self,
        f: impl FnOnce(&mut Sender) -> Result<R, BackendError>,
    ) -> Result<R, BackendError> {
        let mut s = self
            .sender
            .lock()
            .map_err(|_| io("sim link lock poisoned"))?;
        f(&mut s)
    }

    /// Sends the last command again (the lockstep simulator asked for the tick once more).
    pub fn resend(&self) -> Result<(), BackendError> {
        self.with(|s| match s.last_sent.clone() {
            Some(m) => s.send(m),
            None => Ok(()),
        })
    }

    /// Answers tick `t_s` without a command (the bridge is not driving: torque off or
    /// failed): an empty `sim/joint_commands`, which the simulator takes as torque off.
    pub fn answer_without_command(&self, t_s: f64) -> Result<(), BackendError> {
        let msg = JointState {
            header: Header {
                stamp: stamp(self.sim_time, t_s),
                frame_id: String::new(),
            },
            ..JointState::default()
        };
        self.with(|s| s.send(msg))
    }

    /// The stamp of the last message sent (s), if any.
    fn last_stamp_s(&self) -> Option<f64> {
        self.with(|s| Ok(s.last_sent.as_ref().map(|m| m.header.stamp.as_secs_f64())))
            .ok()
            .flatten()
    }
}

/// The DDS link to a sim_bridge node.
pub struct SimLink {
    handle: SimLinkHandle,
    states: Subscription<JointState>,
    names: Vec<String>,
    latest: Option<JointState>,
}

impl std::fmt::Debug for SimLink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimLink")
            .field("names", &self.names)
            .finish()
    }
}

impl SimLink {
    /// The link (commands out on `commands`, the simulator's joint states in on `states`),
    /// and the node's handle on it.
    pub fn new(
        commands: Publisher<JointState>,
        states: Subscription<JointState>,
        sim_time: bool,
    ) -> (Self, SimLinkHandle) {
        let handle = SimLinkHandle {
            sender: Arc::new(Mutex::new(Sender {
                commands,
                last_sent: None,
            })),
            sim_time,
        };
        (
            Self {
                handle: handle.clone(),
                states,
                names: Vec::new(),
                latest: None,
            },
            handle,
        )
    }

    fn drain(&mut self) {
        while let Ok(Some((m, _))) = self.states.take() {
            self.latest = Some(m);
        }
    }

    fn positions(&self, msg: &JointState) -> Result<Vec<f64>, BackendError> {
        let index: HashMap<&str, usize> = msg
            .name
            .iter()
            .enumerate()
            .map(|(i, n)| (n.as_str(), i))
            .collect();
        self.names
            .iter()
            .map(|n| {
                index
                    .get(n.as_str())
                    .and_then(|&i| msg.position.get(i).copied())
                    .ok_or_else(|| BackendError::Joint {
                        backend: NAME.into(),
                        joint: n.clone(),
                        why: "missing from the simulator's joint_states".into(),
                    })
            })
            .collect()
    }
}

impl Backend for SimLink {
    fn name(&self) -> &str {
        NAME
    }

    fn configure(&mut self, joints: &[JointSpec]) -> Result<Option<Vec<f64>>, BackendError> {
        self.names = joints.iter().map(|j| j.name.clone()).collect();
        self.drain();
        match &self.latest {
            Some(m) => self.positions(m).map(Some),
            None => Err(BackendError::Open {
                backend: NAME.into(),
                why: "no joint_states from a sim_bridge node (is it running, in the same ROS_DOMAIN_ID and namespace?)".into(),
            }),
        }
    }

    fn activate(&mut self) -> Result<(), BackendError> {
        Ok(())
    }

    fn write(&mut self, t_s: f64, positions_rad: &[f64]) -> Result<(), BackendError> {
        let msg = JointState {
            header: Header {
                stamp: stamp(self.handle.sim_time, t_s),
                frame_id: String::new(),
            },
            name: self.names.clone(),
            position: positions_rad.to_vec(),
            velocity: Vec::new(),
            effort: Vec::new(),
        };
        self.handle.with(|s| s.send(msg))
    }

    fn read(&mut self, _t_s: f64) -> Result<Reading, BackendError> {
        self.drain();
        let Some(m) = &self.latest else {
            return Err(io("no joint_states from the simulator yet"));
        };
        Ok(Reading {
            positions_rad: self.positions(m)?,
            velocities_rad_s: None,
            measured: true,
        })
    }

    fn deactivate(&mut self) -> Result<(), BackendError> {
        // Torque off, stamped like the last message so a lockstep simulator does not take
        // it as the answer to a tick still to come.
        let t_s = self.handle.last_stamp_s().unwrap_or(0.0);
        self.handle.answer_without_command(t_s)
    }
}
