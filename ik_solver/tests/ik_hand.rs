//! IK against values computed by hand from ALGORITHM.md's formulas (in Python, outside this
//! code), then mapped to each URDF's axis signs by hand.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::*;
use ik_solver::{AnkleTarget, IkError, JointRole as R, Side};

fn assert_angles(got: &[f64; 6], want: [f64; 6]) {
    for (k, (g, w)) in got.iter().zip(want).enumerate() {
        assert!(
            (g - w).abs() < 1e-12,
            "role {:?}: got {g}, want {w}",
            R::ALL[k]
        );
    }
}

#[test]
fn default_robot_leg_geometry_is_read_from_the_urdf() {
    let b = default_biped();
    for s in Side::BOTH {
        let leg = b.leg(s);
        assert!((leg.thigh_m - 0.09).abs() < 1e-12);
        assert!((leg.shin_m - 0.09).abs() < 1e-12);
        assert!((leg.ankle_to_sole_m - 0.03).abs() < 1e-12);
        assert!((leg.hip_in_base_m.y - s.sign() * 0.037).abs() < 1e-12);
        assert!((leg.hip_in_base_m.z + 0.03).abs() < 1e-12);
        assert!(!leg.has_yaw());
        // Sole box 0.10 x 0.06 centred 0.01 ahead of the ankle.
        assert!((leg.sole.x_min_m + 0.04).abs() < 1e-12 && (leg.sole.x_max_m - 0.06).abs() < 1e-12);
        assert!((leg.sole.y_min_m + 0.03).abs() < 1e-12 && (leg.sole.y_max_m - 0.03).abs() < 1e-12);
    }
    assert_eq!(b.leg(Side::Left).joint(R::Knee).unwrap().name, "l_knee");
    assert_eq!(
        b.leg(Side::Right).joint(R::AnkleRoll).unwrap().name,
        "r_ankle_roll"
    );
}

#[test]
fn crouch_straight_below_the_hip() {
    // Isosceles triangle: d = 0.16, L1 = L2 = 0.09; the thigh leans acos(8/9) forward,
    // the knee bends twice that, the ankle takes the thigh's angle back. All axes of the
    // default robot are +x/+y, so thigh flexion is a negative hip pitch.
    let b = default_biped();
    let a = (0.16f64 / 0.18).acos();
    for s in Side::BOTH {
        let sol = b.solve_leg(s, &AnkleTarget::new(0.0, 0.0, -0.16)).unwrap();
        assert!(sol.is_exact());
        assert_angles(&sol.angles_rad, [0.0, 0.0, -a, 2.0 * a, -a, 0.0]);
        assert!((a - 0.475882249660416).abs() < 1e-12);
    }
}

#[test]
fn forward_and_sideways_targets() {
    let b = default_biped();
    // (x, y, z) -> [roll, hip flexion, knee, ankle (knee - hip), -roll] from the formulas.
    let cases = [
        (
            [0.03, 0.02, -0.15],
            [
                0.132551532296674,
                0.736950234872413,
                1.082484369887968,
                0.345534135015555,
            ],
        ),
        (
            [-0.04, -0.03, -0.14],
            [
                -0.211093333222747,
                0.326586283538549,
                1.198025314499217,
                0.871439030960668,
            ],
        ),
    ];
    for ([x, y, z], [roll, hip, knee, ankle]) in cases {
        let sol = b.solve_leg(Side::Left, &AnkleTarget::new(x, y, z)).unwrap();
        assert!(sol.is_exact(), "{:?}", sol.issues);
        assert_angles(&sol.angles_rad, [0.0, roll, -hip, knee, -ankle, -roll]);
    }
}

#[test]
fn six_joint_leg_with_flipped_axes_offset_hip_and_yaw() {
    // test_biped6: L1 0.11, L2 0.10, hip pitch 0.015 below hip roll; left hip roll axis is -x,
    // right knee axis is -y. Target (0.02, 0.01, -0.19), foot yaw 0.2 rad: in the yawed hip
    // frame the formulas give roll 0.030660279288661, hip 0.666001708999223,
    // knee 1.148226652432100, ankle 0.482224943432877.
    let b = biped6();
    let (roll, hip, knee, ankle) = (
        0.030660279288661,
        0.666001708999223,
        1.1482266524321,
        0.482224943432877,
    );
    let t = AnkleTarget {
        ankle_in_hip_m: nalgebra::Vector3::new(0.02, 0.01, -0.19),
        foot_yaw_rad: 0.2,
    };
    let l = b.solve_leg(Side::Left, &t).unwrap();
    assert!(l.is_exact(), "{:?}", l.issues);
    assert_angles(&l.angles_rad, [0.2, -roll, -hip, knee, -ankle, -roll]);
    let r = b.solve_leg(Side::Right, &t).unwrap();
    assert!(r.is_exact(), "{:?}", r.issues);
    assert_angles(&r.angles_rad, [0.2, roll, -hip, -knee, -ankle, -roll]);
    assert_eq!(
        b.leg(Side::Right).joint(R::Knee).unwrap().name,
        "RightLegJ4"
    );
    assert_eq!(
        b.leg(Side::Left).joint(R::HipYaw).unwrap().name,
        "LeftLegJ1"
    );
}

