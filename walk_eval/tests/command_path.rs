//! The fleet's command path in physics: joint vectors through the joint bridge, compensated
//! for servo sag by the bridge from the commanded pose alone (no plan, no support phase),
//! onto the simulated robot.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use gait_planner::{GaitParams, GaitPlanner, Support, WalkRequest};
use ik_solver::{BipedModel, DEFAULT_URDF, Side, Stance};
use joint_bridge::{BridgeConfig, JointBridge, JointSpec, SagCompensation};
use sim_bridge::{SimBackend, SimConfig, static_compensation_rad};
use walk_eval::WalkMonitor;

fn model() -> BipedModel {
    BipedModel::from_urdf_str(DEFAULT_URDF, None).unwrap()
}

/// The stance the bridge reads from a pose agrees with the planner's support wherever a
/// swing foot is off the floor by more than the tolerance, and the compensation it computes
/// then equals the one computed from the plan's support and CoM.
#[test]
fn compensation_from_the_pose_matches_the_plan() {
    let model = model();
    let plan = GaitPlanner::new(model.clone(), GaitParams::default())
        .unwrap()
        .plan(WalkRequest::Steps(4))
        .unwrap();
    let kp = SimConfig::default().kp_nm_per_rad;
    let (mut compared_single, mut compared_double) = (0, 0);
    for s in &plan {
        let poses = model
            .robot()
            .link_poses(&s.base_world, &s.joints_rad)
            .unwrap();
        let stance = model.stance_of_pose(&poses);
        let from_plan = static_compensation_rad(&model, &s.static_pose(), kp).unwrap();
        let from_pose = model.sag_compensation_rad(&s.joints_rad, kp).unwrap();
        let worst = from_plan
            .iter()
            .zip(&from_pose)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        match (s.support, stance) {
            (Support::Left, Stance::Single(Side::Left))
            | (Support::Right, Stance::Single(Side::Right)) => {
                compared_single += 1;
                assert!(worst < 1e-9, "t {}: {worst} rad apart", s.t_s);
            }
            (Support::Double, Stance::Double) => {
                compared_double += 1;
                assert!(worst < 1e-9, "t {}: {worst} rad apart", s.t_s);
            }
            // A swing foot just lifting or landing: the pose says double support while the
            // plan already says single. The CoM is then over the stance sole, so the split
            // gives (nearly) all the weight to it.
            (Support::Left | Support::Right, Stance::Double) => {
                assert!(worst < 2e-3, "t {}: {worst} rad apart at lift-off", s.t_s);
            }
            (support, stance) => panic!("t {}: plan {support:?}, pose {stance:?}", s.t_s),
        }
    }
    assert!(compared_single > 100 && compared_double > 100);
}

/// The default walk, played as joint commands at 100 Hz through the joint bridge (URDF
/// limits, velocity limits, the bridge's own sag compensation) onto the simulated robot: it
/// walks. Without the compensation the same commands make it fall.
#[test]
fn the_bridge_walks_the_robot_with_its_own_compensation() {
    let model = model();
    let mut planner = GaitPlanner::new(model.clone(), GaitParams::default()).unwrap();
    let step_m = planner.config().step_length_m;
    let steps = 8;
    let plan = planner.plan(WalkRequest::Steps(steps)).unwrap();
    let joints = JointSpec::from_robot(model.robot());
    let names: Vec<String> = joints.iter().map(|j| j.name.clone()).collect();
    let walk = |compensate: bool| {
        let backend = SimBackend::new(DEFAULT_URDF, SimConfig::default())
            .with_initial_positions(plan[0].joints_rad.clone());
        let mut bridge = JointBridge::new(backend, joints.clone(), BridgeConfig::default());
        if compensate {
            let c =
                SagCompensation::new(model.clone(), SimConfig::default().kp_nm_per_rad, &joints)
                    .unwrap();
            bridge = bridge.with_sag_compensation(c);
        }
        bridge.start().unwrap();
        let mut monitor = None;
        for s in &plan {
            bridge.command(s.t_s, &names, &s.joints_rad);
            let (reading, events) = bridge.tick(s.t_s);
            reading.unwrap();
            assert!(events.is_empty(), "{events:?}");
            let sim = bridge.backend().sim().unwrap();
            let m = monitor.get_or_insert_with(|| WalkMonitor::new(sim));
            m.observe(sim, s.phase);
            if m.fell() {
                break;
            }
        }
        let sim = bridge.backend().sim().unwrap();
        monitor.unwrap().report(sim, [steps as f64 * step_m, 0.0])
    };
    let with = walk(true);
    eprintln!("with the bridge's compensation: {with:#?}");
    assert!(with.fell.is_none(), "{:?}", with.fell);
    assert!(with.max_tilt_deg < 10.0);
    assert!((with.distance_m - with.planned_distance_m).abs() < 0.1 * with.planned_distance_m);
    let without = walk(false);
    eprintln!("without: fell {:?}", without.fell);
    assert!(
        without.fell.is_some(),
        "uncompensated servos should sag and fall"
    );
}
