//! rosbag2 bags without ROS: the files ROS 2 Jazzy's `ros2 bag record` writes, written and
//! read here, and the DDS ends of `biped record` and `biped replay`.
//!
//! A bag is a folder: `metadata.yaml` ([`metadata`]) and one storage file ([`storage`]:
//! MCAP by default, or sqlite3). [`BagWriter`] writes one; [`Bag::open`] reads and checks
//! one (metadata against storage) and refuses what it cannot trust with a [`BagError`]
//! naming the problem. [`dds`] subscribes and publishes raw CDR over DDS, so any type
//! whose description we know can be recorded and replayed byte for byte.

pub mod dds;
pub mod metadata;
pub mod record;
pub mod replay;
pub mod storage;

use std::path::{Path, PathBuf};

use metadata::{
    BagInfo, FileInfo, MetadataFile, Nanoseconds, QosProfiles, StartingTime, TopicMetadata,
    TopicWithCount,
};
use storage::{BagMessage, StorageKind, StorageWriter, TopicInfo, read_storage};

/// Why a bag cannot be written or read.
#[derive(Debug, thiserror::Error)]
pub enum BagError {
    /// No readable metadata.yaml.
    #[error("{}: no metadata.yaml ({reason}): not a rosbag2 bag folder", dir.display())]
    NoMetadata {
        /// The bag folder.
        dir: PathBuf,
        /// Why.
        reason: String,
    },
    /// metadata.yaml does not parse.
    #[error("{}: not rosbag2 metadata: {reason}", file.display())]
    Metadata {
        /// The file.
        file: PathBuf,
        /// Why.
        reason: String,
    },
    /// A storage we do not read.
    #[error("{}: unknown storage_identifier '{id}' in metadata.yaml (we read mcap and sqlite3)", dir.display())]
    UnknownStorage {
        /// The bag folder.
        dir: PathBuf,
        /// The identifier.
        id: String,
    },
    /// A compression we do not read.
    #[error("{}: compression_mode '{mode}' (format '{format}') is not supported: decompress the bag first (ros2 bag convert)", dir.display())]
    Compressed {
        /// The bag folder.
        dir: PathBuf,
        /// file or message.
        mode: String,
        /// zstd.
        format: String,
    },
    /// A storage file metadata.yaml lists is not there.
    #[error("{}: listed in metadata.yaml but missing", file.display())]
    MissingFile {
        /// The file.
        file: PathBuf,
    },
    /// The storage file is unreadable or corrupt.
    #[error("{}: {reason}", file.display())]
    Storage {
        /// The file.
        file: PathBuf,
        /// Why.
        reason: String,
    },
    /// A topic without a message definition.
    #[error("{}: topic {topic} has no schema (message definition): its messages cannot be decoded by anyone", file.display())]
    MissingSchema {
        /// The file.
        file: PathBuf,
        /// The topic.
        topic: String,
    },
    /// metadata.yaml says one thing, the storage another.
    #[error("{}: metadata.yaml and the storage disagree: {what}", dir.display())]
    Mismatch {
        /// The bag folder.
        dir: PathBuf,
        /// What differs.
        what: String,
    },
    /// Writing over an existing bag.
    #[error("{}: exists already; not overwriting (choose a new bag folder)", dir.display())]
    Exists {
        /// The folder.
        dir: PathBuf,
    },
    /// A file system error.
    #[error("{}: {source}", path.display())]
    Io {
        /// The path.
        path: PathBuf,
        /// The error.
        source: std::io::Error,
    },
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> BagError + '_ {
    move |source| BagError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// A bag read into memory and checked.
#[derive(Debug, Clone)]
pub struct Bag {
    /// The folder.
    pub dir: PathBuf,
    /// metadata.yaml.
    pub info: BagInfo,
    /// The storage format.
    pub kind: StorageKind,
    /// Topics (merged over the storage files).
    pub topics: Vec<TopicInfo>,
    /// Messages in time order.
    pub messages: Vec<BagMessage>,
    /// Messages that could not be read and are skipped.
    pub unreadable: usize,
    /// Why (the first few), and metadata disagreements that the unreadable ones explain.
    pub warnings: Vec<String>,
}

impl Bag {
    /// Reads `dir/metadata.yaml` and its storage files, and checks that they agree: every
    /// topic with its type and count, and the total count.
    pub fn open(dir: &Path) -> Result<Self, BagError> {
        let meta_path = dir.join("metadata.yaml");
        let text = std::fs::read_to_string(&meta_path).map_err(|e| BagError::NoMetadata {
            dir: dir.to_path_buf(),
            reason: e.to_string(),
        })?;
        let file: MetadataFile = serde_norway::from_str(&text).map_err(|e| BagError::Metadata {
            file: meta_path.clone(),
            reason: e.to_string(),
        })?;
        let info = file.rosbag2_bagfile_information;
        let kind = StorageKind::from_id(&info.storage_identifier).ok_or_else(|| {
            BagError::UnknownStorage {
                dir: dir.to_path_buf(),
                id: info.storage_identifier.clone(),
            }
        })?;
        if !info.compression_mode.is_empty() || !info.compression_format.is_empty() {
            return Err(BagError::Compressed {
                dir: dir.to_path_buf(),
                mode: info.compression_mode.clone(),
                format: info.compression_format.clone(),
            });
        }
        if info.relative_file_paths.is_empty() {
            return Err(BagError::Metadata {
                file: meta_path,
                reason: "relative_file_paths is empty".into(),
            });
        }
        let mut topics: Vec<TopicInfo> = Vec::new();
        let mut messages = Vec::new();
        let mut unreadable = 0;
        let mut warnings = Vec::new();
        for rel in &info.relative_file_paths {
            let path = dir.join(rel);
            if !path.is_file() {
                return Err(BagError::MissingFile { file: path });
            }
            let contents = read_storage(kind, &path)?;
            // Topic indices of this file to the merged list.
            let mut map = Vec::new();
            for t in contents.topics {
                let i = match topics
                    .iter()
                    .position(|x| x.name == t.name && x.type_name == t.type_name)
                {
                    Some(i) => i,
                    None => {
                        topics.push(t);
                        topics.len() - 1
                    }
                };
                map.push(i);
            }
            messages.extend(contents.messages.into_iter().map(|mut m| {
                m.topic = map[m.topic];
                m
            }));
            unreadable += contents.unreadable;
            warnings.extend(
                contents
                    .unreadable_reasons
                    .into_iter()
                    .map(|r| format!("{}: {r}", path.display())),
            );
        }
        messages.sort_by_key(|m| m.time_ns);
        let bag = Self {
            dir: dir.to_path_buf(),
            info,
            kind,
            topics,
            messages,
            unreadable,
            warnings,
        };
        bag.check_against_metadata()
    }

