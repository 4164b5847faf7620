//! The machine's floor under any DDS hop: a UDP datagram over loopback from one thread to
//! another and straight back (two wake-ups of a blocked thread, two `sendto`, two
//! `recvfrom`), at the pipeline bench's rates. A middleware hop cannot be cheaper than one
//! such wake-up; how much a hop costs above it is what the middleware adds.
//!
//! At each rate the sender sleeps to the next period, then times two round trips: the first
//! after the idle period (what every message of a 100 Hz stream meets), and a second one right
//! after it (warm: the same code, caches and CPU state just used).
//!
//! Then, at each rate again, a fixed piece of work with no wake-up in it after each idle
//! period: a pass over 512 KiB (what a DDS hop's threads touch is of that order), the same
//! instructions and memory every time. What its time varies by is the machine's, not the
//! code's: the floor under any tail (p99) a pipeline can have. "Stretches": runs of 5 or more
//! periods in a row whose work took over twice its median, the machine slow for a while.
//!
//! ```sh
//! cargo bench --bench wake_floor              # prints a Markdown table
//! cargo bench --bench wake_floor -- --n 3000  # messages per rate (default 2000)
//! cargo bench --bench wake_floor -- --cpu-dma-latency-us 0  # idle CPUs poll meanwhile
//! ```
//!
//! Nothing leaves the machine: both sockets are bound to 127.0.0.1. A benchmark, not a test.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::net::UdpSocket;
use std::process::ExitCode;
use std::time::{Duration, Instant};

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("wake_floor bench: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run() -> anyhow::Result<()> {
    let args = common::count_args(2000)?;
    let n = args.n;
    let here = UdpSocket::bind("127.0.0.1:0")?;
    let echo = UdpSocket::bind("127.0.0.1:0")?;
    let echo_addr = echo.local_addr()?;
    std::thread::Builder::new()
        .name("echo".into())
        .spawn(move || {
            let mut buf = [0u8; 512];
            while let Ok((len, from)) = echo.recv_from(&mut buf) {
                if echo.send_to(&buf[..len], from).is_err() {
                    break;
                }
            }
        })?;
    // A JointState of the pipeline's size.
    let payload = [0x5au8; 380];
    let mut buf = [0u8; 512];
    let mut round_trip = || -> anyhow::Result<f64> {
        let t = Instant::now();
        here.send_to(&payload, echo_addr)?;
        here.recv_from(&mut buf)?;
        Ok(t.elapsed().as_secs_f64() * 1e6)
    };
    println!("Measured {} on {}.", common::today(), common::machine());
    println!();
    println!(
        "| rate | round trips | after the idle period: median | p99 | right after it (warm): median | p99 |"
    );
    println!("|---|---:|---:|---:|---:|---:|");
    for rate_hz in [100.0, 1000.0] {
        let period = Duration::from_secs_f64(1.0 / rate_hz);
        let (mut cold, mut warm) = (Vec::with_capacity(n), Vec::with_capacity(n));
        // Warm-up: the first few include page faults and the echo thread's start.
        for _ in 0..20 {
            round_trip()?;
        }
        let mut next = Instant::now();
        for _ in 0..n {
            next += period;
            if let Some(wait) = next.checked_duration_since(Instant::now()) {
                std::thread::sleep(wait);
            }
            cold.push(round_trip()?);
            warm.push(round_trip()?);
        }
        let (c, w) = (quantiles(&mut cold), quantiles(&mut warm));
        println!(
            "| {rate_hz:.0} Hz | {n} | {:.1} µs | {:.1} µs | {:.1} µs | {:.1} µs |",
            c.0, c.1, w.0, w.1
        );
    }
    println!();
    println!(
        "| rate | periods | fixed work after the idle period: median | p99 | max | over 2 × median | stretches |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|");
    for rate_hz in [100.0, 1000.0] {
        let period = Duration::from_secs_f64(1.0 / rate_hz);
        let mut memory = vec![1u64; 64 * 1024];
        let mut times = Vec::with_capacity(n);
        for _ in 0..20 {
            fixed_work(&mut memory);
        }
        let mut next = Instant::now();
        for _ in 0..n {
            next += period;
            if let Some(wait) = next.checked_duration_since(Instant::now()) {
                std::thread::sleep(wait);
            }
            let t = Instant::now();
            std::hint::black_box(fixed_work(&mut memory));
            times.push(t.elapsed().as_secs_f64() * 1e6);
        }
        let mut sorted = times.clone();
        let (median, p99) = quantiles(&mut sorted);
        let slow: Vec<bool> = times.iter().map(|&t| t > 2.0 * median).collect();
        let stretches = slow.split(|&s| !s).filter(|run| run.len() >= 5).count();
        println!(
            "| {rate_hz:.0} Hz | {n} | {median:.1} µs | {p99:.1} µs | {:.1} µs | {:.1} % | {stretches} |",
            sorted.last().copied().unwrap_or(f64::NAN),
            100.0 * slow.iter().filter(|&&s| s).count() as f64 / n as f64,
        );
    }
    drop(args.latency);
    Ok(())
}

/// The same dependent chain over the same 512 KiB every time: a multiply-add per 8th word,
/// four passes (one cache line per step), written back.
fn fixed_work(memory: &mut [u64]) -> u64 {
    let mut acc = 0u64;
    for pass in 0..4 {
        for word in memory.iter_mut().skip(pass).step_by(8) {
            acc = acc
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(*word);
            *word = acc;
        }
    }
    acc
}

/// Median and 99th percentile.
fn quantiles(v: &mut [f64]) -> (f64, f64) {
    v.sort_by(f64::total_cmp);
    (common::percentile(v, 0.5), common::percentile(v, 0.99))
}
