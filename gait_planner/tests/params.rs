//! The parameter file: ROS 2 layout, defaults, bounds, unknown keys, derived values.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::*;
use gait_planner::{GaitError, GaitParams};
use ik_solver::Side;

#[test]
fn the_shipped_file_gives_the_defaults() {
    let p =
        GaitParams::from_ros_yaml_file(concat!(env!("CARGO_MANIFEST_DIR"), "/../config/gait.yaml"))
            .unwrap();
    assert_eq!(p, GaitParams::default());
}

#[test]
fn auto_values_scale_with_the_robot() {
    // Durations set, so that resolving does not search a timing (durations_left_at_auto...).
    let timed = GaitParams {
        shift_duration_s: 2.0,
        step_duration_s: 1.0,
        crouch_duration_s: 1.0,
        ..GaitParams::default()
    };
    // Default robot: L1 = L2 = 0.09, ankle-to-sole 0.03, sole 0.10 x 0.06.
    let c = timed.resolve(&default_model()).unwrap();
    assert!((c.step_length_m - 0.45 * 0.18).abs() < 1e-12);
    assert!((c.foot_lift_m - 0.0216).abs() < 1e-12);
    assert!((c.hip_height_m - (0.03 + 0.75 * 0.18)).abs() < 1e-12);
    assert!((c.min_com_margin_m - 0.01).abs() < 1e-12);
    // Test biped: L1 0.11, L2 0.10, hip offset 0.015, ankle-to-sole 0.035, sole 0.12 x 0.07.
    let c = timed.resolve(&biped6_model()).unwrap();
    assert!((c.hip_height_m - (0.035 + 0.015 + 0.75 * 0.21)).abs() < 1e-12);
    assert!((c.min_com_margin_m - 0.07 / 6.0).abs() < 1e-12);
    // The slow walk of the tests: 0.25 x leg on hips 0.85 x leg, 2 s / 1 s / 1 s.
    let c = GaitParams::slow(&biped6_model())
        .resolve(&biped6_model())
        .unwrap();
    assert!((c.step_length_m - 0.25 * 0.21).abs() < 1e-12);
    assert!((c.hip_height_m - (0.035 + 0.015 + 0.85 * 0.21)).abs() < 1e-12);
    assert_eq!(
        (c.shift_duration_s, c.step_duration_s, c.crouch_duration_s),
        (2.0, 1.0, 1.0)
    );
}

/// The slow walk's parameter files the CLI and rclpy tests pass (and the golden
/// trajectory's, at 20 Hz) are `GaitParams::slow` of their robots, to the millimetre they are
/// written in, resolved to the same walk.
#[test]
fn the_slow_walk_files_are_the_slow_walk() {
    let data = concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/data/");
    for (file, model, rate_hz) in [
        ("gait_slow.yaml", default_model(), 100.0),
        ("golden_params.yaml", default_model(), 20.0),
        ("biped6_slow.yaml", biped6_model(), 100.0),
    ] {
        let read = GaitParams::from_ros_yaml_file(format!("{data}{file}")).unwrap();
        let slow = GaitParams {
            control_rate_hz: rate_hz,
            ..GaitParams::slow(&model)
        };
        let (a, b) = (read.resolve(&model).unwrap(), slow.resolve(&model).unwrap());
        assert!((a.step_length_m - b.step_length_m).abs() < 5e-4, "{file}");
        assert!((a.hip_height_m - b.hip_height_m).abs() < 5e-4, "{file}");
        assert_eq!(
            GaitParams {
                step_length_m: 0.0,
                hip_height_m: 0.0,
                ..read
            },
            GaitParams {
                step_length_m: 0.0,
                hip_height_m: 0.0,
                ..slow
            },
            "{file}"
        );
    }
}

