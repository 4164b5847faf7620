//! `biped record`: subscribe over DDS and write a rosbag2 bag, as `ros2 bag record` does.
//!
//! Topics are found by discovery: every 100 ms the publishers DDS has seen are scanned, and
//! a topic that was asked for (or any, with `all`) whose type we can describe (ours, or one
//! whose `.msg` file a ROS package installed under `AMENT_PREFIX_PATH`, as rosbag2 finds
//! them: [`TypeLibrary`]) is subscribed
//! with a QoS that matches its publishers and added to the bag with their offered QoS, its
//! RIHS01 hash and its definition. Messages are stamped with their receive time (system
//! clock, ns since the epoch). Stopping (the `stop` flag: Ctrl-C or SIGTERM, or the
//! duration) closes the storage and writes `metadata.yaml`, so an interrupted recording is
//! a complete bag.

use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::{Context, Result};
use biped_msgs::type_description::{TypeLibrary, ament_prefixes};
use ros2_client::dds::rustdds::DomainParticipant;

use super::BagWriter;
use super::dds::{RawReader, offered_qos, ros_topic_name, ros_type_name, subscription_qos};
use super::storage::{StorageKind, TopicInfo};

/// What to record.
#[derive(Debug, Clone)]
pub struct RecordOptions {
    /// The bag folder to create.
    pub dir: PathBuf,
    /// Topics to record (absolute names); empty with `all`.
    pub topics: Vec<String>,
    /// Record every topic whose type we know.
    pub all: bool,
    /// Stop after this long (s).
    pub duration_s: Option<f64>,
    /// MCAP or sqlite3.
    pub storage: StorageKind,
    /// Print progress every this many seconds (0: never).
    pub progress_period_s: f64,
}

/// What a recording wrote.
#[derive(Debug, Clone)]
pub struct RecordSummary {
    /// Messages per topic.
    pub counts: BTreeMap<String, u64>,
    /// All messages.
    pub total: u64,
    /// Wall time recorded (s).
    pub elapsed_s: f64,
    /// Topics seen but not recorded, with why.
    pub skipped: BTreeMap<String, String>,
}

/// Now, ns since the epoch.
pub fn now_ns() -> i64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| i64::try_from(d.as_nanos()).unwrap_or(i64::MAX))
        .unwrap_or(0)
}

struct Recorder {
    bag: BagWriter,
    /// Our types, and those read from `.msg` files under `prefixes`.
    types: TypeLibrary,
    /// `AMENT_PREFIX_PATH`: where ROS packages' `.msg` files are.
    prefixes: Vec<PathBuf>,
    readers: Vec<(usize, RawReader)>,
    subscribed: BTreeSet<String>,
    skipped: BTreeMap<String, String>,
}

impl Recorder {
    /// Subscribes to newly discovered topics that are wanted.
    fn discover(&mut self, dp: &DomainParticipant, opts: &RecordOptions) -> Result<()> {
        let mut offered: BTreeMap<(String, String), Vec<_>> = BTreeMap::new();
        for w in dp.discovered_writers() {
            let d = &w.publication_topic_data;
            let Some(topic) = ros_topic_name(&d.topic_name) else {
                continue;
            };
            if self.subscribed.contains(&topic) || self.skipped.contains_key(&topic) {
                continue;
            }
            if !opts.all && !opts.topics.contains(&topic) {
                continue;
            }
            let Some(type_name) = ros_type_name(&d.type_name) else {
                self.skip(
                    topic,
                    format!("DDS type '{}' is not a ROS message type", d.type_name),
                );
                continue;
            };
            offered
                .entry((topic, type_name))
                .or_default()
                .push(offered_qos(d));
        }
        for ((topic, type_name), qos) in offered {
            let described = if self.types.knows(&type_name) {
                Ok(())
            } else {
                self.types.add_from_prefixes(&type_name, &self.prefixes)
            };
            let (hash, definition) = match described.and_then(|()| {
                Ok((
                    self.types.rihs01(&type_name)?,
                    self.types.ros2msg_definition(&type_name)?,
                ))
            }) {
                Ok(d) => d,
                Err(e) => {
                    self.skip(topic, e.to_string());
                    continue;
                }
            };
            let reader = RawReader::new(dp, &topic, &type_name, &subscription_qos(&qos))
                .map_err(anyhow::Error::msg)
                .with_context(|| format!("subscribing to {topic}"))?;
            let index = self.bag.add_topic(TopicInfo {
                name: topic.clone(),
                type_name: type_name.clone(),
                serialization_format: "cdr".into(),
                qos,
                type_hash: hash,
                definition,
            })?;
            eprintln!("biped record: recording {topic} ({type_name})");
            self.readers.push((index, reader));
            self.subscribed.insert(topic);
        }
        Ok(())
    }

