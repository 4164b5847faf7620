//! What RViz, Foxglove and tf2 get from a walk: the TF tree in a bag of `biped walk`, read by
//! an independent reader (rosbags) and checked against an independent kinematics library
//! (Pinocchio) by tests/python/tf_check.py; the assertions are here. Each walk runs in a
//! private network namespace on its own ROS_DOMAIN_ID (79, 80).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;

use common::{python, root};
use serde_json::Value;

/// `biped walk --steps 2 --bag` (extra args before) in a private network namespace, then
/// tf_check.py on the bag: its JSON.
fn walk_and_check(domain_id: u32, name: &str, urdf: &Path, args: &[&str]) -> Value {
    let dir = walk_dir(name);
    let _ = std::fs::remove_dir_all(&dir);
    let bag = dir.join("bag");
    let mut walk_args = vec!["--steps", "2", "--bag", bag.to_str().unwrap()];
    walk_args.extend(args);
    common::biped_walk_ok(domain_id, &dir.join("out"), &walk_args);
    let check = Command::new(python())
        .arg(root().join("tests/python/tf_check.py"))
        .arg(dir.join("bag"))
        .arg(urdf)
        .output()
        .unwrap();
    assert!(
        check.status.success(),
        "tf_check: {}",
        String::from_utf8_lossy(&check.stderr)
    );
    serde_json::from_slice(&check.stdout).unwrap()
}

fn strings(v: &Value) -> BTreeSet<String> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|s| s.as_str().unwrap().to_owned())
        .collect()
}

fn assert_tf_tree(v: &Value) {
    let root_link = v["root"].as_str().unwrap();
    // Every link of the URDF (as Pinocchio reads it) is a frame of the tree: the root, or
    // the child of a /tf_static or /tf edge.
    let links = strings(&v["links"]);
    let mut covered: BTreeSet<String> = BTreeSet::from([root_link.to_owned()]);
    for e in v["static_edges"]
        .as_array()
        .unwrap()
        .iter()
        .chain(v["moving_edges"].as_array().unwrap())
    {
        covered.insert(e[1].as_str().unwrap().to_owned());
    }
    assert_eq!(covered, links, "frames on /tf and /tf_static vs URDF links");
    assert!(
        v["missing_links"].as_array().unwrap().is_empty(),
        "{}",
        v["missing_links"]
    );
    // Each joint state has its /tf message (where both topics were recorded: the recorder
    // subscribes each topic as it discovers it, so each starts at its own time), and the
    // links placed by it agree with Pinocchio's FK of the same positions.
    let states = v["joint_states"].as_u64().unwrap();
    let in_span = v["joint_states_in_tf_span"].as_u64().unwrap();
    let compared = v["compared"].as_u64().unwrap();
    assert!(states > 500, "{states} joint states in the bag");
    assert!(
        in_span > 500,
        "{in_span} joint states while /tf was recorded"
    );
    assert!(
        compared * 100 >= in_span * 95,
        "only {compared} of {in_span} joint states have a /tf message of their stamp"
    );
    let pos = v["max_position_error_m"].as_f64().unwrap();
    let rot = v["max_rotation_error"].as_f64().unwrap();
    assert!(pos < 1e-6, "links off Pinocchio's FK by {pos} m");
    assert!(rot < 1e-6, "link rotations off Pinocchio's by {rot}");
    // odom -> base link, one per /odom message, the same pose.
    let odom = &v["odom_tf"];
    let count = odom["count"].as_u64().unwrap();
    let in_span = odom["in_odom_span"].as_u64().unwrap();
    assert!(count > 500 && in_span > 500, "{odom}");
    assert_eq!(
        strings(&odom["children"]),
        BTreeSet::from([root_link.to_owned()])
    );
    assert!(
        odom["matched_odom"].as_u64().unwrap() * 100 >= in_span * 95,
        "{odom}"
    );
    assert!(odom["max_difference"].as_f64().unwrap() < 1e-12, "{odom}");
    // The simulator's ground truth beside it, world -> base_gt; the robot walked about two
    // steps (2 x 45 mm) forward by both, and the odometry ends within 2 cm of the truth.
    let world = &v["world_tf"];
    assert_eq!(
        world["edges"],
        serde_json::json!([["world", format!("{root_link}_gt")]])
    );
    let end = &world["end_xy"];
    let (wx, wy) = (
        end["world"][0].as_f64().unwrap(),
        end["world"][1].as_f64().unwrap(),
    );
    let (ox, oy) = (
        end["odom"][0].as_f64().unwrap(),
        end["odom"][1].as_f64().unwrap(),
    );
    assert!(wx > 0.06, "the ground truth moved {wx} m");
    assert!(
        ((wx - ox).powi(2) + (wy - oy).powi(2)).sqrt() < 0.02,
        "odometry ends at ({ox}, {oy}), the truth at ({wx}, {wy})"
    );
}

#[test]
fn a_walks_bag_holds_every_link_on_tf_as_pinocchio_places_it() {
    let urdf = root().join("config/biped.urdf");
    assert_tf_tree(&walk_and_check(79, "default", &urdf, &[]));
    // By default both per-message nodes do their work on the DDS thread that receives it.
    let log = std::fs::read_to_string(log_of("default", "robot_state_publisher")).unwrap();
    assert!(
        log.contains("frames published on the DDS thread that receives each joint state"),
        "{log}"
    );
    let log = std::fs::read_to_string(log_of("default", "ik_solver")).unwrap();
    assert!(
        log.contains("leg joints on the DDS thread that receives each message"),
        "{log}"
    );
}

/// Where [`walk_and_check`]'s walk `name` writes.
fn walk_dir(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("biped-tf-{name}-{}", std::process::id()))
}

/// The log of `node` in [`walk_and_check`]'s walk `name`.
fn log_of(name: &str, node: &str) -> PathBuf {
    walk_dir(name).join(format!("out/logs/{node}.log"))
}

/// A robot we did not tune for: six joints per leg with hip yaw, renamed joints and
/// links, flipped axes; and robot_state_publisher with `publish_on_receive` false (each
/// joint state's frames published by the node's own thread, woken by the DDS thread that
/// received it), which must change nothing of what is published.
#[test]
fn the_six_joint_robots_tf_tree_agrees_with_pinocchio_too_published_on_the_nodes_thread() {
    let urdf = root().join("tests/data/biped6_renamed.urdf");
    let robot = urdf.to_str().unwrap();
    let dir = std::env::temp_dir().join(format!("biped-tf-params-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let params = dir.join("on_thread.yaml");
    std::fs::write(
        &params,
        "robot_state_publisher:\n  ros__parameters:\n    publish_on_receive: false\n",
    )
    .unwrap();
    let args = ["--robot", robot, "--params", params.to_str().unwrap()];
    assert_tf_tree(&walk_and_check(80, "biped6", &urdf, &args));
    let log = std::fs::read_to_string(log_of("biped6", "robot_state_publisher")).unwrap();
    assert!(
        log.contains("frames published on the node's thread"),
        "{log}"
    );
}
