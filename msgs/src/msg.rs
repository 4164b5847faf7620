//! Message types, in `.msg` field order.

use serde::{Deserialize, Serialize};

/// A ROS message type: its package, name and fields (name, type as rosidl spells it in
/// `get_fields_and_field_types()`), in `.msg` order.
pub trait RosMessage: ros2_client::Message + Clone + PartialEq + std::fmt::Debug + Default {
    /// Package, e.g. `sensor_msgs`.
    const PACKAGE: &'static str;
    /// Type name, e.g. `JointState`.
    const NAME: &'static str;
    /// Fields in order: (name, rosidl type).
    const FIELDS: &'static [(&'static str, &'static str)];
    /// `package/msg/Name`, as ROS tools and rosbag2 write it.
    const TYPE_NAME: &'static str;

    /// `package/msg/Name`, as ROS tools print it.
    fn type_name() -> String {
        Self::TYPE_NAME.to_string()
    }
    /// The type name for ros2-client.
    fn message_type_name() -> ros2_client::MessageTypeName {
        ros2_client::MessageTypeName::new(Self::PACKAGE, Self::NAME)
    }
}

macro_rules! ros_message {
    ($ty:ident, $pkg:literal, [$(($field:literal, $fty:literal)),* $(,)?]) => {
        impl ros2_client::Message for $ty {}
        impl RosMessage for $ty {
            const PACKAGE: &'static str = $pkg;
            const NAME: &'static str = stringify!($ty);
            const FIELDS: &'static [(&'static str, &'static str)] = &[$(($field, $fty)),*];
            const TYPE_NAME: &'static str = concat!($pkg, "/msg/", stringify!($ty));
        }
    };
}

/// builtin_interfaces/msg/Time.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub struct Time {
    /// Seconds.
    pub sec: i32,
    /// Nanoseconds within the second.
    pub nanosec: u32,
}
ros_message!(
    Time,
    "builtin_interfaces",
    [("sec", "int32"), ("nanosec", "uint32")]
);

impl Time {
    /// From nanoseconds since the clock's epoch (saturating at the i32 seconds range).
    pub fn from_nanos(nanos: i64) -> Self {
        let sec = nanos.div_euclid(1_000_000_000);
        let nanosec = nanos.rem_euclid(1_000_000_000) as u32;
        Self {
            sec: sec.clamp(i32::MIN as i64, i32::MAX as i64) as i32,
            nanosec,
        }
    }
    /// Nanoseconds since the clock's epoch.
    pub fn to_nanos(self) -> i64 {
        self.sec as i64 * 1_000_000_000 + self.nanosec as i64
    }
    /// Seconds as a float.
    pub fn as_secs_f64(self) -> f64 {
        self.sec as f64 + self.nanosec as f64 * 1e-9
    }
}

impl From<ros2_client::ROSTime> for Time {
    fn from(t: ros2_client::ROSTime) -> Self {
        Self::from_nanos(t.to_nanos())
    }
}

/// std_msgs/msg/Header.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// Time of the data.
    pub stamp: Time,
    /// Frame the data is in.
    pub frame_id: String,
}
ros_message!(
    Header,
    "std_msgs",
    [("stamp", "builtin_interfaces/Time"), ("frame_id", "string")]
);

/// geometry_msgs/msg/Vector3.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}
ros_message!(
    Vector3,
    "geometry_msgs",
    [("x", "double"), ("y", "double"), ("z", "double")]
);

impl From<&nalgebra::Vector3<f64>> for Vector3 {
    /// The wire form of a vector.
    fn from(v: &nalgebra::Vector3<f64>) -> Self {
        Self {
            x: v.x,
            y: v.y,
            z: v.z,
        }
    }
}

/// geometry_msgs/msg/Point.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Point {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}
ros_message!(
    Point,
    "geometry_msgs",
    [("x", "double"), ("y", "double"), ("z", "double")]
);

/// geometry_msgs/msg/Quaternion.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}
ros_message!(
    Quaternion,
    "geometry_msgs",
    [
        ("x", "double"),
        ("y", "double"),
        ("z", "double"),
        ("w", "double")
    ]
);

