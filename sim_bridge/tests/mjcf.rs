//! An MJCF-loaded robot: a scene written for these tests (sim_bridge/tests/data), not
//! generated from the URDF, tied to config/biped.urdf by a joint map. The scene's robot
//! walking a plan: walk_eval/tests/mjcf_walk.rs.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::PathBuf;

use ik_solver::{BipedModel, DEFAULT_URDF};
use joint_bridge::{Backend, JointSpec};
use sim_bridge::{JointMap, Sim, SimBackend, SimConfig, SimError};

fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

fn scene_text() -> String {
    std::fs::read_to_string(data("biped20_scene.xml")).unwrap()
}

fn map_text() -> String {
    std::fs::read_to_string(data("biped20_scene_map.yaml")).unwrap()
}

fn map() -> JointMap {
    JointMap::from_yaml_file(data("biped20_scene_map.yaml")).unwrap()
}

fn from_text(scene: &str, map_yaml: &str) -> Result<Sim, SimError> {
    let map = JointMap::from_yaml_str(map_yaml)?;
    Sim::from_mjcf_str(scene, &map, DEFAULT_URDF, None, &SimConfig::default())
}

#[test]
fn the_scene_robot_stands_on_its_soles() {
    let mut sim = from_text(&scene_text(), &map_text()).unwrap();
    let zeros = vec![0.0; sim.joint_names().len()];
    sim.stand(&zeros).unwrap();
    sim.step(2.0).unwrap();
    let c = sim.contacts();
    let ratio = c.normal_force_sum_n / sim.weight_n();
    assert!(
        (ratio - 1.0).abs() < 0.01,
        "floor carries {ratio} of the weight"
    );
    // Both soles (the named one and the found one) carry the robot, nothing else touches.
    assert_eq!(c.loaded, [true, true]);
    assert_eq!(c.other_force_n, 0.0);
    assert!(sim.fallen().is_none());
    // Straight legs: base 0.24 m above the soles, less a little sag and penetration.
    let z = sim.base_pose().translation.z;
    assert!((0.235..0.2405).contains(&z), "base at {z} m");
    // A joint target moves the mapped scene joint and no other: bend the left elbow.
    let elbow = sim
        .joint_names()
        .iter()
        .position(|n| n == "l_elbow")
        .unwrap();
    let before = sim.joint_positions_rad();
    let mut q = zeros.clone();
    q[elbow] = -0.5;
    sim.set_targets(&q).unwrap();
    sim.step(0.5).unwrap();
    let got = sim.joint_positions_rad();
    assert!(
        (got[elbow] + 0.5).abs() < 0.01,
        "elbow at {} rad",
        got[elbow]
    );
    for (i, (a, b)) in before.iter().zip(&got).enumerate() {
        if i != elbow {
            assert!(
                (a - b).abs() < 0.01,
                "{} moved {a} -> {b}",
                sim.joint_names()[i]
            );
        }
    }
    assert!(sim.fallen().is_none());
}

#[test]
fn the_joint_bridge_drives_the_scene_robot() {
    let model = BipedModel::from_urdf_str(DEFAULT_URDF, None).unwrap();
    let joints = JointSpec::from_robot(model.robot());
    let mut backend = SimBackend::new(DEFAULT_URDF, SimConfig::default())
        .with_mjcf(data("biped20_scene.xml"), map());
    let measured = backend.configure(&joints).unwrap().unwrap();
    assert_eq!(measured.len(), joints.len());
    backend.activate().unwrap();
    let elbow = joints.iter().position(|j| j.name == "l_elbow").unwrap();
    let mut q = vec![0.0; joints.len()];
    q[elbow] = -0.5;
    backend.write(0.0, &q).unwrap();
    let reading = backend.read(0.5).unwrap();
    assert!(reading.measured);
    assert!(
        (reading.positions_rad[elbow] + 0.5).abs() < 0.01,
        "elbow at {}",
        reading.positions_rad[elbow]
    );
    let sim = backend.sim().unwrap();
    assert!(sim.fallen().is_none());
    assert_eq!(sim.config().kp_nm_per_rad, 30.0);
    // A bad scene is reported by configure, naming the file.
    let e = SimBackend::new(DEFAULT_URDF, SimConfig::default())
        .with_mjcf(data("no_such_scene.xml"), map())
        .configure(&joints)
        .unwrap_err();
    assert!(e.to_string().contains("no_such_scene.xml"), "{e}");
}

/// Builds from edited scene and map texts; returns the error text.
fn error(scene: &str, map_yaml: &str) -> String {
    let e = from_text(scene, map_yaml).unwrap_err();
    eprintln!("{e}");
    e.to_string()
}

fn has(text: &str, parts: &[&str]) {
    for p in parts {
        assert!(text.contains(p), "`{p}` not in: {text}");
    }
}