    fn check_against_metadata(mut self) -> Result<Self, BagError> {
        let mut problems = Vec::new();
        let mut counts = vec![0u64; self.topics.len()];
        for m in &self.messages {
            counts[m.topic] += 1;
        }
        for tw in &self.info.topics_with_message_count {
            let t = &tw.topic_metadata;
            match self.topics.iter().position(|x| x.name == t.name) {
                None => problems.push(format!(
                    "topic {} ({}) is not in the storage",
                    t.name, t.type_name
                )),
                Some(i) => {
                    if self.topics[i].type_name != t.type_name {
                        problems.push(format!(
                            "topic {} has type {} in metadata.yaml but {} in the storage",
                            t.name, t.type_name, self.topics[i].type_name
                        ));
                    }
                    if counts[i] != tw.message_count {
                        problems.push(format!(
                            "topic {}: message_count {} in metadata.yaml, {} in the storage",
                            t.name, tw.message_count, counts[i]
                        ));
                    }
                    // Fill in what the storage left out (older bags).
                    if self.topics[i].type_hash.is_empty() {
                        self.topics[i].type_hash = t.type_description_hash.clone();
                    }
                    if self.topics[i].qos.is_empty() {
                        self.topics[i].qos =
                            t.offered_qos_profiles.profiles().map_err(|reason| {
                                BagError::Metadata {
                                    file: self.dir.join("metadata.yaml"),
                                    reason: format!("topic {}: {reason}", t.name),
                                }
                            })?;
                    }
                }
            }
        }
        for t in &self.topics {
            if !self
                .info
                .topics_with_message_count
                .iter()
                .any(|tw| tw.topic_metadata.name == t.name)
            {
                problems.push(format!(
                    "topic {} is in the storage but not in metadata.yaml",
                    t.name
                ));
            }
        }
        if self.messages.len() as u64 != self.info.message_count {
            problems.push(format!(
                "message_count {} in metadata.yaml, {} in the storage",
                self.info.message_count,
                self.messages.len()
            ));
        }
        if problems.is_empty() {
            return Ok(self);
        }
        if self.unreadable > 0 {
            // The unreadable messages explain (part of) the difference: play what is there.
            self.warnings.extend(problems);
            return Ok(self);
        }
        Err(BagError::Mismatch {
            dir: self.dir,
            what: problems.join("; "),
        })
    }
}

/// Writes a bag: creates the folder, adds topics, writes messages, and on
/// [`finish`](Self::finish) closes the storage and writes `metadata.yaml`.
#[derive(Debug)]
pub struct BagWriter {
    dir: PathBuf,
    kind: StorageKind,
    file_name: String,
    storage: StorageWriter,
    topics: Vec<(TopicInfo, u64)>,
    first_ns: Option<i64>,
    last_ns: i64,
}

impl BagWriter {
    /// Creates `dir` (which must not exist) and its storage file `<dir name>_0.<ext>`.
    pub fn create(dir: &Path, kind: StorageKind) -> Result<Self, BagError> {
        if dir.exists() {
            return Err(BagError::Exists {
                dir: dir.to_path_buf(),
            });
        }
        let name = dir
            .file_name()
            .and_then(|n| n.to_str())
            .filter(|n| !n.is_empty() && *n != "..")
            .ok_or_else(|| BagError::Metadata {
                file: dir.to_path_buf(),
                reason: "the bag folder needs a UTF-8 name".into(),
            })?;
        if let Some(parent) = dir.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent).map_err(io_err(parent))?;
        }
        std::fs::create_dir(dir).map_err(io_err(dir))?;
        let file_name = format!("{name}_0.{}", kind.extension());
        let storage = StorageWriter::create(kind, &dir.join(&file_name))?;
        Ok(Self {
            dir: dir.to_path_buf(),
            kind,
            file_name,
            storage,
            topics: Vec::new(),
            first_ns: None,
            last_ns: 0,
        })
    }

    /// Adds a topic and returns its index for [`write`](Self::write).
    pub fn add_topic(&mut self, topic: TopicInfo) -> Result<usize, BagError> {
        self.storage.add_topic(&topic)?;
        self.topics.push((topic, 0));
        Ok(self.topics.len() - 1)
    }

    /// Writes one message (CDR with its header) received at `time_ns` (ns since the epoch).
    pub fn write(&mut self, topic: usize, time_ns: i64, data: &[u8]) -> Result<(), BagError> {
        self.storage.write(topic, time_ns, data)?;
        if let Some((_, n)) = self.topics.get_mut(topic) {
            *n += 1;
        }
        self.first_ns = Some(self.first_ns.map_or(time_ns, |f| f.min(time_ns)));
        self.last_ns = self.last_ns.max(time_ns);
        Ok(())
    }

    /// Messages written so far.
    pub fn message_count(&self) -> u64 {
        self.topics.iter().map(|(_, n)| n).sum()
    }

    /// The metadata as it stands.
    pub fn info(&self) -> BagInfo {
        let start = self.first_ns.unwrap_or(0);
        let duration = Nanoseconds {
            nanoseconds: (self.last_ns - start).max(0) as u64,
        };
        let starting_time = StartingTime {
            nanoseconds_since_epoch: start,
        };
        let count = self.message_count();
        BagInfo {
            version: 9,
            storage_identifier: self.kind.id().to_string(),
            duration,
            starting_time,
            message_count: count,
            topics_with_message_count: self
                .topics
                .iter()
                .map(|(t, n)| TopicWithCount {
                    topic_metadata: TopicMetadata {
                        name: t.name.clone(),
                        type_name: t.type_name.clone(),
                        serialization_format: t.serialization_format.clone(),
                        offered_qos_profiles: QosProfiles::List(t.qos.clone()),
                        type_description_hash: t.type_hash.clone(),
                    },
                    message_count: *n,
                })
                .collect(),
            compression_format: String::new(),
            compression_mode: String::new(),
            relative_file_paths: vec![self.file_name.clone()],
            files: vec![FileInfo {
                path: self.file_name.clone(),
                starting_time,
                duration,
                message_count: count,
            }],
            custom_data: None,
            ros_distro: "jazzy".to_string(),
        }
    }

    /// Closes the storage (with its copy of the metadata) and writes `metadata.yaml`.
    pub fn finish(self) -> Result<BagInfo, BagError> {
        let info = self.info();
        let path = self.dir.join("metadata.yaml");
        self.storage.finish(to_yaml(&info, &path)?.trim_end())?;
        let text = to_yaml(
            &MetadataFile {
                rosbag2_bagfile_information: info.clone(),
            },
            &path,
        )?;
        let tmp = self.dir.join("metadata.yaml.tmp");
        std::fs::write(&tmp, text).map_err(io_err(&tmp))?;
        std::fs::rename(&tmp, &path).map_err(io_err(&path))?;
        Ok(info)
    }
}

