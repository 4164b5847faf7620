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
        let meta_file = self.dir.join("metadata.yaml");
        let yaml = |v: &dyn erased::Yaml| {
            v.to_yaml().map_err(|reason| BagError::Metadata {
                file: meta_file.clone(),
                reason,
            })
        };
        let body = yaml(&info)?;
        self.storage.finish(body.trim_end())?;
        let text = yaml(&MetadataFile {
            rosbag2_bagfile_information: info.clone(),
        })?;
        let path = self.dir.join("metadata.yaml");
        let tmp = self.dir.join("metadata.yaml.tmp");
        std::fs::write(&tmp, text).map_err(io_err(&tmp))?;
        std::fs::rename(&tmp, &path).map_err(io_err(&path))?;
        Ok(info)
    }
}

mod erased {
    /// Serializes to YAML (one function for the two metadata shapes).
    pub trait Yaml {
        fn to_yaml(&self) -> Result<String, String>;
    }
    impl<T: serde::Serialize> Yaml for T {
        fn to_yaml(&self) -> Result<String, String> {
            serde_norway::to_string(self).map_err(|e| e.to_string())
        }
    }
}
