//! What each step does: the body's travel per step (forward or backward, sideways), and its
//! conversion from a velocity command (`cmd_vel`'s Twist, REP-103 signs: x forward, y left,
//! z counter-clockwise) within the limits of the configuration.

use crate::error::GaitError;
use crate::params::GaitConfig;

/// The body's travel per step, in the walk frame (x forward, y left).
///
/// A step is a CoM shift plus a swing ([`GaitConfig::step_period_s`]). The swing foot lands
/// `forward_m` ahead of the stance foot (behind it when negative), so the body advances
/// `forward_m` per step. Sideways, only the foot on the side of travel can open: it lands
/// `2 |left_m|` further out than the standing width, and the next swing brings the other foot
/// back to the standing width, so the body travels `left_m` per step on average and the
/// feet never come closer than they stand.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Stride {
    /// Forward travel per step (m); negative walks backward.
    pub forward_m: f64,
    /// Sideways travel per step (m); positive to the left.
    pub left_m: f64,
    /// Turn per step (rad), counter-clockwise, on average: the foot on the side of the turn
    /// turns by twice this, the other comes back parallel to it. Needs hip yaw joints.
    pub turn_rad: f64,
}

impl Stride {
    /// Straight ahead (or back, when negative).
    pub fn forward(forward_m: f64) -> Self {
        Self {
            forward_m,
            ..Self::default()
        }
    }

    /// True when the stride moves nothing.
    pub fn is_zero(&self) -> bool {
        self.forward_m == 0.0 && self.left_m == 0.0 && self.turn_rad == 0.0
    }
}

/// A velocity command in the walk frame (REP-103): what `cmd_vel` carries, less the axes a
/// walker on the floor cannot use.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Velocity {
    /// Forward speed (m/s), `linear.x`.
    pub x_m_s: f64,
    /// Leftward speed (m/s), `linear.y`.
    pub y_m_s: f64,
    /// Counter-clockwise turn rate (rad/s), `angular.z`.
    pub yaw_rad_s: f64,
}

/// A velocity turned into a stride, and what had to be limited to get there.
#[derive(Debug, Clone, PartialEq)]
pub struct StrideCommand {
    /// The stride to walk.
    pub stride: Stride,
    /// Set when the command was above the limits and was scaled down (direction kept):
    /// the velocity walked, for the warning.
    pub limited_to: Option<Velocity>,
}

impl GaitConfig {
    /// Converts a velocity into a stride per step, scaled down (keeping its direction) into
    /// the ellipsoid of the per-axis limits: `step_length_m` forward, `back_step_length_m`
    /// backward, `side_step_m` sideways, `turn_step_rad` turning, each per step.
    ///
    /// Refused, naming the field and value: a value that is not finite, and a turn rate on
    /// a robot without hip yaw joints (or whose turn limit is 0).
    pub fn stride_for(&self, v: Velocity, has_hip_yaw: bool) -> Result<StrideCommand, GaitError> {
        for (field, value) in [
            ("linear.x", v.x_m_s),
            ("linear.y", v.y_m_s),
            ("angular.z", v.yaw_rad_s),
        ] {
            if !value.is_finite() {
                return Err(GaitError::Request(format!(
                    "{field} = {value} is not a finite number"
                )));
            }
        }
        if v.yaw_rad_s != 0.0 && (!has_hip_yaw || self.turn_step_rad <= 0.0) {
            let why = if has_hip_yaw {
                "turn_step_rad is 0 (no turn passed the check walks)"
            } else {
                "this robot's legs have no hip yaw joint, so it cannot turn"
            };
            return Err(GaitError::Request(format!(
                "angular.z = {} rad/s: {why}",
                v.yaw_rad_s
            )));
        }
        let period = self.step_period_s();
        let want = Stride {
            forward_m: v.x_m_s * period,
            left_m: v.y_m_s * period,
            turn_rad: v.yaw_rad_s * period,
        };
        let x_max = if want.forward_m >= 0.0 {
            self.step_length_m
        } else {
            self.back_step_length_m
        };
        // An axis whose limit is 0 cannot move at all; then the ellipse of the limits.
        let ratio = |value: f64, max: f64| if max > 0.0 { value / max } else { 0.0 };
        let axis = |value: f64, max: f64| if max > 0.0 { value } else { 0.0 };
        let (rx, ry, rz) = (
            ratio(want.forward_m, x_max),
            ratio(want.left_m, self.side_step_m),
            ratio(want.turn_rad, self.turn_step_rad),
        );
        // A command on a limit stays on it (not a part per billion beyond, from rounding).
        let reach = rx.hypot(ry).hypot(rz);
        let scale = if reach <= 1.0 + 1e-9 { 1.0 } else { reach };
        let stride = Stride {
            forward_m: axis(want.forward_m, x_max) / scale,
            left_m: axis(want.left_m, self.side_step_m) / scale,
            turn_rad: axis(want.turn_rad, self.turn_step_rad) / scale,
        };
        if stride == want {
            return Ok(StrideCommand {
                stride,
                limited_to: None,
            });
        }
        Ok(StrideCommand {
            stride,
            limited_to: Some(Velocity {
                x_m_s: stride.forward_m / period,
                y_m_s: stride.left_m / period,
                yaw_rad_s: stride.turn_rad / period,
            }),
        })
    }
}
