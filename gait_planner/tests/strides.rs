//! Walking in other directions than straight ahead: backward and side steps as footsteps,
//! velocity commands turned into strides within the limits, and random stride sequences
//! whose soles never come closer than they stand and whose CoM keeps its margin.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::*;
use gait_planner::{
    GaitError, GaitParams, GaitPlanner, GaitSample, PhaseKind, Stride, Velocity, WalkRequest,
};
use ik_solver::Side;
use nalgebra::Point3;
use proptest::prelude::*;

fn params(side_m: f64, back_m: f64) -> GaitParams {
    GaitParams {
        side_step_m: side_m,
        back_step_length_m: back_m,
        ..slow()
    }
}

/// Plans `steps` swings of one stride and returns the samples.
fn walk(p: GaitParams, stride: Stride, steps: u32) -> Vec<GaitSample> {
    let mut planner = planner(p);
    planner.set_stride(stride).unwrap();
    planner.plan(WalkRequest::Steps(steps)).unwrap()
}

/// The ankle positions where each swing landed, in order, with the foot that swung.
fn landings(samples: &[GaitSample]) -> Vec<(Side, Point3<f64>)> {
    let mut out = Vec::new();
    for w in samples.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        if a.phase.is_swing() && !b.phase.is_swing() {
            let swing = match a.support {
                gait_planner::Support::Left => Side::Right,
                _ => Side::Left,
            };
            out.push((swing, a.ankles_world_m[swing.index()]));
        }
    }
    out
}

fn close(a: &Point3<f64>, x: f64, y: f64) -> bool {
    (a.x - x).abs() < 1e-12 && (a.y - y).abs() < 1e-12
}

#[test]
fn a_side_step_left_opens_the_left_foot_then_closes_the_right() {
    // 15 mm per step: the left foot opens by 30 mm, the right closes to the standing width.
    let samples = walk(
        params(0.015, 0.0),
        Stride {
            left_m: 0.015,
            ..Stride::default()
        },
        2,
    );
    let [l0, r0] = samples[0].ankles_world_m;
    let land = landings(&samples);
    assert_eq!(
        land.iter().map(|(s, _)| *s).collect::<Vec<_>>(),
        [Side::Left, Side::Right, Side::Left],
        "the foot on the side of travel swings first"
    );
    assert!(close(&land[0].1, l0.x, l0.y + 0.03), "{:?}", land[0]);
    assert!(close(&land[1].1, r0.x, r0.y + 0.03), "{:?}", land[1]);
    // The closing half step brings the feet together at the standing width: moved 2 x 15 mm.
    assert!(close(&land[2].1, l0.x, l0.y + 0.03), "{:?}", land[2]);
    let end = samples.last().unwrap();
    assert!(close(&end.ankles_world_m[0], l0.x, l0.y + 0.03));
    assert!(close(&end.ankles_world_m[1], r0.x, r0.y + 0.03));
    // The pelvis ends centred over the feet again, 30 mm to the left.
    let (b0, b1) = (
        samples[0].base_world.translation,
        end.base_world.translation,
    );
    assert!(((b1.y - b0.y) - 0.03).abs() < 1e-4, "{} -> {}", b0.y, b1.y);
}

#[test]
fn a_side_step_right_starts_with_the_right_foot_whatever_the_first_foot() {
    let p = GaitParams {
        first_foot: Side::Left,
        ..params(0.015, 0.0)
    };
    let samples = walk(
        p,
        Stride {
            left_m: -0.015,
            ..Stride::default()
        },
        3,
    );
    let [l0, r0] = samples[0].ankles_world_m;
    let land = landings(&samples);
    let feet: Vec<Side> = land.iter().map(|(s, _)| *s).collect();
    assert_eq!(feet, [Side::Right, Side::Left, Side::Right, Side::Left]);
    assert!(close(&land[0].1, r0.x, r0.y - 0.03));
    assert!(close(&land[1].1, l0.x, l0.y - 0.03));
    assert!(close(&land[2].1, r0.x, r0.y - 0.06));
    assert!(close(&land[3].1, l0.x, l0.y - 0.06));
}

#[test]
fn a_backward_walk_lands_each_foot_behind_the_other() {
    let samples = walk(params(0.0, 0.03), Stride::forward(-0.03), 3);
    let [l0, r0] = samples[0].ankles_world_m;
    let land = landings(&samples);
    assert!(close(&land[0].1, -0.03, l0.y));
    assert!(close(&land[1].1, -0.06, r0.y));
    assert!(close(&land[2].1, -0.09, l0.y));
    assert!(close(&land[3].1, -0.09, r0.y), "feet together at the end");
    assert_eq!(sequence(&samples), expected(3, Side::Left));
}