impl From<&nalgebra::UnitQuaternion<f64>> for Quaternion {
    /// The wire form of a rotation (x, y, z, w).
    fn from(q: &nalgebra::UnitQuaternion<f64>) -> Self {
        let q = q.quaternion();
        Self {
            x: q.i,
            y: q.j,
            z: q.k,
            w: q.w,
        }
    }
}

impl Default for Quaternion {
    /// The identity, as the ROS default (w = 1).
    fn default() -> Self {
        Self {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    }
}

/// geometry_msgs/msg/Pose.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Position.
    pub position: Point,
    /// Orientation.
    pub orientation: Quaternion,
}
ros_message!(
    Pose,
    "geometry_msgs",
    [
        ("position", "geometry_msgs/Point"),
        ("orientation", "geometry_msgs/Quaternion")
    ]
);

impl From<&nalgebra::Isometry3<f64>> for Pose {
    /// The wire form of a pose (the quaternion as x, y, z, w).
    fn from(p: &nalgebra::Isometry3<f64>) -> Self {
        let t = &p.translation.vector;
        Self {
            position: Point {
                x: t.x,
                y: t.y,
                z: t.z,
            },
            orientation: Quaternion::from(&p.rotation),
        }
    }
}

impl From<&Pose> for nalgebra::Isometry3<f64> {
    /// A pose off the wire; the quaternion is normalised.
    fn from(p: &Pose) -> Self {
        let (t, q) = (&p.position, &p.orientation);
        nalgebra::Isometry3::from_parts(
            nalgebra::Translation3::new(t.x, t.y, t.z),
            nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                q.w, q.x, q.y, q.z,
            )),
        )
    }
}

/// geometry_msgs/msg/PoseStamped.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseStamped {
    /// Stamp and frame.
    pub header: Header,
    /// The pose.
    pub pose: Pose,
}
ros_message!(
    PoseStamped,
    "geometry_msgs",
    [
        ("header", "std_msgs/Header"),
        ("pose", "geometry_msgs/Pose")
    ]
);

/// geometry_msgs/msg/PointStamped.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PointStamped {
    /// Stamp and frame.
    pub header: Header,
    /// The point.
    pub point: Point,
}
ros_message!(
    PointStamped,
    "geometry_msgs",
    [
        ("header", "std_msgs/Header"),
        ("point", "geometry_msgs/Point")
    ]
);

/// geometry_msgs/msg/Point32: a point in single precision (polygon vertices).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Point32 {
    /// x (m).
    pub x: f32,
    /// y (m).
    pub y: f32,
    /// z (m).
    pub z: f32,
}
ros_message!(
    Point32,
    "geometry_msgs",
    [("x", "float"), ("y", "float"), ("z", "float")]
);

/// geometry_msgs/msg/Polygon.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Polygon {
    /// The vertices, in order.
    pub points: Vec<Point32>,
}
ros_message!(
    Polygon,
    "geometry_msgs",
    [("points", "sequence<geometry_msgs/Point32>")]
);

/// geometry_msgs/msg/PolygonStamped.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PolygonStamped {
    /// Stamp and frame.
    pub header: Header,
    /// The polygon.
    pub polygon: Polygon,
}
ros_message!(
    PolygonStamped,
    "geometry_msgs",
    [
        ("header", "std_msgs/Header"),
        ("polygon", "geometry_msgs/Polygon")
    ]
);

/// geometry_msgs/msg/Twist.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Twist {
    /// Linear velocity (m/s).
    pub linear: Vector3,
    /// Angular velocity (rad/s).
    pub angular: Vector3,
}
ros_message!(
    Twist,
    "geometry_msgs",
    [
        ("linear", "geometry_msgs/Vector3"),
        ("angular", "geometry_msgs/Vector3")
    ]
);

/// A row-major 6 x 6 covariance (`float64[36]`: x, y, z, rotation about x, y, z), as the
/// `*WithCovariance` types carry it. A fixed array of 36: written as 36 doubles, no length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Covariance6(pub [f64; 36]);

impl Default for Covariance6 {
    fn default() -> Self {
        Self([0.0; 36])
    }
}

impl Serialize for Covariance6 {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeTuple;
        let mut t = serializer.serialize_tuple(36)?;
        for v in &self.0 {
            t.serialize_element(v)?;
        }
        t.end()
    }
}

