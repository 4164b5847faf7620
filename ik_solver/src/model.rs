//! The kinematic tree of any URDF: links, joints, forward kinematics and centre of mass.
//!
//! This is the only module that reads `urdf_rs` types; everything after it speaks nalgebra.
//! Joint positions are a flat slice indexed by *dof index*: the movable joints in URDF file
//! order ([`RobotModel::dof_names`]).

use std::collections::HashMap;

use nalgebra::{Isometry3, Matrix3, Point3, Translation3, Unit, UnitQuaternion, Vector3};

use crate::error::{IkError, ModelError};

/// How a joint moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    /// Rigid.
    Fixed,
    /// Rotation about the axis, with limits (rad).
    Revolute,
    /// Rotation about the axis, no position limits.
    Continuous,
    /// Translation along the axis (m).
    Prismatic,
}

/// Limits of a movable joint, from the URDF `<limit>`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointLimits {
    /// Lowest position (rad, or m for prismatic). `-inf` for continuous joints.
    pub lower: f64,
    /// Highest position (rad, or m for prismatic). `+inf` for continuous joints.
    pub upper: f64,
    /// Speed limit (rad/s or m/s).
    pub velocity: f64,
    /// Torque or force limit (N·m or N).
    pub effort: f64,
}

impl JointLimits {
    /// `position` clamped into `[lower, upper]`.
    pub fn clamp(&self, position: f64) -> f64 {
        position.clamp(self.lower, self.upper)
    }
}

/// Mass properties of a link.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Inertial {
    /// Mass (kg).
    pub mass_kg: f64,
    /// Centre of mass in the link frame (m).
    pub com_in_link_m: Vector3<f64>,
    /// Inertia tensor about the CoM, in link-frame axes (kg·m²).
    pub inertia_kg_m2: Matrix3<f64>,
}

/// An axis-aligned box collision shape, placed in its link's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CollisionBox {
    /// Pose of the box centre in the link frame.
    pub origin: Isometry3<f64>,
    /// Edge lengths (m).
    pub size_m: Vector3<f64>,
}

/// A link of the tree.
#[derive(Debug, Clone)]
pub struct Link {
    /// URDF name.
    pub name: String,
    /// Mass properties; `None` for massless links.
    pub inertial: Option<Inertial>,
    /// Box collision shapes (other shapes are not needed by the core).
    pub collision_boxes: Vec<CollisionBox>,
    /// Index of the joint whose child this is; `None` for the root.
    pub parent_joint: Option<usize>,
    /// Joints whose parent this is.
    pub child_joints: Vec<usize>,
}

/// A joint of the tree.
#[derive(Debug, Clone)]
pub struct Joint {
    /// URDF name.
    pub name: String,
    /// How it moves.
    pub kind: JointKind,
    /// Parent link index.
    pub parent: usize,
    /// Child link index.
    pub child: usize,
    /// Pose of the joint frame in the parent link frame.
    pub origin: Isometry3<f64>,
    /// Unit axis in the joint frame.
    pub axis: Unit<Vector3<f64>>,
    /// Limits (movable joints only).
    pub limits: Option<JointLimits>,
    /// Position of this joint in the joint vector (movable joints only).
    pub dof: Option<usize>,
}

/// The kinematic tree of a URDF, ready for forward kinematics.
#[derive(Debug, Clone)]
pub struct RobotModel {
    name: String,
    links: Vec<Link>,
    joints: Vec<Joint>,
    root: usize,
    /// Joints ordered so that each joint's parent link is placed before it.
    order: Vec<usize>,
    /// Joint index of each dof.
    dof_joints: Vec<usize>,
    link_index: HashMap<String, usize>,
    joint_index: HashMap<String, usize>,
}

fn finite3(element: impl Fn() -> String, v: &[f64; 3]) -> Result<Vector3<f64>, ModelError> {
    for &x in v {
        if !x.is_finite() {
            return Err(ModelError::NonFinite {
                element: element(),
                value: x,
            });
        }
    }
    Ok(Vector3::new(v[0], v[1], v[2]))
}

fn pose(
    element: impl Fn() -> String + Copy,
    p: &urdf_rs::Pose,
) -> Result<Isometry3<f64>, ModelError> {
    let xyz = finite3(|| format!("{} xyz", element()), &p.xyz.0)?;
    let rpy = finite3(|| format!("{} rpy", element()), &p.rpy.0)?;
    Ok(Isometry3::from_parts(
        Translation3::from(xyz),
        UnitQuaternion::from_euler_angles(rpy.x, rpy.y, rpy.z),
    ))
}