#[test]
fn velocities_become_strides_within_the_limits() {
    let planner = planner(params(0.015, 0.03));
    let c = planner.config().clone();
    // Default timing: a 2 s shift and a 1 s swing per step.
    assert_eq!(c.step_period_s(), 3.0);
    let s = |x, y| {
        c.stride_for(
            Velocity {
                x_m_s: x,
                y_m_s: y,
                yaw_rad_s: 0.0,
            },
            false,
        )
        .unwrap()
    };
    // Within the limits: velocity x period.
    let a = s(0.005, -0.002);
    assert!((a.stride.forward_m - 0.015).abs() < 1e-15);
    assert!((a.stride.left_m + 0.006).abs() < 1e-15);
    assert_eq!(a.limited_to, None);
    // Backward, beyond the 30 mm back step: scaled to it.
    let b = s(-0.1, 0.0);
    assert!((b.stride.forward_m + 0.03).abs() < 1e-15);
    assert!((b.limited_to.unwrap().x_m_s + 0.01).abs() < 1e-15);
    // Forward and sideways both at their limit: onto the ellipse, direction kept.
    let step = c.step_length_m;
    let d = s(step / 3.0, 0.015 / 3.0);
    let k = std::f64::consts::FRAC_1_SQRT_2;
    assert!((d.stride.forward_m - step * k).abs() < 1e-15);
    assert!((d.stride.left_m - 0.015 * k).abs() < 1e-15);
    // A robot whose back step is 0 does not walk backward at all.
    let mut c0 = c.clone();
    c0.back_step_length_m = 0.0;
    let e = c0
        .stride_for(
            Velocity {
                x_m_s: -0.01,
                y_m_s: 0.001,
                yaw_rad_s: 0.0,
            },
            false,
        )
        .unwrap();
    assert_eq!(e.stride.forward_m, 0.0);
    assert!((e.stride.left_m - 0.003).abs() < 1e-15);
}

#[test]
fn a_nan_or_a_turn_is_refused_by_name() {
    let planner = planner(slow());
    let c = planner.config();
    let nan = c
        .stride_for(
            Velocity {
                x_m_s: 0.01,
                y_m_s: f64::NAN,
                yaw_rad_s: 0.0,
            },
            false,
        )
        .unwrap_err()
        .to_string();
    assert!(nan.contains("linear.y = NaN"), "{nan}");
    let turn = c
        .stride_for(
            Velocity {
                x_m_s: 0.0,
                y_m_s: 0.0,
                yaw_rad_s: 0.2,
            },
            false,
        )
        .unwrap_err()
        .to_string();
    assert!(
        turn.contains("angular.z = 0.2") && turn.contains("no hip yaw"),
        "{turn}"
    );
}

#[test]
fn a_stride_beyond_the_limits_is_refused_and_the_walk_keeps_its_stride() {
    let mut planner = planner(params(0.015, 0.03));
    let before = planner.stride();
    let e = planner
        .set_stride(Stride {
            left_m: 0.05,
            ..Stride::default()
        })
        .unwrap_err()
        .to_string();
    assert!(e.contains("left_m = 0.05"), "{e}");
    let e = planner.set_stride(Stride::forward(-0.04)).unwrap_err();
    assert!(e.to_string().contains("forward_m = -0.04"), "{e}");
    assert_eq!(planner.stride(), before);
}

#[test]
fn a_side_step_set_by_hand_beyond_reach_is_refused_naming_it() {
    // 0.3 x leg sideways per step: the foot would open by 0.6 x leg.
    let e = GaitPlanner::new(default_model(), params(0.3 * 0.18, 0.0)).unwrap_err();
    match &e {
        GaitError::StepLimit { key, .. } => assert_eq!(*key, "side_step_m"),
        other => panic!("{other}"),
    }
    assert!(e.to_string().contains("side_step_m"), "{e}");
}

#[test]
fn the_auto_limits_of_the_default_robot_pass_their_check_walks() {
    let c = planner(slow()).config().clone();
    // Leg 0.18 m: 0.1 x leg sideways, the forward step backward; both pass as derived.
    assert!((c.side_step_m - 0.018).abs() < 1e-12, "{}", c.side_step_m);
    assert!((c.back_step_length_m - c.step_length_m).abs() < 1e-12);
}

