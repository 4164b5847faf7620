//! The two storage formats of a rosbag2 bag, as ROS 2 Jazzy writes them.
//!
//! **MCAP** (`<bag>/<bag>_0.mcap`, the `mcap` crate): profile `ros2`; one schema per type
//! (name `pkg/msg/Name`, encoding `ros2msg`, the definition text with dependencies); one
//! channel per topic (message encoding `cdr`, metadata `offered_qos_profiles` (YAML text)
//! and `topic_type_hash` (RIHS01)); messages with log time = publish time = receive time
//! (ns since the epoch), in zstd-compressed chunks; a metadata record `rosbag2` holding
//! `serialized_metadata` (the `metadata.yaml` body) and `ROS_DISTRO`.
//!
//! **sqlite3** (`<bag>/<bag>_0.db3`, schema version 4):
//!
//! | table | columns |
//! |---|---|
//! | schema | schema_version (4), ros_distro |
//! | metadata | id, metadata_version (9), metadata (the `metadata.yaml` body) |
//! | topics | id, name, type, serialization_format, offered_qos_profiles (YAML text), type_description_hash |
//! | message_definitions | id, topic_type, encoding (`ros2msg`), encoded_message_definition, type_description_hash |
//! | messages | id, topic_id, timestamp (ns), data (CDR with its 4-byte header) |

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use super::BagError;
use super::metadata::{BagQos, parse_qos_text, qos_text};

/// A topic in a bag.
#[derive(Debug, Clone, PartialEq)]
pub struct TopicInfo {
    /// `/joint_commands`.
    pub name: String,
    /// `sensor_msgs/msg/JointState`.
    pub type_name: String,
    /// `cdr`.
    pub serialization_format: String,
    /// The publishers' QoS.
    pub qos: Vec<BagQos>,
    /// RIHS01 (empty when the writer did not know it).
    pub type_hash: String,
    /// `ros2msg` definition with dependencies.
    pub definition: String,
}

/// One stored message.
#[derive(Debug, Clone, PartialEq)]
pub struct BagMessage {
    /// Index into the bag's topics.
    pub topic: usize,
    /// Receive time, ns since the epoch.
    pub time_ns: i64,
    /// CDR bytes with their 4-byte encapsulation header.
    pub data: Vec<u8>,
}

/// Which format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StorageKind {
    /// `.mcap` (Jazzy's default).
    Mcap,
    /// `.db3`.
    Sqlite3,
}

impl StorageKind {
    /// The `storage_identifier` in metadata.yaml.
    pub fn id(self) -> &'static str {
        match self {
            Self::Mcap => "mcap",
            Self::Sqlite3 => "sqlite3",
        }
    }
    /// The file extension.
    pub fn extension(self) -> &'static str {
        match self {
            Self::Mcap => "mcap",
            Self::Sqlite3 => "db3",
        }
    }
    /// From a `storage_identifier`.
    pub fn from_id(id: &str) -> Option<Self> {
        match id {
            "mcap" => Some(Self::Mcap),
            "sqlite3" => Some(Self::Sqlite3),
            _ => None,
        }
    }
}

fn storage_err(file: &Path, reason: impl std::fmt::Display) -> BagError {
    BagError::Storage {
        file: file.to_path_buf(),
        reason: reason.to_string(),
    }
}

/// Writes one storage file.
pub enum StorageWriter {
    /// MCAP.
    Mcap {
        /// The file.
        path: PathBuf,
        /// The writer.
        writer: Box<mcap::Writer<BufWriter<File>>>,
        /// Channel id per topic index.
        channels: Vec<u16>,
        /// Schema id per type.
        schemas: BTreeMap<String, u16>,
        /// Messages written (MCAP sequence numbers).
        sequence: u32,
    },
    /// sqlite3.
    Sqlite3 {
        /// The file.
        path: PathBuf,
        /// The database, inside a transaction committed every second of messages.
        db: rusqlite::Connection,
        /// Types already in message_definitions.
        types: Vec<String>,
        /// Rows since the last commit.
        pending: usize,
    },
}

impl std::fmt::Debug for StorageWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (kind, path) = match self {
            Self::Mcap { path, .. } => ("mcap", path),
            Self::Sqlite3 { path, .. } => ("sqlite3", path),
        };
        f.debug_struct("StorageWriter")
            .field("kind", &kind)
            .field("path", path)
            .finish_non_exhaustive()
    }
}

const SQLITE_SCHEMA: &str = "
CREATE TABLE schema(schema_version INTEGER PRIMARY KEY, ros_distro TEXT NOT NULL);
CREATE TABLE metadata(id INTEGER PRIMARY KEY, metadata_version INTEGER NOT NULL, metadata TEXT NOT NULL);
CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,
  serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL,
  type_description_hash TEXT NOT NULL);
