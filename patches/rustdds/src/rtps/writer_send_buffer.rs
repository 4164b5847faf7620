use std::{
  cmp::max,
  collections::VecDeque,
  net::{SocketAddr, UdpSocket},
  sync::{
    atomic::{AtomicI32, Ordering},
    Arc, Condvar, Mutex, MutexGuard,
  },
  time::{Duration as StdDuration, Instant},
};
use core::task::Waker;

#[allow(unused_imports)]
use log::{debug, error, trace, warn};

use speedy::Endianness;

use crate::{
  dds::{ddsdata::DDSData, with_key::datawriter::WriteOptions},
  rtps::{constant::PIGGYBACK_ACKNACK_REQUEST_PERIOD, message::MessageBuilder, send_batch},
  structure::{
    cache_change::CacheChange,
    guid::{EntityId, GUID},
    sequence_number::SequenceNumber,
    time::Timestamp,
  },
};

/// A writer's retained samples: consecutive sequence numbers, oldest first.
/// Samples come in at the newest end (each the sequence number after the last
/// one) and leave from the oldest, so a ring buffer holds them and reuses its
/// storage, where a map keyed by sequence number allocates and frees nodes as
/// samples come and go.
#[derive(Default)]
struct SampleHistory {
  /// The sequence number of `samples[0]` (meaningless while empty).
  oldest: SequenceNumber,
  samples: VecDeque<CacheChange>,
}

impl SampleHistory {
  fn len(&self) -> usize {
    self.samples.len()
  }

  /// The oldest retained sample's sequence number.
  fn oldest(&self) -> Option<SequenceNumber> {
    (!self.samples.is_empty()).then_some(self.oldest)
  }

  /// Adds the newest sample: the one after the newest retained (any while
  /// empty).
  fn push(&mut self, cc: CacheChange) {
    if self.samples.is_empty() {
      self.oldest = cc.sequence_number;
    }
    debug_assert_eq!(
      i64::from(cc.sequence_number) - i64::from(self.oldest),
      self.samples.len() as i64,
      "samples must come in sequence"
    );
    self.samples.push_back(cc);
  }

  /// Drops the oldest sample, returning its sequence number.
  fn pop_oldest(&mut self) -> Option<SequenceNumber> {
    let cc = self.samples.pop_front()?;
    self.oldest = cc.sequence_number.plus_1();
    Some(cc.sequence_number)
  }

  fn get(&self, sn: SequenceNumber) -> Option<&CacheChange> {
    let index = usize::try_from(i64::from(sn) - i64::from(self.oldest)).ok()?;
    self.samples.get(index)
  }

  /// Drops every sample before `sn`, returning how many.
  fn remove_before(&mut self, sn: SequenceNumber) -> usize {
    let mut removed = 0;
    while self.oldest().is_some_and(|oldest| oldest < sn) {
      self.pop_oldest();
      removed += 1;
    }
    removed
  }
}

/// A sample admitted into the [`WriterSendBuffer`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct Admitted {
  pub sequence_number: SequenceNumber,
  /// The writing thread has also put it on the wire to every matched reader
  /// (see [`DirectRoute`]), so the event loop need not be woken; otherwise it
  /// is ready for the Writer (event loop) to transmit.
  pub sent_directly: bool,
}

/// Result of an admission attempt into the [`WriterSendBuffer`].
pub(crate) enum Admission {
  /// The sample was admitted. It now lives in the send buffer.
  Admitted(Admitted),
  /// The reliable send window is full and no room became available within the
  /// allotted blocking time. The sample was *not* stored.
  WouldBlock,
}

// The actual shared state. Guarded by a single Mutex; the Condvar is signalled
// whenever the reliable acknowledgement frontier advances or the window grows,
// i.e. whenever a previously-blocked producer (or a `wait_for_acknowledgments`
// waiter) might be able to make progress.
struct Inner {
  // --- the send buffer proper (replaces the old HistoryBuffer) ---
  // Sequence numbers are allocated here under the lock and are thus strictly
  // monotonic and unique. This is the single source of truth for the Writer's
  // outgoing samples (send, repair, fragmentation, eviction).
  changes: SampleHistory,
  first_seq: SequenceNumber, // oldest still retained (default 1)
  last_seq: SequenceNumber,  // latest allocated (default 0 == nothing yet)

  // --- flow control ---
  // Maximum number of unacknowledged samples a reliable writer may have
  // outstanding before `write` must block/fail.
  window_limit: usize,
  // The acknowledgement frontier: the smallest `all_acked_before` over all
  // matched *reliable* readers. Only meaningful when `reliable_readers_present`.
  // Maintained by the Writer (event loop) via `set_acked_frontier`.
  acked_before: SequenceNumber,
  reliable_readers_present: bool,

  // nonblocking-transmit: the unsent backlog limit. The Writer advances
  // `sent_frontier` as it actually transmits samples; when the network socket
  // congests, `sent_frontier` stalls, the backlog `(sent_frontier, last_seq]`
  // fills, and admission blocks -- back-pressure reaching the application.
  // Applies to reliable *and* best-effort writers; built-in/discovery are
  // exempt so discovery never stalls.
  // (see src/rtps/nonblocking_transmit_design.md)
  backlog_limit: usize,
  // Highest sequence number the Writer has actually put on the wire.
  sent_frontier: SequenceNumber,

  // Hard upper bound on the number of retained samples for *non-blocking*
  // (best-effort, DDS-default) writes. Because such writes are never throttled
  // at admission (see `has_room`), and eviction otherwise only happens on the
  // periodic (6 s) cache-cleaning timer, the buffer would grow without bound
  // when the application produces faster than the socket drains. We therefore
  // apply KeepLast-style "newest wins" eviction directly on insert: once the
  // buffer exceeds `max_retain`, the oldest samples are dropped. Derived from
  // the writer's History depth / ResourceLimits (same value as `window_limit`).
  // Does NOT apply to reliable / opted-in writers, which are bounded by the
  // send window / unsent-backlog and must retain samples for repair.
  max_retain: usize,

  // Wakers of async producers / ack-waiters parked because the window was full
  // or acknowledgements were still pending. Drained (woken) on any advance.
  wakers: Vec<Waker>,
  // Threads blocked on `progress` (counted under this lock): with none, an advance
  // skips the notify, a system call on every acknowledgement otherwise.
  blocked_threads: usize,
  // How many times `progress` was notified (tests).
  #[cfg(test)]
  notified: usize,

  // Set by the Writer while every matched reader is reached by one unicast
  // datagram: the writing thread then sends a fresh sample itself.
  direct: Option<DirectRoute>,
  // When a fresh sample last asked its readers for an ACKNACK (its HEARTBEAT
  // without the final flag), sent by the writing thread or by the event loop.
  // See [`piggyback_asks_for_acknack`].
  last_acknack_request: Option<Instant>,
}

impl Inner {
  /// [`piggyback_asks_for_acknack`] for a HEARTBEAT piggybacked now.
  fn acknack_request_due(&self, now: Instant) -> bool {
    let unacked = self
      .reliable_readers_present
      .then(|| i64::from(self.last_seq) - i64::from(self.acked_before) + 1);
    piggyback_asks_for_acknack(self.last_acknack_request, now, unacked, self.window_limit)
  }
}

/// Whether the HEARTBEAT piggybacked on fresh samples asks the readers to
/// acknowledge (final flag clear), as Cyclone DDS's heartbeat control does,
/// whichever thread sends them (the writing thread on the direct route, or the
/// event loop's push): when no fresh sample asked within
/// [`PIGGYBACK_ACKNACK_REQUEST_PERIOD`] (so a sporadic sample is acknowledged
/// at once, and a steady flow about once a period), or when half the reliable
/// send window is unacknowledged (so back-pressure never waits for a periodic
/// heartbeat). Otherwise the HEARTBEAT is final: a reader that has everything
/// it announces stays silent, and one that misses a sample still answers with
/// a NACK at once (RTPS v2.5 8.4.2.3.2), so repair is as prompt as before.
/// Asking on every sample made every reader answer every sample: one more
/// datagram, and a wake-up of both participants' event loops, per sample and
/// reader.
fn piggyback_asks_for_acknack(
  last_request: Option<Instant>,
  now: Instant,
  unacked: Option<i64>,
  window_limit: usize,
) -> bool {
  let period_over = last_request
    .is_none_or(|t| now.saturating_duration_since(t) >= PIGGYBACK_ACKNACK_REQUEST_PERIOD);
  let half_window = unacked.is_some_and(|n| n.saturating_mul(2) >= window_limit as i64);
  period_over || half_window
}

