//! Leg odometry: where the base is in the `odom` frame (REP-105: continuous, drifting), from
//! the joint angles alone, with the planted foot as the fixed point.
//!
//! While a foot carries the robot it is taken not to move: the base is that foot's pose in
//! `odom` composed with the inverse of the foot's pose in the base frame (forward kinematics
//! of the measured joints). When the other foot becomes the planted one, its pose in `odom`
//! is read off the base estimate at that instant, put flat on the floor (the height of the
//! first planted foot, roll and pitch zero: the planner keeps the soles level) and held from
//! then on. Errors come from foot slip and joint sensing, so they grow with the path walked
//! ([`LegOdometry::covariance`]).

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use crate::{BipedModel, IkError, Side};

/// Standard deviation of the position at the start, and added per metre walked (m, m/m).
pub const POSITION_SIGMA_M: (f64, f64) = (0.002, 0.05);
/// Standard deviation of the heading at the start, and added per metre walked (rad, rad/m).
pub const YAW_SIGMA_RAD: (f64, f64) = (0.005, 0.05);
/// Standard deviation of the height (m) and of roll and pitch (rad), which the level-sole
/// assumption fixes rather than measures.
pub const HEIGHT_SIGMA_M: f64 = 0.005;
/// See [`HEIGHT_SIGMA_M`].
pub const TILT_SIGMA_RAD: f64 = 0.02;

/// The base pose in `odom` from the joints and which foot is planted.
#[derive(Debug, Clone)]
pub struct LegOdometry {
    planted: Side,
    foot_odom: Isometry3<f64>,
    floor_z_m: f64,
    base_odom: Isometry3<f64>,
    path_m: f64,
    poses: Vec<Isometry3<f64>>,
}

/// Puts a foot pose flat on the floor at `z`: keeps x, y and the heading.
fn flat(pose: &Isometry3<f64>, z: f64) -> Isometry3<f64> {
    let x = pose.rotation * Vector3::x();
    let yaw = x.y.atan2(x.x);
    Isometry3::from_parts(
        Translation3::new(pose.translation.x, pose.translation.y, z),
        UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
    )
}

impl LegOdometry {
    /// Starts with the base at `base_odom`, the joints at `joints_rad` (model dof order) and
    /// `planted` carrying the robot.
    pub fn new(
        model: &BipedModel,
        base_odom: Isometry3<f64>,
        joints_rad: &[f64],
        planted: Side,
    ) -> Result<Self, IkError> {
        let mut o = Self {
            planted,
            foot_odom: Isometry3::identity(),
            floor_z_m: 0.0,
            base_odom,
            path_m: 0.0,
            poses: Vec::new(),
        };
        let foot = o.foot_in_base(model, joints_rad, planted)?;
        let foot_odom = base_odom * foot;
        o.floor_z_m = foot_odom.translation.z;
        o.foot_odom = flat(&foot_odom, o.floor_z_m);
        Ok(o)
    }

    fn foot_in_base(
        &mut self,
        model: &BipedModel,
        joints_rad: &[f64],
        side: Side,
    ) -> Result<Isometry3<f64>, IkError> {
        model.robot().check_joint_vector(joints_rad)?;
        model
            .robot()
            .link_poses_into(&Isometry3::identity(), joints_rad, &mut self.poses)?;
        Ok(self.poses[model.leg(side).foot_link])
    }

    /// The base pose for new joint angles with `planted` carrying the robot.
    ///
    /// Switch `planted` while both feet are on the floor (a CoM shift onto the new foot, as
    /// [`crate::Stance`] double support): the base is first placed from the foot planted
    /// until now, with these joints, and the new foot is read off it. Switched while the old
    /// foot is already in the air, its lift would become an error.
    pub fn update(
        &mut self,
        model: &BipedModel,
        joints_rad: &[f64],
        planted: Side,
    ) -> Result<Isometry3<f64>, IkError> {
        let old = self.foot_in_base(model, joints_rad, self.planted)?;
        if planted != self.planted {
            let base = self.foot_odom * old.inverse();
            let new = self.poses[model.leg(planted).foot_link];
            self.foot_odom = flat(&(base * new), self.floor_z_m);
            self.planted = planted;
        }
        let foot = self.poses[model.leg(self.planted).foot_link];
        let base = self.foot_odom * foot.inverse();
        self.path_m += (base.translation.vector - self.base_odom.translation.vector)
            .xy()
            .norm();
        self.base_odom = base;
        Ok(base)
    }

    /// The last base pose.
    pub fn base(&self) -> &Isometry3<f64> {
        &self.base_odom
    }

    /// The foot taken as fixed.
    pub fn planted(&self) -> Side {
        self.planted
    }

    /// Horizontal path length of the base so far (m).
    pub fn path_m(&self) -> f64 {
        self.path_m
    }

    /// Row-major 6 x 6 covariance of the pose (x, y, z, roll, pitch, yaw), as
    /// `geometry_msgs/PoseWithCovariance` carries it: position and heading uncertain by
    /// [`POSITION_SIGMA_M`] and [`YAW_SIGMA_RAD`] growing with the path walked, height and
    /// tilt by [`HEIGHT_SIGMA_M`] and [`TILT_SIGMA_RAD`].
    pub fn covariance(&self) -> [f64; 36] {
        let pos = POSITION_SIGMA_M.0 + POSITION_SIGMA_M.1 * self.path_m;
        let yaw = YAW_SIGMA_RAD.0 + YAW_SIGMA_RAD.1 * self.path_m;
        let mut c = [0.0; 36];
        for (i, sigma) in [
            pos,
            pos,
            HEIGHT_SIGMA_M,
            TILT_SIGMA_RAD,
            TILT_SIGMA_RAD,
            yaw,
        ]
        .into_iter()
        .enumerate()
        {
            c[i * 6 + i] = sigma * sigma;
        }
        c
    }
}
