//! The joint bridge as a ROS 2 managed (lifecycle) node: the primary states and
//! transitions of `lifecycle_msgs`, mapped onto the bridge.
//!
//! | transition (id) | from → to | what the bridge does |
//! |---|---|---|
//! | configure (1) | unconfigured → inactive | opens the backend, torque on, holding the measured pose; commands ignored |
//! | activate (3) | inactive → active | commands taken, approached from the hold through the limiter |
//! | deactivate (4) | active → inactive | brakes to a hold (torque on); commands ignored |
//! | cleanup (2) | inactive → unconfigured | torque off |
//! | shutdown (5, 6, 7) | any → finalized | brakes to a hold, then torque off; the node exits |
//!
//! A transition whose action fails leaves the state as it was (and says why).

use crate::backend::{Backend, BackendError};
use crate::bridge::{JointBridge, Operator};

/// A primary state of a managed node (`lifecycle_msgs/msg/State` ids).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ManagedState {
    /// 1: not configured: torque off.
    Unconfigured,
    /// 2: configured, holding; commands ignored.
    Inactive,
    /// 3: commands taken.
    Active,
    /// 4: shut down.
    Finalized,
}

impl ManagedState {
    /// The `lifecycle_msgs/msg/State` id.
    pub fn id(self) -> u8 {
        match self {
            Self::Unconfigured => 1,
            Self::Inactive => 2,
            Self::Active => 3,
            Self::Finalized => 4,
        }
    }
    /// The label ROS tools print.
    pub fn label(self) -> &'static str {
        match self {
            Self::Unconfigured => "unconfigured",
            Self::Inactive => "inactive",
            Self::Active => "active",
            Self::Finalized => "finalized",
        }
    }
}

/// A transition available from a state: its id, label and goal.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ManagedTransition {
    /// The `lifecycle_msgs/msg/Transition` id.
    pub id: u8,
    /// Its label.
    pub label: &'static str,
    /// Where it leads.
    pub goal: ManagedState,
}

const fn t(id: u8, label: &'static str, goal: ManagedState) -> ManagedTransition {
    ManagedTransition { id, label, goal }
}

const FROM_UNCONFIGURED: [ManagedTransition; 2] = [
    t(1, "configure", ManagedState::Inactive),
    t(5, "shutdown", ManagedState::Finalized),
];
const FROM_INACTIVE: [ManagedTransition; 3] = [
    t(2, "cleanup", ManagedState::Unconfigured),
    t(3, "activate", ManagedState::Active),
    t(6, "shutdown", ManagedState::Finalized),
];
const FROM_ACTIVE: [ManagedTransition; 2] = [
    t(4, "deactivate", ManagedState::Inactive),
    t(7, "shutdown", ManagedState::Finalized),
];

/// The transitions available from `state`, as rclcpp lists them.
pub fn transitions_from(state: ManagedState) -> &'static [ManagedTransition] {
    match state {
        ManagedState::Unconfigured => &FROM_UNCONFIGURED,
        ManagedState::Inactive => &FROM_INACTIVE,
        ManagedState::Active => &FROM_ACTIVE,
        ManagedState::Finalized => &[],
    }
}

/// Why a transition was not taken.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TransitionError {
    /// No such transition from this state.
    #[error("transition {id} `{label}` is not available from state `{}`", state.label())]
    NotAvailable {
        /// The id asked.
        id: u8,
        /// The label asked.
        label: String,
        /// The state.
        state: ManagedState,
    },
    /// The bridge failed to do it.
    #[error("transition `{label}` failed: {source}")]
    Failed {
        /// The transition.
        label: &'static str,
        /// Why.
        source: BackendError,
    },
}

/// The transition asked for by id (or, with id 0, by label) from `state`.
pub fn find(
    state: ManagedState,
    id: u8,
    label: &str,
) -> Result<ManagedTransition, TransitionError> {
    transitions_from(state)
        .iter()
        .find(|t| {
            if id != 0 {
                t.id == id
            } else {
                t.label == label
            }
        })
        .copied()
        .ok_or_else(|| TransitionError::NotAvailable {
            id,
            label: label.to_string(),
            state,
        })
}

