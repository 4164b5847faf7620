//! Physics tests of the simulator alone: the default robot in MuJoCo, standing, and refusing
//! bad targets, robots and settings. Walks played into it are walk_eval's tests.
//!
//! Every number asserted here comes out of the physics engine; nothing is mocked.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use ik_solver::{BipedModel, DEFAULT_URDF};
use sim_bridge::{Sim, SimConfig, SimError};

fn model() -> BipedModel {
    BipedModel::from_urdf_str(DEFAULT_URDF, None).unwrap()
}

fn new_sim() -> Sim {
    Sim::from_urdf_str(DEFAULT_URDF, None, &SimConfig::default()).unwrap()
}

#[test]
fn mass_and_standing_contact_force_match_the_urdf() {
    let mut sim = new_sim();
    let urdf_mass = model().robot().total_mass_kg();
    assert!((urdf_mass - 2.3).abs() < 1e-9, "URDF mass {urdf_mass}");
    assert!(
        (sim.total_mass_kg() - urdf_mass).abs() < 1e-9,
        "MuJoCo mass {} kg, URDF {} kg",
        sim.total_mass_kg(),
        urdf_mass
    );
    let zeros = vec![0.0; sim.joint_names().len()];
    sim.stand(&zeros).unwrap();
    sim.step(2.0).unwrap();
    let c = sim.contacts();
    let ratio = c.normal_force_sum_n / sim.weight_n();
    eprintln!(
        "standing 2 s: floor force {:.4} N (L {:.3}, R {:.3}), weight {:.4} N, ratio {ratio:.5}, base z {:.4} m",
        c.normal_force_sum_n,
        c.sole_force_n[0],
        c.sole_force_n[1],
        sim.weight_n(),
        sim.base_pose().translation.z
    );
    assert!(
        (ratio - 1.0).abs() < 0.01,
        "floor carries {ratio} of the weight"
    );
    assert_eq!(c.loaded, [true, true]);
    assert!(c.other_force_n == 0.0);
    assert!(c.cop_margin_m().unwrap() > 0.01);
    assert!(sim.fallen().is_none());
    // Straight legs: base 0.24 m above the soles (URDF), less a little sag and penetration.
    let z = sim.base_pose().translation.z;
    assert!((0.235..0.2405).contains(&z), "base at {z} m");
}

#[test]
fn a_non_finite_target_is_refused_by_joint_name() {
    let mut sim = new_sim();
    let mut q = vec![0.0; sim.joint_names().len()];
    sim.stand(&q).unwrap();
    let knee = sim
        .joint_names()
        .iter()
        .position(|n| n == "l_knee")
        .unwrap();
    q[knee] = f64::NAN;
    let err = sim.set_targets(&q).unwrap_err();
    assert!(matches!(err, SimError::NonFinite { ref joint, .. } if joint == "l_knee"));
    assert!(err.to_string().contains("l_knee"), "{err}");
    q[knee] = f64::INFINITY;
    assert!(
        sim.set_targets(&q)
            .unwrap_err()
            .to_string()
            .contains("l_knee")
    );
    // Nothing changed.
    assert!(sim.targets_rad().iter().all(|&t| t == 0.0));
    let short = sim.set_targets(&[0.0; 3]).unwrap_err();
    assert!(matches!(
        short,
        SimError::JointCount {
            expected: 20,
            got: 3,
            ..
        }
    ));
}

