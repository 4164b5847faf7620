//! Test support: servo-board emulators on pseudo-terminal pairs.
//!
//! A [`Board`] opens a pty pair, points a symlink (the "device path" the backend opens) at
//! the slave side and plays a board on the master side in a thread: Dynamixel 2.0 / 1.0
//! servos (ping, read, write, sync write, sync read, status packets, error bits), a Pololu
//! Maestro (targets, speed, acceleration, get position, get errors) or an SSC-32U (group
//! moves, QP, VER). It parses requests with the crate's decoders and answers with its
//! encoders (both checked against the ROBOTIS SDK and the manuals in serial_sdk.rs and
//! serial_packets.rs). Every goal packet received is logged, in units. Faults on demand:
//! unplug / replug (the pty closes; a new one appears at the same path), garbage replies,
//! missing servos, error bits.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{Read as _, Write as _};
use std::os::fd::AsFd as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use joint_bridge::serial::{Decoded, Protocol, dynamixel1 as d1, dynamixel2 as d2, maestro, ssc32};

/// One emulated servo (or channel).
#[derive(Debug, Clone, Default)]
pub struct Servo {
    /// Present position, units (ticks, or µs for the PWM boards; 0 = no pulse).
    pub position: f64,
    /// Torque on.
    pub torque: bool,
    /// Status error byte (Dynamixel).
    pub error: u8,
    /// Hardware Error Status (Dynamixel X).
    pub hardware_error: u8,
}

/// What the emulated board knows and does.
#[derive(Debug, Default)]
pub struct State {
    /// Servos by id or channel. Ids not here do not answer.
    pub servos: BTreeMap<u8, Servo>,
    /// Each goal packet received: (id, units) per servo, in packet order.
    pub goals: Vec<Vec<(u8, f64)>>,
    /// Other commands received, for the lifecycle checks ("torque on", "speed 3 200"...).
    pub commands: Vec<String>,
    /// The next this many replies are replaced by garbage.
    pub garbage_replies: u32,
    /// The next this many replies get a flipped checksum/CRC byte.
    pub corrupt_replies: u32,
    /// Maestro error bits to report.
    pub maestro_errors: u16,
}

/// An emulated board on a pty, reachable at `path`.
pub struct Board {
    pub protocol: Protocol,
    pub path: PathBuf,
    pub state: Arc<Mutex<State>>,
    run: Option<(Arc<AtomicBool>, JoinHandle<()>)>,
}

impl Board {
    /// A board with these servos (id → initial position, units), at `path` (a symlink).
    pub fn new(protocol: Protocol, path: &Path, servos: &[(u8, f64)]) -> Board {
        let state = State {
            servos: servos
                .iter()
                .map(|&(id, p)| {
                    (
                        id,
                        Servo {
                            position: p,
                            ..Servo::default()
                        },
                    )
                })
                .collect(),
            ..State::default()
        };
        let mut b = Board {
            protocol,
            path: path.to_path_buf(),
            state: Arc::new(Mutex::new(state)),
            run: None,
        };
        b.plug();
        b
    }

    /// A new pty pair at the path, and the emulator on it.
    pub fn plug(&mut self) {
        assert!(self.run.is_none(), "already plugged");
        let pty = nix::pty::openpty(None, None).unwrap();
        // Raw from the start: no echo, no line editing, every byte through unchanged.
        let mut t = nix::sys::termios::tcgetattr(pty.slave.as_fd()).unwrap();
        nix::sys::termios::cfmakeraw(&mut t);
        nix::sys::termios::tcsetattr(pty.slave.as_fd(), nix::sys::termios::SetArg::TCSANOW, &t)
            .unwrap();
        let slave_path = nix::unistd::ttyname(pty.slave.as_fd()).unwrap();
        let _ = std::fs::remove_file(&self.path);
        std::os::unix::fs::symlink(&slave_path, &self.path).unwrap();
        let stop = Arc::new(AtomicBool::new(false));
        let state = self.state.clone();
        let protocol = self.protocol;
        let s = stop.clone();
        let master = File::from(pty.master);
        // The slave stays open here while plugged, so the master never sees a hang-up
        // between the backend's reconnections.
        let slave = pty.slave;
        let handle = std::thread::spawn(move || {
            emulate(protocol, master, &state, &s);
            drop(slave);
        });
        self.run = Some((stop, handle));
    }

    /// Unplugs: the emulator stops and both ends of the pty close; the path dangles.
    pub fn unplug(&mut self) {
        if let Some((stop, handle)) = self.run.take() {
            stop.store(true, Ordering::SeqCst);
            handle.join().unwrap();
        }
    }

    pub fn with<R>(&self, f: impl FnOnce(&mut State) -> R) -> R {
        f(&mut self.state.lock().unwrap())
    }

