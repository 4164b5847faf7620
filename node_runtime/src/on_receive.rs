//! A subscription whose messages are handled on the thread that receives them: the node's
//! DDS participant's event-loop thread, the way a Fast DDS listener's `on_data_available`
//! runs, instead of that thread waking the node's own thread to take them.
//!
//! A message that reaches a node's thread pays two thread wake-ups: the kernel wakes the DDS
//! thread for the datagram, and the DDS thread wakes the node's thread (RustDDS wakes a
//! reader's task through its `Waker`). Here the waker is the handler: it takes what the
//! reader has and runs `handler` on each message right there, so a message costs one
//! wake-up. On a machine where a wake-up across CPUs costs more than the work (a virtual
//! machine whose idle vCPU halts: BENCHMARKS.md, "Where a DDS hop's time goes"), that is
//! most of a hop.
//!
//! What it asks of the handler: to be short and never to wait. While it runs, its
//! participant's DDS thread does nothing else (no other reader's data, no acknowledgement,
//! no heartbeat). A reliable publish from it is fine while the publisher's send window has
//! room (RustDDS sends a fresh sample from the writing thread); a full window makes the
//! publish wait for acknowledgements this very thread would process, so it fails after the
//! publisher's blocking time instead (its error is the handler's to report). A panic in the
//! handler is caught: the handler is dropped, no message is handled any more, and
//! [`OnReceive::failed`] says so, for the node's thread to report and end.
//!
//! Not for nodes composed in one process: their in-process messages come through the bus,
//! which has no DDS thread ([`crate::Subscription::on_receive`] refuses it).

use std::future::Future;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::pin::pin;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::task::{Context, Poll, Wake, Waker};

use ros2_client::{MessageInfo, ReadResult};

use crate::local::RosMessageBound;

/// What a handler is given: the message and its metadata, or why it could not be read.
pub type Received<M> = ReadResult<(M, MessageInfo)>;

/// The subscription and its handler, while handling is on.
type Handling<M> = (
    ros2_client::Subscription<M>,
    Box<dyn FnMut(Received<M>) + Send>,
);

/// Shared by the node (its [`OnReceive`]) and the reader (as its waker).
struct Shared<M: RosMessageBound> {
    /// `None` once stopped, or after the handler panicked.
    handling: Mutex<Option<Handling<M>>>,
    /// A wake not yet answered: set by every wake, cleared by whoever drains.
    woken: AtomicBool,
    /// The handler panicked.
    panicked: AtomicBool,
}

impl<M: RosMessageBound> Shared<M> {
    /// Takes every message the reader has, handing each to the handler, and leaves this as
    /// the reader's waker. Never waits for another drain: a wake during one marks `woken`,
    /// and the drain in progress looks again before it lets go (so no message waits for the
    /// next one's wake).
    fn drain(self: &Arc<Self>) {
        self.woken.store(true, Ordering::SeqCst);
        loop {
            let Ok(mut handling) = self.handling.try_lock() else {
                // Another thread drains; it sees `woken`.
                return;
            };
            if let Some((subscription, handler)) = handling.as_mut() {
                let waker = Waker::from(Arc::clone(self));
                let mut cx = Context::from_waker(&waker);
                while self.woken.swap(false, Ordering::SeqCst) {
                    // Until the reader has nothing: its stream stores `waker` before it says
                    // so, and looks once more after storing it.
                    loop {
                        let next = pin!(subscription.async_take()).as_mut().poll(&mut cx);
                        let Poll::Ready(received) = next else { break };
                        if catch_unwind(AssertUnwindSafe(|| handler(received))).is_err() {
                            self.panicked.store(true, Ordering::SeqCst);
                            *handling = None;
                            return;
                        }
                    }
                }
            } else {
                self.woken.store(false, Ordering::SeqCst);
            }
            drop(handling);
            // A wake between the last look and the unlock found the lock taken and left it
            // to us.
            if !self.woken.load(Ordering::SeqCst) {
                return;
            }
        }
    }
}

impl<M: RosMessageBound> Wake for Shared<M> {
    fn wake(self: Arc<Self>) {
        self.drain();
    }
    fn wake_by_ref(self: &Arc<Self>) {
        self.drain();
    }
}

/// A subscription handled on its DDS thread ([`crate::Subscription::on_receive`]); handling
/// stops when this is dropped (after a handler call in progress has returned).
pub struct OnReceive<M: RosMessageBound> {
    shared: Arc<Shared<M>>,
}

impl<M: RosMessageBound> std::fmt::Debug for OnReceive<M> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OnReceive")
            .field("type", &M::message_type_name())
            .field("failed", &self.failed())
            .finish()
    }
}

impl<M: RosMessageBound> OnReceive<M> {
    pub(crate) fn start(
        subscription: ros2_client::Subscription<M>,
        handler: Box<dyn FnMut(Received<M>) + Send>,
    ) -> Self {
        let shared = Arc::new(Shared {
            handling: Mutex::new(Some((subscription, handler))),
            woken: AtomicBool::new(false),
            panicked: AtomicBool::new(false),
        });
        // What arrived before, and the waker in place for what comes next.
        shared.drain();
        Self { shared }
    }

    /// The handler panicked: nothing is handled any more.
    pub fn failed(&self) -> bool {
        self.shared.panicked.load(Ordering::SeqCst)
    }
}

impl<M: RosMessageBound> Drop for OnReceive<M> {
    fn drop(&mut self) {
        // Waits for a handler call in progress. The reader keeps its waker (the shared
        // state) until its next message, which then finds nothing to do.
        *self
            .shared
            .handling
            .lock()
            .unwrap_or_else(PoisonError::into_inner) = None;
    }
}
