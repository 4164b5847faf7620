//! Shared helpers of the gait_planner tests.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
#![allow(dead_code)]

use gait_planner::{GaitParams, GaitPlanner, GaitSample, PhaseKind, WalkRequest};
use ik_solver::{BipedModel, Side};

pub fn default_model() -> BipedModel {
    BipedModel::from_urdf_str(ik_solver::DEFAULT_URDF, None).expect("default robot")
}

pub fn biped6_model() -> BipedModel {
    BipedModel::from_urdf_str(include_str!("../../tests/data/biped6_renamed.urdf"), None)
        .expect("test biped")
}

pub fn planner(params: GaitParams) -> GaitPlanner {
    GaitPlanner::new(default_model(), params).expect("default parameters are accepted")
}

pub fn plan(steps: u32, params: GaitParams) -> Vec<GaitSample> {
    planner(params)
        .plan(WalkRequest::Steps(steps))
        .expect("plan")
}

/// Phases in order, consecutive repeats merged, with the swinging foot (L/R) on swings.
pub fn sequence(samples: &[GaitSample]) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    let mut last = None;
    for s in samples {
        let key = (s.phase, s.step_index);
        if last != Some(key) {
            let name = match (s.phase.is_swing(), s.support) {
                (true, gait_planner::Support::Left) => format!("{}(R)", s.phase),
                (true, gait_planner::Support::Right) => format!("{}(L)", s.phase),
                _ => s.phase.to_string(),
            };
            out.push(name);
            last = Some(key);
        }
    }
    out
}

/// Hand-written expected sequence: `steps` swings starting with `first`.
pub fn expected(steps: u32, first: Side) -> Vec<String> {
    let f = |s: Side| if s == Side::Left { "L" } else { "R" };
    let mut v = vec![
        "crouch".to_string(),
        "shift".to_string(),
        format!("half_step({})", f(first)),
    ];
    let mut swing = first;
    for _ in 1..steps {
        swing = swing.other();
        v.push("shift".into());
        v.push(format!("step({})", f(swing)));
    }
    v.push("shift".into());
    v.push(format!("final_half_step({})", f(swing.other())));
    v.push("center".into());
    v
}

pub fn phase_ticks(samples: &[GaitSample], kind: PhaseKind) -> usize {
    samples.iter().filter(|s| s.phase == kind).count()
}

/// The slow walk the hand-computed tests are written against (the defaults before #16):
/// [`GaitParams::slow`] of the default robot.
pub fn slow() -> GaitParams {
    GaitParams::slow(&default_model())
}