/// YAML text of the metadata (`file` names it in the error).
fn to_yaml<T: serde::Serialize>(value: &T, file: &Path) -> Result<String, BagError> {
    serde_norway::to_string(value).map_err(|e| BagError::Metadata {
        file: file.to_path_buf(),
        reason: e.to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::metadata::BagQos;
    use super::*;

    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("biped-bag-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    fn topic(name: &str, type_name: &str) -> TopicInfo {
        TopicInfo {
            name: name.into(),
            type_name: type_name.into(),
            serialization_format: "cdr".into(),
            qos: vec![BagQos::reliable(7)],
            type_hash: biped_msgs::type_description::rihs01(type_name).unwrap(),
            definition: biped_msgs::type_description::ros2msg_definition(type_name).unwrap(),
        }
    }

    /// std_msgs/String "hi": header, length 3 (with the NUL), "hi\0".
    const HI: &[u8] = &[0, 1, 0, 0, 3, 0, 0, 0, b'h', b'i', 0, 0];

    /// A bag with two topics: /a (3 messages), /b (1), at 10, 20, 25 and 30 ns.
    fn write_bag(dir: &Path, kind: StorageKind) -> BagInfo {
        let mut w = BagWriter::create(dir, kind).unwrap();
        let a = w.add_topic(topic("/a", "std_msgs/msg/String")).unwrap();
        let b = w.add_topic(topic("/b", "geometry_msgs/msg/Twist")).unwrap();
        let twist = [[0u8, 1, 0, 0].as_slice(), &[0u8; 48]].concat();
        w.write(a, 10, HI).unwrap();
        w.write(a, 20, HI).unwrap();
        w.write(b, 25, &twist).unwrap();
        w.write(a, 30, HI).unwrap();
        w.finish().unwrap()
    }

    fn set_metadata(dir: &Path, from: &str, to: &str) {
        let p = dir.join("metadata.yaml");
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(text.contains(from), "{text}");
        std::fs::write(&p, text.replacen(from, to, 1)).unwrap();
    }

    #[test]
    fn a_written_bag_reads_back_with_its_topics_times_and_bytes() {
        for kind in [StorageKind::Mcap, StorageKind::Sqlite3] {
            let dir = tmp(&format!("roundtrip-{}", kind.id()));
            let info = write_bag(&dir, kind);
            assert_eq!(info.message_count, 4);
            assert_eq!(info.starting_time.nanoseconds_since_epoch, 10);
            assert_eq!(info.duration.nanoseconds, 20);
            assert_eq!(
                info.relative_file_paths,
                [format!(
                    "{}_0.{}",
                    dir.file_name().unwrap().to_str().unwrap(),
                    kind.extension()
                )]
            );
            let bag = Bag::open(&dir).unwrap();
            assert_eq!(bag.kind, kind);
            assert_eq!(
                bag.topics,
                [
                    topic("/a", "std_msgs/msg/String"),
                    topic("/b", "geometry_msgs/msg/Twist")
                ]
            );
            let got: Vec<_> = bag
                .messages
                .iter()
                .map(|m| (m.topic, m.time_ns, m.data.len()))
                .collect();
            assert_eq!(got, [(0, 10, 12), (0, 20, 12), (1, 25, 52), (0, 30, 12)]);
            assert_eq!(bag.messages[0].data, HI);
            assert_eq!(bag.unreadable, 0);
            std::fs::remove_dir_all(&dir).unwrap();
        }
    }

    #[test]
    fn an_existing_folder_is_not_overwritten() {
        let dir = tmp("exists");
        std::fs::create_dir_all(&dir).unwrap();
        let e = BagWriter::create(&dir, StorageKind::Mcap).unwrap_err();
        assert!(matches!(e, BagError::Exists { .. }), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_truncated_mcap_file_is_refused_as_truncated() {
        let dir = tmp("truncated");
        write_bag(&dir, StorageKind::Mcap);
        let file = dir.join(format!(
            "{}_0.mcap",
            dir.file_name().unwrap().to_str().unwrap()
        ));
        let bytes = std::fs::read(&file).unwrap();
        std::fs::write(&file, &bytes[..bytes.len() - 40]).unwrap();
        let e = Bag::open(&dir).unwrap_err();
        assert!(matches!(e, BagError::Storage { .. }), "{e}");
        assert!(e.to_string().contains("truncated"), "{e}");
        assert!(e.to_string().contains("_0.mcap"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn wrong_counts_in_metadata_are_named_with_both_numbers() {
        for kind in [StorageKind::Mcap, StorageKind::Sqlite3] {
            let dir = tmp(&format!("counts-{}", kind.id()));
            write_bag(&dir, kind);
            set_metadata(&dir, "message_count: 3", "message_count: 5");
            let e = Bag::open(&dir).unwrap_err();
            assert!(matches!(e, BagError::Mismatch { .. }), "{e}");
            assert!(
                e.to_string()
                    .contains("topic /a: message_count 5 in metadata.yaml, 3 in the storage"),
                "{e}"
            );
            std::fs::remove_dir_all(&dir).unwrap();
        }
    }

    #[test]
    fn an_unknown_storage_id_is_named() {
        let dir = tmp("storage-id");
        write_bag(&dir, StorageKind::Mcap);
        set_metadata(&dir, "storage_identifier: mcap", "storage_identifier: hdf5");
        let e = Bag::open(&dir).unwrap_err();
        assert!(
            matches!(&e, BagError::UnknownStorage { id, .. } if id == "hdf5"),
            "{e}"
        );
        assert!(e.to_string().contains("'hdf5'"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_missing_storage_file_and_a_compressed_bag_are_named() {
        let dir = tmp("missing-file");
        write_bag(&dir, StorageKind::Sqlite3);
        set_metadata(&dir, "compression_mode: ''", "compression_mode: file");
        let e = Bag::open(&dir).unwrap_err();
        assert!(
            matches!(&e, BagError::Compressed { mode, .. } if mode == "file"),
            "{e}"
        );
        set_metadata(&dir, "compression_mode: file", "compression_mode: ''");
        let file = dir.join(format!(
            "{}_0.db3",
            dir.file_name().unwrap().to_str().unwrap()
        ));
        std::fs::remove_file(&file).unwrap();
        let e = Bag::open(&dir).unwrap_err();
        assert!(
            matches!(&e, BagError::MissingFile { file: f } if *f == file),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn an_mcap_channel_without_its_schema_is_refused_naming_the_topic() {
        let dir = tmp("no-schema");
        write_bag(&dir, StorageKind::Mcap);
        let file = dir.join(format!(
            "{}_0.mcap",
            dir.file_name().unwrap().to_str().unwrap()
        ));
        // The same file, but /b's channel refers to a schema that was never written.
        std::fs::remove_file(&file).unwrap();
        let mut w = mcap::WriteOptions::new()
            .profile("ros2")
            .create(std::io::BufWriter::new(
                std::fs::File::create(&file).unwrap(),
            ))
            .unwrap();
        let s = w
            .add_schema("std_msgs/msg/String", "ros2msg", b"string data\n")
            .unwrap();
        let a = w.add_channel(s, "/a", "cdr", &Default::default()).unwrap();
        let b = w
            .add_channel_with_id(9, 0, "/b", "cdr", &Default::default())
            .unwrap();
        for (t, c) in [(10, a), (20, a), (25, b), (30, a)] {
            let h = mcap::records::MessageHeader {
                channel_id: c,
                sequence: 0,
                log_time: t,
                publish_time: t,
            };
            w.write_to_known_channel(&h, HI).unwrap();
        }
        w.finish().unwrap();
        drop(w);
        let e = Bag::open(&dir).unwrap_err();
        assert!(
            matches!(&e, BagError::MissingSchema { topic, .. } if topic == "/b"),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn broken_metadata_yaml_is_named() {
        let dir = tmp("bad-yaml");
        write_bag(&dir, StorageKind::Mcap);
        set_metadata(&dir, "version: 9", "version: nine");
        let e = Bag::open(&dir).unwrap_err();
        assert!(matches!(e, BagError::Metadata { .. }), "{e}");
        assert!(e.to_string().contains("metadata.yaml"), "{e}");
        let e = Bag::open(&dir.join("nowhere")).unwrap_err();
        assert!(matches!(e, BagError::NoMetadata { .. }), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
