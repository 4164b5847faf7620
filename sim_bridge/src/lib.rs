//! The biped in MuJoCo: the physics test bench of the walk.
//!
//! Data flow: URDF text + [`SimConfig`] → [`Sim`] (the MuJoCo model built from the URDF with
//! MuJoCo's model editor: a free-floating base, a floor, one position servo per joint with
//! the URDF's torque limit) → [`Sim::set_targets`] (servo targets in
//! [`ik_solver::RobotModel::dof_names`] order) and [`Sim::step`] / [`Sim::advance_to`] with
//! the time passed in → readings: joint positions, base pose, floor contact forces, centre
//! of pressure against the support polygon of the loaded soles, and whether and why the
//! robot fell.
//!
//! Or: an MJCF scene + a [`JointMap`] (scene joint, actuator and body names of the URDF's)
//! → [`Sim::from_mjcf_str`] / [`Sim::from_mjcf_file`]: the same API, the URDF still the
//! robot model of the plan and the compensation.
//!
//! Around it:
//! - [`static_torques_nm`] / [`compensated_targets_rad`]: the servo-sag compensation of
//!   ALGORITHM.md ("Position servos are springs") of a planned pose
//!   ([`ik_solver::StaticPose`]), from the URDF mass model alone;
//! - [`DelayLine`]: commands acting a fixed delay of simulated time after they came, as a
//!   servo bus's latency delays them;
//! - [`SimBackend`]: the simulator behind joint_bridge's [`joint_bridge::Backend`] trait,
//!   so the node fleet can drive it like a servo board.
//!
//! Below the planning: this crate knows poses and joint vectors, not gait plans. Playing a plan
//! into it and judging the walk (fall, tilt, distance, centre of pressure) is `walk_eval`'s.
//!
//! Pure library: no clock (physics time only advances when asked), no files, no middleware.
//! MuJoCo comes from the PyPI wheel (`scripts/setup-python-env`), linked dynamically.

mod backend;
mod compensation;
mod config;
mod delay;
mod error;
mod mjcf;
mod mjmodel;
mod sim;

/// The ROS 2 node (feature `node`): [`node::run`] alone in its process or composed.
#[cfg(feature = "node")]
pub mod node;
pub use backend::SimBackend;
pub use compensation::{
    compensated_targets_rad, static_compensation_rad, static_foot_loads, static_torques_nm,
};
pub use config::SimConfig;
pub use delay::DelayLine;
pub use error::SimError;
pub use ik_solver::{FootLoad, GRAVITY_M_S2};
pub use mjcf::{JointMap, MappedJoint};
pub use sim::{
    BODY_CONTACT_FRACTION, COP_MIN_FRACTION, ContactReading, Fall, FallReason, ImuReading,
    LOADED_FRACTION, Sim, tilt_rad,
};
