//! `metadata.yaml` of a rosbag2 bag (version 9, as ROS 2 Jazzy writes it) and the QoS
//! profiles it records per topic.
//!
//! Version 9 writes `offered_qos_profiles` as a list of mappings with names
//! (`history: keep_last`); older versions (and the MCAP channel metadata of some writers)
//! as a YAML text with the rmw enum numbers (`history: 1`). Both are read.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

/// The file's top level.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MetadataFile {
    /// Everything is under this key.
    pub rosbag2_bagfile_information: BagInfo,
}

/// A duration in nanoseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Nanoseconds {
    /// ns.
    pub nanoseconds: u64,
}

/// A time in nanoseconds since the epoch.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct StartingTime {
    /// ns since 1970.
    pub nanoseconds_since_epoch: i64,
}

/// `rosbag2_bagfile_information`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BagInfo {
    /// Format version (we write 9).
    pub version: u32,
    /// `mcap` or `sqlite3`.
    pub storage_identifier: String,
    /// Last message time − first message time.
    pub duration: Nanoseconds,
    /// First message time.
    pub starting_time: StartingTime,
    /// All messages.
    pub message_count: u64,
    /// Per topic.
    pub topics_with_message_count: Vec<TopicWithCount>,
    /// Empty: no compression of files or messages (MCAP chunks may be compressed inside).
    #[serde(default)]
    pub compression_format: String,
    /// Empty, `file` or `message`.
    #[serde(default)]
    pub compression_mode: String,
    /// Storage files, relative to the bag folder.
    pub relative_file_paths: Vec<String>,
    /// Per file (version ≥ 5).
    #[serde(default)]
    pub files: Vec<FileInfo>,
    /// User data (version ≥ 6).
    #[serde(default)]
    pub custom_data: Option<BTreeMap<String, String>>,
    /// Who wrote it (version ≥ 8).
    #[serde(default)]
    pub ros_distro: String,
}

/// One storage file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FileInfo {
    /// Relative to the bag folder.
    pub path: String,
    /// First message time.
    pub starting_time: StartingTime,
    /// Last − first message time.
    pub duration: Nanoseconds,
    /// Messages in it.
    pub message_count: u64,
}

/// One topic and its count.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TopicWithCount {
    /// The topic.
    pub topic_metadata: TopicMetadata,
    /// Messages on it.
    pub message_count: u64,
}

/// A topic as recorded.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TopicMetadata {
    /// `/joint_commands`.
    pub name: String,
    /// `sensor_msgs/msg/JointState`.
    #[serde(rename = "type")]
    pub type_name: String,
    /// `cdr`.
    pub serialization_format: String,
    /// The publishers' QoS.
    #[serde(default)]
    pub offered_qos_profiles: QosProfiles,
    /// RIHS01 (version ≥ 9; empty when unknown).
    #[serde(default)]
    pub type_description_hash: String,
}

/// `offered_qos_profiles`: a list (version 9) or a YAML text of one (older).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum QosProfiles {
    /// Version 9.
    List(Vec<BagQos>),
    /// Version ≤ 8: YAML text.
    Text(String),
}

impl Default for QosProfiles {
    fn default() -> Self {
        Self::List(Vec::new())
    }
}

impl QosProfiles {
    /// The profiles, parsing the text form.
    pub fn profiles(&self) -> Result<Vec<BagQos>, String> {
        match self {
            Self::List(v) => Ok(v.clone()),
            Self::Text(t) => parse_qos_text(t),
        }
    }
}

/// Parses a YAML text of QoS profiles (MCAP channel metadata, sqlite3 topics table, old
/// metadata); empty text = none.
pub fn parse_qos_text(text: &str) -> Result<Vec<BagQos>, String> {
    if text.trim().is_empty() {
        return Ok(Vec::new());
    }
    serde_norway::from_str::<Vec<BagQos>>(text).map_err(|e| format!("QoS profiles: {e}"))
}

/// The YAML text of QoS profiles, as stored in MCAP channel metadata and the sqlite3 topics
/// table.
pub fn qos_text(profiles: &[BagQos]) -> String {
    serde_norway::to_string(profiles)
        .map(|s| s.trim_end().to_string())
        .unwrap_or_default()
}

/// A QoS duration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct SecNsec {
    /// s.
    pub sec: i64,
    /// ns.
    pub nsec: u64,
}

