//! Raw CDR over DDS: readers and writers that move a message's serialized bytes without
//! decoding them, so a bag holds (and a replay sends) exactly what the publisher sent.
//!
//! ROS 2 names on DDS: topic `/joint_commands` is DDS topic `rt/joint_commands`; type
//! `sensor_msgs/msg/JointState` is DDS type `sensor_msgs::msg::dds_::JointState_`.

use bytes::Bytes;
use ros2_client::dds::rustdds::{
    self, DomainParticipant, QosPolicies, QosPolicyBuilder, RepresentationIdentifier, TopicKind,
    no_key::{DataWriter, SimpleDataReader},
    policy,
};

use super::metadata::{BagQos, Durability, History, Liveliness, QosEnum, Reliability, SecNsec};

/// One serialized message: the 4-byte CDR encapsulation header, then the body.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RawCdr(pub Vec<u8>);

/// The (de)serializer adapter that copies bytes.
#[derive(Debug, Clone, Copy)]
pub struct RawAdapter;

/// A message that cannot be sent as is.
#[derive(Debug, thiserror::Error)]
pub enum RawError {
    /// Too short for the encapsulation header.
    #[error("message of {0} bytes has no 4-byte CDR header")]
    NoHeader(usize),
    /// Not little-endian CDR.
    #[error("message is not little-endian CDR (header {0:02x?}); only CDR_LE is replayed")]
    NotCdrLe([u8; 4]),
}

impl RawCdr {
    /// Whether the message can be written by [`RawAdapter`]: a CDR little-endian header.
    pub fn check(&self) -> Result<(), RawError> {
        let header: [u8; 4] = self
            .0
            .get(..4)
            .and_then(|h| h.try_into().ok())
            .ok_or(RawError::NoHeader(self.0.len()))?;
        if header[..2] != RepresentationIdentifier::CDR_LE.to_bytes() {
            return Err(RawError::NotCdrLe(header));
        }
        Ok(())
    }
}

impl rustdds::no_key::DeserializerAdapter<RawCdr> for RawAdapter {
    type Error = RawError;
    type Decoded = RawCdr;
    fn supported_encodings() -> &'static [RepresentationIdentifier] {
        &[
            RepresentationIdentifier::CDR_LE,
            RepresentationIdentifier::CDR_BE,
        ]
    }
    fn transform_decoded(decoded: RawCdr) -> RawCdr {
        decoded
    }
}

impl rustdds::no_key::DefaultDecoder<RawCdr> for RawAdapter {
    type Decoder = RawDecoder;
    const DECODER: RawDecoder = RawDecoder;
}

/// Puts the encapsulation header back in front of the body DDS hands over.
#[derive(Debug, Clone, Copy)]
pub struct RawDecoder;

impl<'de> rustdds::no_key::Decode<'de, RawCdr> for RawDecoder {
    type Error = RawError;
    fn decode_bytes(
        self,
        input: &'de [u8],
        encoding: RepresentationIdentifier,
    ) -> Result<RawCdr, RawError> {
        let mut v = Vec::with_capacity(input.len() + 4);
        v.extend_from_slice(&encoding.to_bytes());
        v.extend_from_slice(&[0, 0]);
        v.extend_from_slice(input);
        Ok(RawCdr(v))
    }
}

impl rustdds::no_key::SerializerAdapter<RawCdr> for RawAdapter {
    type Error = RawError;
    fn output_encoding() -> RepresentationIdentifier {
        RepresentationIdentifier::CDR_LE
    }
    fn to_bytes(value: &RawCdr) -> Result<Bytes, RawError> {
        value.check()?;
        Ok(Bytes::copy_from_slice(&value.0[4..]))
    }
}

/// `/a/b` → `rt/a/b`.
pub fn dds_topic_name(ros_topic: &str) -> String {
    format!("rt/{}", ros_topic.trim_start_matches('/'))
}

/// `rt/a/b` → `/a/b`; `None` for DDS topics that are not ROS topics (services, discovery).
pub fn ros_topic_name(dds_topic: &str) -> Option<String> {
    dds_topic.strip_prefix("rt/").map(|r| format!("/{r}"))
}

/// `pkg/msg/Name` → `pkg::msg::dds_::Name_`.
pub fn dds_type_name(ros_type: &str) -> Option<String> {
    let mut parts = ros_type.split('/');
    let (pkg, kind, name) = (parts.next()?, parts.next()?, parts.next()?);
    let ident = |s: &str| !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
    (parts.next().is_none() && kind == "msg" && ident(pkg) && ident(name))
        .then(|| format!("{pkg}::msg::dds_::{name}_"))
}

/// `pkg::msg::dds_::Name_` → `pkg/msg/Name`.
pub fn ros_type_name(dds_type: &str) -> Option<String> {
    let (pkg, rest) = dds_type.split_once("::msg::dds_::")?;
    Some(format!("{pkg}/msg/{}", rest.strip_suffix('_')?))
}

