//! Walking backward and sideways in MuJoCo physics: the default robot (five joints a leg, no
//! hip yaw) and a six-joint robot of other proportions (tests/data/biped6_renamed.urdf),
//! each playing its own plan of 0.1 m to the left, to the right or backward.
//!
//! The plan's pelvis does not move exactly as far as its feet: the crouched walking pose
//! puts the CoM, not the pelvis, over the middle of the feet, a few millimetres from where
//! the standing pose had the pelvis. So the measured base is held to the plan's base; the
//! plan's feet are held to the command (hand-computed: N steps of a stride).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use gait_planner::{GaitParams, GaitPlanner, GaitSample, Stride, WalkRequest};
use ik_solver::{BipedModel, DEFAULT_URDF};
use sim_bridge::{Sim, SimConfig};
use walk_eval::{PlayOptions, WalkReport, run_plan};

const BIPED6: &str = include_str!("../../tests/data/biped6_renamed.urdf");

/// Plans `steps` swings of `stride` for the robot, checks that the feet end `want_m`
/// (forward, left) from where they started, and plays the plan in physics.
fn walk(urdf: &str, stride: Stride, steps: u32, want_m: [f64; 2]) -> WalkReport {
    let (plan, r) = play(urdf, stride, steps);
    let (a, b) = (&plan[0], plan.last().unwrap());
    for k in 0..2 {
        let moved = b.ankles_world_m[k] - a.ankles_world_m[k];
        assert!(
            (moved.x - want_m[0]).abs() < 1e-9 && (moved.y - want_m[1]).abs() < 1e-9,
            "foot {k} moved {moved:?} in the plan, want {want_m:?}"
        );
    }
    r
}

/// Plans `steps` swings of `stride` for the robot and plays the plan in physics.
fn play(urdf: &str, stride: Stride, steps: u32) -> (Vec<GaitSample>, WalkReport) {
    let model = BipedModel::from_urdf_str(urdf, None).unwrap();
    // The slow walk: the strides below are written for its step limits.
    let params = GaitParams::slow(&model);
    let mut planner = GaitPlanner::new(model, params).unwrap();
    planner.set_stride(stride).unwrap();
    let plan = planner.plan(WalkRequest::Steps(steps)).unwrap();
    let mut sim = Sim::from_urdf_str(urdf, None, &SimConfig::default()).unwrap();
    let r = run_plan(&mut sim, &plan, &PlayOptions::default()).unwrap();
    eprintln!("{r:#?}");
    (plan, r)
}

/// Stood ([`assert_stood`]), heading within 3 deg, and the base within 10 % of the
/// commanded 0.1 m of where the plan puts it, on both axes.
fn assert_followed(r: &WalkReport) {
    assert_stood(r);
    assert!(
        r.heading_drift_deg < 3.0,
        "heading drift {} deg",
        r.heading_drift_deg
    );
    for (axis, got, want) in [
        ("forward", r.distance_m, r.planned_distance_m),
        ("left", r.left_m, r.planned_left_m),
    ] {
        assert!(
            (got - want).abs() <= 0.1 * 0.1,
            "{axis}: the base moved {got} m, the plan {want} m"
        );
    }
}

#[test]
fn the_default_robot_side_steps_left_a_tenth_of_a_metre() {
    // 6 steps of 1/60 m (the limit is 18 mm): the left foot opens 1/30 m three times.
    let r = walk(
        DEFAULT_URDF,
        Stride {
            left_m: 0.1 / 6.0,
            ..Stride::default()
        },
        6,
        [0.0, 0.1],
    );
    assert_followed(&r);
}

#[test]
fn the_default_robot_walks_back_a_tenth_of_a_metre() {
    let r = walk(DEFAULT_URDF, Stride::forward(-0.025), 4, [-0.1, 0.0]);
    assert_followed(&r);
}

#[test]
fn the_six_joint_robot_side_steps_right_a_tenth_of_a_metre() {
    // Its side-step limit is 9.8 mm (the auto value, lowered by its check walks): 12 steps
    // of 1/120 m, the right foot opening 1/60 m six times.
    let r = walk(
        BIPED6,
        Stride {
            left_m: -0.1 / 12.0,
            ..Stride::default()
        },
        12,
        [0.0, -0.1],
    );
    assert_followed(&r);
}

#[test]
fn the_six_joint_robot_walks_back_a_tenth_of_a_metre() {
    let r = walk(BIPED6, Stride::forward(-0.025), 4, [-0.1, 0.0]);
    assert_followed(&r);
}

/// Plans and plays a walk of the six-joint robot; returns the report and the plan's final
/// pelvis heading (deg).
fn walk6(stride: Stride, steps: u32) -> (WalkReport, f64) {
    let (plan, r) = play(BIPED6, stride, steps);
    let (_, _, yaw) = plan.last().unwrap().base_world.rotation.euler_angles();
    (r, yaw.to_degrees())
}

/// No fall, the CoP inside the support polygon >= 99 % of the time, no stance foot sliding
/// 5 mm, tilt under 10 deg.
fn assert_stood(r: &WalkReport) {
    assert!(r.fell.is_none(), "fell: {:?}", r.fell);
    assert!(
        r.cop_inside_fraction >= 0.99,
        "CoP inside {}",
        r.cop_inside_fraction
    );
    assert!(r.max_foot_slip_m < 0.005, "slip {} m", r.max_foot_slip_m);
    assert!(r.max_tilt_deg < 10.0, "tilt {} deg", r.max_tilt_deg);
}

#[test]
fn the_six_joint_robot_turns_on_the_spot_by_ninety_degrees() {
    // 12 steps of pi/24: the left foot turns by pi/12 six times, the right follows.
    let (r, planned_deg) = walk6(
        Stride {
            turn_rad: std::f64::consts::PI / 24.0,
            ..Stride::default()
        },
        12,
    );
    assert!(
        (planned_deg - 90.0).abs() < 1e-6,
        "the plan turns {planned_deg} deg"
    );
    assert_stood(&r);
    assert!(
        (r.final_heading_deg - 90.0).abs() <= 9.0,
        "turned {} deg of 90",
        r.final_heading_deg
    );
    let drift = r.distance_m.hypot(r.left_m);
    assert!(drift < 0.03, "the base drifted {drift} m");
}

#[test]
fn the_six_joint_robot_walks_an_arc() {
    // Forward 30 mm and left 0.1 rad per step, 8 steps: 0.24 m and 45.8 deg in the plan.
    let (r, planned_deg) = walk6(
        Stride {
            forward_m: 0.03,
            turn_rad: 0.1,
            ..Stride::default()
        },
        8,
    );
    assert_stood(&r);
    assert!(planned_deg > 40.0, "{planned_deg}");
    assert!(
        (r.final_heading_deg - planned_deg).abs() <= 0.1 * planned_deg,
        "turned {} deg, the plan {planned_deg}",
        r.final_heading_deg
    );
    let (got, want) = (
        r.distance_m.hypot(r.left_m),
        r.planned_distance_m.hypot(r.planned_left_m),
    );
    assert!(
        (got - want).abs() <= 0.1 * want,
        "moved {got} m, the plan {want} m"
    );
}
