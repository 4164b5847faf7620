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
    /// Not in [`known_types`] nor added to the [`TypeLibrary`] asked.
    #[error(
        "message type '{0}' is not described: not in our own table ({known}) and not read \
         from a .msg definition",
        known = known_type_names().join(", ")
    )]
    Unknown(String),
    /// A `ros2msg` definition that names a dependency we cannot read.
    #[error(
        "the definition of '{type_name}' has a section `MSG:{section}`, which names no message type"
    )]
    BadDefinition {
        /// The type being defined.
        type_name: String,
        /// What the section header says.
        section: String,
    },
    /// Not in our table, and no `.msg` file for it under the ament prefixes.
    #[error(
        "message type '{type_name}' is not one we know, and no ament prefix has its .msg file \
         (share/<pkg>/msg/<Name>.msg under {prefixes:?}; set AMENT_PREFIX_PATH, e.g. source a ROS 2 setup)"
    )]
    NotFound {
        /// The type.
        type_name: String,
        /// Where we looked.
        prefixes: Vec<String>,
    },
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
            Imu,
            Clock,
            StringMsg,
            BoolMsg,
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
            LifecycleState,
            Transition,
            TransitionDescription,
            TransitionEvent,
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

/// Message types beyond our own table ([`known_types`]), read from `.msg` definitions: the
/// `ros2msg` text a bag stores with each type, or the `.msg` files of ROS packages installed
/// under an ament prefix (`<prefix>/share/<pkg>/msg/<Name>.msg`, where rosbag2 finds them).
/// Our own table comes first: a type in it is never read again.
#[derive(Debug, Clone, Default)]
pub struct TypeLibrary {
    /// `pkg/msg/Name` -> its fields (name, rosidl type), in order.
    extra: BTreeMap<String, Vec<(String, String)>>,
}

/// The folders of `AMENT_PREFIX_PATH` (colon-separated), where ROS packages are installed.
pub fn ament_prefixes() -> Vec<std::path::PathBuf> {
    std::env::var_os("AMENT_PREFIX_PATH")
        .map(|v| {
            std::env::split_paths(&v)
                .filter(|p| !p.as_os_str().is_empty())
                .collect()
        })
        .unwrap_or_default()
}

/// `pkg/msg/Name` of a `pkg/Name` or `pkg/msg/Name`.
fn full_type_name(name: &str) -> Option<String> {
    let (pkg, rest) = name.trim().split_once('/')?;
    let rest = rest.strip_prefix("msg/").unwrap_or(rest);
    // Packages are lower case, message names PascalCase (so `float65` is no message name).
    let package = pkg.chars().next().is_some_and(|c| c.is_ascii_lowercase())
        && pkg
            .chars()
            .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_');
    let message = rest.chars().next().is_some_and(|c| c.is_ascii_uppercase())
        && rest.chars().all(|c| c.is_ascii_alphanumeric());
    (package && message).then(|| format!("{pkg}/msg/{rest}"))
}

/// A `.msg` field type (`float64[<=3]`, `string<=10`, `Point`, `geometry_msgs/Point[]`) in
/// rosidl's spelling, as [`RosMessage::FIELDS`] writes it (`sequence<double, 3>`,
/// `string<10>`, `pkg/Point`, `sequence<geometry_msgs/Point>`). `None` if unreadable.
fn msg_type_to_rosidl(package: &str, ty: &str) -> Option<String> {
    let (element, array) = match ty.find('[') {
        Some(i) => (&ty[..i], Some(ty[i + 1..].strip_suffix(']')?)),
        None => (ty, None),
    };
    let element = if let Some((base, n)) = element.split_once("<=") {
        let n: u64 = n.parse().ok()?;
        match base {
            "string" | "wstring" => format!("{base}<{n}>"),
            _ => return None,
        }
    } else {
        match element {
            "bool" => "boolean".into(),
            "byte" => "octet".into(),
            "char" => "uint8".into(),
            "float32" => "float".into(),
            "float64" => "double".into(),
            "int8" | "uint8" | "int16" | "uint16" | "int32" | "uint32" | "int64" | "uint64"
            | "string" | "wstring" => element.into(),
            nested => {
                let full = if nested.contains('/') {
                    full_type_name(nested)?
                } else {
                    full_type_name(&format!("{package}/{nested}"))?
                };
                full.replacen("/msg/", "/", 1)
            }
        }
    };
    Some(match array {
        None => element,
        Some("") => format!("sequence<{element}>"),
        Some(n) => match n.strip_prefix("<=") {
            Some(bound) => format!("sequence<{element}, {}>", bound.parse::<u64>().ok()?),
            None => format!("{element}[{}]", n.parse::<u64>().ok()?),
        },
    })
}

