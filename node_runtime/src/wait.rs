//! A bound on a loop's waits for its next message, kept across the waits.
//!
//! A node's loop waits for its next message but must look at its flags (a stop, a deadline)
//! now and then, so each wait races the message against a timeout. A fresh timer per wait
//! (`smol::Timer::after` in the race) registers with async-io's reactor on every wait that
//! blocks, and a registration notifies the reactor: an `eventfd` write per message, and a
//! wake-up of whichever thread waits in the reactor (often async-io's own, on the other CPU).
//! A [`WaitBound`] is one interval timer the loop keeps: it registers once, and again only
//! each time it fires, whatever the message rate.

use std::future::Future;
use std::time::{Duration, Instant};

use smol::Timer;
use smol::stream::StreamExt as _;

/// One interval timer a loop keeps across its waits, firing every `period`: a wait raced
/// against it ends, at the latest, at the timer's next firing (at most `period` after the
/// wait began, sooner when part of the period was spent before the wait).
#[derive(Debug)]
pub struct WaitBound {
    timer: Timer,
    period: Duration,
}

impl WaitBound {
    /// A bound that fires every `period`, the first time `period` from now.
    pub fn every(period: Duration) -> Self {
        Self {
            timer: Timer::interval(period),
            period,
        }
    }

    /// Waits for the timer's next firing and returns the instant it was due. A firing missed
    /// while nobody waited completes at once; after a stall of more than a period the timer
    /// restarts from now, rather than firing once for every period missed.
    pub async fn fired(&mut self) -> Instant {
        let now = Instant::now;
        // An interval timer's stream never ends.
        let due = self.timer.next().await.unwrap_or_else(now);
        if due + self.period <= now() {
            self.timer.set_interval(self.period);
        }
        due
    }

    /// `next`'s output, or `None` if the timer fires first. `next` is polled first: one that
    /// is ready wins over a due firing.
    pub async fn within<T>(&mut self, next: impl Future<Output = T>) -> Option<T> {
        use smol::future::FutureExt as _;
        async { Some(next.await) }
            .or(async {
                self.fired().await;
                None
            })
            .await
    }
}

/// Runs `future` on this thread to its end, the thread parked between its wake-ups: how a
/// node's thread waits for its messages. (`smol::block_on` instead waits in async-io's
/// reactor when it can take it: `epoll_wait`, its timer and notifier, five system calls a
/// wait, and each wake-up from a DDS thread then writes the reactor's `eventfd`. Parked,
/// a wait and its wake-up are a futex call each. Timers still work: async-io's own thread
/// runs the reactor, and with [`WaitBound`]s instead of a timer per wait it is rarely woken.)
pub fn block_on<T>(future: impl Future<Output = T>) -> T {
    smol::future::block_on(future)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ready_message_wins_over_a_due_firing() {
        smol::block_on(async {
            let mut bound = WaitBound::every(Duration::from_millis(1));
            std::thread::sleep(Duration::from_millis(5));
            // The timer is due, the message too: the message comes first.
            assert_eq!(bound.within(async { 7 }).await, Some(7));
        });
    }

    #[test]
    fn a_wait_for_nothing_ends_when_the_timer_fires() {
        smol::block_on(async {
            let period = Duration::from_millis(20);
            let start = Instant::now();
            let mut bound = WaitBound::every(period);
            assert_eq!(bound.within(std::future::pending::<u8>()).await, None);
            // Not before its time (a lower bound holds on a busy machine, an upper one not).
            assert!(
                start.elapsed() >= period,
                "ended after {:?}",
                start.elapsed()
            );
        });
    }

    #[test]
    fn waits_that_a_message_ended_do_not_restart_the_timer() {
        smol::block_on(async {
            let period = Duration::from_millis(40);
            let mut bound = WaitBound::every(period);
            let made = Instant::now();
            for i in 0..5 {
                let msg = async {
                    Timer::after(Duration::from_millis(5)).await;
                    i
                };
                assert_eq!(bound.within(msg).await, Some(i));
            }
            // The first firing is still the one due a period after the bound was made, not a
            // period after the last wait began (at least 25 ms later): one timer, kept.
            let due = bound.fired().await;
            assert!(
                due <= made + period,
                "due {:?} after it was made",
                due - made
            );
        });
    }

    #[test]
    fn after_a_stall_the_timer_restarts_instead_of_firing_for_every_period_missed() {
        smol::block_on(async {
            let period = Duration::from_millis(10);
            let mut bound = WaitBound::every(period);
            std::thread::sleep(5 * period);
            let after_stall = Instant::now();
            // The missed firing completes at once...
            let missed = bound.fired().await;
            assert!(missed < after_stall);
            // ...and the next is a period after the restart, not the four that were missed.
            let next = bound.fired().await;
            assert!(
                next >= after_stall + period,
                "due {:?} after the stall",
                next.saturating_duration_since(after_stall)
            );
        });
    }
}
