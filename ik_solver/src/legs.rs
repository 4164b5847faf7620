//! Finding the two legs of a biped in a URDF tree, and reading the geometry the closed-form
//! IK needs from it: thigh and shin lengths, hip offsets, ankle-to-sole height, sole
//! rectangle, joint axes' signs and limits.
//!
//! A leg is a chain of movable joints ending in `[hip_yaw,] hip_roll, hip_pitch, knee,
//! ankle_pitch, ankle_roll`. Each joint's role comes from its axis in the base frame at zero
//! joint angles (x: roll, y: pitch, z: yaw; either sign), or from an explicit
//! [`LegRoleMap`] where names or axes are unusual. All geometry is measured at zero joint
//! angles, in the base frame, with a 1 µm tolerance on alignments.

use std::fmt;

use nalgebra::{Isometry3, Point3, Vector3};
use serde::Deserialize;

use crate::error::ModelError;
use crate::model::{JointKind, JointLimits, RobotModel};

/// Alignment tolerance on joint placements (m).
const TOL_M: f64 = 1e-6;
/// An axis counts as along x, y or z when its cosine with it exceeds this.
const AXIS_COS: f64 = 0.999;

/// Which leg.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Side {
    /// +y side of the robot.
    Left,
    /// -y side of the robot.
    Right,
}

impl Side {
    /// Both sides, left first.
    pub const BOTH: [Side; 2] = [Side::Left, Side::Right];
    /// The other leg.
    pub fn other(self) -> Side {
        match self {
            Side::Left => Side::Right,
            Side::Right => Side::Left,
        }
    }
    /// 0 for left, 1 for right.
    pub fn index(self) -> usize {
        self as usize
    }
    /// +1 for left, -1 for right: the sign of this leg's hip in y.
    pub fn sign(self) -> f64 {
        match self {
            Side::Left => 1.0,
            Side::Right => -1.0,
        }
    }
    /// "left" or "right".
    pub fn as_str(self) -> &'static str {
        match self {
            Side::Left => "left",
            Side::Right => "right",
        }
    }
}

impl fmt::Display for Side {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// What a leg joint does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum JointRole {
    /// Rotation about z at the hip (6-joint legs only).
    HipYaw = 0,
    /// Rotation about x at the hip.
    HipRoll = 1,
    /// Rotation about y at the hip.
    HipPitch = 2,
    /// Rotation about y at the knee.
    Knee = 3,
    /// Rotation about y at the ankle.
    AnklePitch = 4,
    /// Rotation about x at the ankle.
    AnkleRoll = 5,
}

impl JointRole {
    /// All roles, hip to foot.
    pub const ALL: [JointRole; 6] = [
        JointRole::HipYaw,
        JointRole::HipRoll,
        JointRole::HipPitch,
        JointRole::Knee,
        JointRole::AnklePitch,
        JointRole::AnkleRoll,
    ];
    /// snake_case name.
    pub fn as_str(self) -> &'static str {
        match self {
            JointRole::HipYaw => "hip_yaw",
            JointRole::HipRoll => "hip_roll",
            JointRole::HipPitch => "hip_pitch",
            JointRole::Knee => "knee",
            JointRole::AnklePitch => "ankle_pitch",
            JointRole::AnkleRoll => "ankle_roll",
        }
    }
    /// The base-frame axis this role rotates about at zero joint angles.
    pub fn axis(self) -> Axis {
        match self {
            JointRole::HipYaw => Axis::Z,
            JointRole::HipRoll | JointRole::AnkleRoll => Axis::X,
            _ => Axis::Y,
        }
    }
}

