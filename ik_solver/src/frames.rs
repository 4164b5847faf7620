//! The robot's links as a tree of frames: what a robot state publisher sends to TF.
//!
//! Every URDF joint is one edge, parent link → child link, with the child link's pose in
//! the parent link's frame: the joint's origin, then its motion at the joint position
//! (rotation about the axis, or translation along it). Fixed joints never change: they are
//! sent once, on `/tf_static`. Movable joints are sent on `/tf` for every joint state that
//! names them, stamped with that state's stamp, as ROS's `robot_state_publisher` does.
//!
//! Pure: the node (`robot_state_publisher`) puts these on the wire.

use std::collections::HashMap;

use nalgebra::Isometry3;

use crate::model::{JointKind, RobotModel};

/// One edge of the tree: where `child` is in `parent`.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameTransform<'a> {
    /// The parent link's name.
    pub parent: &'a str,
    /// The child link's name.
    pub child: &'a str,
    /// The child link's frame in the parent link's frame.
    pub transform: Isometry3<f64>,
}

/// A joint state that cannot be turned into frames.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum JointStateError {
    /// `name` and `position` differ in length.
    #[error("joint state has {names} names but {positions} positions; they must pair up")]
    LengthMismatch {
        /// Number of names.
        names: usize,
        /// Number of positions.
        positions: usize,
    },
}

/// What was left out of a joint state's frames, with why.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SkippedJoints {
    /// Names that are no movable joint of the robot (ignored, as robot_state_publisher does).
    pub unknown: Vec<String>,
    /// Joints whose position is NaN or infinite (their frames are not sent): (name, value).
    pub non_finite: Vec<(String, f64)>,
}

impl SkippedJoints {
    /// Nothing was skipped.
    pub fn is_empty(&self) -> bool {
        self.unknown.is_empty() && self.non_finite.is_empty()
    }
}

/// The frames of a robot, ready to turn joint states into transforms.
#[derive(Debug, Clone)]
pub struct FrameTree {
    model: RobotModel,
    /// Movable joint name → joint index.
    movable: HashMap<String, usize>,
}

impl FrameTree {
    /// The frames of `model`.
    pub fn new(model: RobotModel) -> Self {
        let movable = model
            .joints()
            .iter()
            .enumerate()
            .filter(|(_, j)| j.dof.is_some())
            .map(|(i, j)| (j.name.clone(), i))
            .collect();
        Self { model, movable }
    }

    /// The robot.
    pub fn model(&self) -> &RobotModel {
        &self.model
    }

    /// The edges of the fixed joints, in URDF order: `/tf_static`.
    pub fn fixed(&self) -> Vec<FrameTransform<'_>> {
        self.model
            .joints()
            .iter()
            .enumerate()
            .filter(|(_, j)| j.kind == JointKind::Fixed || j.dof.is_none())
            .map(|(i, _)| self.edge(i, 0.0))
            .collect()
    }

    /// The edges of the movable joints a joint state names, in its order: `/tf`. Names the
    /// robot does not have are skipped; so are non-finite positions (never sent as frames).
    pub fn moving<'s>(
        &'s self,
        names: &[String],
        positions: &[f64],
    ) -> Result<(Vec<FrameTransform<'s>>, SkippedJoints), JointStateError> {
        if names.len() != positions.len() {
            return Err(JointStateError::LengthMismatch {
                names: names.len(),
                positions: positions.len(),
            });
        }
        let mut out = Vec::with_capacity(names.len());
        let mut skipped = SkippedJoints::default();
        for (name, &q) in names.iter().zip(positions) {
            match self.movable.get(name) {
                None => skipped.unknown.push(name.clone()),
                Some(_) if !q.is_finite() => skipped.non_finite.push((name.clone(), q)),
                Some(&i) => out.push(self.edge(i, q)),
            }
        }
        Ok((out, skipped))
    }

    fn edge(&self, joint: usize, position: f64) -> FrameTransform<'_> {
        let j = &self.model.joints()[joint];
        let links = self.model.links();
        FrameTransform {
            parent: &links[j.parent].name,
            child: &links[j.child].name,
            transform: self.model.joint_transform(joint, position),
        }
    }
}