impl<'de> Deserialize<'de> for Covariance6 {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl<'de> serde::de::Visitor<'de> for Visitor {
            type Value = Covariance6;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("36 doubles")
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> Result<Covariance6, A::Error> {
                let mut out = [0.0; 36];
                for (i, slot) in out.iter_mut().enumerate() {
                    *slot = seq
                        .next_element()?
                        .ok_or_else(|| serde::de::Error::invalid_length(i, &self))?;
                }
                Ok(Covariance6(out))
            }
        }
        deserializer.deserialize_tuple(36, Visitor)
    }
}

/// geometry_msgs/msg/PoseWithCovariance.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseWithCovariance {
    /// The pose.
    pub pose: Pose,
    /// Its covariance (m², rad²).
    pub covariance: Covariance6,
}
ros_message!(
    PoseWithCovariance,
    "geometry_msgs",
    [("pose", "geometry_msgs/Pose"), ("covariance", "double[36]")]
);

/// geometry_msgs/msg/TwistWithCovariance.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct TwistWithCovariance {
    /// The velocity.
    pub twist: Twist,
    /// Its covariance ((m/s)², (rad/s)²).
    pub covariance: Covariance6,
}
ros_message!(
    TwistWithCovariance,
    "geometry_msgs",
    [
        ("twist", "geometry_msgs/Twist"),
        ("covariance", "double[36]")
    ]
);

/// nav_msgs/msg/Odometry: the pose in `header.frame_id` (odom), the velocity in
/// `child_frame_id` (the base link), REP-105.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Odometry {
    /// Stamp and the pose's frame (`odom`).
    pub header: Header,
    /// The frame of the velocity and of the body (the base link).
    pub child_frame_id: String,
    /// The base pose in `header.frame_id`.
    pub pose: PoseWithCovariance,
    /// The base velocity in `child_frame_id`.
    pub twist: TwistWithCovariance,
}
ros_message!(
    Odometry,
    "nav_msgs",
    [
        ("header", "std_msgs/Header"),
        ("child_frame_id", "string"),
        ("pose", "geometry_msgs/PoseWithCovariance"),
        ("twist", "geometry_msgs/TwistWithCovariance"),
    ]
);

/// sensor_msgs/msg/JointState.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct JointState {
    /// Stamp.
    pub header: Header,
    /// Joint names.
    pub name: Vec<String>,
    /// Positions (rad or m).
    pub position: Vec<f64>,
    /// Velocities (rad/s or m/s); empty when not known.
    pub velocity: Vec<f64>,
    /// Efforts (N·m or N); empty when not known.
    pub effort: Vec<f64>,
}
ros_message!(
    JointState,
    "sensor_msgs",
    [
        ("header", "std_msgs/Header"),
        ("name", "sequence<string>"),
        ("position", "sequence<double>"),
        ("velocity", "sequence<double>"),
        ("effort", "sequence<double>"),
    ]
);

/// sensor_msgs/msg/Imu: orientation, angular velocity and linear acceleration (specific
/// force: gravity included, +9.81 m/s² up when still) of `header.frame_id`, in that frame.
/// The covariances are row-major 3 x 3 (x, y, z); all 0 means unknown (REP-145), element 0
/// at -1 that the quantity is not given.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Imu {
    /// Stamp and the sensor's frame.
    pub header: Header,
    /// The sensor frame's orientation in the world (a fixed frame, z up).
    pub orientation: Quaternion,
    /// Covariance of the orientation (rad²).
    pub orientation_covariance: [f64; 9],
    /// Angular velocity in the sensor frame (rad/s).
    pub angular_velocity: Vector3,
    /// Covariance of the angular velocity ((rad/s)²).
    pub angular_velocity_covariance: [f64; 9],
    /// Linear acceleration less gravity in the sensor frame (m/s²).
    pub linear_acceleration: Vector3,
    /// Covariance of the linear acceleration ((m/s²)²).
    pub linear_acceleration_covariance: [f64; 9],
}
ros_message!(
    Imu,
    "sensor_msgs",
    [
        ("header", "std_msgs/Header"),
        ("orientation", "geometry_msgs/Quaternion"),
        ("orientation_covariance", "double[9]"),
        ("angular_velocity", "geometry_msgs/Vector3"),
        ("angular_velocity_covariance", "double[9]"),
        ("linear_acceleration", "geometry_msgs/Vector3"),
        ("linear_acceleration_covariance", "double[9]"),
    ]
);

