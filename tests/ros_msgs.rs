//! biped_msgs' Rust message types against real ROS 2, without DDS: the field lists against
//! the classes rosidl generates (for biped_msgs from msgs/msg/*.msg, built into the venv by
//! scripts/setup-python-env), and the CDR bytes, both ways, against rclpy's serializer
//! (rmw_fastrtps_cpp, Fast-CDR). The reference side is tests/python/msg_check.py.
//!
//! One set of sample values, tests/data/cdr_samples.json, feeds both sides. The Rust side
//! encodes exactly as ros2-client puts a message on the wire: RustDDS's
//! `CDRSerializerAdapter` (the `cdr-encoding` crate, little endian) behind the 4-byte
//! encapsulation header `00 01 00 00` of a `SerializedPayload`, and decodes as a
//! ros2-client subscription does (`CDRDeserializerAdapter`).
//!
//! Where rclpy's bytes may differ from ours, and why (nowhere else):
//! - alignment padding: Fast-CDR skips padding bytes without writing them, so they hold
//!   whatever was in rclpy's buffer; RustDDS writes zeros. The padding offsets come from
//!   msg_check.py, which lays the message out from the rosidl types (XCDR1 rules);
//! - trailing bytes: rclpy's `serialize_message` returns as many bytes as rmw_fastrtps_cpp
//!   estimated, not as many as Fast-CDR wrote, and the rest is never written. For a
//!   fixed-size type (no string or sequence anywhere) the estimate is the size rounded up
//!   to a multiple of 4 (a type ending in a `bool`: 29 -> 32 bytes); otherwise it counts alignment for
//!   the elements of every sequence of primitives even when the sequence is empty
//!   (JointState with empty `velocity` or `effort`: up to 4 more bytes for each).
//!   msg_check.py works that length out ("rmw_size") and the test holds rclpy to it; ours
//!   stops at the last field, as RustDDS sends it (RTPS pads outside the payload).
//!
//! The venv is required: without it the Python-backed tests fail and say how to make it.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::path::Path;

use biped_msgs::RosMessage;
use biped_msgs::msg::{
    AnkleTargets, BoolMsg, Clock, ColorRGBA, CompressedImage, DiagnosticArray, DiagnosticStatus,
    Duration, GaitPhase, Header, Imu, JointState, KeyValue, LifecycleState, Marker, MarkerArray,
    MeshFile, Odometry, Point, Point32, PointStamped, Polygon, PolygonStamped, Pose, PoseStamped,
    PoseWithCovariance, Quaternion, StringMsg, TFMessage, Time, Transform, TransformStamped,
    Transition, TransitionDescription, TransitionEvent, Twist, TwistWithCovariance, UVCoordinate,
    Vector3, WalkCommand,
};
use ros2_client::dds::rustdds;
use rustdds::no_key::{DeserializerAdapter, SerializerAdapter};
use rustdds::{CDRDeserializerAdapter, CDRSerializerAdapter, SerializedPayload};
use serde_json::{Value as Json, json};
use serde_norway::{Mapping as YamlMapping, Number as YamlNumber, Value as Yaml};

const WORKSPACE: &str = env!("CARGO_MANIFEST_DIR");
const SAMPLES: &str = "tests/data/cdr_samples.json";
const MSG_RS: &str = include_str!("../msgs/src/msg.rs");
/// The encapsulation header ros2-client / RustDDS and rclpy / Fast DDS put in front of the
/// CDR body: CDR_LE, options 0.
const CDR_LE_HEADER: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

// ---------------------------------------------------------------- the wire, as ros2-client

/// A message as ros2-client publishes it: RustDDS's CDR serializer adapter (the one behind
/// `no_key::DataWriterCdr`, which `ros2_client::Publisher` wraps), then the
/// `SerializedPayload` (encapsulation header + body) of the RTPS DATA submessage.
fn to_wire<T: RosMessage>(value: &T) -> Vec<u8> {
    let body = <CDRSerializerAdapter<T> as SerializerAdapter<T>>::to_bytes(value)
        .unwrap_or_else(|e| panic!("CDR encoding of {value:?} failed: {e}"));
    let encoding = <CDRSerializerAdapter<T> as SerializerAdapter<T>>::output_encoding();
    bytes::Bytes::from(SerializedPayload::new_from_bytes(encoding, body)).to_vec()
}

