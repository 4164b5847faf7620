//! Tick-by-tick checks of whole planned walks, with forward kinematics computed here from the
//! joint angles (not the planner's own fields): joint speeds within limits, feet never below
//! the floor, stance feet still, soles level, CoM margin kept. Then refusals.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::*;
use gait_planner::params::{hip_height_for, leg_length_m};
use gait_planner::{
    GaitError, GaitParams, GaitPlanner, GaitSample, PhaseKind, Support, WalkRequest,
};
use ik_solver::{BipedModel, Side};
use nalgebra::Point3;

struct Fk {
    ankles: [Point3<f64>; 2],
    foot_tilt_rad: [f64; 2],
    sole_bottom_z_m: [f64; 2],
}

fn fk(model: &BipedModel, s: &GaitSample) -> Fk {
    let robot = model.robot();
    let poses = robot.link_poses(&s.base_world, &s.joints_rad).unwrap();
    let ankles = Side::BOTH.map(|side| model.leg(side).ankle_world(robot, &poses));
    let foot_tilt_rad = Side::BOTH.map(|side| {
        let leg = model.leg(side);
        // Level means: as at zero angles with a level base, up to a turn about z.
        let r = poses[leg.foot_link].rotation * leg.foot_rotation0.inverse();
        let up = r * nalgebra::Vector3::z();
        up.angle(&nalgebra::Vector3::z())
    });
    let sole_bottom_z_m =
        Side::BOTH.map(|side| ankles[side.index()].z - model.leg(side).ankle_to_sole_m);
    Fk {
        ankles,
        foot_tilt_rad,
        sole_bottom_z_m,
    }
}

fn check_walk(model: &BipedModel, planner: &GaitPlanner, samples: &[GaitSample]) {
    let cfg = planner.config();
    let dt = cfg.dt_s();
    let robot = model.robot();
    let mut prev: Option<(&GaitSample, Fk)> = None;
    for s in samples {
        let f = fk(model, s);
        assert!(s.issues.is_empty(), "t = {}: {:?}", s.t_s, s.issues);
        for side in Side::BOTH {
            let k = side.index();
            assert!(
                f.sole_bottom_z_m[k] > -1e-12,
                "t = {}: {side} sole {} m below the floor",
                s.t_s,
                f.sole_bottom_z_m[k]
            );
            assert!(
                f.foot_tilt_rad[k] < 1e-9,
                "t = {}: {side} sole tilted {} rad",
                s.t_s,
                f.foot_tilt_rad[k]
            );
            // The planner's ankle positions are the ones forward kinematics gives.
            assert!(
                (f.ankles[k] - s.ankles_world_m[k]).norm() < 1e-9,
                "t = {}: {side} ankle off its plan",
                s.t_s
            );
        }
        // Whole-body CoM and its margin as the planner reports them.
        let poses = robot.link_poses(&s.base_world, &s.joints_rad).unwrap();
        assert!((robot.center_of_mass(&poses) - s.com_world_m).norm() < 1e-12);
        assert!(
            s.margin_m >= cfg.min_com_margin_m,
            "t = {} ({}): margin {} below {}",
            s.t_s,
            s.phase,
            s.margin_m,
            cfg.min_com_margin_m
        );
        if let Some((p, pf)) = &prev {
            for (d, (a, b)) in p.joints_rad.iter().zip(&s.joints_rad).enumerate() {
                let j = &robot.joints()[robot.dof_joints()[d]];
                let limit = j.limits.unwrap().velocity;
                assert!(
                    (b - a).abs() <= limit * dt,
                    "t = {}: joint {} moved {} rad in one tick",
                    s.t_s,
                    j.name,
                    (b - a).abs()
                );
            }
            // A foot that carried the robot over the last tick has not moved.
            for side in Side::BOTH {
                let carrying = |sup: Support| sup == Support::Double || sup == Support::on(side);
                if carrying(p.support) && carrying(s.support) {
                    let slid = (f.ankles[side.index()] - pf.ankles[side.index()]).norm();
                    assert!(
                        slid < 1e-9,
                        "t = {}: {side} stance foot slid {slid} m",
                        s.t_s
                    );
                }
            }
        }
        prev = Some((s, f));
    }
}

#[test]
fn default_walk_is_continuous_stable_and_feet_fixed() {
    let model = default_model();
    let mut planner = GaitPlanner::new(
        model.clone(),
        GaitParams {
            rise_at_end: true,
            ..GaitParams::default()
        },
    )
    .unwrap();
    let samples = planner.plan(WalkRequest::Steps(7)).unwrap();
    check_walk(&model, &planner, &samples);
    // The stance sole carries the CoM in single support: margin well above the minimum there.
    let single: Vec<&GaitSample> = samples
        .iter()
        .filter(|s| s.support != Support::Double)
        .collect();
    assert!(!single.is_empty());
    // The sideways shift was derived from the mass model: the CoM sits over the stance sole's
    // centre line (y = hip offset ± 0) throughout single support.
    for s in single {
        let stance = if s.support == Support::Left {
            Side::Left
        } else {
            Side::Right
        };
        let want_y = s.ankles_world_m[stance.index()].y;
        assert!(
            (s.com_world_m.y - want_y).abs() < 1e-9,
            "t = {}: CoM y {} not over the stance foot {}",
            s.t_s,
            s.com_world_m.y,
            want_y
        );
    }
}