/// How the writing thread can send a fresh sample itself, as the Writer's
/// aggregated push would (one datagram, INFO_TS? + DATA + HEARTBEAT, to
/// every matched reader), instead of waking the event loop to do it. Saves one
/// thread hand-off per sample on the latency path.
///
/// Published by the Writer (event loop) whenever its matched readers or their
/// routes change, and only while every reader has a resolved unicast route (no
/// multicast, no legacy all-locators fallback), the writer is a user writer in
/// push mode without security. A sample is sent directly only when it is the
/// next one to go out (everything before it is on the wire, so the order on
/// the wire is the order of sequence numbers and the event loop has nothing in
/// progress), fits one datagram and is meant for all readers. Any send that
/// does not fully succeed (WouldBlock, an error) leaves the sample to the event
/// loop, which then sends it to all readers as before: a reader may get a
/// duplicate, which it discards by sequence number. Reliability is unchanged:
/// the sample is in the send buffer, acknowledged and repaired by the Writer.
#[derive(Clone, Debug)]
pub(crate) struct DirectRoute {
  /// The participant's unicast sender socket (a duplicate descriptor, so
  /// non-blocking like the event loop's).
  pub socket: Arc<UdpSocket>,
  /// Distinct destinations of the matched readers (possibly none).
  pub destinations: Vec<SocketAddr>,
  pub endianness: Endianness,
  /// Largest payload the Writer sends unfragmented.
  pub max_payload: usize,
  /// Largest datagram for these readers: the bound of one that gathers several
  /// samples ([`send_batch::coalesce_sends`]).
  pub max_datagram: usize,
  /// The Writer's heartbeat counter, for the HEARTBEAT piggybacked on each DATA
  /// (reliable, stateful writers); `None` sends no HEARTBEAT.
  pub heartbeat_count: Option<Arc<AtomicI32>>,
}

struct Shared {
  inner: Mutex<Inner>,
  // Signalled together with `wakers` whenever progress may be possible.
  progress: Condvar,
  // Fixed for the lifetime of the writer.
  writer_guid: GUID,
  reliable_writer: bool,
  is_builtin: bool,
  // True for VOLATILE durability (the DDS default). When true, a reliable writer
  // with no matched reliable reader trims KeepLast on insert (there is no
  // late-joiner to serve, so retaining unacked samples is pointless). When false
  // (TRANSIENT_LOCAL / TRANSIENT / PERSISTENT) the writer must retain samples for
  // late-joining readers, so pre-match trimming is disabled.
  volatile: bool,
  topic_name: String,
}

/// A shared, flow-controlled buffer of samples between a `DataWriter`
/// (producer, application threads) and its RTPS `Writer` (consumer, event
/// loop).
///
/// The producer side allocates a sequence number and inserts a sample only when
/// the reliable send window has room (synchronous admission, no round-trip).
/// The consumer side transmits unsent samples, advances the acknowledgement
/// frontier as ACKNACKs arrive, and evicts acknowledged samples. Both sides
/// hold a cloned handle to the same `Arc`.
#[derive(Clone)]
pub(crate) struct WriterSendBuffer {
  shared: Arc<Shared>,
}

impl WriterSendBuffer {
  #[allow(clippy::too_many_arguments)]
  pub fn new(
    writer_guid: GUID,
    topic_name: String,
    reliable_writer: bool,
    is_builtin: bool,
    volatile: bool,
    window_limit: usize,
    backlog_limit: usize,
    max_retain: usize,
  ) -> Self {
    Self {
      shared: Arc::new(Shared {
        inner: Mutex::new(Inner {
          changes: SampleHistory::default(),
          first_seq: SequenceNumber::new(1),
          last_seq: SequenceNumber::new(0),
          window_limit: window_limit.max(1),
          acked_before: SequenceNumber::new(1),
          reliable_readers_present: false,
          backlog_limit: backlog_limit.max(1),
          sent_frontier: SequenceNumber::new(0),
          max_retain: max_retain.max(1),
          wakers: Vec::new(),
          blocked_threads: 0,
          #[cfg(test)]
          notified: 0,
          direct: None,
          last_acknack_request: None,
        }),
        progress: Condvar::new(),
        writer_guid,
        reliable_writer,
        is_builtin,
        volatile,
        topic_name,
      }),
    }
  }

  // --- predicates (must be called while holding the lock) ---

  // Is there room to admit one more sample right now?
  //
  // `may_block` is `true` for reliable writers and for best-effort writes that
  // opted in via `WriteOptions::best_effort_may_block`. When `false` (a
  // best-effort write that must not block, the DDS default) admission is never
  // throttled: congested samples are dropped later at the socket instead.
  fn has_room(shared: &Shared, inner: &Inner, may_block: bool) -> bool {
    if shared.is_builtin {
      // Built-in (discovery) writers must never stall.
      return true;
    }

    if !may_block {
      // Best-effort write that must not block (DDS v1.4 2.2.2.4.2.11 default).
      // Never throttle admission.
      return true;
    }

    // nonblocking-transmit: unsent-backlog limit. Applies to reliable writers
    // and to best-effort writers that opted in -- when the socket cannot drain,
    // the application is back-pressured instead of dropping. Samples in
    // (sent_frontier, last_seq].
    let unsent = i64::from(inner.last_seq) - i64::from(inner.sent_frontier);
    if unsent >= inner.backlog_limit as i64 {
      return false;
    }

    if !shared.reliable_writer || !inner.reliable_readers_present {
      // Best-effort and "no reliable reader yet" writers have no acknowledgement
      // window to wait on; the backlog limit above is their only throttle.
      return true;
    }
    // Number of unacknowledged samples in [acked_before, last_seq].
    let unacked = i64::from(inner.last_seq) - i64::from(inner.acked_before) + 1;
    unacked < inner.window_limit as i64
  }

  // Wake every parked producer / ack-waiter. Called after any state change that
  // could let someone make progress.
  fn wake_all(inner: &mut Inner, progress: &Condvar) {
    for w in inner.wakers.drain(..) {
      w.wake();
    }
    if inner.blocked_threads > 0 {
      progress.notify_all();
      #[cfg(test)]
      {
        inner.notified += 1;
      }
    }
  }