/// rosgraph_msgs/msg/Clock.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Clock {
    /// The simulated time.
    pub clock: Time,
}
ros_message!(
    Clock,
    "rosgraph_msgs",
    [("clock", "builtin_interfaces/Time")]
);

/// std_msgs/msg/String.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct StringMsg {
    /// The text.
    pub data: String,
}
impl ros2_client::Message for StringMsg {}
impl RosMessage for StringMsg {
    const PACKAGE: &'static str = "std_msgs";
    const NAME: &'static str = "String";
    const FIELDS: &'static [(&'static str, &'static str)] = &[("data", "string")];
    const TYPE_NAME: &'static str = "std_msgs/msg/String";
}

/// std_msgs/msg/Bool.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct BoolMsg {
    /// The value.
    pub data: bool,
}
impl ros2_client::Message for BoolMsg {}
impl RosMessage for BoolMsg {
    const PACKAGE: &'static str = "std_msgs";
    const NAME: &'static str = "Bool";
    const FIELDS: &'static [(&'static str, &'static str)] = &[("data", "boolean")];
    const TYPE_NAME: &'static str = "std_msgs/msg/Bool";
}

/// biped_msgs/msg/GaitPhase: where the walk is (msg/GaitPhase.msg).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct GaitPhase {
    /// Stamp of the control tick.
    pub header: Header,
    /// idle, crouch, shift, half_step, step, final_half_step, center or rise.
    pub phase: String,
    /// Which feet carry the robot: double, left or right.
    pub support: String,
    /// Number of the swing in progress or last finished (1 = the first half step).
    pub step_index: u32,
    /// Progress through the phase, 0 to 1.
    pub progress: f64,
}
ros_message!(
    GaitPhase,
    "biped_msgs",
    [
        ("header", "std_msgs/Header"),
        ("phase", "string"),
        ("support", "string"),
        ("step_index", "uint32"),
        ("progress", "double")
    ]
);

/// biped_msgs/msg/AnkleTargets: one control tick of the ankle trajectory (msg/AnkleTargets.msg).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct AnkleTargets {
    /// Stamp of the control tick; frame: the robot's base link.
    pub header: Header,
    /// Left ankle-pitch axis relative to the left hip point, base-link axes (m).
    pub left_ankle: Point,
    /// Right ankle-pitch axis relative to the right hip point, base-link axes (m).
    pub right_ankle: Point,
    /// Left foot yaw relative to the base (rad).
    pub left_foot_yaw: f64,
    /// Right foot yaw relative to the base (rad).
    pub right_foot_yaw: f64,
    /// Pelvis (base link) position in the walk's world frame (m).
    pub pelvis: Point,
}
ros_message!(
    AnkleTargets,
    "biped_msgs",
    [
        ("header", "std_msgs/Header"),
        ("left_ankle", "geometry_msgs/Point"),
        ("right_ankle", "geometry_msgs/Point"),
        ("left_foot_yaw", "double"),
        ("right_foot_yaw", "double"),
        ("pelvis", "geometry_msgs/Point"),
    ]
);

/// biped_msgs/msg/WalkCommand: start or stop a walk (msg/WalkCommand.msg).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct WalkCommand {
    /// Steps to walk; 0 walks until stopped.
    pub steps: u32,
    /// Step length (m); 0 keeps the configured one.
    pub step_length: f64,
    /// Step duration (s); 0 keeps the configured one.
    pub step_duration: f64,
    /// Stop at the next point where the feet can come together (other fields ignored).
    pub stop: bool,
    /// Take the command at the first control tick at or after this ROS time (simulated
    /// time under `use_sim_time`); zero: at once.
    pub start_time: Time,
    /// Walk at this velocity (as `cmd_vel`: REP-103 signs), scaled into the step limits;
    /// all zero: straight ahead at `step_length`.
    pub velocity: Twist,
}
ros_message!(
    WalkCommand,
    "biped_msgs",
    [
        ("steps", "uint32"),
        ("step_length", "double"),
        ("step_duration", "double"),
        ("stop", "boolean"),
        ("start_time", "builtin_interfaces/Time"),
        ("velocity", "geometry_msgs/Twist")
    ]
);