/// A payload decoded as a ros2-client subscription does (`SerializedPayload::from_bytes`,
/// then `CDRDeserializerAdapter`), with the number of body bytes the decoder consumed.
fn from_wire<T: RosMessage>(wire: &[u8]) -> Result<(T, usize), String> {
    let payload = SerializedPayload::from_bytes(&bytes::Bytes::copy_from_slice(wire))
        .map_err(|e| format!("not a serialized payload: {e}"))?;
    let encoding = payload.representation_identifier;
    let value =
        <CDRDeserializerAdapter<T> as DeserializerAdapter<T>>::from_bytes(&payload.value, encoding)
            .map_err(|e| format!("CDR decoding failed: {e}"))?;
    let (_, consumed) =
        rustdds::serialization::deserialize_from_cdr_with_rep_id::<T>(&payload.value, encoding)
            .map_err(|e| format!("CDR decoding failed: {e}"))?;
    Ok((value, consumed))
}

// ---------------------------------------------------------------- the registry

/// One `RosMessage` type, with what the tests do with it behind plain function pointers.
struct Entry {
    rust_name: &'static str,
    package: &'static str,
    name: &'static str,
    fields: &'static [(&'static str, &'static str)],
    /// Field names in the order serde (and so the CDR encoder) walks the struct.
    serde_fields: fn() -> Vec<String>,
    /// A thawed sample value -> the Rust value -> our wire bytes.
    encode: fn(Yaml) -> Result<Vec<u8>, String>,
    /// Wire bytes -> the Rust value, as what it re-encodes to.
    decode: fn(&[u8]) -> Result<Decoded, String>,
}

/// A value decoded from wire bytes.
struct Decoded {
    /// Our wire bytes for the value: bit-exact comparison, -0.0 and NaN included.
    wire: Vec<u8>,
    /// Body bytes (after the encapsulation header) the decoder consumed.
    consumed: usize,
    /// The value, for messages.
    debug: String,
}

impl Entry {
    /// `pkg/msg/Name`.
    fn type_name(&self) -> String {
        format!("{}/msg/{}", self.package, self.name)
    }
    /// `pkg/Name`, as nested types appear in rosidl's field types.
    fn field_type_name(&self) -> String {
        format!("{}/{}", self.package, self.name)
    }
}

fn entry<T: RosMessage>(rust_name: &'static str) -> Entry {
    Entry {
        rust_name,
        package: T::PACKAGE,
        name: T::NAME,
        fields: T::FIELDS,
        serde_fields: || match serde_norway::to_value(T::default()) {
            Ok(Yaml::Mapping(m)) => m
                .keys()
                .map(|k| k.as_str().unwrap_or("<non-string key>").to_owned())
                .collect(),
            other => panic!("{} does not serialize as a struct: {other:?}", T::NAME),
        },
        encode: |value| {
            let v: T = serde_norway::from_value(value).map_err(|e| e.to_string())?;
            Ok(to_wire(&v))
        },
        decode: |wire| {
            let (v, consumed) = from_wire::<T>(wire)?;
            Ok(Decoded {
                wire: to_wire(&v),
                consumed,
                debug: format!("{v:?}"),
            })
        },
    }
}

macro_rules! registry {
    ($($ty:ident),* $(,)?) => {
        vec![$(entry::<$ty>(stringify!($ty))),*]
    };
}

/// Every `RosMessage` type of biped_msgs (checked against msg.rs by
/// `every_ros_message_is_registered_sampled_and_round_trips`).
fn registry() -> Vec<Entry> {
    registry!(
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
        BoolMsg,
        LifecycleState,
        Transition,
        TransitionDescription,
        TransitionEvent,
    )
}

fn find<'a>(registry: &'a [Entry], field_type_name: &str) -> Option<&'a Entry> {
    registry
        .iter()
        .find(|e| e.field_type_name() == field_type_name)
}

