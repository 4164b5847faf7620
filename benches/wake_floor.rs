//! The machine's floor under any DDS hop: a UDP datagram over loopback from one thread to
//! another and straight back (two wake-ups of a blocked thread, two `sendto`, two
//! `recvfrom`), at the pipeline bench's rates. A middleware hop cannot be cheaper than one
//! such wake-up; how much a hop costs above it is what the middleware adds.
//!
//! At each rate the sender sleeps to the next period, then times two round trips: the first
//! after the idle period (what every message of a 100 Hz stream meets), and a second one right
//! after it (warm: the same code, caches and CPU state just used).
//!
//! ```sh
//! cargo bench --bench wake_floor              # prints a Markdown table
//! cargo bench --bench wake_floor -- --n 3000  # messages per rate (default 2000)
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
    let n = common::count_arg(2000)?;
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
    Ok(())
}

/// Median and 99th percentile.
fn quantiles(v: &mut [f64]) -> (f64, f64) {
    v.sort_by(f64::total_cmp);
    (common::percentile(v, 0.5), common::percentile(v, 0.99))
}