    fn skip(&mut self, topic: String, why: String) {
        eprintln!("biped record: not recording {topic}: {why}");
        self.skipped.insert(topic, why);
    }

    /// Writes every message waiting; returns how many.
    fn drain(&mut self) -> Result<usize> {
        let mut n = 0;
        for (index, reader) in &self.readers {
            while let Some(msg) = reader.take().map_err(anyhow::Error::msg)? {
                self.bag.write(*index, now_ns(), &msg.0)?;
                n += 1;
            }
        }
        Ok(n)
    }
}

/// Records until `stop` is set or the duration is over; the bag is closed either way.
pub fn record(
    dp: &DomainParticipant,
    opts: &RecordOptions,
    stop: &AtomicBool,
) -> Result<RecordSummary> {
    let bag = BagWriter::create(&opts.dir, opts.storage)?;
    let mut rec = Recorder {
        bag,
        types: TypeLibrary::new(),
        prefixes: ament_prefixes(),
        readers: Vec::new(),
        subscribed: BTreeSet::new(),
        skipped: BTreeMap::new(),
    };
    let start = Instant::now();
    let end = opts
        .duration_s
        .map(|s| start + Duration::from_secs_f64(s.max(0.0)));
    let mut next_scan = start;
    let mut next_progress = start + Duration::from_secs_f64(opts.progress_period_s.max(0.1));
    let mut last_count = 0u64;
    let result = (|| -> Result<()> {
        while !stop.load(Ordering::SeqCst) && end.is_none_or(|e| Instant::now() < e) {
            let now = Instant::now();
            if now >= next_scan {
                rec.discover(dp, opts)?;
                next_scan = now + Duration::from_millis(100);
            }
            if rec.drain()? == 0 {
                std::thread::sleep(Duration::from_micros(500));
            }
            if opts.progress_period_s > 0.0 && now >= next_progress {
                let count = rec.bag.message_count();
                eprintln!(
                    "biped record: {count} messages on {} topics, {:.0} msg/s, {:.1} s",
                    rec.readers.len(),
                    (count - last_count) as f64 / opts.progress_period_s,
                    start.elapsed().as_secs_f64()
                );
                last_count = count;
                next_progress = now + Duration::from_secs_f64(opts.progress_period_s);
            }
        }
        rec.drain()?;
        Ok(())
    })();
    // Close the bag whatever happened, so what was recorded stays readable.
    let info = rec.bag.finish()?;
    result?;
    let counts = info
        .topics_with_message_count
        .iter()
        .map(|t| (t.topic_metadata.name.clone(), t.message_count))
        .collect();
    for want in &opts.topics {
        if !rec.subscribed.contains(want) && !rec.skipped.contains_key(want) {
            rec.skipped
                .insert(want.clone(), "no publisher was seen".into());
        }
    }
    Ok(RecordSummary {
        counts,
        total: info.message_count,
        elapsed_s: start.elapsed().as_secs_f64(),
        skipped: rec.skipped,
    })
}

/// A recording running in a thread of its own (`biped walk --bag`), on its own DDS
/// participant.
#[derive(Debug)]
pub struct Background {
    stop: Arc<AtomicBool>,
    handle: std::thread::JoinHandle<Result<RecordSummary>>,
}

impl Background {
    /// Starts recording on `domain`; fails at once if the bag folder exists.
    pub fn start(
        opts: RecordOptions,
        domain: u16,
        range: node_runtime::DiscoveryRange,
    ) -> Result<Self> {
        if opts.dir.exists() {
            return Err(super::BagError::Exists {
                dir: opts.dir.clone(),
            }
            .into());
        }
        let context = node_runtime::context_for(domain, range)?;
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let handle = std::thread::Builder::new()
            .name("bag-record".into())
            .spawn(move || record(&context.domain_participant(), &opts, &flag))
            .context("starting the recording thread")?;
        Ok(Self { stop, handle })
    }

    /// Stops, closes the bag and returns what was recorded.
    pub fn finish(self) -> Result<RecordSummary> {
        self.stop.store(true, Ordering::SeqCst);
        self.handle
            .join()
            .map_err(|_| anyhow::anyhow!("the recording thread panicked"))?
    }
}