CREATE TABLE message_definitions(id INTEGER PRIMARY KEY, topic_type TEXT NOT NULL,
  encoding TEXT NOT NULL, encoded_message_definition TEXT NOT NULL,
  type_description_hash TEXT NOT NULL);
CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL,
  timestamp INTEGER NOT NULL, data BLOB NOT NULL);
CREATE INDEX timestamp_idx ON messages (timestamp ASC);
INSERT INTO schema(schema_version, ros_distro) VALUES (4, 'jazzy');
";

/// Commit the sqlite3 transaction after this many messages, so a crash loses little.
const SQLITE_BATCH: usize = 1000;

impl StorageWriter {
    /// Creates the storage file (which must not exist).
    pub fn create(kind: StorageKind, path: &Path) -> Result<Self, BagError> {
        if path.exists() {
            return Err(storage_err(path, "exists already; not overwriting"));
        }
        match kind {
            StorageKind::Mcap => {
                let file = File::create_new(path).map_err(|e| storage_err(path, e))?;
                let writer = mcap::WriteOptions::new()
                    .profile("ros2")
                    .library(concat!(
                        "biped ",
                        env!("CARGO_PKG_VERSION"),
                        " (mcap crate)"
                    ))
                    .compression(Some(mcap::Compression::Zstd))
                    .create(BufWriter::new(file))
                    .map_err(|e| storage_err(path, e))?;
                Ok(Self::Mcap {
                    path: path.to_path_buf(),
                    writer: Box::new(writer),
                    channels: Vec::new(),
                    schemas: BTreeMap::new(),
                    sequence: 0,
                })
            }
            StorageKind::Sqlite3 => {
                let db = rusqlite::Connection::open(path).map_err(|e| storage_err(path, e))?;
                db.execute_batch(SQLITE_SCHEMA)
                    .map_err(|e| storage_err(path, e))?;
                db.execute_batch("BEGIN")
                    .map_err(|e| storage_err(path, e))?;
                Ok(Self::Sqlite3 {
                    path: path.to_path_buf(),
                    db,
                    types: Vec::new(),
                    pending: 0,
                })
            }
        }
    }

    /// Adds a topic; its index is the number of topics added before it.
    pub fn add_topic(&mut self, topic: &TopicInfo) -> Result<(), BagError> {
        let qos = qos_text(&topic.qos);
        match self {
            Self::Mcap {
                path,
                writer,
                channels,
                schemas,
                ..
            } => {
                let schema = match schemas.get(&topic.type_name) {
                    Some(id) => *id,
                    None => {
                        let id = writer
                            .add_schema(&topic.type_name, "ros2msg", topic.definition.as_bytes())
                            .map_err(|e| storage_err(path, e))?;
                        schemas.insert(topic.type_name.clone(), id);
                        id
                    }
                };
                let meta = BTreeMap::from([
                    ("offered_qos_profiles".to_string(), qos),
                    ("topic_type_hash".to_string(), topic.type_hash.clone()),
                ]);
                let id = writer
                    .add_channel(schema, &topic.name, &topic.serialization_format, &meta)
                    .map_err(|e| storage_err(path, e))?;
                channels.push(id);
            }
            Self::Sqlite3 {
                path, db, types, ..
            } => {
                if !types.contains(&topic.type_name) {
                    db.execute(
                        "INSERT INTO message_definitions (topic_type, encoding, encoded_message_definition, type_description_hash) VALUES (?1, 'ros2msg', ?2, ?3)",
                        (&topic.type_name, &topic.definition, &topic.type_hash),
                    )
                    .map_err(|e| storage_err(path, e))?;
                    types.push(topic.type_name.clone());
                }
                let id: i64 = db
                    .query_row("SELECT COUNT(*) FROM topics", [], |r| r.get(0))
                    .map_err(|e| storage_err(path, e))?;
                db.execute(
                    "INSERT INTO topics (id, name, type, serialization_format, offered_qos_profiles, type_description_hash) VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
                    (id + 1, &topic.name, &topic.type_name, &topic.serialization_format, &qos, &topic.type_hash),
                )
                .map_err(|e| storage_err(path, e))?;
            }
        }
        Ok(())
    }

