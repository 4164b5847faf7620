//! What rosbag2 stores about a message type, computed from our own type table (no ROS
//! install): the type description hash (RIHS01, REP 2016) and the `ros2msg` definition text
//! with its dependencies.
//!
//! # RIHS01
//! The hash of a type is SHA-256 over a JSON text of its `type_description_interfaces`
//! description: `{"type_description": T, "referenced_type_descriptions": [R...]}` where each
//! description is `{"type_name": "pkg/msg/Name", "fields": [{"name": .., "type": {"type_id":
//! .., "capacity": .., "string_capacity": .., "nested_type_name": ..}}]}`, the referenced
//! types are every nested type reached, transitively, sorted by name, and the JSON is
//! written with `", "` and `": "` separators, keys in that order, no default values (Python's
//! `json.dumps` as `rosidl_generator_type_description` calls it). The result is printed
//! `RIHS01_<64 hex digits>`. Constants are not part of the description.
//!
//! `type_id` is the field's `FieldType`: a base id for the element type plus 48 for a
//! fixed array, 96 for a bounded sequence, 144 for an unbounded sequence:
//!
//! | element | id | element | id |
//! |---|---|---|---|
//! | nested message | 1 | float32 (`float`) | 10 |
//! | int8 / uint8 | 2 / 3 | float64 (`double`) | 11 |
//! | int16 / uint16 | 4 / 5 | char | 13 |
//! | int32 / uint32 | 6 / 7 | bool (`boolean`) | 15 |
//! | int64 / uint64 | 8 / 9 | byte (`octet`) | 16 |
//! | string / bounded `string<N>` | 17 / 21 | wstring / `wstring<N>` | 18 / 22 |
//!
//! The tests check every hash against the ones rosidl installed with the ROS wheels and
//! against the `rosbags` library's own computation.
//!
//! # ros2msg definition
//! The type's fields in `.msg` syntax, then for each dependency a line of 80 `=`, a line
//! `MSG: pkg/Name` and its fields: the text Jazzy's recorder stores as an MCAP schema.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use sha2::{Digest, Sha256};

use crate::RosMessage;
use crate::msg::*;

/// A type this crate cannot describe.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TypeError {
    /// Not in [`known_types`].
    #[error(
        "message type '{0}' is not one we know (we know: {known}); \
         only these can be recorded or replayed",
        known = known_type_names().join(", ")
    )]
    Unknown(String),
    /// A field type string we cannot parse.
    #[error(
        "message type '{type_name}': field '{field}' has a type we cannot read: '{field_type}'"
    )]
    BadField {
        /// The message type.
        type_name: String,
        /// The field.
        field: String,
        /// Its type as written.
        field_type: String,
    },
}

/// A message type's fields, as [`RosMessage`] lists them: (name, rosidl type).
#[derive(Debug, Clone, Copy)]
pub struct KnownType {
    /// `pkg/msg/Name`.
    pub type_name: &'static str,
    /// Fields in order.
    pub fields: &'static [(&'static str, &'static str)],
}

macro_rules! known {
    ($($ty:ty),* $(,)?) => {
        [$(KnownType { type_name: <$ty as RosMessage>::TYPE_NAME, fields: <$ty as RosMessage>::FIELDS }),*]
    };
}

/// `rcl_interfaces/msg/Log` (the `/rosout` type): described here so `/rosout` can be
/// recorded and replayed, though no node of ours decodes it.
const LOG_FIELDS: &[(&str, &str)] = &[
    ("stamp", "builtin_interfaces/Time"),
    ("level", "uint8"),
    ("name", "string"),
    ("msg", "string"),
    ("file", "string"),
    ("function", "string"),
    ("line", "uint32"),
];

