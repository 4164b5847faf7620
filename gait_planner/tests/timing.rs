//! The fastest timing: accepted by the planner's own checks, pausing anywhere within the
//! brake budget, and tight: a tenth shorter on any duration that a limit binds is refused,
//! by that limit.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::*;
use gait_planner::timing::{
    Bound, PAUSE_BRAKE_BUDGET_S, fastest_timing, fastest_timing_with_brake,
};
use gait_planner::{GaitError, GaitParams, GaitPlanner};

fn shorter(params: &GaitParams, slot: usize, factor: f64) -> GaitParams {
    let mut p = params.clone();
    match slot {
        0 => p.shift_duration_s *= factor,
        1 => p.step_duration_s *= factor,
        _ => p.crouch_duration_s *= factor,
    }
    p
}

fn check_tight(model: ik_solver::BipedModel) {
    let f = fastest_timing(&model, &GaitParams::slow(&model)).unwrap();
    eprintln!("{f:?}");
    let t = f.timing;
    let fastest = f.params.clone();
    assert_eq!(
        (
            fastest.shift_duration_s,
            fastest.step_duration_s,
            fastest.crouch_duration_s
        ),
        (t.shift_duration_s, t.step_duration_s, t.crouch_duration_s)
    );
    // The step limits are those of the default walk, not lowered to buy speed.
    let reference = GaitPlanner::new(model.clone(), GaitParams::slow(&model)).unwrap();
    let walk = GaitPlanner::new(model.clone(), fastest.clone()).expect("the fastest timing passes");
    let (a, b) = (reference.config(), walk.config());
    assert_eq!(
        (a.back_step_length_m, a.side_step_m, a.turn_step_rad),
        (b.back_step_length_m, b.side_step_m, b.turn_step_rad)
    );
    // Faster than the defaults (2 s shifts, 1 s steps) by far.
    assert!(t.shift_duration_s < 1.5 && t.step_duration_s < 1.0, "{t:?}");
    // Its pauses come to rest within the budget (the auto brake, in whole ticks).
    let brake_s = walk.config().pause_brake_time_s;
    assert!(
        brake_s > 0.0 && brake_s <= PAUSE_BRAKE_BUDGET_S + 1e-9,
        "brake {brake_s} s"
    );
    // Without the budget it is as fast or faster, never slower.
    let free = fastest_timing_with_brake(&model, &GaitParams::slow(&model), None)
        .unwrap()
        .timing;
    assert!(
        free.shift_duration_s <= t.shift_duration_s && free.step_duration_s <= t.step_duration_s,
        "{free:?} vs {t:?}"
    );
    // Tightness, with the budget held (the auto brake would lengthen instead).
    let budgeted = GaitParams {
        pause_brake_time_s: PAUSE_BRAKE_BUDGET_S,
        ..fastest.clone()
    };
    for (slot, bound) in f.bound.iter().enumerate() {
        if *bound == Bound::Floor {
            continue;
        }
        // A pause bound lies just above the plain ZMP bound (braking adds to the planned
        // acceleration): a tenth shorter would fail the ZMP check first; a twentieth.
        let factor = if *bound == Bound::Pause { 0.95 } else { 0.9 };
        let Err(err) = GaitPlanner::new(model.clone(), shorter(&budgeted, slot, factor)) else {
            panic!("slot {slot} ({bound:?}) a tenth faster is accepted: {f:?}");
        };
        let by = match &err {
            GaitError::TooFast { .. } => "speed",
            GaitError::ZmpOutside { .. } => "zmp",
            GaitError::PauseBrake { .. } => "pause",
            GaitError::StepLimit { cause, .. } => match **cause {
                GaitError::TooFast { .. } => "speed",
                GaitError::ZmpOutside { .. } => "zmp",
                _ => "other",
            },
            _ => "other",
        };
        match bound {
            Bound::JointSpeed => assert_eq!(by, "speed", "slot {slot}: {err}"),
            Bound::Zmp => assert_eq!(by, "zmp", "slot {slot}: {err}"),
            Bound::Pause => assert_eq!(by, "pause", "slot {slot}: {err}"),
            _ => assert!(by != "other", "slot {slot}: {err}"),
        }
    }
}

