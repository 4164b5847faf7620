//! How a node's thread waits: parked on a futex between wake-ups ([`block_on`]), with its
//! deadlines kept by itself ([`sleep_until`], [`WaitBound`]) rather than by async-io's
//! reactor.
//!
//! A node's loop waits for its next message but must look at its flags (a stop, a deadline)
//! now and then, so each wait races the message against a timeout. A fresh async-io timer
//! per wait (`smol::Timer::after` in the race) registers with async-io's reactor on every
//! wait that blocks, and a registration notifies the reactor: an `eventfd` write per
//! message, and a wake-up of whichever thread waits in it (often async-io's own, on the
//! other CPU). And `smol::block_on` waits in that reactor itself (`epoll_wait`, its timer and
//! notifier: five system calls a wait), so each wake-up from a DDS thread writes an
//! `eventfd`. Here a wait is one futex call, a wake-up another, and a deadline is the
//! futex wait's timeout: no other thread is involved.

use std::cell::RefCell;
use std::future::Future;
use std::pin::{Pin, pin};
use std::sync::Arc;
use std::task::{Context, Poll, Wake, Waker};
use std::time::{Duration, Instant};

thread_local! {
    /// The deadlines of the futures waiting in this thread's [`block_on`] (`None` when the
    /// thread runs none): each with the waker to wake when it is due.
    static DEADLINES: RefCell<Option<Vec<(Instant, Waker)>>> = const { RefCell::new(None) };
}

/// Wakes a thread parked in [`block_on`].
struct ThreadWaker(std::thread::Thread);

impl Wake for ThreadWaker {
    fn wake(self: Arc<Self>) {
        self.0.unpark();
    }
    fn wake_by_ref(self: &Arc<Self>) {
        self.0.unpark();
    }
}

/// Puts back the thread's deadlines as they were before a [`block_on`] (however it ends).
struct RestoreDeadlines(Option<Vec<(Instant, Waker)>>);

impl Drop for RestoreDeadlines {
    fn drop(&mut self) {
        let outer = self.0.take();
        DEADLINES.with(|d| *d.borrow_mut() = outer);
    }
}

/// Runs `future` on this thread to its end: the thread parks (a futex wait) until a waker
/// wakes it or the earliest [`sleep_until`] deadline of the futures it runs is due.
/// async-io's timers (`smol::Timer`) work too, through async-io's own thread.
pub fn block_on<T>(future: impl Future<Output = T>) -> T {
    let mut future = pin!(future);
    let waker = Waker::from(Arc::new(ThreadWaker(std::thread::current())));
    let mut cx = Context::from_waker(&waker);
    let _restore = RestoreDeadlines(DEADLINES.with(|d| d.borrow_mut().replace(Vec::new())));
    loop {
        if let Poll::Ready(out) = future.as_mut().poll(&mut cx) {
            return out;
        }
        // Wake what is due (outside the borrow: a waker may be anything), else park until
        // the earliest deadline left, or until woken.
        let now = Instant::now();
        let (due, next) = DEADLINES.with(|d| {
            let mut d = d.borrow_mut();
            let list = d.get_or_insert_with(Vec::new);
            // (Allocates only when something is due.)
            let due: Vec<_> = list.extract_if(.., |(t, _)| *t <= now).collect();
            (due, list.iter().map(|(t, _)| *t).min())
        });
        if !due.is_empty() {
            for (_, w) in due {
                w.wake();
            }
            continue;
        }
        match next {
            Some(t) => std::thread::park_timeout(t.saturating_duration_since(now)),
            None => std::thread::park(),
        }
    }
}

/// Completes at `due`. In this module's [`block_on`] the deadline is the parked thread's
/// own timeout; anywhere else an async-io timer.
pub fn sleep_until(due: Instant) -> Sleep {
    Sleep {
        due,
        fallback: None,
    }
}

/// The future of [`sleep_until`].
#[derive(Debug)]
pub struct Sleep {
    due: Instant,
    fallback: Option<smol::Timer>,
}

impl Future for Sleep {
    type Output = ();

    fn poll(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<()> {
        let due = self.due;
        if Instant::now() >= due {
            return Poll::Ready(());
        }
        let kept = DEADLINES.with(|d| match d.borrow_mut().as_mut() {
            Some(list) => {
                // One entry per deadline and task: a loop that makes a new `Sleep` for the
                // same deadline each time it waits (raced against a message) adds nothing.
                if !list
                    .iter()
                    .any(|(t, w)| *t == due && w.will_wake(cx.waker()))
                {
                    list.push((due, cx.waker().clone()));
                }
                true
            }
            None => false,
        });
        if kept {
            return Poll::Pending;
        }
        let timer = self.fallback.get_or_insert_with(|| smol::Timer::at(due));
        Pin::new(timer).poll(cx).map(|_| ())
    }
}

/// A bound on a loop's waits for its next message, kept across the waits: a deadline every
/// `period`. A wait raced against it ends, at the latest, at the next deadline (at most
/// `period` after the wait began, sooner when part of the period was spent before it).
#[derive(Debug)]
pub struct WaitBound {
    next: Instant,
    period: Duration,
}

impl WaitBound {
    /// A bound that fires every `period`, the first time `period` from now.
    pub fn every(period: Duration) -> Self {
        Self {
            next: Instant::now() + period,
            period,
        }
    }

