//! FK(IK(target)) == target and the sole stays level, over the reachable workspace; outside
//! it, every answer is finite, within limits, and flagged.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::*;
use ik_solver::{AnkleTarget, BipedModel, IkIssue, JointRole, Side};
use nalgebra::{Rotation3, Vector3};
use proptest::prelude::*;

fn check_roundtrip(b: &BipedModel, side: Side, t: AnkleTarget) -> Result<(), TestCaseError> {
    let sol = b.solve_leg(side, &t).unwrap();
    prop_assume!(sol.is_exact());
    let mut q = vec![0.0; b.robot().dof_count()];
    b.write_leg(&sol, &mut q);
    let got = b.ankles_in_hips(&q).unwrap()[side.index()];
    let err = (got - t.ankle_in_hip_m).norm();
    prop_assert!(err < 1e-12, "FK(IK) off by {err} m for {:?}", t);
    let tilt = foot_tilt_rad(b, side, &q, t.foot_yaw_rad);
    prop_assert!(tilt < 1e-12, "sole tilted by {tilt} rad for {:?}", t);
    Ok(())
}

fn check_clamped(b: &BipedModel, side: Side, t: AnkleTarget) -> Result<(), TestCaseError> {
    let sol = b.solve_leg(side, &t).unwrap();
    let leg = b.leg(side);
    for (role, j) in leg.present() {
        let a = sol.angle(role);
        prop_assert!(a.is_finite());
        prop_assert!(
            a >= j.limits.lower && a <= j.limits.upper,
            "{} = {a} outside limits",
            j.name
        );
    }
    let mut q = vec![0.0; b.robot().dof_count()];
    b.write_leg(&sol, &mut q);
    let got = b.ankles_in_hips(&q).unwrap()[side.index()];
    let missed =
        (got - t.ankle_in_hip_m).norm() > 1e-9 || foot_tilt_rad(b, side, &q, t.foot_yaw_rad) > 1e-9;
    prop_assert!(
        !missed || !sol.issues.is_empty(),
        "missed the target without a flag: {:?}",
        t
    );
    Ok(())
}

/// The paper's angles as written in ALGORITHM.md, each term on its own (atan2, asin, acos),
/// before the joint limits: the reference for the solver's fused form (sums of angles as one
/// atan2). Targets pulled onto the reach or pushed out of the fold as the solver documents.
/// Also the knee's inner angle (pi: stretched).
fn textbook_angles(b: &BipedModel, side: Side, t: &AnkleTarget) -> ([f64; 6], f64) {
    use std::f64::consts::PI;
    let leg = b.leg(side);
    let yaw = if leg.has_yaw() { t.foot_yaw_rad } else { 0.0 };
    let p = Rotation3::from_axis_angle(&Vector3::z_axis(), -yaw) * t.ankle_in_hip_m;
    let e = leg.ankle_lateral_m;
    let r = p.y.hypot(p.z);
    let s = if r < e.abs() { e.signum() } else { e / r };
    let roll = p.y.atan2(-p.z) - s.asin();
    let mut x = p.x - leg.hip_pitch_forward_m;
    let mut z = r * (1.0 - s * s).sqrt() - leg.hip_roll_to_pitch_m;
    let (l1, l2) = (leg.thigh_m, leg.shin_m);
    let (reach, min) = (l1 + l2, (l1 - l2).abs().max(1e-6 * (l1 + l2)));
    let mut d = x.hypot(z);
    if d > reach || d < min {
        let to = d.clamp(min, reach);
        (x, z, d) = (x * to / d, z * to / d, to);
    }
    let gamma = ((l1 * l1 + l2 * l2 - d * d) / (2.0 * l1 * l2))
        .clamp(-1.0, 1.0)
        .acos();
    let beta = ((l1 * l1 + d * d - l2 * l2) / (2.0 * l1 * d))
        .clamp(-1.0, 1.0)
        .acos();
    let thigh = x.atan2(z) + beta;
    let shin = thigh - (PI - gamma);
    let sign = |r: JointRole| leg.joint(r).map_or(1.0, |j| j.axis_sign);
    let (t0, s0) = (leg.thigh_angle0_rad, leg.shin_angle0_rad);
    let angles = [
        sign(JointRole::HipYaw) * yaw,
        sign(JointRole::HipRoll) * roll,
        sign(JointRole::HipPitch) * (t0 - thigh),
        sign(JointRole::Knee) * ((thigh - shin) - (t0 - s0)),
        sign(JointRole::AnklePitch) * (shin - s0),
        -sign(JointRole::AnkleRoll) * roll,
    ];
    (angles, gamma)
}

