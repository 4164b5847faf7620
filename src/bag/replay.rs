//! `biped replay`: publish a bag's messages over DDS with their recorded timing and QoS, as
//! `ros2 bag play` does.
//!
//! Before anything is sent the bag is opened and checked ([`Bag::open`]) and every topic to
//! play is checked: CDR serialization, a type we know, and, when the bag carries a type
//! hash, the same hash as ours (a different hash means a different message layout: its
//! bytes would be misread, so the topic is refused). Then one writer per topic with the
//! first recorded QoS profile; optionally a wait for subscribers and a delay (DDS matching
//! takes a moment on both sides: messages sent before a subscriber has matched the writer
//! are lost to it). Message i is sent at start + (t_i − t_first) / rate. Messages that
//! cannot be sent (no CDR little-endian header) are skipped and counted.
//!
//! Joint commands replayed onto `/joint_commands` reach the joint bridge like live ones:
//! its limits, start-up ramp and watchdog apply.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use biped_msgs::type_description::TypeLibrary;
use ros2_client::dds::rustdds::DomainParticipant;

use super::Bag;
use super::dds::{RawCdr, RawWriter, qos_policies};
use super::metadata::BagQos;

/// What to play.
#[derive(Debug, Clone)]
pub struct ReplayOptions {
    /// The bag folder.
    pub dir: PathBuf,
    /// Speed factor (> 0).
    pub rate: f64,
    /// Play again from the start until stopped.
    pub repeat: bool,
    /// Only these topics (recorded names); empty = all.
    pub topics: Vec<String>,
    /// Skip this much of the bag's start (s).
    pub start_offset_s: f64,
    /// Topic renames: recorded name → published name.
    pub remaps: Vec<(String, String)>,
    /// Wait up to this long for every topic to have a subscriber (s; 0 = do not wait).
    pub wait_for_subscribers_s: f64,
    /// Then wait this long before the first message, and until discovery is quiet (s).
    pub delay_s: f64,
    /// Print progress every this many seconds (0: never).
    pub progress_period_s: f64,
}

/// What a replay sent.
#[derive(Debug, Clone, Default)]
pub struct ReplaySummary {
    /// Messages sent per published topic.
    pub sent: BTreeMap<String, u64>,
    /// Messages skipped as unreadable or unsendable (bag and replay).
    pub skipped: usize,
    /// Latest a message was sent after its due time (s).
    pub max_late_s: f64,
    /// Passes through the bag.
    pub passes: u32,
    /// Wall time (s).
    pub elapsed_s: f64,
}

/// How long the replay waits at its end for reliable subscribers to acknowledge every message
/// (it returns as soon as they have; rosbag2's `--wait-for-all-acked`).
const ACKED_WAIT: Duration = Duration::from_secs(5);

/// A checked topic to play.
struct Track {
    /// Published name.
    name: String,
    writer: RawWriter,
}

/// Refuses a topic we must not publish, naming why. A type that is not ours is described by
/// the definition the bag stores with it (added to `types`), so any type can be replayed
/// whose definition and hash agree.
fn check_topic(
    types: &mut TypeLibrary,
    name: &str,
    type_name: &str,
    format: &str,
    bag_hash: &str,
    definition: &str,
) -> Result<()> {
    if format != "cdr" {
        bail!("topic {name}: serialization format '{format}' is not cdr; cannot publish it");
    }
    if !types.knows(type_name) && !definition.is_empty() {
        types
            .add_ros2msg(type_name, definition)
            .with_context(|| format!("topic {name}: the bag's definition of {type_name}"))?;
    }
    let ours = types
        .rihs01(type_name)
        .with_context(|| format!("topic {name} cannot be published"))?;
    if !bag_hash.is_empty() && bag_hash != ours {
        bail!(
            "topic {name}: type {type_name} was recorded with a different definition \
             (hash {bag_hash}, ours {ours}); its bytes would be misread, so it is not published"
        );
    }
    Ok(())
}

/// Sleeps until `t` or until `stop`; false if stopped.
fn sleep_until(t: Instant, stop: &AtomicBool) -> bool {
    loop {
        if stop.load(Ordering::SeqCst) {
            return false;
        }
        let now = Instant::now();
        if now >= t {
            return true;
        }
        std::thread::sleep((t - now).min(Duration::from_millis(20)));
    }
}