  // Blocks on `progress` for up to `timeout` (`None`: until notified), counted in
  // `blocked_threads` so that `wake_all` knows to notify.
  fn wait_for_progress<'a>(
    shared: &'a Shared,
    mut inner: MutexGuard<'a, Inner>,
    timeout: Option<StdDuration>,
  ) -> MutexGuard<'a, Inner> {
    inner.blocked_threads += 1;
    let mut inner = match timeout {
      None => shared.progress.wait(inner).unwrap(),
      Some(timeout) => shared.progress.wait_timeout(inner, timeout).unwrap().0,
    };
    inner.blocked_threads -= 1;
    inner
  }

  // --- producer side ---

  /// Synchronous admission. Blocks the calling thread until there is room in
  /// the reliable send window, or `timeout` elapses. On success the sample is
  /// stored and its sequence number returned. Built-in / best-effort writers
  /// always admit immediately.
  pub fn admit_blocking(
    &self,
    write_options: WriteOptions,
    data: DDSData,
    timeout: Option<StdDuration>,
  ) -> Admission {
    let shared = &*self.shared;
    let mut inner = shared.inner.lock().unwrap();

    // Reliable writers always back-pressure; best-effort only if this write
    // opted in via `best_effort_may_block`.
    let may_block = shared.reliable_writer || write_options.best_effort_may_block();

    let deadline = timeout.map(|t| Instant::now() + t);
    loop {
      if Self::has_room(shared, &inner, may_block) {
        let seq = Self::insert_locked(shared, &mut inner, write_options, data, may_block);
        return Admission::Admitted(Admitted {
          sequence_number: seq,
          sent_directly: Self::send_directly_locked(shared, &mut inner, seq),
        });
      }
      // Window full: wait for an acknowledgement to free up space.
      match deadline {
        None => {
          inner = Self::wait_for_progress(shared, inner, None);
        }
        Some(deadline) => {
          let now = Instant::now();
          if now >= deadline {
            return Admission::WouldBlock;
          }
          inner = Self::wait_for_progress(shared, inner, Some(deadline - now));
        }
      }
    }
  }

  /// Non-blocking admission for async writers. On success returns the
  /// admission (sequence number, and whether it was sent directly). On a full
  /// window returns the (write_options, data) back so the caller can retry
  /// later, and registers `waker` to be woken when room becomes available.
  pub fn try_admit(
    &self,
    write_options: WriteOptions,
    data: DDSData,
    waker: &Waker,
  ) -> Result<Admitted, (WriteOptions, DDSData)> {
    let shared = &*self.shared;
    let mut inner = shared.inner.lock().unwrap();
    let may_block = shared.reliable_writer || write_options.best_effort_may_block();
    if Self::has_room(shared, &inner, may_block) {
      let seq = Self::insert_locked(shared, &mut inner, write_options, data, may_block);
      Ok(Admitted {
        sequence_number: seq,
        sent_directly: Self::send_directly_locked(shared, &mut inner, seq),
      })
    } else {
      register_waker(&mut inner.wakers, waker);
      Err((write_options, data))
    }
  }

  fn insert_locked(
    shared: &Shared,
    inner: &mut Inner,
    write_options: WriteOptions,
    data: DDSData,
    may_block: bool,
  ) -> SequenceNumber {
    let seq = inner.last_seq.plus_1();
    // Stamped under the lock that orders the sequence numbers, so one writer's
    // timestamps never go backwards against its sequence numbers (unless the
    // system clock does).
    let write_options = write_options.with_source_timestamp_or(Timestamp::now());
    let cc = CacheChange::new(shared.writer_guid, seq, write_options, data);
    inner.changes.push(cc);
    inner.last_seq = seq;

    // KeepLast "newest wins" bound. Applied on insert for:
    //  - non-blocking best-effort writes: never throttled at admission (`has_room`
    //    returns true), and the only other eviction path is the periodic
    //    cache-cleaning timer, which starves under a sustained flood -- so without
    //    this the buffer grows without bound (confirmed multi-GB leak);
    //  - reliable writers with NO matched reliable reader yet: there is nobody to
    //    repair to, so retaining unacknowledged samples is pointless. A reliable
    //    writer that produces flat-out before discovery completes (discovery is
    //    CPU-starved under load and can lag ~1 s) would otherwise race thousands of
    //    samples ahead, and when the reader finally matches it faces a huge
    //    unacknowledged backlog that must be recovered via repair at the slow (100
    //    ms) heartbeat cadence -- collapsing reliable throughput. Trimming to
    //    KeepLast here keeps only the recent samples (correct for volatile
    //    durability); once a reliable reader matches, `reliable_readers_present`
    //    flips true and what some reader has not acknowledged is kept for repair.
    // Built-in (discovery) writers are always exempt to never lose discovery data.
    let trim_keep_last = !shared.is_builtin
      && (!may_block
        || (shared.reliable_writer && shared.volatile && !inner.reliable_readers_present));
    // A reliable writer with reliable readers keeps beyond its KeepLast depth only
    // what some reader has not acknowledged yet: the oldest samples every reader has
    // acknowledged (and so the writer has sent) go now, as the periodic cache
    // cleaning would drop them seconds later (a writer at 1 kHz would hold thousands
    // of samples, all freed at once in the event loop).
    let trim_acknowledged = !shared.is_builtin && inner.reliable_readers_present;
    while inner.changes.len() > inner.max_retain {
      match inner.changes.oldest() {
        Some(oldest)
          if trim_keep_last
            || (trim_acknowledged
              && oldest < inner.acked_before
              && oldest <= inner.sent_frontier) =>
        {
          inner.changes.pop_oldest();
          inner.first_seq = oldest.plus_1();
        }
        _ => break,
      }
    }
    seq
  }

  // Send the just-admitted sample `seq` from the writing thread, under the
  // buffer's lock (so the event loop cannot send it at the same time, and
  // samples of concurrent writes go out in order). See [`DirectRoute`].
  fn send_directly_locked(shared: &Shared, inner: &mut Inner, seq: SequenceNumber) -> bool {
    let Some(route) = inner.direct.as_ref() else {
      return false;
    };
    if inner.sent_frontier.plus_1() != seq {
      return false;
    }
    let Some(cc) = inner.changes.get(seq) else {
      return false; // trimmed at once (cannot happen for the newest sample)
    };
    if cc.data_value.payload_size() > route.max_payload
      || cc.write_options.to_single_reader().is_some()
    {
      return false;
    }
    let mut builder = MessageBuilder::new();
    let coalesced = send_batch::active();
    match cc.write_options.source_timestamp() {
      Some(ts) => builder = builder.ts_msg(route.endianness, Some(ts)),
      // Gathered after another sample's INFO_TS, this DATA would take its time:
      // say there is none.
      None if coalesced => builder = builder.ts_msg(route.endianness, None),
      None => {}
    }
    builder = builder.data_msg(
      cc,
      EntityId::UNKNOWN, // to all readers
      shared.writer_guid,
      route.endianness,
      None,
    );
    let mut asks_for_acknack = false;
    if let Some(count) = &route.heartbeat_count {
      asks_for_acknack = inner.acknack_request_due(Instant::now());
      builder = builder.heartbeat_msg(
        shared.writer_guid.entity_id,
        inner.first_seq,
        inner.last_seq,
        count.fetch_add(1, Ordering::SeqCst),
        route.endianness,
        EntityId::UNKNOWN, // to all readers
        !asks_for_acknack, // final_flag
        false,             // liveliness_flag
      );
    }
    let message = builder.add_header_and_build(shared.writer_guid.prefix);
    let buffer = match message.write_to_vec_fast(route.endianness) {
      Ok(b) => b,
      Err(e) => {
        debug!("direct send: cannot serialise, left to the event loop: {e:?}");
        return false;
      }
    };
    for destination in &route.destinations {
      if coalesced && send_batch::offer(&route.socket, *destination, &buffer, route.max_datagram) {
        continue;
      }
      match route.socket.send_to(&buffer, destination) {
        Ok(n) if n == buffer.len() => {}
        other => {
          trace!("direct send to {destination}: {other:?}, left to the event loop");
          return false;
        }
      }
    }
    inner.sent_frontier = seq;
    if asks_for_acknack {
      inner.last_acknack_request = Some(Instant::now());
    }
    true
  }

  // --- consumer side (Writer / event loop) ---

  /// Publish (or withdraw, `None`) the route on which writing threads send
  /// fresh samples themselves. See [`DirectRoute`].
  pub fn set_direct_route(&self, route: Option<DirectRoute>) {
    self.shared.inner.lock().unwrap().direct = route;
  }

  /// Whether the HEARTBEAT the event loop piggybacks now on fresh samples asks
  /// the readers for an ACKNACK (the rule of [`piggyback_asks_for_acknack`],
  /// shared with the writing thread's direct sends). When it does and the
  /// datagram goes out, the loop calls [`Self::acknack_requested`].
  pub fn acknack_request_due(&self) -> bool {
    self
      .shared
      .inner
      .lock()
      .unwrap()
      .acknack_request_due(Instant::now())
  }

  /// A HEARTBEAT asking for an ACKNACK went out with fresh samples: the next
  /// one asks again a period from now (or at half the window).
  pub fn acknack_requested(&self) {
    self.shared.inner.lock().unwrap().last_acknack_request = Some(Instant::now());
  }

  /// The latest allocated sequence number and the highest one on the wire, in
  /// one look (a directly sent sample advances the latter without the Writer).
  pub fn last_and_sent_sequence_numbers(&self) -> (SequenceNumber, SequenceNumber) {
    let inner = self.shared.inner.lock().unwrap();
    (inner.last_seq, inner.sent_frontier)
  }

  /// Update the reliable acknowledgement frontier. `acked_before` is the
  /// minimum `all_acked_before` over all matched reliable readers, and
  /// `present` tells whether any reliable reader is currently matched. Wakes
  /// blocked producers / ack-waiters when the frontier advances or a reader
  /// goes away.
  ///
  /// A reader that has not sent an ACKNACK yet reports `all_acked_before == 0`.
  /// Sequence numbers start at 1, so the frontier is never below 1: anything
  /// lower would count a sample that does not exist against the send window.
  pub fn set_acked_frontier(&self, acked_before: Option<SequenceNumber>) {
    let shared = &*self.shared;
    let mut inner = shared.inner.lock().unwrap();
    let advanced = match acked_before {
      Some(sn) => {
        let sn = max(sn, SequenceNumber::new(1));
        let adv = sn > inner.acked_before || !inner.reliable_readers_present;
        inner.acked_before = sn;
        inner.reliable_readers_present = true;
        adv
      }
      None => {
        // No reliable readers (any more). Everything counts as acknowledged.
        let adv = inner.reliable_readers_present;
        inner.reliable_readers_present = false;
        adv
      }
    };
    if advanced {
      Self::wake_all(&mut inner, &shared.progress);
    }
  }

  /// nonblocking-transmit: advance the "actually transmitted" frontier. Called
  /// by the Writer as it puts samples on the wire. Wakes producers parked on a
  /// full unsent backlog when the frontier advances.
  pub fn set_sent_frontier(&self, sent_frontier: SequenceNumber) {
    let shared = &*self.shared;
    let mut inner = shared.inner.lock().unwrap();
    if sent_frontier > inner.sent_frontier {
      inner.sent_frontier = sent_frontier;
      Self::wake_all(&mut inner, &shared.progress);
    }
  }

  /// The sequence number of the latest allocated sample (0 if none yet).
  pub fn last_change_sequence_number(&self) -> SequenceNumber {
    self.shared.inner.lock().unwrap().last_seq
  }

  /// Number of samples currently retained in the buffer. Test-only.
  #[cfg(test)]
  pub fn retained_len(&self) -> usize {
    self.shared.inner.lock().unwrap().changes.len()
  }

  /// The lowest sequence number still retained (or the next-to-be-written if
  /// the buffer is empty).
  pub fn first_change_sequence_number(&self) -> SequenceNumber {
    self.shared.inner.lock().unwrap().first_seq
  }

  /// Fetch a clone of the sample with the given sequence number, if retained.
  /// Returns an owned `CacheChange` (a cheap `Bytes`-backed clone) so the
  /// caller can serialize and transmit without holding the lock.
  pub fn get_by_sn(&self, sn: SequenceNumber) -> Option<CacheChange> {
    self.shared.inner.lock().unwrap().changes.get(sn).cloned()
  }

  /// Evict all samples with sequence number strictly less than `remove_before`.
  pub fn remove_changes_before(&self, remove_before: SequenceNumber) {
    let shared = &*self.shared;
    let mut inner = shared.inner.lock().unwrap();
    let removed = inner.changes.remove_before(remove_before);
    if remove_before > inner.first_seq {
      inner.first_seq = remove_before;
    }
    if removed > 0 {
      debug!(
        "WriterSendBuffer: removed {} change(s) before {:?} topic={}",
        removed, remove_before, shared.topic_name
      );
    }
  }

  // --- wait_for_acknowledgments support ---

  /// Has every matched reliable reader acknowledged everything up to and
  /// including `target`? Also true when there are no reliable readers.
  pub fn is_acked_through(&self, target: SequenceNumber) -> bool {
    let inner = self.shared.inner.lock().unwrap();
    !inner.reliable_readers_present || inner.acked_before > target
  }

  /// Synchronously wait until everything up to `target` is acknowledged, or
  /// `max_wait` elapses. Returns `true` if acknowledged.
  pub fn wait_for_acked_through(&self, target: SequenceNumber, max_wait: StdDuration) -> bool {
    let shared = &*self.shared;
    let mut inner = shared.inner.lock().unwrap();
    let deadline = Instant::now() + max_wait;
    loop {
      if !inner.reliable_readers_present || inner.acked_before > target {
        return true;
      }
      let now = Instant::now();
      if now >= deadline {
        return false;
      }
      inner = Self::wait_for_progress(shared, inner, Some(deadline - now));
    }
  }

  /// Register `waker` to be notified when the acknowledgement frontier advances
  /// (used by the async `wait_for_acknowledgments` future).
  pub fn register_ack_waker(&self, waker: &Waker) {
    let mut inner = self.shared.inner.lock().unwrap();
    register_waker(&mut inner.wakers, waker);
  }
}

