//! A planner restarted while the robot is not standing: the targets that hold a measured
//! pose, and the guard that decides from measured joint states.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::*;
use gait_planner::standing::targets_holding;
use gait_planner::{GaitParams, GaitPlanner, PhaseKind, StandGuard, Standing, Stride, WalkRequest};
use ik_solver::{BipedModel, Side};

/// The leg joints of `q` by name, as a joint_states message carries them.
fn joint_state(model: &BipedModel, q: &[f64]) -> (Vec<String>, Vec<f64>) {
    let mut names = Vec::new();
    let mut positions = Vec::new();
    for side in Side::BOTH {
        for (_, j) in model.leg(side).present() {
            names.push(j.name.clone());
            positions.push(q[j.dof]);
        }
    }
    (names, positions)
}

/// A turning walk's sample in the middle of its first full swing, and the idle sample.
fn mid_swing_and_idle(model: &BipedModel) -> (Vec<f64>, Vec<f64>) {
    let mut p = GaitPlanner::new(model.clone(), GaitParams::slow(model)).unwrap();
    let idle = p.update(0.0).unwrap().joints_rad;
    let c = p.config().clone();
    let turn = if model.leg(Side::Left).has_yaw() {
        c.turn_step_rad
    } else {
        0.0
    };
    p.set_stride(Stride {
        forward_m: c.step_length_m,
        left_m: 0.0,
        turn_rad: turn,
    })
    .unwrap();
    p.request(WalkRequest::Steps(4));
    let dt = c.dt_s();
    let mut k = 1u32;
    loop {
        let s = p.update(f64::from(k) * dt).unwrap();
        if s.phase == PhaseKind::Step && s.progress >= 0.5 {
            return (s.joints_rad, idle);
        }
        k += 1;
        assert!(k < 100_000, "no full swing");
    }
}

#[test]
fn the_targets_holding_a_pose_give_its_leg_angles_back() {
    for model in [default_model(), biped6_model()] {
        let (q, _) = mid_swing_and_idle(&model);
        let targets = targets_holding(&model, &q).unwrap();
        let mut back = vec![0.0; q.len()];
        let issues = model
            .solve_legs(&targets[0], &targets[1], &mut back)
            .unwrap();
        assert!(issues.is_empty(), "{issues:?}");
        for side in Side::BOTH {
            for (role, j) in model.leg(side).present() {
                assert!(
                    (back[j.dof] - q[j.dof]).abs() < 1e-9,
                    "{} {role:?}: {} back, {} held",
                    model.robot().name(),
                    back[j.dof],
                    q[j.dof]
                );
            }
        }
    }
}

#[test]
fn a_robot_standing_in_the_idle_pose_clears_the_guard() {
    let model = default_model();
    let (_, idle) = mid_swing_and_idle(&model);
    let mut guard = StandGuard::new(0.05);
    assert!(
        guard
            .refusal()
            .unwrap()
            .contains("no measured joint_states")
    );
    // Within the tolerance: 0.04 rad on one knee.
    let mut q = idle.clone();
    let knee = model
        .leg(Side::Left)
        .joint(ik_solver::JointRole::Knee)
        .unwrap();
    q[knee.dof] += 0.04;
    let (names, positions) = joint_state(&model, &q);
    let said = guard.measured(&model, &idle, &names, &positions).unwrap();
    assert!(said.contains("walk commands taken"), "{said}");
    assert!(guard.clear());
    assert_eq!(guard.refusal(), None);
    assert!(guard.held_targets().is_none());
}

#[test]
fn a_robot_caught_mid_swing_is_held_where_it_is_and_walks_are_refused() {
    let model = default_model();
    let (mid, idle) = mid_swing_and_idle(&model);
    let mut guard = StandGuard::new(0.05);
    let (names, positions) = joint_state(&model, &mid);
    let said = guard.measured(&model, &idle, &names, &positions).unwrap();
    // The farthest leg joint, found here by a plain scan.
    let (far_name, far) = names
        .iter()
        .zip(&positions)
        .map(|(n, &v)| {
            let j = model.robot().dof_index(n).unwrap();
            (n.clone(), (v - idle[j]).abs())
        })
        .fold((String::new(), 0.0), |a, b| if b.1 > a.1 { b } else { a });
    assert!(far > 0.1, "mid-swing is far from standing: {far}");
    assert_eq!(
        guard.state(),
        &Standing::No {
            joint: far_name.clone(),
            off_rad: far
        }
    );
    assert!(
        said.contains(&far_name) && said.contains("holding the measured pose"),
        "{said}"
    );
    assert!(guard.refusal().unwrap().contains("restart the fleet"));
    // It holds the first measured pose: its targets give the mid-swing angles back.
    let held = *guard.held_targets().unwrap();
    let mut back = vec![0.0; mid.len()];
    model.solve_legs(&held[0], &held[1], &mut back).unwrap();
    for (n, &v) in names.iter().zip(&positions) {
        let j = model.robot().dof_index(n).unwrap();
        assert!((back[j] - v).abs() < 1e-9, "{n}");
    }
    // Said once; a later state that still does not stand changes nothing.
    assert_eq!(guard.measured(&model, &idle, &names, &positions), None);
    assert_eq!(*guard.held_targets().unwrap(), held);
    // Stood up (by a fleet restart's ramp, or by hand with the torque off): clear.
    let (names, positions) = joint_state(&model, &idle);
    assert!(guard.measured(&model, &idle, &names, &positions).is_some());
    assert!(guard.clear());
}

#[test]
fn a_joint_state_without_every_leg_joint_or_with_nan_decides_nothing() {
    let model = default_model();
    let (mid, idle) = mid_swing_and_idle(&model);
    let mut guard = StandGuard::new(0.05);
    let (mut names, mut positions) = joint_state(&model, &mid);
    names.pop();
    positions.pop();
    assert_eq!(guard.measured(&model, &idle, &names, &positions), None);
    assert_eq!(guard.state(), &Standing::Unknown);
    let (names, mut positions) = joint_state(&model, &idle);
    positions[2] = f64::NAN;
    assert_eq!(guard.measured(&model, &idle, &names, &positions), None);
    assert_eq!(guard.state(), &Standing::Unknown);
    assert!(guard.held_targets().is_none());
}
