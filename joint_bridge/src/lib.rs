//! The joint bridge: joint commands in, a backend (mock, simulator, serial servo board)
//! moved safely, joint states out.
//!
//! Data flow: [`JointBridge::command`] takes a command (names, positions) at any time; it
//! refuses non-finite values and unknown joints by name, clamps to the URDF limits and feeds
//! the watchdog. [`JointBridge::tick`] runs at the bridge's rate with the time passed in: it
//! trips the watchdog when commands stop (hold the pose, or go limp), moves the output toward
//! the target within each joint's velocity and acceleration limits ([`motion`], the one
//! limiter every written position goes through, sag offset included), optionally aiming
//! each servo beyond it by the sag of the pose's static torque ([`SagCompensation`]),
//! writes it to the [`Backend`] and
//! reads the joint states back. Everything the bridge notices comes back as [`Event`]s for the
//! node to log.
//!
//! Pure library: no clock, no middleware. The `joint_bridge` ROS 2 node wraps it.

mod backend;
mod bridge;
mod compensation;
mod limits;
pub mod managed;
mod mock;
pub mod motion;
pub mod pacing;
pub mod serial;

/// The ROS 2 node (feature `node`): [`node::run`] alone in its process or composed.
#[cfg(feature = "node")]
pub mod node;
pub use backend::{Backend, BackendError, DiagnosticLevel, Diagnostics, Lifecycle, Reading};
pub use bridge::{
    Backoff, BridgeConfig, Event, FOLLOW_SILENCE_S, FollowEnd, JointBridge, MAX_UNKNOWN_REPORTED,
    Operator, TimeoutAction, TorqueError,
};
pub use compensation::{CompensationError, GYRO_MAX_AGE_S, GyroDamping, SagCompensation};
pub use limits::JointSpec;
pub use mock::MockBackend;
pub use pacing::TickPacing;