/// The element type of `sequence<T>`, if it is one.
fn sequence_of(ty: &str) -> Option<&str> {
    ty.strip_prefix("sequence<")?.strip_suffix('>')
}

/// The element type and length of a fixed array `T[N]`, if it is one.
fn fixed_array_of(ty: &str) -> Option<(&str, usize)> {
    let (element, rest) = ty.split_once('[')?;
    Some((element, rest.strip_suffix(']')?.parse().ok()?))
}

/// The `RosMessage` types msg.rs defines: every `ros_message!(Type, ...)` and every
/// `impl RosMessage for Type`.
fn types_in_msg_rs() -> BTreeSet<String> {
    let mut names = BTreeSet::new();
    for marker in ["ros_message!(", "impl RosMessage for "] {
        for (at, _) in MSG_RS.match_indices(marker) {
            let ident: String = MSG_RS[at + marker.len()..]
                .trim_start()
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_' || *c == '$')
                .collect();
            if !ident.starts_with('$') {
                names.insert(ident);
            }
        }
    }
    names
}

// ---------------------------------------------------------------- sample values

/// The samples file: `pkg/msg/Name` -> sample values; keys starting with `_` are comments.
/// (serde_json is built with `float_roundtrip`: its default float parser can land 1 ulp
/// off, e.g. 0.9238795325112867 -> ...68, where Python's is exact.)
fn samples() -> BTreeMap<String, Vec<Json>> {
    let path = Path::new(WORKSPACE).join(SAMPLES);
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    let all: BTreeMap<String, Json> = serde_json::from_str(&text)
        .unwrap_or_else(|e| panic!("{} is not a JSON object: {e}", path.display()));
    all.into_iter()
        .filter(|(k, _)| !k.starts_with('_'))
        .map(|(k, v)| match v {
            Json::Array(values) => (k, values),
            other => panic!("{SAMPLES}: {k}: expected a list of samples, got {other}"),
        })
        .collect()
}

/// A JSON sample value -> a serde value the Rust type deserializes from, led by the rosidl
/// field types: every field required, no unknown ones; the strings "NaN", "Infinity",
/// "-Infinity" in float fields become those floats (JSON has no numbers for them).
fn thaw(registry: &[Entry], value: &Json, ty: &str, at: &str) -> Result<Yaml, String> {
    let wrong = || Err(format!("{at}: {value} is not a {ty}"));
    match ty {
        "double" | "float" => match value {
            Json::Number(n) => n
                .as_f64()
                .map(|f| Yaml::Number(YamlNumber::from(f)))
                .ok_or_else(|| format!("{at}: {n} is not a float")),
            Json::String(s) => match s.as_str() {
                "NaN" => Ok(Yaml::Number(YamlNumber::from(f64::NAN))),
                "Infinity" => Ok(Yaml::Number(YamlNumber::from(f64::INFINITY))),
                "-Infinity" => Ok(Yaml::Number(YamlNumber::from(f64::NEG_INFINITY))),
                _ => wrong(),
            },
            _ => wrong(),
        },
        "boolean" => value.as_bool().map(Yaml::Bool).map_or_else(wrong, Ok),
        "string" => value
            .as_str()
            .map(|s| Yaml::String(s.to_owned()))
            .map_or_else(wrong, Ok),
        // `octet` is the `byte` of a .msg file (DiagnosticStatus.level): a u8 in CDR.
        "octet" | "int8" | "int16" | "int32" | "int64" | "uint8" | "uint16" | "uint32"
        | "uint64" => match (value.as_i64(), value.as_u64()) {
            (Some(i), _) => Ok(Yaml::Number(YamlNumber::from(i))),
            (None, Some(u)) => Ok(Yaml::Number(YamlNumber::from(u))),
            _ => wrong(),
        },
        _ => {
            // A sequence (any length) or a fixed array (exactly its length).
            let list = sequence_of(ty)
                .map(|e| (e, None))
                .or_else(|| fixed_array_of(ty).map(|(e, n)| (e, Some(n))));
            if let Some((element, len)) = list {
                let Json::Array(items) = value else {
                    return wrong();
                };
                if let Some(n) = len.filter(|&n| n != items.len()) {
                    return Err(format!(
                        "{at}: {ty} needs {n} values, the sample has {}",
                        items.len()
                    ));
                }
                let items = items
                    .iter()
                    .enumerate()
                    .map(|(i, v)| thaw(registry, v, element, &format!("{at}[{i}]")))
                    .collect::<Result<Vec<_>, _>>()?;
                return Ok(Yaml::Sequence(items));
            }
            let Some(nested) = find(registry, ty) else {
                return Err(format!(
                    "{at}: field type {ty} is not supported by this test"
                ));
            };
            let Json::Object(object) = value else {
                return wrong();
            };
            let names: Vec<&str> = nested.fields.iter().map(|(n, _)| *n).collect();
            let unknown: Vec<&String> = object
                .keys()
                .filter(|k| !names.contains(&k.as_str()))
                .collect();
            let missing: Vec<&&str> = names.iter().filter(|n| !object.contains_key(**n)).collect();
            if !unknown.is_empty() || !missing.is_empty() {
                return Err(format!(
                    "{at}: {ty} has the fields {names:?}; missing {missing:?}, unknown {unknown:?}"
                ));
            }
            let mut out = YamlMapping::new();
            for (name, field_ty) in nested.fields {
                let v = thaw(registry, &object[*name], field_ty, &format!("{at}.{name}"))?;
                out.insert(Yaml::String((*name).to_owned()), v);
            }
            Ok(Yaml::Mapping(out))
        }
    }
}