// Avoid storing duplicate wakers for the same task.
fn register_waker(wakers: &mut Vec<Waker>, waker: &Waker) {
  if !wakers.iter().any(|w| w.will_wake(waker)) {
    wakers.push(waker.clone());
  }
}

#[cfg(test)]
pub(crate) mod tests {
  use std::time::Duration as StdDuration;

  use super::*;
  use crate::{
    dds::{ddsdata::DDSData, with_key::datawriter::WriteOptionsBuilder},
    messages::submessages::elements::serialized_payload::SerializedPayload,
    structure::guid::GUID,
    RepresentationIdentifier,
  };

  fn sample() -> DDSData {
    DDSData::new(SerializedPayload::new(
      RepresentationIdentifier::CDR_LE,
      vec![0u8; 8],
    ))
  }

  fn admit_now(buf: &WriterSendBuffer, opts: WriteOptions) -> bool {
    matches!(
      buf.admit_blocking(opts, sample(), Some(StdDuration::ZERO)),
      Admission::Admitted(_)
    )
  }

  fn may_block_opts() -> WriteOptions {
    WriteOptionsBuilder::new()
      .best_effort_may_block(true)
      .build()
  }

  // A user writer whose readers all have a unicast route: the buffer with a
  // direct route, and a socket standing in for the readers.
  fn buffer_with_direct_route(reliable: bool) -> (WriterSendBuffer, UdpSocket) {
    let buf = WriterSendBuffer::new(
      GUID::dummy_test_guid(crate::structure::guid::EntityKind::WRITER_WITH_KEY_USER_DEFINED),
      "direct".to_string(),
      reliable,
      /* is_builtin */ false,
      /* volatile */ true,
      /* window_limit */ 100,
      /* backlog_limit */ 100,
      /* max_retain */ 100,
    );
    let reader = UdpSocket::bind("127.0.0.1:0").unwrap();
    reader
      .set_read_timeout(Some(StdDuration::from_secs(5)))
      .unwrap();
    let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
    socket.set_nonblocking(true).unwrap();
    buf.set_direct_route(Some(DirectRoute {
      socket: Arc::new(socket),
      destinations: vec![reader.local_addr().unwrap()],
      endianness: Endianness::LittleEndian,
      max_payload: 1000,
      max_datagram: 1400,
      heartbeat_count: reliable.then(|| Arc::new(AtomicI32::new(7))),
    }));
    (buf, reader)
  }

  // Pretends the last ACKNACK request was just made and the period will not
  // run out during the test, whatever the machine's pauses between sends.
  fn hold_acknack_period(buf: &WriterSendBuffer) {
    set_last_acknack_request(buf, Some(Instant::now() + StdDuration::from_secs(3600)));
  }