/// Takes `transition` (from [`find`]) on the bridge; returns the new state. On failure the
/// state is unchanged.
pub fn apply<B: Backend>(
    bridge: &mut JointBridge<B>,
    transition: ManagedTransition,
) -> Result<ManagedState, TransitionError> {
    let failed = |source| TransitionError::Failed {
        label: transition.label,
        source,
    };
    match transition.label {
        "configure" => {
            if let Err(e) = bridge.start() {
                // Unconfigured again: no reconnection retries behind the manager's back.
                let _ = bridge.stop();
                return Err(failed(e));
            }
            // Holding the measured pose the start found.
            bridge.hold(Operator::Inactive);
        }
        "activate" => {
            bridge.release(Operator::Inactive);
        }
        // Braked along the walk's path like an e-stop (`estop_follow_s`), then held.
        "deactivate" => bridge.stop_along(Operator::Inactive),
        "cleanup" => bridge.stop().map_err(failed)?,
        _ => {
            // shutdown: brake to a hold, then torque off.
            bridge.hold(Operator::Inactive);
            bridge.stop().map_err(failed)?;
        }
    }
    Ok(transition.goal)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_transitions_are_those_of_rclcpp() {
        use ManagedState::*;
        let ids = |s| transitions_from(s).iter().map(|t| t.id).collect::<Vec<_>>();
        assert_eq!(ids(Unconfigured), [1, 5]);
        assert_eq!(ids(Inactive), [2, 3, 6]);
        assert_eq!(ids(Active), [4, 7]);
        assert!(ids(Finalized).is_empty());
        assert_eq!(find(Active, 0, "shutdown").unwrap().id, 7);
        assert_eq!(find(Inactive, 3, "").unwrap().goal, Active);
        let e = find(Active, 3, "activate").unwrap_err();
        assert_eq!(
            e.to_string(),
            "transition 3 `activate` is not available from state `active`"
        );
    }

    /// A board that is not there (unpowered, unplugged).
    struct Absent;
    impl Backend for Absent {
        fn name(&self) -> &str {
            "absent"
        }
        fn configure(&mut self, _: &[crate::JointSpec]) -> Result<Option<Vec<f64>>, BackendError> {
            Err(BackendError::Open {
                backend: "absent".into(),
                why: "no such port".into(),
            })
        }
        fn activate(&mut self) -> Result<(), BackendError> {
            Ok(())
        }
        fn write(&mut self, _: f64, _: &[f64]) -> Result<(), BackendError> {
            Ok(())
        }
        fn read(&mut self, _: f64) -> Result<crate::Reading, BackendError> {
            Err(BackendError::Open {
                backend: "absent".into(),
                why: "not open".into(),
            })
        }
        fn deactivate(&mut self) -> Result<(), BackendError> {
            Ok(())
        }
    }

    #[test]
    fn a_configure_that_fails_leaves_no_reconnection_running_behind_the_manager() {
        // A serial bridge retries a failed start by itself; configured by a manager, a
        // failure is the manager's to retry: the node stays unconfigured, nothing retries.
        let config = crate::BridgeConfig {
            reconnect: Some(crate::Backoff {
                first_s: 0.1,
                max_s: 1.0,
            }),
            ..Default::default()
        };
        let mut bridge = JointBridge::new(Absent, Vec::new(), config);
        let configure = find(ManagedState::Unconfigured, 1, "").unwrap();
        let e = apply(&mut bridge, configure).unwrap_err();
        assert_eq!(
            e.to_string(),
            "transition `configure` failed: absent: cannot open: no such port"
        );
        assert_ne!(bridge.state(), crate::Lifecycle::Error);
        let (_, events) = bridge.tick(5.0);
        assert!(
            !events
                .iter()
                .any(|e| matches!(e, crate::Event::RetryFailed { .. })),
            "{events:?}"
        );
    }
}