/// Our wire bytes for sample `at` of `e`.
fn encode_sample(registry: &[Entry], e: &Entry, value: &Json, at: &str) -> Result<Vec<u8>, String> {
    let thawed = thaw(registry, value, &e.field_type_name(), at)?;
    (e.encode)(thawed).map_err(|err| {
        format!(
            "{at}: {value} does not deserialize into {}: {err}",
            e.rust_name
        )
    })
}

// ---------------------------------------------------------------- the reference

/// Runs msg_check.py once on a request and returns its answer.
fn msg_check(request: &Json) -> Json {
    let out = common::run_python("msg_check.py", &[], request.to_string().as_bytes());
    let text = String::from_utf8_lossy(&out);
    serde_json::from_str(&text)
        .unwrap_or_else(|e| panic!("msg_check.py answer does not parse: {e}\n{text}"))
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().fold(String::new(), |mut s, b| {
        let _ = write!(s, "{b:02x}");
        s
    })
}

fn unhex(text: &str) -> Result<Vec<u8>, String> {
    if !text.len().is_multiple_of(2) {
        return Err(format!("odd-length hex {text:?}"));
    }
    (0..text.len())
        .step_by(2)
        .map(|i| {
            u8::from_str_radix(&text[i..i + 2], 16).map_err(|e| format!("bad hex {text:?}: {e}"))
        })
        .collect()
}

/// Both byte strings in rows of 16, with the offsets that differ marked.
fn hex_dump(ours: &[u8], theirs: &[u8], padding: &BTreeSet<usize>) -> String {
    let mut out = String::from("offset  ours / rclpy ('p' = alignment padding, '^' = differs)\n");
    for row in (0..ours.len().max(theirs.len())).step_by(16) {
        let cells = |bytes: &[u8]| {
            (row..row + 16)
                .map(|i| bytes.get(i).map_or("  ".to_owned(), |b| format!("{b:02x}")))
                .collect::<Vec<_>>()
                .join(" ")
        };
        let marks: Vec<&str> = (row..row + 16)
            .map(|i| match (ours.get(i), theirs.get(i)) {
                _ if padding.contains(&i) => " p",
                (Some(a), Some(b)) if a == b => "  ",
                (None, None) => "  ",
                _ => " ^",
            })
            .collect();
        let _ = writeln!(
            out,
            "{row:6}  {}\n        {}\n        {}",
            cells(ours),
            cells(theirs),
            marks.join(" ")
        );
    }
    out
}

// ---------------------------------------------------------------- tests