fn duration_of(d: SecNsec) -> rustdds::Duration {
    if d.is_infinite() {
        rustdds::Duration::INFINITE
    } else {
        rustdds::Duration::from_frac_seconds(d.sec as f64 + d.nsec as f64 * 1e-9)
    }
}

fn sec_nsec(d: rustdds::Duration) -> SecNsec {
    if d == rustdds::Duration::INFINITE {
        return SecNsec::INFINITE;
    }
    let ns = d.to_nanoseconds();
    SecNsec {
        sec: ns.div_euclid(1_000_000_000),
        nsec: ns.rem_euclid(1_000_000_000) as u64,
    }
}

/// A DDS endpoint QoS from a recorded profile; a history the recorder could not see (or
/// depth 0) becomes keep last 10, what `ros2 bag play` uses.
pub fn qos_policies(q: &BagQos) -> QosPolicies {
    let history = match (q.history.0, q.depth) {
        (History::KeepAll, _) => policy::History::KeepAll,
        (_, 0) => policy::History::KeepLast { depth: 10 },
        (_, d) => policy::History::KeepLast {
            depth: i32::try_from(d).unwrap_or(i32::MAX),
        },
    };
    let reliability = match q.reliability.0 {
        Reliability::BestEffort => policy::Reliability::BestEffort,
        _ => policy::Reliability::Reliable {
            max_blocking_time: rustdds::Duration::from_frac_seconds(0.1),
        },
    };
    let durability = match q.durability.0 {
        Durability::TransientLocal => policy::Durability::TransientLocal,
        _ => policy::Durability::Volatile,
    };
    let lease = duration_of(q.liveliness_lease_duration);
    let liveliness = match q.liveliness.0 {
        Liveliness::ManualByTopic => policy::Liveliness::ManualByTopic {
            lease_duration: lease,
        },
        _ => policy::Liveliness::Automatic {
            lease_duration: lease,
        },
    };
    let mut b = QosPolicyBuilder::new()
        .history(history)
        .reliability(reliability)
        .durability(durability)
        .liveliness(liveliness);
    if !q.deadline.is_infinite() {
        b = b.deadline(policy::Deadline(duration_of(q.deadline)));
    }
    if !q.lifespan.is_infinite() {
        b = b.lifespan(policy::Lifespan {
            duration: duration_of(q.lifespan),
        });
    }
    b.build()
}

/// The QoS a discovered publisher offers, as rosbag2 records it (a remote history is not
/// announced: `unknown`, depth 0).
pub fn offered_qos(w: &rustdds::discovery::PublicationBuiltinTopicData) -> BagQos {
    let mut q = BagQos::reliable(0);
    q.history = QosEnum(History::Unknown);
    if let Some(policy::Reliability::BestEffort) = w.reliability {
        q.reliability = QosEnum(Reliability::BestEffort);
    }
    if let Some(
        policy::Durability::TransientLocal
        | policy::Durability::Transient
        | policy::Durability::Persistent,
    ) = w.durability
    {
        q.durability = QosEnum(Durability::TransientLocal);
    }
    match w.liveliness {
        Some(policy::Liveliness::ManualByTopic { lease_duration }) => {
            q.liveliness = QosEnum(Liveliness::ManualByTopic);
            q.liveliness_lease_duration = sec_nsec(lease_duration);
        }
        Some(
            policy::Liveliness::Automatic { lease_duration }
            | policy::Liveliness::ManualByParticipant { lease_duration },
        ) => q.liveliness_lease_duration = sec_nsec(lease_duration),
        None => {}
    }
    if let Some(policy::Deadline(d)) = w.deadline {
        q.deadline = sec_nsec(d);
    }
    if let Some(policy::Lifespan { duration }) = w.lifespan {
        q.lifespan = sec_nsec(duration);
    }
    q
}

/// The QoS to subscribe with so every offered profile matches: best effort if any publisher
/// is, transient local only if all are (rosbag2's rule), keep last 1000.
pub fn subscription_qos(offered: &[BagQos]) -> QosPolicies {
    let mut q = BagQos::reliable(1000);
    if offered
        .iter()
        .any(|o| o.reliability.0 == Reliability::BestEffort)
    {
        q.reliability = QosEnum(Reliability::BestEffort);
    }
    if !offered.is_empty()
        && offered
            .iter()
            .all(|o| o.durability.0 == Durability::TransientLocal)
    {
        q.durability = QosEnum(Durability::TransientLocal);
    }
    qos_policies(&q)
}

/// A raw reader of one ROS topic.
pub struct RawReader {
    reader: SimpleDataReader<RawCdr, RawAdapter>,
}

impl std::fmt::Debug for RawReader {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RawReader").finish_non_exhaustive()
    }
}

/// A raw writer of one ROS topic.
pub struct RawWriter {
    writer: DataWriter<RawCdr, RawAdapter>,
    dds_topic: String,
}

impl std::fmt::Debug for RawWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RawWriter").finish_non_exhaustive()
    }
}