impl fmt::Display for JointRole {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A base-frame axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Axis {
    /// Forward.
    X,
    /// Left.
    Y,
    /// Up.
    Z,
}

/// Explicit joint names of one leg, for URDFs whose legs are not found by their axes.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LegJointNames {
    /// Hip yaw joint, for 6-joint legs.
    #[serde(default)]
    pub hip_yaw: Option<String>,
    /// Hip roll joint.
    pub hip_roll: String,
    /// Hip pitch joint.
    pub hip_pitch: String,
    /// Knee joint.
    pub knee: String,
    /// Ankle pitch joint.
    pub ankle_pitch: String,
    /// Ankle roll joint.
    pub ankle_roll: String,
}

/// Explicit leg joints of both legs (the `legs:` key of the robot config).
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LegRoleMap {
    /// Left leg.
    pub left: LegJointNames,
    /// Right leg.
    pub right: LegJointNames,
}

impl LegRoleMap {
    /// Reads a leg map (YAML with `left:` and `right:`), naming the file in every error.
    pub fn from_yaml_file(path: impl AsRef<std::path::Path>) -> Result<Self, ModelError> {
        let path = path.as_ref().display().to_string();
        let text = std::fs::read_to_string(&path).map_err(|source| ModelError::LegMapRead {
            path: path.clone(),
            source,
        })?;
        Self::parse(&text, path)
    }

    /// A leg map from YAML text.
    pub fn from_yaml_str(text: &str) -> Result<Self, ModelError> {
        Self::parse(text, "(text)".into())
    }

    fn parse(text: &str, path: String) -> Result<Self, ModelError> {
        serde_norway::from_str(text).map_err(|source| ModelError::LegMapParse { path, source })
    }

    /// The map of a `leg_map_file` parameter: none for an empty string.
    pub fn from_file_or_none(path: &str) -> Result<Option<Self>, ModelError> {
        if path.is_empty() {
            Ok(None)
        } else {
            Self::from_yaml_file(path).map(Some)
        }
    }
}

impl LegJointNames {
    fn by_role(&self) -> [Option<&str>; 6] {
        [
            self.hip_yaw.as_deref(),
            Some(&self.hip_roll),
            Some(&self.hip_pitch),
            Some(&self.knee),
            Some(&self.ankle_pitch),
            Some(&self.ankle_roll),
        ]
    }
}

/// One joint of a leg.
#[derive(Debug, Clone, PartialEq)]
pub struct LegJoint {
    /// URDF name.
    pub name: String,
    /// Index in [`RobotModel::joints`].
    pub joint: usize,
    /// Index in the joint vector.
    pub dof: usize,
    /// +1 if the URDF axis points along +x/+y/+z of the base for this role, -1 if along -.
    pub axis_sign: f64,
    /// Limits from the URDF.
    pub limits: JointLimits,
}

/// The sole rectangle of a foot, in base-frame axes at zero joint angles, relative to the
/// point on the sole plane straight below the ankle point (where the ankle axes cross).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SoleRect {
    /// Rear edge (m).
    pub x_min_m: f64,
    /// Front edge (m).
    pub x_max_m: f64,
    /// Right edge (m).
    pub y_min_m: f64,
    /// Left edge (m).
    pub y_max_m: f64,
}

impl SoleRect {
    /// The four corners, counter-clockwise seen from above, for a foot whose ankle projects to
    /// `ankle_xy` and whose yaw is `yaw_rad`.
    pub fn corners(&self, ankle_xy: [f64; 2], yaw_rad: f64) -> [[f64; 2]; 4] {
        let (s, c) = yaw_rad.sin_cos();
        let p = |x: f64, y: f64| [ankle_xy[0] + c * x - s * y, ankle_xy[1] + s * x + c * y];
        [
            p(self.x_min_m, self.y_min_m),
            p(self.x_max_m, self.y_min_m),
            p(self.x_max_m, self.y_max_m),
            p(self.x_min_m, self.y_max_m),
        ]
    }
    /// Length along x (m).
    pub fn length_m(&self) -> f64 {
        self.x_max_m - self.x_min_m
    }
    /// Width along y (m).
    pub fn width_m(&self) -> f64 {
        self.y_max_m - self.y_min_m
    }
}

