//! Leg odometry (ik_solver::odometry) fed with planned walks: the planned feet never slide,
//! so the base it computes from the joint angles alone, with the stance foot as the fixed
//! point, is the planner's base at every tick, forward, backward and sideways, on the
//! default robot and the six-joint one.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::*;
use gait_planner::{GaitParams, GaitPlanner, Stride, Support, WalkRequest};
use ik_solver::{BipedModel, LegOdometry, Side};

fn follow(model: BipedModel, stride: Stride, steps: u32) -> f64 {
    let mut planner = GaitPlanner::new(model.clone(), GaitParams::slow(&model)).unwrap();
    planner.set_stride(stride).unwrap();
    let plan = planner.plan(WalkRequest::Steps(steps)).unwrap();
    let mut planted = Side::Left;
    let mut odo =
        LegOdometry::new(&model, plan[0].base_world, &plan[0].joints_rad, planted).unwrap();
    let mut worst: f64 = 0.0;
    for s in &plan {
        planted = match s.support {
            Support::Left => Side::Left,
            Support::Right => Side::Right,
            Support::Double => planted,
        };
        let base = odo.update(&model, &s.joints_rad, planted).unwrap();
        let err = (base.translation.vector - s.base_world.translation.vector).norm()
            + base.rotation.angle_to(&s.base_world.rotation);
        worst = worst.max(err);
    }
    let moved = (plan.last().unwrap().base_world.translation.vector
        - plan[0].base_world.translation.vector)
        .xy()
        .norm();
    assert!(
        odo.path_m() >= moved - 1e-9,
        "path {} < displacement {moved}",
        odo.path_m()
    );
    worst
}

#[test]
fn leg_odometry_of_a_planned_walk_is_the_planned_base() {
    for (name, model, stride, steps) in [
        (
            "default forward",
            default_model(),
            Stride::forward(0.045),
            4,
        ),
        ("default back", default_model(), Stride::forward(-0.03), 3),
        (
            "default side",
            default_model(),
            Stride {
                left_m: -0.015,
                ..Stride::default()
            },
            4,
        ),
        (
            "biped6 side",
            biped6_model(),
            Stride {
                left_m: 0.009,
                ..Stride::default()
            },
            3,
        ),
    ] {
        let worst = follow(model, stride, steps);
        // Rounding only: the leg IK keeps its digits near the stretched leg (Heron's area
        // instead of an acos of a cosine near -1, which left 1.5e-10 m here).
        assert!(worst < 1e-12, "{name}: {worst} off the plan");
    }
}

#[test]
fn the_covariance_grows_with_the_path_walked() {
    let model = default_model();
    let mut planner = GaitPlanner::new(model.clone(), GaitParams::slow(&model)).unwrap();
    let first = planner.update(0.0).unwrap();
    let odo = LegOdometry::new(&model, first.base_world, &first.joints_rad, Side::Left).unwrap();
    // Standing: 2 mm and 0.005 rad; row-major 6 x 6, variances on the diagonal.
    let c = odo.covariance();
    assert!((c[0] - 0.002f64.powi(2)).abs() < 1e-18);
    assert!((c[7] - 0.002f64.powi(2)).abs() < 1e-18);
    assert!((c[35] - 0.005f64.powi(2)).abs() < 1e-18);
    assert_eq!(c[1], 0.0);
    // After 0.1 m: 2 mm + 5 % of 0.1 m = 7 mm, 0.005 + 0.005 = 0.01 rad.
    let mut planner = GaitPlanner::new(model.clone(), GaitParams::slow(&model)).unwrap();
    let plan = planner.plan(WalkRequest::Steps(2)).unwrap();
    let mut odo =
        LegOdometry::new(&model, plan[0].base_world, &plan[0].joints_rad, Side::Left).unwrap();
    for s in &plan {
        let side = if s.support == Support::Left {
            Side::Left
        } else {
            Side::Right
        };
        odo.update(&model, &s.joints_rad, side).unwrap();
    }
    let path = odo.path_m();
    assert!(path > 0.08, "{path}");
    let c = odo.covariance();
    assert!((c[0] - (0.002 + 0.05 * path).powi(2)).abs() < 1e-15);
    assert!((c[35] - (0.005 + 0.05 * path).powi(2)).abs() < 1e-15);
}

#[test]
fn a_bad_joint_vector_is_refused() {
    let model = default_model();
    let mut planner = GaitPlanner::new(model.clone(), GaitParams::slow(&model)).unwrap();
    let first = planner.update(0.0).unwrap();
    let mut odo =
        LegOdometry::new(&model, first.base_world, &first.joints_rad, Side::Left).unwrap();
    assert!(odo.update(&model, &[0.0; 3], Side::Left).is_err());
    let mut q = first.joints_rad.clone();
    q[0] = f64::NAN;
    assert!(odo.update(&model, &q, Side::Left).is_err());
    assert_eq!(*odo.base(), first.base_world, "the estimate is kept");
}