/// Without Python: the registry holds every `RosMessage` type of msg.rs, each struct's
/// serde field order is its FIELDS order, nested field types are registered types, the
/// samples file has non-trivial samples of exactly those types, and each sample survives
/// ros2-client's encode -> decode unchanged, bit for bit.
#[test]
fn every_ros_message_is_registered_sampled_and_round_trips() {
    let registry = registry();
    let mut errors = Vec::new();

    let registered: BTreeSet<String> = registry.iter().map(|e| e.rust_name.to_owned()).collect();
    let defined = types_in_msg_rs();
    assert_eq!(
        registered, defined,
        "the types registered in tests/ros_msgs.rs differ from the RosMessage types msgs/src/msg.rs defines"
    );
    let type_names: BTreeSet<String> = registry.iter().map(Entry::type_name).collect();
    assert_eq!(
        type_names.len(),
        registry.len(),
        "two Rust types claim the same ROS type"
    );

    for e in &registry {
        let names: Vec<String> = e.fields.iter().map(|(n, _)| (*n).to_owned()).collect();
        let serde_names = (e.serde_fields)();
        if serde_names != names {
            errors.push(format!(
                "{}: struct fields (serde order) {serde_names:?} but FIELDS {names:?}",
                e.rust_name
            ));
        }
        for (field, ty) in e.fields {
            let element = sequence_of(ty).unwrap_or(ty);
            if element.contains('/') && find(&registry, element).is_none() {
                errors.push(format!(
                    "{}.{field}: {ty} is not a registered RosMessage type",
                    e.rust_name
                ));
            }
        }
    }

    let samples = samples();
    let sampled: BTreeSet<String> = samples.keys().cloned().collect();
    assert_eq!(
        sampled, type_names,
        "{SAMPLES} must hold samples of exactly the registered types"
    );

    for e in &registry {
        let values = &samples[&e.type_name()];
        if values.len() < 2 {
            errors.push(format!(
                "{}: at least 2 samples wanted, {SAMPLES} has {}",
                e.type_name(),
                values.len()
            ));
        }
        // Non-trivial samples: strings of odd and even byte length and non-ASCII;
        // sequences of length 0, 1 and 3 or more.
        for (field, ty) in e.fields {
            let get = |v: &Json| v.get(*field).cloned().unwrap_or(Json::Null);
            if *ty == "string" {
                let lens: BTreeSet<usize> = values
                    .iter()
                    .filter_map(|v| get(v).as_str().map(str::len))
                    .collect();
                let non_ascii = values
                    .iter()
                    .any(|v| get(v).as_str().is_some_and(|s| !s.is_ascii()));
                if !lens.iter().any(|l| l % 2 == 1)
                    || !lens.iter().any(|l| l % 2 == 0)
                    || !non_ascii
                {
                    errors.push(format!(
                        "{}.{field}: samples want strings of odd and even byte length and a non-ASCII one (have lengths {lens:?}, non-ASCII: {non_ascii})",
                        e.type_name()
                    ));
                }
            }
            if sequence_of(ty).is_some() {
                let lens: BTreeSet<usize> = values
                    .iter()
                    .filter_map(|v| get(v).as_array().map(Vec::len))
                    .collect();
                if !lens.contains(&0) || !lens.contains(&1) || !lens.iter().any(|l| *l >= 3) {
                    errors.push(format!(
                        "{}.{field}: samples want sequences of length 0, 1 and >= 3 (have {lens:?})",
                        e.type_name()
                    ));
                }
            }
        }
        for (i, value) in values.iter().enumerate() {
            let at = format!("{}[{i}]", e.type_name());
            let ours = match encode_sample(&registry, e, value, &at) {
                Ok(bytes) => bytes,
                Err(err) => {
                    errors.push(err);
                    continue;
                }
            };
            if ours[..4] != CDR_LE_HEADER {
                errors.push(format!(
                    "{at}: encapsulation header {} is not CDR_LE 00010000",
                    hex(&ours[..4])
                ));
            }
            match (e.decode)(&ours) {
                Ok(Decoded {
                    wire: again,
                    consumed,
                    ..
                }) => {
                    if again != ours {
                        errors.push(format!(
                            "{at}: encode -> decode -> encode changed the bytes\n{}",
                            hex_dump(&ours, &again, &BTreeSet::new())
                        ));
                    }
                    if consumed != ours.len() - 4 {
                        errors.push(format!(
                            "{at}: the decoder consumed {consumed} of {} body bytes",
                            ours.len() - 4
                        ));
                    }
                }
                Err(err) => errors.push(format!("{at}: our own bytes do not decode: {err}")),
            }
        }
    }
    assert!(
        errors.is_empty(),
        "{} problem(s):\n{}",
        errors.len(),
        errors.join("\n")
    );
}