/// diagnostic_msgs/msg/KeyValue.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct KeyValue {
    /// What is reported.
    pub key: String,
    /// Its value.
    pub value: String,
}
ros_message!(
    KeyValue,
    "diagnostic_msgs",
    [("key", "string"), ("value", "string")]
);

/// diagnostic_msgs/msg/DiagnosticStatus.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct DiagnosticStatus {
    /// 0 OK, 1 WARN, 2 ERROR, 3 STALE.
    pub level: u8,
    /// What this status is about.
    pub name: String,
    /// One line.
    pub message: String,
    /// The device.
    pub hardware_id: String,
    /// Details.
    pub values: Vec<KeyValue>,
}
ros_message!(
    DiagnosticStatus,
    "diagnostic_msgs",
    [
        ("level", "octet"),
        ("name", "string"),
        ("message", "string"),
        ("hardware_id", "string"),
        ("values", "sequence<diagnostic_msgs/KeyValue>"),
    ]
);

/// diagnostic_msgs/msg/DiagnosticArray (topic `/diagnostics`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct DiagnosticArray {
    /// Stamp.
    pub header: Header,
    /// One status per device.
    pub status: Vec<DiagnosticStatus>,
}
ros_message!(
    DiagnosticArray,
    "diagnostic_msgs",
    [
        ("header", "std_msgs/Header"),
        ("status", "sequence<diagnostic_msgs/DiagnosticStatus>"),
    ]
);

/// builtin_interfaces/msg/Duration.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub struct Duration {
    /// Seconds.
    pub sec: i32,
    /// Nanoseconds within the second.
    pub nanosec: u32,
}
ros_message!(
    Duration,
    "builtin_interfaces",
    [("sec", "int32"), ("nanosec", "uint32")]
);

/// geometry_msgs/msg/Transform: where a child frame is in its parent frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Transform {
    /// The child frame's origin in the parent frame (m).
    pub translation: Vector3,
    /// The child frame's orientation in the parent frame.
    pub rotation: Quaternion,
}
ros_message!(
    Transform,
    "geometry_msgs",
    [
        ("translation", "geometry_msgs/Vector3"),
        ("rotation", "geometry_msgs/Quaternion")
    ]
);

impl From<&Pose> for Transform {
    /// The same placement: the position as the translation.
    fn from(p: &Pose) -> Self {
        Self {
            translation: Vector3 {
                x: p.position.x,
                y: p.position.y,
                z: p.position.z,
            },
            rotation: p.orientation,
        }
    }
}

impl From<&nalgebra::Isometry3<f64>> for Transform {
    /// The wire form of a frame's pose in its parent (the quaternion as x, y, z, w).
    fn from(p: &nalgebra::Isometry3<f64>) -> Self {
        Self::from(&Pose::from(p))
    }
}

/// geometry_msgs/msg/TransformStamped: one edge of the TF tree.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TransformStamped {
    /// Stamp and the parent frame.
    pub header: Header,
    /// The child frame.
    pub child_frame_id: String,
    /// The child frame in the parent frame.
    pub transform: Transform,
}
ros_message!(
    TransformStamped,
    "geometry_msgs",
    [
        ("header", "std_msgs/Header"),
        ("child_frame_id", "string"),
        ("transform", "geometry_msgs/Transform")
    ]
);

impl Odometry {
    /// The odometry's pose as the TF edge `header.frame_id` → `child_frame_id` (REP-105's
    /// `odom` → `base_link`), with its stamp.
    pub fn transform(&self) -> TransformStamped {
        TransformStamped {
            header: self.header.clone(),
            child_frame_id: self.child_frame_id.clone(),
            transform: Transform::from(&self.pose.pose),
        }
    }
}