fn topic(
    dp: &DomainParticipant,
    ros_topic: &str,
    ros_type: &str,
    qos: &QosPolicies,
) -> Result<rustdds::Topic, String> {
    let type_name = dds_type_name(ros_type)
        .ok_or_else(|| format!("'{ros_type}' is not a message type name (pkg/msg/Name)"))?;
    dp.create_topic(dds_topic_name(ros_topic), type_name, qos, TopicKind::NoKey)
        .map_err(|e| format!("topic {ros_topic}: {e:?}"))
}

impl RawReader {
    /// Subscribes to `ros_topic` of `ros_type`.
    pub fn new(
        dp: &DomainParticipant,
        ros_topic: &str,
        ros_type: &str,
        qos: &QosPolicies,
    ) -> Result<Self, String> {
        let t = topic(dp, ros_topic, ros_type, qos)?;
        let sub = dp
            .create_subscriber(qos)
            .map_err(|e| format!("subscriber for {ros_topic}: {e:?}"))?;
        let reader = sub
            .create_simple_datareader_no_key::<RawCdr, RawAdapter>(&t, Some(qos.clone()))
            .map_err(|e| format!("reader for {ros_topic}: {e:?}"))?;
        Ok(Self { reader })
    }

    /// The next received message, if any.
    pub fn take(&self) -> Result<Option<RawCdr>, String> {
        self.reader.drain_read_notifications();
        self.reader
            .try_take_one()
            .map(|o| o.map(|c| c.into_value()))
            .map_err(|e| format!("{e:?}"))
    }
}

impl RawWriter {
    /// A publisher of `ros_topic` of `ros_type`.
    pub fn new(
        dp: &DomainParticipant,
        ros_topic: &str,
        ros_type: &str,
        qos: &QosPolicies,
    ) -> Result<Self, String> {
        let t = topic(dp, ros_topic, ros_type, qos)?;
        let publisher = dp
            .create_publisher(qos)
            .map_err(|e| format!("publisher for {ros_topic}: {e:?}"))?;
        let writer = publisher
            .create_datawriter_no_key::<RawCdr, RawAdapter>(&t, Some(qos.clone()))
            .map_err(|e| format!("writer for {ros_topic}: {e:?}"))?;
        Ok(Self {
            writer,
            dds_topic: dds_topic_name(ros_topic),
        })
    }

    /// Sends one message.
    pub fn write(&self, msg: RawCdr) -> Result<(), String> {
        self.writer
            .write(msg, Some(rustdds::Timestamp::now()))
            .map_err(|e| format!("{e:?}"))
    }

    /// Waits until every matched reliable subscriber has acknowledged all that was written,
    /// at most `max_wait`: true if they all have (at once for a best-effort writer).
    pub fn wait_for_acknowledgments(&self, max_wait: std::time::Duration) -> bool {
        self.writer
            .wait_for_acknowledgments(max_wait)
            .unwrap_or(false)
    }

    /// How many subscriptions of the topic discovery has seen (rustdds does not expose the
    /// writer's matched count).
    pub fn subscribers(&self, dp: &DomainParticipant) -> usize {
        dp.discovered_readers()
            .iter()
            .filter(|r| r.subscription_topic_data.topic_name() == &self.dds_topic)
            .count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ros_and_dds_names_convert_both_ways() {
        assert_eq!(dds_topic_name("/joint_commands"), "rt/joint_commands");
        assert_eq!(ros_topic_name("rt/sim/cop").as_deref(), Some("/sim/cop"));
        assert_eq!(ros_topic_name("rq/x/get_parametersRequest"), None);
        assert_eq!(
            dds_type_name("sensor_msgs/msg/JointState").as_deref(),
            Some("sensor_msgs::msg::dds_::JointState_")
        );
        assert_eq!(
            ros_type_name("sensor_msgs::msg::dds_::JointState_").as_deref(),
            Some("sensor_msgs/msg/JointState")
        );
        assert_eq!(dds_type_name("sensor_msgs/srv/SetBool"), None);
        assert_eq!(dds_type_name("JointState"), None);
    }

    #[test]
    fn only_little_endian_cdr_is_written() {
        assert!(RawCdr(vec![0, 1, 0, 0, 7]).check().is_ok());
        assert!(matches!(
            RawCdr(vec![0, 0, 0, 0, 7]).check(),
            Err(RawError::NotCdrLe(_))
        ));
        assert!(matches!(
            RawCdr(vec![0, 1]).check(),
            Err(RawError::NoHeader(2))
        ));
    }

    #[test]
    fn recorded_qos_round_trips_through_dds_durations() {
        let d = SecNsec {
            sec: 2,
            nsec: 500_000_000,
        };
        assert_eq!(sec_nsec(duration_of(d)).sec, 2);
        assert!((sec_nsec(duration_of(d)).nsec as i64 - 500_000_000).abs() < 10);
        assert_eq!(sec_nsec(rustdds::Duration::INFINITE), SecNsec::INFINITE);
    }
}