/// Every message type we can describe: ours and the standard ones the fleet speaks.
pub fn known_types() -> &'static [KnownType] {
    static TABLE: std::sync::OnceLock<Vec<KnownType>> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        let mut v: Vec<KnownType> = known![
            Time,
            Header,
            Vector3,
            Point,
            Quaternion,
            Pose,
            PoseStamped,
            PointStamped,
            Point32,
            Polygon,
            PolygonStamped,
            Twist,
            PoseWithCovariance,
            TwistWithCovariance,
            Odometry,
            JointState,
            Clock,
            StringMsg,
            GaitPhase,
            AnkleTargets,
            WalkCommand,
            KeyValue,
            DiagnosticStatus,
            DiagnosticArray,
            Duration,
            Transform,
            TransformStamped,
            TFMessage,
            ColorRGBA,
            CompressedImage,
            UVCoordinate,
            MeshFile,
            Marker,
            MarkerArray,
        ]
        .to_vec();
        v.push(KnownType {
            type_name: "rcl_interfaces/msg/Log",
            fields: LOG_FIELDS,
        });
        v.sort_by_key(|k| k.type_name);
        v
    })
}

/// The names of [`known_types`].
pub fn known_type_names() -> Vec<&'static str> {
    known_types().iter().map(|k| k.type_name).collect()
}

fn lookup(type_name: &str) -> Result<&'static KnownType, TypeError> {
    known_types()
        .iter()
        .find(|k| k.type_name == type_name)
        .ok_or_else(|| TypeError::Unknown(type_name.to_string()))
}

/// A field's type, parsed from the rosidl spelling (`double`, `sequence<string>`,
/// `std_msgs/Header`, `double[3]`, `sequence<int32, 5>`, `string<10>`).
#[derive(Debug, Clone, PartialEq, Eq)]
struct FieldType {
    /// Base `type_id` of the element (1 for nested).
    element_id: u8,
    /// 0 single, 48 array, 96 bounded sequence, 144 sequence.
    container_offset: u8,
    capacity: u64,
    string_capacity: u64,
    /// `pkg/msg/Name` of a nested element, else empty.
    nested: String,
    /// The element in `.msg` syntax (`float64`, `string<=10`, `std_msgs/Header`).
    msg_element: String,
}

fn primitive(name: &str) -> Option<(u8, &'static str)> {
    Some(match name {
        "boolean" | "bool" => (15, "bool"),
        "octet" | "byte" => (16, "byte"),
        "char" => (13, "char"),
        "float" | "float32" => (10, "float32"),
        "double" | "float64" => (11, "float64"),
        "int8" => (2, "int8"),
        "uint8" => (3, "uint8"),
        "int16" => (4, "int16"),
        "uint16" => (5, "uint16"),
        "int32" => (6, "int32"),
        "uint32" => (7, "uint32"),
        "int64" => (8, "int64"),
        "uint64" => (9, "uint64"),
        "string" => (17, "string"),
        "wstring" => (18, "wstring"),
        _ => return None,
    })
}

fn parse_element(s: &str) -> Option<(u8, u64, String, String)> {
    let s = s.trim();
    if let Some((base, rest)) = s.split_once('<') {
        // string<N> / wstring<N>
        let n: u64 = rest.strip_suffix('>')?.trim().parse().ok()?;
        return match base {
            "string" => Some((21, n, String::new(), format!("string<={n}"))),
            "wstring" => Some((22, n, String::new(), format!("wstring<={n}"))),
            _ => None,
        };
    }
    if let Some((id, msg)) = primitive(s) {
        return Some((id, 0, String::new(), msg.to_string()));
    }
    let (pkg, name) = s.split_once('/')?;
    let valid = |p: &str| !p.is_empty() && p.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
    let name = name.strip_prefix("msg/").unwrap_or(name);
    (valid(pkg) && valid(name))
        .then(|| (1, 0, format!("{pkg}/msg/{name}"), format!("{pkg}/{name}")))
}

fn parse_field_type(s: &str) -> Option<FieldType> {
    let s = s.trim();
    let (inner, offset, capacity) = if let Some(inner) = s
        .strip_prefix("sequence<")
        .and_then(|r| r.strip_suffix('>'))
    {
        // sequence<T> or sequence<T, N>; T itself may be string<N>, so split at the last ','.
        match inner.rsplit_once(',') {
            Some((t, n)) if !t.contains('<') || t.contains('>') => {
                (t.to_string(), 96u8, n.trim().parse::<u64>().ok()?)
            }
            _ => (inner.to_string(), 144u8, 0),
        }
    } else if let Some(open) = s.rfind('[') {
        let n: u64 = s[open + 1..].strip_suffix(']')?.trim().parse().ok()?;
        (s[..open].to_string(), 48u8, n)
    } else {
        (s.to_string(), 0u8, 0)
    };
    let (element_id, string_capacity, nested, msg_element) = parse_element(&inner)?;
    Some(FieldType {
        element_id,
        container_offset: offset,
        capacity,
        string_capacity,
        nested,
        msg_element,
    })
}

