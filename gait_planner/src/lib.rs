//! The paper's statically stable walk as a pure library.
//!
//! Data flow: [`GaitParams`] (YAML, ROS 2 parameter-file layout) + the robot's
//! [`ik_solver::BipedModel`] → [`GaitPlanner`], which checks the walk before it starts →
//! [`WalkRequest`]s (walk N steps, walk until stopped, stop) → [`GaitPlanner::update`] at
//! each control tick with the time as an argument → [`GaitSample`]: phase, support, pelvis
//! pose, ankle targets, joint angles, whole-body CoM and its margin to the support polygon.
//!
//! No clock, no middleware, no files but the parameter file when asked: the `gait_planner`
//! ROS 2 node and `biped plan` wrap it.
//!
//! The walk (ALGORITHM.md): crouch; shift the CoM over the stance foot; half step; then
//! diagonal shift and full step, alternating feet; at the end a shift, the final half step
//! (trailing foot comes level) and centring. The pelvis is solved at every tick so the
//! whole-body CoM follows a smooth path between sole centres, including while the swing leg
//! moves, and the feet never slide.

mod error;
pub mod params;
pub mod pause;
mod phase;
mod planner;
pub mod schedule;
pub mod standing;
mod stride;
pub mod teleop;
pub mod timing;
pub mod trajectory;
pub mod zmp;

/// The ROS 2 node (feature `node`): [`node::run`] alone in its process or composed.
#[cfg(feature = "node")]
pub mod node;
pub use error::GaitError;
pub use params::{GaitConfig, GaitParams};
pub use phase::{PhaseKind, Support, WalkRequest};
pub use planner::{BalanceView, GaitPlanner, GaitSample, plan_walk};
pub use schedule::StartQueue;
pub use standing::{StandGuard, Standing};
pub use stride::{Stride, StrideCommand, Velocity};
pub use teleop::VelocityFollower;