/// Each joint's angle before the limits: the solver's answer, or what a limit issue says was
/// requested.
fn requested_angles(b: &BipedModel, side: Side, t: &AnkleTarget) -> [f64; 6] {
    let sol = b.solve_leg(side, t).unwrap();
    let mut a = sol.angles_rad;
    for issue in &sol.issues {
        if let IkIssue::JointLimit {
            role,
            requested_rad,
            ..
        } = issue
        {
            a[*role as usize] = *requested_rad;
        }
    }
    a
}

fn check_textbook(b: &BipedModel, side: Side, t: AnkleTarget) -> Result<(), TestCaseError> {
    prop_assume!(t.ankle_in_hip_m.y.hypot(t.ankle_in_hip_m.z) > 1e-6);
    let got = requested_angles(b, side, &t);
    let (want, gamma) = textbook_angles(b, side, &t);
    // At the stretched or folded leg (targets pulled onto the reach land there) an angle's
    // cosine is +-1, where acos turns a rounding of the cosine (1e-16) into 1.5e-8 rad, in
    // either form; elsewhere both agree to 1e-9.
    let singular = gamma < 1e-3 || std::f64::consts::PI - gamma < 1e-3;
    let tol = if singular { 1e-7 } else { 1e-9 };
    for (role, (g, w)) in JointRole::ALL.iter().zip(got.iter().zip(want)) {
        if b.leg(side).joint(*role).is_some() {
            prop_assert!(
                (g - w).abs() < tol,
                "{role}: {g} against the textbook {w} for {t:?}"
            );
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, max_global_rejects: 20_000, ..ProptestConfig::default() })]

    #[test]
    fn default_robot_roundtrip(x in -0.07..0.07f64, y in -0.06..0.06f64, z in -0.178..-0.06f64, left in any::<bool>()) {
        let b = default_biped();
        let side = if left { Side::Left } else { Side::Right };
        check_roundtrip(&b, side, AnkleTarget::new(x, y, z))?;
    }

    #[test]
    fn six_joint_robot_roundtrip(x in -0.08..0.08f64, y in -0.05..0.05f64, z in -0.225..-0.1f64, yaw in -0.4..0.4f64, left in any::<bool>()) {
        let b = biped6();
        let side = if left { Side::Left } else { Side::Right };
        check_roundtrip(&b, side, AnkleTarget { ankle_in_hip_m: Vector3::new(x, y, z), foot_yaw_rad: yaw })?;
    }

    #[test]
    fn op3_layout_robot_roundtrip(x in -0.09..0.09f64, y in -0.07..0.07f64, z in -0.24..-0.02f64, yaw in -0.6..0.6f64, left in any::<bool>()) {
        let b = op3_layout();
        let side = if left { Side::Left } else { Side::Right };
        check_roundtrip(&b, side, AnkleTarget { ankle_in_hip_m: Vector3::new(x, y, z), foot_yaw_rad: yaw })?;
    }

    #[test]
    fn anywhere_gives_finite_limited_flagged_answers(x in -1.0..1.0f64, y in -1.0..1.0f64, z in -1.0..1.0f64, yaw in -4.0..4.0f64, left in any::<bool>(), robot in 0..3u8) {
        let b = match robot { 0 => default_biped(), 1 => biped6(), _ => op3_layout() };
        let side = if left { Side::Left } else { Side::Right };
        check_clamped(&b, side, AnkleTarget { ankle_in_hip_m: Vector3::new(x, y, z), foot_yaw_rad: yaw })?;
    }

    /// Anywhere, reachable or not, above the hip or below: the solver's angles are the
    /// textbook terms' to rounding, quadrant included. (Only a target on the roll axis itself,
    /// where atan2(0, -0) is the sign of a zero, is left out.)
    #[test]
    fn the_fused_angles_are_the_textbook_terms(x in -1.0..1.0f64, y in -1.0..1.0f64, z in -1.0..1.0f64, yaw in -4.0..4.0f64, left in any::<bool>(), robot in 0..3u8) {
        let b = match robot { 0 => default_biped(), 1 => biped6(), _ => op3_layout() };
        let side = if left { Side::Left } else { Side::Right };
        check_textbook(&b, side, AnkleTarget { ankle_in_hip_m: Vector3::new(x, y, z), foot_yaw_rad: yaw })?;
    }

    /// Both legs solved together (side by side in SIMD lanes) give each leg exactly what it
    /// gets alone (which the tests above hold to the textbook), clamps and issues included,
    /// whatever the other leg is asked: one leg out of reach, folded, beyond a limit or inside
    /// its offset changes nothing of the other's. A refused target leaves `q` as it was.
    #[test]
    fn both_legs_together_are_each_leg_alone(
        l in (-0.5..0.5f64, -0.5..0.5f64, -0.5..0.5f64, -2.0..2.0f64),
        r in (-0.5..0.5f64, -0.5..0.5f64, -0.5..0.5f64, -2.0..2.0f64),
        robot in 0..3u8,
        refuse in 0..3u8,
    ) {
        let b = match robot { 0 => default_biped(), 1 => biped6(), _ => op3_layout() };
        let target = |(x, y, z, yaw): (f64, f64, f64, f64)| AnkleTarget {
            ankle_in_hip_m: Vector3::new(x, y, z),
            foot_yaw_rad: yaw,
        };
        let (mut left, mut right) = (target(l), target(r));
        // One case in three: one of the two targets is refused.
        match refuse {
            1 => left.ankle_in_hip_m.y = f64::NAN,
            2 => right.foot_yaw_rad = f64::INFINITY,
            _ => {}
        }
        let before: Vec<f64> = (0..b.robot().dof_count()).map(|i| 0.1 * i as f64).collect();
        let mut q = before.clone();
        let both = b.solve_legs(&left, &right, &mut q);
        let alone = [(Side::Left, left), (Side::Right, right)].map(|(s, t)| b.solve_leg(s, &t));
        match (both, alone) {
            (Ok(issues), [Ok(l), Ok(r)]) => {
                let mut want = before.clone();
                b.write_leg(&l, &mut want);
                b.write_leg(&r, &mut want);
                prop_assert_eq!(
                    q.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                    want.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                    "joint vectors differ for {:?} / {:?}", left, right
                );
                prop_assert_eq!(issues, [l.issues, r.issues].concat());
            }
            (Err(e), [l, r]) => {
                // The error of the first refused leg, left before right; `q` untouched.
                let first = l.err().or(r.err());
                prop_assert_eq!(Some(e.to_string()), first.map(|e| e.to_string()));
                prop_assert_eq!(&q, &before);
            }
            (both, alone) => prop_assert!(false, "together {both:?}, alone {alone:?}"),
        }
    }

    /// The same closer to the hip roll axis than the OP3 layout's 6 mm sideways offset,
    /// where the leg is laid sideways (asin(+-1)).
    #[test]
    fn the_fused_angles_are_the_textbook_terms_inside_the_offset(x in -0.2..0.2f64, y in -0.0055..0.0055f64, z in -0.0055..0.0055f64, left in any::<bool>()) {
        let b = op3_layout();
        let side = if left { Side::Left } else { Side::Right };
        check_textbook(&b, side, AnkleTarget::new(x, y, z))?;
    }
}

#[test]
fn roundtrip_covers_most_of_the_sampled_workspace() {
    // Guards the property tests above against passing by rejecting everything: most of a
    // grid around each robot's stance, a fifth of a leg up, is solved exactly.
    for (name, b) in [
        ("default", default_biped()),
        ("biped6", biped6()),
        ("op3_layout", op3_layout()),
    ] {
        let leg = b.leg(Side::Left);
        let reach = leg.max_reach_m();
        let stance = leg.straight_ankle_in_hip_m();
        let mut exact = 0;
        let n = 20;
        for i in 0..n {
            for k in 0..n {
                let t = AnkleTarget::new(
                    stance.x + reach * (-0.25 + 0.5 * i as f64 / n as f64),
                    stance.y + reach * (-0.2 + 0.4 * k as f64 / n as f64),
                    stance.z + 0.2 * reach,
                );
                exact += usize::from(b.solve_leg(Side::Left, &t).unwrap().is_exact());
            }
        }
        assert!(
            exact > n * n * 9 / 10,
            "{name}: only {exact} of {} exact",
            n * n
        );
    }
}
