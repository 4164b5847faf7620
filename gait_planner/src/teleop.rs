//! Following a stream of velocity commands (`cmd_vel`), with time passed in: what the
//! gait_planner node does with each Twist and at each tick, testable without DDS.
//!
//! - A non-zero velocity becomes the stride of the next swings ([`GaitPlanner::stride_for`]:
//!   scaled into the step limits) and walks until stopped; a new one while walking is taken
//!   at the next swing.
//! - A zero velocity ends the walk: the foot in the air lands, then the closing half step.
//! - No command for `cmd_vel_timeout_s` ends it the same way: a teleop that dies does not
//!   leave the robot walking.
//! - A command that cannot be walked (not finite, a turn on a robot without hip yaw) is
//!   refused whole, with a warning naming the field and value; the walk in progress goes on
//!   and, with no valid command after it, times out. The turn is reported once.

use crate::GaitPlanner;
use crate::phase::WalkRequest;
use crate::stride::{Stride, Velocity};

/// The state of a `cmd_vel` stream: when the walk it drives times out.
#[derive(Debug, Clone, Default)]
pub struct VelocityFollower {
    /// Time after which the walk ends unless another command comes (s); `None` when no
    /// walk is driven by velocity commands.
    deadline_s: Option<f64>,
    /// A turn was refused and said so.
    reported_turn: bool,
    /// The last velocity reported as limited, so a steady stream warns once.
    reported_limit: Option<Velocity>,
    /// The last stride reported as lowered by its check from the present pose, and the
    /// stride taken instead, so a steady stream warns once per change.
    reported_lowered: Option<(Stride, Stride)>,
}

impl VelocityFollower {
    /// No walk driven yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// True while a walk is driven by velocity commands (and has not timed out).
    pub fn is_driving(&self) -> bool {
        self.deadline_s.is_some()
    }

    /// Takes a velocity command received at `now_s` (the tick time). Returns a warning for
    /// the log when the command was refused or limited.
    pub fn command(
        &mut self,
        planner: &mut GaitPlanner,
        v: Velocity,
        now_s: f64,
    ) -> Option<String> {
        let is_zero = v.x_m_s == 0.0 && v.y_m_s == 0.0 && v.yaw_rad_s == 0.0;
        if is_zero {
            // A zero Twist stops any walk, however it was started.
            planner.request(WalkRequest::Stop);
            self.deadline_s = None;
            return None;
        }
        let cmd = match planner.stride_for(v) {
            Ok(cmd) => cmd,
            Err(e) => {
                let finite = [v.x_m_s, v.y_m_s, v.yaw_rad_s]
                    .iter()
                    .all(|x| x.is_finite());
                let is_turn = finite && v.yaw_rad_s != 0.0;
                if is_turn && self.reported_turn {
                    return None;
                }
                self.reported_turn |= is_turn;
                let once = if is_turn { " (reported once)" } else { "" };
                return Some(format!("cmd_vel refused: {e}{once}"));
            }
        };
        if cmd.stride.is_zero() {
            // Every axis asked for has a limit of 0 here (no back step, no side step): no
            // walk in place for it.
            return Some(format!(
                "cmd_vel refused: linear.x = {}, linear.y = {} m/s: this robot's step limits allow no motion that way",
                v.x_m_s, v.y_m_s
            ));
        }
        let taken = match planner.set_stride(cmd.stride) {
            Ok(taken) => taken,
            Err(e) => return Some(format!("cmd_vel refused: {e}")),
        };
        if self.deadline_s.is_none() {
            planner.request(WalkRequest::UntilStop);
        }
        self.deadline_s = Some(now_s + planner.config().cmd_vel_timeout_s);
        if taken != cmd.stride {
            if self.reported_lowered == Some((cmd.stride, taken)) {
                return None;
            }
            self.reported_lowered = Some((cmd.stride, taken));
            return Some(format!(
                "cmd_vel: from the present pose a step of {:.4} m, {:.4} m, {:.4} rad fails its check; taking {:.4} m, {:.4} m, {:.4} rad",
                cmd.stride.forward_m,
                cmd.stride.left_m,
                cmd.stride.turn_rad,
                taken.forward_m,
                taken.left_m,
                taken.turn_rad
            ));
        }
        match cmd.limited_to {
            Some(l) if self.reported_limit != Some(l) => {
                self.reported_limit = Some(l);
                Some(format!(
                    "cmd_vel: linear.x = {}, linear.y = {} m/s is beyond the step limits; walking {:.4}, {:.4} m/s",
                    v.x_m_s, v.y_m_s, l.x_m_s, l.y_m_s
                ))
            }
            Some(_) => None,
            None => {
                self.reported_limit = None;
                None
            }
        }
    }

    /// Called at every tick before the planner's update: ends a walk whose commands
    /// stopped coming. Returns a message for the log when it does.
    pub fn tick(&mut self, planner: &mut GaitPlanner, now_s: f64) -> Option<String> {
        let deadline = self.deadline_s?;
        if now_s <= deadline {
            return None;
        }
        self.deadline_s = None;
        if planner.is_idle() {
            return None;
        }
        planner.request(WalkRequest::Stop);
        Some(format!(
            "cmd_vel: no command for {} s (cmd_vel_timeout_s); ending the walk",
            planner.config().cmd_vel_timeout_s
        ))
    }

    /// Another command source took over the walk (a walk command): its walk does not time
    /// out.
    pub fn release(&mut self) {
        self.deadline_s = None;
    }
}