/// tf2_msgs/msg/TFMessage (topics `/tf` and `/tf_static`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TFMessage {
    /// The transforms.
    pub transforms: Vec<TransformStamped>,
}
ros_message!(
    TFMessage,
    "tf2_msgs",
    [("transforms", "sequence<geometry_msgs/TransformStamped>")]
);

/// std_msgs/msg/ColorRGBA: each channel 0..1.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct ColorRGBA {
    /// Red.
    pub r: f32,
    /// Green.
    pub g: f32,
    /// Blue.
    pub b: f32,
    /// Opacity (0 invisible).
    pub a: f32,
}
ros_message!(
    ColorRGBA,
    "std_msgs",
    [
        ("r", "float"),
        ("g", "float"),
        ("b", "float"),
        ("a", "float")
    ]
);

/// sensor_msgs/msg/CompressedImage (here only as a Marker's texture).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CompressedImage {
    /// Acquisition time and frame.
    pub header: Header,
    /// `jpeg`, `png`, ...
    pub format: String,
    /// The compressed image.
    pub data: Vec<u8>,
}
ros_message!(
    CompressedImage,
    "sensor_msgs",
    [
        ("header", "std_msgs/Header"),
        ("format", "string"),
        ("data", "sequence<uint8>")
    ]
);

/// visualization_msgs/msg/UVCoordinate: a texture coordinate of a Marker vertex.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct UVCoordinate {
    /// u.
    pub u: f32,
    /// v.
    pub v: f32,
}
ros_message!(
    UVCoordinate,
    "visualization_msgs",
    [("u", "float"), ("v", "float")]
);

/// visualization_msgs/msg/MeshFile: a mesh sent inside a Marker.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct MeshFile {
    /// The file name (its extension says the format).
    pub filename: String,
    /// The file's bytes.
    pub data: Vec<u8>,
}
ros_message!(
    MeshFile,
    "visualization_msgs",
    [("filename", "string"), ("data", "sequence<uint8>")]
);

/// visualization_msgs/msg/Marker: one shape for RViz or Foxglove.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Marker {
    /// Stamp and the frame the shape is drawn in.
    pub header: Header,
    /// Namespace: with `id`, what names the marker.
    pub ns: String,
    /// Id within the namespace.
    pub id: i32,
    /// [`Marker::ARROW`] ... [`Marker::ARROW_STRIP`].
    pub r#type: i32,
    /// [`Marker::ADD`], [`Marker::DELETE`] or [`Marker::DELETEALL`].
    pub action: i32,
    /// Pose of the shape in the frame.
    pub pose: Pose,
    /// Size (m; for lines, x is the width).
    pub scale: Vector3,
    /// Colour of the whole shape.
    pub color: ColorRGBA,
    /// How long the shape stays (0: until replaced).
    pub lifetime: Duration,
    /// Redrawn in its frame as the frame moves.
    pub frame_locked: bool,
    /// Vertices of lines, lists and points (in the pose's frame).
    pub points: Vec<Point>,
    /// A colour per point (empty: `color`).
    pub colors: Vec<ColorRGBA>,
    /// Texture URI.
    pub texture_resource: String,
    /// Texture sent inline.
    pub texture: CompressedImage,
    /// Texture coordinates per point.
    pub uv_coordinates: Vec<UVCoordinate>,
    /// Text of a TEXT_VIEW_FACING marker.
    pub text: String,
    /// Mesh URI.
    pub mesh_resource: String,
    /// Mesh sent inline.
    pub mesh_file: MeshFile,
    /// Use the mesh's own materials.
    pub mesh_use_embedded_materials: bool,
}
ros_message!(
    Marker,
    "visualization_msgs",
    [
        ("header", "std_msgs/Header"),
        ("ns", "string"),
        ("id", "int32"),
        ("type", "int32"),
        ("action", "int32"),
        ("pose", "geometry_msgs/Pose"),
        ("scale", "geometry_msgs/Vector3"),
        ("color", "std_msgs/ColorRGBA"),
        ("lifetime", "builtin_interfaces/Duration"),
        ("frame_locked", "boolean"),
        ("points", "sequence<geometry_msgs/Point>"),
        ("colors", "sequence<std_msgs/ColorRGBA>"),
        ("texture_resource", "string"),
        ("texture", "sensor_msgs/CompressedImage"),
        (
            "uv_coordinates",
            "sequence<visualization_msgs/UVCoordinate>"
        ),
        ("text", "string"),
        ("mesh_resource", "string"),
        ("mesh_file", "visualization_msgs/MeshFile"),
        ("mesh_use_embedded_materials", "boolean"),
    ]
);

