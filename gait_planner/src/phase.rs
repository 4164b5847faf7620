//! The phases of the walk (paper section III.C) and who carries the robot in each.

use std::fmt;

use ik_solver::{Side, Stance};
use serde::Serialize;

/// A phase of the walk, as written in the plan CSV and on `/gait/phase`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PhaseKind {
    /// Not walking: holding the last pose.
    Idle,
    /// Bending the knees from standing to the walking hip height.
    Crouch,
    /// Moving the CoM in double support: onto the stance foot before a swing (sideways, or
    /// diagonally onto the front foot), so the other foot can lift.
    Shift,
    /// The first swing: the foot advances one step length from level with the other.
    HalfStep,
    /// A full swing: the foot travels two step lengths, from behind the other to ahead of it.
    Step,
    /// The last swing: the trailing foot comes level with the other.
    FinalHalfStep,
    /// Moving the CoM back to the middle between the feet.
    Center,
    /// Straightening the legs back to standing (optional).
    Rise,
}

impl std::str::FromStr for PhaseKind {
    type Err = String;
    /// Parses the snake_case name (as `gait/phase` carries it).
    fn from_str(s: &str) -> Result<Self, String> {
        PhaseKind::ALL
            .into_iter()
            .find(|k| k.as_str() == s)
            .ok_or_else(|| format!("`{s}` is not a gait phase"))
    }
}

impl PhaseKind {
    /// Every phase kind, in walk order.
    pub const ALL: [PhaseKind; 8] = [
        PhaseKind::Idle,
        PhaseKind::Crouch,
        PhaseKind::Shift,
        PhaseKind::HalfStep,
        PhaseKind::Step,
        PhaseKind::FinalHalfStep,
        PhaseKind::Center,
        PhaseKind::Rise,
    ];

    /// snake_case name.
    pub fn as_str(self) -> &'static str {
        match self {
            PhaseKind::Idle => "idle",
            PhaseKind::Crouch => "crouch",
            PhaseKind::Shift => "shift",
            PhaseKind::HalfStep => "half_step",
            PhaseKind::Step => "step",
            PhaseKind::FinalHalfStep => "final_half_step",
            PhaseKind::Center => "center",
            PhaseKind::Rise => "rise",
        }
    }
    /// True for the phases where one foot is in the air.
    pub fn is_swing(self) -> bool {
        matches!(
            self,
            PhaseKind::HalfStep | PhaseKind::Step | PhaseKind::FinalHalfStep
        )
    }
}

impl fmt::Display for PhaseKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Which feet carry the robot.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Support {
    /// Both feet on the floor.
    Double,
    /// Only the left foot.
    Left,
    /// Only the right foot.
    Right,
}

impl Support {
    /// Single support on `side`.
    pub fn on(side: Side) -> Self {
        match side {
            Side::Left => Support::Left,
            Side::Right => Support::Right,
        }
    }
    /// The same support as ik_solver's statics name it.
    pub fn stance(self) -> Stance {
        match self {
            Support::Double => Stance::Double,
            Support::Left => Stance::Single(Side::Left),
            Support::Right => Stance::Single(Side::Right),
        }
    }
    /// "double", "left" or "right".
    pub fn as_str(self) -> &'static str {
        match self {
            Support::Double => "double",
            Support::Left => "left",
            Support::Right => "right",
        }
    }
}

impl fmt::Display for Support {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// What the walk is asked to do. Taken at the next phase boundary.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum WalkRequest {
    /// Take this many steps (swings before the closing half step), then stop with the feet
    /// together. Given during a walk, counts from the next swing.
    Steps(u32),
    /// Walk until [`WalkRequest::Stop`].
    UntilStop,
    /// Finish at the next point where the feet can come together: the swing in the air
    /// lands, the CoM shifts onto the front foot, the trailing foot comes level.
    Stop,
}