impl SecNsec {
    /// "Infinite" as rmw spells it (`RMW_DURATION_INFINITE`), what Jazzy records.
    pub const INFINITE: Self = Self {
        sec: 9_223_372_036,
        nsec: 854_775_807,
    };
    /// Whether this means no limit: rmw's infinite, the older DDS one
    /// (2147483647 s 4294967295 ns, in Foxy-era bags and the rosbags library's), or 0
    /// (the rmw default, "unspecified").
    pub fn is_infinite(&self) -> bool {
        *self == Self::INFINITE
            || (self.sec == 2_147_483_647 && self.nsec == 4_294_967_295)
            || (self.sec == 0 && self.nsec == 0)
    }
}

/// One QoS profile as rosbag2 records it. Enum fields are read from names or rmw numbers and
/// written as names.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct BagQos {
    /// keep_last / keep_all / system_default.
    pub history: QosEnum<History>,
    /// Depth of keep_last.
    pub depth: u32,
    /// reliable / best_effort.
    pub reliability: QosEnum<Reliability>,
    /// volatile / transient_local.
    pub durability: QosEnum<Durability>,
    /// Deadline.
    pub deadline: SecNsec,
    /// Lifespan.
    pub lifespan: SecNsec,
    /// automatic / manual_by_topic.
    pub liveliness: QosEnum<Liveliness>,
    /// Liveliness lease.
    pub liveliness_lease_duration: SecNsec,
    /// ROS name mangling off.
    pub avoid_ros_namespace_conventions: bool,
}

/// An rmw QoS enumeration: its names and numbers.
pub trait RmwEnum: Copy + Eq + std::fmt::Debug + 'static {
    /// (number, name) of every value.
    const VALUES: &'static [(u8, &'static str, Self)];
}

/// A QoS enum value, serialized by name, read by name or number.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct QosEnum<E: RmwEnum>(pub E);

impl<E: RmwEnum> Serialize for QosEnum<E> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let name = E::VALUES
            .iter()
            .find(|v| v.2 == self.0)
            .map(|v| v.1)
            .unwrap_or("unknown");
        s.serialize_str(name)
    }
}

impl<'de, E: RmwEnum> Deserialize<'de> for QosEnum<E> {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum NameOrNumber {
            Number(u64),
            Name(String),
        }
        let v = NameOrNumber::deserialize(d)?;
        let found = E::VALUES.iter().find(|(n, name, _)| match &v {
            NameOrNumber::Number(x) => *x == u64::from(*n),
            NameOrNumber::Name(s) => s.eq_ignore_ascii_case(name),
        });
        found.map(|v| QosEnum(v.2)).ok_or_else(|| {
            let got = match v {
                NameOrNumber::Number(x) => x.to_string(),
                NameOrNumber::Name(s) => s,
            };
            let names: Vec<_> = E::VALUES.iter().map(|v| v.1).collect();
            serde::de::Error::custom(format!("unknown QoS value '{got}' (one of {names:?})"))
        })
    }
}

/// History policy.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum History {
    /// The middleware's default.
    SystemDefault,
    /// Keep the last `depth`.
    KeepLast,
    /// Keep all.
    KeepAll,
    /// Not announced (a recorder cannot see a remote publisher's history).
    Unknown,
}
impl RmwEnum for History {
    const VALUES: &'static [(u8, &'static str, Self)] = &[
        (0, "system_default", Self::SystemDefault),
        (1, "keep_last", Self::KeepLast),
        (2, "keep_all", Self::KeepAll),
        (3, "unknown", Self::Unknown),
    ];
}

/// Reliability policy.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reliability {
    /// The middleware's default (reliable).
    SystemDefault,
    /// Resend lost samples.
    Reliable,
    /// Never resend.
    BestEffort,
    /// Match the other side (Jazzy).
    BestAvailable,
}
impl RmwEnum for Reliability {
    const VALUES: &'static [(u8, &'static str, Self)] = &[
        (0, "system_default", Self::SystemDefault),
        (1, "reliable", Self::Reliable),
        (2, "best_effort", Self::BestEffort),
        (4, "best_available", Self::BestAvailable),
    ];
}

