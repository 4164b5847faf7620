// PollEventSource and PollEventSender are an event communication channel that
// carries no data. The receiver is always a mio 1.2 `Source`, and also a mio
// 0.8 `Source` when that optional compatibility feature is enabled.
//
// The internal reactors do not use this channel.

macro_rules! socketpair_bridge {
  ($modname:ident, $mio:ident) => {
    mod $modname {
      use std::{
        io,
        io::{Read, Write},
        sync::{
          atomic::{AtomicBool, Ordering},
          Arc, Mutex,
        },
      };
      #[cfg(not(target_os = "windows"))]
      use std::os::fd::OwnedFd;
      #[cfg(target_os = "windows")]
      use std::{thread::sleep, time::Duration};

      #[allow(unused_imports)]
      use log::{debug, error, info};
      #[cfg(not(target_os = "windows"))]
      use socketpair::{socketpair_stream, SocketpairStream};

      pub struct Source {
        rec: Mutex<$mio::net::TcpStream>,
        // The sending end, for the one byte that tells a new registration about what
        // was sent before it.
        kick: Sender,
        // How many drains read the socket (tests: a drain with nothing written reads
        // nothing).
        #[cfg(test)]
        pub(super) reads: std::sync::atomic::AtomicUsize,
      }

      // Writes a byte for each event, but only while the Source is registered with a
      // poll: a channel nobody polls (every reader's, when the application uses async
      // or the plain API) would otherwise cost a system call per event on the event
      // loop's thread, failing once its buffer is full, since nothing drains it.
      #[derive(Clone)]
      pub struct Sender {
        send: Arc<Mutex<$mio::net::TcpStream>>,
        registered: Arc<AtomicBool>,
      }

      fn pair(rec: $mio::net::TcpStream, send: $mio::net::TcpStream) -> (Source, Sender) {
        let sender = Sender {
          send: Arc::new(Mutex::new(send)),
          registered: Arc::new(AtomicBool::new(false)),
        };
        (
          Source {
            rec: Mutex::new(rec),
            kick: sender.clone(),
            #[cfg(test)]
            reads: std::sync::atomic::AtomicUsize::new(0),
          },
          sender,
        )
      }

      #[cfg(not(target_os = "windows"))]
      fn set_non_blocking(s: SocketpairStream) -> io::Result<SocketpairStream> {
        let owned_fd = OwnedFd::from(s);
        let std_socket = std::net::TcpStream::from(owned_fd);
        std_socket.set_nonblocking(true)?;
        Ok(SocketpairStream::from(OwnedFd::from(std_socket)))
      }

      #[cfg(not(target_os = "windows"))]
      pub fn make() -> io::Result<(Source, Sender)> {
        let (rec_sps, send_sps) = socketpair_stream()?;
        let rec_sps = set_non_blocking(rec_sps)?;
        let send_sps = set_non_blocking(send_sps)?;
        let rec = $mio::net::TcpStream::from_std(std::net::TcpStream::from(OwnedFd::from(rec_sps)));
        let send =
          $mio::net::TcpStream::from_std(std::net::TcpStream::from(OwnedFd::from(send_sps)));
        Ok(pair(rec, send))
      }

      #[cfg(target_os = "windows")]
      pub fn make() -> io::Result<(Source, Sender)> {
        let listener = $mio::net::TcpListener::bind("127.0.0.1:0".parse().unwrap())?;
        let addr = listener.local_addr()?;
        let rec = $mio::net::TcpStream::connect(addr)?;
        let mut accepted = listener.accept();
        while accepted.is_err() {
          sleep(Duration::from_millis(100));
          accepted = listener.accept();
        }
        let (send, _addr_send) = accepted?;
        debug!("IPC socket: {addr:#?} <-> {_addr_send:#?}");
        Ok(pair(rec, send))
      }

      impl Sender {
        pub fn send(&self) {
          if self.registered.load(Ordering::Acquire) {
            self.write_byte();
          }
        }

        fn write_byte(&self) {
          match self.send.lock().unwrap().write(&[0xcc]) {
            Ok(_b) => {}
            Err(e) => info!("PollEventSender.send: {e}"),
          }
        }
      }

      impl Source {
        // Nothing is written while no poll has the source (`Sender::send`), so a drain
        // then has nothing to read: no system call. The bytes of a registration that
        // ended stay until the next one, whose first poll reads them with its own.
        pub fn drain(&self) {
          if !self.kick.registered.load(Ordering::Acquire) {
            return;
          }
          #[cfg(test)]
          self.reads.fetch_add(1, Ordering::Relaxed);
          let mut buf = Vec::with_capacity(16);
          match self.rec.lock().unwrap().read_to_end(&mut buf) {
            Ok(_) => (),
            Err(err) => match err.kind() {
              io::ErrorKind::WouldBlock => {}
              other_kind => info!("PollEventSource.drain(): {other_kind}"),
            },
          }
        }

        #[cfg(test)]
        pub fn pending_bytes(&self) -> usize {
          let mut buf = Vec::new();
          let _ = self.rec.lock().unwrap().read_to_end(&mut buf);
          buf.len()
        }
      }

      impl $mio::event::Source for Source {
        fn register(
          &mut self,
          registry: &$mio::Registry,
          token: $mio::Token,
          interests: $mio::Interest,
        ) -> io::Result<()> {
          self
            .rec
            .lock()
            .unwrap()
            .register(registry, token, interests)?;
          // Events from now on are written; one byte stands for any that came before,
          // so the first poll sees the source readable and the owner looks.
          self.kick.registered.store(true, Ordering::Release);
          self.kick.write_byte();
          Ok(())
        }

        fn reregister(
          &mut self,
          registry: &$mio::Registry,
          token: $mio::Token,
          interests: $mio::Interest,
        ) -> io::Result<()> {
          self
            .rec
            .lock()
            .unwrap()
            .reregister(registry, token, interests)
        }

        fn deregister(&mut self, registry: &$mio::Registry) -> io::Result<()> {
          self.kick.registered.store(false, Ordering::Release);
          self.rec.lock().unwrap().deregister(registry)
        }
      }
    }
  };
}