#[test]
fn broken_robots_give_errors() {
    let cfg = SimConfig::default();
    let err = |urdf: &str| Sim::from_urdf_str(urdf, None, &cfg).unwrap_err();
    let e = err("this is not xml");
    assert!(matches!(e, SimError::Model(_)), "{e}");
    let e = err(&DEFAULT_URDF[..DEFAULT_URDF.len() / 2]);
    assert!(matches!(e, SimError::Model(_)), "{e}");
    let e = err(r#"<robot name="r"><link name="only"/></robot>"#);
    assert!(matches!(e, SimError::Model(_)), "{e}");
    let e = err(&DEFAULT_URDF.replace("<robot name=\"biped20\">", "<robot name=\"biped20\">\0"));
    assert!(
        e.to_string().contains("NUL") || matches!(e, SimError::Model(_)),
        "{e}"
    );
    // A URDF the robot model accepts but MuJoCo cannot build (a mesh file that is not there).
    let e = err(&DEFAULT_URDF.replace(
        r#"<box size="0.07 0.11 0.1"/>"#,
        r#"<mesh filename="no_such_torso.stl"/>"#,
    ));
    eprintln!("{e}");
    assert!(matches!(e, SimError::Mujoco { .. }), "{e}");
    assert!(e.to_string().contains("no_such_torso"), "{e}");
    // A joint the URDF gives no torque: named.
    let e = err(&DEFAULT_URDF.replacen(r#"effort="1.5""#, r#"effort="0""#, 1));
    assert!(
        matches!(e, SimError::TorqueLimit { ref joint, .. } if joint == "l_hip_roll"),
        "{e}"
    );
    // ... unless the config gives one.
    let with_limit = SimConfig {
        torque_limit_nm: Some(1.5),
        ..SimConfig::default()
    };
    Sim::from_urdf_str(
        &DEFAULT_URDF.replacen(r#"effort="1.5""#, r#"effort="0""#, 1),
        None,
        &with_limit,
    )
    .unwrap();
    // Bad settings are named.
    let bad = SimConfig {
        kp_nm_per_rad: -1.0,
        ..SimConfig::default()
    };
    let e = Sim::from_urdf_str(DEFAULT_URDF, None, &bad).unwrap_err();
    assert!(e.to_string().contains("kp_nm_per_rad"), "{e}");
    let e = SimConfig::from_yaml_str("timestep_s: 0.001\nfrction: 1.0").unwrap_err();
    assert!(e.to_string().contains("frction"), "{e}");
    let e = SimConfig::from_yaml_str("timestep_s: 0.5").unwrap_err();
    assert!(e.to_string().contains("timestep_s"), "{e}");
}

/// The base's IMU against what it must read by hand: standing still, gravity's 9.81 m/s²
/// up the base's z and no rotation; dropped from 1 m tilted by 0.4 rad about x, nothing at
/// all from the accelerometer (free fall) whatever the tilt; toppling over from a tilted
/// stance, the gyroscope's rate is the rate at which the base's orientation turns (taken
/// from the base pose, tick to tick).
#[test]
fn the_imu_reads_gravity_standing_nothing_falling_and_the_turn_of_the_base() {
    let mut sim = new_sim();
    let zeros = vec![0.0; sim.joint_names().len()];
    let g = 9.81; // MuJoCo's default gravity, which the built-in robot's model keeps.
    sim.stand(&zeros).unwrap();
    sim.step(1.0).unwrap();
    let imu = sim.imu();
    eprintln!("standing: {imu:?}");
    let f = imu.specific_force_m_s2;
    assert!(f.x.abs() < 0.05 && f.y.abs() < 0.05, "standing: {f}");
    assert!((f.z - g).abs() < 0.05, "standing: {f}");
    assert!(
        imu.angular_velocity_rad_s.norm() < 0.01,
        "standing: {imu:?}"
    );
    assert!(imu.orientation.angle() < 0.01);

    let tilt = nalgebra::UnitQuaternion::from_euler_angles(0.4, 0.0, 0.0);
    let high = nalgebra::Isometry3::from_parts(nalgebra::Translation3::new(0.0, 0.0, 1.0), tilt);
    sim.reset(&high, &zeros).unwrap();
    sim.step(0.05).unwrap();
    let imu = sim.imu();
    eprintln!("falling: {imu:?}");
    assert!(imu.specific_force_m_s2.norm() < 1e-6, "falling: {imu:?}");
    assert!(imu.orientation.angle_to(&tilt) < 1e-6);

    // Standing on the sole edges, tilted 0.3 rad about x: the robot topples sideways.
    sim.stand(&zeros).unwrap();
    let start = sim.base_pose();
    let tipped = nalgebra::Isometry3::from_parts(
        nalgebra::Translation3::new(0.0, 0.0, start.translation.z + 0.05),
        nalgebra::UnitQuaternion::from_euler_angles(0.3, 0.0, 0.0),
    );
    sim.reset(&tipped, &zeros).unwrap();
    sim.step(0.3).unwrap();
    let h = 0.002;
    let before = sim.base_pose().rotation;
    let w0 = sim.imu().angular_velocity_rad_s;
    sim.step(h).unwrap();
    let after = sim.base_pose().rotation;
    let w1 = sim.imu().angular_velocity_rad_s;
    // The turn over h in the base's own frame: before⁻¹·after = exp(ω h).
    let turn = (before.inverse() * after).scaled_axis() / h;
    let w = (w0 + w1) / 2.0;
    eprintln!("toppling: gyro {w}, from the poses {turn}");
    assert!(w.norm() > 0.2, "not toppling: {w}");
    assert!(
        (w - turn).norm() < 0.02 * w.norm(),
        "gyro {w}, poses {turn}"
    );
}