/// After the delay, how long no subscriber may have come or gone before the first message.
const SUBSCRIBERS_QUIET_S: f64 = 1.0;
/// The delay is extended by at most this while subscribers keep coming.
const MAX_EXTENSION_S: f64 = 5.0;

/// Waits for subscribers before playing, printing each one that comes or goes: first, at
/// most `wait_s`, until every topic has one; then `delay_s`, extended (by at most
/// [`MAX_EXTENSION_S`]) until none has come or gone for [`SUBSCRIBERS_QUIET_S`].
///
/// Why: a message sent before a subscriber has matched the writer is lost to it (volatile
/// durability), and discovery is not instant: Fast DDS answers a new participant at once,
/// RustDDS participants (our nodes) were seen here 2 to 4 s after the writers appeared.
/// Returns false if stopped.
fn wait_for_subscribers(
    dp: &DomainParticipant,
    tracks: &BTreeMap<usize, Track>,
    wait_s: f64,
    delay_s: f64,
    stop: &AtomicBool,
) -> bool {
    let start = Instant::now();
    let count = || {
        tracks
            .values()
            .map(|t| t.writer.subscribers(dp))
            .collect::<Vec<_>>()
    };
    let mut counts = count();
    let mut changed = start;
    let poll = |counts: &mut Vec<usize>, changed: &mut Instant| {
        let c = count();
        for (t, (old, new)) in tracks.values().zip(counts.iter().zip(&c)) {
            if old != new {
                eprintln!(
                    "biped replay: {}: {new} subscriber{} ({:.2} s)",
                    t.name,
                    if *new == 1 { "" } else { "s" },
                    start.elapsed().as_secs_f64()
                );
                *changed = Instant::now();
            }
        }
        *counts = c;
    };
    let until = start + Duration::from_secs_f64(wait_s);
    while counts.contains(&0) && Instant::now() < until {
        if stop.load(Ordering::SeqCst) {
            return false;
        }
        std::thread::sleep(Duration::from_millis(20));
        poll(&mut counts, &mut changed);
    }
    if wait_s > 0.0 {
        for (t, _) in tracks.values().zip(&counts).filter(|(_, n)| **n == 0) {
            eprintln!(
                "biped replay: warning: no subscriber on {} after {wait_s} s; playing anyway",
                t.name
            );
        }
    }
    let delay_end = Instant::now() + Duration::from_secs_f64(delay_s);
    let hard_end = delay_end + Duration::from_secs_f64(MAX_EXTENSION_S);
    loop {
        if stop.load(Ordering::SeqCst) {
            return false;
        }
        let now = Instant::now();
        if now >= hard_end
            || (now >= delay_end
                && (now - changed).as_secs_f64() >= SUBSCRIBERS_QUIET_S.min(delay_s))
        {
            return true;
        }
        std::thread::sleep(Duration::from_millis(20));
        poll(&mut counts, &mut changed);
    }
}