/// Walks a sequence of strides given as fractions of the limits (forward or back, side,
/// turn; scaled into the ellipsoid), at 20 Hz: the first from the start, each next one set
/// when a swing begins (so it applies from the swing after), then a stop. Returns the
/// resolved configuration and every tick up to idle again.
fn walk_random(
    model: &ik_solver::BipedModel,
    strides: &[(f64, f64, f64)],
) -> (gait_planner::GaitConfig, Vec<GaitSample>) {
    let p = GaitParams {
        control_rate_hz: 20.0,
        ..GaitParams::slow(model)
    };
    let mut planner = GaitPlanner::new(model.clone(), p).unwrap();
    let c = planner.config().clone();
    let stride_of = |(fx, ly, tz): (f64, f64, f64)| {
        let k = (fx * fx + ly * ly + tz * tz).sqrt().max(1.0);
        let x = if fx >= 0.0 {
            c.step_length_m
        } else {
            c.back_step_length_m
        };
        Stride {
            forward_m: fx / k * x,
            left_m: ly / k * c.side_step_m,
            turn_rad: tz / k * c.turn_step_rad,
        }
    };
    planner.set_stride(stride_of(strides[0])).unwrap();
    planner.request(WalkRequest::UntilStop);
    let (mut next, mut last_step, mut out) = (1, 0, Vec::new());
    for k in 0..100_000u32 {
        let s = planner.update(f64::from(k) / 20.0).unwrap();
        if s.step_index != last_step {
            last_step = s.step_index;
            if next < strides.len() {
                planner.set_stride(stride_of(strides[next])).unwrap();
                next += 1;
            } else {
                planner.request(WalkRequest::Stop);
            }
        }
        let done = s.phase == PhaseKind::Idle && k > 2;
        out.push(s);
        if done {
            return (c, out);
        }
    }
    panic!("the walk never ended");
}

/// Soles as floor rectangles (no yaw): (x_min, x_max, y_min, y_max).
fn sole_box(model: &ik_solver::BipedModel, side: Side, ankle: &Point3<f64>) -> [f64; 4] {
    let r = &model.leg(side).sole;
    [
        ankle.x + r.x_min_m,
        ankle.x + r.x_max_m,
        ankle.y + r.y_min_m,
        ankle.y + r.y_max_m,
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 12, ..ProptestConfig::default() })]

    /// Any sequence of strides within the limits, changed before any swing: at every tick
    /// the CoM keeps its margin, no joint is clamped, and the soles' inner edges stay at
    /// least as far apart as when standing (they never collide or cross).
    #[test]
    fn random_stride_sequences_keep_the_soles_apart_and_the_com_inside(
        strides in prop::collection::vec((-1.0f64..=1.0, -1.0f64..=1.0), 2..6),
    ) {
        let model = default_model();
        let (c, samples) = walk_random(&model, &strides.iter().map(|&(f, l)| (f, l, 0.0)).collect::<Vec<_>>());
        let stand_gap = {
            let [l, r] = samples[0].ankles_world_m;
            sole_box(&model, Side::Left, &l)[2] - sole_box(&model, Side::Right, &r)[3]
        };
        for s in &samples {
            prop_assert!(s.issues.is_empty(), "t = {}: {:?}", s.t_s, s.issues);
            prop_assert!(s.margin_m >= c.min_com_margin_m - 1e-12,
                "t = {} ({}): margin {} below {}", s.t_s, s.phase, s.margin_m, c.min_com_margin_m);
            let [l, r] = s.ankles_world_m;
            let gap = sole_box(&model, Side::Left, &l)[2] - sole_box(&model, Side::Right, &r)[3];
            prop_assert!(gap >= stand_gap - 1e-12, "t = {}: inner edges {} m apart, {} standing",
                s.t_s, gap, stand_gap);
        }
    }
}

