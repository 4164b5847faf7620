//! The MJCF scene of sim_bridge's tests (sim_bridge/tests/data/biped20_scene.xml, written by
//! hand, not generated from the URDF), tied to config/biped.urdf by a joint map, walks the
//! default plan.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::path::PathBuf;

use gait_planner::{GaitParams, GaitPlanner, WalkRequest};
use ik_solver::{BipedModel, DEFAULT_URDF};
use sim_bridge::{JointMap, Sim, SimConfig};
use walk_eval::{PlayOptions, run_plan};

const STEPS: u32 = 20;

fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../sim_bridge/tests/data")
        .join(name)
}

fn map() -> JointMap {
    JointMap::from_yaml_file(data("biped20_scene_map.yaml")).unwrap()
}

#[test]
fn the_scene_robot_walks_twenty_steps_with_a_joint_map() {
    let mut sim = Sim::from_mjcf_file(
        data("biped20_scene.xml"),
        &map(),
        DEFAULT_URDF,
        None,
        &SimConfig::default(),
    )
    .unwrap();
    // The scene's physics, not the defaults of SimConfig: its servos and step.
    let cfg = sim.config();
    assert_eq!(cfg.kp_nm_per_rad, 30.0);
    assert_eq!(cfg.kv_nm_s_per_rad, 0.25);
    assert_eq!(cfg.torque_limit_nm, Some(1.5));
    assert_eq!(cfg.armature_kg_m2, 0.005);
    assert_eq!(cfg.timestep_s, 0.001);
    assert_eq!(cfg.friction, 1.0);
    // Joint vectors stay in the URDF's names and order.
    let model = BipedModel::from_urdf_str(DEFAULT_URDF, None).unwrap();
    let urdf_names: Vec<&str> = model.robot().dof_names().collect();
    assert_eq!(sim.joint_names(), urdf_names.as_slice());
    // Same masses as the URDF (2.3 kg, the sum of the link masses in its header comment).
    assert!(
        (sim.total_mass_kg() - 2.3).abs() < 1e-9,
        "{}",
        sim.total_mass_kg()
    );

    let mut planner = GaitPlanner::new(model, GaitParams::default()).unwrap();
    let step_m = planner.config().step_length_m;
    let plan = planner.plan(WalkRequest::Steps(STEPS)).unwrap();
    let report = run_plan(&mut sim, &plan, &PlayOptions::default()).unwrap();
    eprintln!("MJCF scene, 20-step walk:\n{report:#?}");
    common::assert_walked_well(&report, f64::from(STEPS) * step_m);
}

/// The OP3-layout test robot (tests/data/make_op3_layout.py): hip yaw and roll joints apart,
/// the pitch plane and the ankle roll axis offset sideways, read from its URDF as it stands,
/// walks 10 steps in its own MuJoCo scene (other names, its own servos) through its joint map.
#[test]
fn the_op3_layout_robot_walks_ten_steps_in_its_own_scene() {
    const STEPS: u32 = 10;
    let tests = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/data");
    let urdf = std::fs::read_to_string(tests.join("op3_layout.urdf")).unwrap();
    let map = JointMap::from_yaml_file(tests.join("op3_layout_scene_map.yaml")).unwrap();
    let mut sim = Sim::from_mjcf_file(
        tests.join("op3_layout_scene.xml"),
        &map,
        &urdf,
        None,
        &SimConfig::default(),
    )
    .unwrap();
    // The scene's servos (make_op3_layout.py), not SimConfig's defaults; the URDF's masses.
    assert_eq!(sim.config().kp_nm_per_rad, 40.0);
    assert_eq!(sim.config().torque_limit_nm, Some(3.0));
    assert!(
        (sim.total_mass_kg() - 2.94).abs() < 1e-9,
        "{}",
        sim.total_mass_kg()
    );

    let model = BipedModel::from_urdf_str(&urdf, None).unwrap();
    let mut planner = GaitPlanner::new(model, GaitParams::default()).unwrap();
    let step_m = planner.config().step_length_m;
    let plan = planner.plan(WalkRequest::Steps(STEPS)).unwrap();
    let report = run_plan(&mut sim, &plan, &PlayOptions::default()).unwrap();
    eprintln!("OP3-layout scene, {STEPS}-step walk:\n{report:#?}");
    common::assert_walked_well(&report, f64::from(STEPS) * step_m);
    assert!(
        report.max_tilt_deg < 5.0,
        "tilt {} deg",
        report.max_tilt_deg
    );
    assert!(
        report.max_foot_slip_m < 0.005,
        "a foot slipped {} m",
        report.max_foot_slip_m
    );
}