/// Plays the bag until its end (or, with `repeat`, until `stop`).
pub fn replay(
    dp: &DomainParticipant,
    opts: &ReplayOptions,
    stop: &AtomicBool,
) -> Result<ReplaySummary> {
    if !(opts.rate.is_finite() && opts.rate > 0.0) {
        bail!("--rate must be a positive number, got {}", opts.rate);
    }
    if !(opts.start_offset_s.is_finite() && opts.start_offset_s >= 0.0) {
        bail!("--start-offset must be ≥ 0 s, got {}", opts.start_offset_s);
    }
    let bag = Bag::open(&opts.dir)?;
    eprintln!(
        "biped replay: {} ({}): {} messages on {} topics over {:.1} s",
        opts.dir.display(),
        bag.kind.id(),
        bag.messages.len(),
        bag.topics.len(),
        bag.info.duration.nanoseconds as f64 * 1e-9
    );
    for w in &bag.warnings {
        eprintln!("biped replay: warning: {w}");
    }
    for t in &opts.topics {
        if !bag.topics.iter().any(|b| &b.name == t) {
            let names: Vec<_> = bag.topics.iter().map(|b| b.name.as_str()).collect();
            bail!("topic {t} is not in the bag (it has {})", names.join(", "));
        }
    }
    for (from, _) in &opts.remaps {
        if !bag.topics.iter().any(|b| &b.name == from) {
            bail!("--remap {from}:=...: {from} is not a topic of the bag");
        }
    }
    // Topic index in the bag → track.
    let mut tracks: BTreeMap<usize, Track> = BTreeMap::new();
    let mut types = TypeLibrary::new();
    for (i, t) in bag.topics.iter().enumerate() {
        if !opts.topics.is_empty() && !opts.topics.contains(&t.name) {
            continue;
        }
        check_topic(
            &mut types,
            &t.name,
            &t.type_name,
            &t.serialization_format,
            &t.type_hash,
            &t.definition,
        )?;
        let name = opts
            .remaps
            .iter()
            .find(|(f, _)| f == &t.name)
            .map_or(t.name.clone(), |(_, to)| to.clone());
        let qos = t
            .qos
            .first()
            .cloned()
            .unwrap_or_else(|| BagQos::reliable(10));
        let writer = RawWriter::new(dp, &name, &t.type_name, &qos_policies(&qos))
            .map_err(anyhow::Error::msg)?;
        eprintln!("biped replay: {} → {name} ({})", t.name, t.type_name);
        tracks.insert(i, Track { name, writer });
    }
    let first_ns = bag.messages.first().map_or(0, |m| m.time_ns);
    let from_ns = first_ns.saturating_add((opts.start_offset_s * 1e9) as i64);
    let to_play: Vec<_> = bag
        .messages
        .iter()
        .filter(|m| m.time_ns >= from_ns && tracks.contains_key(&m.topic))
        .collect();
    if to_play.is_empty() {
        bail!("nothing to play: no message of the chosen topics after the start offset");
    }

    if !wait_for_subscribers(dp, &tracks, opts.wait_for_subscribers_s, opts.delay_s, stop) {
        return Ok(ReplaySummary::default());
    }

    let mut summary = ReplaySummary {
        skipped: bag.unreadable,
        ..Default::default()
    };
    let start = Instant::now();
    let mut next_progress = start + Duration::from_secs_f64(opts.progress_period_s.max(0.1));
    let t0 = to_play[0].time_ns;
    'passes: loop {
        let pass_start = Instant::now();
        summary.passes += 1;
        for m in &to_play {
            let due =
                pass_start + Duration::from_secs_f64((m.time_ns - t0) as f64 * 1e-9 / opts.rate);
            if !sleep_until(due, stop) {
                break 'passes;
            }
            summary.max_late_s = summary.max_late_s.max(due.elapsed().as_secs_f64());
            let Some(track) = tracks.get(&m.topic) else {
                continue;
            };
            match track.writer.write(RawCdr(m.data.clone())) {
                Ok(()) => *summary.sent.entry(track.name.clone()).or_insert(0) += 1,
                Err(e) => {
                    summary.skipped += 1;
                    eprintln!(
                        "biped replay: skipped a message on {} at {} ns: {e}",
                        track.name, m.time_ns
                    );
                }
            }
            if opts.progress_period_s > 0.0 && Instant::now() >= next_progress {
                let sent: u64 = summary.sent.values().sum();
                eprintln!(
                    "biped replay: {sent} messages sent, {:.0} msg/s, {:.1} s of {:.1} s",
                    sent as f64 / start.elapsed().as_secs_f64(),
                    (m.time_ns - t0) as f64 * 1e-9,
                    (to_play[to_play.len() - 1].time_ns - t0) as f64 * 1e-9
                );
                next_progress += Duration::from_secs_f64(opts.progress_period_s);
            }
        }
        if !opts.repeat || stop.load(Ordering::SeqCst) {
            break;
        }
    }
    // Let reliable writers deliver what is still in flight (repairs included) before they
    // are dropped: until every subscriber has acknowledged it, at most ACKED_WAIT (a fixed
    // 200 ms before lost the last messages' repairs to a subscriber slowed by a busy machine).
    if !stop.load(Ordering::SeqCst) {
        let deadline = Instant::now() + ACKED_WAIT;
        let unacknowledged: Vec<&str> = tracks
            .values()
            .filter(|t| {
                !t.writer
                    .wait_for_acknowledgments(deadline.saturating_duration_since(Instant::now()))
            })
            .map(|t| t.name.as_str())
            .collect();
        if !unacknowledged.is_empty() {
            eprintln!(
                "biped replay: after {} s a subscriber had still not acknowledged every message on {}",
                ACKED_WAIT.as_secs(),
                unacknowledged.join(", ")
            );
        }
    }
    summary.elapsed_s = start.elapsed().as_secs_f64();
    Ok(summary)
}