#[cfg(feature = "mio_08")]
socketpair_bridge!(bridge_08, mio_08);
socketpair_bridge!(bridge_1, mio1);

pub struct PollEventSource {
  #[cfg(feature = "mio_08")]
  mio08: bridge_08::Source,
  mio1: bridge_1::Source,
}

#[derive(Clone)]
pub struct PollEventSender {
  #[cfg(feature = "mio_08")]
  mio08: bridge_08::Sender,
  mio1: bridge_1::Sender,
}

pub fn make_poll_channel() -> std::io::Result<(PollEventSource, PollEventSender)> {
  #[cfg(feature = "mio_08")]
  let (mio08_source, mio08_sender) = bridge_08::make()?;
  let (mio1_source, mio1_sender) = bridge_1::make()?;
  Ok((
    PollEventSource {
      #[cfg(feature = "mio_08")]
      mio08: mio08_source,
      mio1: mio1_source,
    },
    PollEventSender {
      #[cfg(feature = "mio_08")]
      mio08: mio08_sender,
      mio1: mio1_sender,
    },
  ))
}

impl PollEventSender {
  pub fn send(&self) {
    #[cfg(feature = "mio_08")]
    self.mio08.send();
    self.mio1.send();
  }
}

impl PollEventSource {
  /// Drain sent bytes so the socketpair can trigger again. Call before acting
  /// on the event.
  pub fn drain(&self) {
    #[cfg(feature = "mio_08")]
    self.mio08.drain();
    self.mio1.drain();
  }
}

#[cfg(feature = "mio_08")]
impl mio_08::event::Source for PollEventSource {
  fn register(
    &mut self,
    registry: &mio_08::Registry,
    token: mio_08::Token,
    interests: mio_08::Interest,
  ) -> std::io::Result<()> {
    self.mio08.register(registry, token, interests)
  }

  fn reregister(
    &mut self,
    registry: &mio_08::Registry,
    token: mio_08::Token,
    interests: mio_08::Interest,
  ) -> std::io::Result<()> {
    self.mio08.reregister(registry, token, interests)
  }

  fn deregister(&mut self, registry: &mio_08::Registry) -> std::io::Result<()> {
    self.mio08.deregister(registry)
  }
}

impl mio1::event::Source for PollEventSource {
  fn register(
    &mut self,
    registry: &mio1::Registry,
    token: mio1::Token,
    interests: mio1::Interest,
  ) -> std::io::Result<()> {
    self.mio1.register(registry, token, interests)
  }

  fn reregister(
    &mut self,
    registry: &mio1::Registry,
    token: mio1::Token,
    interests: mio1::Interest,
  ) -> std::io::Result<()> {
    self.mio1.reregister(registry, token, interests)
  }

  fn deregister(&mut self, registry: &mio1::Registry) -> std::io::Result<()> {
    self.mio1.deregister(registry)
  }
}

/// Bounded reader-notification queue with optional mio 0.6 readiness.
#[derive(Clone)]
pub(crate) struct NotificationSender {
  sender: std::sync::mpsc::SyncSender<()>,
  #[cfg(feature = "mio_06")]
  legacy_sender: mio_extras::channel::SyncSender<()>,
}

