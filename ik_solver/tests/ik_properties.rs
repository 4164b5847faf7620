//! FK(IK(target)) == target and the sole stays level, over the reachable workspace; outside
//! it, every answer is finite, within limits, and flagged.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::*;
use ik_solver::{AnkleTarget, BipedModel, Side};
use nalgebra::Vector3;
use proptest::prelude::*;

fn check_roundtrip(b: &BipedModel, side: Side, t: AnkleTarget) -> Result<(), TestCaseError> {
    let sol = b.solve_leg(side, &t).unwrap();
    prop_assume!(sol.is_exact());
    let mut q = vec![0.0; b.robot().dof_count()];
    b.write_leg(&sol, &mut q);
    let got = b.ankles_in_hips(&q).unwrap()[side.index()];
    let err = (got - t.ankle_in_hip_m).norm();
    prop_assert!(err < 1e-9, "FK(IK) off by {err} m for {:?}", t);
    let tilt = foot_tilt_rad(b, side, &q, t.foot_yaw_rad);
    prop_assert!(tilt < 1e-9, "sole tilted by {tilt} rad for {:?}", t);
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
