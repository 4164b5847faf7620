//! Statics of a pose held still: the floor reactions that carry the robot and the torque
//! each joint must give, from the URDF mass model alone.
//!
//! Position servos are springs (ALGORITHM.md): under the robot's weight each joint sags below
//! its target by about torque / kp. Aiming each servo torque / kp beyond the wanted angle
//! cancels most of that sag: [`BipedModel::sag_compensation_rad`].
//!
//! The floor carries the weight under the CoM: on one sole all of it; on both soles split by
//! where the CoM lies along the line joining the sole centres, each share under the CoM's
//! offset from that line (so the centre of pressure is under the CoM and the base needs no
//! force).

use nalgebra::{Isometry3, Point3, Vector3};

use crate::error::IkError;
use crate::ik::BipedModel;
use crate::legs::Side;
use crate::model::JointKind;

/// Standard gravity (m/s²), MuJoCo's default.
pub const GRAVITY_M_S2: f64 = 9.81;

/// Soles whose lowest points are within this height of each other both carry the robot
/// when the stance is read from a pose ([`BipedModel::stance_of_pose`], m).
pub const DOUBLE_SUPPORT_TOLERANCE_M: f64 = 0.002;

/// Which soles carry the robot.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stance {
    /// One sole.
    Single(Side),
    /// Both soles.
    Double,
}

/// A whole-body pose held still: what the statics need of a planned (or measured) pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StaticPose<'a> {
    /// Pose of the base (root) link in the world.
    pub base_world: &'a Isometry3<f64>,
    /// All joint positions (rad; m for a prismatic joint), in
    /// [`crate::RobotModel::dof_names`] order.
    pub joints_rad: &'a [f64],
    /// Whole-body centre of mass in the world (m): the centre of pressure goes under it.
    pub com_world_m: Point3<f64>,
    /// Which soles carry the robot.
    pub stance: Stance,
}

/// A vertical floor reaction on one sole.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FootLoad {
    /// Which sole.
    pub side: Side,
    /// Upward force (N).
    pub force_n: f64,
    /// Where it acts: a point on the sole plane (world, m).
    pub point_world_m: Point3<f64>,
}

impl BipedModel {
    /// The centre of a sole rectangle on the sole plane (world, m), from link poses.
    pub fn sole_centre_world(&self, poses: &[Isometry3<f64>], side: Side) -> Point3<f64> {
        let leg = self.leg(side);
        let ankle = leg.ankle_world(self.robot(), poses);
        let turn = poses[leg.foot_link].rotation * leg.foot_rotation0.inverse();
        let r = &leg.sole;
        ankle
            + turn
                * Vector3::new(
                    (r.x_min_m + r.x_max_m) / 2.0,
                    (r.y_min_m + r.y_max_m) / 2.0,
                    -leg.ankle_to_sole_m,
                )
    }

    /// The four bottom corners of a sole in the world for link poses `poses` (m), in the
    /// order of [`crate::legs::SoleRect::corners`].
    pub fn sole_corners_world(&self, poses: &[Isometry3<f64>], side: Side) -> [Point3<f64>; 4] {
        let leg = self.leg(side);
        let ankle = leg.ankle_world(self.robot(), poses);
        let turn = poses[leg.foot_link].rotation * leg.foot_rotation0.inverse();
        let r = &leg.sole;
        [
            (r.x_min_m, r.y_min_m),
            (r.x_max_m, r.y_min_m),
            (r.x_max_m, r.y_max_m),
            (r.x_min_m, r.y_max_m),
        ]
        .map(|(x, y)| ankle + turn * Vector3::new(x, y, -leg.ankle_to_sole_m))
    }

    /// The stance a pose stands on, the floor being horizontal under a level base: the
    /// lower sole, or both when their centres are within [`DOUBLE_SUPPORT_TOLERANCE_M`] of the
    /// same height.
    pub fn stance_of_pose(&self, poses: &[Isometry3<f64>]) -> Stance {
        let zl = self.sole_centre_world(poses, Side::Left).z;
        let zr = self.sole_centre_world(poses, Side::Right).z;
        if (zl - zr).abs() <= DOUBLE_SUPPORT_TOLERANCE_M {
            Stance::Double
        } else if zl < zr {
            Stance::Single(Side::Left)
        } else {
            Stance::Single(Side::Right)
        }
    }