/// The fields of one `.msg` text of type `type_name` (`pkg/msg/Name`), in rosidl's
/// spelling: comments, blank lines and constants (`TYPE NAME=value`) skipped, default values
/// (a third word) ignored, as they are by the type description; a message without fields
/// gets rosidl's `uint8 structure_needs_at_least_one_member`.
pub fn parse_msg(type_name: &str, text: &str) -> Result<Vec<(String, String)>, TypeError> {
    let package = type_name.split('/').next().unwrap_or_default();
    let bad = |field: &str, field_type: &str| TypeError::BadField {
        type_name: type_name.to_string(),
        field: field.to_string(),
        field_type: field_type.to_string(),
    };
    let mut fields = Vec::new();
    for line in text.lines() {
        let code = line.split('#').next().unwrap_or_default();
        let words: Vec<&str> = code.split_whitespace().collect();
        let (ty, name) = match words.as_slice() {
            [] => continue,
            [ty] => return Err(bad("", ty)),
            // A constant: `TYPE NAME=VALUE` or `TYPE NAME = VALUE`.
            [_, name, ..] if name.contains('=') => continue,
            [_, _, next, ..] if next.starts_with('=') => continue,
            [ty, name, ..] => (*ty, *name),
        };
        let valid_name = name.chars().next().is_some_and(|c| c.is_ascii_lowercase())
            && name
                .chars()
                .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_');
        if !valid_name {
            return Err(bad(name, ty));
        }
        let rosidl = msg_type_to_rosidl(package, ty).ok_or_else(|| bad(name, ty))?;
        fields.push((name.to_string(), rosidl));
    }
    if fields.is_empty() {
        // rosidl gives a message without fields (only constants) this one member.
        fields.push(("structure_needs_at_least_one_member".into(), "uint8".into()));
    }
    Ok(fields)
}

impl TypeLibrary {
    /// Our own table only.
    pub fn new() -> Self {
        Self::default()
    }

    /// Whether the type can be described: ours, or added.
    pub fn knows(&self, type_name: &str) -> bool {
        lookup(type_name).is_ok() || self.extra.contains_key(type_name)
    }

    /// Adds the types of a `ros2msg` definition (a bag's: the type's `.msg` text, then for
    /// each dependency a line of `=`, `MSG: pkg/Name` and its text) that are not known yet.
    pub fn add_ros2msg(&mut self, type_name: &str, definition: &str) -> Result<(), TypeError> {
        let mut current = type_name.to_string();
        let mut text = String::new();
        let mut lines = definition.lines().peekable();
        let mut sections = Vec::new();
        while let Some(line) = lines.next() {
            let is_separator = line.len() >= 10 && line.chars().all(|c| c == '=');
            if is_separator && let Some(next) = lines.peek().and_then(|l| l.strip_prefix("MSG:")) {
                let name = full_type_name(next).ok_or_else(|| TypeError::BadDefinition {
                    type_name: type_name.to_string(),
                    section: next.to_string(),
                })?;
                lines.next();
                sections.push((
                    std::mem::replace(&mut current, name),
                    std::mem::take(&mut text),
                ));
                continue;
            }
            text.push_str(line);
            text.push('\n');
        }
        sections.push((current, text));
        for (name, text) in sections {
            if !self.knows(&name) {
                let fields = parse_msg(&name, &text)?;
                self.extra.insert(name, fields);
            }
        }
        // Every nested type must be described by now.
        self.dependencies(type_name).map(|_| ())
    }

