//! One datagram per destination for samples written back to back.
//!
//! A writing thread that sends its own samples ([`DirectRoute`]) puts each one
//! in a datagram of its own, to each destination. A thread that writes several
//! topics in a row to the same readers (a simulator publishing its state once a
//! tick: joint states, IMU, clock, poses...) sends as many datagrams to each
//! reader participant, and each costs a system call, a pass through the
//! network stack and, on the reading side, a receive and often a wake-up.
//! Inside [`coalesce_sends`] the thread's direct sends are gathered instead:
//! the submessages of every sample for one destination are appended, in write
//! order, to one RTPS message (its header said once: the writers are of one
//! participant), sent when the closure returns or when the next would exceed
//! the writer's datagram budget. A reader processes the submessages in order,
//! so each writer's samples still arrive in sequence and each sample keeps its
//! own INFO_TS. Other writers' and the event loop's traffic is untouched.
//!
//! [`DirectRoute`]: crate::rtps::writer_send_buffer::DirectRoute

use std::{
  cell::RefCell,
  net::{SocketAddr, UdpSocket},
  sync::Arc,
};

#[allow(unused_imports)]
use log::{debug, trace};

// The RTPS message header: "RTPS", version, vendor, GUID prefix.
use crate::rtps::message::RTPS_MESSAGE_HEADER_SIZE;

/// Datagrams being gathered for one destination.
struct Pending {
  socket: Arc<UdpSocket>,
  destination: SocketAddr,
  /// One RTPS message: a header, then submessages.
  bytes: Vec<u8>,
}

impl Pending {
  fn send(&self) {
    match self.socket.send_to(&self.bytes, self.destination) {
      Ok(n) if n == self.bytes.len() => {}
      // The samples are marked sent: a reliable reader has them repaired after
      // the next HEARTBEAT, as after a datagram lost on the way.
      other => debug!(
        "coalesced send of {} bytes to {}: {other:?}",
        self.bytes.len(),
        self.destination
      ),
    }
  }
}

thread_local! {
  /// This thread's batch while it runs inside [`coalesce_sends`].
  static BATCH: RefCell<Option<Vec<Pending>>> = const { RefCell::new(None) };
}

/// Runs `f`; the samples it writes that the writing thread sends itself (a
/// writer whose matched readers each have one unicast destination) go out as
/// one datagram per destination when `f` returns (or unwinds), instead of one
/// per sample and destination. Nested calls join the outermost one.
///
/// The datagrams go out in the order their destinations were first written to
/// in the burst. Samples sent so wait for the end of `f`: wrap a burst of
/// writes, not a loop that waits on something. A reliable write that blocks
/// inside a burst on a full send window waits for acknowledgements of what was
/// sent before it, not of what the burst has gathered, which is still unsent:
/// write a writer once per burst, or leave room in its window.
pub fn coalesce_sends<R>(f: impl FnOnce() -> R) -> R {
  let outermost = BATCH.with(|b| {
    let mut b = b.borrow_mut();
    if b.is_some() {
      false
    } else {
      *b = Some(Vec::new());
      true
    }
  });
  if !outermost {
    return f();
  }
  struct Flush;
  impl Drop for Flush {
    fn drop(&mut self) {
      let pending = BATCH.with(|b| b.borrow_mut().take()).unwrap_or_default();
      for p in &pending {
        p.send();
      }
    }
  }
  let _flush = Flush;
  f()
}

/// Whether this thread gathers its direct sends now.
pub(crate) fn active() -> bool {
  BATCH.with(|b| b.borrow().is_some())
}

/// Takes `message` (a whole RTPS message) for `destination` into this thread's
/// batch, if it runs inside [`coalesce_sends`]: appended to what is gathered
/// for that destination from the same participant, unless the result would
/// exceed `max_datagram` bytes, in which case what was gathered is sent first.
/// Returns false (nothing taken) outside a batch.
pub(crate) fn offer(
  socket: &Arc<UdpSocket>,
  destination: SocketAddr,
  message: &[u8],
  max_datagram: usize,
) -> bool {
  if message.len() < RTPS_MESSAGE_HEADER_SIZE {
    return false;
  }
  BATCH.with(|b| {
    let mut b = b.borrow_mut();
    let Some(batch) = b.as_mut() else {
      return false;
    };
    let (header, body) = message.split_at(RTPS_MESSAGE_HEADER_SIZE);
    match batch
      .iter_mut()
      .find(|p| p.destination == destination && p.bytes[..RTPS_MESSAGE_HEADER_SIZE] == *header)
    {
      Some(p) if p.bytes.len() + body.len() <= max_datagram => {
        p.bytes.extend_from_slice(body);
      }
      Some(p) => {
        trace!(
          "coalesced datagram to {destination} full at {} bytes",
          p.bytes.len()
        );
        p.send();
        p.bytes.clear();
        p.bytes.extend_from_slice(message);
      }
      None => batch.push(Pending {
        socket: Arc::clone(socket),
        destination,
        bytes: message.to_vec(),
      }),
    }
    true
  })
}
