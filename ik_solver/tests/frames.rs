//! The frames a robot state publisher sends, against values worked out by hand.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::f64::consts::FRAC_PI_2;

use ik_solver::{FrameTree, JointStateError, RobotModel};
use nalgebra::{Point3, Vector3};

/// base --(fixed, 0.1 m up, turned 90 deg about z)--> plate
///      --(revolute about x, 0.2 m along the plate's y)--> arm
///      --(prismatic along z)--> slider
const URDF: &str = r#"<robot name="t">
  <link name="base"/><link name="plate"/><link name="arm"/><link name="slider"/>
  <joint name="mount" type="fixed"><parent link="base"/><child link="plate"/>
    <origin xyz="0 0 0.1" rpy="0 0 1.5707963267948966"/></joint>
  <joint name="swing" type="revolute"><parent link="plate"/><child link="arm"/>
    <origin xyz="0 0.2 0"/><axis xyz="1 0 0"/>
    <limit lower="-2" upper="2" velocity="1" effort="1"/></joint>
  <joint name="slide" type="prismatic"><parent link="arm"/><child link="slider"/>
    <axis xyz="0 0 1"/><limit lower="0" upper="0.5" velocity="1" effort="1"/></joint>
</robot>"#;

fn tree() -> FrameTree {
    FrameTree::new(RobotModel::from_urdf_str(URDF).unwrap())
}

fn close(a: Point3<f64>, b: [f64; 3]) -> bool {
    (a - Point3::from(b)).norm() < 1e-12
}

#[test]
fn fixed_joints_are_static_frames() {
    let t = tree();
    let fixed = t.fixed();
    assert_eq!(fixed.len(), 1);
    let f = &fixed[0];
    assert_eq!((f.parent, f.child), ("base", "plate"));
    // The plate's x axis is the base's y axis; its origin 0.1 m up.
    assert!(close(f.transform * Point3::origin(), [0.0, 0.0, 0.1]));
    assert!(close(
        f.transform * Point3::new(1.0, 0.0, 0.0),
        [0.0, 1.0, 0.1]
    ));
}

#[test]
fn movable_joints_move_their_child_frame() {
    let t = tree();
    let names = ["slide".to_string(), "swing".to_string()];
    let (frames, skipped) = t.moving(&names, &[0.3, FRAC_PI_2]).unwrap();
    assert!(skipped.is_empty());
    // In the joint state's order.
    assert_eq!(frames[0].parent, "arm");
    assert_eq!(frames[0].child, "slider");
    assert!(close(
        frames[0].transform * Point3::origin(),
        [0.0, 0.0, 0.3]
    ));
    assert_eq!((frames[1].parent, frames[1].child), ("plate", "arm"));
    // Swung 90 deg about x: the arm's y axis is the plate's z axis, from (0, 0.2, 0).
    let arm = frames[1].transform;
    assert!(close(arm * Point3::origin(), [0.0, 0.2, 0.0]));
    assert!(close(arm * Point3::new(0.0, 1.0, 0.0), [0.0, 0.2, 1.0]));
    // Chained, the slider's origin in the base: 0.3 m along the arm's z (the plate's -y,
    // the base's +x), from (0, 0.2, 0) in the plate ((-0.2, 0, 0.1) in the base).
    let fixed = t.fixed()[0].transform;
    let slider = fixed * arm * frames[0].transform;
    assert!(close(slider * Point3::origin(), [0.3 - 0.2, 0.0, 0.1]));
    let fk = t
        .model()
        .link_poses(&nalgebra::Isometry3::identity(), &[FRAC_PI_2, 0.3])
        .unwrap();
    let i = t.model().link_index("slider").unwrap();
    assert!((fk[i].translation.vector - Vector3::new(0.1, 0.0, 0.1)).norm() < 1e-12);
}

#[test]
fn unknown_names_and_non_finite_positions_are_skipped_and_named() {
    let t = tree();
    let names = ["swing", "wheel", "slide", "mount"].map(String::from);
    let (frames, skipped) = t.moving(&names, &[0.1, 1.0, f64::NAN, 0.0]).unwrap();
    assert_eq!(frames.len(), 1);
    assert_eq!(frames[0].child, "arm");
    // A fixed joint is not a joint state's to move.
    assert_eq!(
        skipped.unknown,
        vec!["wheel".to_string(), "mount".to_string()]
    );
    assert_eq!(skipped.non_finite.len(), 1);
    assert_eq!(skipped.non_finite[0].0, "slide");
    assert!(skipped.non_finite[0].1.is_nan());
}

#[test]
fn names_and_positions_must_pair_up() {
    let t = tree();
    let err = t.moving(&["swing".to_string()], &[]).unwrap_err();
    assert_eq!(
        err,
        JointStateError::LengthMismatch {
            names: 1,
            positions: 0
        }
    );
    assert!(err.to_string().contains("1 names but 0 positions"));
}