#[test]
fn a_turn_in_place_turns_the_feet_about_the_point_between_them() {
    // The six-joint robot (hip yaw): 2 steps of 0.1 rad. The left foot (the side of the
    // turn) turns by 0.2 rad about the point between the feet, the right comes back
    // parallel; the closing half step has nothing left to do.
    let mut planner = GaitPlanner::new(biped6_model(), GaitParams::slow(&biped6_model())).unwrap();
    planner
        .set_stride(Stride {
            turn_rad: 0.1,
            ..Stride::default()
        })
        .unwrap();
    let samples = planner.plan(WalkRequest::Steps(2)).unwrap();
    let [l0, r0] = samples[0].ankles_world_m;
    let mid0 = nalgebra::center(&l0, &r0);
    let half = (l0.y - r0.y) / 2.0;
    let land = landings(&samples);
    assert_eq!(
        land[0].0,
        Side::Left,
        "the foot on the side of the turn first"
    );
    // Left: the midpoint plus half the width at 0.2 rad.
    let (s, c) = 0.2f64.sin_cos();
    assert!(
        close(&land[0].1, mid0.x - s * half, mid0.y + c * half),
        "{:?}",
        land[0]
    );
    assert!(
        close(&land[1].1, mid0.x + s * half, mid0.y - c * half),
        "{:?}",
        land[1]
    );
    let end = samples.last().unwrap();
    assert!(
        end.feet_yaw_rad.iter().all(|y| (y - 0.2).abs() < 1e-12),
        "{:?}",
        end.feet_yaw_rad
    );
    let (_, _, base_yaw) = end.base_world.rotation.euler_angles();
    assert!((base_yaw - 0.2).abs() < 1e-9, "pelvis heading {base_yaw}");
    // No swing foot ever touched the other sole; every tick kept the CoM margin.
    assert!(samples.iter().all(|s| s.issues.is_empty()));
}

#[test]
fn the_robot_without_hip_yaw_refuses_a_turn_limit_by_name() {
    let e = GaitPlanner::new(
        default_model(),
        GaitParams {
            turn_step_rad: 0.1,
            ..slow()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("turn_step_rad") && e.contains("no hip yaw"),
        "{e}"
    );
}

/// True when a corner of either sole lies inside the other (turned rectangles).
fn corners_inside(model: &ik_solver::BipedModel, s: &GaitSample) -> bool {
    let rect = |side: Side| {
        let a = s.ankles_world_m[side.index()];
        model
            .leg(side)
            .sole
            .corners([a.x, a.y], s.feet_yaw_rad[side.index()])
    };
    let (l, r) = (rect(Side::Left), rect(Side::Right));
    l.iter()
        .any(|&p| ik_solver::support::signed_margin(&r, p) > 1e-12)
        || r.iter()
            .any(|&p| ik_solver::support::signed_margin(&l, p) > 1e-12)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 8, ..ProptestConfig::default() })]

    /// The six-joint robot walking any sequence of strides with turns, arcs and side steps
    /// within its limits: at every tick the CoM keeps its margin and no corner of a sole
    /// enters the other, and no joint is clamped: a change of stride that the check walks at
    /// the limits do not cover is checked from the present pose when it is set, and
    /// lowered if its step fails.
    #[test]
    fn random_turning_sequences_keep_the_soles_apart_and_the_com_inside(
        strides in prop::collection::vec((-1.0f64..=1.0, -1.0f64..=1.0, -1.0f64..=1.0), 2..5),
    ) {
        let model = biped6_model();
        let (c, samples) = walk_random(&model, &strides);
        for s in &samples {
            prop_assert!(s.issues.is_empty(), "t = {}: {:?}", s.t_s, s.issues);
            prop_assert!(s.margin_m >= c.min_com_margin_m - 1e-12, "t = {}: margin {}", s.t_s, s.margin_m);
            prop_assert!(!corners_inside(&model, s), "t = {} ({}): the soles overlap", s.t_s, s.phase);
        }
    }
}

/// A case the random walks found (seed cc b9fe3eec…): a turning, side-stepping arc, then
/// a stride of zero, then a stop. The closing steps must keep every joint within its
/// limits (the left ankle roll needed 0.50016 rad against its 0.5 rad limit at 6.3 s).
#[test]
fn an_arc_then_standing_still_then_a_stop_stays_within_the_joint_limits() {
    let model = biped6_model();
    let strides = [
        (
            0.47753459344933563,
            -0.9542293126927226,
            -0.5480892873187272,
        ),
        (0.0, 0.0, 0.0),
    ];
    let (c, samples) = walk_random(&model, &strides);
    let mut last = String::new();
    for s in &samples {
        let k = format!("{} {} {:?}", s.phase, s.step_index, s.support);
        if k != last {
            eprintln!("{:.2} {}", s.t_s, k);
            last = k;
        }
    }
    for s in &samples {
        assert!(
            s.issues.is_empty(),
            "t = {} ({}): {:?}",
            s.t_s,
            s.phase,
            s.issues
        );
        assert!(
            s.margin_m >= c.min_com_margin_m - 1e-12,
            "t = {}: margin {}",
            s.t_s,
            s.margin_m
        );
        assert!(
            !corners_inside(&model, s),
            "t = {} ({}): the soles overlap",
            s.t_s,
            s.phase
        );
    }
}