  // Sets when a fresh sample last asked for an ACKNACK; returns the time it
  // replaces.
  pub(crate) fn set_last_acknack_request(
    buf: &WriterSendBuffer,
    at: Option<Instant>,
  ) -> Option<Instant> {
    std::mem::replace(
      &mut buf.shared.inner.lock().unwrap().last_acknack_request,
      at,
    )
  }

  pub(crate) fn admit(buf: &WriterSendBuffer, payload_len: usize) -> Admitted {
    match buf.admit_blocking(
      WriteOptions::default(),
      DDSData::new(SerializedPayload::new(
        RepresentationIdentifier::CDR_LE,
        vec![0u8; payload_len],
      )),
      Some(StdDuration::ZERO),
    ) {
      Admission::Admitted(a) => a,
      Admission::WouldBlock => panic!("not admitted"),
    }
  }

  // The DATA sequence numbers and HEARTBEAT (first, last, count, final flag)
  // of one received datagram.
  #[allow(clippy::type_complexity)]
  pub(crate) fn receive(reader: &UdpSocket) -> (Vec<i64>, Vec<(i64, i64, i32, bool)>) {
    use crate::{
      messages::submessages::{submessage_flag::HEARTBEAT_Flags, submessages::WriterSubmessage},
      rtps::message::Message,
    };
    let mut datagram = [0u8; 2048];
    let n = reader.recv(&mut datagram).expect("a datagram");
    let message =
      Message::read_from_buffer(&bytes::Bytes::copy_from_slice(&datagram[..n])).unwrap();
    let (mut data, mut heartbeats) = (Vec::new(), Vec::new());
    for sub in message.submessages() {
      match sub.body {
        crate::rtps::submessage::SubmessageBody::Writer(WriterSubmessage::Data(d, _)) => {
          data.push(i64::from(d.writer_sn));
        }
        crate::rtps::submessage::SubmessageBody::Writer(WriterSubmessage::Heartbeat(h, flags)) => {
          heartbeats.push((
            i64::from(h.first_sn),
            i64::from(h.last_sn),
            h.count,
            flags.contains(HEARTBEAT_Flags::Final),
          ));
        }
        _ => {}
      }
    }
    (data, heartbeats)
  }

  // A user writer of the test participant (`key` tells writers apart) whose
  // direct route leads to `destination`, with a datagram budget of
  // `max_datagram` bytes.
  fn writer_to(key: u8, destination: SocketAddr, max_datagram: usize) -> WriterSendBuffer {
    use crate::structure::guid::{EntityId, EntityKind};
    let buf = WriterSendBuffer::new(
      GUID::new(
        crate::structure::guid::GuidPrefix::new(b"FakeTestGUID"),
        EntityId::new([0, 0, key], EntityKind::WRITER_NO_KEY_USER_DEFINED),
      ),
      format!("topic{key}"),
      /* reliable */ true,
      /* is_builtin */ false,
      /* volatile */ true,
      /* window_limit */ 100,
      /* backlog_limit */ 100,
      /* max_retain */ 100,
    );
    let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
    socket.set_nonblocking(true).unwrap();
    buf.set_direct_route(Some(DirectRoute {
      socket: Arc::new(socket),
      destinations: vec![destination],
      endianness: Endianness::LittleEndian,
      max_payload: 1000,
      max_datagram,
      heartbeat_count: Some(Arc::new(AtomicI32::new(1))),
    }));
    hold_acknack_period(&buf);
    buf
  }

  // The submessages of one datagram, in order: ("TS", 0, 0) for an INFO_TS,
  // ("DATA", writer key, sn), ("HB", writer key, last sn); None when nothing
  // has arrived (the socket is read without waiting: a datagram sent on the
  // loopback is there when `send_to` returns).
  fn submessages_waiting(reader: &UdpSocket) -> Option<Vec<(&'static str, u8, i64)>> {
    use crate::{
      messages::submessages::submessages::{InterpreterSubmessage, WriterSubmessage},
      rtps::{message::Message, submessage::SubmessageBody},
    };
    reader.set_nonblocking(true).unwrap();
    let mut datagram = [0u8; 4096];
    let got = reader.recv(&mut datagram);
    reader.set_nonblocking(false).unwrap();
    let n = match got {
      Ok(n) => n,
      Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => return None,
      Err(e) => panic!("recv: {e}"),
    };
    let message =
      Message::read_from_buffer(&bytes::Bytes::copy_from_slice(&datagram[..n])).unwrap();
    Some(
      message
        .submessages()
        .into_iter()
        .map(|sub| match sub.body {
          SubmessageBody::Interpreter(InterpreterSubmessage::InfoTimestamp(..)) => ("TS", 0, 0),
          SubmessageBody::Writer(WriterSubmessage::Data(d, _)) => {
            ("DATA", d.writer_id.entity_key[2], i64::from(d.writer_sn))
          }
          SubmessageBody::Writer(WriterSubmessage::Heartbeat(h, _)) => {
            ("HB", h.writer_id.entity_key[2], i64::from(h.last_sn))
          }
          _ => ("other", 0, 0),
        })
        .collect(),
    )
  }

  // Inside `coalesce_sends`, two writers' samples for one reader participant
  // wait for the end of the burst and go out as one datagram, in write order,
  // each DATA with its own INFO_TS and HEARTBEAT; outside, one datagram each.
  #[test]
  fn a_burst_of_writes_to_one_destination_goes_out_as_one_datagram() {
    let reader = UdpSocket::bind("127.0.0.1:0").unwrap();
    let to = reader.local_addr().unwrap();
    let (a, b) = (writer_to(1, to, 1400), writer_to(2, to, 1400));
    crate::coalesce_sends(|| {
      assert!(admit(&a, 8).sent_directly);
      assert!(admit(&b, 8).sent_directly);
      assert!(admit(&a, 8).sent_directly);
      assert_eq!(
        submessages_waiting(&reader),
        None,
        "sent before the burst ended"
      );
    });
    let sample = |key, sn| [("TS", 0, 0), ("DATA", key, sn), ("HB", key, sn)];
    assert_eq!(
      submessages_waiting(&reader),
      Some([sample(1, 1), sample(2, 1), sample(1, 2)].concat())
    );
    assert_eq!(submessages_waiting(&reader), None, "one datagram");
    assert_eq!(
      a.last_and_sent_sequence_numbers(),
      (SequenceNumber::new(2), SequenceNumber::new(2))
    );

    assert!(admit(&b, 8).sent_directly);
    assert_eq!(submessages_waiting(&reader), Some(sample(2, 2).to_vec()));
    assert_eq!(submessages_waiting(&reader), None);
  }

  // A gathered datagram stays within the writers' datagram budget: the sample
  // that would overflow it sends what was gathered and starts the next one.
  // Each destination gets its own datagrams; a nested burst joins the outer.
  #[test]
  fn a_burst_is_cut_at_the_datagram_budget_and_kept_apart_per_destination() {
    let (r1, r2) = (
      UdpSocket::bind("127.0.0.1:0").unwrap(),
      UdpSocket::bind("127.0.0.1:0").unwrap(),
    );
    // One sample's message, measured: the header, then its submessages.
    let probe = writer_to(9, r1.local_addr().unwrap(), 1400);
    admit(&probe, 8);
    let mut datagram = [0u8; 4096];
    let one = r1.recv(&mut datagram).unwrap();
    let budget = 20 + 2 * (one - 20); // room for two samples, not three
    let a = writer_to(1, r1.local_addr().unwrap(), budget);
    let b = writer_to(2, r2.local_addr().unwrap(), budget);
    crate::coalesce_sends(|| {
      for _ in 0..3 {
        admit(&a, 8);
        crate::coalesce_sends(|| admit(&b, 8));
      }
      let first = submessages_waiting(&r1).expect("the full datagram went out");
      let data = |d: &[(&str, u8, i64)]| -> Vec<i64> {
        d.iter().filter(|s| s.0 == "DATA").map(|s| s.2).collect()
      };
      assert_eq!(data(&first), [1, 2]);
      assert_eq!(data(&submessages_waiting(&r2).unwrap()), [1, 2]);
      assert_eq!(submessages_waiting(&r1), None, "the third waits");
      crate::coalesce_sends(|| {});
      assert_eq!(
        submessages_waiting(&r1),
        None,
        "an inner burst does not send"
      );
    });
    let data = |r: &UdpSocket| -> Vec<i64> {
      submessages_waiting(r)
        .unwrap()
        .iter()
        .filter(|s| s.0 == "DATA")
        .map(|s| s.2)
        .collect()
    };
    assert_eq!(data(&r1), [3]);
    assert_eq!(data(&r2), [3]);
  }