    /// The floor reactions that hold the pose of `poses` still with the centre of pressure
    /// under `com_world_m`, for a robot of weight `weight_n`.
    pub fn static_foot_loads(
        &self,
        poses: &[Isometry3<f64>],
        com_world_m: Point3<f64>,
        stance: Stance,
        weight_n: f64,
    ) -> Vec<FootLoad> {
        let c = com_world_m;
        let centre = |s: Side| self.sole_centre_world(poses, s);
        match stance {
            Stance::Single(s) => vec![FootLoad {
                side: s,
                force_n: weight_n,
                point_world_m: Point3::new(c.x, c.y, centre(s).z),
            }],
            Stance::Double => {
                let (l, r) = (centre(Side::Left), centre(Side::Right));
                let e = Vector3::new(l.x - r.x, l.y - r.y, 0.0);
                let to_c = Vector3::new(c.x - r.x, c.y - r.y, 0.0);
                let share_left = if e.norm_squared() > 0.0 {
                    (to_c.dot(&e) / e.norm_squared()).clamp(0.0, 1.0)
                } else {
                    0.5
                };
                let on_line = Vector3::new(r.x, r.y, 0.0) + e * share_left;
                let (dx, dy) = (c.x - on_line.x, c.y - on_line.y);
                let load = |side: Side, p: Point3<f64>, share: f64| FootLoad {
                    side,
                    force_n: share * weight_n,
                    point_world_m: Point3::new(p.x + dx, p.y + dy, p.z),
                };
                vec![
                    load(Side::Left, l, share_left),
                    load(Side::Right, r, 1.0 - share_left),
                ]
            }
        }
    }

    /// The static torque (N·m; N for a prismatic joint) each joint must give to hold the
    /// pose of `poses` against gravity and the floor reactions `loads`, one per joint in
    /// [`crate::RobotModel::dof_names`] order, positive along the joint axis.
    pub fn static_torques_nm(&self, poses: &[Isometry3<f64>], loads: &[FootLoad]) -> Vec<f64> {
        let robot = self.robot();
        // Is `link` below joint `joint` (moved by it)?
        let below = |joint: usize, mut link: usize| {
            while let Some(j) = robot.links()[link].parent_joint {
                if j == joint {
                    return true;
                }
                link = robot.joints()[j].parent;
            }
            false
        };
        let mut tau = Vec::with_capacity(robot.dof_count());
        for &ji in robot.dof_joints() {
            let joint = &robot.joints()[ji];
            let frame = robot.joint_frame(poses, ji);
            let axis = frame.rotation * joint.axis.into_inner();
            let p = Point3::from(frame.translation.vector);
            let (mass_kg, com) = robot.subtree_mass_and_com(poses, ji);
            let gravity = Vector3::new(0.0, 0.0, -mass_kg * GRAVITY_M_S2);
            let mut force = gravity;
            let mut moment = (com - p).cross(&gravity);
            for load in loads {
                if below(ji, self.leg(load.side).foot_link) {
                    let f = Vector3::new(0.0, 0.0, load.force_n);
                    force += f;
                    moment += (load.point_world_m - p).cross(&f);
                }
            }
            // The servo balances what gravity and the floor do to everything below the joint.
            tau.push(match joint.kind {
                JointKind::Prismatic => -axis.dot(&force),
                _ => -axis.dot(&moment),
            });
        }
        tau
    }

    /// Servo-sag compensation for the joint vector `joints_rad` (all movable joints, in
    /// [`crate::RobotModel::dof_names`] order): static torque / `kp_nm_per_rad` per joint
    /// (rad), to add to the wanted positions. The base is taken as level and the stance as
    /// [`Self::stance_of_pose`] reads it, which is how the gait planner holds the robot.
    ///
    /// ```
    /// use ik_solver::{BipedModel, DEFAULT_URDF};
    /// let model = BipedModel::from_urdf_str(DEFAULT_URDF, None).unwrap();
    /// let mut q = vec![0.0; model.robot().dof_count()];
    /// let knee = model.robot().dof_index("l_knee").unwrap();
    /// // Straight legs: the weight goes down the bones, the knees need no torque.
    /// let straight = model.sag_compensation_rad(&q, 30.0).unwrap();
    /// assert!(straight[knee].abs() < 1e-9);
    /// // Bent knees carry the robot: the servo must aim further than the wanted bend.
    /// q[knee] = 0.6;
    /// q[model.robot().dof_index("r_knee").unwrap()] = 0.6;
    /// for hip in ["l_hip_pitch", "r_hip_pitch"] { q[model.robot().dof_index(hip).unwrap()] = -0.3; }
    /// for ankle in ["l_ankle_pitch", "r_ankle_pitch"] { q[model.robot().dof_index(ankle).unwrap()] = -0.3; }
    /// let bent = model.sag_compensation_rad(&q, 30.0).unwrap();
    /// assert!(bent[knee].abs() > 0.005);
    /// ```
    pub fn sag_compensation_rad(
        &self,
        joints_rad: &[f64],
        kp_nm_per_rad: f64,
    ) -> Result<Vec<f64>, IkError> {
        if !(kp_nm_per_rad.is_finite() && kp_nm_per_rad > 0.0) {
            return Err(IkError::BadParameter {
                name: "kp_nm_per_rad",
                value: kp_nm_per_rad,
                why: "a servo stiffness must be a finite number above 0 N·m/rad",
            });
        }
        let robot = self.robot();
        let poses = robot.link_poses(&Isometry3::identity(), joints_rad)?;
        let com = robot.center_of_mass(&poses);
        let weight_n = robot.total_mass_kg() * GRAVITY_M_S2;
        let loads = self.static_foot_loads(&poses, com, self.stance_of_pose(&poses), weight_n);
        Ok(self
            .static_torques_nm(&poses, &loads)
            .into_iter()
            .map(|t| t / kp_nm_per_rad)
            .collect())
    }

