//! Joint limits from the URDF: what the bridge enforces whatever the backend.

use ik_solver::RobotModel;

/// One joint the bridge drives, with its URDF limits.
#[derive(Debug, Clone, PartialEq)]
pub struct JointSpec {
    /// URDF joint name.
    pub name: String,
    /// Lowest position (rad).
    pub lower_rad: f64,
    /// Highest position (rad).
    pub upper_rad: f64,
    /// Speed limit (rad/s).
    pub velocity_rad_s: f64,
}

impl JointSpec {
    /// Every movable joint of a robot, in URDF order, with its limits (continuous joints
    /// without position limits keep ±inf).
    pub fn from_robot(robot: &RobotModel) -> Vec<JointSpec> {
        robot
            .dof_joints()
            .iter()
            .map(|&j| {
                let joint = &robot.joints()[j];
                let l = joint.limits.unwrap_or(ik_solver::JointLimits {
                    lower: f64::NEG_INFINITY,
                    upper: f64::INFINITY,
                    velocity: f64::INFINITY,
                    effort: f64::INFINITY,
                });
                JointSpec {
                    name: joint.name.clone(),
                    lower_rad: l.lower,
                    upper_rad: l.upper,
                    velocity_rad_s: if l.velocity > 0.0 {
                        l.velocity
                    } else {
                        f64::INFINITY
                    },
                }
            })
            .collect()
    }

    /// The position clamped into the limits.
    pub fn clamp(&self, position_rad: f64) -> f64 {
        position_rad.clamp(self.lower_rad, self.upper_rad)
    }
}