  // With a direct route the writing thread sends the sample itself, DATA with
  // a HEARTBEAT for reliable writers, and marks it sent, so the event loop
  // (which is not woken) sends nothing more. The first HEARTBEAT asks for an
  // ACKNACK, the one right after it does not (final flag).
  #[test]
  fn a_sample_is_sent_by_the_writing_thread_on_a_direct_route() {
    let (buf, reader) = buffer_with_direct_route(true);
    let first = admit(&buf, 8);
    assert!(first.sent_directly, "{first:?}");
    assert_eq!(receive(&reader), (vec![1], vec![(1, 1, 7, false)]));
    hold_acknack_period(&buf);
    let second = admit(&buf, 8);
    assert!(second.sent_directly, "{second:?}");
    assert_eq!(receive(&reader), (vec![2], vec![(1, 2, 8, true)]));
    assert_eq!(
      buf.last_and_sent_sequence_numbers(),
      (SequenceNumber::new(2), SequenceNumber::new(2))
    );

    let (buf, reader) = buffer_with_direct_route(false);
    assert!(admit(&buf, 8).sent_directly);
    assert_eq!(
      receive(&reader),
      (vec![1], vec![]),
      "best effort: no HEARTBEAT"
    );
  }

  // A directly sent sample asks its readers for an ACKNACK (HEARTBEAT without
  // the final flag) when none did for a period, or when half the send window
  // is unacknowledged; otherwise its HEARTBEAT is final, so readers that have
  // everything do not answer every sample.
  #[test]
  fn a_direct_send_asks_for_an_acknack_once_a_period_or_when_half_the_window_is_unacknowledged() {
    let final_flags = |reader: &UdpSocket, n: usize| -> Vec<bool> {
      (0..n).map(|_| receive(reader).1[0].3).collect()
    };
    let (buf, reader) = buffer_with_direct_route(true);
    let before = Instant::now();
    assert!(admit(&buf, 8).sent_directly);
    let asked = set_last_acknack_request(&buf, Some(Instant::now() + StdDuration::from_secs(3600)));
    assert!(asked.is_some_and(|t| t >= before), "{asked:?}");
    for _ in 0..2 {
      assert!(admit(&buf, 8).sent_directly);
    }
    assert_eq!(final_flags(&reader, 3), [false, true, true]);
    // A period after the last request, the next sample asks again.
    set_last_acknack_request(
      &buf,
      Some(Instant::now() - PIGGYBACK_ACKNACK_REQUEST_PERIOD),
    );
    assert!(admit(&buf, 8).sent_directly);
    hold_acknack_period(&buf);
    assert!(admit(&buf, 8).sent_directly);
    assert_eq!(final_flags(&reader, 2), [false, true]);

    // A reader acknowledged samples 1..=4 (window 100): samples 6..=53 leave up
    // to 49 unacknowledged (5..=53) and ask nothing; sample 54 makes it 50 and
    // asks; so does every one after it until an ACKNACK moves the frontier.
    buf.set_acked_frontier(Some(SequenceNumber::new(5)));
    for _ in 6..=55 {
      assert!(admit(&buf, 8).sent_directly);
    }
    let flags = final_flags(&reader, 50);
    assert!(flags[..48].iter().all(|&f| f), "{flags:?}");
    assert_eq!(flags[48..], [false, false], "{flags:?}");
    buf.set_acked_frontier(Some(SequenceNumber::new(56)));
    hold_acknack_period(&buf);
    assert!(admit(&buf, 8).sent_directly);
    assert_eq!(final_flags(&reader, 1), [true]);
  }

  #[test]
  fn an_acknack_is_asked_for_after_a_period_or_at_half_the_window() {
    let t0 = Instant::now();
    let p = PIGGYBACK_ACKNACK_REQUEST_PERIOD;
    assert!(piggyback_asks_for_acknack(None, t0, None, 100));
    assert!(!piggyback_asks_for_acknack(Some(t0), t0 + p / 2, None, 100));
    assert!(piggyback_asks_for_acknack(Some(t0), t0 + p, None, 100));
    assert!(!piggyback_asks_for_acknack(Some(t0), t0, Some(49), 100));
    assert!(piggyback_asks_for_acknack(Some(t0), t0, Some(50), 100));
    assert!(piggyback_asks_for_acknack(Some(t0), t0, Some(1), 1));
  }

  // A sample is sent directly only when everything before it is on the wire
  // and it fits one datagram; otherwise it is left to the event loop, and so
  // is everything after it until the event loop has caught up. Without a
  // route, nothing is sent directly.
  #[test]
  fn a_sample_goes_to_the_event_loop_when_it_cannot_be_sent_in_order_in_one_datagram() {
    let (buf, reader) = buffer_with_direct_route(true);
    let big = admit(&buf, 2000);
    assert!(!big.sent_directly, "larger than max_payload: {big:?}");
    let after = admit(&buf, 8);
    assert!(!after.sent_directly, "seq 1 not on the wire yet: {after:?}");
    assert_eq!(
      buf.last_and_sent_sequence_numbers(),
      (SequenceNumber::new(2), SequenceNumber::new(0))
    );
    // The event loop sends 1 and 2; then the next goes directly again.
    buf.set_sent_frontier(SequenceNumber::new(2));
    assert!(admit(&buf, 8).sent_directly);
    assert_eq!(receive(&reader).0, vec![3]);

    buf.set_direct_route(None);
    assert!(!admit(&buf, 8).sent_directly);
  }

  // A send that fails (here: an IPv6 destination on an IPv4 socket) leaves the
  // sample unsent, for the event loop.
  #[test]
  fn a_failed_direct_send_leaves_the_sample_to_the_event_loop() {
    let (buf, _reader) = buffer_with_direct_route(true);
    let mut route = buf.shared.inner.lock().unwrap().direct.clone().unwrap();
    route.destinations.push("[::1]:9".parse().unwrap());
    buf.set_direct_route(Some(route));
    assert!(!admit(&buf, 8).sent_directly);
    assert_eq!(
      buf.last_and_sent_sequence_numbers(),
      (SequenceNumber::new(1), SequenceNumber::new(0))
    );
  }

  // DDS v1.4 2.2.2.4.2.11: a write without a source timestamp is stamped with
  // the current time, and the stamp goes on the wire (INFO_TS). One given by the
  // application is kept.
  #[test]
  fn a_write_without_source_timestamp_is_stamped_with_the_time_of_the_write() {
    let buf = WriterSendBuffer::new(
      GUID::GUID_UNKNOWN,
      "t".to_string(),
      /* reliable_writer */ true,
      /* is_builtin */ true,
      /* volatile */ false,
      /* window_limit */ 100,
      /* backlog_limit */ 100,
      /* max_retain */ 100,
    );
    let before = Timestamp::now();
    assert!(admit_now(&buf, WriteOptions::default())); // seq 1
    let after = Timestamp::now();
    let given = Timestamp::from_ticks(12_345);
    assert!(admit_now(
      &buf,
      WriteOptionsBuilder::new().source_timestamp(given).build()
    )); // seq 2

    let stamped = buf
      .get_by_sn(SequenceNumber::new(1))
      .unwrap()
      .write_options
      .source_timestamp()
      .expect("a write without a timestamp is stamped");
    assert!(
      before <= stamped && stamped <= after,
      "{stamped:?} not within the write ({before:?} .. {after:?})"
    );
    assert_eq!(
      buf
        .get_by_sn(SequenceNumber::new(2))
        .unwrap()
        .write_options
        .source_timestamp(),
      Some(given)
    );
  }

