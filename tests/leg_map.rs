//! The leg map reaches every entry point: each node's `leg_map_file` parameter and
//! `biped walk` / `biped plan --leg-map`. A map naming a joint the URDF lacks stops each of
//! them before anything moves, naming the joint; a missing map file is named; a right map
//! walks the robot through the fleet.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::path::PathBuf;
use std::process::Command;

use common::{bin_dir, in_netns, root};

const NODES: [&str; 4] = ["gait_planner", "ik_solver", "joint_bridge", "sim_bridge"];

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("biped-leg-map-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The map of tests/data/biped6_renamed.urdf, with the left knee named `left_knee`.
fn map_text(left_knee: &str) -> String {
    format!(
        "left:  {{hip_yaw: LeftLegJ1,  hip_roll: LeftLegJ2,  hip_pitch: LeftLegJ3,  knee: {left_knee},  ankle_pitch: LeftLegJ5,  ankle_roll: LeftLegJ6}}\n\
         right: {{hip_yaw: RightLegJ1, hip_roll: RightLegJ2, hip_pitch: RightLegJ3, knee: RightLegJ4, ankle_pitch: RightLegJ5, ankle_roll: RightLegJ6}}\n"
    )
}

/// Starts a node (in a private network namespace, on domain 84) with these parameters;
/// it must exit by itself. Returns (exit code, stderr).
fn node_start_failure(node: &str, params: &[String]) -> (Option<i32>, String) {
    let mut c = in_netns("exec timeout 20 \"$@\"", 84);
    c.arg(bin_dir().join(node)).arg("--ros-args");
    for p in params {
        c.arg("-p").arg(p);
    }
    let out = c.output().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn every_node_reads_its_leg_map_and_refuses_a_wrong_one_naming_it() {
    let dir = scratch("nodes");
    let wrong = dir.join("wrong.yaml");
    std::fs::write(&wrong, map_text("LeftKnee")).unwrap();
    let robot = root().join("tests/data/biped6_renamed.urdf");
    let missing = dir.join("no_such_map.yaml");
    for node in NODES {
        let (code, stderr) = node_start_failure(
            node,
            &[
                format!("robot_description_file:={}", robot.display()),
                format!("leg_map_file:={}", wrong.display()),
            ],
        );
        assert!(
            code.is_some_and(|c| c != 0 && c != 124),
            "{node}: {code:?} {stderr}"
        );
        assert!(stderr.contains("`LeftKnee`"), "{node}: {stderr}");
        let (code, stderr) =
            node_start_failure(node, &[format!("leg_map_file:={}", missing.display())]);
        assert!(
            code.is_some_and(|c| c != 0 && c != 124),
            "{node}: {code:?} {stderr}"
        );
        assert!(
            stderr.contains("leg_map_file") && stderr.contains("no_such_map.yaml"),
            "{node}: {stderr}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn biped_plan_and_walk_take_the_leg_map() {
    let dir = scratch("cli");
    let robot = root().join("tests/data/biped6_renamed.urdf");
    let (good, wrong) = (dir.join("good.yaml"), dir.join("wrong.yaml"));
    std::fs::write(&good, map_text("LeftLegJ4")).unwrap();
    std::fs::write(&wrong, map_text("LeftKnee")).unwrap();
    let biped = || Command::new(bin_dir().join("biped"));

    let plan = |map: &PathBuf| {
        biped()
            .args(["plan", "--steps", "1", "--no-plots", "--robot"])
            .arg(&robot)
            .arg("--leg-map")
            .arg(map)
            .arg("--csv")
            .arg(dir.join("plan.csv"))
            .output()
            .unwrap()
    };
    let ok = plan(&good);
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    let bad = plan(&wrong);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("`LeftKnee`"));

    // The walk refuses the map before it starts anything.
    let walk = biped()
        .args(["walk", "--steps", "1", "--robot"])
        .arg(&robot)
        .arg("--leg-map")
        .arg(&wrong)
        .arg("--out")
        .arg(dir.join("walk"))
        .env("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        .env("ROS_DOMAIN_ID", "85")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&walk.stderr);
    assert!(!walk.status.success(), "{stderr}");
    assert!(stderr.contains("`LeftKnee`"), "{stderr}");
    assert!(!dir.join("walk/logs").exists(), "the fleet was started");

    // With the right map every node of the fleet takes it, and the robot walks.
    common::biped_walk_ok(
        85,
        &dir.join("walk_ok"),
        &[
            "--steps",
            "2",
            "--robot",
            robot.to_str().unwrap(),
            "--leg-map",
            good.to_str().unwrap(),
        ],
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