/// Package, name and fields (names, order, rosidl type strings) of every Rust type equal
/// rclpy's `get_fields_and_field_types()` of the generated class; for biped_msgs that
/// class comes from msgs/msg/*.msg, so this ties the Rust types to the .msg files.
#[test]
fn field_lists_match_rosidl() {
    let registry = registry();
    let names: Vec<String> = registry.iter().map(Entry::type_name).collect();
    let answer = msg_check(&json!({ "schema": names }));
    let mut errors = Vec::new();
    for e in &registry {
        let type_name = e.type_name();
        let got = &answer["schema"][&type_name];
        let Some(fields) = got["fields"].as_array() else {
            errors.push(format!(
                "{type_name} ({}): rclpy has no such message: {}",
                e.rust_name, got["error"]
            ));
            continue;
        };
        let theirs: Vec<(String, String)> = fields
            .iter()
            .map(|f| {
                (
                    f[0].as_str().unwrap_or("?").to_owned(),
                    f[1].as_str().unwrap_or("?").to_owned(),
                )
            })
            .collect();
        let ours: Vec<(String, String)> = e
            .fields
            .iter()
            .map(|(n, t)| ((*n).to_owned(), (*t).to_owned()))
            .collect();
        if ours != theirs {
            errors.push(format!(
                "{type_name} ({}):\n  Rust FIELDS: {ours:?}\n  rosidl:      {theirs:?}",
                e.rust_name
            ));
        }
    }
    assert!(
        errors.is_empty(),
        "field lists differ from rosidl's:\n{}",
        errors.join("\n")
    );
}