#[test]
fn the_default_robot_s_fastest_timing_passes_and_is_tight() {
    check_tight(default_model());
}

#[test]
fn the_six_joint_robot_s_fastest_timing_passes_and_is_tight() {
    check_tight(biped6_model());
}

/// Durations that the robot cannot walk at all as a reference are refused as they are.
#[test]
fn a_reference_walk_that_fails_its_checks_is_refused() {
    let err = fastest_timing(
        &default_model(),
        &GaitParams {
            shift_duration_s: 0.3,
            ..slow()
        },
    )
    .unwrap_err();
    assert!(matches!(err, GaitError::ZmpOutside { .. }), "{err}");
}

/// With the simulator's servo model (config/sim.yaml: damping 0.25 N·m·s/rad, rotor 0.005
/// kg·m²) the 1.5 N·m servos of the default robot bound the timing before the joint speed
/// limits do: slower than without a servo model, by the torque, and still accepted.
#[test]
fn a_servo_model_bounds_the_timing_by_torque() {
    let model = default_model();
    let free = fastest_timing(&model, &slow()).unwrap();
    let servo = GaitParams {
        servo_damping_nm_s_per_rad: 0.25,
        servo_armature_kg_m2: 0.005,
        ..slow()
    };
    let budget = fastest_timing(&model, &servo).unwrap();
    eprintln!("{free:?}\n{budget:?}");
    assert!(budget.bound.contains(&Bound::Torque), "{budget:?}");
    let (a, b) = (free.timing, budget.timing);
    assert!(b.step_duration_s >= a.step_duration_s, "{a:?} {b:?}");
    assert!(
        b.step_duration_s + b.shift_duration_s > a.step_duration_s + a.shift_duration_s,
        "{a:?} {b:?}"
    );
    GaitPlanner::new(model, budget.params).expect("accepted");
}

fn auto_durations() -> GaitParams {
    auto_durations_of(&default_model())
}

/// The slow walk of `model` with every duration left at 0 (auto).
fn auto_durations_of(model: &ik_solver::BipedModel) -> GaitParams {
    GaitParams {
        shift_duration_s: 0.0,
        step_duration_s: 0.0,
        crouch_duration_s: 0.0,
        ..GaitParams::slow(model)
    }
}

fn durations(p: &GaitParams) -> (f64, f64, f64) {
    (p.shift_duration_s, p.step_duration_s, p.crouch_duration_s)
}

/// Durations left at 0 are the fastest timing of the same walk at the reference durations
/// (2 s / 1 s / 1 s, the defaults): what `biped plan --fastest` prints, now used by the
/// planner itself, with the step limits of the slow walk kept.
#[test]
fn durations_left_at_auto_are_the_fastest_timing() {
    for model in [default_model(), biped6_model()] {
        let planner = GaitPlanner::new(model.clone(), auto_durations_of(&model)).unwrap();
        let fastest = fastest_timing(&model, &GaitParams::slow(&model)).unwrap();
        let c = planner.config();
        assert_eq!(durations(c), durations(&fastest.params));
        assert!(c.shift_duration_s < 2.0 && c.step_duration_s < 1.0, "{c:?}");
        assert_eq!(planner.auto_timing(), Some(&fastest));
        let slow = GaitPlanner::new(model.clone(), GaitParams::slow(&model)).unwrap();
        let s = slow.config();
        assert_eq!(
            (c.back_step_length_m, c.side_step_m, c.turn_step_rad),
            (s.back_step_length_m, s.side_step_m, s.turn_step_rad)
        );
        assert!(slow.auto_timing().is_none());
        // `resolve` (what `biped check-robot` prints) gives the same durations.
        let resolved = auto_durations_of(&model).resolve(&model).unwrap();
        assert_eq!(durations(&resolved), durations(c));
    }
}