fn inertial(link: &urdf_rs::Link) -> Result<Option<Inertial>, ModelError> {
    let bad = |why: String| ModelError::BadInertial {
        link: link.name.clone(),
        why,
    };
    let i = &link.inertial;
    let m = i.mass.value;
    if !m.is_finite() || m < 0.0 {
        return Err(bad(format!(
            "mass {m} kg is not a finite non-negative number"
        )));
    }
    if m == 0.0 {
        return Ok(None);
    }
    let origin = pose(
        || format!("link `{}` inertial origin", link.name),
        &i.origin,
    )?;
    let t = &i.inertia;
    let local = Matrix3::new(
        t.ixx, t.ixy, t.ixz, t.ixy, t.iyy, t.iyz, t.ixz, t.iyz, t.izz,
    );
    if local.iter().any(|x| !x.is_finite()) {
        return Err(bad("inertia has a non-finite entry".into()));
    }
    let eig = local.symmetric_eigenvalues();
    let (a, b, c) = (eig[0], eig[1], eig[2]);
    // A small relative tolerance: URDFs are written with a few significant digits.
    let tol = 1e-6 * (a.abs() + b.abs() + c.abs()).max(1e-12);
    if a < -tol || b < -tol || c < -tol {
        return Err(bad(format!(
            "inertia is not positive semi-definite (principal moments {a:.3e}, {b:.3e}, {c:.3e} kg·m²)"
        )));
    }
    if a + b < c - tol || a + c < b - tol || b + c < a - tol {
        return Err(bad(format!(
            "principal moments {a:.3e}, {b:.3e}, {c:.3e} kg·m² break the triangle inequality (no real body has them)"
        )));
    }
    let r = origin.rotation.to_rotation_matrix();
    Ok(Some(Inertial {
        mass_kg: m,
        com_in_link_m: origin.translation.vector,
        inertia_kg_m2: r.matrix() * local * r.matrix().transpose(),
    }))
}

impl RobotModel {
    /// Parses a URDF document.
    ///
    /// ```
    /// let urdf = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../config/biped.urdf")).unwrap();
    /// let robot = ik_solver::RobotModel::from_urdf_str(&urdf).unwrap();
    /// assert_eq!(robot.dof_count(), 20);
    /// ```
    pub fn from_urdf_str(urdf: &str) -> Result<Self, ModelError> {
        let robot =
            urdf_rs::read_from_string(urdf).map_err(|e| ModelError::Parse(e.to_string()))?;
        Self::from_urdf(&robot)
    }