/// A leg of the biped, with everything the closed-form IK needs.
#[derive(Debug, Clone, PartialEq)]
pub struct Leg {
    /// Which leg.
    pub side: Side,
    /// The joints, indexed by [`JointRole`] (`joints[0]`, the hip yaw, is `None` on 5-joint legs).
    pub joints: [Option<LegJoint>; 6],
    /// The hip point H, in the base frame at zero angles (m): where the hip yaw axis crosses
    /// the hip roll axis (a leg without yaw: the point of the roll axis level with the hip
    /// pitch axis in x). IK targets are given relative to it. It does not move with the leg's
    /// joints.
    pub hip_in_base_m: Vector3<f64>,
    /// h_h: height of the hip roll axis above the hip pitch axis (m); 0 when they intersect.
    pub hip_roll_to_pitch_m: f64,
    /// a_h: forward (x) distance from the hip point to the hip pitch axis at zero angles (m).
    pub hip_pitch_forward_m: f64,
    /// e: sideways (y) distance from the hip point to the ankle point at zero angles (m): the
    /// sum of the chain's sideways steps between the hip roll axis, the pitch plane and the
    /// ankle roll axis. The leg's plane stays tangent to a circle of this radius around the
    /// roll axis (ALGORITHM.md, "Leg layouts of real servo humanoids").
    pub ankle_lateral_m: f64,
    /// The ankle point A (where the ankle pitch axis crosses the ankle roll axis) in the ankle
    /// roll joint's frame (m). It lies on the roll axis, so no ankle angle moves it there.
    pub ankle_in_roll_joint_m: Vector3<f64>,
    /// L1: hip-pitch axis to knee axis (m).
    pub thigh_m: f64,
    /// L2: knee axis to ankle-pitch axis (m).
    pub shin_m: f64,
    /// Forward angle of the thigh (hip pitch → knee) from straight down at zero angles (rad).
    pub thigh_angle0_rad: f64,
    /// Forward angle of the shin (knee → ankle pitch) from straight down at zero angles (rad).
    pub shin_angle0_rad: f64,
    /// h_a: ankle point to the sole plane (m).
    pub ankle_to_sole_m: f64,
    /// The sole rectangle around the ankle.
    pub sole: SoleRect,
    /// The link moved by the ankle roll joint (the foot).
    pub foot_link: usize,
    /// Orientation of the foot link in the base frame at zero angles.
    pub foot_rotation0: nalgebra::UnitQuaternion<f64>,
}

impl Leg {
    /// The joint of a role, if the leg has it.
    pub fn joint(&self, role: JointRole) -> Option<&LegJoint> {
        self.joints[role as usize].as_ref()
    }
    /// True for a 6-joint leg with a hip yaw.
    pub fn has_yaw(&self) -> bool {
        self.joints[0].is_some()
    }
    /// The joints present, hip to foot.
    pub fn present(&self) -> impl Iterator<Item = (JointRole, &LegJoint)> {
        JointRole::ALL
            .into_iter()
            .filter_map(|r| self.joint(r).map(|j| (r, j)))
    }
    /// The ankle point (where the ankle axes cross) in the world (m), from link poses.
    pub fn ankle_world(&self, robot: &RobotModel, poses: &[Isometry3<f64>]) -> Point3<f64> {
        let j = self
            .joint(JointRole::AnkleRoll)
            .map(|j| j.joint)
            .unwrap_or_default();
        robot.joint_frame(poses, j) * Point3::from(self.ankle_in_roll_joint_m)
    }
    /// The ankle point relative to the hip point with the leg straight below the hip pitch
    /// axis and no hip roll (m): where the feet stand at zero angles.
    pub fn straight_ankle_in_hip_m(&self) -> Vector3<f64> {
        Vector3::new(
            self.hip_pitch_forward_m,
            self.ankle_lateral_m,
            -(self.hip_roll_to_pitch_m + self.thigh_m + self.shin_m),
        )
    }
    /// Longest reach from the hip-pitch axis to the ankle-pitch axis (m).
    pub fn max_reach_m(&self) -> f64 {
        self.thigh_m + self.shin_m
    }
}