impl Marker {
    /// `type`: an arrow.
    pub const ARROW: i32 = 0;
    /// `type`: a box.
    pub const CUBE: i32 = 1;
    /// `type`: a sphere.
    pub const SPHERE: i32 = 2;
    /// `type`: a cylinder.
    pub const CYLINDER: i32 = 3;
    /// `type`: a polyline through `points`.
    pub const LINE_STRIP: i32 = 4;
    /// `type`: a segment per pair of `points`.
    pub const LINE_LIST: i32 = 5;
    /// `type`: a box per point.
    pub const CUBE_LIST: i32 = 6;
    /// `type`: a sphere per point.
    pub const SPHERE_LIST: i32 = 7;
    /// `type`: a square per point.
    pub const POINTS: i32 = 8;
    /// `type`: text facing the viewer.
    pub const TEXT_VIEW_FACING: i32 = 9;
    /// `type`: a mesh.
    pub const MESH_RESOURCE: i32 = 10;
    /// `type`: a triangle per three `points`.
    pub const TRIANGLE_LIST: i32 = 11;
    /// `type`: arrows along `points`.
    pub const ARROW_STRIP: i32 = 12;
    /// `action`: add or replace.
    pub const ADD: i32 = 0;
    /// `action`: remove this marker.
    pub const DELETE: i32 = 2;
    /// `action`: remove every marker (of the namespace, if given).
    pub const DELETEALL: i32 = 3;
}

impl ColorRGBA {
    /// An opaque or translucent colour.
    pub const fn rgba(r: f32, g: f32, b: f32, a: f32) -> Self {
        Self { r, g, b, a }
    }
}

impl Marker {
    fn base(header: &Header, ns: &str, id: i32, kind: i32, color: ColorRGBA) -> Self {
        Self {
            header: header.clone(),
            ns: ns.to_owned(),
            id,
            r#type: kind,
            action: Self::ADD,
            color,
            ..Self::default()
        }
    }

    /// A closed line through floor points (x, y) at height `z_m`, `width_m` wide.
    pub fn closed_line(
        header: &Header,
        ns: &str,
        id: i32,
        points_xy: &[[f64; 2]],
        z_m: f64,
        width_m: f64,
        color: ColorRGBA,
    ) -> Self {
        let mut m = Self::base(header, ns, id, Self::LINE_STRIP, color);
        m.points = points_xy
            .iter()
            .chain(points_xy.first())
            .map(|p| Point {
                x: p[0],
                y: p[1],
                z: z_m,
            })
            .collect();
        m.scale.x = width_m;
        m
    }

    /// A sphere of `diameter_m` at `at`.
    pub fn sphere(
        header: &Header,
        ns: &str,
        id: i32,
        at: Point,
        diameter_m: f64,
        color: ColorRGBA,
    ) -> Self {
        let mut m = Self::base(header, ns, id, Self::SPHERE, color);
        m.pose.position = at;
        m.scale = Vector3 {
            x: diameter_m,
            y: diameter_m,
            z: diameter_m,
        };
        m
    }

    /// A flat disc (1 mm thick) of `diameter_m`, level, centred at `at`.
    pub fn disc(
        header: &Header,
        ns: &str,
        id: i32,
        at: Point,
        diameter_m: f64,
        color: ColorRGBA,
    ) -> Self {
        let mut m = Self::sphere(header, ns, id, at, diameter_m, color);
        m.r#type = Self::CYLINDER;
        m.scale.z = 0.001;
        m
    }

    /// Text facing the viewer at `at`, `height_m` tall.
    pub fn text(
        header: &Header,
        ns: &str,
        id: i32,
        at: Point,
        text: String,
        height_m: f64,
        color: ColorRGBA,
    ) -> Self {
        let mut m = Self::base(header, ns, id, Self::TEXT_VIEW_FACING, color);
        m.pose.position = at;
        m.scale.z = height_m;
        m.text = text;
        m
    }

