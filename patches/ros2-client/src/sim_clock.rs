//! The simulated time a node keeps from `/clock`, stored by the thread that
//! receives each `/clock` sample (the participant's DDS event-loop thread)
//! instead of by the node's `Spinner` task.
//!
//! Every node subscribes `/clock` (its simulated time is updated
//! unconditionally; `use_sim_time` decides whether [`crate::Node::time_now`]
//! uses it). Taken by the spinner's task, each `/clock` sample (1 kHz from a
//! typical simulator) woke the thread running the spinner only to store one
//! value, also in a node that does nothing else with the clock. Here the
//! reader's waker is the store itself: RustDDS wakes a reader's waker from its
//! event loop when a sample arrives, and the waker takes every sample the
//! reader has and stores the newest, right there.

use std::{
  future::Future,
  pin::pin,
  sync::{
    Arc, Mutex,
    atomic::{AtomicBool, Ordering},
  },
  task::{Context, Poll, Wake, Waker},
};

#[allow(unused_imports)]
use log::{debug, error, info, trace, warn};

use crate::{builtin_interfaces, pubsub::Subscription, ros_time::ROSTime};

/// The `/clock` reader and where its samples go.
struct Shared {
  /// `None` once stopped.
  reader: Mutex<Option<Subscription<builtin_interfaces::Time>>>,
  sim_time: Arc<Mutex<ROSTime>>,
  /// A wake not yet answered: set by every wake, cleared by whoever drains.
  woken: AtomicBool,
}

impl Shared {
  /// Stores every sample the reader has, leaving this as the reader's waker.
  /// Never waits for another drain: a wake during one marks `woken`, and the
  /// drain in progress looks again before it lets go.
  fn drain(self: &Arc<Self>) {
    self.woken.store(true, Ordering::SeqCst);
    loop {
      let Ok(reader) = self.reader.try_lock() else {
        // Another thread drains; it sees `woken`.
        return;
      };
      match reader.as_ref() {
        Some(reader) => {
          let waker = Waker::from(Arc::clone(self));
          let mut cx = Context::from_waker(&waker);
          while self.woken.swap(false, Ordering::SeqCst) {
            // Until the reader has nothing: its stream stores `waker` before
            // it says so.
            while let Poll::Ready(sample) = pin!(reader.async_take()).as_mut().poll(&mut cx) {
              match sample {
                Ok((time, _info)) => *self.sim_time.lock().unwrap() = time.into(),
                Err(e) => warn!("Simulated clock receive error {e:?}"),
              }
            }
          }
        }
        None => self.woken.store(false, Ordering::SeqCst),
      }
      drop(reader);
      // A wake between the last look and the unlock found the lock taken and
      // left it to us.
      if !self.woken.load(Ordering::SeqCst) {
        return;
      }
    }
  }
}

impl Wake for Shared {
  fn wake(self: Arc<Self>) {
    self.drain();
  }
  fn wake_by_ref(self: &Arc<Self>) {
    self.drain();
  }
}

/// Keeps `sim_time` at the newest `/clock` sample from the thread that
/// receives it, until dropped.
pub(crate) struct SimClock {
  shared: Arc<Shared>,
}

impl SimClock {
  /// Takes what `reader` has now and stores what it gets from now on.
  pub(crate) fn start(
    reader: Subscription<builtin_interfaces::Time>,
    sim_time: Arc<Mutex<ROSTime>>,
  ) -> Self {
    let shared = Arc::new(Shared {
      reader: Mutex::new(Some(reader)),
      sim_time,
      woken: AtomicBool::new(false),
    });
    shared.drain();
    SimClock { shared }
  }
}

impl Drop for SimClock {
  fn drop(&mut self) {
    // The reader (which holds the waker, which holds this) goes: no cycle left.
    *self
      .shared
      .reader
      .lock()
      .unwrap_or_else(std::sync::PoisonError::into_inner) = None;
  }
}