    /// Gyro damping: offsets (rad, one per joint in [`crate::RobotModel::dof_names`]
    /// order) that make position servos damp the body's rotation as if each joint of a leg
    /// standing on the floor had `gain_s` x its stiffness more damping against it:
    /// `gain_s · (a_j · ω)` for every joint `j` of those legs, `a_j` its axis and `ω` the
    /// base's angular velocity (`body_rate_rad_s`, what a gyroscope on the base reads) less
    /// its part about the base's z axis, both in the base frame; 0 for the other joints.
    /// Only the roll and pitch of the body are damped: turning about the vertical is the
    /// walk's own (a turn in place), not to be resisted. Why: a servo of stiffness kp aimed Δ
    /// further gives kp·Δ more torque, and with the foot fixed a joint turns the body above
    /// it by minus its own rotation, so aiming `gain_s · (a_j · ω)` further gives the torque
    /// `kp · gain_s · (a_j · ω)` against the body's turn: the damping `kp · gain_s`
    /// (N·m·s/rad) a servo's own derivative gain would give. The legs on the floor are read
    /// from the pose as [`Self::sag_compensation_rad`] reads them (both in double support).
    ///
    /// ```
    /// use ik_solver::{BipedModel, DEFAULT_URDF};
    /// use nalgebra::Vector3;
    /// let model = BipedModel::from_urdf_str(DEFAULT_URDF, None).unwrap();
    /// let q = vec![0.0; model.robot().dof_count()];
    /// // Standing on both feet, rolling at 0.5 rad/s: the roll joints (axes along x) of both
    /// // legs aim 0.01 s x 0.5 rad/s further, the pitch joints not at all.
    /// let d = model.gyro_damping_rad(&q, &Vector3::new(0.5, 0.0, 0.0), 0.01).unwrap();
    /// let r = |n: &str| d[model.robot().dof_index(n).unwrap()];
    /// assert!((r("l_hip_roll").abs() - 0.005).abs() < 1e-12);
    /// assert!((r("r_ankle_roll").abs() - 0.005).abs() < 1e-12);
    /// assert_eq!(r("l_knee"), 0.0);
    /// ```
    pub fn gyro_damping_rad(
        &self,
        joints_rad: &[f64],
        body_rate_rad_s: &Vector3<f64>,
        gain_s: f64,
    ) -> Result<Vec<f64>, IkError> {
        if !(gain_s.is_finite() && gain_s >= 0.0) {
            return Err(IkError::BadParameter {
                name: "gain_s",
                value: gain_s,
                why: "a gyro damping gain must be a finite number of seconds, 0 or more",
            });
        }
        if let Some(w) = body_rate_rad_s.iter().find(|w| !w.is_finite()) {
            return Err(IkError::BadParameter {
                name: "body_rate_rad_s",
                value: *w,
                why: "the base's angular velocity must be finite",
            });
        }
        let w = Vector3::new(body_rate_rad_s.x, body_rate_rad_s.y, 0.0);
        let robot = self.robot();
        let poses = robot.link_poses(&Isometry3::identity(), joints_rad)?;
        let standing: &[Side] = match self.stance_of_pose(&poses) {
            Stance::Double => &[Side::Left, Side::Right],
            Stance::Single(Side::Left) => &[Side::Left],
            Stance::Single(Side::Right) => &[Side::Right],
        };
        let mut out = vec![0.0; robot.dof_count()];
        for &side in standing {
            for j in self.leg(side).joints.iter().flatten() {
                let joint = &robot.joints()[j.joint];
                if joint.kind == JointKind::Prismatic {
                    continue;
                }
                let axis = robot.joint_frame(&poses, j.joint).rotation * joint.axis.into_inner();
                out[j.dof] = gain_s * axis.dot(&w);
            }
        }
        Ok(out)
    }
}
