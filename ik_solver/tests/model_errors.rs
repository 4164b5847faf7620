//! Malformed and non-biped URDFs are refused with a named [`ModelError`] variant whose message
//! names the link, joint or value at fault; nothing panics. Each bad URDF is the default robot
//! with one specific attribute or element edited, or a small inline document.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::*;
use ik_solver::{
    AnkleTarget, BipedModel, DEFAULT_URDF, JointRole, LegRoleMap, ModelError, RobotModel, Side,
};

/// The default URDF with the first `from` after the first `anchor` replaced by `to`. Fails the
/// test if either is missing, so an edit that no longer applies cannot pass silently.
fn edit(anchor: &str, from: &str, to: &str) -> String {
    edit_in(DEFAULT_URDF, anchor, from, to)
}

fn edit_in(urdf: &str, anchor: &str, from: &str, to: &str) -> String {
    let a = urdf
        .find(anchor)
        .unwrap_or_else(|| panic!("anchor {anchor:?} not in the URDF"));
    let off = urdf[a..]
        .find(from)
        .unwrap_or_else(|| panic!("{from:?} not found after {anchor:?}"));
    let at = a + off;
    format!("{}{}{}", &urdf[..at], to, &urdf[at + from.len()..])
}

/// The default URDF with the text from `start` (inclusive) to the next `end` (inclusive), both
/// found after `anchor`, removed.
fn cut(anchor: &str, start: &str, end: &str) -> String {
    let a = DEFAULT_URDF
        .find(anchor)
        .unwrap_or_else(|| panic!("anchor {anchor:?} not in the URDF"));
    let s = a + DEFAULT_URDF[a..]
        .find(start)
        .unwrap_or_else(|| panic!("{start:?} not after {anchor:?}"));
    let e = s
        + DEFAULT_URDF[s..]
            .find(end)
            .unwrap_or_else(|| panic!("{end:?} not after {start:?}"))
        + end.len();
    format!("{}{}", &DEFAULT_URDF[..s], &DEFAULT_URDF[e..])
}

/// The default URDF with `extra` inserted just before `</robot>`.
fn append(extra: &str) -> String {
    DEFAULT_URDF.replace("</robot>", &format!("{extra}\n</robot>"))
}

fn err(urdf: &str) -> ModelError {
    match BipedModel::from_urdf_str(urdf, None) {
        Ok(_) => panic!("the URDF was accepted"),
        Err(e) => e,
    }
}

fn assert_names(e: &ModelError, parts: &[&str]) {
    let msg = e.to_string();
    for p in parts {
        assert!(msg.contains(p), "message does not name {p}: {msg}");
    }
}

// ---------------------------------------------------------------- parsing and the tree

#[test]
fn text_that_is_not_xml_is_a_parse_error() {
    let e = err("this is not a URDF");
    assert!(matches!(e, ModelError::Parse(_)), "{e:?}");
    assert!(e.to_string().starts_with("URDF does not parse: "), "{e}");
}

#[test]
fn truncated_document_is_a_parse_error() {
    // Cut inside the l_knee joint element: unclosed tags.
    let at = DEFAULT_URDF.find("<joint name=\"l_knee\"").unwrap() + 30;
    let e = err(&DEFAULT_URDF[..at]);
    assert!(matches!(e, ModelError::Parse(_)), "{e:?}");
}