pub(crate) struct NotificationReceiver {
  receiver: std::sync::mpsc::Receiver<()>,
  #[cfg(feature = "mio_06")]
  legacy_receiver: mio_extras::channel::Receiver<()>,
}

pub(crate) fn notification_channel(capacity: usize) -> (NotificationSender, NotificationReceiver) {
  let (sender, receiver) = std::sync::mpsc::sync_channel(capacity);
  #[cfg(feature = "mio_06")]
  let (legacy_sender, legacy_receiver) = mio_extras::channel::sync_channel(capacity);
  (
    NotificationSender {
      sender,
      #[cfg(feature = "mio_06")]
      legacy_sender,
    },
    NotificationReceiver {
      receiver,
      #[cfg(feature = "mio_06")]
      legacy_receiver,
    },
  )
}

impl NotificationSender {
  pub(crate) fn try_send(&self, value: ()) -> Result<(), std::sync::mpsc::TrySendError<()>> {
    self.sender.try_send(value)?;
    #[cfg(feature = "mio_06")]
    let _ = self.legacy_sender.try_send(());
    Ok(())
  }
}

impl NotificationReceiver {
  pub(crate) fn try_recv(&self) -> Result<(), std::sync::mpsc::TryRecvError> {
    self.receiver.try_recv()
  }
}

#[cfg(feature = "mio_06")]
impl mio_06::Evented for NotificationReceiver {
  fn register(
    &self,
    poll: &mio_06::Poll,
    token: mio_06::Token,
    interest: mio_06::Ready,
    opts: mio_06::PollOpt,
  ) -> std::io::Result<()> {
    self.legacy_receiver.register(poll, token, interest, opts)
  }

  fn reregister(
    &self,
    poll: &mio_06::Poll,
    token: mio_06::Token,
    interest: mio_06::Ready,
    opts: mio_06::PollOpt,
  ) -> std::io::Result<()> {
    self.legacy_receiver.reregister(poll, token, interest, opts)
  }

  fn deregister(&self, poll: &mio_06::Poll) -> std::io::Result<()> {
    self.legacy_receiver.deregister(poll)
  }
}

#[cfg(test)]
mod tests {
  use std::time::Duration;

  use super::*;

  // Registers `source` with `poll` for reading, under token 7.
  fn register(source: &mut PollEventSource, poll: &mio1::Poll) {
    mio1::event::Source::register(
      source,
      poll.registry(),
      mio1::Token(7),
      mio1::Interest::READABLE,
    )
    .unwrap();
  }

  // A reader's poll channel that no one registers costs nothing per event; one that is
  // registered late still wakes its poll for what came before, and then for every event.
  #[test]
  fn poll_events_are_written_only_once_the_source_is_registered() {
    let (mut source, sender) = make_poll_channel().unwrap();
    for _ in 0..5 {
      sender.send();
    }
    assert_eq!(source.mio1.pending_bytes(), 0, "written while unregistered");

    let mut poll = mio1::Poll::new().unwrap();
    let mut events = mio1::Events::with_capacity(4);
    register(&mut source, &poll);
    poll
      .poll(&mut events, Some(Duration::from_secs(1)))
      .unwrap();
    assert!(
      events
        .iter()
        .any(|e| e.token() == mio1::Token(7) && e.is_readable()),
      "registering late must wake the poll for the events before it"
    );
    assert_eq!(source.mio1.pending_bytes(), 1);

    sender.send();
    sender.send();
    assert_eq!(source.mio1.pending_bytes(), 2);

    mio1::event::Source::deregister(&mut source, poll.registry()).unwrap();
    sender.send();
    assert_eq!(
      source.mio1.pending_bytes(),
      0,
      "written after deregistering"
    );
  }

  // A reader takes with `drain_read_notifications` before every take; with no poll on
  // its channel (ros2-client, the plain API) that drain reads nothing and makes no system
  // call. Once registered, it empties the channel as before.
  #[test]
  fn a_drain_reads_the_channel_only_while_it_is_registered() {
    use std::sync::atomic::Ordering;
    let (mut source, sender) = make_poll_channel().unwrap();
    for _ in 0..3 {
      sender.send();
      source.drain();
    }
    assert_eq!(
      source.mio1.reads.load(Ordering::Relaxed),
      0,
      "drains of an unregistered channel read its socket"
    );

    let poll = mio1::Poll::new().unwrap();
    register(&mut source, &poll);
    sender.send();
    source.drain();
    assert_eq!(source.mio1.reads.load(Ordering::Relaxed), 1);
    assert_eq!(
      source.mio1.pending_bytes(),
      0,
      "a drain while registered leaves bytes"
    );
  }
}