    /// Adds a type, and the types it uses, from the `.msg` files under the prefixes
    /// (`<prefix>/share/<pkg>/msg/<Name>.msg`, the first prefix that has it).
    pub fn add_from_prefixes(
        &mut self,
        type_name: &str,
        prefixes: &[std::path::PathBuf],
    ) -> Result<(), TypeError> {
        let mut stack = vec![type_name.to_string()];
        while let Some(t) = stack.pop() {
            if self.knows(&t) {
                continue;
            }
            let (pkg, name) = t
                .split_once("/msg/")
                .ok_or_else(|| TypeError::Unknown(t.clone()))?;
            let text = prefixes
                .iter()
                .find_map(|p| {
                    std::fs::read_to_string(
                        p.join("share")
                            .join(pkg)
                            .join("msg")
                            .join(format!("{name}.msg")),
                    )
                    .ok()
                })
                .ok_or_else(|| TypeError::NotFound {
                    type_name: t.clone(),
                    prefixes: prefixes.iter().map(|p| p.display().to_string()).collect(),
                })?;
            let fields = parse_msg(&t, &text)?;
            for (_, ty) in &fields {
                if let Some(f) = parse_field_type(ty).filter(|f| !f.nested.is_empty()) {
                    stack.push(f.nested);
                }
            }
            self.extra.insert(t, fields);
        }
        Ok(())
    }

    /// A type's fields, parsed: ours first, then the added ones.
    fn fields_of(&self, type_name: &str) -> Result<Vec<(String, FieldType)>, TypeError> {
        let owned: Vec<(String, String)> = match lookup(type_name) {
            Ok(known) => known
                .fields
                .iter()
                .map(|(n, t)| ((*n).to_string(), (*t).to_string()))
                .collect(),
            Err(e) => self.extra.get(type_name).cloned().ok_or(e)?,
        };
        owned
            .into_iter()
            .map(|(name, ty)| match parse_field_type(&ty) {
                Some(t) => Ok((name, t)),
                None => Err(TypeError::BadField {
                    type_name: type_name.to_string(),
                    field: name,
                    field_type: ty,
                }),
            })
            .collect()
    }

    /// The nested types a type reaches, transitively, by name (itself excluded), sorted.
    pub fn dependencies(&self, type_name: &str) -> Result<Vec<String>, TypeError> {
        let mut seen = BTreeMap::new();
        let mut stack = vec![type_name.to_string()];
        while let Some(t) = stack.pop() {
            for (_, f) in self.fields_of(&t)? {
                if !f.nested.is_empty() && f.nested != type_name && !seen.contains_key(&f.nested) {
                    seen.insert(f.nested.clone(), ());
                    stack.push(f.nested.clone());
                }
            }
        }
        Ok(seen.into_keys().collect())
    }