/// Durability policy.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Durability {
    /// The middleware's default (volatile).
    SystemDefault,
    /// Late joiners get the last samples.
    TransientLocal,
    /// Late joiners get nothing old.
    Volatile,
    /// Match the other side (Jazzy).
    BestAvailable,
}
impl RmwEnum for Durability {
    const VALUES: &'static [(u8, &'static str, Self)] = &[
        (0, "system_default", Self::SystemDefault),
        (1, "transient_local", Self::TransientLocal),
        (2, "volatile", Self::Volatile),
        (4, "best_available", Self::BestAvailable),
    ];
}

/// Liveliness policy.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Liveliness {
    /// The middleware's default (automatic).
    SystemDefault,
    /// Asserted by the middleware.
    Automatic,
    /// Asserted by publishing.
    ManualByTopic,
    /// Match the other side (Jazzy).
    BestAvailable,
}
impl RmwEnum for Liveliness {
    const VALUES: &'static [(u8, &'static str, Self)] = &[
        (0, "system_default", Self::SystemDefault),
        (1, "automatic", Self::Automatic),
        (3, "manual_by_topic", Self::ManualByTopic),
        (5, "best_available", Self::BestAvailable),
    ];
}

impl BagQos {
    /// Reliable, volatile, keep last `depth`, no deadline/lifespan: ROS 2's default
    /// publisher profile.
    pub fn reliable(depth: u32) -> Self {
        Self {
            history: QosEnum(History::KeepLast),
            depth,
            reliability: QosEnum(Reliability::Reliable),
            durability: QosEnum(Durability::Volatile),
            deadline: SecNsec::INFINITE,
            lifespan: SecNsec::INFINITE,
            liveliness: QosEnum(Liveliness::Automatic),
            liveliness_lease_duration: SecNsec::INFINITE,
            avoid_ros_namespace_conventions: false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn qos_reads_names_and_rmw_numbers_and_writes_names() {
        let v9 = "- history: keep_last\n  depth: 10\n  reliability: best_effort\n  durability: transient_local\n  deadline: {sec: 2147483647, nsec: 4294967295}\n  lifespan: {sec: 2147483647, nsec: 4294967295}\n  liveliness: automatic\n  liveliness_lease_duration: {sec: 2147483647, nsec: 4294967295}\n  avoid_ros_namespace_conventions: false\n";
        let v8 = v9
            .replace("keep_last", "1")
            .replace("best_effort", "2")
            .replace("transient_local", "1")
            .replace("liveliness: automatic", "liveliness: 1");
        let a = parse_qos_text(v9).unwrap();
        assert_eq!(a, parse_qos_text(&v8).unwrap());
        assert_eq!(a[0].reliability.0, Reliability::BestEffort);
        assert_eq!(a[0].durability.0, Durability::TransientLocal);
        assert_eq!(a[0].depth, 10);
        assert_eq!(parse_qos_text(&qos_text(&a)).unwrap(), a);
        assert!(qos_text(&a).contains("reliability: best_effort"));
    }

    #[test]
    fn an_unknown_qos_value_is_named() {
        let text = "- history: keep_some\n  depth: 1\n";
        let e = parse_qos_text(text).unwrap_err();
        assert!(e.contains("keep_some"), "{e}");
    }

    #[test]
    fn metadata_reads_text_qos_of_older_versions() {
        let yaml = "rosbag2_bagfile_information:\n  version: 8\n  storage_identifier: sqlite3\n  duration: {nanoseconds: 5}\n  starting_time: {nanoseconds_since_epoch: 7}\n  message_count: 1\n  topics_with_message_count:\n    - message_count: 1\n      topic_metadata:\n        name: /a\n        type: std_msgs/msg/String\n        serialization_format: cdr\n        offered_qos_profiles: \"- history: 1\\n  depth: 0\\n  reliability: 1\\n  durability: 2\\n  deadline: {sec: 0, nsec: 0}\\n  lifespan: {sec: 0, nsec: 0}\\n  liveliness: 1\\n  liveliness_lease_duration: {sec: 0, nsec: 0}\\n  avoid_ros_namespace_conventions: false\"\n  relative_file_paths: [a_0.db3]\n";
        let m: MetadataFile = serde_norway::from_str(yaml).unwrap();
        let t = &m.rosbag2_bagfile_information.topics_with_message_count[0].topic_metadata;
        let q = t.offered_qos_profiles.profiles().unwrap();
        assert_eq!(q[0].reliability.0, Reliability::Reliable);
        assert_eq!(t.type_description_hash, "");
    }
}