    /// Waits for the next deadline and returns it. A deadline missed while nobody waited
    /// completes at once; after a stall of more than a period the bound restarts from now,
    /// rather than firing once for every period missed.
    pub async fn fired(&mut self) -> Instant {
        sleep_until(self.next).await;
        let due = self.next;
        let now = Instant::now();
        self.next = if due + self.period <= now {
            now + self.period
        } else {
            due + self.period
        };
        due
    }

    /// `next`'s output, or `None` if the bound fires first. `next` is polled first: one that
    /// is ready wins over a due deadline.
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ready_message_wins_over_a_due_deadline() {
        block_on(async {
            let mut bound = WaitBound::every(Duration::from_millis(1));
            std::thread::sleep(Duration::from_millis(5));
            // The deadline is due, the message too: the message comes first.
            assert_eq!(bound.within(async { 7 }).await, Some(7));
        });
    }

    #[test]
    fn a_wait_for_nothing_ends_at_the_deadline() {
        let period = Duration::from_millis(20);
        let start = Instant::now();
        let ended = block_on(async {
            let mut bound = WaitBound::every(period);
            bound.within(std::future::pending::<u8>()).await
        });
        assert_eq!(ended, None);
        // Not before its time (a lower bound holds on a busy machine, an upper one not).
        assert!(
            start.elapsed() >= period,
            "ended after {:?}",
            start.elapsed()
        );
    }

    #[test]
    fn waits_that_a_message_ended_do_not_move_the_deadline() {
        let period = Duration::from_secs(3600);
        block_on(async {
            let before = Instant::now();
            let mut bound = WaitBound::every(period);
            let after = Instant::now();
            for i in 0..5 {
                // Pending at first (the bound's deadline is then registered), then ready.
                let msg = async {
                    smol::future::yield_now().await;
                    i
                };
                assert_eq!(bound.within(msg).await, Some(i));
            }
            // The deadline is still the one a period after the bound was made (a fresh
            // deadline per wait would have moved it to a period after the last wait).
            assert!(bound.next >= before + period && bound.next <= after + period);
        });
    }

    #[test]
    fn after_a_stall_the_bound_restarts_instead_of_firing_for_every_period_missed() {
        let period = Duration::from_millis(10);
        block_on(async {
            let mut bound = WaitBound::every(period);
            std::thread::sleep(5 * period);
            let after_stall = Instant::now();
            // The missed deadline completes at once...
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

    #[test]
    fn in_block_on_a_deadline_is_the_threads_own_not_an_async_io_timer() {
        block_on(async {
            let due = Instant::now() + Duration::from_secs(3600);
            let mut sleep = sleep_until(due);
            let waker = Waker::noop();
            assert!(
                Pin::new(&mut sleep)
                    .poll(&mut Context::from_waker(waker))
                    .is_pending()
            );
            assert!(sleep.fallback.is_none());
            // Polled again by the same task, the deadline is kept once.
            assert!(
                Pin::new(&mut sleep)
                    .poll(&mut Context::from_waker(waker))
                    .is_pending()
            );
            let kept = DEADLINES.with(|d| {
                d.borrow()
                    .as_ref()
                    .map(|l| l.iter().filter(|(t, _)| *t == due).count())
            });
            assert_eq!(kept, Some(1));
        });
        // Outside, the thread keeps no deadlines.
        assert!(DEADLINES.with(|d| d.borrow().is_none()));
    }

    #[test]
    fn tasks_sleeping_to_different_deadlines_each_wake_no_sooner_than_theirs() {
        let start = Instant::now();
        let ex = smol::LocalExecutor::new();
        let order = std::rc::Rc::new(RefCell::new(Vec::new()));
        let tasks: Vec<_> = [30u64, 10, 20]
            .into_iter()
            .map(|ms| {
                let order = order.clone();
                ex.spawn(async move {
                    sleep_until(start + Duration::from_millis(ms)).await;
                    order.borrow_mut().push((ms, start.elapsed()));
                })
            })
            .collect();
        block_on(ex.run(async {
            for t in tasks {
                t.await;
            }
        }));
        // Each woke, none before its deadline (their order is the clock's: a stalled
        // machine may find all three due at once).
        let order = order.borrow();
        assert_eq!(order.len(), 3);
        for (ms, at) in order.iter() {
            assert!(*at >= Duration::from_millis(*ms), "{ms} ms woke at {at:?}");
        }
    }

    #[test]
    fn outside_block_on_a_sleep_is_an_async_io_timer() {
        // Polled where no block_on of this module runs, the deadline is an async-io timer...
        let mut sleep = sleep_until(Instant::now() + Duration::from_secs(3600));
        assert!(
            Pin::new(&mut sleep)
                .poll(&mut Context::from_waker(Waker::noop()))
                .is_pending()
        );
        assert!(sleep.fallback.is_some());
        assert!(DEADLINES.with(|d| d.borrow().is_none()));
        // ...which completes, not before its time, in another executor.
        let due = Instant::now() + Duration::from_millis(10);
        smol::block_on(sleep_until(due));
        assert!(Instant::now() >= due);
    }
}