    /// Writes a message of topic index `topic`.
    pub fn write(&mut self, topic: usize, time_ns: i64, data: &[u8]) -> Result<(), BagError> {
        match self {
            Self::Mcap {
                path,
                writer,
                channels,
                sequence,
                ..
            } => {
                let channel = *channels
                    .get(topic)
                    .ok_or_else(|| storage_err(path, format!("no topic number {topic}")))?;
                *sequence = sequence.wrapping_add(1);
                let header = mcap::records::MessageHeader {
                    channel_id: channel,
                    sequence: *sequence,
                    log_time: time_ns.max(0) as u64,
                    publish_time: time_ns.max(0) as u64,
                };
                writer
                    .write_to_known_channel(&header, data)
                    .map_err(|e| storage_err(path, e))
            }
            Self::Sqlite3 {
                path, db, pending, ..
            } => {
                db.execute(
                    "INSERT INTO messages (topic_id, timestamp, data) VALUES (?1, ?2, ?3)",
                    (topic as i64 + 1, time_ns, data),
                )
                .map_err(|e| storage_err(path, e))?;
                *pending += 1;
                if *pending >= SQLITE_BATCH {
                    db.execute_batch("COMMIT; BEGIN")
                        .map_err(|e| storage_err(path, e))?;
                    *pending = 0;
                }
                Ok(())
            }
        }
    }

    /// Writes the metadata copy and closes the file (MCAP: summary, index and footer).
    pub fn finish(self, metadata_yaml: &str) -> Result<(), BagError> {
        match self {
            Self::Mcap {
                path, mut writer, ..
            } => {
                let record = mcap::records::Metadata {
                    name: "rosbag2".to_string(),
                    metadata: BTreeMap::from([
                        ("serialized_metadata".to_string(), metadata_yaml.to_string()),
                        ("ROS_DISTRO".to_string(), "jazzy".to_string()),
                    ]),
                };
                writer
                    .write_metadata(&record)
                    .map_err(|e| storage_err(&path, e))?;
                writer.finish().map_err(|e| storage_err(&path, e))?;
                let inner = writer.into_inner();
                inner
                    .into_inner()
                    .map_err(|e| storage_err(&path, e.error().to_string()))?
                    .sync_all()
                    .map_err(|e| storage_err(&path, e))
            }
            Self::Sqlite3 { path, db, .. } => {
                db.execute(
                    "INSERT INTO metadata (metadata_version, metadata) VALUES (9, ?1)",
                    [metadata_yaml],
                )
                .map_err(|e| storage_err(&path, e))?;
                db.execute_batch("COMMIT")
                    .map_err(|e| storage_err(&path, e))?;
                db.close().map_err(|(_, e)| storage_err(&path, e))
            }
        }
    }
}

/// What a storage file holds: its topics and messages (in time order), and how many
/// messages could not be read.
#[derive(Debug, Clone, Default)]
pub struct StorageContents {
    /// Topics in file order.
    pub topics: Vec<TopicInfo>,
    /// Messages sorted by time.
    pub messages: Vec<BagMessage>,
    /// Messages skipped as unreadable, with why (the first few).
    pub unreadable: usize,
    /// The first reasons.
    pub unreadable_reasons: Vec<String>,
}

impl StorageContents {
    fn skip(&mut self, reason: String) {
        self.unreadable += 1;
        if self.unreadable_reasons.len() < 5 {
            self.unreadable_reasons.push(reason);
        }
    }
}

/// Reads a whole storage file.
pub fn read_storage(kind: StorageKind, path: &Path) -> Result<StorageContents, BagError> {
    match kind {
        StorageKind::Mcap => read_mcap(path),
        StorageKind::Sqlite3 => read_sqlite(path),
    }
}