fn axis_of(v: &Vector3<f64>) -> Option<(Axis, f64)> {
    for (axis, k) in [(Axis::X, 0), (Axis::Y, 1), (Axis::Z, 2)] {
        if v[k].abs() > AXIS_COS {
            return Some((axis, v[k].signum()));
        }
    }
    None
}

fn axis_name(a: Option<(Axis, f64)>) -> &'static str {
    match a {
        Some((Axis::X, _)) => "x",
        Some((Axis::Y, _)) => "y",
        Some((Axis::Z, _)) => "z",
        None => "oblique",
    }
}

/// Zero-angle facts of the tree that leg finding needs.
struct ZeroPose {
    poses: Vec<Isometry3<f64>>,
}

impl ZeroPose {
    fn new(robot: &RobotModel) -> Self {
        let q = vec![0.0; robot.dof_count()];
        // A zero vector of the right length is always accepted.
        let poses = robot
            .link_poses(&Isometry3::identity(), &q)
            .unwrap_or_default();
        Self { poses }
    }
    fn origin(&self, robot: &RobotModel, joint: usize) -> Vector3<f64> {
        robot.joint_frame(&self.poses, joint).translation.vector
    }
    fn axis(&self, robot: &RobotModel, joint: usize) -> Vector3<f64> {
        robot.joint_frame(&self.poses, joint).rotation * robot.joints()[joint].axis.into_inner()
    }
}

/// The movable-joint chains from the root to every leaf link.
fn chains(robot: &RobotModel) -> Vec<(usize, Vec<usize>)> {
    let mut out = Vec::new();
    let mut stack = vec![(robot.root(), Vec::new())];
    while let Some((link, path)) = stack.pop() {
        let children = &robot.links()[link].child_joints;
        if children.is_empty() {
            out.push((link, path));
            continue;
        }
        for &j in children {
            let mut p = path.clone();
            if robot.joints()[j].kind != JointKind::Fixed {
                p.push(j);
            }
            stack.push((robot.joints()[j].child, p));
        }
    }
    out.sort_by_key(|(leaf, _)| *leaf);
    out
}

const PATTERN: [JointRole; 6] = JointRole::ALL;

/// Joint indices of one leg by [`JointRole`].
type LegIds = [Option<usize>; 6];

/// Finds the two legs and reads their geometry; the first problem found is the error.
pub(crate) fn find_legs(
    robot: &RobotModel,
    role_map: Option<&LegRoleMap>,
) -> Result<[Leg; 2], ModelError> {
    find_legs_all(robot, role_map).map_err(|mut problems| problems.swap_remove(0))
}

/// Finds the two legs and reads their geometry, or lists every problem found (never an
/// empty list): both legs are read even when the first is wrong.
pub(crate) fn find_legs_all(
    robot: &RobotModel,
    role_map: Option<&LegRoleMap>,
) -> Result<[Leg; 2], Vec<ModelError>> {
    let zero = ZeroPose::new(robot);
    let found: Vec<(Side, LegIds)> = match role_map {
        Some(map) => match (
            mapped(robot, &zero, &map.left),
            mapped(robot, &zero, &map.right),
        ) {
            (Ok(l), Ok(r)) => vec![(Side::Left, l), (Side::Right, r)],
            (l, r) => return Err(l.err().into_iter().chain(r.err()).collect()),
        },
        None => detect(robot, &zero).map_err(|e| vec![e])?,
    };
    let mut legs = found
        .into_iter()
        .map(|(side, joints)| leg_geometry(robot, &zero, side, joints));
    let (Some(a), Some(b)) = (legs.next(), legs.next()) else {
        return Err(vec![ModelError::NotABiped("fewer than two legs".into())]);
    };
    let (left, right) = match (a, b) {
        (Ok(l), Ok(r)) => (l, r),
        (l, r) => return Err(l.err().into_iter().chain(r.err()).flatten().collect()),
    };
    // A role map can swap the sides (or name one leg twice): the left hip must be left of the right one.
    if left.hip_in_base_m.y <= right.hip_in_base_m.y {
        let hip = |l: &Leg| {
            l.joint(JointRole::HipRoll)
                .map(|j| j.name.clone())
                .unwrap_or_default()
        };
        return Err(vec![ModelError::RoleMap(format!(
            "the left leg's hip roll joint `{}` is at y = {:.4} m, not left of the right leg's `{}` at y = {:.4} m (left and right swapped, or one leg named twice?)",
            hip(&left),
            left.hip_in_base_m.y,
            hip(&right),
            right.hip_in_base_m.y
        ))]);
    }
    Ok([left, right])
}

