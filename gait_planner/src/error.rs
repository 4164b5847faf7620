//! Errors of the gait planner; each names the parameter, phase or value at fault.

use crate::phase::PhaseKind;

/// Why a gait could not be planned or a parameter file was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GaitError {
    /// A parameter value outside its bounds.
    #[error("gait parameter `{key}` = {value} is out of range: {why}")]
    Param {
        /// The parameter name.
        key: &'static str,
        /// The value given (or derived).
        value: f64,
        /// The bound, with units.
        why: String,
    },
    /// The parameter file does not parse or has unknown keys.
    #[error("gait parameter file{}: {message}", .path.as_ref().map(|p| format!(" {p}")).unwrap_or_default())]
    ParamFile {
        /// The file, when read from one.
        path: Option<String>,
        /// What is wrong (the YAML or serde message, naming the key).
        message: String,
    },
    /// The CoM leaves the support polygon (or comes closer to its edge than the minimum).
    #[error(
        "gait parameters refused: in phase `{phase}` ({detail}) at t = {t_s:.3} s the CoM margin is {margin_m:.4} m, below the minimum {min_m:.4} m by {:.4} m",
        min_m - margin_m
    )]
    Unstable {
        /// The phase.
        phase: PhaseKind,
        /// Which foot swings or what moves.
        detail: String,
        /// When, from the start of the check walk.
        t_s: f64,
        /// The margin found (m, negative outside).
        margin_m: f64,
        /// The configured minimum (m).
        min_m: f64,
    },
    /// The planned ZMP leaves the support polygon (or comes closer to its edge than the
    /// minimum): the CoM accelerates too hard for the feet under it.
    #[error(
        "gait parameters refused: in phase `{phase}` ({detail}) at t = {t_s:.3} s the ZMP margin is {margin_m:.4} m, below the minimum {min_m:.4} m by {:.4} m (the CoM accelerates at {accel_m_s2:.3} m/s²; a longer phase or a shorter step accelerates less)",
        min_m - margin_m
    )]
    ZmpOutside {
        /// The phase.
        phase: PhaseKind,
        /// Which foot swings or what moves.
        detail: String,
        /// When, from the start of the check walk.
        t_s: f64,
        /// The ZMP margin found (m, negative outside).
        margin_m: f64,
        /// The configured minimum (m).
        min_m: f64,
        /// The CoM's horizontal acceleration then (m/s²).
        accel_m_s2: f64,
    },
    /// A planned ankle position the legs cannot reach (or only beyond a joint limit).
    #[error("gait parameters refused: in phase `{phase}` at t = {t_s:.3} s: {issue}")]
    Unreachable {
        /// The phase.
        phase: PhaseKind,
        /// When, from the start of the check walk.
        t_s: f64,
        /// The IK's report.
        issue: String,
    },
    /// A joint would move faster than its URDF velocity limit.
    #[error(
        "gait parameters refused: in phase `{phase}` at t = {t_s:.3} s joint `{joint}` moves at {velocity_rad_s:.3} rad/s, above its limit {limit_rad_s:.3} rad/s"
    )]
    TooFast {
        /// The phase.
        phase: PhaseKind,
        /// When, from the start of the check walk.
        t_s: f64,
        /// The joint.
        joint: String,
        /// Its speed.
        velocity_rad_s: f64,
        /// Its limit.
        limit_rad_s: f64,
    },
    /// The time given to `update` is not finite or went backwards.
    #[error("planner time {t_s} s is not finite or is before the previous update {previous_s} s")]
    Time {
        /// The time given.
        t_s: f64,
        /// The previous time.
        previous_s: f64,
    },
    /// The soles would overlap (collide or cross) at some tick of the check walk.
    #[error("gait parameters refused: in phase `{phase}` at t = {t_s:.3} s the soles overlap")]
    SolesOverlap {
        /// The phase.
        phase: PhaseKind,
        /// When, from the start of the check walk.
        t_s: f64,
    },
    /// A step limit set by hand whose check walk fails.
    #[error(
        "gait parameter `{key}` = {value_m} m refused: the check walk at that step fails: {cause}"
    )]
    StepLimit {
        /// The parameter.
        key: &'static str,
        /// Its value (m).
        value_m: f64,
        /// Why the check walk failed (in the message too).
        cause: Box<GaitError>,
    },
    /// Pausing at some tick with the brake time given would move the ZMP closer to the
    /// support polygon's edge than the minimum ([`crate::pause`]).
    #[error(
        "gait parameter `pause_brake_time_s` = {brake_s} s refused: {} at t = {t_s:.3} s in phase `{phase}` moves the ZMP closer than `min_zmp_margin_m`; it needs at least {needed_s:.3} s (0 = auto)",
        if *.resuming { "speeding up again" } else { "a pause braking" }
    )]
    PauseBrake {
        /// The brake time given (s).
        brake_s: f64,
        /// The shortest that keeps the margin (s; infinite for none).
        needed_s: f64,
        /// The phase of the tick that needs it.
        phase: PhaseKind,
        /// When, from the start of the check walk.
        t_s: f64,
        /// Speeding up (resume) rather than braking.
        resuming: bool,
    },
    /// A walk request with a bad value.
    #[error("walk request refused: {0}")]
    Request(String),
}

impl GaitError {
    /// The phase of the check walk that failed, for refusals that have one.
    pub fn phase(&self) -> Option<PhaseKind> {
        match self {
            Self::Unstable { phase, .. }
            | Self::ZmpOutside { phase, .. }
            | Self::Unreachable { phase, .. }
            | Self::TooFast { phase, .. }
            | Self::SolesOverlap { phase, .. }
            | Self::PauseBrake { phase, .. } => Some(*phase),
            Self::StepLimit { cause, .. } => cause.phase(),
            Self::Param { .. } | Self::ParamFile { .. } | Self::Time { .. } | Self::Request(_) => {
                None
            }
        }
    }
}
