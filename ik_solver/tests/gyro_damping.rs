//! Gyro damping offsets against values worked out by hand on the default robot, whose leg
//! joints all turn about +x (roll) or +y (pitch, knee) at zero angles (config/biped.urdf).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use ik_solver::{BipedModel, DEFAULT_URDF, Side};
use nalgebra::Vector3;

fn model() -> BipedModel {
    BipedModel::from_urdf_str(DEFAULT_URDF, None).unwrap()
}

fn set(model: &BipedModel, q: &mut [f64], name: &str, v: f64) {
    q[model.robot().dof_index(name).unwrap()] = v;
}

/// The offset of every leg joint, left leg then right, hip to ankle (roll, pitch, knee,
/// ankle pitch, ankle roll on this robot), by name.
fn offsets(model: &BipedModel, q: &[f64], w: Vector3<f64>, gain_s: f64) -> Vec<(String, f64)> {
    let d = model.gyro_damping_rad(q, &w, gain_s).unwrap();
    Side::BOTH
        .iter()
        .flat_map(|&s| model.leg(s).joints.iter().flatten())
        .map(|j| (j.name.clone(), d[j.dof]))
        .collect()
}

fn close(got: &[(String, f64)], want: &[f64; 10]) {
    assert_eq!(got.len(), 10, "{got:?}");
    for ((n, g), w) in got.iter().zip(want) {
        assert!((g - w).abs() < 1e-12, "{n}: {g} rad, by hand {w} rad");
    }
}

#[test]
fn standing_on_both_feet_every_leg_joint_damps_its_own_axis() {
    let m = model();
    let q = vec![0.0; m.robot().dof_count()];
    // 0.02 s x (0.5, -0.2, 0.1) rad/s: roll joints 0.01, pitch joints -0.004; no joint
    // turns about z, so the yaw rate asks nothing.
    let got = offsets(&m, &q, Vector3::new(0.5, -0.2, 0.1), 0.02);
    close(
        &got,
        &[
            0.01, -0.004, -0.004, -0.004, 0.01, 0.01, -0.004, -0.004, -0.004, 0.01,
        ],
    );
    // Arms and head are not damped.
    let d = m
        .gyro_damping_rad(&q, &Vector3::new(0.5, -0.2, 0.1), 0.02)
        .unwrap();
    for n in ["l_shoulder_pitch", "l_shoulder_roll", "l_elbow"] {
        assert_eq!(d[m.robot().dof_index(n).unwrap()], 0.0, "{n}");
    }
}

#[test]
fn a_rolled_stance_turns_the_pitch_axes_with_it() {
    let m = model();
    let mut q = vec![0.0; m.robot().dof_count()];
    // Both hips rolled 0.1 rad (ankles back, feet level): the pitch and knee axes below
    // the hip roll point along (0, cos 0.1, sin 0.1) in the base frame; the ankle roll axis
    // along (1, 0, 0) again after the ankle's -0.1 rad. The yaw rate (about the base's z)
    // is the walk's turn, left out: only cos 0.1 · ω_y is damped.
    for side in ["l", "r"] {
        set(&m, &mut q, &format!("{side}_hip_roll"), 0.1);
        set(&m, &mut q, &format!("{side}_ankle_roll"), -0.1);
    }
    let (wy, wz) = (0.3, -0.4);
    let g = 0.01;
    let pitch = g * 0.1f64.cos() * wy;
    let got = offsets(&m, &q, Vector3::new(0.0, wy, wz), g);
    close(
        &got,
        &[0.0, pitch, pitch, pitch, 0.0, 0.0, pitch, pitch, pitch, 0.0],
    );
}

#[test]
fn only_the_leg_on_the_floor_is_damped() {
    let m = model();
    let mut q = vec![0.0; m.robot().dof_count()];
    // The right foot lifted: its knee bent, hip and ankle pitched back so the sole stays
    // level; the left leg straight carries the robot.
    set(&m, &mut q, "r_hip_pitch", -0.3);
    set(&m, &mut q, "r_knee", 0.6);
    set(&m, &mut q, "r_ankle_pitch", -0.3);
    let got = offsets(&m, &q, Vector3::new(0.5, -0.2, 0.0), 0.02);
    close(
        &got,
        &[0.01, -0.004, -0.004, -0.004, 0.01, 0.0, 0.0, 0.0, 0.0, 0.0],
    );
}

#[test]
fn a_non_finite_rate_or_gain_is_refused_by_name() {
    let m = model();
    let q = vec![0.0; m.robot().dof_count()];
    let e = m
        .gyro_damping_rad(&q, &Vector3::new(0.0, f64::NAN, 0.0), 0.01)
        .unwrap_err()
        .to_string();
    assert!(e.contains("body_rate_rad_s") && e.contains("NaN"), "{e}");
    let e = m
        .gyro_damping_rad(&q, &Vector3::zeros(), -1.0)
        .unwrap_err()
        .to_string();
    assert!(e.contains("gain_s") && e.contains("-1"), "{e}");
}