fn role_of(robot: &RobotModel, zero: &ZeroPose, j: usize) -> Option<(Axis, f64)> {
    if !matches!(
        robot.joints()[j].kind,
        JointKind::Revolute | JointKind::Continuous
    ) {
        return None;
    }
    axis_of(&zero.axis(robot, j))
}

fn detect(robot: &RobotModel, zero: &ZeroPose) -> Result<Vec<(Side, LegIds)>, ModelError> {
    let mut legs: Vec<LegIds> = Vec::new();
    let mut rejected = Vec::new();
    for (leaf, path) in chains(robot) {
        let axes: Vec<Option<(Axis, f64)>> =
            path.iter().map(|&j| role_of(robot, zero, j)).collect();
        let matches = |n: usize| {
            path.len() >= n
                && PATTERN[6 - n..]
                    .iter()
                    .zip(&axes[path.len() - n..])
                    .all(|(role, a)| a.map(|(ax, _)| ax) == Some(role.axis()))
        };
        let n = if matches(6) {
            6
        } else if matches(5) {
            5
        } else {
            0
        };
        if n > 0 {
            let mut joints = [None; 6];
            for (k, &j) in path[path.len() - n..].iter().enumerate() {
                joints[6 - n + k] = Some(j);
            }
            if !legs.contains(&joints) {
                legs.push(joints);
            }
        } else if path.len() >= 3 {
            // Say which joint breaks the pattern, counting from the foot end.
            let tail = &path[path.len().saturating_sub(5)..];
            let tail_axes = &axes[path.len() - tail.len()..];
            let pattern = &PATTERN[6 - tail.len()..];
            let fault = tail
                .iter()
                .zip(tail_axes)
                .zip(pattern)
                .rev()
                .find(|((_, a), role)| a.map(|(ax, _)| ax) != Some(role.axis()))
                .map(|((&j, a), role)| {
                    format!(
                        "joint `{}` (axis {}) where a {role} joint (axis {}) belongs",
                        robot.joints()[j].name,
                        axis_name(*a),
                        match role.axis() {
                            Axis::X => "x",
                            Axis::Y => "y",
                            Axis::Z => "z",
                        }
                    )
                })
                .unwrap_or_else(|| "too few movable joints".into());
            let names: Vec<String> = path
                .iter()
                .zip(&axes)
                .map(|(&j, a)| format!("{}({})", robot.joints()[j].name, axis_name(*a)))
                .collect();
            rejected.push(format!(
                "chain to link `{}` [{}]: {fault}",
                robot.links()[leaf].name,
                names.join(", ")
            ));
        }
    }
    let side_of = |joints: &LegIds| {
        let hip = joints[1].map(|j| zero.origin(robot, j).y).unwrap_or(0.0);
        if hip > 0.0 { Side::Left } else { Side::Right }
    };
    let explain = |what: String| {
        let mut s = format!(
            "{what}; a leg is a chain of movable joints ending in [hip_yaw (z),] hip_roll (x), hip_pitch (y), knee (y), ankle_pitch (y), ankle_roll (x), axes in the base frame at zero angles"
        );
        if !rejected.is_empty() {
            s.push_str("; chains that are not legs: ");
            s.push_str(&rejected.join("; "));
        }
        s.push_str(" (name the leg joints explicitly with a role map if the axes are unusual)");
        ModelError::NotABiped(s)
    };
    if legs.len() != 2 {
        let names: Vec<String> = legs
            .iter()
            .map(|l| {
                l[1].map(|j| robot.joints()[j].name.clone())
                    .unwrap_or_default()
            })
            .collect();
        return Err(explain(format!(
            "found {} leg chain(s) {:?} from base link `{}`, need 2",
            legs.len(),
            names,
            robot.links()[robot.root()].name
        )));
    }
    let (a, b) = (side_of(&legs[0]), side_of(&legs[1]));
    if a == b {
        return Err(ModelError::NotABiped(format!(
            "both legs (hip roll joints `{}` and `{}`) are on the {a} side of the base",
            legs[0][1]
                .map(|j| robot.joints()[j].name.clone())
                .unwrap_or_default(),
            legs[1][1]
                .map(|j| robot.joints()[j].name.clone())
                .unwrap_or_default()
        )));
    }
    let mut out = vec![(a, legs[0]), (b, legs[1])];
    out.sort_by_key(|(s, _)| s.index());
    Ok(out)
}