#[test]
fn six_joint_robot_with_other_lengths_walks_with_derived_defaults() {
    let model = biped6_model();
    let mut planner = GaitPlanner::new(model.clone(), GaitParams::default())
        .expect("another robot gets a valid walk untuned");
    let samples = planner.plan(WalkRequest::Steps(4)).unwrap();
    check_walk(&model, &planner, &samples);
    // Its defaults scale with its legs (0.21 m vs the default robot's 0.18 m): the auto
    // step is 0.45 x leg, or lowered until the check walk passes (here to 0.0856 m: its
    // hip pitch's range).
    let step = planner.config().step_length_m;
    assert!(step > 0.35 * 0.21 && step <= 0.45 * 0.21 + 1e-12, "{step}");
}

#[test]
fn one_kilohertz_walk_is_as_smooth() {
    let model = default_model();
    let mut planner = GaitPlanner::new(
        model.clone(),
        GaitParams {
            control_rate_hz: 1000.0,
            ..slow()
        },
    )
    .unwrap();
    let samples = planner.plan(WalkRequest::Steps(2)).unwrap();
    // Crouch 1 s, shift 2 s, half step 1 s, shift 2 s, step 1 s, shift 2 s, final half
    // step 1 s, centring 2 s: 12 s at 1 kHz, both ends included.
    assert_eq!(samples.len(), 12001);
    check_walk(&model, &planner, &samples);
}

#[test]
fn margin_short_of_the_minimum_is_refused_naming_phase_and_shortfall() {
    // With the CoM over the stance sole's centre, the first shift (1 s to 3 s) ends 0.030 m (half the sole
    // width) from the support polygon's outer edge: a 0.032 m minimum cannot be kept.
    let err = GaitPlanner::new(
        default_model(),
        GaitParams {
            min_com_margin_m: 0.032,
            ..slow()
        },
    )
    .unwrap_err();
    match &err {
        GaitError::Unstable {
            phase,
            margin_m,
            min_m,
            t_s,
            ..
        } => {
            assert_eq!(*phase, PhaseKind::Shift);
            assert!(
                *t_s > 1.0 && *t_s <= 3.0,
                "during the first shift, t = {t_s}"
            );
            assert!(*margin_m < 0.032 && *margin_m > 0.030, "{margin_m}");
            assert_eq!(*min_m, 0.032);
        }
        other => panic!("wanted Unstable, got {other:?}"),
    }
    let msg = err.to_string();
    assert!(
        msg.contains("`shift`")
            && msg.contains("both feet on the floor")
            && msg.contains("below the minimum 0.0320 m"),
        "{msg}"
    );
}

#[test]
fn a_step_beyond_the_legs_reach_is_refused_naming_the_phase() {
    // Slow enough that no joint speed limit is hit first.
    let p = GaitParams {
        step_length_m: 0.1,
        step_duration_s: 10.0,
        shift_duration_s: 5.0,
        ..slow()
    };
    let err = GaitPlanner::new(default_model(), p).unwrap_err();
    match &err {
        GaitError::Unreachable { phase, issue, .. } => {
            assert_eq!(*phase, PhaseKind::HalfStep);
            assert!(
                issue.contains("left leg") && issue.contains("reach"),
                "{issue}"
            );
        }
        other => panic!("wanted Unreachable, got {other:?}"),
    }
}

#[test]
fn too_fast_a_step_is_refused_naming_the_joint() {
    let err = GaitPlanner::new(
        default_model(),
        GaitParams {
            step_duration_s: 0.1,
            step_length_m: 0.07,
            foot_lift_m: 0.03,
            ..slow()
        },
    )
    .unwrap_err();
    assert!(matches!(err, GaitError::TooFast { .. }), "{err:?}");
    assert!(err.to_string().contains("rad/s"), "{err}");
}

/// A forward step left at 0 (auto) that the check walk refuses is lowered until it passes,
/// like the other step limits: on hips raised to 0.94 x leg the default robot's knees would
/// straighten too fast for the auto step of 0.45 x leg (set by hand, that is refused, naming the
/// phase); the auto step is the largest passing one, to the bisection's 1/64 of the auto
/// value.
#[test]
fn an_auto_step_the_check_walk_refuses_is_lowered_until_it_passes() {
    let model = default_model();
    let leg = leg_length_m(&model);
    let high = GaitParams {
        hip_height_m: hip_height_for(&model, 0.94),
        step_length_m: 0.0,
        ..slow()
    };
    let auto = gait_planner::params::auto::STEP_LENGTH_PER_LEG * leg;
    let by_hand = |step_length_m: f64| {
        GaitPlanner::new(
            model.clone(),
            GaitParams {
                step_length_m,
                ..high.clone()
            },
        )
    };
    match by_hand(auto) {
        Err(e @ GaitError::TooFast { .. }) => assert!(e.phase().is_some(), "{e}"),
        other => panic!("wanted TooFast, got {other:?}"),
    }
    let mut planner = GaitPlanner::new(model.clone(), high.clone()).expect("auto step lowered");
    let step = planner.config().step_length_m;
    assert!(step < auto && step > 0.0, "{step} of {auto}");
    // The auto back step follows the lowered forward step.
    assert!(planner.config().back_step_length_m <= step);
    let samples = planner.plan(WalkRequest::Steps(4)).unwrap();
    check_walk(&model, &planner, &samples);
    assert!(by_hand(step).is_ok());
    assert!(by_hand(step + auto / 64.0).is_err());
}