#[test]
fn empty_robot_has_no_links() {
    let e = err(r#"<?xml version="1.0"?><robot name="nothing"></robot>"#);
    assert!(matches!(e, ModelError::NoLinks), "{e:?}");
}

#[test]
fn joint_to_a_missing_child_link_names_joint_and_link() {
    let e = err(&edit(
        "<joint name=\"l_knee\"",
        "<child link=\"l_shin\"/>",
        "<child link=\"l_shinn\"/>",
    ));
    match &e {
        ModelError::UnknownLink { joint, role, link } => {
            assert_eq!(
                (joint.as_str(), *role, link.as_str()),
                ("l_knee", "child", "l_shinn")
            );
        }
        other => panic!("expected UnknownLink, got {other:?}"),
    }
    assert_names(&e, &["`l_knee`", "`l_shinn`", "child"]);
}

#[test]
fn joint_from_a_missing_parent_link_names_joint_and_link() {
    let e = err(&edit(
        "<joint name=\"neck_yaw\"",
        "<parent link=\"torso\"/>",
        "<parent link=\"chest\"/>",
    ));
    assert!(
        matches!(&e, ModelError::UnknownLink { role: "parent", .. }),
        "{e:?}"
    );
    assert_names(&e, &["`neck_yaw`", "`chest`"]);
}

#[test]
fn two_links_with_one_name_are_refused() {
    let e = err(&edit(
        "<!-- ========== Right arm",
        "<link name=\"r_forearm\">",
        "<link name=\"l_forearm\">",
    ));
    assert!(
        matches!(&e, ModelError::DuplicateLink { link } if link == "l_forearm"),
        "{e:?}"
    );
    assert_names(&e, &["`l_forearm`"]);
}

#[test]
fn two_joints_with_one_name_are_refused() {
    let e = err(&edit(
        "<!-- ========== Right arm",
        "<joint name=\"r_elbow\"",
        "<joint name=\"l_elbow\"",
    ));
    assert!(
        matches!(&e, ModelError::DuplicateJoint { joint } if joint == "l_elbow"),
        "{e:?}"
    );
    assert_names(&e, &["`l_elbow`"]);
}

#[test]
fn link_with_two_parent_joints_names_both_joints() {
    // r_elbow now also ends in l_forearm.
    let e = err(&edit(
        "<joint name=\"r_elbow\"",
        "<child link=\"r_forearm\"/>",
        "<child link=\"l_forearm\"/>",
    ));
    match &e {
        ModelError::TwoParents {
            link,
            first,
            second,
        } => {
            assert_eq!(
                (link.as_str(), first.as_str(), second.as_str()),
                ("l_forearm", "l_elbow", "r_elbow")
            );
        }
        other => panic!("expected TwoParents, got {other:?}"),
    }
    assert_names(&e, &["`l_forearm`", "`l_elbow`", "`r_elbow`"]);
}

#[test]
fn stray_link_makes_two_roots_and_both_are_listed() {
    let e = err(&append(r#"<link name="stray_camera"/>"#));
    match &e {
        ModelError::NotATree { roots } => {
            assert_eq!(roots, &["base_link".to_owned(), "stray_camera".to_owned()])
        }
        other => panic!("expected NotATree, got {other:?}"),
    }
    assert_names(&e, &["base_link", "stray_camera"]);
}

#[test]
fn detached_cycle_is_not_a_tree_and_names_a_joint_of_the_cycle() {
    // One root (base_link) and every link has one parent, but ring_a <-> ring_b is unreachable.
    let e = err(&append(
        r#"<link name="ring_a"/><link name="ring_b"/>
        <joint name="ring_ab" type="fixed"><parent link="ring_a"/><child link="ring_b"/></joint>
        <joint name="ring_ba" type="fixed"><parent link="ring_b"/><child link="ring_a"/></joint>"#,
    ));
    assert!(matches!(&e, ModelError::NotATree { .. }), "{e:?}");
    assert!(
        e.to_string().contains("cycle through joint `ring_ab`")
            || e.to_string().contains("cycle through joint `ring_ba`"),
        "{e}"
    );
}

// ---------------------------------------------------------------- numbers

#[test]
fn negative_mass_names_the_link_and_value() {
    let e = err(&edit(
        "<link name=\"l_shin\">",
        "<mass value=\"0.13\"/>",
        "<mass value=\"-0.13\"/>",
    ));
    assert!(
        matches!(&e, ModelError::BadInertial { link, .. } if link == "l_shin"),
        "{e:?}"
    );
    assert_names(&e, &["`l_shin`", "-0.13"]);
}

#[test]
fn inertia_breaking_the_triangle_inequality_is_refused() {
    // Principal moments 1e-6, 1e-6, 1e-3: 1e-6 + 1e-6 < 1e-3, no real body has them.
    let urdf = edit(
        "<link name=\"l_thigh\">",
        r#"ixx="7.25e-05" ixy="0" ixz="0" iyy="7.65625e-05" iyz="0" izz="2.65625e-05""#,
        r#"ixx="1e-6" ixy="0" ixz="0" iyy="1e-6" iyz="0" izz="1e-3""#,
    );
    let e = err(&urdf);
    assert!(
        matches!(&e, ModelError::BadInertial { link, .. } if link == "l_thigh"),
        "{e:?}"
    );
    assert_names(&e, &["`l_thigh`", "triangle inequality", "1.000e-3"]);
}

#[test]
fn inertia_that_is_not_positive_semidefinite_is_refused() {
    let urdf = edit(
        "<link name=\"torso\">",
        "iyy=\"0.000745\"",
        "iyy=\"-0.000745\"",
    );
    let e = err(&urdf);
    assert!(
        matches!(&e, ModelError::BadInertial { link, .. } if link == "torso"),
        "{e:?}"
    );
    assert_names(&e, &["`torso`", "positive semi-definite"]);
}

#[test]
fn nan_in_an_inertia_is_refused_naming_the_link() {
    // urdf-rs parses "nan" as f64::NAN (Rust's f64 parser accepts it), so the model sees it.
    let urdf = edit(
        "<link name=\"r_foot\">",
        "ixx=\"3.08333e-05\"",
        "ixx=\"nan\"",
    );
    let e = err(&urdf);
    assert!(
        matches!(&e, ModelError::BadInertial { link, .. } if link == "r_foot"),
        "{e:?}"
    );
    assert_names(&e, &["`r_foot`", "non-finite"]);
}

#[test]
fn nan_in_a_joint_origin_is_non_finite_naming_the_element() {
    let e = err(&edit(
        "<joint name=\"l_knee\"",
        "<origin xyz=\"0 0 -0.09\"",
        "<origin xyz=\"0 nan -0.09\"",
    ));
    match &e {
        ModelError::NonFinite { element, value } => {
            assert_eq!(element, "joint `l_knee` origin xyz");
            assert!(value.is_nan());
        }
        other => panic!("expected NonFinite, got {other:?}"),
    }
    assert_names(&e, &["joint `l_knee` origin xyz", "NaN"]);
}

#[test]
fn infinity_in_an_inertial_origin_or_collision_is_non_finite() {
    let e = err(&edit(
        "<link name=\"head\">",
        "<origin xyz=\"0 0 0.025\" rpy=\"0 0 0\"/>",
        "<origin xyz=\"0 0 0.025\" rpy=\"0 inf 0\"/>",
    ));
    assert!(
        matches!(&e, ModelError::NonFinite { element, value } if element == "link `head` inertial origin rpy" && *value == f64::INFINITY),
        "{e:?}"
    );
    // The third origin of l_foot is its collision's.
    let urdf = edit(
        "<link name=\"l_foot\">",
        "<collision>\n      <origin xyz=\"0.01 0 -0.025\"",
        "<collision>\n      <origin xyz=\"0.01 -inf -0.025\"",
    );
    let e = err(&urdf);
    assert!(
        matches!(&e, ModelError::NonFinite { element, .. } if element == "link `l_foot` collision 0 origin xyz"),
        "{e:?}"
    );
    assert_names(&e, &["-inf"]);
}

#[test]
fn lower_limit_above_upper_names_the_joint_and_values() {
    let e = err(&edit(
        "<joint name=\"l_knee\"",
        "lower=\"-0.05\" upper=\"2.3\"",
        "lower=\"2.3\" upper=\"-0.05\"",
    ));
    assert!(
        matches!(&e, ModelError::BadLimits { joint, .. } if joint == "l_knee"),
        "{e:?}"
    );
    assert_names(&e, &["`l_knee`", "lower 2.3", "upper -0.05"]);
}

#[test]
fn zero_velocity_limit_names_the_joint() {
    let e = err(&edit(
        "<joint name=\"r_ankle_pitch\"",
        "velocity=\"6.0\"",
        "velocity=\"0\"",
    ));
    assert!(
        matches!(&e, ModelError::BadLimits { joint, .. } if joint == "r_ankle_pitch"),
        "{e:?}"
    );
    assert_names(&e, &["`r_ankle_pitch`", "velocity limit 0"]);
}

#[test]
fn negative_effort_limit_names_the_joint() {
    let e = err(&edit(
        "<joint name=\"head_pitch\"",
        "effort=\"1.5\"",
        "effort=\"-1\"",
    ));
    assert!(
        matches!(&e, ModelError::BadLimits { joint, .. } if joint == "head_pitch"),
        "{e:?}"
    );
    assert_names(&e, &["`head_pitch`", "effort limit -1"]);
}

#[test]
fn zero_axis_on_a_revolute_joint_is_refused() {
    let e = err(&edit(
        "<joint name=\"l_hip_pitch\"",
        "<axis xyz=\"0 1 0\"/>",
        "<axis xyz=\"0 0 0\"/>",
    ));
    assert!(
        matches!(&e, ModelError::ZeroAxis { joint } if joint == "l_hip_pitch"),
        "{e:?}"
    );
    assert_names(&e, &["`l_hip_pitch`"]);
}

#[test]
fn floating_and_planar_joints_are_unsupported() {
    for kind in ["floating", "planar"] {
        let e = err(&edit(
            "<joint name=\"torso_fixed\"",
            "type=\"fixed\"",
            &format!("type=\"{kind}\""),
        ));
        assert!(
            matches!(&e, ModelError::UnsupportedJoint { joint, kind: k } if joint == "torso_fixed" && k == kind),
            "{e:?}"
        );
        assert_names(&e, &["`torso_fixed`", kind]);
    }
}

// ---------------------------------------------------------------- biped shape

#[test]
fn one_leg_is_not_a_biped() {
    let urdf = cut(
        "<!-- ========== Right leg",
        "<!-- ========== Right leg",
        "<!-- ========== Left arm",
    );
    assert!(!urdf.contains("r_hip_roll") && urdf.contains("l_hip_roll"));
    let e = err(&urdf);
    assert!(matches!(&e, ModelError::NotABiped(_)), "{e:?}");
    assert_names(&e, &["found 1 leg chain(s)", "l_hip_roll", "need 2"]);
}

#[test]
fn knee_about_z_is_not_a_leg_and_the_message_names_the_knee() {
    let e = err(&edit(
        "<joint name=\"l_knee\"",
        "<axis xyz=\"0 1 0\"/>",
        "<axis xyz=\"0 0 1\"/>",
    ));
    assert!(matches!(&e, ModelError::NotABiped(_)), "{e:?}");
    assert_names(
        &e,
        &[
            "found 1 leg chain(s)",
            "joint `l_knee` (axis z) where a knee joint (axis y) belongs",
            "`l_foot`",
        ],
    );
}

#[test]
fn both_legs_on_one_side_names_both_hip_roll_joints() {
    let e = err(&edit(
        "<joint name=\"r_hip_roll\"",
        "xyz=\"0 -0.037 -0.03\"",
        "xyz=\"0 0.037 -0.03\"",
    ));
    assert!(matches!(&e, ModelError::NotABiped(_)), "{e:?}");
    assert_names(&e, &["`l_hip_roll`", "`r_hip_roll`", "left side"]);
}

#[test]
fn ankle_axes_that_do_not_intersect_are_leg_geometry_errors() {
    // The roll joint 10 mm above the pitch joint: its axis passes above the pitch axis.
    let e = err(&edit(
        "<joint name=\"l_ankle_roll\"",
        "<origin xyz=\"0 0 0\"",
        "<origin xyz=\"0 0 0.01\"",
    ));
    assert!(
        matches!(
            &e,
            ModelError::LegGeometry {
                side: Side::Left,
                ..
            }
        ),
        "{e:?}"
    );
    assert_names(
        &e,
        &[
            "left leg",
            "`l_ankle_roll`",
            "`l_ankle_pitch`",
            "0.010000 m above",
            "anywhere along its axis",
        ],
    );
}

#[test]
fn a_hip_yaw_axis_beside_the_roll_axis_is_a_leg_geometry_error() {
    // The roll joint 7 mm to the right of the yaw axis: the axes miss each other.
    let urdf = edit_in(
        TEST_BIPED6,
        "<joint name=\"LeftLegJ2\"",
        "<origin xyz=\"0 0 -0.02\"",
        "<origin xyz=\"0 -0.007 -0.02\"",
    );
    let e = match BipedModel::from_urdf_str(&urdf, None) {
        Ok(_) => panic!("accepted"),
        Err(e) => e,
    };
    assert!(
        matches!(
            &e,
            ModelError::LegGeometry {
                side: Side::Left,
                ..
            }
        ),
        "{e:?}"
    );
    assert_names(
        &e,
        &["`LeftLegJ1`", "`LeftLegJ2`", "0.007000 m", "fore or aft"],
    );
}

/// FK(IK(t)) = t with a level sole, for a few targets around the stance of `b`.
fn assert_solves_around_the_stance(b: &BipedModel) {
    for side in Side::BOTH {
        let stance = b.leg(side).straight_ankle_in_hip_m();
        for d in [
            nalgebra::Vector3::new(0.02, 0.01, 0.03),
            nalgebra::Vector3::new(-0.03, -0.02, 0.05),
        ] {
            let t = AnkleTarget {
                ankle_in_hip_m: stance + d,
                foot_yaw_rad: 0.0,
            };
            let sol = b.solve_leg(side, &t).unwrap();
            assert!(sol.is_exact(), "{:?}", sol.issues);
            let mut q = vec![0.0; b.robot().dof_count()];
            b.write_leg(&sol, &mut q);
            let got = b.ankles_in_hips(&q).unwrap()[side.index()];
            assert!((got - t.ankle_in_hip_m).norm() < 1e-9, "{got} for {t:?}");
        }
    }
}

#[test]
fn a_hip_pitch_sideways_of_hip_roll_is_a_sideways_offset_of_the_leg() {
    // Once refused; the pitch plane 10 mm inward of the roll axis is what servo hips do.
    let b = BipedModel::from_urdf_str(
        &edit(
            "<joint name=\"r_hip_pitch\"",
            "<origin xyz=\"0 0 0\"",
            "<origin xyz=\"0 0.01 0\"",
        ),
        None,
    )
    .unwrap();
    assert!((b.leg(Side::Right).ankle_lateral_m - 0.01).abs() < 1e-12);
    assert_eq!(b.leg(Side::Left).ankle_lateral_m, 0.0);
    assert_solves_around_the_stance(&b);
}

#[test]
fn a_knee_beside_the_hip_pitch_moves_the_ankle_point_sideways() {
    // The knee and everything below it 5 mm outward: the ankle point moves with them.
    let b = BipedModel::from_urdf_str(
        &edit(
            "<joint name=\"l_knee\"",
            "<origin xyz=\"0 0 -0.09\"",
            "<origin xyz=\"0 0.005 -0.09\"",
        ),
        None,
    )
    .unwrap();
    assert!((b.leg(Side::Left).ankle_lateral_m - 0.005).abs() < 1e-12);
    assert_solves_around_the_stance(&b);
}

#[test]
fn foot_without_a_box_collision_names_the_foot_link() {
    let urdf = cut("<link name=\"r_foot\">", "<collision>", "</collision>");
    let e = err(&urdf);
    assert!(
        matches!(
            &e,
            ModelError::LegGeometry {
                side: Side::Right,
                ..
            }
        ),
        "{e:?}"
    );
    assert_names(
        &e,
        &["foot link `r_foot`", "`r_ankle_roll`", "no box collision"],
    );
}

#[test]
fn foot_with_only_a_cylinder_collision_names_the_foot_link() {
    let urdf = edit(
        "<link name=\"l_foot\">",
        "<collision>\n      <origin xyz=\"0.01 0 -0.025\" rpy=\"0 0 0\"/>\n      <geometry><box size=\"0.1 0.06 0.01\"/></geometry>",
        "<collision>\n      <origin xyz=\"0.01 0 -0.025\" rpy=\"0 0 0\"/>\n      <geometry><cylinder radius=\"0.03\" length=\"0.01\"/></geometry>",
    );
    let e = err(&urdf);
    assert!(
        matches!(
            &e,
            ModelError::LegGeometry {
                side: Side::Left,
                ..
            }
        ),
        "{e:?}"
    );
    assert_names(&e, &["`l_foot`", "no box collision"]);
}

#[test]
fn missing_file_is_an_io_error_naming_the_path() {
    let e = BipedModel::from_urdf_file("/nonexistent/x.urdf", None).unwrap_err();
    match &e {
        ModelError::Io { path, source } => {
            assert_eq!(path, "/nonexistent/x.urdf");
            assert_eq!(source.kind(), std::io::ErrorKind::NotFound);
        }
        other => panic!("expected Io, got {other:?}"),
    }
    assert_names(&e, &["/nonexistent/x.urdf"]);
    assert!(matches!(
        RobotModel::from_urdf_file("/nonexistent/x.urdf"),
        Err(ModelError::Io { .. })
    ));
}

// ---------------------------------------------------------------- explicit role map

const DEFAULT_ROLE_MAP: &str = "
left:
  hip_roll: l_hip_roll
  hip_pitch: l_hip_pitch
  knee: l_knee
  ankle_pitch: l_ankle_pitch
  ankle_roll: l_ankle_roll
right:
  hip_roll: r_hip_roll
  hip_pitch: r_hip_pitch
  knee: r_knee
  ankle_pitch: r_ankle_pitch
  ankle_roll: r_ankle_roll
";

const BIPED6_ROLE_MAP: &str = "
left:  {hip_yaw: LeftLegJ1,  hip_roll: LeftLegJ2,  hip_pitch: LeftLegJ3,  knee: LeftLegJ4,  ankle_pitch: LeftLegJ5,  ankle_roll: LeftLegJ6}
right: {hip_yaw: RightLegJ1, hip_roll: RightLegJ2, hip_pitch: RightLegJ3, knee: RightLegJ4, ankle_pitch: RightLegJ5, ankle_roll: RightLegJ6}
";

fn role_map(yaml: &str) -> LegRoleMap {
    serde_norway::from_str(yaml).unwrap_or_else(|e| panic!("role map does not parse: {e}"))
}

fn role_map_err(urdf: &str, yaml: &str) -> ModelError {
    match BipedModel::from_urdf_str(urdf, Some(&role_map(yaml))) {
        Ok(_) => panic!("the role map was accepted"),
        Err(e) => e,
    }
}

#[test]
fn role_map_for_the_default_robot_gives_the_detected_legs() {
    let map = role_map(DEFAULT_ROLE_MAP);
    assert_eq!(map.left.hip_yaw, None);
    assert_eq!(map.right.knee, "r_knee");
    let mapped = BipedModel::from_urdf_str(DEFAULT_URDF, Some(&map)).unwrap();
    let auto = default_biped();
    for s in Side::BOTH {
        assert_eq!(mapped.leg(s), auto.leg(s), "{s} leg differs");
    }
    assert_eq!(
        mapped.leg(Side::Left).joint(JointRole::Knee).unwrap().name,
        "l_knee"
    );
}

#[test]
fn role_map_for_the_six_joint_robot_gives_the_detected_legs_and_the_same_ik() {
    let mapped = BipedModel::from_urdf_str(TEST_BIPED6, Some(&role_map(BIPED6_ROLE_MAP))).unwrap();
    let auto = biped6();
    for s in Side::BOTH {
        assert_eq!(mapped.leg(s), auto.leg(s), "{s} leg differs");
    }
    // Hand-computed angles of ik_hand.rs (six_joint_leg_with_flipped_axes_offset_hip_and_yaw):
    // target (0.02, 0.01, -0.19), yaw 0.2; left hip roll axis -x, right knee axis -y.
    let (roll, hip, knee, ankle) = (
        0.030660279288661,
        0.666001708999223,
        1.1482266524321,
        0.482224943432877,
    );
    let t = AnkleTarget {
        ankle_in_hip_m: nalgebra::Vector3::new(0.02, 0.01, -0.19),
        foot_yaw_rad: 0.2,
    };
    let want = [
        [0.2, -roll, -hip, knee, -ankle, -roll],
        [0.2, roll, -hip, -knee, -ankle, -roll],
    ];
    for s in Side::BOTH {
        let sol = mapped.solve_leg(s, &t).unwrap();
        assert!(sol.is_exact(), "{:?}", sol.issues);
        for (k, (g, w)) in sol.angles_rad.iter().zip(want[s.index()]).enumerate() {
            assert!(
                (g - w).abs() < 1e-12,
                "{s} {:?}: got {g}, want {w}",
                JointRole::ALL[k]
            );
        }
        assert_eq!(sol, auto.solve_leg(s, &t).unwrap());
    }
}

#[test]
fn role_map_naming_a_missing_joint_is_refused_naming_it() {
    let e = role_map_err(
        DEFAULT_URDF,
        &DEFAULT_ROLE_MAP.replace("knee: r_knee", "knee: r_knee_servo"),
    );
    assert!(matches!(&e, ModelError::RoleMap(_)), "{e:?}");
    assert_names(&e, &["knee joint `r_knee_servo`", "not in the URDF"]);
}

#[test]
fn role_map_giving_a_pitch_joint_as_hip_roll_is_refused_naming_it() {
    let e = role_map_err(
        DEFAULT_URDF,
        &DEFAULT_ROLE_MAP.replace("hip_roll: l_hip_roll", "hip_roll: l_knee"),
    );
    assert!(matches!(&e, ModelError::RoleMap(_)), "{e:?}");
    assert_names(&e, &["hip_roll joint `l_knee`", "x axis", "its axis is y"]);
}

#[test]
fn role_map_giving_a_fixed_joint_is_refused_naming_it() {
    let e = role_map_err(
        DEFAULT_URDF,
        &DEFAULT_ROLE_MAP.replace("hip_pitch: l_hip_pitch", "hip_pitch: torso_fixed"),
    );
    assert!(matches!(&e, ModelError::RoleMap(_)), "{e:?}");
    assert_names(&e, &["`torso_fixed`", "not revolute"]);
}

#[test]
fn role_map_out_of_chain_order_is_refused() {
    // hip_pitch and knee swapped: both are y joints, so only the chain order is wrong.
    let yaml = DEFAULT_ROLE_MAP
        .replace("hip_pitch: l_hip_pitch", "hip_pitch: TMP")
        .replace("knee: l_knee", "knee: l_hip_pitch")
        .replace("hip_pitch: TMP", "hip_pitch: l_knee");
    assert!(yaml.contains("hip_pitch: l_knee") && yaml.contains("knee: l_hip_pitch"));
    let e = role_map_err(DEFAULT_URDF, &yaml);
    assert!(matches!(&e, ModelError::RoleMap(_)), "{e:?}");
    assert_names(&e, &["joint `l_knee` does not follow joint `l_hip_roll`"]);
}

#[test]
fn role_map_mixing_the_two_legs_is_refused() {
    let e = role_map_err(
        DEFAULT_URDF,
        &DEFAULT_ROLE_MAP.replace("knee: l_knee", "knee: r_knee"),
    );
    assert!(matches!(&e, ModelError::RoleMap(_)), "{e:?}");
    assert_names(&e, &["`r_knee`", "`l_hip_pitch`"]);
}

#[test]
fn role_map_with_the_sides_swapped_does_not_give_a_left_leg_on_the_right() {
    // `left:` lists the r_* joints (hips at y = -0.037) and `right:` the l_* ones. Either the
    // map is refused, or the leg returned as Left is the one whose hip is at +y (Side::Left is
    // "+y side of the robot" and IK targets are given per side).
    let yaml = DEFAULT_ROLE_MAP
        .replace("left:", "TMP:")
        .replace("right:", "left:")
        .replace("TMP:", "right:");
    match BipedModel::from_urdf_str(DEFAULT_URDF, Some(&role_map(&yaml))) {
        Err(e) => assert!(matches!(e, ModelError::RoleMap(_)), "{e:?}"),
        Ok(b) => {
            let left = b.leg(Side::Left);
            assert!(
                left.hip_in_base_m.y > 0.0,
                "role map with swapped sides accepted: the Left leg is `{}` with its hip at y = {} m",
                left.joint(JointRole::HipRoll).unwrap().name,
                left.hip_in_base_m.y
            );
        }
    }
}

#[test]
fn role_map_with_an_unknown_key_does_not_deserialize() {
    let bad_leg = DEFAULT_ROLE_MAP.replace("  knee: l_knee", "  knee: l_knee\n  toe: l_toe");
    let e = serde_norway::from_str::<LegRoleMap>(&bad_leg).unwrap_err();
    assert!(e.to_string().contains("unknown field `toe`"), "{e}");
    let bad_top = format!("{DEFAULT_ROLE_MAP}middle:\n  hip_roll: x\n");
    let e = serde_norway::from_str::<LegRoleMap>(&bad_top).unwrap_err();
    assert!(e.to_string().contains("unknown field `middle`"), "{e}");
    // A missing required role is a serde error too.
    let e = serde_norway::from_str::<LegRoleMap>(
        &DEFAULT_ROLE_MAP.replace("  ankle_roll: r_ankle_roll\n", ""),
    )
    .unwrap_err();
    assert!(e.to_string().contains("missing field `ankle_roll`"), "{e}");
}