/// For every sample of every type, one rclpy process:
/// - rclpy decodes OUR bytes to the sample value (bit for bit, -0.0 and NaN included);
/// - rclpy's bytes for the sample equal ours except at alignment padding (ours zero) and
///   the trailing bytes of fixed-size types (see the module doc);
/// - the byte length and padding msg_check.py lays out from the rosidl types match ours;
/// - we decode rclpy's bytes to the sample value, consuming exactly the body we write.
#[test]
fn cdr_matches_rclpy_both_ways() {
    let registry = registry();
    let samples = samples();
    let mut errors = Vec::new();

    let mut ours: BTreeMap<String, Vec<Vec<u8>>> = BTreeMap::new();
    for e in &registry {
        let type_name = e.type_name();
        let Some(values) = samples.get(&type_name) else {
            errors.push(format!("{SAMPLES} has no samples of {type_name}"));
            continue;
        };
        let encoded = values
            .iter()
            .enumerate()
            .map(|(i, v)| encode_sample(&registry, e, v, &format!("{type_name}[{i}]")))
            .collect::<Result<Vec<_>, _>>();
        match encoded {
            Ok(bytes) => {
                ours.insert(type_name, bytes);
            }
            Err(err) => errors.push(err),
        }
    }
    assert!(
        errors.is_empty(),
        "samples that do not encode:\n{}",
        errors.join("\n")
    );

    let encoded: BTreeMap<&String, Vec<String>> = ours
        .iter()
        .map(|(k, v)| (k, v.iter().map(|b| hex(b)).collect()))
        .collect();
    let samples_file = Path::new(WORKSPACE).join(SAMPLES);
    let answer = msg_check(&json!({
        "cdr": { "samples_file": samples_file, "encoded": encoded }
    }));

    let mut checked = 0;
    for e in &registry {
        let type_name = e.type_name();
        let results = answer["cdr"][&type_name]
            .as_array()
            .cloned()
            .unwrap_or_default();
        if results.len() != ours[&type_name].len() {
            errors.push(format!(
                "{type_name}: msg_check.py answered {} results for {} samples",
                results.len(),
                ours[&type_name].len()
            ));
            continue;
        }
        for (i, (r, ours)) in results.iter().zip(&ours[&type_name]).enumerate() {
            let at = format!("{type_name}[{i}] ({})", samples[&type_name][i]);
            let before = errors.len();
            for key in ["encode_error", "decode_error"] {
                if let Some(err) = r[key].as_str() {
                    errors.push(format!("{at}: rclpy {key}: {err}"));
                }
            }
            if errors.len() > before {
                continue;
            }

            // rclpy decodes our bytes to the sample value.
            match thaw(&registry, &r["decoded"], &e.field_type_name(), &at)
                .and_then(|v| (e.encode)(v))
            {
                Ok(again) if again == *ours => {}
                Ok(again) => errors.push(format!(
                    "{at}: rclpy decodes our bytes to {}, which is not the sample\n{}",
                    r["decoded"],
                    hex_dump(ours, &again, &BTreeSet::new())
                )),
                Err(err) => errors.push(format!(
                    "{at}: rclpy's decoding of our bytes, {}: {err}",
                    r["decoded"]
                )),
            }

            // rclpy's bytes equal ours, but for padding and a fixed-size type's tail.
            let theirs = match r["cdr"].as_str().map(unhex) {
                Some(Ok(b)) => b,
                other => {
                    errors.push(format!("{at}: no CDR from rclpy: {other:?}"));
                    continue;
                }
            };
            let padding: BTreeSet<usize> = r["padding"]
                .as_array()
                .map(|p| {
                    p.iter()
                        .filter_map(Json::as_u64)
                        .map(|p| p as usize)
                        .collect()
                })
                .unwrap_or_default();
            let size = r["size"].as_u64().map(|s| s as usize);
            if size != Some(ours.len()) {
                errors.push(format!(
                    "{at}: rosidl layout says {size:?} bytes, we encode {}",
                    ours.len()
                ));
            }
            if let Some(p) = padding
                .iter()
                .find(|p| ours.get(**p).is_none_or(|b| *b != 0))
            {
                errors.push(format!(
                    "{at}: our padding byte at {p} is not 0\n{}",
                    hex_dump(ours, &theirs, &padding)
                ));
            }
            // rclpy's length is rmw_fastrtps's size estimate: ours, or more (trailing bytes).
            let rmw_size = r["rmw_size"].as_u64().map(|s| s as usize);
            let differs: Vec<usize> = (0..ours.len())
                .filter(|i| !padding.contains(i) && theirs.get(*i) != Some(&ours[*i]))
                .collect();
            if rmw_size != Some(theirs.len()) || theirs.len() < ours.len() || !differs.is_empty() {
                errors.push(format!(
                    "{at}: rclpy's bytes differ from ours (length {} vs our {}, rmw_fastrtps's \
                     estimate {rmw_size:?}; bytes differ at {differs:?})\n{}",
                    theirs.len(),
                    ours.len(),
                    hex_dump(ours, &theirs, &padding)
                ));
            }

            // We decode rclpy's bytes to the sample value.
            match (e.decode)(&theirs) {
                Ok(Decoded {
                    wire: again,
                    consumed,
                    debug,
                }) => {
                    if again != *ours {
                        errors.push(format!(
                            "{at}: we decode rclpy's bytes to {debug}, which is not the sample"
                        ));
                    }
                    if consumed != ours.len() - 4 {
                        errors.push(format!(
                            "{at}: decoding rclpy's bytes consumed {consumed} body bytes, \
                             ours have {}",
                            ours.len() - 4
                        ));
                    }
                }
                Err(err) => errors.push(format!(
                    "{at}: rclpy's bytes do not decode: {err}\n{}",
                    hex_dump(ours, &theirs, &padding)
                )),
            }
            checked += 1;
        }
    }
    assert!(
        errors.is_empty(),
        "{} problem(s):\n{}",
        errors.len(),
        errors.join("\n\n")
    );
    assert!(
        checked >= registry.len() * 2,
        "only {checked} samples checked"
    );
}
