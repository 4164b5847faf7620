//! Errors of the kinematic core. Every variant names the link, joint or value at fault.

use crate::legs::Side;

/// Why a URDF could not be turned into a [`crate::RobotModel`] or a [`crate::BipedModel`].
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// The file could not be read.
    #[error("cannot read URDF file {path}: {source}")]
    Io {
        /// The path given.
        path: String,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A leg map file could not be read.
    #[error("cannot read leg map file {path}: {source}")]
    LegMapRead {
        /// The path given.
        path: String,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A leg map file is not a leg map (bad YAML, an unknown or missing key).
    #[error("leg map file {path}: {source}")]
    LegMapParse {
        /// The path given.
        path: String,
        /// What the YAML reader found.
        source: serde_norway::Error,
    },
    /// The text is not a URDF urdf-rs can parse (bad XML, missing attribute, bad number).
    #[error("URDF does not parse: {0}")]
    Parse(String),
    /// The URDF has no link at all.
    #[error("URDF has no links")]
    NoLinks,
    /// Two links share one name.
    #[error("link name `{link}` is used twice")]
    DuplicateLink {
        /// The repeated name.
        link: String,
    },
    /// Two joints share one name.
    #[error("joint name `{joint}` is used twice")]
    DuplicateJoint {
        /// The repeated name.
        joint: String,
    },
    /// A joint refers to a link that does not exist.
    #[error("joint `{joint}` names {role} link `{link}`, which does not exist")]
    UnknownLink {
        /// The joint.
        joint: String,
        /// "parent" or "child".
        role: &'static str,
        /// The missing link.
        link: String,
    },
    /// A link is the child of two joints.
    #[error("link `{link}` is the child of two joints, `{first}` and `{second}`")]
    TwoParents {
        /// The link.
        link: String,
        /// One joint.
        first: String,
        /// The other joint.
        second: String,
    },
    /// The tree does not have exactly one root (several roots, or a cycle).
    #[error(
        "the links do not form one tree: roots {roots:?} (a URDF has exactly one root link; a cycle leaves none)"
    )]
    NotATree {
        /// The links without a parent joint.
        roots: Vec<String>,
    },
    /// A link named as base is not in the URDF.
    #[error("base link `{0}` is not in the URDF")]
    UnknownBase(String),
    /// A number in the URDF is NaN or infinite.
    #[error("{element} has a non-finite value {value}")]
    NonFinite {
        /// Where it is, e.g. "joint `l_knee` origin".
        element: String,
        /// The value.
        value: f64,
    },
    /// A movable joint has a zero axis.
    #[error("joint `{joint}` has a zero-length axis")]
    ZeroAxis {
        /// The joint.
        joint: String,
    },
    /// A movable joint has unusable limits.
    #[error("joint `{joint}` has unusable limits: {why}")]
    BadLimits {
        /// The joint.
        joint: String,
        /// What is wrong, with the values.
        why: String,
    },
    /// A joint type the kinematic core does not handle (floating, planar, spherical).
    #[error("joint `{joint}` has type {kind}, which this robot model does not support")]
    UnsupportedJoint {
        /// The joint.
        joint: String,
        /// Its type.
        kind: String,
    },
    /// An inertial that is not physically valid.
    #[error("link `{link}` has an invalid inertial: {why}")]
    BadInertial {
        /// The link.
        link: String,
        /// What is wrong, with the values.
        why: String,
    },
    /// The URDF is not a biped of the supported shape.
    #[error("not a supported biped: {0}")]
    NotABiped(String),
    /// A leg does not have the geometry the closed-form IK needs.
    #[error("{side} leg: {why}")]
    LegGeometry {
        /// Which leg.
        side: Side,
        /// What is wrong, naming joints and distances.
        why: String,
    },
    /// The explicit role map is wrong.
    #[error("leg role map: {0}")]
    RoleMap(String),
}

/// Why an IK or FK call was refused. Unreachable targets and joint limits are *not*
/// errors: they are clamped and reported as [`crate::IkIssue`]s.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum IkError {
    /// A target coordinate is NaN or infinite.
    #[error("{side} leg: target {field} is {value}, not a finite number")]
    NonFiniteTarget {
        /// Which leg.
        side: Side,
        /// Which field, e.g. "ankle_in_hip.z".
        field: &'static str,
        /// The value.
        value: f64,
    },
    /// A joint vector of the wrong length.
    #[error("joint vector has {got} values, the robot has {expected} movable joints")]
    JointCount {
        /// Expected length.
        expected: usize,
        /// Given length.
        got: usize,
    },
    /// A joint position given to FK is NaN or infinite.
    #[error("joint `{joint}` position is {value}, not a finite number")]
    NonFiniteJoint {
        /// The joint.
        joint: String,
        /// The value.
        value: f64,
    },
    /// A numeric argument out of its range.
    #[error("{name} = {value}: {why}")]
    BadParameter {
        /// The argument.
        name: &'static str,
        /// The value given.
        value: f64,
        /// What it must be.
        why: &'static str,
    },
}

/// The robot of a node's `robot_description_file` and `leg_map_file` parameters could not be
/// built.
#[derive(Debug, thiserror::Error)]
#[error("robot_description_file `{robot_file}`, leg_map_file `{leg_map_file}`")]
pub struct ParameterFilesError {
    /// The URDF path given (empty: the built-in robot).
    pub robot_file: String,
    /// The leg map path given (empty: none).
    pub leg_map_file: String,
    /// Why.
    #[source]
    pub source: ModelError,
}
