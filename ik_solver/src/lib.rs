//! The kinematic core of the biped walk: a robot model read from any biped URDF, the paper's
//! closed-form leg inverse kinematics, forward kinematics and the whole-body centre of mass.
//!
//! Data flow: URDF text → [`RobotModel`] (tree of links and joints, inertials, limits, FK,
//! CoM) → [`BipedModel`] (the two legs found in the tree, with thigh and shin lengths, hip
//! offsets, sole rectangles and axis signs) → [`BipedModel::solve_legs`] (ankle targets
//! relative to the hips → joint angles in URDF convention).
//!
//! Also the statics of a pose held still ([`StaticPose`]: floor reactions and joint torques,
//! for the servo-sag compensation) and [`support`] polygons, which the planner (the CoM's
//! margin) and the simulator (the measured centre of pressure's) both use: the bottom layer
//! of the workspace, depending on no other crate of it.
//!
//! [`frames`] turns joint states into the link frames a robot state publisher sends to TF.
//!
//! Pure library: no I/O beyond reading a URDF file when asked, no clock, no middleware. The
//! `ik_solver` ROS 2 node wraps it (the `node` feature). Frames follow REP-103 (x forward,
//! y left, z up), lengths in metres, angles in radians.

mod error;
pub mod frames;
mod ik;
mod legs;
mod model;
pub mod odometry;
mod statics;
pub mod support;
pub mod trig;

/// The ROS 2 node (feature `node`): [`node::run`] alone in its process or composed.
#[cfg(feature = "node")]
pub mod node;
pub use error::{IkError, ModelError, ParameterFilesError};
pub use frames::{FrameTransform, FrameTree, JointStateError, SkippedJoints};
pub use ik::{AnkleTarget, BipedModel, IkIssue, LegSolution};
pub use legs::{Axis, JointRole, Leg, LegJoint, LegJointNames, LegRoleMap, Side, SoleRect};
pub use model::{CollisionBox, Inertial, Joint, JointKind, JointLimits, Link, RobotModel};
pub use odometry::LegOdometry;
pub use statics::{DOUBLE_SUPPORT_TOLERANCE_M, FootLoad, GRAVITY_M_S2, Stance, StaticPose};

/// The URDF of the project's default robot, built in so every command has a robot to use.
pub const DEFAULT_URDF: &str = include_str!("../../config/biped.urdf");