#[test]
fn node_section_overrides_the_wildcard_and_other_nodes_are_ignored() {
    let yaml = r#"
/**:
  ros__parameters:
    control_rate_hz: 50.0
    use_sim_time: true
ik_solver:
  ros__parameters:
    whatever: 1
/robot/gait_planner:
  ros__parameters:
    step_length_m: 0.03
    first_foot: right
"#;
    let p = GaitParams::from_ros_yaml_str(yaml).unwrap();
    assert_eq!(p.control_rate_hz, 50.0);
    assert_eq!(p.step_length_m, 0.03);
    assert_eq!(p.first_foot, Side::Right);
    assert_eq!(p.step_duration_s, 0.0);
}

#[test]
fn unknown_keys_and_wrong_types_are_named() {
    let e = GaitParams::from_ros_yaml_str(
        "gait_planner:\n  ros__parameters:\n    step_lenght_m: 0.03\n",
    )
    .unwrap_err();
    assert!(matches!(e, GaitError::ParamFile { .. }));
    assert!(e.to_string().contains("step_lenght_m"), "{e}");
    let e = GaitParams::from_ros_yaml_str(
        "gait_planner:\n  ros__parameters:\n    step_duration_s: fast\n",
    )
    .unwrap_err();
    assert!(
        e.to_string().contains("step_duration_s") || e.to_string().contains("f64"),
        "{e}"
    );
    let e = GaitParams::from_ros_yaml_str(
        "gait_planner:\n  ros__parameters:\n    first_foot: middle\n",
    )
    .unwrap_err();
    assert!(e.to_string().contains("middle"), "{e}");
    let e = GaitParams::from_ros_yaml_str("ik_solver:\n  ros__parameters: {}\n").unwrap_err();
    assert!(e.to_string().contains("gait_planner"), "{e}");
    let e = GaitParams::from_ros_yaml_str("gait_planner: [1, 2\n").unwrap_err();
    assert!(matches!(e, GaitError::ParamFile { .. }));
    let e = GaitParams::from_ros_yaml_file("/nonexistent/gait.yaml").unwrap_err();
    assert!(e.to_string().contains("/nonexistent/gait.yaml"), "{e}");
}

#[test]
fn out_of_bounds_values_name_the_key_and_value() {
    let model = default_model();
    let cases = [
        (
            GaitParams {
                control_rate_hz: 2000.0,
                ..slow()
            },
            "control_rate_hz",
            2000.0,
        ),
        (
            GaitParams {
                step_duration_s: 0.05,
                ..slow()
            },
            "step_duration_s",
            0.05,
        ),
        (
            GaitParams {
                step_duration_s: -1.0,
                ..slow()
            },
            "step_duration_s",
            -1.0,
        ),
        // With durations at 0 (auto), a bad value is named before any timing search.
        (
            GaitParams {
                shift_duration_s: 0.0,
                step_duration_s: 0.0,
                foot_lift_m: 1.0,
                ..slow()
            },
            "foot_lift_m",
            1.0,
        ),
        (
            GaitParams {
                shift_duration_s: f64::NAN,
                ..slow()
            },
            "shift_duration_s",
            f64::NAN,
        ),
        (
            GaitParams {
                step_length_m: -0.01,
                ..slow()
            },
            "step_length_m",
            -0.01,
        ),
        (
            GaitParams {
                hip_height_m: 0.5,
                ..slow()
            },
            "hip_height_m",
            0.5,
        ),
        (
            GaitParams {
                foot_lift_m: 1.0,
                ..slow()
            },
            "foot_lift_m",
            1.0,
        ),
    ];
    for (p, key, value) in cases {
        match p.resolve(&model) {
            Err(GaitError::Param {
                key: k, value: v, ..
            }) => {
                assert_eq!(k, key);
                assert!(v == value || (v.is_nan() && value.is_nan()));
            }
            other => panic!("{key}: wanted a Param error, got {other:?}"),
        }
    }
    let msg = GaitParams {
        control_rate_hz: 2000.0,
        ..slow()
    }
    .resolve(&model)
    .unwrap_err()
    .to_string();
    assert!(
        msg.contains("control_rate_hz") && msg.contains("2000") && msg.contains("Hz"),
        "{msg}"
    );
}

/// A parameter file written from parameters reads back to the same parameters.
#[test]
fn written_parameters_read_back_the_same() {
    let p = GaitParams {
        step_length_m: 0.081,
        hip_height_m: 0.165,
        shift_duration_s: 0.72,
        first_foot: Side::Right,
        rise_at_end: true,
        ..slow()
    };
    let text = p.to_ros_yaml_string().unwrap();
    assert!(
        text.starts_with("gait_planner:\n  ros__parameters:\n"),
        "{text}"
    );
    assert_eq!(GaitParams::from_ros_yaml_str(&text).unwrap(), p);
}

/// `check_bounds` names a value out of its bounds without running the timing search; a
/// duration within its bounds but too fast for the joints passes it and is refused by the
/// planner's own checks (which `biped walk` runs while its fleet starts).
#[test]
fn bounds_are_checked_without_the_timing_search() {
    let m = default_model();
    GaitParams::default().check_bounds(&m).unwrap();
    let long = GaitParams {
        step_length_m: 0.5,
        ..GaitParams::default()
    };
    let e = long.check_bounds(&m).unwrap_err().to_string();
    assert!(e.contains("`step_length_m` = 0.5"), "{e}");
    let fast = GaitParams {
        step_duration_s: 0.12,
        ..GaitParams::default()
    };
    fast.check_bounds(&m).unwrap();
    let e = gait_planner::GaitPlanner::new(m, fast)
        .unwrap_err()
        .to_string();
    assert!(e.contains("rad/s"), "{e}");
}

/// How far the base went over a walk (x, y, m).
fn travel(samples: &[gait_planner::GaitSample]) -> [f64; 2] {
    let (a, b) = (
        samples[0].base_world.translation.vector,
        samples[samples.len() - 1].base_world.translation.vector,
    );
    [b.x - a.x, b.y - a.y]
}

/// Between walks the node gives the planner its parameters at every walk command, mostly
/// the ones it holds: taken as checked (the checks depend on the parameters and the robot
/// only), they give the configuration they gave before and put the stride back to straight
/// ahead, as a new planner has it; parameters checked by another planner (the node's
/// parameter and timing-search threads) come with that planner's configuration; others are
/// checked, and refused naming the value, the planner keeping what it had.
#[test]
fn parameters_given_again_give_what_their_check_gave() {
    let model = default_model();
    let params = slow();
    let mut planner = planner(params.clone());
    let checked = planner.config().clone();
    assert!(!planner.needs_check(&params));
    let side = gait_planner::Stride {
        forward_m: 0.0,
        left_m: checked.side_step_m,
        turn_rad: 0.0,
    };
    planner.set_stride(side).unwrap();
    let sideways = travel(&planner.plan(gait_planner::WalkRequest::Steps(2)).unwrap());
    assert!(sideways[1] > 0.5 * checked.side_step_m, "{sideways:?}");

    planner.set_params(params.clone()).unwrap();
    assert_eq!(planner.config(), &checked);
    let ahead = travel(&planner.plan(gait_planner::WalkRequest::Steps(2)).unwrap());
    assert!(ahead[0] > 0.5 * checked.step_length_m, "{ahead:?}");
    assert!(ahead[1].abs() < 1e-3, "{ahead:?}");

    // Checked on another planner (a step 1.5 cm shorter), then given: its configuration.
    let shorter = GaitParams {
        step_length_m: checked.step_length_m - 0.015,
        ..params.clone()
    };
    // (Durations set: a check, no timing search, which a node runs off its loop alike.)
    assert!(planner.needs_check(&shorter));
    assert!(!planner.needs_timing_search(&shorter));
    let other = gait_planner::GaitPlanner::new(model, shorter.clone()).unwrap();
    planner.remember_checks(&other);
    assert!(!planner.needs_check(&shorter));
    assert!(planner.needs_check(&params));
    planner.set_params(shorter).unwrap();
    assert_eq!(planner.config(), other.config());
    assert_ne!(planner.config(), &checked);
    // And the first ones again: checked again, the same as at first.
    planner.set_params(params.clone()).unwrap();
    assert_eq!(planner.config(), &checked);

    // Parameters not checked yet are: a step too long is refused, naming it, and the
    // planner keeps what it had.
    let long = GaitParams {
        step_length_m: 0.5,
        ..params
    };
    assert!(planner.needs_check(&long));
    let e = planner.set_params(long).unwrap_err().to_string();
    assert!(e.contains("step_length_m") && e.contains("0.5"), "{e}");
    assert_eq!(planner.config(), &checked);
}

/// Durations left at 0 (auto): parameters checked need neither the timing search nor the
/// check walks again; changed, both; checked on another planner and taken over, neither.
#[test]
fn auto_durations_need_the_search_and_the_check_only_when_new() {
    let params = GaitParams::default();
    assert!(params.has_auto_timing());
    let mut planner = planner(params.clone());
    assert!(!planner.needs_timing_search(&params));
    assert!(!planner.needs_check(&params));
    let higher = GaitParams {
        foot_lift_m: planner.config().foot_lift_m + 0.001,
        ..params.clone()
    };
    assert!(planner.needs_timing_search(&higher));
    assert!(planner.needs_check(&higher));
    let other = gait_planner::GaitPlanner::new(default_model(), higher.clone()).unwrap();
    planner.remember_checks(&other);
    assert!(!planner.needs_timing_search(&higher));
    assert!(!planner.needs_check(&higher));
    planner.set_params(higher).unwrap();
    assert_eq!(planner.config(), other.config());
}
