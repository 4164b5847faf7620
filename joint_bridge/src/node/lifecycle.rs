//! The managed-node (lifecycle) interface of the joint bridge, as `ros2 lifecycle` and a
//! lifecycle manager use it: the services `~/get_state`, `~/change_state` and
//! `~/get_available_transitions` (lifecycle_msgs/srv) and the topic `~/transition_event`
//! (lifecycle_msgs/msg/TransitionEvent), answered between ticks. What each transition does to
//! the bridge is [`joint_bridge::managed`]'s.

use std::cell::Cell;

use crate::managed::{self, ManagedState, ManagedTransition};
use crate::{Backend, JointBridge};
use biped_msgs::msg::{LifecycleState, Transition, TransitionDescription, TransitionEvent};
use biped_msgs::srv::{
    ChangeState, ChangeStateRequest, ChangeStateResponse, GetAvailableTransitions,
    GetAvailableTransitionsResponse, GetState, GetStateResponse, TriggerRequest,
};
use node_runtime::Publisher;
use node_runtime::RosNode;
use ros2_client::Server;

/// The lifecycle servers, the transition event publisher and the managed state.
pub struct LifecycleServices {
    get_state: Server<TriggerRequest, GetStateResponse>,
    change_state: Server<ChangeStateRequest, ChangeStateResponse>,
    transitions: Server<TriggerRequest, GetAvailableTransitionsResponse>,
    transition_event: Publisher<TransitionEvent>,
    state: Cell<ManagedState>,
}

fn state_msg(s: ManagedState) -> LifecycleState {
    LifecycleState {
        id: s.id(),
        label: s.label().into(),
    }
}

fn transition_msg(t: &ManagedTransition) -> Transition {
    Transition {
        id: t.id,
        label: t.label.into(),
    }
}

impl LifecycleServices {
    /// Creates the servers in the node's private namespace, in `state`: `active` when the
    /// node configured and activated its backend itself (autostart), else `unconfigured`.
    pub fn new(ros: &mut RosNode, state: ManagedState) -> anyhow::Result<Self> {
        Ok(Self {
            get_state: ros.service::<GetState>("~/get_state")?,
            change_state: ros.service::<ChangeState>("~/change_state")?,
            transitions: ros.service::<GetAvailableTransitions>("~/get_available_transitions")?,
            transition_event: ros.publisher::<TransitionEvent>("~/transition_event")?,
            state: Cell::new(state),
        })
    }

    /// True once a shutdown transition was taken: the node exits.
    pub fn finalized(&self) -> bool {
        self.state.get() == ManagedState::Finalized
    }

    /// Answers every lifecycle request waiting, taking the transitions asked on the bridge
    /// and publishing each one taken.
    pub fn serve<B: Backend>(&self, ros: &RosNode, bridge: &mut JointBridge<B>) {
        while let Ok(Some((id, _))) = self.get_state.receive_request() {
            let current_state = state_msg(self.state.get());
            let _ = self
                .get_state
                .send_response(id, GetStateResponse { current_state });
        }
        while let Ok(Some((id, _))) = self.transitions.receive_request() {
            let from = self.state.get();
            let available_transitions = managed::transitions_from(from)
                .iter()
                .map(|t| TransitionDescription {
                    transition: transition_msg(t),
                    start_state: state_msg(from),
                    goal_state: state_msg(t.goal),
                })
                .collect();
            let _ = self.transitions.send_response(
                id,
                GetAvailableTransitionsResponse {
                    available_transitions,
                },
            );
        }
        while let Ok(Some((id, req))) = self.change_state.receive_request() {
            let from = self.state.get();
            let taken = managed::find(from, req.transition.id, &req.transition.label)
                .and_then(|t| managed::apply(bridge, t).map(|goal| (t, goal)));
            let success = match taken {
                Ok((t, goal)) => {
                    self.state.set(goal);
                    ros.warn(&format!(
                        "lifecycle: {} -> {} ({})",
                        from.label(),
                        goal.label(),
                        t.label
                    ));
                    let event = TransitionEvent {
                        timestamp: u64::try_from(ros.node.time_now().to_nanos()).unwrap_or(0),
                        transition: transition_msg(&t),
                        start_state: state_msg(from),
                        goal_state: state_msg(goal),
                    };
                    if let Err(e) = self.transition_event.publish(event) {
                        ros.error(&format!("publish transition_event: {e}"));
                    }
                    true
                }
                Err(e) => {
                    ros.error(&format!("lifecycle: {e}"));
                    false
                }
            };
            let _ = self
                .change_state
                .send_response(id, ChangeStateResponse { success });
        }
    }
}
