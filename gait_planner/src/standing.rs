//! A planner that starts while the robot is not standing (restarted mid-walk): it must not
//! command the pose it would stand in, which may be far from where the legs are, but hold
//! the measured pose until the robot stands as the planner's idle pose has it.
//!
//! [`StandGuard`] decides from measured joint states; [`targets_holding`] gives the ankle
//! targets that keep a measured pose (forward kinematics of the legs, so the IK gives the
//! measured leg angles back).

use ik_solver::{AnkleTarget, BipedModel, IkError, JointRole, Side};

/// How far (rad) a leg joint may be from the planner's idle pose for the robot to count as
/// standing in it.
pub const STANDING_TOLERANCE_RAD: f64 = 0.05;

/// The ankle targets that hold the leg pose of the joint vector `q` (dof order): each ankle
/// point relative to its hip point, by forward kinematics, and each foot's yaw from its hip
/// yaw joint.
pub fn targets_holding(model: &BipedModel, q: &[f64]) -> Result<[AnkleTarget; 2], IkError> {
    let ankles = model.ankles_in_hips(q)?;
    Ok(Side::BOTH.map(|s| {
        let leg = model.leg(s);
        let foot_yaw_rad = leg
            .joint(JointRole::HipYaw)
            .map_or(0.0, |j| j.axis_sign * q.get(j.dof).copied().unwrap_or(0.0));
        AnkleTarget {
            ankle_in_hip_m: ankles[s.index()],
            foot_yaw_rad,
        }
    }))
}

/// Whether the measured robot stands in the planner's idle pose.
#[derive(Debug, Clone, PartialEq)]
pub enum Standing {
    /// No complete measured joint state yet.
    Unknown,
    /// It stands as the planner's idle pose has it: the planner may command it.
    Yes,
    /// It does not: the leg joint farthest from the idle pose, and how far (rad).
    No {
        /// URDF name of the joint.
        joint: String,
        /// Its distance from the idle pose (rad).
        off_rad: f64,
    },
}

/// Holds a restarted planner back until the robot stands in its idle pose.
#[derive(Debug, Clone)]
pub struct StandGuard {
    tolerance_rad: f64,
    state: Standing,
    held: Option<[AnkleTarget; 2]>,
}

impl StandGuard {
    /// A guard with a tolerance per leg joint (rad).
    pub fn new(tolerance_rad: f64) -> Self {
        Self {
            tolerance_rad,
            state: Standing::Unknown,
            held: None,
        }
    }

    /// What it knows.
    pub fn state(&self) -> &Standing {
        &self.state
    }

    /// True once the robot was seen standing in the idle pose: from then on the planner
    /// commands it as usual.
    pub fn clear(&self) -> bool {
        self.state == Standing::Yes
    }

    /// The targets that hold the first measured pose, while the robot does not stand;
    /// `None` before a measured pose (publish nothing) or once clear.
    pub fn held_targets(&self) -> Option<&[AnkleTarget; 2]> {
        self.held.as_ref()
    }

    /// A measured joint state (`names`, `positions`) against the planner's idle joint
    /// vector `idle_q` (dof order). Leg joints only: the arms do not carry the robot.
    /// Ignored until clear is decided if a leg joint is missing or not finite. Returns a
    /// sentence when the verdict changes.
    pub fn measured(
        &mut self,
        model: &BipedModel,
        idle_q: &[f64],
        names: &[String],
        positions: &[f64],
    ) -> Option<String> {
        if self.clear() || names.len() != positions.len() {
            return None;
        }
        let mut q = idle_q.to_vec();
        let mut worst: Option<(&str, f64)> = None;
        for side in Side::BOTH {
            for (_, joint) in model.leg(side).present() {
                let v = names
                    .iter()
                    .position(|n| *n == joint.name)
                    .map(|i| positions[i])?;
                if !v.is_finite() {
                    return None;
                }
                let off = (v - idle_q.get(joint.dof).copied().unwrap_or(0.0)).abs();
                if worst.is_none_or(|(_, w)| off > w) {
                    worst = Some((joint.name.as_str(), off));
                }
                if let Some(slot) = q.get_mut(joint.dof) {
                    *slot = v;
                }
            }
        }
        let (joint, off_rad) = worst?;
        if off_rad <= self.tolerance_rad {
            self.state = Standing::Yes;
            self.held = None;
            return Some(
                "the robot stands in the planner's standing pose: walk commands taken".into(),
            );
        }
        let first = self.state == Standing::Unknown;
        self.state = Standing::No {
            joint: joint.to_string(),
            off_rad,
        };
        if self.held.is_none() {
            self.held = targets_holding(model, &q).ok();
        }
        first.then(|| {
            format!(
                "the robot is not in the planner's standing pose ({joint} is {off_rad:.3} rad from it; restarted mid-walk?): holding the measured pose, walk commands refused until it stands"
            )
        })
    }

    /// Why a walk command is refused now, if it is.
    pub fn refusal(&self) -> Option<String> {
        match &self.state {
            Standing::Yes => None,
            Standing::Unknown => Some(
                "no measured joint_states yet: the planner does not know the robot's pose".into(),
            ),
            Standing::No { joint, off_rad } => Some(format!(
                "the robot is not in the planner's standing pose ({joint} is {off_rad:.3} rad from it): it holds where it is; restart the fleet to stand it up from there"
            )),
        }
    }
}