#[test]
fn non_finite_targets_are_refused_naming_the_field() {
    let b = default_biped();
    let err = b
        .solve_leg(Side::Right, &AnkleTarget::new(0.0, f64::NAN, -0.15))
        .unwrap_err();
    assert!(matches!(
        err,
        IkError::NonFiniteTarget {
            side: Side::Right,
            field: "ankle_in_hip.y",
            ..
        }
    ));
    assert!(err.to_string().contains("right leg") && err.to_string().contains("ankle_in_hip.y"));
    let err = b.solve_leg(
        Side::Left,
        &AnkleTarget {
            foot_yaw_rad: f64::INFINITY,
            ..AnkleTarget::new(0.0, 0.0, -0.15)
        },
    );
    assert!(matches!(
        err,
        Err(IkError::NonFiniteTarget {
            field: "foot_yaw",
            ..
        })
    ));
    // A refused target leaves the joint vector untouched.
    let mut q = vec![0.5; b.robot().dof_count()];
    assert!(
        b.solve_legs(
            &AnkleTarget::new(0.0, 0.0, -0.15),
            &AnkleTarget::new(f64::NAN, 0.0, -0.15),
            &mut q
        )
        .is_err()
    );
    assert!(q.iter().all(|&v| v == 0.5));
}

#[test]
fn unreachable_target_is_clamped_and_reported_with_the_amount() {
    let b = default_biped();
    let sol = b
        .solve_leg(Side::Left, &AnkleTarget::new(0.0, 0.0, -0.25))
        .unwrap();
    assert!(sol.angles_rad.iter().all(|a| a.is_finite()));
    let reach = sol.issues.iter().find_map(|i| match i {
        ik_solver::IkIssue::OutOfReach {
            side,
            distance_m,
            reach_m,
        } => Some((*side, *distance_m, *reach_m)),
        _ => None,
    });
    let (side, d, r) = reach.expect("out of reach reported");
    assert_eq!(side, Side::Left);
    assert!((d - 0.25).abs() < 1e-12 && (r - 0.18).abs() < 1e-12);
    // Clamped onto the reach: the leg is straight.
    assert!(sol.angle(R::Knee).abs() < 1e-6);
    assert!(
        sol.issues[0].to_string().contains("by 0.0700 m"),
        "{}",
        sol.issues[0]
    );
}

#[test]
fn joint_limit_is_clamped_and_names_the_joint() {
    let b = default_biped();
    // Far to the side: hip roll beyond its 0.6 rad limit.
    let sol = b
        .solve_leg(Side::Left, &AnkleTarget::new(0.0, 0.12, -0.12))
        .unwrap();
    let lim = sol
        .issues
        .iter()
        .find(|i| {
            matches!(
                i,
                ik_solver::IkIssue::JointLimit {
                    role: R::HipRoll,
                    ..
                }
            )
        })
        .expect("hip roll clamp reported");
    assert!(lim.to_string().contains("`l_hip_roll`"), "{lim}");
    assert!((sol.angle(R::HipRoll) - 0.6).abs() < 1e-12);
}

#[test]
fn yaw_on_a_five_joint_leg_is_reported_and_ignored() {
    let b = default_biped();
    let t = AnkleTarget {
        foot_yaw_rad: 0.1,
        ..AnkleTarget::new(0.0, 0.0, -0.16)
    };
    let sol = b.solve_leg(Side::Left, &t).unwrap();
    assert!(matches!(
        sol.issues[..],
        [ik_solver::IkIssue::NoYawJoint { .. }]
    ));
    assert_eq!(sol.angle(R::HipYaw), 0.0);
}

#[test]
fn op3_layout_leg_geometry_is_read_as_lines_from_the_urdf() {
    // tests/data/make_op3_layout.py: yaw joint at (0.005, ±0.035, -0.035); roll joint
    // (-0.024, 0, -0.028) from it; pitch joint (0.027, ±0.016, -0.004) from the roll joint;
    // knee (0.002, 0, -0.1); ankle pitch (-0.002, 0, -0.1); ankle roll (-0.022, ∓0.010, 0);
    // sole 0.11 x 0.066, centre (0.030, ∓0.003, -0.030) from the ankle roll joint, 8 mm thick.
    let b = op3_layout();
    for s in Side::BOTH {
        let leg = b.leg(s);
        let y = s.sign();
        // H: below the yaw joint, where the roll axis passes.
        let h = leg.hip_in_base_m;
        assert!(
            (h - nalgebra::Vector3::new(0.005, y * 0.035, -0.063)).norm() < 1e-12,
            "{h}"
        );
        assert!((leg.hip_pitch_forward_m - 0.003).abs() < 1e-12);
        assert!((leg.hip_roll_to_pitch_m - 0.004).abs() < 1e-12);
        assert!((leg.ankle_lateral_m - y * 0.006).abs() < 1e-12);
        assert!((leg.thigh_m - 0.002f64.hypot(0.1)).abs() < 1e-12);
        assert!((leg.shin_m - 0.002f64.hypot(0.1)).abs() < 1e-12);
        assert!((leg.thigh_angle0_rad - 0.02f64.atan()).abs() < 1e-12);
        assert!((leg.shin_angle0_rad + 0.02f64.atan()).abs() < 1e-12);
        assert!((leg.ankle_to_sole_m - 0.034).abs() < 1e-12);
        // The sole around the ankle point, 22 mm ahead of the ankle roll joint.
        let r = leg.sole;
        assert!(
            (r.x_min_m + 0.047).abs() < 1e-12 && (r.x_max_m - 0.063).abs() < 1e-12,
            "{r:?}"
        );
        let (inner, outer) = (-0.036, 0.030);
        let (y_min, y_max) = if y > 0.0 {
            (inner, outer)
        } else {
            (-outer, -inner)
        };
        assert!(
            (r.y_min_m - y_min).abs() < 1e-12 && (r.y_max_m - y_max).abs() < 1e-12,
            "{r:?}"
        );
        assert!(leg.has_yaw());
    }
}

