//! Where a node's control ticks come from: the monotonic clock without drift, or `/clock`
//! under `use_sim_time` (lockstep with a simulator).

use biped_msgs::msg::{Clock, Time};

use crate::error::RosError;
use crate::node::RosNode;

/// Fixed-rate ticks on the monotonic clock, without drift: tick k is due at start + k·period.
#[derive(Debug)]
pub struct Ticker {
    start: std::time::Instant,
    period: std::time::Duration,
    k: u64,
}

impl Ticker {
    /// Ticks at `rate_hz`.
    pub fn new(rate_hz: f64) -> Self {
        Self {
            start: std::time::Instant::now(),
            period: std::time::Duration::from_secs_f64(1.0 / rate_hz),
            k: 0,
        }
    }
    /// Waits for the next tick and returns its index. A late tick is not made up for twice:
    /// after a stall the schedule restarts from now.
    pub async fn next(&mut self) -> u64 {
        let due = self.start + self.period * (self.k as u32);
        let now = std::time::Instant::now();
        if due > now {
            crate::wait::sleep_until(due).await;
        } else if now - due > self.period * 10 {
            self.start = now - self.period * (self.k as u32);
        }
        self.k += 1;
        self.k - 1
    }
}

/// One control tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tick {
    /// Tick index: the tick is due at k / rate (s) on the node's time line.
    pub k: u64,
    /// The simulated time of the tick, under `use_sim_time` (the `/clock` value it came
    /// from); `None` on the monotonic clock.
    pub sim_time: Option<Time>,
    /// The same `/clock` value again: the simulator, in lockstep, asks for this tick's
    /// output once more (a peer may have joined late). Republish, do not step.
    pub repeat: bool,
}

/// Where a node's control ticks come from: the monotonic clock, or `/clock` under
/// `use_sim_time`. On simulated time, tick k is the first `/clock` value at or after k / rate
/// (with the simulator publishing at the control rate, every `/clock` message is a tick), so
/// a node stepped by a lockstep simulator computes exactly what it would in real time.
pub enum TickSource {
    /// Monotonic clock.
    Wall(Ticker),
    /// `/clock` messages.
    Sim {
        /// The `/clock` subscription.
        clock: Box<crate::local::Subscription<Clock>>,
        /// Tick period (ns).
        period_ns: i64,
        /// The last tick's index and `/clock` value (ns).
        last: Option<(u64, i64)>,
        /// Ends a wait for `/clock` every 100 ms (one deadline kept across the waits).
        bound: crate::WaitBound,
    },
}

impl std::fmt::Debug for TickSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            TickSource::Wall(t) => f.debug_tuple("Wall").field(t).finish(),
            TickSource::Sim {
                period_ns, last, ..
            } => f
                .debug_struct("Sim")
                .field("period_ns", period_ns)
                .field("last", last)
                .finish(),
        }
    }
}

impl TickSource {
    /// Ticks at `rate_hz`, from `/clock` when the node has `use_sim_time`.
    pub fn new(ros: &mut RosNode, rate_hz: f64) -> Result<Self, RosError> {
        if ros.setup.use_sim_time() {
            Ok(TickSource::Sim {
                // Best effort: a `ros2 bag play --clock` or a simulator's best-effort clock
                // matches too.
                clock: Box::new(ros.best_effort_subscription::<Clock>("/clock")?),
                period_ns: (1e9 / rate_hz).round() as i64,
                last: None,
                bound: crate::WaitBound::every(std::time::Duration::from_millis(100)),
            })
        } else {
            Ok(TickSource::Wall(Ticker::new(rate_hz)))
        }
    }

    /// True on simulated time.
    pub fn simulated(&self) -> bool {
        matches!(self, TickSource::Sim { .. })
    }

    /// Waits for the next tick. `None` when 100 ms pass without one (on simulated time, when
    /// the clock stands still; at most 100 ms, one deadline kept across the waits), so the
    /// caller can check for shutdown.
    pub async fn next(&mut self) -> Option<Tick> {
        match self {
            TickSource::Wall(t) => Some(Tick {
                k: t.next().await,
                sim_time: None,
                repeat: false,
            }),
            TickSource::Sim {
                clock,
                period_ns,
                last,
                bound,
            } => {
                loop {
                    let Ok((msg, _)) = bound.within(clock.async_take()).await? else {
                        continue;
                    };
                    let ns = msg.clock.to_nanos();
                    if ns < 0 {
                        continue;
                    }
                    // Tick k is due at k·period; 1 µs of slack for clocks computed in floats.
                    let k = ((ns + 1_000) / *period_ns) as u64;
                    match *last {
                        Some((last_k, last_ns)) if ns == last_ns => {
                            return Some(Tick {
                                k: last_k,
                                sim_time: Some(msg.clock),
                                repeat: true,
                            });
                        }
                        // The clock went back (the simulation restarted): start over.
                        Some((_, last_ns)) if ns < last_ns => *last = None,
                        _ => {}
                    }
                    if last.is_none_or(|(last_k, _)| k > last_k) {
                        *last = Some((k, ns));
                        return Some(Tick {
                            k,
                            sim_time: Some(msg.clock),
                            repeat: false,
                        });
                    }
                }
            }
        }
    }
}