    /// Reads and parses a URDF file.
    pub fn from_urdf_file(path: impl AsRef<std::path::Path>) -> Result<Self, ModelError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| ModelError::Io {
            path: path.display().to_string(),
            source,
        })?;
        Self::from_urdf_str(&text)
    }

    /// Builds the tree from a parsed URDF; the first problem found is the error.
    pub fn from_urdf(robot: &urdf_rs::Robot) -> Result<Self, ModelError> {
        Self::from_urdf_all(robot).map_err(|mut problems| problems.swap_remove(0))
    }

    /// Builds the tree from a parsed URDF, or lists every problem found (never an empty
    /// list): each link and joint is checked on its own, then the tree. A bad link or joint
    /// stands in the tree as a massless link or a fixed joint, so one mistake is reported once
    /// and not again as a broken tree.
    pub fn from_urdf_all(robot: &urdf_rs::Robot) -> Result<Self, Vec<ModelError>> {
        if robot.links.is_empty() {
            return Err(vec![ModelError::NoLinks]);
        }
        let mut problems = Vec::new();
        let mut links = Vec::with_capacity(robot.links.len());
        let mut link_index = HashMap::new();
        for l in &robot.links {
            if link_index.insert(l.name.clone(), links.len()).is_some() {
                problems.push(ModelError::DuplicateLink {
                    link: l.name.clone(),
                });
                continue;
            }
            let link = Self::link(l).unwrap_or_else(|e| {
                problems.push(e);
                Link {
                    name: l.name.clone(),
                    inertial: None,
                    collision_boxes: Vec::new(),
                    parent_joint: None,
                    child_joints: Vec::new(),
                }
            });
            links.push(link);
        }

        let mut joints = Vec::with_capacity(robot.joints.len());
        let mut joint_index = HashMap::new();
        for j in &robot.joints {
            if joint_index.contains_key(&j.name) {
                problems.push(ModelError::DuplicateJoint {
                    joint: j.name.clone(),
                });
                continue;
            }
            let find = |role: &'static str, name: &str| {
                link_index
                    .get(name)
                    .copied()
                    .ok_or_else(|| ModelError::UnknownLink {
                        joint: j.name.clone(),
                        role,
                        link: name.to_owned(),
                    })
            };
            let (parent, child) =
                match (find("parent", &j.parent.link), find("child", &j.child.link)) {
                    (Ok(p), Ok(c)) => (p, c),
                    (p, c) => {
                        problems.extend(p.err());
                        problems.extend(c.err());
                        continue;
                    }
                };
            joint_index.insert(j.name.clone(), joints.len());
            let joint = Self::joint(j, parent, child).unwrap_or_else(|e| {
                problems.push(e);
                Joint {
                    name: j.name.clone(),
                    kind: JointKind::Fixed,
                    parent,
                    child,
                    origin: Isometry3::identity(),
                    axis: Vector3::x_axis(),
                    limits: None,
                    dof: None,
                }
            });
            joints.push(joint);
        }
        Self::tree(robot, links, joints, link_index, joint_index, problems)
    }

    /// One link, checked.
    fn link(l: &urdf_rs::Link) -> Result<Link, ModelError> {
        let mut collision_boxes = Vec::new();
        for (k, c) in l.collision.iter().enumerate() {
            if let urdf_rs::Geometry::Box { size } = &c.geometry {
                let origin = pose(
                    || format!("link `{}` collision {k} origin", l.name),
                    &c.origin,
                )?;
                let size_m = finite3(
                    || format!("link `{}` collision {k} box size", l.name),
                    &size.0,
                )?;
                collision_boxes.push(CollisionBox { origin, size_m });
            }
        }
        Ok(Link {
            name: l.name.clone(),
            inertial: inertial(l)?,
            collision_boxes,
            parent_joint: None,
            child_joints: Vec::new(),
        })
    }

    /// One joint between known links, checked.
    fn joint(j: &urdf_rs::Joint, parent: usize, child: usize) -> Result<Joint, ModelError> {
        let kind = match j.joint_type {
            urdf_rs::JointType::Fixed => JointKind::Fixed,
            urdf_rs::JointType::Revolute => JointKind::Revolute,
            urdf_rs::JointType::Continuous => JointKind::Continuous,
            urdf_rs::JointType::Prismatic => JointKind::Prismatic,
            ref other => {
                return Err(ModelError::UnsupportedJoint {
                    joint: j.name.clone(),
                    kind: format!("{other:?}").to_lowercase(),
                });
            }
        };
        let origin = pose(|| format!("joint `{}` origin", j.name), &j.origin)?;
        let axis_v = finite3(|| format!("joint `{}` axis", j.name), &j.axis.xyz.0)?;
        let axis = if kind == JointKind::Fixed {
            Unit::new_normalize(Vector3::x())
        } else {
            Unit::try_new(axis_v, 1e-9).ok_or_else(|| ModelError::ZeroAxis {
                joint: j.name.clone(),
            })?
        };
        let limits = match kind {
            JointKind::Fixed => None,
            JointKind::Continuous => Some(JointLimits {
                lower: f64::NEG_INFINITY,
                upper: f64::INFINITY,
                velocity: j.limit.velocity,
                effort: j.limit.effort,
            }),
            JointKind::Revolute | JointKind::Prismatic => {
                let l = &j.limit;
                let bad = |why: String| ModelError::BadLimits {
                    joint: j.name.clone(),
                    why,
                };
                if l.lower.is_nan() || l.upper.is_nan() || l.lower >= l.upper {
                    return Err(bad(format!(
                        "lower {} is not below upper {}",
                        l.lower, l.upper
                    )));
                }
                if !(l.velocity.is_finite() && l.velocity > 0.0) {
                    return Err(bad(format!(
                        "velocity limit {} is not a positive number",
                        l.velocity
                    )));
                }
                if l.effort.is_nan() || l.effort < 0.0 {
                    return Err(bad(format!(
                        "effort limit {} is negative or not a number",
                        l.effort
                    )));
                }
                Some(JointLimits {
                    lower: l.lower,
                    upper: l.upper,
                    velocity: l.velocity,
                    effort: l.effort,
                })
            }
        };
        Ok(Joint {
            name: j.name.clone(),
            kind,
            parent,
            child,
            origin,
            axis,
            limits,
            dof: None,
        })
    }

    /// Links the checked links and joints into one tree, or lists every problem.
    fn tree(
        robot: &urdf_rs::Robot,
        mut links: Vec<Link>,
        mut joints: Vec<Joint>,
        link_index: HashMap<String, usize>,
        joint_index: HashMap<String, usize>,
        mut problems: Vec<ModelError>,
    ) -> Result<Self, Vec<ModelError>> {
        let mut two_parents = false;
        for (ji, j) in joints.iter().enumerate() {
            let child = &mut links[j.child];
            if let Some(prev) = child.parent_joint {
                problems.push(ModelError::TwoParents {
                    link: child.name.clone(),
                    first: joints[prev].name.clone(),
                    second: j.name.clone(),
                });
                two_parents = true;
                continue;
            }
            child.parent_joint = Some(ji);
            links[j.parent].child_joints.push(ji);
        }
        let roots: Vec<usize> = (0..links.len())
            .filter(|&i| links[i].parent_joint.is_none())
            .collect();
        if roots.len() != 1 {
            problems.push(ModelError::NotATree {
                roots: roots.iter().map(|&i| links[i].name.clone()).collect(),
            });
            return Err(problems);
        }
        if two_parents {
            return Err(problems);
        }
        let root = roots[0];

        // Breadth-first from the root; a cycle leaves joints unreached.
        let mut order = Vec::with_capacity(joints.len());
        let mut queue = std::collections::VecDeque::from([root]);
        while let Some(l) = queue.pop_front() {
            for &ji in &links[l].child_joints {
                order.push(ji);
                queue.push_back(joints[ji].child);
            }
        }
        if order.len() != joints.len() {
            let reached: std::collections::HashSet<usize> = order.iter().copied().collect();
            let stray = (0..joints.len())
                .find(|i| !reached.contains(i))
                .map(|i| joints[i].name.clone());
            problems.push(ModelError::NotATree {
                roots: stray
                    .into_iter()
                    .map(|j| format!("(cycle through joint `{j}`)"))
                    .collect(),
            });
        }
        if !problems.is_empty() {
            return Err(problems);
        }

        let mut dof_joints = Vec::new();
        for (ji, j) in joints.iter_mut().enumerate() {
            if j.kind != JointKind::Fixed {
                j.dof = Some(dof_joints.len());
                dof_joints.push(ji);
            }
        }
        Ok(Self {
            name: robot.name.clone(),
            links,
            joints,
            root,
            order,
            dof_joints,
            link_index,
            joint_index,
        })
    }

    /// The robot's name from the URDF.
    pub fn name(&self) -> &str {
        &self.name
    }
    /// All links, in URDF order.
    pub fn links(&self) -> &[Link] {
        &self.links
    }
    /// All joints, in URDF order.
    pub fn joints(&self) -> &[Joint] {
        &self.joints
    }
    /// Index of the root link.
    pub fn root(&self) -> usize {
        self.root
    }
    /// Link index by name.
    pub fn link_index(&self, name: &str) -> Option<usize> {
        self.link_index.get(name).copied()
    }
    /// Joint index by name.
    pub fn joint_index(&self, name: &str) -> Option<usize> {
        self.joint_index.get(name).copied()
    }
    /// Number of movable joints: the length of a joint vector.
    pub fn dof_count(&self) -> usize {
        self.dof_joints.len()
    }
    /// Joint index of each dof.
    pub fn dof_joints(&self) -> &[usize] {
        &self.dof_joints
    }
    /// Names of the movable joints, in joint-vector order.
    pub fn dof_names(&self) -> impl Iterator<Item = &str> {
        self.dof_joints
            .iter()
            .map(|&j| self.joints[j].name.as_str())
    }
    /// Dof index of a movable joint, by name.
    pub fn dof_index(&self, joint_name: &str) -> Option<usize> {
        self.joint_index(joint_name)
            .and_then(|j| self.joints[j].dof)
    }
    /// Total mass (kg).
    pub fn total_mass_kg(&self) -> f64 {
        self.links
            .iter()
            .filter_map(|l| l.inertial.map(|i| i.mass_kg))
            .sum()
    }

    /// Checks a joint vector: right length, every value finite.
    pub fn check_joint_vector(&self, q: &[f64]) -> Result<(), IkError> {
        if q.len() != self.dof_count() {
            return Err(IkError::JointCount {
                expected: self.dof_count(),
                got: q.len(),
            });
        }
        if let Some((i, &v)) = q.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(IkError::NonFiniteJoint {
                joint: self.joints[self.dof_joints[i]].name.clone(),
                value: v,
            });
        }
        Ok(())
    }

    /// Forward kinematics: the world pose of every link (indexed like [`Self::links`]) for a
    /// base (root link) pose and a joint vector. Writes into `poses` to avoid allocation.
    pub fn link_poses_into(
        &self,
        base: &Isometry3<f64>,
        q: &[f64],
        poses: &mut Vec<Isometry3<f64>>,
    ) -> Result<(), IkError> {
        self.check_joint_vector(q)?;
        poses.clear();
        poses.resize(self.links.len(), Isometry3::identity());
        poses[self.root] = *base;
        for &ji in &self.order {
            let j = &self.joints[ji];
            let position = j.dof.map_or(0.0, |d| q[d]);
            poses[j.child] = poses[j.parent] * self.joint_transform(ji, position);
        }
        Ok(())
    }

    /// The pose of joint `joint`'s child link in its parent link's frame, at `position` (rad,
    /// or m for a prismatic joint; ignored for a fixed one): the joint origin, then the
    /// rotation about (or translation along) the axis.
    pub fn joint_transform(&self, joint: usize, position: f64) -> Isometry3<f64> {
        let j = &self.joints[joint];
        let motion = match (j.kind, j.dof) {
            (JointKind::Revolute | JointKind::Continuous, Some(_)) => Isometry3::from_parts(
                Translation3::identity(),
                UnitQuaternion::from_axis_angle(&j.axis, position),
            ),
            (JointKind::Prismatic, Some(_)) => Isometry3::from_parts(
                Translation3::from(j.axis.into_inner() * position),
                UnitQuaternion::identity(),
            ),
            _ => Isometry3::identity(),
        };
        j.origin * motion
    }

    /// Forward kinematics, allocating: see [`Self::link_poses_into`].
    pub fn link_poses(
        &self,
        base: &Isometry3<f64>,
        q: &[f64],
    ) -> Result<Vec<Isometry3<f64>>, IkError> {
        let mut poses = Vec::new();
        self.link_poses_into(base, q, &mut poses)?;
        Ok(poses)
    }

    /// World pose of a joint's frame (at the joint's own position, before its motion), from
    /// link poses computed by [`Self::link_poses`].
    pub fn joint_frame(&self, poses: &[Isometry3<f64>], joint: usize) -> Isometry3<f64> {
        let j = &self.joints[joint];
        poses[j.parent] * j.origin
    }

    /// Whole-body centre of mass (world, m) from link poses.
    pub fn center_of_mass(&self, poses: &[Isometry3<f64>]) -> Point3<f64> {
        let (mut m, mut sum) = (0.0, Vector3::zeros());
        for (l, pose) in self.links.iter().zip(poses) {
            if let Some(i) = &l.inertial {
                m += i.mass_kg;
                sum += i.mass_kg * (pose * Point3::from(i.com_in_link_m)).coords;
            }
        }
        if m > 0.0 {
            Point3::from(sum / m)
        } else {
            poses[self.root].translation.vector.into()
        }
    }

    /// Mass (kg) and centre of mass (world) of the subtree below joint `joint` (its child link
    /// and everything after it), from link poses.
    pub fn subtree_mass_and_com(
        &self,
        poses: &[Isometry3<f64>],
        joint: usize,
    ) -> (f64, Point3<f64>) {
        let (mut m, mut sum) = (0.0, Vector3::zeros());
        let mut stack = vec![self.joints[joint].child];
        while let Some(l) = stack.pop() {
            let link = &self.links[l];
            if let Some(i) = &link.inertial {
                m += i.mass_kg;
                sum += i.mass_kg * (poses[l] * Point3::from(i.com_in_link_m)).coords;
            }
            stack.extend(link.child_joints.iter().map(|&j| self.joints[j].child));
        }
        (
            m,
            if m > 0.0 {
                Point3::from(sum / m)
            } else {
                Point3::origin()
            },
        )
    }
}
