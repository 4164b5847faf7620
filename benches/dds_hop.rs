//! One bare RustDDS hop: a DataWriter on one DomainParticipant to a DataReader on another
//! (each participant with its own event loop thread, as two processes would have), reliable,
//! keep last 10, a 380-byte sample (a joint command's size), at 100 Hz and 1 kHz. No
//! ros2-client, no node, no relay: what RustDDS itself costs per hop, to set beside the
//! machine's floor (`cargo bench --bench wake_floor`) and the pipeline's two hops through the
//! ik_solver node (`cargo bench --bench pipeline`).
//!
//! Latency = the reader's task taking the sample − the send time in the sample, on one clock
//! (`Instant` since the start); lost = sent − taken.
//!
//! ```sh
//! cargo bench --bench dds_hop              # prints a Markdown table
//! cargo bench --bench dds_hop -- --n 3000  # samples per rate (default 2000)
//! cargo bench --bench dds_hop -- --cpu-dma-latency-us 0  # idle CPUs poll meanwhile
//! ```
//!
//! Nothing leaves the machine: the process re-executes itself in a private network namespace
//! with only loopback (`unshare -n`, root), ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::process::ExitCode;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::{Context as _, anyhow};
use ros2_client::dds::rustdds::{
    self, CDRDeserializerAdapter, CDRSerializerAdapter, DomainParticipant, QosPolicyBuilder,
    TopicKind, policy,
};
use serde::{Deserialize, Serialize};
use smol::stream::StreamExt as _;

/// Our own DDS domain (the namespace is private anyway).
const DOMAIN_ID: u16 = 96;

#[derive(Debug, Clone, Serialize, Deserialize)]
struct Sample {
    /// Send time, ns since the bench's start.
    sent_ns: u64,
    /// Sequence number.
    seq: u64,
    payload: Vec<u8>,
}

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("dds_hop bench: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run() -> anyhow::Result<()> {
    let args = common::count_args(2000)?;
    let n = args.n;
    if !common::in_netns() {
        return common::reexec_in_netns(&DOMAIN_ID.to_string());
    }
    common::check_only_loopback()?;

    let qos = QosPolicyBuilder::new()
        .reliability(policy::Reliability::Reliable {
            max_blocking_time: rustdds::Duration::from_millis(100),
        })
        .history(policy::History::KeepLast { depth: 10 })
        .durability(policy::Durability::Volatile)
        .build();
    let dds = |what: &str, e: String| anyhow!("{what}: {e}");
    let writer_side =
        DomainParticipant::new(DOMAIN_ID).map_err(|e| dds("participant", e.to_string()))?;
    let reader_side =
        DomainParticipant::new(DOMAIN_ID).map_err(|e| dds("participant", e.to_string()))?;
    let topic = |p: &DomainParticipant| {
        p.create_topic(
            "dds_hop".to_string(),
            "biped::DdsHopSample".to_string(),
            &qos,
            TopicKind::NoKey,
        )
        .map_err(|e| dds("topic", e.to_string()))
    };
    let writer = writer_side
        .create_publisher(&qos)
        .map_err(|e| dds("publisher", e.to_string()))?
        .create_datawriter_no_key::<Sample, CDRSerializerAdapter<Sample>>(
            &topic(&writer_side)?,
            None,
        )
        .map_err(|e| dds("writer", e.to_string()))?;
    let reader = reader_side
        .create_subscriber(&qos)
        .map_err(|e| dds("subscriber", e.to_string()))?
        .create_datareader_no_key::<Sample, CDRDeserializerAdapter<Sample>>(
            &topic(&reader_side)?,
            None,
        )
        .map_err(|e| dds("reader", e.to_string()))?;

    let start = Instant::now();
    let (tx, rx) = mpsc::channel::<(u64, u64)>();
    std::thread::Builder::new()
        .name("reader".into())
        .spawn(move || {
            smol::block_on(async {
                let mut stream = reader.async_sample_stream();
                while let Some(s) = stream.next().await {
                    let Ok(s) = s else { continue };
                    let now = start.elapsed().as_nanos() as u64;
                    let v = s.into_value();
                    if tx.send((v.seq, now.saturating_sub(v.sent_ns))).is_err() {
                        break;
                    }
                }
            });
        })
        .context("reader thread")?;

    // Discovery: send until the first sample comes back.
    let payload = vec![0x5au8; 380 - 24];
    let deadline = Instant::now() + Duration::from_secs(20);
    let mut seq = 0u64;
    loop {
        let sent_ns = start.elapsed().as_nanos() as u64;
        let _ = writer.write(
            Sample {
                sent_ns,
                seq,
                payload: payload.clone(),
            },
            None,
        );
        seq += 1;
        if rx.recv_timeout(Duration::from_millis(100)).is_ok() {
            break;
        }
        anyhow::ensure!(
            Instant::now() < deadline,
            "the reader saw nothing within 20 s"
        );
    }
    println!(
        "Measured on {} (RustDDS {}).",
        common::machine(),
        common::lock_version(std::path::Path::new(env!("CARGO_MANIFEST_DIR")), "rustdds")
    );
    println!();
    println!("| rate | samples | median | p99 | max | lost |");
    println!("|---|---:|---:|---:|---:|---:|");
    for rate_hz in [100.0, 1000.0] {
        // Warm-up, then the counted run.
        for (count, counted) in [((rate_hz * 0.5) as usize, false), (n, true)] {
            while rx.try_recv().is_ok() {}
            let first = seq;
            let period = Duration::from_secs_f64(1.0 / rate_hz);
            let mut next = Instant::now();
            for _ in 0..count {
                next += period;
                if let Some(wait) = next.checked_duration_since(Instant::now()) {
                    std::thread::sleep(wait);
                }
                let sent_ns = start.elapsed().as_nanos() as u64;
                writer
                    .write(
                        Sample {
                            sent_ns,
                            seq,
                            payload: payload.clone(),
                        },
                        None,
                    )
                    .map_err(|e| anyhow!("write: {e:?}"))?;
                seq += 1;
            }
            std::thread::sleep(Duration::from_millis(200));
            let mut lat: Vec<f64> = rx
                .try_iter()
                .filter(|(s, _)| *s >= first)
                .map(|(_, ns)| ns as f64 * 1e-3)
                .collect();
            if counted {
                let got = lat.len();
                lat.sort_by(f64::total_cmp);
                let at = |q: f64| common::percentile(&lat, q);
                println!(
                    "| {rate_hz:.0} Hz | {count} | {:.1} µs | {:.1} µs | {:.1} µs | {} |",
                    at(0.5),
                    at(0.99),
                    at(1.0),
                    count.saturating_sub(got)
                );
            }
        }
    }
    Ok(())
}
