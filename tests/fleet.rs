//! The fleet against a real ROS 2 Jazzy peer: rclpy with Fast DDS from PyPI, using the
//! `biped_msgs` types built from `msgs/` (scripts/setup-python-env). Each test runs the
//! peer and the nodes in a private network namespace with only loopback, on its own
//! ROS_DOMAIN_ID, with ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST: nothing leaves the machine.
//! The Python peer acts and records (tests/python/fleet_peer.py); the assertions are here.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use common::{bin_dir, json_of, python_in_netns};
use gait_planner::{GaitParams, GaitPlanner, WalkRequest};
use ik_solver::{BipedModel, Side};
use serde_json::Value;
use std::path::PathBuf;

/// Runs a peer scenario in a new network namespace and returns what it recorded.
fn peer(scenario: &str, domain_id: u32) -> Value {
    peer_with_params(scenario, domain_id, None)
}

/// A slow walk's parameter file in tests/data (the defaults before #16): `gait_slow.yaml`
/// (the default robot) or `biped6_slow.yaml` (the six-joint robot), for the scenarios whose
/// expectations are computed by hand for that walk.
fn slow_params(file: &str) -> PathBuf {
    common::root().join("tests/data").join(file)
}

/// [`peer`] with every node (or `biped launch`) given the parameter file `params`.
fn peer_with_params(scenario: &str, domain_id: u32, params: Option<PathBuf>) -> Value {
    let mut cmd = python_in_netns("fleet_peer.py", domain_id);
    cmd.arg(scenario).arg(bin_dir());
    if let Some(p) = params {
        cmd.arg(p);
    }
    json_of(
        cmd.env(
            "BIPED_TEST_LOG_DIR",
            std::env::temp_dir().join(format!("biped-launch-{domain_id}-{}", std::process::id())),
        ),
        &format!("peer scenario {scenario}"),
    )
}

fn xy(p: &Value) -> [f64; 2] {
    [p[0].as_f64().unwrap(), p[1].as_f64().unwrap()]
}

/// Distance from `p` to the segment `a`-`b`.
fn segment_distance(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let t = (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / (dx * dx + dy * dy)).clamp(0.0, 1.0);
    ((p[0] - a[0] - t * dx).powi(2) + (p[1] - a[1] - t * dy).powi(2)).sqrt()
}

/// The gait/markers arrays rclpy decoded during the walk: one per tick of the plan, in the
/// walk frame; the support polygon they draw (a closed, counter-clockwise line) holds the
/// CoM sphere with the margin disc inside it at every tick; the swinging foot's landing is
/// drawn during each swing, where the plan has that foot once the swing is over, and
/// deleted otherwise.
fn assert_markers_draw_the_balance(
    v: &Value,
    walk: &[(i64, &str)],
    plan: &[gait_planner::GaitSample],
    model: &BipedModel,
) {
    let by_stamp: std::collections::HashMap<i64, &Value> = v["markers"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|m| m["stamp"].is_i64())
        .map(|m| (m["stamp"].as_i64().unwrap(), m))
        .collect();
    let mut swing_end: Option<usize> = None;
    for (k, ((stamp, phase), row)) in walk.iter().zip(plan).enumerate() {
        let m = by_stamp
            .get(stamp)
            .unwrap_or_else(|| panic!("tick {k} ({phase}): no gait/markers"));
        assert_eq!(m["frame"], "odom");
        let poly = &m["support_polygon"][0];
        assert_eq!(poly["type"], 4, "a LINE_STRIP");
        let pts: Vec<[f64; 2]> = poly["points"].as_array().unwrap().iter().map(xy).collect();
        assert!(
            pts.len() >= 5 && pts[0] == pts[pts.len() - 1],
            "closed: {pts:?}"
        );
        let com = &m["com"][0];
        assert_eq!(com["type"], 2, "a SPHERE");
        let c = xy(&com["xyz"]);
        let radius = m["com_margin"][0]["scale"][0].as_f64().unwrap() / 2.0;
        assert!(radius > 0.0);
        for w in pts.windows(2) {
            let (a, b) = (w[0], w[1]);
            let cross = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
            assert!(cross > 0.0, "tick {k} ({phase}): CoM {c:?} outside {pts:?}");
            assert!(
                segment_distance(c, a, b) >= radius - 1e-9,
                "tick {k} ({phase}): CoM {c:?} within {radius} m of the edge {a:?}-{b:?}"
            );
        }
        // The swing's last tick.
        if swing_end.is_none_or(|e| e < k) {
            swing_end = (k..plan.len())
                .take_while(|&j| plan[j].phase == row.phase)
                .last();
        }
        let steps = m["footsteps"].as_array().unwrap();
        let drawn: Vec<&Value> = steps.iter().filter(|f| f["action"] == 0).collect();
        if row.phase.is_swing() {
            assert_eq!(drawn.len(), 1, "tick {k} ({phase}): {steps:?}");
            let side = if drawn[0]["id"] == 0 {
                Side::Left
            } else {
                Side::Right
            };
            assert_eq!(row.support, gait_planner::Support::on(side.other()));
            // The first tick after the swing: the foot down where the swing took it.
            let end = &plan[swing_end.unwrap() + 1];
            let ankle = end.ankles_world_m[side.index()];
            let want = model
                .leg(side)
                .sole
                .corners([ankle.x, ankle.y], end.feet_yaw_rad[side.index()]);
            let got: Vec<[f64; 2]> = drawn[0]["points"]
                .as_array()
                .unwrap()
                .iter()
                .map(xy)
                .collect();
            for (g, w) in got.iter().zip(&want) {
                assert!(
                    (g[0] - w[0]).abs() < 1e-9 && (g[1] - w[1]).abs() < 1e-9,
                    "tick {k} ({phase}): landing drawn at {got:?}, the foot lands at {want:?}"
                );
            }
        } else {
            assert!(drawn.is_empty(), "tick {k} ({phase}): {steps:?}");
            assert_eq!(steps.len(), 2, "both footsteps deleted");
        }
    }
}

/// A `/joint_commands` message the peer recorded: the leg joints `legs` (name, dof) by name,
/// in order, each position within `tol` of `want_rad` (the whole robot's joint vector).
fn assert_leg_command(
    cmd: &Value,
    legs: &[(String, usize)],
    want_rad: &[f64],
    tol: f64,
    what: &str,
) {
    let names: Vec<&str> = cmd["name"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        legs.iter().map(|(n, _)| n.as_str()).collect::<Vec<_>>(),
        "{what}: joint names"
    );
    for (i, (name, dof)) in legs.iter().enumerate() {
        let got = cmd["position"][i].as_f64().unwrap();
        let want = want_rad[*dof];
        assert!(
            (got - want).abs() < tol,
            "{what}, joint {name}: received {got}, expected {want}"
        );
    }
}

/// The planner said on /rosout that the cmd_vel stream stopped and it ended the walk.
fn assert_timed_out(v: &Value) {
    assert!(
        rosout_has(
            v,
            "gait_planner",
            &["no command for 0.5 s", "ending the walk"]
        ),
        "no timeout message"
    );
}

/// The nodes were seen, commands and states flowed, and the walk moved the joints.
fn assert_walk_moved(v: &Value) {
    assert_eq!(v["nodes_seen"], true);
    assert_eq!(
        v["flowing"], true,
        "joint commands and states never flowed: {}",
        v["flow_diag"]
    );
    assert_eq!(v["moving"], true, "the walk never moved the joints");
}

