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
    /// Hands each message of a plain ros2-client `subscription` to `handler` on its DDS
    /// thread, from those already waiting on. A node's subscriptions go through
    /// [`crate::Subscription::on_receive`], which refuses a composed node's.
    pub fn new(
        subscription: ros2_client::Subscription<M>,
        handler: impl FnMut(Received<M>) + Send + 'static,
    ) -> Self {
        let handler: Box<dyn FnMut(Received<M>) + Send> = Box::new(handler);
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

/// What a handler run on the DDS thread ([`crate::RosNode::serve_on_receive`]) has the
/// node's thread log: the DDS thread does not write the log itself (`/rosout` is the node's,
/// and a handler must not wait).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Said {
    /// A warning.
    Warn(String),
    /// An error, logged at most once a second per `key` ([`crate::RosNode::error_throttled`]).
    Error {
        /// What kind of error, for the throttle.
        key: &'static str,
        /// The error.
        text: String,
    },
}

impl crate::RosNode {
    /// Logs what a handler said: a warning as it comes, an error throttled by its key.
    pub fn log_said(&self, said: Said) {
        match said {
            Said::Warn(text) => self.warn(&text),
            Said::Error { key, text } => self.error_throttled(key, &text),
        }
    }

    /// Hands each message of `sub` (topic `topic`) to `handler` until `stop` is set: on the DDS
    /// thread that receives it when `on_receive` ([`Self::serve_on_receive`]), else on this,
    /// the node's thread, which logs what the handler says either way.
    pub async fn serve<M: RosMessageBound>(
        &self,
        sub: crate::Subscription<M>,
        topic: &str,
        stop: &AtomicBool,
        on_receive: bool,
        mut handler: impl FnMut(M, &mut dyn FnMut(Said)) + Send + 'static,
    ) -> Result<(), crate::RosError> {
        if on_receive {
            return self.serve_on_receive(sub, topic, stop, handler).await;
        }
        // The stop flag is looked at, without a message, every 100 ms.
        let mut bound = crate::WaitBound::every(std::time::Duration::from_millis(100));
        while !stop.load(Ordering::SeqCst) {
            if let Some(m) = self.take_within(&sub, topic, &mut bound).await {
                handler(m, &mut |said| self.log_said(said));
            }
        }
        Ok(())
    }

    /// Hands each message of `sub` (topic `topic`) to `handler` on the DDS thread that
    /// receives it ([`crate::Subscription::on_receive`]) until `stop` is set, while this, the
    /// node's thread, logs what the handler says through its second argument. What is said
    /// goes through a queue of 64: when the node's thread falls behind, what is said is
    /// dropped, never a message. An unreadable message is dropped with a warning naming
    /// `topic`. Ends with an error if the handler panicked (no message is handled after it).
    pub async fn serve_on_receive<M: RosMessageBound>(
        &self,
        sub: crate::Subscription<M>,
        topic: &str,
        stop: &AtomicBool,
        mut handler: impl FnMut(M, &mut dyn FnMut(Said)) + Send + 'static,
    ) -> Result<(), crate::RosError> {
        let (tx, rx) = smol::channel::bounded(64);
        let name = topic.to_owned();
        let on_receive = sub.on_receive(move |received| {
            let mut say = |said| {
                let _ = tx.try_send(said);
            };
            match received {
                Ok((m, _)) => handler(m, &mut say),
                Err(e) => say(Said::Warn(format!(
                    "{name}: unreadable message dropped: {e:?}"
                ))),
            }
        })?;
        // The stop flag is looked at, without anything said, every 100 ms.
        let mut bound = crate::WaitBound::every(std::time::Duration::from_millis(100));
        while !stop.load(Ordering::SeqCst) {
            if on_receive.failed() {
                return Err(crate::RosError::HandlerPanicked {
                    topic: topic.to_owned(),
                });
            }
            if let Some(Ok(said)) = bound.within(rx.recv()).await {
                self.log_said(said);
            }
        }
        Ok(())
    }
}