fn read_mcap(path: &Path) -> Result<StorageContents, BagError> {
    let bytes = std::fs::read(path).map_err(|e| storage_err(path, e))?;
    // A file without its summary and footer was not closed: a recorder that crashed or was
    // killed. Refuse it rather than play part of it silently.
    let summary = mcap::Summary::read(&bytes)
        .map_err(|e| match e {
            mcap::McapError::UnknownSchema(topic, _) => {
                BagError::MissingSchema { file: path.to_path_buf(), topic }
            }
            e => storage_err(
                path,
                format!("not a complete MCAP file ({e}): truncated, or the recorder was killed before closing it"),
            ),
        })?
        .ok_or_else(|| storage_err(path, "MCAP file has no summary section (not closed by its writer)"))?;
    let mut out = StorageContents::default();
    let mut channel_topic = BTreeMap::new();
    // In channel id order (the summary's map has none): the order they were written.
    let mut channels: Vec<_> = summary.channels.iter().collect();
    channels.sort_by_key(|(id, _)| **id);
    for (id, channel) in channels {
        let Some(schema) = channel.schema.as_ref() else {
            return Err(BagError::MissingSchema {
                file: path.to_path_buf(),
                topic: channel.topic.clone(),
            });
        };
        let definition = String::from_utf8(schema.data.to_vec()).map_err(|_| {
            storage_err(
                path,
                format!("schema of {} is not UTF-8 text", channel.topic),
            )
        })?;
        let qos = parse_qos_text(
            channel
                .metadata
                .get("offered_qos_profiles")
                .map(String::as_str)
                .unwrap_or(""),
        )
        .map_err(|e| storage_err(path, format!("topic {}: {e}", channel.topic)))?;
        channel_topic.insert(*id, out.topics.len());
        out.topics.push(TopicInfo {
            name: channel.topic.clone(),
            type_name: schema.name.clone(),
            serialization_format: channel.message_encoding.clone(),
            qos,
            type_hash: channel
                .metadata
                .get("topic_type_hash")
                .cloned()
                .unwrap_or_default(),
            definition,
        });
    }
    let stream = mcap::MessageStream::new(&bytes).map_err(|e| storage_err(path, e))?;
    for m in stream {
        match m {
            Ok(m) => match channel_topic.get(&m.channel.id) {
                Some(&topic) => out.messages.push(BagMessage {
                    topic,
                    time_ns: i64::try_from(m.log_time).unwrap_or(i64::MAX),
                    data: m.data.into_owned(),
                }),
                None => out.skip(format!(
                    "message on channel {} not in the summary",
                    m.channel.id
                )),
            },
            // A corrupt record ends the stream: what follows cannot be framed.
            Err(e) => {
                out.skip(format!("unreadable record: {e}"));
                break;
            }
        }
    }
    out.messages.sort_by_key(|m| m.time_ns);
    Ok(out)
}

fn read_sqlite(path: &Path) -> Result<StorageContents, BagError> {
    let db =
        rusqlite::Connection::open_with_flags(path, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY)
            .map_err(|e| storage_err(path, e))?;
    let sql = |e: rusqlite::Error| storage_err(path, e);
    let mut definitions = BTreeMap::new();
    // message_definitions is absent in bags older than schema version 4.
    if let Ok(mut st) =
        db.prepare("SELECT topic_type, encoded_message_definition FROM message_definitions")
    {
        let rows = st
            .query_map([], |r| Ok((r.get::<_, String>(0)?, r.get::<_, String>(1)?)))
            .map_err(sql)?;
        for row in rows {
            let (t, d) = row.map_err(sql)?;
            definitions.insert(t, d);
        }
    }
    let has_hash = db
        .prepare("SELECT type_description_hash FROM topics LIMIT 1")
        .is_ok();
    let query = if has_hash {
        "SELECT id, name, type, serialization_format, offered_qos_profiles, type_description_hash FROM topics ORDER BY id"
    } else {
        "SELECT id, name, type, serialization_format, offered_qos_profiles, '' FROM topics ORDER BY id"
    };
    let mut out = StorageContents::default();
    let mut topic_index = BTreeMap::new();
    let mut st = db.prepare(query).map_err(sql)?;
    let rows = st
        .query_map([], |r| {
            Ok((
                r.get::<_, i64>(0)?,
                r.get::<_, String>(1)?,
                r.get::<_, String>(2)?,
                r.get::<_, String>(3)?,
                r.get::<_, String>(4)?,
                r.get::<_, String>(5)?,
            ))
        })
        .map_err(sql)?;
    for row in rows {
        let (id, name, type_name, format, qos, hash) = row.map_err(sql)?;
        let qos =
            parse_qos_text(&qos).map_err(|e| storage_err(path, format!("topic {name}: {e}")))?;
        topic_index.insert(id, out.topics.len());
        out.topics.push(TopicInfo {
            definition: definitions.get(&type_name).cloned().unwrap_or_default(),
            name,
            type_name,
            serialization_format: format,
            qos,
            type_hash: hash,
        });
    }
    let mut st = db
        .prepare("SELECT topic_id, timestamp, data FROM messages ORDER BY timestamp, id")
        .map_err(sql)?;
    let rows = st
        .query_map([], |r| {
            Ok((
                r.get::<_, i64>(0)?,
                r.get::<_, i64>(1)?,
                r.get::<_, Vec<u8>>(2),
            ))
        })
        .map_err(sql)?;
    for row in rows {
        match row {
            Ok((topic_id, time_ns, Ok(data))) => match topic_index.get(&topic_id) {
                Some(&topic) => out.messages.push(BagMessage {
                    topic,
                    time_ns,
                    data,
                }),
                None => out.skip(format!("message of unknown topic id {topic_id}")),
            },
            Ok((_, time_ns, Err(e))) => out.skip(format!("message at {time_ns} ns: {e}")),
            Err(e) => out.skip(format!("unreadable row: {e}")),
        }
    }
    Ok(out)
}