  // A matched reliable reader that has not sent an ACKNACK yet reports
  // `all_acked_before == 0`. Sequence numbers start at 1, so that frontier
  // leaves nothing unacknowledged on a fresh writer: the window must still
  // admit `window_limit` samples.
  #[test]
  fn unacknowledged_reader_frontier_leaves_full_window() {
    let buf = WriterSendBuffer::new(
      GUID::GUID_UNKNOWN,
      "t".to_string(),
      /* reliable_writer */ true,
      /* is_builtin */ false,
      /* volatile */ true,
      /* window_limit */ 1,
      /* backlog_limit */ 1000,
      /* max_retain */ 1,
    );
    buf.set_acked_frontier(Some(SequenceNumber::zero()));

    assert!(admit_now(&buf, WriteOptions::default())); // seq 1
    assert!(!admit_now(&buf, WriteOptions::default())); // window full

    // The reader's first ACKNACK acknowledges seq 1.
    buf.set_acked_frontier(Some(SequenceNumber::new(2)));
    assert!(admit_now(&buf, WriteOptions::default())); // seq 2
  }

  // nonblocking-transmit: a best-effort writer that opted in via
  // `best_effort_may_block` is throttled by the unsent-backlog limit once the
  // socket stops draining, and released when the Writer advances the sent
  // frontier.
  #[test]
  fn backlog_limit_backpressures_best_effort_when_may_block() {
    let buf = WriterSendBuffer::new(
      GUID::GUID_UNKNOWN,
      "t".to_string(),
      /* reliable_writer */ false,
      /* is_builtin */ false,
      /* volatile */ true,
      /* window_limit */ 1000,
      /* backlog_limit */ 2,
      /* max_retain */ 1000,
    );

    // Nothing sent yet: backlog fills after two admissions.
    assert!(admit_now(&buf, may_block_opts())); // seq 1
    assert!(admit_now(&buf, may_block_opts())); // seq 2
    assert!(!admit_now(&buf, may_block_opts())); // backlog full (2 unsent, limit 2)

    // The Writer transmits seq 1; backlog drops to 1, room opens for one more.
    buf.set_sent_frontier(SequenceNumber::new(1));
    assert!(admit_now(&buf, may_block_opts())); // seq 3
    assert!(!admit_now(&buf, may_block_opts())); // full again (2 unsent: seq
                                                 // 2,3)
  }

  // By default (`best_effort_may_block == false`, DDS v1.4 2.2.2.4.2.11) a
  // best-effort write is never throttled at admission, even when the backlog is
  // already full -- congested samples are dropped later at the socket instead.
  #[test]
  fn backlog_limit_ignored_for_best_effort_by_default() {
    let buf = WriterSendBuffer::new(
      GUID::GUID_UNKNOWN,
      "t".to_string(),
      /* reliable_writer */ false,
      /* is_builtin */ false,
      /* volatile */ true,
      /* window_limit */ 1000,
      /* backlog_limit */ 1,
      /* max_retain */ 1000,
    );
    // Default WriteOptions => best_effort_may_block == false => never blocks.
    assert!(admit_now(&buf, WriteOptions::default()));
    assert!(admit_now(&buf, WriteOptions::default()));
    assert!(admit_now(&buf, WriteOptions::default())); // still admitted despite
                                                       // full backlog
  }

  // Built-in (discovery) writers must never be throttled by the backlog.
  #[test]
  fn backlog_limit_exempts_builtin() {
    let buf = WriterSendBuffer::new(
      GUID::GUID_UNKNOWN,
      "t".to_string(),
      false,
      /* is_builtin */ true,
      /* volatile */ true,
      1000,
      /* backlog_limit */ 1,
      /* max_retain */ 1000,
    );
    assert!(admit_now(&buf, may_block_opts()));
    assert!(admit_now(&buf, may_block_opts()));
    assert!(admit_now(&buf, may_block_opts())); // still admitted despite tiny
                                                // backlog limit
  }

  // A reliable writer whose reliable readers acknowledge as it writes retains its
  // KeepLast depth and what some reader has not acknowledged, not every sample
  // written since the last periodic cache cleaning (6 s: thousands at 1 kHz).
  #[test]
  fn acknowledged_samples_beyond_the_depth_go_on_insert() {
    let depth = 3;
    let buf = WriterSendBuffer::new(
      GUID::GUID_UNKNOWN,
      "t".to_string(),
      /* reliable_writer */ true,
      /* is_builtin */ false,
      /* volatile */ true,
      /* window_limit */ 1000,
      /* backlog_limit */ 1000,
      /* max_retain */ depth,
    );
    // A reliable reader matched, nothing acknowledged yet.
    buf.set_acked_frontier(Some(SequenceNumber::new(1)));
    for n in 1..=50 {
      assert!(admit_now(&buf, WriteOptions::default()));
      buf.set_sent_frontier(SequenceNumber::new(n));
      // The reader acknowledges all but the newest two samples.
      buf.set_acked_frontier(Some(SequenceNumber::new(n - 1)));
    }
    // Written 50, acknowledged before 49 when 50 went in: 48 (acknowledged, within
    // the depth), 49 and 50 (not acknowledged).
    assert_eq!(buf.retained_len(), depth);
    assert_eq!(buf.first_change_sequence_number(), SequenceNumber::new(48));
    assert!(buf.get_by_sn(SequenceNumber::new(47)).is_none());

    // The reader stops acknowledging: everything it has not acknowledged stays
    // for repair, however far beyond the depth.
    for n in 51..=60 {
      assert!(admit_now(&buf, WriteOptions::default()));
      buf.set_sent_frontier(SequenceNumber::new(n));
    }
    assert_eq!(buf.retained_len(), 12); // 49..=60
    assert!(buf.get_by_sn(SequenceNumber::new(49)).is_some());

    // It acknowledges everything, even beyond what the writer counts as sent:
    // what was sent goes down to the depth, what was not stays.
    buf.set_acked_frontier(Some(SequenceNumber::new(66)));
    for _ in 61..=65 {
      assert!(admit_now(&buf, WriteOptions::default()));
    }
    assert_eq!(buf.retained_len(), 5); // 61..=65
    assert_eq!(buf.first_change_sequence_number(), SequenceNumber::new(61));
  }

  // The ring of retained samples finds each by its sequence number as samples
  // come in at one end and leave at the other, around the ring's wrap.
  #[test]
  fn sample_history_finds_samples_by_sequence_number() {
    let change = |sn: i64| {
      CacheChange::new(
        GUID::GUID_UNKNOWN,
        SequenceNumber::new(sn),
        WriteOptions::default(),
        sample(),
      )
    };
    let sn = SequenceNumber::new;
    let mut h = SampleHistory::default();
    assert_eq!(h.oldest(), None);
    assert!(h.get(sn(0)).is_none());
    for n in 5..=8 {
      h.push(change(n));
    }
    assert_eq!((h.len(), h.oldest()), (4, Some(sn(5))));
    for n in 1..=9 {
      let found = h.get(sn(n)).map(|cc| cc.sequence_number);
      assert_eq!(found, (5..=8).contains(&n).then(|| sn(n)), "{n}");
    }
    // Slide the window far past the ring's first capacity.
    for n in 9..=100 {
      h.push(change(n));
      assert_eq!(h.pop_oldest(), Some(sn(n - 4)));
    }
    assert_eq!((h.len(), h.oldest()), (4, Some(sn(97))));
    assert_eq!(h.get(sn(99)).map(|cc| cc.sequence_number), Some(sn(99)));
    assert!(h.get(sn(96)).is_none() && h.get(sn(101)).is_none());
    assert_eq!(h.remove_before(sn(99)), 2);
    assert_eq!(h.remove_before(sn(50)), 0);
    assert_eq!(h.remove_before(sn(1000)), 2);
    assert_eq!((h.len(), h.oldest(), h.pop_oldest()), (0, None, None));
    // Empty, it takes any sequence number next (a writer's buffer after cleaning).
    h.push(change(500));
    assert_eq!(h.get(sn(500)).map(|cc| cc.sequence_number), Some(sn(500)));
  }