/// A recorded joint_states message's positions (rad).
fn state_positions(s: &Value) -> Vec<f64> {
    s["position"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// A recorded joint_states message's stamp (the bridge's clock, s).
fn state_t(s: &Value) -> f64 {
    s["t"].as_f64().unwrap()
}

fn rosout_has(v: &Value, node: &str, needles: &[&str]) -> bool {
    v["rosout"].as_array().unwrap().iter().any(|m| {
        let msg = m["msg"].as_str().unwrap_or_default();
        m["name"].as_str().unwrap_or_default().ends_with(node)
            && needles.iter().all(|n| msg.contains(n))
    })
}

/// The phases (stamp, name) of the first walk in the recorded phases from index `from`, its
/// first non-idle tick to its last, and the joint commands stamped as those ticks.
fn walk_and_commands(v: &Value, from: usize) -> (Vec<(i64, &str)>, Vec<&Value>) {
    let walk: Vec<(i64, &str)> = v["phases"].as_array().unwrap()[from..]
        .iter()
        .map(|p| (p["stamp"].as_i64().unwrap(), p["phase"].as_str().unwrap()))
        .skip_while(|(_, ph)| *ph == "idle")
        .take_while(|(_, ph)| *ph != "idle")
        .collect();
    let stamps: std::collections::HashSet<i64> = walk.iter().map(|(s, _)| *s).collect();
    let commands = v["commands"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| stamps.contains(&c["stamp"].as_i64().unwrap()))
        .collect();
    (walk, commands)
}

/// Each joint command of a walk against the plan's joints at its tick, and the phases.
fn assert_walk_is_plan(
    walk: &[(i64, &str)],
    commands: &[&Value],
    plan: &[gait_planner::GaitSample],
    legs: &[(String, usize)],
) {
    assert_eq!(walk.len(), plan.len(), "phase ticks received vs planned");
    assert_eq!(
        commands.len(),
        plan.len(),
        "joint commands received for the walk's ticks (none lost)"
    );
    for (k, (cmd, row)) in commands.iter().zip(plan).enumerate() {
        assert_eq!(walk[k].1, row.phase.as_str(), "tick {k}: phase");
        let tick = format!("tick {k} ({})", row.phase);
        assert_leg_command(cmd, legs, &row.joints_rad, 1e-6, &tick);
    }
}

#[test]
fn an_rclpy_peer_walks_the_robot_and_gets_the_offline_plan() {
    let v = peer_with_params("walk", 61, Some(slow_params("gait_slow.yaml")));
    assert_eq!(v["nodes_seen"], true, "nodes: {}", v["node_names"]);
    assert_eq!(v["matched"], true);
    assert_eq!(
        v["flowing"], true,
        "joint commands and states never flowed: {}",
        v["flow_diag"]
    );

    // The joint commands of the walk, from the first crouch tick to the end of the walk, by
    // the stamps /gait/phase and /joint_commands share.
    let phases = v["phases"].as_array().unwrap();
    let (walk, commands) = walk_and_commands(&v, 0);

    // The same walk planned offline, as `biped plan` does (the nodes have the slow walk's
    // parameter file).
    let model = BipedModel::from_urdf_str(ik_solver::DEFAULT_URDF, None).unwrap();
    let plan = GaitPlanner::new(model.clone(), GaitParams::slow(&model))
        .unwrap()
        .plan(WalkRequest::Steps(2))
        .unwrap();
    let legs: Vec<(String, usize)> = model
        .leg_joints()
        .map(|(_, j)| (j.name.clone(), j.dof))
        .collect();
    assert_walk_is_plan(&walk, &commands, &plan, &legs);

    assert_markers_draw_the_balance(&v, &walk, &plan, &model);

    // The bad commands were refused with warnings naming field and value; the walk above
    // went on unchanged.
    assert!(
        rosout_has(&v, "gait_planner", &["linear.x = NaN"]),
        "no warning for NaN cmd_vel"
    );
    assert!(rosout_has(
        &v,
        "gait_planner",
        &["angular.z = 0.5", "no hip yaw"]
    ));
    assert!(rosout_has(&v, "gait_planner", &["step_length = -1"]));
    assert!(rosout_has(&v, "gait_planner", &["step_duration = inf"]));
    assert!(rosout_has(
        &v,
        "gait_planner",
        &[
            "walk_command refused: step_length = 0.03",
            "the walk in progress keeps its steps"
        ]
    ));
    assert!(
        rosout_has(
            &v,
            "gait_planner",
            &["walk_command: unreadable message dropped"]
        ),
        "no warning for the walk command that could not be read"
    );

    // Parameters: read, refused while walking, set between walks, refused out of bounds.
    assert_eq!(v["param_before"]["double"], 1.0);
    assert_eq!(
        v["set_during_walk"]["successful"], false,
        "{}",
        v["set_during_walk"]
    );
    assert_eq!(
        v["set_after_walk"]["successful"], true,
        "{}",
        v["set_after_walk"]
    );
    assert_eq!(v["param_after"]["double"], 0.02);

    // step_duration_s set to 0 (auto) between walks: accepted, and the next walk (one step)
    // swings for the fastest step duration of these parameters, shorter than the 1 s before.
    assert_eq!(v["set_auto"]["successful"], true, "{}", v["set_auto"]);
    assert_eq!(v["auto_walk_finished"], true);
    let auto = GaitPlanner::new(
        model.clone(),
        GaitParams {
            foot_lift_m: 0.02,
            step_duration_s: 0.0,
            ..GaitParams::slow(&model)
        },
    )
    .unwrap();
    let swing_s = auto.config().step_duration_s;
    assert!(swing_s < 1.0, "{swing_s}");
    let auto_walk = v["auto_walk_from"].as_u64().unwrap() as usize
        ..v["searched_walk_from"].as_u64().unwrap() as usize;
    let half_step_ticks = phases[auto_walk]
        .iter()
        .filter(|p| p["phase"] == "half_step")
        .count();
    assert_eq!(
        half_step_ticks,
        (swing_s * 100.0).round() as usize,
        "the first half step of the walk after step_duration_s := 0 (auto: {swing_s} s)"
    );
    assert!(rosout_has(&v, "gait_planner", &["parameters changed"]));
    // Then a walk command with a new step length: its timing is searched off the control
    // loop, which publishes its idle ticks meanwhile (searched in the loop, none came between
    // the two log lines), and the walk follows.
    assert_eq!(v["searched_walk_finished"], true);
    let logged = |needle: &str, after: i64| -> Option<i64> {
        v["rosout"].as_array().unwrap().iter().find_map(|m| {
            let stamp = m["stamp"].as_i64().unwrap();
            (m["name"].as_str().unwrap().ends_with("gait_planner")
                && m["msg"].as_str().unwrap().contains(needle)
                && stamp > after)
                .then_some(stamp)
        })
    };
    // The phases published between two log lines: idle ticks, and perhaps the walk's first
    // (stamped at the tick's start, before the log line).
    let idle_between = |from: i64, to: i64, what: &str| {
        let during: Vec<&str> = phases
            .iter()
            .filter(|p| (from..to).contains(&p["stamp"].as_i64().unwrap()))
            .map(|p| p["phase"].as_str().unwrap())
            .collect();
        assert!(
            during.len() >= 2 && during[..during.len() - 1].iter().all(|p| *p == "idle"),
            "phases published during the {what}: {during:?}"
        );
    };
    let searching = logged("searching their timing", 0).expect("the search was logged");
    let found = logged("durations left at 0 (auto)", searching).expect("its result logged");
    idle_between(searching, found, "search");
    let from = v["searched_walk_from"].as_u64().unwrap() as usize;
    assert!(phases[from..].iter().any(|p| p["phase"] == "half_step"));
    // Durations set again, then a walk command with a new step length: no timing search,
    // but its check walks (0.1 s here) run off the loop too on the monotonic clock, the
    // standing robot's ticks going on meanwhile (in the loop, none came between the two log
    // lines, and on a robot a longer stall trips the joint bridge's watchdog).
    assert_eq!(v["set_timed"]["successful"], true, "{}", v["set_timed"]);
    assert_eq!(v["checked_walk_finished"], true);
    let planner_log = || -> Vec<&str> {
        v["rosout"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|m| m["name"].as_str().unwrap().ends_with("gait_planner"))
            .map(|m| m["msg"].as_str().unwrap())
            .collect()
    };
    let checking = logged("checking them off the control loop", found)
        .unwrap_or_else(|| panic!("the check was not logged: {:#?}", planner_log()));
    let passed = logged("passed their check", checking)
        .unwrap_or_else(|| panic!("its result was not logged: {:#?}", planner_log()));
    idle_between(checking, passed, "check");
    let from = v["checked_walk_from"].as_u64().unwrap() as usize;
    assert!(phases[from..].iter().any(|p| p["phase"] == "half_step"));
    // Then a walk command without a step length: the configured one (the parameters as
    // set: the slow walk with foot_lift_m 0.02), not the last command's 4 cm, with the
    // checks its parameter set made (not checked again). Planned offline as a second walk
    // (the robot crouched already).
    assert_eq!(v["configured_walk_finished"], true);
    let checks = planner_log()
        .iter()
        .filter(|m| m.contains("checking them off the control loop"))
        .count();
    assert_eq!(checks, 1, "{:#?}", planner_log());
    let configured = GaitParams {
        foot_lift_m: 0.02,
        ..GaitParams::slow(&model)
    };
    let mut offline = GaitPlanner::new(model.clone(), configured.clone()).unwrap();
    offline.plan(WalkRequest::Steps(1)).unwrap();
    offline.set_params(configured).unwrap();
    let second = offline.plan(WalkRequest::Steps(1)).unwrap();
    let (walk, commands) =
        walk_and_commands(&v, v["configured_walk_from"].as_u64().unwrap() as usize);
    assert_walk_is_plan(&walk, &commands, &second, &legs);
    assert_eq!(v["set_invalid"]["successful"], false);
    assert!(
        v["set_invalid"]["reason"]
            .as_str()
            .unwrap()
            .contains("control_rate_hz"),
        "{}",
        v["set_invalid"]
    );

    // The joint bridge published every joint, at rest at the end of the walk (mock backend:
    // the commanded pose).
    let last = &v["states_last"];
    assert_eq!(last["name"].as_array().unwrap().len(), 20);
    let end = plan.last().unwrap();
    for (name, dof) in &legs {
        let i = last["name"]
            .as_array()
            .unwrap()
            .iter()
            .position(|n| n == name.as_str())
            .unwrap();
        assert!(
            (last["position"][i].as_f64().unwrap() - end.joints_rad[*dof]).abs() < 1e-6,
            "joint_states {name}"
        );
    }
    for node in ["gait_planner", "ik_solver", "joint_bridge"] {
        assert_eq!(
            v["exits"][node]["returncode"], 0,
            "{node}: {}",
            v["exits"][node]["stderr_tail"]
        );
    }
}

/// A teleop over /cmd_vel: Twists at 10 Hz side-stepping left (12 mm per step at
/// 0.004 m/s), then none. The walk ends by itself (cmd_vel_timeout_s), the feet together at
/// the standing width, and the pelvis moved left by 24 mm per left-foot swing (the foot on
/// the side of travel opens by twice the step; the other closes behind it).
#[test]
fn an_rclpy_teleop_side_steps_the_robot_and_the_walk_ends_when_it_stops() {
    let v = peer_with_params("teleop", 64, Some(slow_params("gait_slow.yaml")));
    assert_eq!(v["nodes_seen"], true);
    assert_eq!(v["matched"], true);
    assert_eq!(v["flowing"], true, "{}", v["flow_diag"]);
    assert_eq!(
        v["finished"], true,
        "the walk did not end after the Twists stopped"
    );
    assert_timed_out(&v);
    let phases = v["phases"].as_array().unwrap();
    let mut swings = std::collections::BTreeSet::new();
    for p in phases {
        let kind = p["phase"].as_str().unwrap();
        if matches!(kind, "half_step" | "step") {
            swings.insert((
                p["step"].as_u64().unwrap(),
                p["support"].as_str().unwrap().to_owned(),
            ));
        }
    }
    // The left foot swings first (the side of travel), with the right foot carrying.
    let left_swings = swings.iter().filter(|(_, sup)| sup == "right").count();
    assert!(left_swings >= 2, "swings: {swings:?}");
    assert_eq!(swings.first().unwrap().1, "right", "{swings:?}");
    let pelvis = v["pelvis"].as_array().unwrap();
    let y = |p: &Value| p["y"].as_f64().unwrap();
    let x = |p: &Value| p["x"].as_f64().unwrap();
    let (first, last) = (&pelvis[0], pelvis.last().unwrap());
    let moved = y(last) - y(first);
    assert!(
        (moved - 0.024 * left_swings as f64).abs() < 1e-3,
        "pelvis moved {moved} m left after {left_swings} left swings"
    );
    assert!(
        (x(last) - x(first)).abs() < 0.01,
        "forward drift {}",
        x(last) - x(first)
    );
    // nav_msgs/Odometry on /odom, decoded by rclpy: frames per REP-105; leg odometry of the
    // mock bridge's joint states (the commands, so the planned pelvis) ends where the
    // planned pelvis does; its covariance grew with the path; it saw the sideways speed.
    assert!(
        v["odom_count"].as_u64().unwrap() > 100,
        "{}",
        v["odom_count"]
    );
    let (o0, o1) = (&v["odom_first"], &v["odom_last"]);
    assert_eq!(o1["frame"], "odom");
    assert_eq!(o1["child"], "base_link");
    let oy = |o: &Value| o["y"].as_f64().unwrap();
    assert!(
        (oy(o1) - y(last)).abs() < 0.003,
        "odom y {} vs planned pelvis {}",
        oy(o1),
        y(last)
    );
    assert!(o1["qz"].as_f64().unwrap().abs() < 0.01, "odom turned");
    let cov = |o: &Value, i: usize| o["cov"][i].as_f64().unwrap();
    assert!(cov(o1, 0) > cov(o0, 0) && cov(o0, 0) >= 0.002f64.powi(2) - 1e-12);
    assert!(v["odom_max_vy"].as_f64().unwrap() > 0.0);
    for node in ["gait_planner", "ik_solver", "joint_bridge"] {
        assert_eq!(v["exits"][node]["returncode"], 0, "{node}");
    }
}

/// What the ik_solver answered the peer's 300 ankle targets (`scenario_ik`): a command for
/// each, in order, equal to the library's closed form on the targets the peer sent, none for
/// the one with a NaN (refused with a warning naming it), and a clean exit on Ctrl-C.
fn assert_ik_answered_every_target(v: &Value, mode: &str) {
    assert_eq!(
        v["matched"], true,
        "{mode}: the node's subscription matched"
    );
    let model = BipedModel::from_urdf_str(ik_solver::DEFAULT_URDF, None).unwrap();
    let legs: Vec<(String, usize)> = model
        .leg_joints()
        .map(|(_, j)| (j.name.clone(), j.dof))
        .collect();
    let sent = v["sent"].as_array().unwrap();
    // (A warm-up target's command, stamped 1 s + k, may still come after the peer cleared
    // its list: only the 300's, stamped 10 s + k, count.)
    let commands: Vec<&Value> = v["commands"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| c["stamp"].as_i64().unwrap() >= 10_000_000_000)
        .collect();
    let stamps: Vec<i64> = commands
        .iter()
        .map(|c| c["stamp"].as_i64().unwrap())
        .collect();
    let want: Vec<i64> = (0..300)
        .filter(|k| *k != 150)
        .map(|k| 10_000_000_000 + k)
        .collect();
    assert_eq!(
        stamps, want,
        "{mode}: one command per finite target, in order"
    );
    let mut q = vec![0.0; model.robot().dof_count()];
    for cmd in commands {
        let k = (cmd["stamp"].as_i64().unwrap() - 10_000_000_000) as usize;
        let t: Vec<f64> = sent[k].as_array().unwrap()[1..]
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        let target = |o: usize| ik_solver::AnkleTarget {
            ankle_in_hip_m: nalgebra::Vector3::new(t[o], t[o + 1], t[o + 2]),
            foot_yaw_rad: t[o + 3],
        };
        model.solve_legs(&target(0), &target(4), &mut q).unwrap();
        assert_leg_command(cmd, &legs, &q, 1e-12, &format!("{mode}: target {k}"));
    }
    assert!(
        rosout_has(v, "ik_solver", &["ankle targets refused", "NaN"]),
        "{mode}: no warning for the NaN target"
    );
    assert_eq!(
        v["exits"]["ik_solver"]["returncode"], 0,
        "{mode}: {}",
        v["exits"]["ik_solver"]["stderr_tail"]
    );
}

#[test]
fn the_ik_solver_answers_every_target_alike_on_its_own_thread_or_on_the_receiving_dds_thread() {
    let on_thread = peer("ik", 225);
    assert_ik_answered_every_target(&on_thread, "the node's thread");
    assert!(!rosout_has(&on_thread, "ik_solver", &["on the DDS thread"]));
    assert!(
        rosout_has(&on_thread, "ik_solver", &["on the node's thread"]),
        "the node did not say it solves on its own thread"
    );
    let on_receive = peer("ik_on_receive", 226);
    assert_ik_answered_every_target(&on_receive, "solve_on_receive");
    assert!(
        rosout_has(&on_receive, "ik_solver", &["on the DDS thread"]),
        "the node did not say it solves on the DDS thread"
    );
}

#[test]
fn a_joint_command_ticks_the_bridge_as_it_comes_not_at_its_next_own_tick() {
    // The bridge at 1 Hz, commands 0.6 s apart: each must be answered by a joint_states
    // stamped after it was sent and before the next was sent. A command is held until half a
    // period (0.5 s) after the last tick: the first, after an own tick, up to 0.5 s, and the
    // next few a little less each (at worst 0.4, 0.3, 0.2 and 0.1 s, within their 0.6 s), so
    // the windows checked are the fifth command's on, where a command ticks as it comes
    // (0.5 s of margin for the hop). On its own 1 Hz ticks alone, nine windows of 0.6 s would
    // all hold a tick with a chance of 0.6^9, 1 %.
    let v = peer("bridge_ticks", 212);
    assert_eq!(v["matched"], true, "{v}");
    assert_eq!(v["flowing"], true, "no joint_states from the bridge: {v}");
    for (name, exit) in v["exits"].as_object().unwrap() {
        assert_eq!(exit["returncode"], 0, "{name} did not exit cleanly: {exit}");
    }
    assert!(
        rosout_has(&v, "joint_bridge", &["at each command as it comes"]),
        "the bridge did not say it ticks at each command"
    );
    let times = |key: &str| -> Vec<f64> {
        v[key]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let (sent, states) = (times("sent"), times("states"));
    assert_eq!(sent.len(), 14);
    for (k, w) in sent.windows(2).enumerate().skip(4) {
        let answered = states.iter().filter(|&&t| t >= w[0] && t < w[1]).count();
        assert!(
            answered >= 1,
            "command {k} (sent at {:.3} s) had no tick before the next was sent {:.3} s later; joint_states stamps {:?}",
            w[0],
            w[1] - w[0],
            states
                .iter()
                .filter(|&&t| t > w[0] - 1.5 && t < w[1] + 1.5)
                .map(|t| format!("{:+.3}", t - w[0]))
                .collect::<Vec<_>>()
        );
    }
}

#[test]
fn killing_ik_solver_mid_walk_makes_the_bridge_hold_the_pose() {
    let v = peer("watchdog", 62);
    assert_walk_moved(&v);
    let kill_t = v["kill_t"].as_f64().unwrap();
    let states = v["states"].as_array().unwrap();
    let (pos, t) = (state_positions, state_t);
    // Moving before the kill (mid-walk).
    let before: Vec<&Value> = states
        .iter()
        .filter(|s| t(s) > kill_t - 0.5 && t(s) < kill_t)
        .collect();
    assert!(before.len() > 10);
    assert_ne!(
        pos(before[0]),
        pos(before[before.len() - 1]),
        "the joints were moving before the kill"
    );
    // Still after the watchdog's time (0.2 s) plus a few bridge periods: nothing moves. Times
    // are the bridge's own joint_states stamps, on the clock the kill time was read from.
    let after: Vec<&Value> = states
        .iter()
        .filter(|s| t(s) > kill_t + 0.2 + 0.15)
        .collect();
    assert!(after.len() > 50, "joint_states keep coming while holding");
    for s in &after {
        assert_eq!(
            pos(s),
            pos(after[0]),
            "joint moved at t = {} after the watchdog held",
            t(s)
        );
    }
    assert!(rosout_has(
        &v,
        "joint_bridge",
        &["watchdog", "holding the last pose"]
    ));
    assert_eq!(v["exits"]["joint_bridge"]["returncode"], 0);
}

#[test]
fn biped_launch_starts_the_fleet_and_leaves_no_process_behind() {
    let v = peer("launch", 63);
    assert_eq!(v["nodes_seen"], true, "{}", v["launcher_stderr"]);
    assert_eq!(v["launcher_returncode"], 0, "{}", v["launcher_stderr"]);
    assert_eq!(
        v["pids"].as_array().unwrap().len(),
        4,
        "{}",
        v["launcher_stdout"]
    );
    // A subscriber that joined after the fleet published (transient local, as RViz's
    // RobotModel display) gets the URDF in use, and the fixed joints' frames.
    let descriptions = v["robot_description"].as_array().unwrap();
    assert_eq!(
        descriptions.len(),
        1,
        "one robot_description: {descriptions:?}"
    );
    assert_eq!(descriptions[0].as_str().unwrap(), ik_solver::DEFAULT_URDF);
    let robot = ik_solver::RobotModel::from_urdf_str(ik_solver::DEFAULT_URDF).unwrap();
    let fixed: Vec<(&str, &str)> = robot
        .joints()
        .iter()
        .filter(|j| j.dof.is_none())
        .map(|j| {
            (
                robot.links()[j.parent].name.as_str(),
                robot.links()[j.child].name.as_str(),
            )
        })
        .collect();
    let statics = v["tf_static"].as_array().unwrap();
    assert_eq!(statics.len(), 1, "one /tf_static message: {statics:?}");
    let edges: Vec<(&str, &str)> = statics[0]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| (t["parent"].as_str().unwrap(), t["child"].as_str().unwrap()))
        .collect();
    assert_eq!(edges, fixed);
    assert_eq!(
        v["alive_after"].as_array().unwrap().len(),
        0,
        "nodes left after Ctrl-C: {}",
        v["alive_after"]
    );
    assert!(
        v["launcher_stdout"].as_str().unwrap().contains("log: "),
        "says where each node logs"
    );
    assert_eq!(v["pids_after_kill"].as_array().unwrap().len(), 4);
    assert_eq!(
        v["alive_after_kill"].as_array().unwrap().len(),
        0,
        "nodes left after the launcher was killed: {}",
        v["alive_after_kill"]
    );
}

/// `biped compose` on one thread and with a thread per node: a node that fails (the joint
/// bridge, given a backend that does not exist) stops the others, which shut down, and the
/// process fails naming the node and the bad value.
#[test]
fn a_composed_node_that_fails_stops_the_others_on_either_executor() {
    for (executor, says, domain) in [
        ("single", "ik_solver, joint_bridge on one thread", 194),
        (
            "per-node",
            "ik_solver, joint_bridge each on its own thread",
            195,
        ),
    ] {
        // `timeout`: a node left running would keep the process alive (exit status 124).
        let out = common::in_netns("exec timeout 60 \"$@\"", domain)
            .arg(bin_dir().join("biped"))
            .args(["compose", "--executor", executor])
            .args(["--node", "ik_solver", "--node", "joint_bridge"])
            .args(["--ros-args", "-p", "backend:=warp_drive"])
            .output()
            .expect("unshare runs (root needed for a private network namespace)");
        let all = format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        assert_eq!(out.status.code(), Some(1), "{executor}: {all}");
        assert!(all.contains(says), "{executor}: {all}");
        assert!(
            all.contains("joint_bridge failed: parameter `backend` = `warp_drive`"),
            "{executor}: {all}"
        );
        assert!(
            all.contains("[/ik_solver]: shutting down"),
            "{executor}: the other node did not shut down: {all}"
        );
    }
}

/// The simulator's `command_delay_s`: an rclpy peer as the joint bridge, answering every
/// `/clock` tick, steps `l_elbow` from 0 to -0.3 rad at t = 1 s; the simulated servo acts on
/// it at once (0), a tick later (0.01 s) and half a tick later (0.005 s, between two ticks).
#[test]
fn the_simulated_servos_act_on_a_command_the_set_delay_after_it_comes() {
    let v = peer("sim_delay", 227);
    let elbow = |delay: &str, ms: i64| -> f64 {
        v["runs"][delay]["elbow"][(ms * 1_000_000).to_string()]
            .as_f64()
            .unwrap_or_else(|| panic!("no joint_states stamped {ms} ms with delay {delay}"))
    };
    for (delay, says) in [
        ("0.0", "act on a command as it comes"),
        ("0.01", "act on a command 10 ms after it comes"),
        ("0.005", "act on a command 5 ms after it comes"),
    ] {
        assert_eq!(v["runs"][delay]["done"], true, "delay {delay}: {v}");
        assert_eq!(v["exits"][delay]["returncode"], 0, "delay {delay}: {v}");
        assert!(
            v["ready"][delay].as_str().is_some_and(|r| r.contains(says)),
            "delay {delay}: {}",
            v["ready"][delay]
        );
        // Up to the step the three runs are one: the robot standing, the arm at rest at 0.
        for ms in [990, 1000] {
            assert!(elbow(delay, ms).abs() < 1e-4, "delay {delay}, {ms} ms");
            assert!((elbow(delay, ms) - elbow("0.0", ms)).abs() < 1e-9);
        }
    }
    // At once: the state after the step's tick has the elbow on its way to -0.3 rad.
    let first = elbow("0.0", 1010) - elbow("0.0", 1000);
    assert!(first < -0.005, "no response a tick after the step: {first}");
    // A tick later: still at rest a tick after the step, then the same response as at once,
    // tick for tick, 10 ms later (the rest of the robot stood still meanwhile).
    assert!((elbow("0.01", 1010) - elbow("0.01", 1000)).abs() < 1e-5);
    for k in 1..=25 {
        let (late, on_time) = (elbow("0.01", 1010 + 10 * k), elbow("0.0", 1000 + 10 * k));
        assert!(
            (late - on_time).abs() < 1e-4,
            "{} ms after the step: {late} with 10 ms of delay, {on_time} 10 ms earlier without",
            10 * k + 10
        );
    }
    // Half a tick later: the servo pushed for the tick's last 5 ms only. At its torque limit
    // (1.5 N m, far below kp x 0.3 rad), from rest, the arm moves as t squared: 5 ms give
    // about (5/10)^2 = 1/4 of what 10 ms give.
    let half = elbow("0.005", 1010) - elbow("0.005", 1000);
    assert!(
        (0.15..0.4).contains(&(half / first)),
        "5 ms of push moved the elbow {half} rad against {first} rad for 10 ms"
    );
}

/// A `command_delay_s` the simulator cannot keep (negative, over 1 s, or between two physics
/// steps of 1 ms) stops it at start, naming the parameter and the value.
#[test]
fn the_simulator_refuses_a_command_delay_it_cannot_keep() {
    for value in ["-0.01", "2.0", "0.0005"] {
        let err = failed_start(
            common::in_netns("exec timeout 60 \"$@\"", 228)
                .arg(bin_dir().join("sim_bridge"))
                .args(["--ros-args", "-p", &format!("command_delay_s:={value}")]),
        );
        let shown = value.parse::<f64>().unwrap().to_string();
        assert!(
            err.contains(&format!("parameter `command_delay_s` = {shown}: "))
                && err.contains("whole number of physics steps"),
            "{value}: {err}"
        );
    }
}

/// `biped launch --backend sim`: a plain rclpy node (as RViz or Foxglove would be) watches
/// the simulated robot in real time and walks it with a `ros2 topic pub`-style command.
#[test]
fn an_rclpy_peer_watches_and_walks_the_simulated_robot_in_real_time() {
    assert_watched_and_walked_in_real_time(&peer("sim", 60));
}

/// The same with `biped launch --backend sim --composed`: the four nodes in one process
/// (`biped compose`, in-process delivery between them) look to an rclpy peer exactly as
/// four processes do: every node found by name, every topic flowing, its walk command
/// taken, its errors none.
#[test]
fn an_rclpy_peer_watches_and_walks_the_composed_simulated_robot_as_if_separate() {
    let v = peer("sim_composed", 192);
    assert_watched_and_walked_in_real_time(&v);
    assert!(
        v["launcher_stdout"]
            .as_str()
            .unwrap()
            .contains("started composed"),
        "{}",
        v["launcher_stdout"]
    );
}

fn assert_watched_and_walked_in_real_time(v: &Value) {
    assert_eq!(v["nodes_seen"], true, "nodes: {}", v["node_names"]);
    assert_eq!(
        v["flowing"], true,
        "no joint_states or /clock from the simulator"
    );
    assert_eq!(
        v["walked"], true,
        "the walk did not end: {}",
        v["launcher_stderr"]
    );
    assert_eq!(v["launcher_returncode"], 0, "{}", v["launcher_stderr"]);
    assert!(
        v["rosout_errors"].as_array().unwrap().is_empty(),
        "errors on /rosout: {}",
        v["rosout_errors"]
    );
    // /clock is paced by the wall clock: never ahead of real time (how far behind it falls
    // is the machine's speed, measured in BENCHMARKS.md, not asserted here).
    let clock = v["clock"].as_array().unwrap();
    let (first, last) = (&clock[0], &clock[clock.len() - 1]);
    let sim_s = last["t"].as_f64().unwrap() - first["t"].as_f64().unwrap();
    let wall_s = last["wall"].as_f64().unwrap() - first["wall"].as_f64().unwrap();
    assert!(sim_s > 5.0, "walk of {sim_s} s simulated");
    let rtf = sim_s / wall_s;
    assert!(
        rtf < 1.05,
        "simulated time ran ahead of the wall clock: {rtf}x"
    );
    let ticks: Vec<f64> = clock.iter().map(|c| c["t"].as_f64().unwrap()).collect();
    assert!(
        ticks.windows(2).all(|w| w[1] >= w[0]),
        "/clock went backwards"
    );
    // joint_states: every joint of the robot, measured, stamped on the simulated clock.
    assert_eq!(v["joint_state_names"].as_array().unwrap().len(), 20);
    let clock_values: Vec<f64> = v["clock_values"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_f64().unwrap())
        .collect();
    let newest_clock = clock_values.iter().copied().fold(f64::MIN, f64::max);
    for s in v["joint_state_stamps"].as_array().unwrap() {
        let s = s.as_f64().unwrap();
        if s > newest_clock {
            continue; // arrived before its /clock when the peer stopped listening
        }
        assert!(
            clock_values.iter().any(|c| (c - s).abs() < 1e-6),
            "joint_states stamp {s} is not a /clock value"
        );
    }
    // Ground truth: the base in the world frame moved forward by about the planned 2 steps
    // (the defaults: 2 × 81 mm, 0.45 × the 0.18 m leg), the centre of pressure and the
    // support polygon were published.
    let base = v["base"].as_array().unwrap();
    assert_eq!(base[0]["frame"], "world");
    let dx = base[base.len() - 1]["x"].as_f64().unwrap() - base[0]["x"].as_f64().unwrap();
    assert!((0.13..0.19).contains(&dx), "base moved {dx} m");
    assert!(v["cop_count"].as_u64().unwrap() > 500);
    let sizes: Vec<u64> = v["polygon_sizes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s.as_u64().unwrap())
        .collect();
    assert!(
        sizes.contains(&4),
        "single-support polygons (one sole): {sizes:?}"
    );
    assert!(
        sizes.iter().any(|&s| s > 4),
        "double-support polygons: {sizes:?}"
    );
    // imu/data (sensor_msgs/Imu) in the base link's frame: standing before the walk, gravity
    // up the base's z, level, still; the walk turns the base.
    assert!(v["imu_count"].as_u64().unwrap() > 500, "{}", v["imu_count"]);
    assert_eq!(v["imu_frames"], serde_json::json!(["base_link"]));
    let standing = v["imu_standing"].as_array().unwrap();
    assert!(
        standing.len() >= 20,
        "{} IMU messages standing",
        standing.len()
    );
    let f64s = |j: &Value| -> Vec<f64> {
        j.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    for m in standing {
        let (a, w, q) = (f64s(&m["a"]), f64s(&m["w"]), f64s(&m["q"]));
        assert!(
            a[0].abs() < 0.3 && a[1].abs() < 0.3 && (a[2] - 9.81).abs() < 0.3,
            "standing, the accelerometer reads {a:?}"
        );
        assert!(
            w.iter().all(|x| x.abs() < 0.05),
            "standing, the gyro reads {w:?}"
        );
        assert!(
            q[0].abs() < 0.02 && q[1].abs() < 0.02,
            "standing, tilted: {q:?}"
        );
    }
    let rate = v["imu_walking_max_rate"].as_f64().unwrap();
    assert!(
        rate > 0.05,
        "walking, the gyro never read more than {rate} rad/s"
    );
}

/// A teleop over /cmd_vel drives the six-joint robot (hip yaw) in the simulator at real
/// time, changing the command mid-walk: it turns left (0.03 rad/s: 0.09 rad per 3 s step,
/// the left foot turning 0.18 rad about the point between the feet, the right coming back
/// parallel) for two swings, walks forward (10 mm/s: 30 mm per step) for three, back
/// (-8 mm/s) for three, in an arc (both) for three, then the Twists stop. The robot follows
/// each command in physics, the walk ends by itself, nothing falls, and /odom agrees with
/// the simulator's ground truth.
#[test]
fn an_rclpy_teleop_turns_then_walks_the_simulated_six_joint_robot() {
    let v = peer_with_params("teleop_sim", 65, Some(slow_params("biped6_slow.yaml")));
    assert_eq!(v["nodes_seen"], true);
    assert_eq!(v["flowing"], true);
    assert_eq!(v["matched"], true);
    assert_eq!(
        v["finished"], true,
        "the walk did not end: {}",
        v["launcher_stderr"]
    );
    assert_eq!(v["launcher_returncode"], 0, "{}", v["launcher_stderr"]);
    assert!(v["falls"].as_array().unwrap().is_empty(), "{}", v["falls"]);
    let yaw = |p: &Value| 2.0 * p["qz"].as_f64().unwrap().atan2(p["qw"].as_f64().unwrap());
    let xy = |p: &Value| [p["x"].as_f64().unwrap(), p["y"].as_f64().unwrap()];
    let base = v["base"].as_array().unwrap();
    let odom = v["odom"].as_array().unwrap();
    assert!(odom.len() > 100, "{} odom messages", odom.len());
    // The walk's first and last ticks, by the phase stamps.
    let phases = v["phases"].as_array().unwrap();
    let walk: Vec<i64> = phases
        .iter()
        .filter(|p| p["phase"] != "idle")
        .map(|p| p["stamp"].as_i64().unwrap())
        .collect();
    let (t0, t1) = (walk[0], *walk.last().unwrap());
    let at = |msgs: &[Value], t: i64| -> Value {
        msgs.iter()
            .rev()
            .find(|m| m["stamp"].as_i64().unwrap() <= t)
            .cloned()
            .unwrap_or_else(|| msgs[0].clone())
    };
    let (b0, b1) = (at(base, t0), at(base, t1 + 2_000_000_000));
    let d = [xy(&b1)[0] - xy(&b0)[0], xy(&b1)[1] - xy(&b0)[1]];
    let turned = yaw(&b1) - yaw(&b0);
    // Each segment's effect, measured on the true base: from 3 s (a swing and a shift, the
    // last swing of its stride landed and the pelvis settled) after the previous segment's
    // end to 3 s after its own (the walk's end for the last).
    let segments = v["segments"].as_array().unwrap();
    let mut seg = std::collections::BTreeMap::new();
    let mut from = t0;
    for (k, sg) in segments.iter().enumerate() {
        let to = if k + 1 == segments.len() {
            t1 + 2_000_000_000
        } else {
            sg["to"].as_i64().unwrap() + 3_000_000_000
        };
        let (a, b) = (at(base, from), at(base, to));
        let (s, c) = yaw(&a).sin_cos();
        let dd = [xy(&b)[0] - xy(&a)[0], xy(&b)[1] - xy(&a)[1]];
        let along = c * dd[0] + s * dd[1];
        let name = sg["name"].as_str().unwrap().to_owned();
        eprintln!(
            "{name}: turned {} rad, {along} m along the heading",
            yaw(&b) - yaw(&a)
        );
        seg.insert(name, (yaw(&b) - yaw(&a), along));
        from = to;
    }
    // Turn: two swings, the left foot turned 0.18 rad, the pelvis followed.
    let (turn, _) = seg["turn"];
    assert!(
        (turn - 0.18).abs() <= 0.018,
        "turned {turn} rad, commanded 0.18 (swings {})",
        v["swings_turning"]
    );
    // Ahead: three swings of 30 mm; back: three of 24 mm; the heading kept.
    let (ahead_turn, ahead) = seg["ahead"];
    assert!(
        ahead > 0.06 && ahead_turn.abs() < 0.03,
        "ahead: {ahead} m, {ahead_turn} rad"
    );
    let (back_turn, back) = seg["back"];
    assert!(
        back < -0.045 && back_turn.abs() < 0.03,
        "back: {back} m, {back_turn} rad"
    );
    // Arc: forward while turning left (the left foot turns 0.18 rad at each of its two
    // swings).
    let (arc_turn, arc) = seg["arc"];
    assert!(
        arc > 0.03 && arc_turn > 0.25,
        "arc: {arc} m, {arc_turn} rad"
    );
    // Odometry against ground truth, as displacements over the walk.
    let (o0, o1) = (at(odom, t0), at(odom, t1 + 2_000_000_000));
    let od = [xy(&o1)[0] - xy(&o0)[0], xy(&o1)[1] - xy(&o0)[1]];
    let err = (od[0] - d[0]).hypot(od[1] - d[1]);
    let moved = d[0].hypot(d[1]);
    assert!(
        err < 0.1 * moved + 0.005,
        "odometry {err} m off after {moved} m"
    );
    let yaw_err = ((yaw(&o1) - yaw(&o0)) - turned).abs().to_degrees();
    eprintln!("odometry {err} m and {yaw_err} deg off after {moved} m and {turned} rad");
    assert!(yaw_err < 5.0, "odometry heading {yaw_err} deg off");
    assert_timed_out(&v);
}

/// An operator's `ros2 service call /joint_bridge/estop std_srvs/srv/Trigger` mid-walk: the
/// bridge answers, brakes and holds while the planner goes on commanding; `~/reset` lets the
/// walk move the joints again; `~/set_torque` answers both ways; a reset with no stop on is
/// refused, saying so. Before that, a walk scheduled ahead is cancelled by a stop.
#[test]
fn an_rclpy_operator_estops_the_walk_and_resets_it_through_the_bridge_services() {
    let v = peer("estop", 87);
    assert_walk_moved(&v);
    let ok = |k: &str| {
        assert_eq!(v[k]["success"], true, "{k}: {}", v[k]);
    };
    ok("estop");
    ok("reset");
    ok("torque_off");
    ok("torque_on");
    assert_eq!(v["early_reset"]["success"], false, "{}", v["early_reset"]);
    // A walk scheduled ahead, then a stop: the stop cancelled it, the planner stayed idle.
    assert_eq!(
        v["phases_after_cancel"],
        serde_json::json!(["idle"]),
        "phases after the stop"
    );
    assert!(rosout_has(
        &v,
        "gait_planner",
        &["1 walk command(s) waiting for their start time cancelled"]
    ));
    assert!(
        v["early_reset"]["message"]
            .as_str()
            .unwrap()
            .contains("no emergency stop"),
        "{}",
        v["early_reset"]
    );
    let states = v["states"].as_array().unwrap();
    let (pos, t) = (state_positions, state_t);
    let (answered, reset_t) = (
        v["estop_answered_t"].as_f64().unwrap(),
        v["reset_t"].as_f64().unwrap(),
    );
    // The e-stop keeps to the walk's path: the bridge, stopped mid-walk with commands
    // coming, follows them; the planner, told by ~/holding, brakes its walk to a pause.
    // (Wall clock here, planner and bridge not in step: the follow must outlast a late
    // command.)
    assert!(rosout_has(
        &v,
        "joint_bridge",
        &["emergency stop: the walk brakes along its path"]
    ));
    assert!(rosout_has(
        &v,
        "gait_planner",
        &["the walk brakes to a pause along its path"]
    ));
    // And it held once the walk stood (in lockstep the reason is always that the commands
    // came to rest; on this wall clock a stalled planner could also end it by silence).
    assert!(rosout_has(
        &v,
        "joint_bridge",
        &["emergency stop: holding after following the commands for"]
    ));
    // Held from the answer plus the bridge's longest follow (estop_follow_s, 0.4 s), the
    // braking at the limits after it (6 rad/s at 100 rad/s²: 0.06 s) and a few bridge
    // periods, until the reset: nothing moves, though the planner goes on commanding.
    let held: Vec<&Value> = states
        .iter()
        .filter(|s| t(s) > answered + 0.5 && t(s) < reset_t)
        .collect();
    assert!(held.len() > 50, "joint_states keep coming while holding");
    for s in &held {
        assert_eq!(
            pos(s),
            pos(held[0]),
            "joint moved at t = {} during the stop",
            t(s)
        );
    }
    // After the reset's answer (the reset is done by then), until the torque request, the
    // walk moves the joints again.
    let (reset_answered, torque_t) = (
        v["reset_answered_t"].as_f64().unwrap(),
        v["torque_t"].as_f64().unwrap(),
    );
    let after: Vec<&Value> = states
        .iter()
        .filter(|s| t(s) > reset_answered + 0.2 && t(s) < torque_t)
        .collect();
    assert!(after.len() > 50);
    assert!(
        after.iter().any(|s| pos(s) != pos(held[0])),
        "the joints never moved after the reset"
    );
    assert!(rosout_has(
        &v,
        "joint_bridge",
        &["emergency stop", "~/reset"]
    ));
    assert!(rosout_has(&v, "joint_bridge", &["joint commands ignored"]));
    assert_eq!(v["exits"]["joint_bridge"]["returncode"], 0);
}

/// An operator's `ros2 service call /gait_planner/pause std_srvs/srv/SetBool "{data: true}"`
/// mid-walk: the planner answers and brings the walk to rest on its path within its brake
/// time (0.25 s for the default robot at the defaults); the joint commands stop changing, the phases still
/// say where the walk stands (it is paused, not over); asked again, it says so; `false`
/// takes the walk on from there and the commands move again.
#[test]
fn an_rclpy_operator_pauses_and_resumes_the_walk_through_the_planner_service() {
    let v = peer("pause", 100);
    assert_walk_moved(&v);
    let said = |k: &str, needle: &str| {
        assert_eq!(v[k]["success"], true, "{k}: {}", v[k]);
        let msg = v[k]["message"].as_str().unwrap();
        assert!(msg.contains(needle), "{k}: {msg}");
    };
    said("pause", "comes to rest along its path");
    said("pause_again", "already paused");
    said("resume", "comes back to speed");
    said("resume_again", "not paused");
    let at = |c: &Value| c["stamp"].as_f64().unwrap() * 1e-9;
    let (answered, resume_t) = (
        v["pause_answered_t"].as_f64().unwrap(),
        v["resume_t"].as_f64().unwrap(),
    );
    let commands = v["commands"].as_array().unwrap();
    // At rest from the answer plus the brake (0.25 s) and the pipeline's ticks, until the
    // resume: published every tick, never changing (not in the last bit either).
    let held: Vec<&Value> = commands
        .iter()
        .filter(|c| at(c) > answered + 0.5 && at(c) < resume_t)
        .collect();
    assert!(
        held.len() > 50,
        "{} joint commands while paused",
        held.len()
    );
    for c in &held {
        assert_eq!(
            state_positions(c),
            state_positions(held[0]),
            "a joint command changed at t = {} during the pause",
            at(c)
        );
    }
    let phases = v["phases"].as_array().unwrap();
    let paused_phases: Vec<&str> = phases
        .iter()
        .filter(|p| {
            let t = p["stamp"].as_f64().unwrap() * 1e-9;
            t > answered + 0.5 && t < resume_t
        })
        .map(|p| p["phase"].as_str().unwrap())
        .collect();
    assert!(!paused_phases.is_empty());
    assert!(
        paused_phases.iter().all(|p| *p != "idle"),
        "the walk ended instead of pausing: {paused_phases:?}"
    );
    let after: Vec<&Value> = commands.iter().filter(|c| at(c) > resume_t + 0.5).collect();
    assert!(
        after
            .iter()
            .any(|c| state_positions(c) != state_positions(held[0])),
        "the joints were never commanded again after the resume"
    );
    assert!(rosout_has(&v, "gait_planner", &["pause:", "comes to rest"]));
    assert_eq!(v["exits"]["gait_planner"]["returncode"], 0);
}

/// The joint bridge as a managed node, from an rclpy lifecycle client (the services
/// `ros2 lifecycle get/list/set` call): mid-walk, deactivate brakes the walk along its path and holds the joints while the walk
/// goes on commanding, a transition not available is refused, activate by label moves them
/// again, shutdown ends the node by itself with the torque off; each transition is
/// published on `~/transition_event`. A bridge started with `autostart:=false` waits
/// unconfigured (publishing nothing) until its manager configures and activates it.
#[test]
fn an_rclpy_lifecycle_client_deactivates_activates_and_shuts_down_the_joint_bridge() {
    let v = peer("lifecycle", 88);
    assert_walk_moved(&v);
    let json = |x: Value| x;
    assert_eq!(v["state_first"], "active");
    assert_eq!(
        v["available_active"],
        json(serde_json::json!([
            [4, "deactivate", "inactive"],
            [7, "shutdown", "finalized"]
        ]))
    );
    assert_eq!(v["deactivate"], true);
    assert_eq!(v["state_deactivated"], "inactive");
    assert_eq!(
        v["available_inactive"],
        json(serde_json::json!([
            [2, "cleanup", "unconfigured"],
            [3, "activate", "active"],
            [6, "shutdown", "finalized"]
        ]))
    );
    assert_eq!(
        v["configure_from_inactive"], false,
        "configure is not available from inactive"
    );
    assert!(rosout_has(
        &v,
        "joint_bridge",
        &["transition 1 `` is not available from state `inactive`"]
    ));
    assert_eq!(v["activate"], true);
    assert_eq!(v["state_activated"], "active");
    assert_eq!(v["shutdown"], true);
    assert_eq!(
        v["bridge_exited_by_itself"], true,
        "the bridge still ran 10 s after shutdown"
    );
    assert_eq!(
        v["exits"]["joint_bridge"]["returncode"], 0,
        "{}",
        v["exits"]
    );
    let tail = v["exits"]["joint_bridge"]["stderr_tail"].as_str().unwrap();
    assert!(tail.contains("torque off"), "{tail}");
    // Every transition taken, in order, as `ros2 lifecycle echo` would print them.
    let events: Vec<(String, String, String)> = v["events"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| {
            (
                e["label"].as_str().unwrap().to_owned(),
                e["start"].as_str().unwrap().to_owned(),
                e["goal"].as_str().unwrap().to_owned(),
            )
        })
        .collect();
    let want = [
        ("deactivate", "active", "inactive"),
        ("activate", "inactive", "active"),
        ("shutdown", "active", "finalized"),
    ]
    .map(|(a, b, c)| (a.to_owned(), b.to_owned(), c.to_owned()));
    assert_eq!(events, want);
    // Inactive: the walk braked along its path (the bridge follows the commands to rest,
    // within estop_follow_s = 0.4 s), then held until the activation, though the walk goes
    // on commanding.
    let states = v["states"].as_array().unwrap();
    let (pos, t) = (state_positions, state_t);
    let (held_from, activate_t) = (
        v["deactivate_answered_t"].as_f64().unwrap() + 0.5,
        v["activate_t"].as_f64().unwrap(),
    );
    let held: Vec<&Value> = states
        .iter()
        .filter(|s| t(s) > held_from && t(s) < activate_t)
        .collect();
    assert!(held.len() > 50, "joint_states keep coming while inactive");
    for s in &held {
        assert_eq!(
            pos(s),
            pos(held[0]),
            "joint moved at t = {} while inactive",
            t(s)
        );
    }
    let (active_from, shutdown_t) = (
        v["activate_answered_t"].as_f64().unwrap() + 0.2,
        v["shutdown_t"].as_f64().unwrap(),
    );
    let after: Vec<&Value> = states
        .iter()
        .filter(|s| t(s) > active_from && t(s) < shutdown_t)
        .collect();
    assert!(after.len() > 50);
    assert!(
        after.iter().any(|s| pos(s) != pos(held[0])),
        "the joints never moved after the activation"
    );
    assert!(rosout_has(
        &v,
        "joint_bridge",
        &["lifecycle: active -> inactive (deactivate)"]
    ));
    assert!(rosout_has(
        &v,
        "joint_bridge",
        &[
            "inactive: holding after following the commands for",
            "came to rest"
        ]
    ));
    assert!(rosout_has(
        &v,
        "joint_bridge",
        &["joint commands ignored: the managed node is not active"]
    ));
    // autostart false: unconfigured, nothing published, until configured and activated.
    assert_eq!(
        v["manual_state_first"], "unconfigured",
        "{}",
        v["manual_exits"]
    );
    assert_eq!(
        v["manual_available"],
        json(serde_json::json!([
            [1, "configure", "inactive"],
            [5, "shutdown", "finalized"]
        ]))
    );
    assert_eq!(
        v["manual_states_unconfigured"], 0,
        "joint_states while unconfigured"
    );
    assert_eq!(v["manual_configure"], true);
    assert_eq!(v["manual_state_configured"], "inactive");
    assert!(
        v["manual_states_inactive"].as_u64().unwrap() > 50,
        "configured, the bridge holds and publishes joint_states"
    );
    assert_eq!(v["manual_activate"], true);
    assert_eq!(v["manual_state_activated"], "active");
    let said = v["manual_rosout"].to_string();
    assert!(said.contains("unconfigured (autostart false"), "{said}");
    assert!(!said.contains("backend read"), "{said}");
    assert_eq!(
        v["manual_exits"]["joint_bridge"]["returncode"], 0,
        "{}",
        v["manual_exits"]
    );
}

/// `biped launch` supervises: `kill -9` of the IK node mid-walk, then of the joint bridge.
/// The launcher restarts each (after `--respawn-delay`) while the others run on; while the
/// IK node is away the bridge holds the joints still (its watchdog), though the planner goes
/// on walking; with each back, commands and states flow again and the walk moves the joints.
#[test]
fn biped_launch_restarts_a_killed_node_while_the_bridge_holds() {
    let v = peer("supervise", 89);
    assert_walk_moved(&v);
    let stdout = v["launcher_stdout"].as_str().unwrap_or_default();
    let stderr = v["launcher_stderr"].as_str().unwrap_or_default();
    for name in ["ik_solver", "joint_bridge"] {
        assert_eq!(
            v[format!("{name}_restarted")],
            true,
            "{name} not restarted: {stdout}\n{stderr}"
        );
        assert_eq!(
            v[format!("{name}_flowing_again")],
            true,
            "{name}: no commands and states after its restart"
        );
        assert!(
            stdout.contains(&format!("restarted {name} (pid ")),
            "{stdout}"
        );
        assert!(
            stderr.contains(&format!("{name} exited (signal: 9")),
            "{stderr}"
        );
    }
    assert_eq!(v["launcher_alive"], true, "the launcher stopped: {stderr}");
    assert_eq!(v["launcher_returncode"], 0, "{stderr}");
    // The IK node away: from its kill plus the watchdog (0.25 s) and the braking (0.06 s)
    // until it is back, the joints hold still while the planner walks on.
    let states = v["states"].as_array().unwrap();
    let (pos, t) = (state_positions, state_t);
    let (killed, back) = (
        v["ik_solver_kill_t"].as_f64().unwrap(),
        v["ik_solver_restart_t"].as_f64().unwrap(),
    );
    let held: Vec<&Value> = states
        .iter()
        .filter(|s| t(s) > killed + 0.4 && t(s) < back)
        .collect();
    assert!(held.len() > 20, "joint_states kept coming: {}", held.len());
    for s in &held {
        assert_eq!(
            pos(s),
            pos(held[0]),
            "joint moved at t = {} without the IK node",
            t(s)
        );
    }
    assert!(rosout_has(&v, "joint_bridge", &["watchdog", "holding"]));
    // After each restart the walk moves the joints again.
    for name in ["ik_solver", "joint_bridge"] {
        let from = v[format!("{name}_restart_t")].as_f64().unwrap();
        let after: Vec<&Value> = states.iter().filter(|s| t(s) > from).collect();
        assert!(
            after.windows(2).any(|w| pos(w[0]) != pos(w[1])),
            "the joints never moved after {name} came back"
        );
    }
}

/// The simulated robot (MuJoCo, real time) under `biped launch --backend sim`, mid-walk: an
/// rclpy operator's `~/estop` holds it standing and at rest until `~/reset`; then `kill -9`
/// of the IK node, the joint bridge and the planner in turn, each restarted by the
/// launcher: the robot never falls, and after the planner's restart it stands still where
/// it was (the restarted planner holds the measured pose instead of commanding its standing
/// pose from mid-step, which threw the robot over before) and refuses a walk, saying why.
#[test]
fn the_simulated_robot_stands_through_an_estop_and_each_node_killed_mid_walk() {
    let v = peer_with_params("sim_kill", 91, Some(slow_params("gait_slow.yaml")));
    assert_eq!(v["nodes_seen"], true);
    assert_eq!(v["flowing"], true, "no joint_states or base pose");
    assert_eq!(v["walking"], true, "the walk never started");
    let stderr = v["launcher_stderr"].as_str().unwrap_or_default();
    for k in [
        "estop",
        "reset",
        "ik_solver_restarted",
        "joint_bridge_restarted",
        "gait_planner_restarted",
    ] {
        assert_eq!(v[k], true, "{k}: {stderr}");
    }
    assert_eq!(v["launcher_returncode"], 0, "{stderr}");
    let events: std::collections::BTreeMap<String, f64> = v["events"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| (e[0].as_str().unwrap().to_owned(), e[1].as_f64().unwrap()))
        .collect();
    let base = v["base"].as_array().unwrap();
    let f = |p: &Value, k: &str| p[k].as_f64().unwrap();
    // Tilt from the base's orientation: 2 asin(|(qx, qy)|).
    let tilt_deg = |p: &Value| (2.0 * f(p, "qx").hypot(f(p, "qy")).min(1.0).asin()).to_degrees();
    let between = |a: f64, b: f64| -> Vec<&Value> {
        base.iter()
            .filter(|p| f(p, "t") >= a && f(p, "t") < b)
            .collect()
    };
    // Standing throughout: the base above 80 % of its walking height, tilted < 20 deg.
    let walking_z = 0.213;
    for p in between(events["estop"], events["end"]) {
        assert!(
            f(p, "z") > 0.8 * walking_z && tilt_deg(p) < 20.0,
            "fallen at t = {}: z {} m, tilt {} deg",
            f(p, "t"),
            f(p, "z"),
            tilt_deg(p)
        );
    }
    let at_rest = |what: &str, ps: &[&Value]| {
        assert!(ps.len() > 50, "{what}: {} base poses", ps.len());
        let (x0, y0) = (f(ps[0], "x"), f(ps[0], "y"));
        for p in ps {
            let d = (f(p, "x") - x0).hypot(f(p, "y") - y0);
            assert!(
                d < 0.005,
                "{what}: the base moved {d} m by t = {}",
                f(p, "t")
            );
            assert!(tilt_deg(p) < 5.0, "{what}: tilt {} deg", tilt_deg(p));
        }
    };
    // Held by the e-stop: at rest from 0.5 s after its answer (braking, the body settling;
    // a new client's first call can take RustDDS seconds to be heard) until the reset.
    at_rest(
        "e-stop",
        &between(events["estop answered"] + 0.5, events["reset"]),
    );
    // The planner killed and back: the robot stands still where it was.
    at_rest(
        "planner restarted",
        &between(events["restarted gait_planner"] + 1.0, events["end"]),
    );
    assert!(rosout_has(
        &v,
        "gait_planner",
        &[
            "not in the planner's standing pose",
            "holding the measured pose"
        ]
    ));
    assert!(rosout_has(&v, "gait_planner", &["walk_command refused"]));
}

/// `/clock` published best effort, as `ros2 bag play --clock` and most simulators publish it
/// (rclcpp's ClockQoS): the planner on `use_sim_time` ticks on it, stamping what it
/// publishes with the clock values sent. A reliable-only `/clock` reader never matched such
/// a publisher: the planner stood still.
#[test]
fn a_best_effort_clock_drives_a_node_on_simulated_time() {
    let v = peer("clock", 92);
    let (sent, stamps) = clock_and_phase_stamps(&v);
    // The planner runs at 100 Hz and the clock advances 10 ms per message: most of the
    // ~400 clock values become a tick (best effort may drop a few on a busy machine).
    assert!(
        stamps.len() > sent.len() / 2,
        "{} phases for {} clock messages",
        stamps.len(),
        sent.len()
    );
    for s in &stamps {
        assert!(
            sent.contains(s),
            "phase stamped {s}, not a /clock value sent"
        );
    }
    // The last value, said six times, is the last tick.
    assert_eq!(stamps.iter().max(), sent.last());
    assert_eq!(
        v["exits"]["gait_planner"]["returncode"], 0,
        "{}",
        v["exits"]
    );
}

/// The `/clock` values the clock scenario sent and the `gait/phase` stamps it received (ns).
fn clock_and_phase_stamps(v: &Value) -> (Vec<i64>, Vec<i64>) {
    assert_eq!(
        v["matched"], true,
        "the /clock publisher never matched: {}",
        v["exits"]
    );
    let ns = |key: &str| -> Vec<i64> {
        v[key]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_i64().unwrap())
            .collect()
    };
    (ns("sent"), ns("phase_stamps"))
}

/// With `plan_ahead` the planner sends tick k's messages at `/clock` k - 1: every phase it
/// publishes is stamped one period (10 ms at 100 Hz) after a `/clock` value sent, but for
/// the first `/clock` it heard, which gets its own tick too; the last value, said six times
/// as a lockstep simulator says a tick while it waits, gets the phase of the tick after it,
/// a time no `/clock` carried. Without `use_sim_time` the parameter is refused, naming it
/// and what it needs (on the monotonic clock a command is taken when it comes: there is no
/// tick to be ahead of), and how to run without it (`config/sim.yaml` sets it).
#[test]
fn a_planner_ahead_sends_each_tick_one_period_before_its_clock() {
    let v = peer_with_params(
        "clock",
        218,
        Some(common::root().join("tests/data/plan_ahead.yaml")),
    );
    let (sent, stamps) = clock_and_phase_stamps(&v);
    assert!(stamps.len() > sent.len() / 2, "{} phases", stamps.len());
    let period_ns = 10_000_000;
    let first = stamps[0];
    assert!(sent.contains(&first), "first phase stamped {first}");
    for s in &stamps[1..] {
        assert!(
            sent.contains(&(s - period_ns)),
            "phase stamped {s}: not one period after a /clock value sent"
        );
    }
    let last = *sent.last().unwrap();
    assert_eq!(stamps.iter().max(), Some(&(last + period_ns)));
    assert_eq!(
        v["exits"]["gait_planner"]["returncode"], 0,
        "{}",
        v["exits"]
    );

    let err = failed_start(
        common::in_netns("exec timeout 60 \"$@\"", 218)
            .arg(bin_dir().join("gait_planner"))
            .args(["--ros-args", "-p", "plan_ahead:=true"]),
    );
    assert!(
        err.contains("`plan_ahead` = true needs `use_sim_time` = true")
            && err.contains("set `plan_ahead: false`"),
        "{err}"
    );
}

/// `ROS_AUTOMATIC_DISCOVERY_RANGE=OFF` as ROS 2 Jazzy's rmw_fastrtps means it, against
/// rclpy on Fast DDS: an OFF node is found by no one, not even by a LOCALHOST peer on the
/// same machine that announces itself to it, while a LOCALHOST node beside it is found and
/// walked (the control). Before, OFF was taken as LOCALHOST: the node was found.
#[test]
fn a_node_with_discovery_off_is_found_by_no_one() {
    let v = peer("discovery_off", 95);
    assert_eq!(
        v["planner_seen"], true,
        "control: the LOCALHOST planner was never seen: {}",
        v["exits"]
    );
    assert_eq!(v["walk_command_matched"], true, "{}", v["exits"]);
    assert_eq!(
        v["walked"], true,
        "control: the peer's walk command did not start the walk"
    );
    let seen: Vec<&str> = v["nodes_seen"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_str().unwrap())
        .collect();
    assert!(
        !seen.contains(&"ik_solver"),
        "the IK node, OFF, was found: {seen:?}"
    );
    assert_eq!(
        v["ankle_targets_subscribers"], 0,
        "the OFF IK node's /gait/ankle_targets subscription was found"
    );
    for node in ["gait_planner", "ik_solver"] {
        assert_eq!(v["exits"][node]["returncode"], 0, "{}", v["exits"]);
    }
}

/// `biped launch` refuses a DDS environment its fleet cannot work in, naming it, before any
/// node starts: discovery OFF (its nodes, separate processes, would never find each other)
/// and a `ROS_DOMAIN_ID` that is not one (every node would refuse it, restarted in a loop).
#[test]
fn launch_refuses_discovery_off_and_a_bad_domain_before_starting_a_node() {
    for (var, value) in [
        ("ROS_AUTOMATIC_DISCOVERY_RANGE", "OFF"),
        ("ROS_DOMAIN_ID", "seven"),
    ] {
        let log_dir = std::env::temp_dir().join(format!(
            "biped-launch-refused-{}-{value}",
            std::process::id()
        ));
        // Were it not refused, the fleet would run until the timeout (exit 124).
        let err = failed_start(
            common::in_netns("exec timeout 60 \"$@\"", 232)
                .arg(bin_dir().join("biped"))
                .args(["launch", "--no-respawn", "--log-dir"])
                .arg(&log_dir)
                .env(var, value),
        );
        assert!(
            err.contains(&format!("{var}={value}")),
            "{var}={value}: {err}"
        );
        assert!(!log_dir.exists(), "{var}={value}: a node was started");
    }
}

/// The CPUs in a `Cpus_allowed_list` line of /proc (`0-1,3`).
fn cpu_list(text: &str) -> Vec<usize> {
    let list = text
        .lines()
        .find_map(|l| l.strip_prefix("Cpus_allowed_list:"))
        .expect("a Cpus_allowed_list line")
        .trim();
    list.split(',')
        .flat_map(|part| match part.split_once('-') {
            Some((a, b)) => (a.parse().unwrap()..=b.parse().unwrap()).collect::<Vec<usize>>(),
            None => vec![part.parse().unwrap()],
        })
        .collect()
}

/// Starts `program` (a binary beside the tests) with `args` in a private network namespace on
/// `domain` under `timeout 60`, and waits for its "ready" line; returns the `unshare` child
/// and the pid of the program's own process.
fn start_ready_in_netns(
    domain: u32,
    program: &str,
    args: &[&str],
) -> (std::process::Child, String) {
    use std::io::{BufRead, BufReader};
    let mut process = common::in_netns("exec timeout 60 \"$@\"", domain)
        .arg(bin_dir().join(program))
        .args(args)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("unshare runs (root needed for a private network namespace)");
    let mut log = String::new();
    for line in BufReader::new(process.stderr.take().unwrap()).lines() {
        let line = line.unwrap();
        log.push_str(&line);
        log.push('\n');
        if line.contains("ready") {
            break;
        }
    }
    assert!(log.contains("ready"), "{program} did not start: {log}");
    // `unshare` and `sh` exec `timeout`, whose child is the program's process.
    let children =
        std::fs::read_to_string(format!("/proc/{0}/task/{0}/children", process.id())).unwrap();
    let pid = children
        .split_whitespace()
        .next()
        .expect("timeout runs the program")
        .to_owned();
    (process, pid)
}

/// Kills what [`start_ready_in_netns`] started: the program (killing `timeout` would leave
/// it running); `timeout` then ends.
fn kill_started(mut process: std::process::Child, pid: &str) {
    let pid = nix::unistd::Pid::from_raw(pid.parse().unwrap());
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGKILL).unwrap();
    process.wait().unwrap();
}

/// `cpu_affinity` (as ros2_control_node's) binds every thread of a node's process, the DDS
/// threads included, to the CPUs given; a CPU it may not use is refused by number, and
/// `biped compose` refuses it for a node (its nodes share one process).
#[test]
fn cpu_affinity_binds_every_thread_of_a_node_and_a_bad_cpu_is_refused_by_number() {
    // The last CPU this test may use: unless the machine has one CPU, not where an unbound
    // node would be.
    let ours = cpu_list(&std::fs::read_to_string("/proc/self/status").unwrap());
    let cpu = *ours.last().unwrap();
    let cpus = format!("cpu_affinity:=[{cpu}]");
    let (node, pid) = start_ready_in_netns(196, "ik_solver", &["--ros-args", "-p", &cpus]);
    // Every thread the node has started by now (main, signal, DDS event loop and discovery,
    // async-io) is bound.
    let tasks: Vec<(String, Vec<usize>)> = std::fs::read_dir(format!("/proc/{pid}/task"))
        .unwrap()
        .map(|t| {
            let status = std::fs::read_to_string(t.unwrap().path().join("status")).unwrap();
            let name = status.lines().next().unwrap_or_default().to_owned();
            (name, cpu_list(&status))
        })
        .collect();
    kill_started(node, &pid);
    assert!(tasks.len() >= 3, "{tasks:?}");
    for (name, cpus) in &tasks {
        assert_eq!(cpus, &vec![cpu], "{name} (of {tasks:?})");
    }

    let err = failed_start(
        common::in_netns("exec timeout 60 \"$@\"", 197)
            .arg(bin_dir().join("ik_solver"))
            .args(["--ros-args", "-p", "cpu_affinity:=[1023]"]),
    );
    assert!(
        err.contains(
            "ik_solver: error: parameters: parameter `cpu_affinity`: CPU [1023] is not one"
        ),
        "{err}"
    );

    let err = failed_start(
        common::in_netns("exec timeout 60 \"$@\"", 197)
            .arg(bin_dir().join("biped"))
            .args(["compose", "--node", "ik_solver", "--node", "joint_bridge"])
            .args(["--ros-args", "-p", &format!("cpu_affinity:=[{cpu}]")]),
    );
    assert!(
        err.contains("parameter `cpu_affinity` binds a node's own process"),
        "{err}"
    );
}

/// The files a process holds open that are the PM QoS CPU latency device.
fn held_latency_requests(pid: &str) -> usize {
    std::fs::read_dir(format!("/proc/{pid}/fd"))
        .unwrap()
        .filter(|fd| {
            std::fs::read_link(fd.as_ref().unwrap().path()).is_ok_and(|target| {
                target == std::path::Path::new(node_runtime::cpu_latency::CPU_DMA_LATENCY_DEVICE)
            })
        })
        .count()
}

/// `cpu_dma_latency_us` makes a node's process hold a CPU latency request (the PM QoS device
/// open, the machine's limit at most the value) for as long as it runs; `biped compose` holds
/// one, the lowest its nodes ask for; a value that is not microseconds is refused naming it.
#[test]
fn cpu_dma_latency_is_held_while_a_node_runs_and_a_bad_value_is_refused_naming_it() {
    let limit_us = || node_runtime::cpu_latency::current_limit_us().unwrap();
    let (node, pid) = start_ready_in_netns(
        198,
        "ik_solver",
        &["--ros-args", "-p", "cpu_dma_latency_us:=50"],
    );
    let held = held_latency_requests(&pid);
    let limit = limit_us();
    kill_started(node, &pid);
    assert_eq!(held, 1, "the ik_solver holds {held} requests");
    assert!(limit <= 50, "the machine's limit is {limit} µs");

    let (node, pid) = start_ready_in_netns(198, "ik_solver", &[]);
    let held = held_latency_requests(&pid);
    kill_started(node, &pid);
    assert_eq!(held, 0, "unset, the ik_solver still holds {held} requests");

    let (composed, pid) = start_ready_in_netns(
        199,
        "biped",
        &[
            "compose",
            "--node",
            "ik_solver",
            "--ros-args",
            "-p",
            "cpu_dma_latency_us:=80",
            "--node",
            "joint_bridge",
            "--ros-args",
            "-p",
            "backend:=mock",
            "-p",
            "cpu_dma_latency_us:=60",
        ],
    );
    let held = held_latency_requests(&pid);
    let limit = limit_us();
    kill_started(composed, &pid);
    assert_eq!(held, 1, "biped compose holds {held} requests");
    assert!(
        limit <= 60,
        "the machine's limit is {limit} µs, not its nodes' lowest"
    );

    for value in ["-1", "0.5", "fast"] {
        assert_ik_solver_refuses(199, "cpu_dma_latency_us", value);
    }
}

/// Runs `command`, which must fail to start (exit status 1); its standard error.
fn failed_start(command: &mut std::process::Command) -> String {
    let out = command.output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "{err}");
    err
}

/// The ik_solver given `-p PARAM:=VALUE` does not start, and its error names the parameter
/// and the value.
fn assert_ik_solver_refuses(domain: u32, param: &str, value: &str) {
    let err = failed_start(
        common::in_netns("exec timeout 60 \"$@\"", domain)
            .arg(bin_dir().join("ik_solver"))
            .args(["--ros-args", "-p", &format!("{param}:={value}")]),
    );
    assert!(
        err.contains(&format!(
            "ik_solver: error: parameters: parameter `{param}`: "
        )) && err.contains(value),
        "{value}: {err}"
    );
}

/// The scheduling policy and real-time priority of every thread of process `pid`, with the
/// thread's name.
fn thread_policies(pid: &str) -> Vec<(String, (u32, u32))> {
    std::fs::read_dir(format!("/proc/{pid}/task"))
        .unwrap()
        .map(|t| {
            let t = t.unwrap().path();
            let name = std::fs::read_to_string(t.join("comm")).unwrap();
            let stat = std::fs::read_to_string(t.join("stat")).unwrap();
            let policy = node_runtime::priority::task_policy(&stat).unwrap();
            (name.trim().to_owned(), policy)
        })
        .collect()
}

/// `thread_priority` (as ros2_control_node's) runs every thread of a node's process, the DDS
/// threads included, under SCHED_FIFO at that priority; unset, they stay with the normal
/// scheduler; `biped compose` runs its process at the highest its nodes ask for. Without the
/// privilege it takes the node does not start and says what it takes; a value that is not a
/// priority is refused naming it.
#[test]
fn thread_priority_runs_every_thread_under_sched_fifo_and_a_refusal_says_what_it_takes() {
    const FIFO: u32 = 1;
    let (node, pid) = start_ready_in_netns(
        213,
        "ik_solver",
        &["--ros-args", "-p", "thread_priority:=30"],
    );
    let tasks = thread_policies(&pid);
    kill_started(node, &pid);
    // Main, signal, DDS event loop and discovery, async-io.
    assert!(tasks.len() >= 3, "{tasks:?}");
    for (name, policy) in &tasks {
        assert_eq!(policy, &(FIFO, 30), "{name} (of {tasks:?})");
    }

    let (node, pid) = start_ready_in_netns(213, "ik_solver", &[]);
    let tasks = thread_policies(&pid);
    kill_started(node, &pid);
    for (name, policy) in &tasks {
        assert_eq!(policy, &(0, 0), "unset: {name} (of {tasks:?})");
    }

    let (composed, pid) = start_ready_in_netns(
        214,
        "biped",
        &[
            "compose",
            "--node",
            "ik_solver",
            "--ros-args",
            "-p",
            "thread_priority:=20",
            "--node",
            "joint_bridge",
            "--ros-args",
            "-p",
            "backend:=mock",
            "-p",
            "thread_priority:=40",
        ],
    );
    let tasks = thread_policies(&pid);
    kill_started(composed, &pid);
    assert!(tasks.len() >= 3, "{tasks:?}");
    for (name, policy) in &tasks {
        assert_eq!(policy, &(FIFO, 40), "composed: {name} (of {tasks:?})");
    }

    // Root without CAP_SYS_NICE, with an RLIMIT_RTPRIO of 0: refused.
    let err = failed_start(
        common::in_netns("exec timeout 60 \"$@\"", 214)
            .args(["setpriv", "--bounding-set", "-sys_nice"])
            .args(["prlimit", "--rtprio=0"])
            .arg(bin_dir().join("ik_solver"))
            .args(["--ros-args", "-p", "thread_priority:=50"]),
    );
    assert!(
        err.contains(
            "ik_solver: error: parameter `thread_priority` = 50: cannot run the process under \
             SCHED_FIFO (it takes CAP_SYS_NICE"
        ) && err.contains("Operation not permitted"),
        "{err}"
    );

    for value in ["0", "100", "high"] {
        assert_ik_solver_refuses(214, "thread_priority", value);
    }
}