/// A duration set by hand stays as set beside auto ones, is the reference the others are
/// scaled with, and is checked: too short, the planner refuses it by its phase.
#[test]
fn a_duration_set_by_hand_beside_auto_ones_stays_and_is_checked() {
    let model = default_model();
    let shift_by_hand = GaitParams {
        shift_duration_s: 1.5,
        ..auto_durations()
    };
    let planner = GaitPlanner::new(model.clone(), shift_by_hand.clone()).unwrap();
    let c = planner.config();
    assert_eq!(c.shift_duration_s, 1.5);
    let all_auto = GaitPlanner::new(model.clone(), auto_durations()).unwrap();
    assert_eq!(
        (c.step_duration_s, c.crouch_duration_s),
        (
            all_auto.config().step_duration_s,
            all_auto.config().crouch_duration_s
        )
    );
    // 0.3 s shifts fail the ZMP margin as a reference walk (as above): refused, saying the
    // durations were auto, and naming what failed.
    let err = GaitPlanner::new(
        model.clone(),
        GaitParams {
            shift_duration_s: 0.3,
            ..auto_durations()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("durations left at 0 (auto)") && err.contains("ZMP margin"),
        "{err}"
    );
    // Between walks: the same parameters again, and back to fixed durations.
    let mut planner = planner;
    planner.set_params(shift_by_hand).unwrap();
    assert_eq!(planner.config().shift_duration_s, 1.5);
    planner.set_params(slow()).unwrap();
    assert_eq!(durations(planner.config()), (2.0, 1.0, 1.0));
    assert!(planner.auto_timing().is_none());
}

/// The fastest walk: every step length and hip height of the grid tried (15), the winner
/// the fastest of those the planner accepted, faster than the auto step length's fastest
/// timing, accepted itself; a step length set by hand is the only one tried.
#[test]
fn the_fastest_walk_is_the_fastest_accepted_trial() {
    use gait_planner::timing::{
        WALK_HIP_DROP_PER_LEG, WALK_STEP_BISECTIONS, WALK_STEP_PER_LEG, fastest_walk,
    };
    let model = default_model();
    let lengths_auto = GaitParams {
        step_length_m: 0.0,
        hip_height_m: 0.0,
        ..auto_durations()
    };
    let w = fastest_walk(&model, &lengths_auto).unwrap();
    let grid = WALK_STEP_PER_LEG.len() * WALK_HIP_DROP_PER_LEG.len();
    let n = w.trials.len();
    assert!(
        (grid..=grid + WALK_STEP_BISECTIONS as usize).contains(&n),
        "{n}"
    );
    // Lengths in whole millimetres, as a parameter file would say them.
    for t in &w.trials {
        for v in [t.step_length_m, t.hip_height_m] {
            assert!(((v * 1000.0).round() - v * 1000.0).abs() < 1e-9, "{v}");
        }
    }
    let accepted: Vec<f64> = w
        .trials
        .iter()
        .filter_map(|t| t.outcome.as_ref().ok().map(|(v, _)| *v))
        .collect();
    assert!(
        accepted.len() >= 2 && accepted.len() < w.trials.len(),
        "{w:?}"
    );
    let top = accepted.iter().cloned().fold(0.0, f64::max);
    assert_eq!(w.speed_m_s, top);
    // The default robot's leg is 0.18 m: the slow walk steps 0.045 m on 0.183 m hips.
    let plain = GaitPlanner::new(model.clone(), auto_durations()).unwrap();
    let c = plain.config();
    assert!((c.step_length_m - 0.045).abs() < 1e-12, "{c:?}");
    assert!(
        w.speed_m_s > 1.2 * c.step_length_m / c.step_period_s(),
        "{} vs {}",
        w.speed_m_s,
        c.step_length_m / c.step_period_s()
    );
    let p = &w.params;
    let walk = GaitPlanner::new(model.clone(), p.clone()).expect("the winner is accepted");
    assert_eq!(walk.config().step_length_m, p.step_length_m);
    assert!((p.step_length_m / (p.shift_duration_s + p.step_duration_s) - top).abs() < 1e-12);
    // The refused ones say why.
    assert!(
        w.trials
            .iter()
            .filter_map(|t| t.outcome.as_ref().err())
            .all(|e| e.contains("refused")),
        "{w:?}"
    );
    // Step length set: only the hip heights are searched.
    let set = fastest_walk(
        &model,
        &GaitParams {
            step_length_m: 0.05,
            ..lengths_auto
        },
    )
    .unwrap();
    assert_eq!(set.trials.len(), WALK_HIP_DROP_PER_LEG.len());
    assert!(set.trials.iter().all(|t| t.step_length_m == 0.05));
}