impl FieldType {
    fn type_id(&self) -> u8 {
        self.element_id + self.container_offset
    }
    /// The field type in `.msg` syntax.
    fn msg_syntax(&self) -> String {
        match self.container_offset {
            48 => format!("{}[{}]", self.msg_element, self.capacity),
            96 => format!("{}[<={}]", self.msg_element, self.capacity),
            144 => format!("{}[]", self.msg_element),
            _ => self.msg_element.clone(),
        }
    }
}

/// A known type's fields, parsed.
fn fields_of(type_name: &str) -> Result<Vec<(&'static str, FieldType)>, TypeError> {
    let known = lookup(type_name)?;
    known
        .fields
        .iter()
        .map(|(name, ty)| {
            parse_field_type(ty)
                .map(|t| (*name, t))
                .ok_or_else(|| TypeError::BadField {
                    type_name: type_name.to_string(),
                    field: name.to_string(),
                    field_type: ty.to_string(),
                })
        })
        .collect()
}

/// The nested types a type reaches, transitively, by name (itself excluded), sorted.
pub fn dependencies(type_name: &str) -> Result<Vec<String>, TypeError> {
    let mut seen = BTreeMap::new();
    let mut stack = vec![type_name.to_string()];
    while let Some(t) = stack.pop() {
        for (_, f) in fields_of(&t)? {
            if !f.nested.is_empty() && f.nested != type_name && !seen.contains_key(&f.nested) {
                seen.insert(f.nested.clone(), ());
                stack.push(f.nested.clone());
            }
        }
    }
    Ok(seen.into_keys().collect())
}

fn json_str(s: &str) -> String {
    // Type and field names are ASCII identifiers; serde_json's escaping equals Python's
    // ensure_ascii=True for them.
    serde_json::to_string(s).unwrap_or_default()
}

fn description_json(type_name: &str, out: &mut String) -> Result<(), TypeError> {
    let fields = fields_of(type_name)?;
    let _ = write!(
        out,
        "{{\"type_name\": {}, \"fields\": [",
        json_str(type_name)
    );
    for (i, (name, f)) in fields.iter().enumerate() {
        if i > 0 {
            out.push_str(", ");
        }
        let _ = write!(
            out,
            "{{\"name\": {}, \"type\": {{\"type_id\": {}, \"capacity\": {}, \"string_capacity\": {}, \"nested_type_name\": {}}}}}",
            json_str(name),
            f.type_id(),
            f.capacity,
            f.string_capacity,
            json_str(&f.nested)
        );
    }
    out.push_str("]}");
    Ok(())
}

/// The JSON text RIHS01 hashes (see the module doc).
pub fn hashable_json(type_name: &str) -> Result<String, TypeError> {
    let mut out = String::from("{\"type_description\": ");
    description_json(type_name, &mut out)?;
    out.push_str(", \"referenced_type_descriptions\": [");
    for (i, dep) in dependencies(type_name)?.iter().enumerate() {
        if i > 0 {
            out.push_str(", ");
        }
        description_json(dep, &mut out)?;
    }
    out.push_str("]}");
    Ok(out)
}

/// The type's RIHS01 type description hash, `RIHS01_<hex>`.
pub fn rihs01(type_name: &str) -> Result<String, TypeError> {
    let digest = Sha256::digest(hashable_json(type_name)?.as_bytes());
    let mut s = String::from("RIHS01_");
    for b in digest {
        let _ = write!(s, "{b:02x}");
    }
    Ok(s)
}

fn msg_fields(type_name: &str, out: &mut String) -> Result<(), TypeError> {
    for (name, f) in fields_of(type_name)? {
        let _ = writeln!(out, "{} {}", f.msg_syntax(), name);
    }
    Ok(())
}

