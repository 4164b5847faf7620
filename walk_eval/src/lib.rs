//! Where walks are judged: a gait_planner plan played open-loop into the sim_bridge simulator,
//! and the measures of a walk, from the simulator itself or from what a simulated fleet
//! published.
//!
//! Data flow: plan ([`gait_planner::GaitSample`]s) → [`Playback`] (servo targets per sample,
//! with the sag compensation of [`sim_bridge::compensated_targets_rad`], held or
//! interpolated) → [`run_plan`] (reset, settle, play, hold) → [`Observation`]s, one per
//! physics step → [`WalkMonitor`] → [`WalkReport`]: fall, tilt, heading, distance, foot
//! slip, centre of pressure against the support polygon per phase (what `biped walk` writes
//! to `report.json`).
//!
//! The layer above both the planner and the physics: `sim_bridge` knows poses, not plans;
//! `gait_planner` knows plans, not physics. Pure library: physics time only advances when
//! asked, no files, no middleware.

mod walk;

pub use walk::{
    FallReport, Interpolation, Observation, PhaseMargin, PlayOptions, Playback, STANCE_FRACTION,
    WalkMonitor, WalkReport, along_heading, heading_change_rad, heading_rad, run_plan,
};
