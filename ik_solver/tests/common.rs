//! Shared helpers of the ik_solver tests.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
#![allow(dead_code)]

use ik_solver::{BipedModel, Side};
use nalgebra::{Isometry3, UnitQuaternion, Vector3};

pub const TEST_BIPED6: &str = include_str!("../../tests/data/biped6_renamed.urdf");

pub fn default_biped() -> BipedModel {
    BipedModel::from_urdf_str(ik_solver::DEFAULT_URDF, None).expect("default robot loads")
}

pub fn biped6() -> BipedModel {
    BipedModel::from_urdf_str(TEST_BIPED6, None).expect("test biped loads")
}

/// Angle (rad) between the foot's orientation and "level, turned by `yaw` about z", for the
/// foot of `side` at joint vector `q` with the base at the identity.
pub fn foot_tilt_rad(b: &BipedModel, side: Side, q: &[f64], yaw: f64) -> f64 {
    let poses = b.robot().link_poses(&Isometry3::identity(), q).unwrap();
    let leg = b.leg(side);
    let now = poses[leg.foot_link].rotation;
    let want = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw) * leg.foot_rotation0;
    now.angle_to(&want)
}

/// The OP3-layout test robot (tests/data/make_op3_layout.py): hip yaw and roll origins
/// apart, pitch plane and ankle roll axis offset sideways, a tilted thigh and shin.
pub const TEST_OP3_LAYOUT: &str = include_str!("../../tests/data/op3_layout.urdf");

pub fn op3_layout() -> BipedModel {
    BipedModel::from_urdf_str(TEST_OP3_LAYOUT, None).expect("OP3-layout robot loads")
}