    fn description_json(&self, type_name: &str, out: &mut String) -> Result<(), TypeError> {
        let fields = self.fields_of(type_name)?;
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
    pub fn hashable_json(&self, type_name: &str) -> Result<String, TypeError> {
        let mut out = String::from("{\"type_description\": ");
        self.description_json(type_name, &mut out)?;
        out.push_str(", \"referenced_type_descriptions\": [");
        for (i, dep) in self.dependencies(type_name)?.iter().enumerate() {
            if i > 0 {
                out.push_str(", ");
            }
            self.description_json(dep, &mut out)?;
        }
        out.push_str("]}");
        Ok(out)
    }

    /// The type's RIHS01 type description hash, `RIHS01_<hex>`.
    pub fn rihs01(&self, type_name: &str) -> Result<String, TypeError> {
        let digest = Sha256::digest(self.hashable_json(type_name)?.as_bytes());
        let mut s = String::from("RIHS01_");
        for b in digest {
            let _ = write!(s, "{b:02x}");
        }
        Ok(s)
    }

    fn msg_fields(&self, type_name: &str, out: &mut String) -> Result<(), TypeError> {
        for (name, f) in self.fields_of(type_name)? {
            let _ = writeln!(out, "{} {}", f.msg_syntax(), name);
        }
        Ok(())
    }

    /// The `ros2msg` definition text of a type with its dependencies (see the module doc).
    pub fn ros2msg_definition(&self, type_name: &str) -> Result<String, TypeError> {
        let mut out = String::new();
        self.msg_fields(type_name, &mut out)?;
        for dep in self.dependencies(type_name)? {
            out.push_str(&"=".repeat(80));
            let _ = writeln!(out, "\nMSG: {}", dep.replacen("/msg/", "/", 1));
            self.msg_fields(&dep, &mut out)?;
        }
        Ok(out)
    }
}

/// The nested types a type of our table reaches ([`TypeLibrary::dependencies`]).
pub fn dependencies(type_name: &str) -> Result<Vec<String>, TypeError> {
    TypeLibrary::new().dependencies(type_name)
}

/// [`TypeLibrary::hashable_json`] of a type of our table.
pub fn hashable_json(type_name: &str) -> Result<String, TypeError> {
    TypeLibrary::new().hashable_json(type_name)
}

/// [`TypeLibrary::rihs01`] of a type of our table.
pub fn rihs01(type_name: &str) -> Result<String, TypeError> {
    TypeLibrary::new().rihs01(type_name)
}

/// [`TypeLibrary::ros2msg_definition`] of a type of our table.
pub fn ros2msg_definition(type_name: &str) -> Result<String, TypeError> {
    TypeLibrary::new().ros2msg_definition(type_name)
}

fn json_str(s: &str) -> String {
    // Type and field names are ASCII identifiers; serde_json's escaping equals Python's
    // ensure_ascii=True for them.
    serde_json::to_string(s).unwrap_or_default()
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
    fn a_msg_text_reads_as_rosidl_spells_it() {
        let text = "# A comment line\n\
            int32 MAX=5\n\
            string NAME = \"x#y\"\n\
            std_msgs/Header header  # trailing comment\n\
            \n\
            float64[<=3] small\n\
            string<=10 label \"a\"\n\
            Point[] pts\n\
            char c\n\
            byte b\n\
            bool flag true\n\
            uint8[4] raw\n\
            wstring<=2[] words\n";
        let got = parse_msg("my_pkg/msg/Thing", text).unwrap();
        let want = [
            ("header", "std_msgs/Header"),
            ("small", "sequence<double, 3>"),
            ("label", "string<10>"),
            ("pts", "sequence<my_pkg/Point>"),
            ("c", "uint8"),
            ("b", "octet"),
            ("flag", "boolean"),
            ("raw", "uint8[4]"),
            ("words", "sequence<wstring<2>>"),
        ];
        assert_eq!(
            got,
            want.map(|(a, b)| (a.to_string(), b.to_string())).to_vec()
        );
    }

    #[test]
    fn a_bad_msg_line_names_the_field_and_type() {
        let e = parse_msg("p/msg/T", "float65 x\n").unwrap_err();
        assert!(
            e.to_string().contains("'x'") && e.to_string().contains("float65"),
            "{e}"
        );
        let e = parse_msg("p/msg/T", "int32 Bad\n").unwrap_err();
        assert!(e.to_string().contains("Bad"), "{e}");
        assert!(parse_msg("p/msg/T", "int32\n").is_err());
    }

    #[test]
    fn a_bags_definition_describes_a_type_we_do_not_have() {
        let sep = "=".repeat(80);
        let def = format!(
            "# outer\nmy_pkg/Inner inner\nfloat64 x\n{sep}\nMSG: my_pkg/Inner\nint32 a\nbuiltin_interfaces/Time t\n"
        );
        let mut lib = TypeLibrary::new();
        assert!(!lib.knows("my_pkg/msg/Outer"));
        lib.add_ros2msg("my_pkg/msg/Outer", &def).unwrap();
        assert!(lib.knows("my_pkg/msg/Outer") && lib.knows("my_pkg/msg/Inner"));
        assert_eq!(
            lib.dependencies("my_pkg/msg/Outer").unwrap(),
            ["builtin_interfaces/msg/Time", "my_pkg/msg/Inner"]
        );
        // Written back: the same types, comments gone, dependencies sorted.
        assert_eq!(
            lib.ros2msg_definition("my_pkg/msg/Outer").unwrap(),
            format!(
                "my_pkg/Inner inner\nfloat64 x\n{sep}\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n\
                 {sep}\nMSG: my_pkg/Inner\nint32 a\nbuiltin_interfaces/Time t\n"
            )
        );
        // A definition missing a nested type is refused, naming it.
        let e = TypeLibrary::new()
            .add_ros2msg("my_pkg/msg/Outer", "my_pkg/Gone g\n")
            .unwrap_err();
        assert!(e.to_string().contains("my_pkg/msg/Gone"), "{e}");
    }

    #[test]
    fn an_unknown_type_is_named_in_the_error() {
        let e = rihs01("sensor_msgs/msg/LaserScan").unwrap_err();
        assert!(e.to_string().contains("'sensor_msgs/msg/LaserScan'"), "{e}");
        assert!(e.to_string().contains("sensor_msgs/msg/JointState"), "{e}");
    }
}