/// The `ros2msg` definition text of a type with its dependencies (see the module doc).
pub fn ros2msg_definition(type_name: &str) -> Result<String, TypeError> {
    let mut out = String::new();
    msg_fields(type_name, &mut out)?;
    for dep in dependencies(type_name)? {
        out.push_str(&"=".repeat(80));
        let _ = writeln!(out, "\nMSG: {}", dep.replacen("/msg/", "/", 1));
        msg_fields(&dep, &mut out)?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn field_types_parse_to_rosidl_type_ids() {
        let id =
            |s: &str| parse_field_type(s).map(|f| (f.type_id(), f.capacity, f.string_capacity));
        assert_eq!(id("double"), Some((11, 0, 0)));
        assert_eq!(id("sequence<double>"), Some((155, 0, 0)));
        assert_eq!(id("sequence<string>"), Some((161, 0, 0)));
        assert_eq!(id("std_msgs/Header"), Some((1, 0, 0)));
        assert_eq!(id("sequence<diagnostic_msgs/KeyValue>"), Some((145, 0, 0)));
        assert_eq!(id("double[3]"), Some((59, 3, 0)));
        assert_eq!(id("sequence<int32, 5>"), Some((102, 5, 0)));
        assert_eq!(id("string<10>"), Some((21, 0, 10)));
        assert_eq!(id("sequence<string<10>, 4>"), Some((117, 4, 10)));
        assert_eq!(id("vector<double>"), None);
        assert_eq!(id("std_msgs/"), None);
    }

    #[test]
    fn field_types_print_in_msg_syntax() {
        let m = |s: &str| parse_field_type(s).map(|f| f.msg_syntax());
        assert_eq!(m("sequence<double>").as_deref(), Some("float64[]"));
        assert_eq!(m("octet").as_deref(), Some("byte"));
        assert_eq!(m("double[3]").as_deref(), Some("float64[3]"));
        assert_eq!(m("sequence<int32, 5>").as_deref(), Some("int32[<=5]"));
        assert_eq!(m("string<10>").as_deref(), Some("string<=10"));
        assert_eq!(
            m("builtin_interfaces/Time").as_deref(),
            Some("builtin_interfaces/Time")
        );
    }

    #[test]
    fn dependencies_are_transitive_and_sorted() {
        assert_eq!(
            dependencies("sensor_msgs/msg/JointState").unwrap(),
            ["builtin_interfaces/msg/Time", "std_msgs/msg/Header"]
        );
        assert!(dependencies("geometry_msgs/msg/Twist").unwrap() == ["geometry_msgs/msg/Vector3"]);
        assert!(
            dependencies("builtin_interfaces/msg/Time")
                .unwrap()
                .is_empty()
        );
    }

    /// The JSON for builtin_interfaces/msg/Time, written out by hand from REP 2016 and the
    /// FieldType ids (int32 = 6, uint32 = 7).
    #[test]
    fn the_hashed_json_of_time_is_the_rep_2016_text() {
        assert_eq!(
            hashable_json("builtin_interfaces/msg/Time").unwrap(),
            "{\"type_description\": {\"type_name\": \"builtin_interfaces/msg/Time\", \"fields\": [\
             {\"name\": \"sec\", \"type\": {\"type_id\": 6, \"capacity\": 0, \"string_capacity\": 0, \"nested_type_name\": \"\"}}, \
             {\"name\": \"nanosec\", \"type\": {\"type_id\": 7, \"capacity\": 0, \"string_capacity\": 0, \"nested_type_name\": \"\"}}]}, \
             \"referenced_type_descriptions\": []}"
        );
    }

    #[test]
    fn the_joint_state_definition_lists_its_dependencies() {
        let text = ros2msg_definition("sensor_msgs/msg/JointState").unwrap();
        let sep = "=".repeat(80);
        assert_eq!(
            text,
            format!(
                "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n\
                 {sep}\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n\
                 {sep}\nMSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
            )
        );
    }

    #[test]
    fn an_unknown_type_is_named_in_the_error() {
        let e = rihs01("sensor_msgs/msg/Imu").unwrap_err();
        assert!(e.to_string().contains("'sensor_msgs/msg/Imu'"), "{e}");
        assert!(e.to_string().contains("sensor_msgs/msg/JointState"), "{e}");
    }
}