#[test]
fn bad_scenes_and_maps_are_refused_by_name() {
    let (scene, map) = (scene_text(), map_text());
    let replace = |text: &str, from: &str, to: &str| {
        assert!(text.contains(from), "{from}");
        text.replacen(from, to, 1)
    };
    // The map forgets a URDF joint.
    let e = error(
        &scene,
        &replace(
            &map,
            "  l_knee: {joint: knee_L, actuator: act_knee_L}\n",
            "",
        ),
    );
    has(&e, &["joints", "l_knee", "not mapped"]);
    // ... or maps one the URDF does not have.
    let e = error(
        &scene,
        &format!("{map}  tail: {{joint: knee_L, actuator: act_knee_L}}\n"),
    );
    has(&e, &["joints.tail", "not a movable joint"]);
    // Two URDF joints on one scene joint.
    let e = error(&scene, &replace(&map, "{joint: knee_R,", "{joint: knee_L,"));
    has(&e, &["knee_L", "already mapped"]);
    // A misspelt key of the map file.
    let e = error(&scene, &replace(&map, "floor_geom:", "floor_gem:"));
    has(&e, &["floor_gem"]);
    let e = error(&scene, &replace(&map, "{joint: knee_L,", "{jiont: knee_L,"));
    has(&e, &["jiont"]);
    // Names the scene does not have.
    let e = error(
        &scene,
        &replace(&map, "{joint: knee_L,", "{joint: knee_left,"),
    );
    has(&e, &["joint `knee_left`"]);
    let e = error(
        &scene,
        &replace(&map, "actuator: act_knee_L}", "actuator: knee_L_servo}"),
    );
    has(&e, &["actuator `knee_L_servo`"]);
    let e = error(
        &scene,
        &replace(&map, "base_link: torso", "base_link: pelvis"),
    );
    has(&e, &["body `pelvis`"]);
    let e = error(&scene, &replace(&map, "  r_foot: foot_R\n", ""));
    has(&e, &["links", "r_foot"]);
    let e = error(
        &scene,
        &replace(&map, "l_foot: sole_L", "l_foot: thigh_L_box"),
    );
    has(&e, &["soles.l_foot", "thigh_L_box", "foot_L"]);
    let e = error(
        &scene,
        &replace(&map, "floor_geom: ground", "floor_geom: lawn"),
    );
    has(&e, &["geom `lawn`"]);
    // Actuators that are not position servos on their joint.
    let e = error(
        &replace(
            &scene,
            r#"<position name="act_knee_L" joint="knee_L"/>"#,
            r#"<motor name="act_knee_L" joint="knee_L"/>"#,
        ),
        &map,
    );
    has(&e, &["act_knee_L", "not a position servo"]);
    let e = error(
        &replace(
            &scene,
            r#"<position name="act_knee_L" joint="knee_L"/>"#,
            r#"<velocity name="act_knee_L" joint="knee_L" kv="1"/>"#,
        ),
        &map,
    );
    has(&e, &["act_knee_L", "not a position servo"]);
    let e = error(
        &replace(
            &scene,
            r#"<position name="act_knee_L" joint="knee_L"/>"#,
            r#"<position name="act_knee_L" joint="knee_L" timeconst="0.01"/>"#,
        ),
        &map,
    );
    has(&e, &["act_knee_L", "activation dynamics"]);
    let swapped = replace(
        &replace(
            &map,
            "{joint: knee_L, actuator: act_knee_L}",
            "{joint: knee_L, actuator: act_hip_pitch_L}",
        ),
        "{joint: hip_pitch_L, actuator: act_hip_pitch_L}",
        "{joint: hip_pitch_L, actuator: act_knee_L}",
    );
    let e = error(&scene, &swapped);
    has(&e, &["act_knee_L", "does not drive joint `hip_pitch_L`"]);
    let e = error(
        &replace(
            &scene,
            r#"<position name="act_knee_L" joint="knee_L"/>"#,
            r#"<position name="act_knee_L" joint="knee_L" kp="40"/>"#,
        ),
        &map,
    );
    has(&e, &["act_knee_L", "kp 40"]);
    // A joint of another type than the URDF's.
    let e = error(
        &replace(
            &scene,
            r#"<joint name="knee_L" axis="0 1 0""#,
            r#"<joint name="knee_L" type="slide" axis="0 1 0""#,
        ),
        &map,
    );
    has(&e, &["joints.l_knee.joint", "hinge"]);
    // Scene joints and actuators the map forgets.
    let tail = r#"<body name="tail" pos="-0.05 0 0"><joint name="tail_hinge" axis="0 1 0"/><inertial pos="0 0 0" mass="0.01" diaginertia="1e-6 1e-6 1e-6"/></body>
      <body name="chest""#;
    let e = error(&replace(&scene, r#"<body name="chest""#, tail), &map);
    has(&e, &["tail_hinge", "not in the joint map"]);
    let e = error(
        &replace(
            &scene,
            "  </actuator>",
            r#"    <position name="act_extra" joint="knee_L"/>
  </actuator>"#,
        ),
        &map,
    );
    has(&e, &["act_extra", "not in the joint map"]);
    // No free joint: the robot would hang in the air.
    let e = error(
        &replace(&scene, r#"<freejoint name="floating_base"/>"#, ""),
        &map,
    );
    has(&e, &["no free joint"]);
    // A scene MuJoCo cannot read.
    let e = error(&scene[..scene.len() / 2], &map);
    has(&e, &["MuJoCo cannot parse"]);
    let e = Sim::from_mjcf_file(
        data("no_such_scene.xml"),
        &self::map(),
        DEFAULT_URDF,
        None,
        &SimConfig::default(),
    )
    .unwrap_err();
    has(&e.to_string(), &["no_such_scene.xml"]);
    let e = JointMap::from_yaml_file(data("no_such_map.yaml")).unwrap_err();
    has(&e.to_string(), &["no_such_map.yaml"]);
}