#[test]
fn op3_layout_leg_rolls_to_the_tangent_of_its_offset() {
    // Target (0.02, ±0.05, -0.19), foot yaw 0.15 rad; e = ±0.006, a_h = 0.003, h_h = 0.004,
    // thigh (0.002, 0.1) and shin (-0.002, 0.1) (forward, down). ALGORITHM.md's "Leg layouts
    // of real servo humanoids" in Python gives roll, thigh and shin angles from straight down
    // (forward positive), and δ = atan(0.02):
    let d = 0.01999733397315053;
    let cases = [
        (
            Side::Left,
            0.2090892911518677,
            0.3914174255595978,
            -0.13952648894539188,
        ),
        (
            Side::Right,
            -0.23878761401373866,
            0.30978111319150786,
            -0.21345078661980604,
        ),
    ];
    let b = op3_layout();
    for (side, roll, thigh, shin) in cases {
        let t = AnkleTarget {
            ankle_in_hip_m: nalgebra::Vector3::new(0.02, side.sign() * 0.05, -0.19),
            foot_yaw_rad: 0.15,
        };
        let sol = b.solve_leg(side, &t).unwrap();
        assert!(sol.is_exact(), "{:?}", sol.issues);
        // Joint angles: hip pitch δ1 - thigh, knee (thigh - shin) - (δ1 - δ2), ankle pitch
        // shin - δ2; both hip rolls turn about -x, the right leg's pitch joints about -y.
        let pitch = [d - thigh, (thigh - shin) - 2.0 * d, shin + d];
        let k = if side == Side::Left { 1.0 } else { -1.0 };
        assert_angles(
            &sol.angles_rad,
            [0.15, -roll, k * pitch[0], k * pitch[1], k * pitch[2], -roll],
        );
    }
}

#[test]
fn a_target_inside_the_sideways_offset_is_flagged() {
    // 4 mm from the roll axis, inside e = 6 mm: no roll reaches it.
    let b = op3_layout();
    let sol = b
        .solve_leg(Side::Left, &AnkleTarget::new(0.0, 0.0, -0.004))
        .unwrap();
    assert!(sol.angles_rad.iter().all(|a| a.is_finite()));
    assert!(
        sol.issues.iter().any(|i| matches!(
            i,
            ik_solver::IkIssue::InsideLateralOffset { distance_m, offset_m, .. }
                if (distance_m - 0.004).abs() < 1e-12 && (offset_m - 0.006).abs() < 1e-12
        )),
        "{:?}",
        sol.issues
    );
}

#[test]
fn a_target_light_years_away_stretches_the_leg_toward_it_without_nan() {
    // Squares of such lengths overflow f64; the solver brings the target in to 1 km along
    // its direction first. Straight down, 1e200 m: the leg hangs stretched, no roll, and the
    // issue names the distance asked for.
    for b in [default_biped(), biped6(), op3_layout()] {
        let sol = b
            .solve_leg(Side::Left, &AnkleTarget::new(0.0, 0.0, -1e200))
            .unwrap();
        assert!(sol.angles_rad.iter().all(|a| a.is_finite()), "{sol:?}");
        assert!(sol.angle(R::HipRoll).abs() < 1e-6, "{sol:?}");
        assert!(
            sol.issues.iter().any(|i| matches!(
                i,
                ik_solver::IkIssue::OutOfReach { distance_m, .. } if (distance_m / 1e200 - 1.0).abs() < 1e-6
            )),
            "{:?}",
            sol.issues
        );
        // Every direction, at the largest finite values: finite and within limits.
        for p in [
            [f64::MAX, f64::MAX, f64::MAX],
            [-f64::MAX, 1e300, -1e-300],
            [0.0, -1e308, 1e308],
        ] {
            let t = AnkleTarget::new(p[0], p[1], p[2]);
            let sol = b.solve_leg(Side::Right, &t).unwrap();
            for (role, j) in b.leg(Side::Right).present() {
                let a = sol.angle(role);
                assert!(
                    a.is_finite() && a >= j.limits.lower && a <= j.limits.upper,
                    "{role} = {a} for {t:?}"
                );
            }
        }
    }
}
