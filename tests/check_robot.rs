//! `biped check-robot` as a newcomer runs it: on the OP3-layout test robot with its scene
//! (accepted, its offsets reported, the legs drawn), and on broken URDFs (every problem
//! listed by name, exit 1).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use common::{bin_dir, root};

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("biped-check-robot-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn check_robot(urdf: &Path, extra: &[&Path], svg: &Path) -> Output {
    let mut c = Command::new(bin_dir().join("biped"));
    c.arg("check-robot").arg(urdf).arg("--svg").arg(svg);
    for pair in extra.chunks(2) {
        c.arg(pair[0]).arg(pair[1]);
    }
    c.output().unwrap()
}

fn op3_urdf() -> String {
    std::fs::read_to_string(root().join("tests/data/op3_layout.urdf")).unwrap()
}

/// `text` with `from` replaced once, after `anchor`.
fn edit(text: &str, anchor: &str, from: &str, to: &str) -> String {
    let a = text.find(anchor).unwrap_or_else(|| panic!("{anchor:?}"));
    let at = a + text[a..].find(from).unwrap_or_else(|| panic!("{from:?}"));
    format!("{}{to}{}", &text[..at], &text[at + from.len()..])
}

#[test]
fn the_op3_layout_robot_is_accepted_and_its_offsets_and_legs_are_shown() {
    let dir = scratch("op3");
    let svg = dir.join("legs.svg");
    let data = root().join("tests/data");
    let out = check_robot(
        &data.join("op3_layout.urdf"),
        &[
            Path::new("--mjcf"),
            &data.join("op3_layout_scene.xml"),
            Path::new("--joint-map"),
            &data.join("op3_layout_scene_map.yaml"),
        ],
        &svg,
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // The numbers of tests/data/make_op3_layout.py, as the stack reads them.
    for want in [
        "20 movable joints, 2.940 kg",
        "`l_hip_yaw`",
        "hip_roll     `r_hip_roll`             axis -x",
        "hip_pitch    `r_hip_pitch`            axis -y",
        "hip point (0.0050, 0.0350, -0.0630) m",
        "e = 0.0060 m",
        "e = -0.0060 m",
        "a_h = 0.0030 m",
        "h_h = 0.0040 m",
        "sole 0.110 x 0.066 m",
        "passes the stability check",
        "accepted, 20 joints driven, 2.940 kg (URDF 2.940 kg)",
        "no problems found",
    ] {
        assert!(stdout.contains(want), "no {want:?} in:\n{stdout}");
    }
    // Two views; each of the 12 leg joints is a ring in one view (pitch axes from the side,
    // roll axes from the front) and a line in the other.
    let drawing = std::fs::read_to_string(&svg).unwrap();
    assert_eq!(drawing.matches("<g class=\"view\">").count(), 2);
    assert_eq!(
        drawing.matches("class=\"axis-across\"").count(),
        3 * 2 + 2 * 2
    );
    assert_eq!(drawing.matches("class=\"axis-along\"").count(), 24 - 10);
    assert_eq!(drawing.matches("class=\"sole\"").count(), 4);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn every_problem_of_a_broken_urdf_is_listed_by_name() {
    let dir = scratch("broken");
    // Three independent mistakes: a NaN in a joint origin, a negative mass, a zero axis.
    let mut urdf = edit(
        &op3_urdf(),
        "<joint name=\"l_knee\"",
        "xyz=\"0.002 0 -0.1\"",
        "xyz=\"0.002 nan -0.1\"",
    );
    urdf = edit(
        &urdf,
        "<link name=\"r_shin\"",
        "<mass value=\"0.1\"/>",
        "<mass value=\"-0.1\"/>",
    );
    urdf = edit(
        &urdf,
        "<joint name=\"head_tilt\"",
        "<axis xyz=\"0 1 0\"/>",
        "<axis xyz=\"0 0 0\"/>",
    );
    let path = dir.join("broken.urdf");
    std::fs::write(&path, urdf).unwrap();
    let out = check_robot(&path, &[], &dir.join("legs.svg"));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    for want in [
        "`l_knee`",
        "`r_shin`",
        "-0.1",
        "`head_tilt`",
        "3 problem(s)",
    ] {
        assert!(stderr.contains(want), "no {want:?} in:\n{stderr}");
    }
    assert_eq!(stderr.matches("problem: ").count(), 3, "{stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn both_legs_of_an_unsupported_layout_are_named() {
    let dir = scratch("legs");
    // Left: the ankle roll axis 5 mm above the pitch axis. Right: the hip roll joint 4 mm
    // left of the yaw axis, which so passes right of the roll axis.
    let mut urdf = edit(
        &op3_urdf(),
        "<joint name=\"l_ankle_roll\"",
        "xyz=\"-0.022 -0.01 0\"",
        "xyz=\"-0.022 -0.01 0.005\"",
    );
    urdf = edit(
        &urdf,
        "<joint name=\"r_hip_roll\"",
        "xyz=\"-0.024 0 -0.028\"",
        "xyz=\"-0.024 0.004 -0.028\"",
    );
    let path = dir.join("legs.urdf");
    std::fs::write(&path, urdf).unwrap();
    let out = check_robot(&path, &[], &dir.join("legs.svg"));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    for want in [
        "left leg",
        "`l_ankle_roll`",
        "0.005000 m above",
        "right leg",
        "`r_hip_yaw`",
        "0.004000 m right of the hip roll axis",
    ] {
        assert!(stderr.contains(want), "no {want:?} in:\n{stderr}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_file_that_is_not_a_urdf_and_a_missing_scene_map_are_named() {
    let dir = scratch("parse");
    let path = dir.join("truncated.urdf");
    let text = op3_urdf();
    std::fs::write(&path, &text[..text.len() / 2]).unwrap();
    let out = check_robot(&path, &[], &dir.join("legs.svg"));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("truncated.urdf"), "{stderr}");

    let data = root().join("tests/data");
    let missing = dir.join("no_such_map.yaml");
    let out = check_robot(
        &data.join("op3_layout.urdf"),
        &[
            Path::new("--mjcf"),
            &data.join("op3_layout_scene.xml"),
            Path::new("--joint-map"),
            &missing,
        ],
        &dir.join("legs.svg"),
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("no_such_map.yaml"), "{stderr}");
    // The robot itself is fine: it is still described.
    assert!(String::from_utf8_lossy(&out.stdout).contains("e = 0.0060 m"));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The malformed-URDF corpus of `ik_solver/tests/model_errors.rs`, one mistake per copy of
/// the default robot: `biped check-robot` refuses each (exit 1) and names what is wrong.
#[test]
fn each_malformed_urdf_of_the_corpus_is_refused_naming_the_fault() {
    let dir = scratch("corpus");
    let default = std::fs::read_to_string(root().join("config/biped.urdf")).unwrap();
    // (anchor, from, to, what the message must name)
    let corpus: [(&str, &str, &str, &[&str]); 12] = [
        (
            "<joint name=\"l_knee\"",
            "<child link=\"l_shin\"/>",
            "<child link=\"l_shinn\"/>",
            &["`l_knee`", "`l_shinn`"],
        ),
        (
            "<link name=\"l_shin\">",
            "<mass value=\"0.13\"/>",
            "<mass value=\"-0.13\"/>",
            &["`l_shin`", "-0.13"],
        ),
        (
            "<link name=\"r_foot\">",
            "ixx=\"3.08333e-05\"",
            "ixx=\"nan\"",
            &["`r_foot`", "non-finite"],
        ),
        (
            "<joint name=\"l_knee\"",
            "<origin xyz=\"0 0 -0.09\"",
            "<origin xyz=\"0 nan -0.09\"",
            &["`l_knee`", "NaN"],
        ),
        (
            "<link name=\"head\">",
            "<origin xyz=\"0 0 0.025\" rpy=\"0 0 0\"/>",
            "<origin xyz=\"0 0 0.025\" rpy=\"0 inf 0\"/>",
            &["`head`", "inf"],
        ),
        (
            "<joint name=\"l_knee\"",
            "lower=\"-0.05\" upper=\"2.3\"",
            "lower=\"2.3\" upper=\"-0.05\"",
            &["`l_knee`", "limits"],
        ),
        (
            "<joint name=\"r_ankle_pitch\"",
            "velocity=\"6.0\"",
            "velocity=\"0\"",
            &["`r_ankle_pitch`", "velocity"],
        ),
        (
            "<joint name=\"l_hip_pitch\"",
            "<axis xyz=\"0 1 0\"/>",
            "<axis xyz=\"0 0 0\"/>",
            &["`l_hip_pitch`", "zero-length axis"],
        ),
        (
            "<joint name=\"l_knee\"",
            "<axis xyz=\"0 1 0\"/>",
            "<axis xyz=\"0 0 1\"/>",
            &["`l_knee`", "knee joint (axis y)"],
        ),
        (
            "<joint name=\"r_hip_roll\"",
            "xyz=\"0 -0.037 -0.03\"",
            "xyz=\"0 0.037 -0.03\"",
            &["`l_hip_roll`", "`r_hip_roll`", "left side"],
        ),
        (
            "<joint name=\"l_ankle_roll\"",
            "<origin xyz=\"0 0 0\"",
            "<origin xyz=\"0 0 0.01\"",
            &["left leg", "`l_ankle_roll`", "0.010000 m above"],
        ),
        (
            "<joint name=\"neck_yaw\"",
            "<parent link=\"torso\"/>",
            "<parent link=\"nowhere\"/>",
            &["`neck_yaw`", "`nowhere`"],
        ),
    ];
    for (k, (anchor, from, to, want)) in corpus.iter().enumerate() {
        let path = dir.join(format!("malformed_{k}.urdf"));
        std::fs::write(&path, edit(&default, anchor, from, to)).unwrap();
        let out = check_robot(&path, &[], &dir.join("legs.svg"));
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{to}: {stderr}");
        assert!(stderr.contains("problem: "), "{to}: {stderr}");
        for w in *want {
            assert!(stderr.contains(w), "{to}: no {w:?} in:\n{stderr}");
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