  // Cleaning removes in place what it drops and keeps the rest.
  #[test]
  fn remove_changes_before_keeps_the_rest() {
    let buf = WriterSendBuffer::new(
      GUID::GUID_UNKNOWN,
      "t".to_string(),
      true,
      false,
      /* volatile */ false,
      1000,
      1000,
      1000,
    );
    for _ in 1..=20 {
      assert!(admit_now(&buf, WriteOptions::default()));
    }
    buf.remove_changes_before(SequenceNumber::new(15));
    assert_eq!(buf.retained_len(), 6);
    assert_eq!(buf.first_change_sequence_number(), SequenceNumber::new(15));
    assert!(buf.get_by_sn(SequenceNumber::new(14)).is_none());
    assert!(buf.get_by_sn(SequenceNumber::new(20)).is_some());
    buf.remove_changes_before(SequenceNumber::new(3)); // nothing before 15 left
    assert_eq!(buf.retained_len(), 6);
    buf.remove_changes_before(SequenceNumber::new(100));
    assert_eq!(buf.retained_len(), 0);
  }

  // A best-effort (non-blocking, DDS-default) writer is never throttled at
  // admission, but the retained buffer must stay bounded by `max_retain`
  // (KeepLast "newest wins"): the leak fix. Every write is admitted, yet the
  // buffer never holds more than `max_retain` samples, and it retains the
  // newest ones (oldest are evicted on insert).
  #[test]
  fn best_effort_default_bounded_by_max_retain() {
    let max_retain = 4;
    let buf = WriterSendBuffer::new(
      GUID::GUID_UNKNOWN,
      "t".to_string(),
      /* reliable_writer */ false,
      /* is_builtin */ false,
      /* volatile */ true,
      /* window_limit */ 1000,
      /* backlog_limit */ 1000,
      max_retain,
    );

    for _ in 0..100 {
      // Default WriteOptions => best-effort, non-blocking => always admitted.
      assert!(admit_now(&buf, WriteOptions::default()));
      // Invariant after every insert: never exceeds the retain bound.
      assert!(buf.retained_len() <= max_retain);
    }

    // Exactly `max_retain` retained, and they are the newest sequence numbers.
    assert_eq!(buf.retained_len(), max_retain);
    let last = buf.last_change_sequence_number();
    assert_eq!(last, SequenceNumber::new(100));
    let first = buf.first_change_sequence_number();
    assert_eq!(first, SequenceNumber::new(100 - max_retain as i64 + 1));
    // Newest is retained, an evicted older one is gone.
    assert!(buf.get_by_sn(last).is_some());
    assert!(buf.get_by_sn(SequenceNumber::new(1)).is_none());
  }

  // A durable (non-VOLATILE) reliable writer must NOT drop on insert even before
  // a reader matches: it retains samples for late-joining readers. The
  // `max_retain` bound does not apply to it.
  #[test]
  fn durable_reliable_writer_not_trimmed_before_match() {
    let max_retain = 2;
    let buf = WriterSendBuffer::new(
      GUID::GUID_UNKNOWN,
      "t".to_string(),
      /* reliable_writer */ true,
      /* is_builtin */ false,
      /* volatile */ false, // TRANSIENT_LOCAL etc: keep for late joiners
      /* window_limit */ 1000,
      /* backlog_limit */ 1000,
      max_retain,
    );
    // No reliable readers matched yet => admission not window-throttled.
    for _ in 0..10 {
      assert!(admit_now(&buf, WriteOptions::default()));
    }
    // Durable path keeps everything for potential late-joiner delivery / repair
    // despite tiny max_retain.
    assert_eq!(buf.retained_len(), 10);
  }

  // A VOLATILE reliable writer with no matched reliable reader trims KeepLast on
  // insert: there is no late joiner to serve, so retaining unacknowledged samples
  // is pointless and would create a huge post-match repair backlog (the reliable
  // flat-out throughput fix). Once a reliable reader matches
  // (`set_acked_frontier(Some(..))`), trimming stops and everything is retained
  // for repair.
  #[test]
  fn volatile_reliable_writer_trimmed_until_reader_matches() {
    let max_retain = 4;
    let buf = WriterSendBuffer::new(
      GUID::GUID_UNKNOWN,
      "t".to_string(),
      /* reliable_writer */ true,
      /* is_builtin */ false,
      /* volatile */ true,
      /* window_limit */ 1000,
      /* backlog_limit */ 1000,
      max_retain,
    );
    // No reliable reader yet: admitted freely (backlog has room) but trimmed to
    // KeepLast so the buffer cannot balloon before discovery completes.
    for _ in 0..100 {
      assert!(admit_now(&buf, WriteOptions::default()));
      assert!(buf.retained_len() <= max_retain);
    }
    assert_eq!(buf.retained_len(), max_retain);

    // A reliable reader matches: from now on the writer retains everything for
    // repair (no trimming), even past max_retain.
    buf.set_acked_frontier(Some(SequenceNumber::new(101)));
    for _ in 0..10 {
      assert!(admit_now(&buf, WriteOptions::default()));
    }
    assert_eq!(buf.retained_len(), max_retain + 10);
  }

  // An acknowledgement notifies the condition variable (a system call) only when a
  // thread is blocked on it, and then wakes that thread: a producer waiting for room in
  // the window, and one waiting for its samples to be acknowledged.
  #[test]
  fn an_acknowledgement_notifies_only_while_a_thread_is_blocked_and_wakes_it() {
    let buf = WriterSendBuffer::new(
      GUID::GUID_UNKNOWN,
      "t".to_string(),
      /* reliable_writer */ true,
      /* is_builtin */ false,
      /* volatile */ true,
      /* window_limit */ 2,
      /* backlog_limit */ 1000,
      /* max_retain */ 2,
    );
    let notified = |buf: &WriterSendBuffer| buf.shared.inner.lock().unwrap().notified;
    let blocked = |buf: &WriterSendBuffer| buf.shared.inner.lock().unwrap().blocked_threads;
    buf.set_acked_frontier(Some(SequenceNumber::zero()));
    for acked_before in 2..5 {
      assert!(admit_now(&buf, WriteOptions::default()));
      buf.set_acked_frontier(Some(SequenceNumber::new(acked_before)));
    }
    assert_eq!(notified(&buf), 0, "notified with no thread blocked");

    // Seq 4 and 5 fill the window; the third write blocks until seq 4 is acknowledged.
    assert!(admit_now(&buf, WriteOptions::default()));
    assert!(admit_now(&buf, WriteOptions::default()));
    let producer = {
      let buf = buf.clone();
      std::thread::spawn(move || {
        matches!(
          buf.admit_blocking(WriteOptions::default(), sample(), None),
          Admission::Admitted(_)
        )
      })
    };
    while blocked(&buf) == 0 {
      std::thread::yield_now();
    }
    buf.set_acked_frontier(Some(SequenceNumber::new(5)));
    assert!(
      producer.join().unwrap(),
      "the blocked producer was not admitted"
    );
    assert_eq!(notified(&buf), 1);

    let waiter = {
      let buf = buf.clone();
      std::thread::spawn(move || {
        buf.wait_for_acked_through(SequenceNumber::new(6), StdDuration::from_secs(600))
      })
    };
    while blocked(&buf) == 0 {
      std::thread::yield_now();
    }
    buf.set_acked_frontier(Some(SequenceNumber::new(7)));
    assert!(
      waiter.join().unwrap(),
      "the waiter was not told of the acknowledgement"
    );
    assert_eq!(notified(&buf), 2);
    assert_eq!(blocked(&buf), 0);
  }
}