fn mapped(
    robot: &RobotModel,
    zero: &ZeroPose,
    names: &LegJointNames,
) -> Result<LegIds, ModelError> {
    let mut joints = [None; 6];
    for (role, name) in JointRole::ALL.into_iter().zip(names.by_role()) {
        let Some(name) = name else { continue };
        let j = robot.joint_index(name).ok_or_else(|| {
            ModelError::RoleMap(format!("{role} joint `{name}` is not in the URDF"))
        })?;
        match role_of(robot, zero, j) {
            Some((axis, _)) if axis == role.axis() => {}
            other => {
                return Err(ModelError::RoleMap(format!(
                    "{role} joint `{name}` is not a revolute joint about the base {} axis at zero angles (its axis is {})",
                    axis_name(Some((role.axis(), 1.0))),
                    if matches!(
                        robot.joints()[j].kind,
                        JointKind::Revolute | JointKind::Continuous
                    ) {
                        axis_name(other)
                    } else {
                        "not revolute"
                    }
                )));
            }
        }
        joints[role as usize] = Some(j);
    }
    // Each joint must be the nearest movable ancestor of the next.
    let present: Vec<usize> = joints.iter().flatten().copied().collect();
    for w in present.windows(2) {
        let mut link = robot.joints()[w[1]].parent;
        let ok = loop {
            let Some(pj) = robot.links()[link].parent_joint else {
                break false;
            };
            if pj == w[0] {
                break true;
            }
            if robot.joints()[pj].kind != JointKind::Fixed {
                break false;
            }
            link = robot.joints()[pj].parent;
        };
        if !ok {
            return Err(ModelError::RoleMap(format!(
                "joint `{}` does not follow joint `{}` in the chain (only fixed joints may stand between leg joints)",
                robot.joints()[w[1]].name,
                robot.joints()[w[0]].name
            )));
        }
    }
    Ok(joints)
}