    /// Waits (up to 10 s) until the emulator has handled what makes `done` true: commands
    /// without a reply reach it asynchronously. Returns whether it did.
    pub fn wait_until(&self, done: impl Fn(&State) -> bool) -> bool {
        for _ in 0..1000 {
            if done(&self.state.lock().unwrap()) {
                return true;
            }
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        false
    }
}

impl Drop for Board {
    fn drop(&mut self) {
        self.unplug();
        let _ = std::fs::remove_file(&self.path);
    }
}

fn emulate(protocol: Protocol, mut master: File, state: &Mutex<State>, stop: &AtomicBool) {
    let mut buf: Vec<u8> = Vec::new();
    let mut chunk = [0u8; 4096];
    while !stop.load(Ordering::SeqCst) {
        let mut fds = [nix::poll::PollFd::new(
            master.as_fd(),
            nix::poll::PollFlags::POLLIN,
        )];
        match nix::poll::poll(&mut fds, nix::poll::PollTimeout::from(20u16)) {
            Ok(0) => continue,
            Ok(_) => {}
            Err(_) => continue,
        }
        let n = match master.read(&mut chunk) {
            Ok(n) => n,
            // EIO: nobody has the slave open right now.
            Err(_) => {
                std::thread::sleep(std::time::Duration::from_millis(5));
                continue;
            }
        };
        buf.extend_from_slice(&chunk[..n]);
        loop {
            let (reply, used) = {
                let mut st = state.lock().unwrap();
                match handle(protocol, &buf, &mut st) {
                    Some(x) => x,
                    None => break,
                }
            };
            buf.drain(..used);
            if !reply.is_empty() {
                let reply = {
                    let mut st = state.lock().unwrap();
                    damage(protocol, reply, &mut st)
                };
                let _ = master.write_all(&reply);
            }
        }
    }
}

fn damage(protocol: Protocol, mut reply: Vec<u8>, st: &mut State) -> Vec<u8> {
    if st.garbage_replies > 0 {
        st.garbage_replies -= 1;
        // Plausible-looking junk: a header start and noise, same length.
        return (0..reply.len())
            .map(|i| if i < 2 { 0xFF } else { (i * 37 % 251) as u8 })
            .collect();
    }
    if st.corrupt_replies > 0 && matches!(protocol, Protocol::Dynamixel1 | Protocol::Dynamixel2) {
        st.corrupt_replies -= 1;
        let n = reply.len();
        reply[n - 1] ^= 0x40;
    }
    reply
}

/// Handles one request at the start of `buf`: the reply and the bytes used; `None` when
/// more bytes are needed.
fn handle(protocol: Protocol, buf: &[u8], st: &mut State) -> Option<(Vec<u8>, usize)> {
    if buf.is_empty() {
        return None;
    }
    match protocol {
        Protocol::Dynamixel2 => match d2::decode_packet(buf) {
            Decoded::Incomplete => None,
            Decoded::Invalid { skip, .. } => Some((Vec::new(), skip)),
            Decoded::Packet { value, used } => Some((dxl2(&value, st), used)),
        },
        Protocol::Dynamixel1 => match d1::decode_packet(buf) {
            Decoded::Incomplete => None,
            Decoded::Invalid { skip, .. } => Some((Vec::new(), skip)),
            Decoded::Packet { value, used } => Some((dxl1(&value, st), used)),
        },
        Protocol::Maestro => match maestro::decode_command(buf) {
            Decoded::Incomplete => None,
            Decoded::Invalid { skip, .. } => Some((Vec::new(), skip)),
            Decoded::Packet { value, used } => Some((pololu(value, st), used)),
        },
        Protocol::Ssc32 => {
            let end = buf.iter().position(|&b| b == b'\r')?;
            let reply = match ssc32::decode_line(&buf[..end]) {
                Ok(line) => lynx(line, st),
                Err(_) => Vec::new(),
            };
            Some((reply, end + 1))
        }
    }
}

fn dxl2(p: &d2::Packet, st: &mut State) -> Vec<u8> {
    use d2::instruction as i;
    let status = |st: &State, id: u8, params: &[u8]| -> Vec<u8> {
        let e = st.servos.get(&id).map_or(0, |s| s.error);
        d2::status_packet(id, e, params)
    };
    match p.instruction {
        i::PING if st.servos.contains_key(&p.id) => status(st, p.id, &[0x06, 0x04, 0x26]),
        i::READ if st.servos.contains_key(&p.id) => {
            let addr = u16::from_le_bytes([p.params[0], p.params[1]]);
            let s = &st.servos[&p.id];
            let data = if addr == d2::address::HARDWARE_ERROR_STATUS {
                vec![s.hardware_error]
            } else {
                (s.position.round() as i32).to_le_bytes().to_vec()
            };
            status(st, p.id, &data)
        }
        i::SYNC_WRITE => {
            let addr = u16::from_le_bytes([p.params[0], p.params[1]]);
            let len = usize::from(u16::from_le_bytes([p.params[2], p.params[3]]));
            let mut goals = Vec::new();
            for c in p.params[4..].chunks(len + 1) {
                let id = c[0];
                if addr == d2::address::GOAL_POSITION {
                    let v = f64::from(i32::from_le_bytes([c[1], c[2], c[3], c[4]]));
                    goals.push((id, v));
                    if let Some(s) = st.servos.get_mut(&id)
                        && s.torque
                    {
                        s.position = v;
                    }
                } else if addr == d2::address::TORQUE_ENABLE {
                    if let Some(s) = st.servos.get_mut(&id) {
                        s.torque = c[1] == 1;
                    }
                    st.commands.push(format!("torque {id} {}", c[1]));
                }
            }
            if !goals.is_empty() {
                st.goals.push(goals);
            }
            Vec::new()
        }
        i::SYNC_READ => {
            let mut out = Vec::new();
            for &id in &p.params[4..] {
                if let Some(s) = st.servos.get(&id) {
                    let pos = (s.position.round() as i32).to_le_bytes();
                    out.extend(status(st, id, &pos));
                }
            }
            out
        }
        _ => Vec::new(),
    }
}

fn dxl1(p: &d1::Packet, st: &mut State) -> Vec<u8> {
    use d1::instruction as i;
    let status = |st: &State, id: u8, params: &[u8]| -> Vec<u8> {
        let e = st.servos.get(&id).map_or(0, |s| s.error);
        d1::status_packet(id, e, params)
    };
    match p.code {
        i::PING if st.servos.contains_key(&p.id) => status(st, p.id, &[]),
        i::READ if st.servos.contains_key(&p.id) => {
            let pos = (st.servos[&p.id].position.round() as u16).to_le_bytes();
            status(st, p.id, &pos)
        }
        i::SYNC_WRITE => {
            let addr = p.params[0];
            let len = usize::from(p.params[1]);
            let mut goals = Vec::new();
            for c in p.params[2..].chunks(len + 1) {
                let id = c[0];
                if addr == d1::address::GOAL_POSITION {
                    let v = f64::from(u16::from_le_bytes([c[1], c[2]]));
                    goals.push((id, v));
                    if let Some(s) = st.servos.get_mut(&id)
                        && s.torque
                    {
                        s.position = v;
                    }
                } else if addr == d1::address::TORQUE_ENABLE {
                    if let Some(s) = st.servos.get_mut(&id) {
                        s.torque = c[1] == 1;
                    }
                    st.commands.push(format!("torque {id} {}", c[1]));
                }
            }
            if !goals.is_empty() {
                st.goals.push(goals);
            }
            Vec::new()
        }
        _ => Vec::new(),
    }
}

fn pololu(c: maestro::Command, st: &mut State) -> Vec<u8> {
    use maestro::Command as C;
    match c {
        C::SetTarget(ch, q) => {
            st.commands.push(format!("target {ch} {q}"));
            if let Some(s) = st.servos.get_mut(&ch) {
                s.position = f64::from(q) / 4.0;
            }
            Vec::new()
        }
        C::SetMultipleTargets(first, qs) => {
            let mut goals = Vec::new();
            for (k, q) in qs.into_iter().enumerate() {
                let ch = first + k as u8;
                goals.push((ch, f64::from(q) / 4.0));
                if let Some(s) = st.servos.get_mut(&ch) {
                    s.position = f64::from(q) / 4.0;
                }
            }
            if goals.iter().all(|g| g.1 == 0.0) {
                st.commands.push(format!("off {}", goals.len()));
            } else {
                st.goals.push(goals);
            }
            Vec::new()
        }
        C::SetSpeed(ch, v) => {
            st.commands.push(format!("speed {ch} {v}"));
            Vec::new()
        }
        C::SetAcceleration(ch, v) => {
            st.commands.push(format!("acceleration {ch} {v}"));
            Vec::new()
        }
        C::GetPosition(ch) => {
            let q = st
                .servos
                .get(&ch)
                .map_or(0, |s| (s.position * 4.0).round() as u16);
            q.to_le_bytes().to_vec()
        }
        C::GetErrors => {
            let e = st.maestro_errors;
            st.maestro_errors = 0;
            e.to_le_bytes().to_vec()
        }
    }
}

fn lynx(line: ssc32::Line, st: &mut State) -> Vec<u8> {
    match line {
        ssc32::Line::Version => b"SSC32-V2.50USB\r".to_vec(),
        ssc32::Line::Query(chs) => chs
            .iter()
            .map(|ch| {
                st.servos
                    .get(ch)
                    .map_or(0, |s| (s.position / 10.0).round() as u8)
            })
            .collect(),
        ssc32::Line::MoveAt(moves, time) => {
            // Recorded as commands; the emulator's output pulse follows at once (its query
            // then says the move is over).
            for &(ch, _, speed) in &moves {
                if let Some(v) = speed {
                    st.commands.push(format!("speed {ch} {v}"));
                }
            }
            lynx(
                ssc32::Line::Move(moves.iter().map(|&(c, p, _)| (c, p)).collect(), time),
                st,
            )
        }
        ssc32::Line::Move(moves, _) => {
            for &(ch, pw) in &moves {
                if let Some(s) = st.servos.get_mut(&ch) {
                    s.position = f64::from(pw);
                }
            }
            if moves.iter().all(|m| m.1 == 0) {
                st.commands.push(format!("off {}", moves.len()));
            } else {
                st.goals
                    .push(moves.iter().map(|&(c, p)| (c, f64::from(p))).collect());
            }
            Vec::new()
        }
    }
}

/// A fresh folder for this test's device symlinks.
pub fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("biped-serial-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}