    /// Removes the marker `ns`/`id` from the viewer.
    pub fn delete(header: &Header, ns: &str, id: i32) -> Self {
        Self {
            action: Self::DELETE,
            ..Self::base(header, ns, id, Self::ARROW, ColorRGBA::default())
        }
    }
}

/// visualization_msgs/msg/MarkerArray.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct MarkerArray {
    /// The markers.
    pub markers: Vec<Marker>,
}
ros_message!(
    MarkerArray,
    "visualization_msgs",
    [("markers", "sequence<visualization_msgs/Marker>")]
);

/// lifecycle_msgs/msg/State: a managed node's primary state (ids 1 unconfigured,
/// 2 inactive, 3 active, 4 finalized).
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct LifecycleState {
    /// The state's id.
    pub id: u8,
    /// Its label (`unconfigured`, `inactive`, `active`, `finalized`).
    pub label: String,
}
impl ros2_client::Message for LifecycleState {}
impl RosMessage for LifecycleState {
    const PACKAGE: &'static str = "lifecycle_msgs";
    const NAME: &'static str = "State";
    const FIELDS: &'static [(&'static str, &'static str)] = &[("id", "uint8"), ("label", "string")];
    const TYPE_NAME: &'static str = "lifecycle_msgs/msg/State";
}

/// lifecycle_msgs/msg/Transition: a managed node's transition (ids 1 configure, 2 cleanup,
/// 3 activate, 4 deactivate, 5-7 shutdown from unconfigured, inactive, active).
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Transition {
    /// The transition's id (0: named by its label).
    pub id: u8,
    /// Its label (`configure`, `cleanup`, `activate`, `deactivate`, `shutdown`).
    pub label: String,
}
ros_message!(
    Transition,
    "lifecycle_msgs",
    [("id", "uint8"), ("label", "string")]
);

/// lifecycle_msgs/msg/TransitionDescription: a transition available from a state.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct TransitionDescription {
    /// The transition.
    pub transition: Transition,
    /// Where it starts.
    pub start_state: LifecycleState,
    /// Where it ends.
    pub goal_state: LifecycleState,
}
ros_message!(
    TransitionDescription,
    "lifecycle_msgs",
    [
        ("transition", "lifecycle_msgs/Transition"),
        ("start_state", "lifecycle_msgs/State"),
        ("goal_state", "lifecycle_msgs/State"),
    ]
);

/// lifecycle_msgs/msg/TransitionEvent (topic `<node>/transition_event`).
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct TransitionEvent {
    /// When (ns).
    pub timestamp: u64,
    /// The transition taken.
    pub transition: Transition,
    /// The state before.
    pub start_state: LifecycleState,
    /// The state after.
    pub goal_state: LifecycleState,
}
ros_message!(
    TransitionEvent,
    "lifecycle_msgs",
    [
        ("timestamp", "uint64"),
        ("transition", "lifecycle_msgs/Transition"),
        ("start_state", "lifecycle_msgs/State"),
        ("goal_state", "lifecycle_msgs/State"),
    ]
);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pose_goes_to_the_wire_and_back() {
        // 1, 2, 3 m, turned 90 deg about z: the quaternion (0, 0, sin 45, cos 45).
        let p = nalgebra::Isometry3::from_parts(
            nalgebra::Translation3::new(1.0, 2.0, 3.0),
            nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.0, std::f64::consts::FRAC_PI_2),
        );
        let wire = Pose::from(&p);
        let h = std::f64::consts::FRAC_1_SQRT_2;
        assert_eq!(
            (wire.position.x, wire.position.y, wire.position.z),
            (1.0, 2.0, 3.0)
        );
        let q = &wire.orientation;
        assert!(q.x.abs() < 1e-15 && q.y.abs() < 1e-15);
        assert!((q.z - h).abs() < 1e-15 && (q.w - h).abs() < 1e-15);
        let back = nalgebra::Isometry3::from(&wire);
        assert!((back.translation.vector - p.translation.vector).norm() < 1e-15);
        assert!(back.rotation.angle_to(&p.rotation) < 1e-12);
    }
}