fn leg_geometry(
    robot: &RobotModel,
    zero: &ZeroPose,
    side: Side,
    ids: LegIds,
) -> Result<Leg, Vec<ModelError>> {
    let bad = |why: String| ModelError::LegGeometry { side, why };
    // Every problem of the leg, each one independent of the others; the ones after which
    // nothing more can be measured return at once.
    let mut problems = Vec::new();
    let name = |j: usize| robot.joints()[j].name.clone();
    let mut joints: [Option<LegJoint>; 6] = Default::default();
    for role in JointRole::ALL {
        let Some(j) = ids[role as usize] else {
            continue;
        };
        let joint = &robot.joints()[j];
        let (_, sign) = axis_of(&zero.axis(robot, j)).unwrap_or((Axis::X, 1.0));
        let (Some(dof), Some(limits)) = (joint.dof, joint.limits) else {
            problems.push(bad(format!("{role} joint `{}` is not movable", joint.name)));
            continue;
        };
        joints[role as usize] = Some(LegJoint {
            name: joint.name.clone(),
            joint: j,
            dof,
            axis_sign: sign,
            limits,
        });
    }
    let id = |r: JointRole| ids[r as usize].ok_or_else(|| vec![bad(format!("no {r} joint"))]);
    let (roll, pitch, knee, ap, ar) = (
        id(JointRole::HipRoll)?,
        id(JointRole::HipPitch)?,
        id(JointRole::Knee)?,
        id(JointRole::AnklePitch)?,
        id(JointRole::AnkleRoll)?,
    );
    let (p_roll, p_pitch, p_knee, p_ap, p_ar) = (
        zero.origin(robot, roll),
        zero.origin(robot, pitch),
        zero.origin(robot, knee),
        zero.origin(robot, ap),
        zero.origin(robot, ar),
    );

    // The legs are read as lines: a joint origin may slide along its own axis without
    // changing any pose (ALGORITHM.md, "Leg layouts of real servo humanoids").
    let p_hip = match ids[0] {
        Some(yaw) => {
            // The yaw axis (vertical) crosses the roll axis (along x) where y agrees.
            let p_yaw = zero.origin(robot, yaw);
            let dy = p_yaw.y - p_roll.y;
            if dy.abs() > TOL_M {
                problems.push(bad(format!(
                    "the hip yaw axis of joint `{}` passes {:.6} m {} of the hip roll axis of joint `{}`; the closed form needs them to cross (the yaw joint may sit anywhere above the roll axis, fore or aft of the roll joint, but not beside it)",
                    name(yaw),
                    dy.abs(),
                    if dy > 0.0 { "left" } else { "right" },
                    name(roll)
                )));
            }
            Vector3::new(p_yaw.x, p_roll.y, p_roll.z)
        }
        None => Vector3::new(p_pitch.x, p_roll.y, p_roll.z),
    };
    // The ankle pitch axis (along y) crosses the ankle roll axis (along x) where z agrees.
    let dz = p_ar.z - p_ap.z;
    if dz.abs() > TOL_M {
        problems.push(bad(format!(
            "the ankle roll axis of joint `{}` passes {:.6} m {} the ankle pitch axis of joint `{}`; the closed form needs the ankle axes to cross (the roll joint may sit anywhere along its axis, fore or aft, and sideways of the pitch joint, but not above or below it)",
            name(ar),
            dz.abs(),
            if dz > 0.0 { "above" } else { "below" },
            name(ap)
        )));
    }
    let p_ankle = Vector3::new(p_ap.x, p_ar.y, p_ap.z);
    let thigh = p_knee - p_pitch;
    let shin = p_ap - p_knee;
    let (l1, l2) = (thigh.xz().norm(), shin.xz().norm());
    for (what, l, j) in [("thigh", l1, knee), ("shin", l2, ap)] {
        if l < 1e-3 {
            problems.push(bad(format!(
                "{what} length {l:.6} m (to joint `{}`) is too short to be a leg",
                name(j)
            )));
        }
    }
    if p_ap.z >= p_pitch.z {
        problems.push(bad(format!(
            "ankle pitch joint `{}` is not below hip pitch joint `{}` at zero angles",
            name(ap),
            name(pitch)
        )));
    }

    // The foot: the ankle roll's child link and everything fixed to it; its lowest box is the sole.
    let foot_link = robot.joints()[ar].child;
    let mut sole: Option<(f64, [Vector3<f64>; 8], String)> = None;
    let mut stack = vec![foot_link];
    while let Some(l) = stack.pop() {
        let link = &robot.links()[l];
        for b in &link.collision_boxes {
            let h = b.size_m / 2.0;
            let corners: [Vector3<f64>; 8] = std::array::from_fn(|k| {
                let local = Vector3::new(
                    if k & 1 == 0 { -h.x } else { h.x },
                    if k & 2 == 0 { -h.y } else { h.y },
                    if k & 4 == 0 { -h.z } else { h.z },
                );
                (zero.poses[l] * b.origin * Point3::from(local)).coords
            });
            let bottom = corners.iter().map(|c| c.z).fold(f64::INFINITY, f64::min);
            if sole.as_ref().is_none_or(|(z, _, _)| bottom < *z) {
                sole = Some((bottom, corners, link.name.clone()));
            }
        }
        stack.extend(
            link.child_joints
                .iter()
                .filter(|&&j| robot.joints()[j].kind == JointKind::Fixed)
                .map(|&j| robot.joints()[j].child),
        );
    }
    let Some((bottom, corners, sole_link)) = sole else {
        problems.push(bad(format!(
            "foot link `{}` (after ankle roll joint `{}`) has no box collision to serve as the sole",
            robot.links()[foot_link].name,
            name(ar)
        )));
        return Err(problems);
    };
    let on_floor: Vec<&Vector3<f64>> = corners.iter().filter(|c| c.z - bottom < TOL_M).collect();
    if on_floor.len() != 4 {
        problems.push(bad(format!(
            "the sole box of link `{sole_link}` is not level at zero joint angles"
        )));
        return Err(problems);
    }
    let xs = on_floor.iter().map(|c| c.x - p_ankle.x);
    let ys = on_floor.iter().map(|c| c.y - p_ankle.y);
    let rect = SoleRect {
        x_min_m: xs.clone().fold(f64::INFINITY, f64::min),
        x_max_m: xs.fold(f64::NEG_INFINITY, f64::max),
        y_min_m: ys.clone().fold(f64::INFINITY, f64::min),
        y_max_m: ys.fold(f64::NEG_INFINITY, f64::max),
    };
    // Axis-aligned: the bottom face's four corners lie on the rectangle's corners.
    let area = rect.length_m() * rect.width_m();
    let box_area = {
        let v: Vec<Vector3<f64>> = on_floor.iter().map(|c| **c - on_floor[0]).collect();
        let mut d: Vec<f64> = v.iter().map(|x| x.norm()).collect();
        d.sort_by(f64::total_cmp);
        d[1] * d[2]
    };
    if (area - box_area).abs() > 1e-6 * area.max(1e-9) + 1e-9 {
        problems.push(bad(format!(
            "the sole box of link `{sole_link}` is turned about z; the sole must be aligned with the base x and y axes"
        )));
    }
    let ankle_to_sole = p_ankle.z - bottom;
    if ankle_to_sole <= 0.0 {
        problems.push(bad(format!(
            "the sole of link `{sole_link}` is not below the ankle pitch joint `{}`",
            name(ap)
        )));
    }

    if !problems.is_empty() {
        return Err(problems);
    }
    let angle = |v: Vector3<f64>| v.x.atan2(-v.z);
    let ankle_in_roll_joint_m =
        (robot.joint_frame(&zero.poses, ar).inverse() * Point3::from(p_ankle)).coords;
    Ok(Leg {
        side,
        joints,
        hip_in_base_m: p_hip,
        hip_roll_to_pitch_m: p_hip.z - p_pitch.z,
        hip_pitch_forward_m: p_pitch.x - p_hip.x,
        ankle_lateral_m: p_ankle.y - p_hip.y,
        ankle_in_roll_joint_m,
        thigh_m: l1,
        shin_m: l2,
        thigh_angle0_rad: angle(thigh),
        shin_angle0_rad: angle(shin),
        ankle_to_sole_m: ankle_to_sole,
        sole: rect,
        foot_link,
        foot_rotation0: zero.poses[foot_link].rotation,
    })
}
