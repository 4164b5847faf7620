//! [`SerialBackend`]: one servo board over a serial port, through the protocol modules.
//!
//! Lifecycle:
//! - `configure`: open the port, ping every servo (Dynamixel: ping; Maestro: get errors;
//!   SSC-32U: version), read the positions where the board can (Dynamixel: measured;
//!   Maestro, SSC-32U: the pulse the board already outputs, if any). A servo that does not
//!   answer is an error naming its joint and id.
//! - `activate`: torque on (Dynamixel), the board's speed and acceleration limits
//!   (Maestro). The move from the measured pose to the first command is the bridge's start
//!   ramp ([`crate::BridgeConfig::start_ramp_s`]): the backend sends what it is given.
//! - `write`: every goal in one packet (Dynamixel sync write, Maestro set multiple targets,
//!   SSC-32U group move), through the calibration and its limits; a non-finite angle is
//!   refused naming the joint.
//! - `read`: Dynamixel: present positions (sync read in 2.0, one read per servo in 1.0);
//!   the boards without feedback report the commanded positions (`measured: false`).
//! - `deactivate`: torque off (Dynamixel), pulses off (Maestro, SSC-32U); safe in any state.
//!
//! Faults: a reply that does not come within the timeout, or comes corrupted (bad header,
//! length, checksum or CRC), is dropped and counted ([`SerialCounters`]); the joint keeps
//! its last measured position. A servo's error bits are reported by name once when they
//! change ([`crate::Backend::take_notices`]). A port that fails (USB unplugged) is closed
//! and the call fails: the bridge then retries `configure` + `activate` with backoff.

use std::io::{ErrorKind, Write as _};
use std::time::{Duration, Instant};

use crate::backend::{Backend, BackendError, DiagnosticLevel, Diagnostics, Lifecycle, Reading};
use crate::limits::JointSpec;

use super::calibration::{Calibration, JointCalibration};
use super::{Decoded, Protocol, dynamixel1, dynamixel2, maestro, ssc32};

/// How to reach the board.
#[derive(Debug, Clone, PartialEq)]
pub struct SerialConfig {
    /// Serial device, e.g. `/dev/ttyUSB0`.
    pub port: String,
    /// Baud rate.
    pub baud: u32,
    /// The joints' servos (its protocol is the board's).
    pub calibration: Calibration,
    /// How long to wait for a reply (s).
    pub reply_timeout_s: f64,
}

/// What went wrong on the wire so far (kept across reconnects).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SerialCounters {
    /// Control cycles written.
    pub cycles: u64,
    /// Bytes sent.
    pub bytes_sent: u64,
    /// Bytes received.
    pub bytes_received: u64,
    /// Replies that did not come in time.
    pub timeouts: u64,
    /// Received byte runs dropped as corrupted (no header, bad length, wrong packet).
    pub corrupted: u64,
    /// Replies dropped for a bad checksum or CRC.
    pub checksum_errors: u64,
    /// Replies from an id that was not asked.
    pub unexpected_replies: u64,
    /// Replies carrying error bits.
    pub servo_errors: u64,
    /// Times the port failed (unplugged, I/O error).
    pub port_failures: u64,
    /// Successful configurations after the first (reconnections).
    pub reconnects: u64,
}

#[derive(Debug, Clone)]
struct Servo {
    joint: String,
    cal: JointCalibration,
    /// Last error bits reported (to report changes only).
    error_bits: u16,
    /// Last measured position (units).
    measured_units: Option<f64>,
    /// Last commanded position (units, as sent).
    commanded_units: Option<f64>,
}

/// A serial servo board as a [`Backend`].
pub struct SerialBackend {
    config: SerialConfig,
    port: Option<Box<dyn serialport::SerialPort>>,
    servos: Vec<Servo>,
    state: Lifecycle,
    counters: SerialCounters,
    notices: Vec<String>,
    rx: Vec<u8>,
    configured_once: bool,
    last_failure: Option<String>,
    /// SSC-32U: the first move to the rest pose, at the calibration's start speed, until
    /// the board outputs the commanded pulses.
    start_move: bool,
}

impl std::fmt::Debug for SerialBackend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SerialBackend")
            .field("protocol", &self.protocol())
            .field("port", &self.config.port)
            .field("baud", &self.config.baud)
            .field("state", &self.state)
            .field("counters", &self.counters)
            .finish()
    }
}

impl SerialBackend {
    /// A backend for this board; nothing is opened until `configure`.
    pub fn new(config: SerialConfig) -> Self {
        Self {
            config,
            port: None,
            servos: Vec::new(),
            state: Lifecycle::Unconfigured,
            counters: SerialCounters::default(),
            notices: Vec::new(),
            rx: Vec::new(),
            configured_once: false,
            start_move: false,
            last_failure: None,
        }
    }

    /// The board's protocol.
    pub fn protocol(&self) -> Protocol {
        self.config.calibration.protocol
    }
    /// The wire counters.
    pub fn counters(&self) -> SerialCounters {
        self.counters
    }
    /// Lifecycle state.
    pub fn state(&self) -> Lifecycle {
        self.state
    }

    fn io(&self, why: String) -> BackendError {
        BackendError::Io {
            backend: self.protocol().name().to_string(),
            why,
        }
    }

    fn joint_error(&self, servo: &Servo, why: String) -> BackendError {
        BackendError::Joint {
            backend: self.protocol().name().to_string(),
            joint: servo.joint.clone(),
            why: format!("servo {} {}: {why}", self.id_word(), servo.cal.id),
        }
    }

    fn id_word(&self) -> &'static str {
        if self.protocol().measures() {
            "id"
        } else {
            "channel"
        }
    }

    fn timeout(&self) -> Duration {
        Duration::from_secs_f64(self.config.reply_timeout_s.clamp(1e-4, 10.0))
    }

    /// The port failed: close it, remember why, and fail.
    fn port_failed(&mut self, what: &str, e: &std::io::Error) -> BackendError {
        self.port = None;
        self.rx.clear();
        self.counters.port_failures += 1;
        if self.state != Lifecycle::Unconfigured {
            self.state = Lifecycle::Error;
        }
        let why = format!(
            "port {} failed while {what}: {e}; closed, will reopen",
            self.config.port
        );
        self.last_failure = Some(why.clone());
        self.io(why)
    }

    fn send(&mut self, bytes: &[u8], what: &str) -> Result<(), BackendError> {
        let Some(port) = self.port.as_mut() else {
            return Err(self.io(format!("port {} is not open", self.config.port)));
        };
        // Stale bytes (a late reply) must not be taken for the answer to this request.
        self.rx.clear();
        let r = port
            .clear(serialport::ClearBuffer::Input)
            .map_err(std::io::Error::other)
            .and_then(|()| port.write_all(bytes))
            .and_then(|()| port.flush());
        match r {
            Ok(()) => {
                self.counters.bytes_sent += bytes.len() as u64;
                Ok(())
            }
            Err(e) => Err(self.port_failed(what, &e)),
        }
    }

    /// Receives one reply with `parse` before `deadline`. `Ok(None)`: timed out (counted).
    fn receive<T>(
        &mut self,
        parse: impl Fn(&[u8]) -> Decoded<T>,
        deadline: Instant,
        what: &str,
    ) -> Result<Option<T>, BackendError> {
        let mut chunk = [0u8; 256];
        loop {
            match parse(&self.rx) {
                Decoded::Packet { value, used } => {
                    self.rx.drain(..used.min(self.rx.len()));
                    return Ok(Some(value));
                }
                Decoded::Invalid { skip, why } => {
                    match why {
                        super::Corruption::BadChecksum => self.counters.checksum_errors += 1,
                        _ => self.counters.corrupted += 1,
                    }
                    self.rx
                        .drain(..skip.clamp(1, self.rx.len().max(1)).min(self.rx.len()));
                    continue;
                }
                Decoded::Incomplete => {}
            }
            let now = Instant::now();
            if now >= deadline {
                self.counters.timeouts += 1;
                return Ok(None);
            }
            let Some(port) = self.port.as_mut() else {
                return Err(self.io(format!("port {} is not open", self.config.port)));
            };
            let _ = port.set_timeout(deadline - now);
            match port.read(&mut chunk) {
                Ok(0) => {
                    let e = std::io::Error::new(ErrorKind::UnexpectedEof, "end of file");
                    return Err(self.port_failed(what, &e));
                }
                Ok(n) => {
                    self.counters.bytes_received += n as u64;
                    self.rx.extend_from_slice(&chunk[..n]);
                }
                Err(e) if e.kind() == ErrorKind::TimedOut || e.kind() == ErrorKind::Interrupted => {
                }
                Err(e) => return Err(self.port_failed(what, &e)),
            }
        }
    }

    fn deadline(&self) -> Instant {
        Instant::now() + self.timeout()
    }

    /// A servo's error bits: reported by name when they change.
    fn note_errors(&mut self, i: usize, bits: u16, names: Vec<&'static str>) {
        if bits != 0 {
            self.counters.servo_errors += 1;
        }
        let Some(servo) = self.servos.get_mut(i) else {
            return;
        };
        if servo.error_bits != bits {
            servo.error_bits = bits;
            let word = if self.config.calibration.protocol.measures() {
                "id"
            } else {
                "board of channel"
            };
            self.notices.push(if bits == 0 {
                format!(
                    "joint `{}` (servo {word} {}): errors cleared",
                    servo.joint, servo.cal.id
                )
            } else {
                format!(
                    "joint `{}` (servo {word} {}) reports: {}",
                    servo.joint,
                    servo.cal.id,
                    names.join(", ")
                )
            });
        }
    }

    fn open(&mut self) -> Result<(), BackendError> {
        self.port = None;
        self.rx.clear();
        let port = serialport::new(&self.config.port, self.config.baud)
            .timeout(self.timeout())
            .open()
            .map_err(|e| BackendError::Open {
                backend: self.protocol().name().to_string(),
                why: format!(
                    "port {} at {} baud: {e}",
                    self.config.port, self.config.baud
                ),
            })?;
        let _ = port.clear(serialport::ClearBuffer::All);
        self.port = Some(port);
        Ok(())
    }

    /// Pings every servo; a missing one is an error naming it.
    fn ping_all(&mut self) -> Result<(), BackendError> {
        match self.protocol() {
            Protocol::Dynamixel2 | Protocol::Dynamixel1 => {
                for i in 0..self.servos.len() {
                    let id = self.servos[i].cal.id;
                    let p2 = self.protocol() == Protocol::Dynamixel2;
                    let packet = if p2 {
                        dynamixel2::ping(id)
                    } else {
                        dynamixel1::ping(id)
                    };
                    self.send(&packet, "pinging")?;
                    let deadline = self.deadline();
                    let got = if p2 {
                        self.receive(dynamixel2::decode_status, deadline, "pinging")?
                            .filter(|p| p.id == id)
                            .map(|p| (u16::from(p.error), dynamixel2::error_names(p.error)))
                    } else {
                        self.receive(dynamixel1::decode_status, deadline, "pinging")?
                            .filter(|p| p.id == id)
                            .map(|p| (u16::from(p.code), dynamixel1::error_names(p.code)))
                    };
                    let Some((bits, names)) = got else {
                        return Err(self.joint_error(
                            &self.servos[i],
                            format!(
                                "no reply to ping on {} at {} baud (missing, unpowered, wrong id or wrong baud rate)",
                                self.config.port, self.config.baud
                            ),
                        ));
                    };
                    self.note_errors(i, bits, names);
                }
                Ok(())
            }
            Protocol::Maestro => {
                self.send(&maestro::get_errors(), "asking the Maestro for its errors")?;
                let deadline = self.deadline();
                let Some(bits) =
                    self.receive(two_bytes, deadline, "asking the Maestro for its errors")?
                else {
                    return Err(self.io(format!(
                        "no reply from a Maestro on {} at {} baud (unpowered, wrong port or baud rate)",
                        self.config.port, self.config.baud
                    )));
                };
                self.note_errors(0, bits, maestro::error_names(bits));
                Ok(())
            }
            Protocol::Ssc32 => {
                self.send(&ssc32::version(), "asking the SSC-32U for its version")?;
                let deadline = self.deadline();
                if self
                    .receive(line, deadline, "asking the SSC-32U for its version")?
                    .is_none()
                {
                    return Err(self.io(format!(
                        "no reply to VER from an SSC-32U on {} at {} baud (unpowered, wrong port or baud rate)",
                        self.config.port, self.config.baud
                    )));
                }
                Ok(())
            }
        }
    }

    /// Reads what the board can tell about the positions (units), updating the servos.
    fn read_positions(&mut self) -> Result<(), BackendError> {
        match self.protocol() {
            Protocol::Dynamixel2 => {
                let ids: Vec<u8> = self.servos.iter().map(|s| s.cal.id).collect();
                let packet = dynamixel2::sync_read(dynamixel2::address::PRESENT_POSITION, 4, &ids);
                self.send(&packet, "reading positions")?;
                let deadline = self.deadline();
                let mut missing = ids.len();
                let mut alerts = Vec::new();
                while missing > 0 {
                    let Some(p) =
                        self.receive(dynamixel2::decode_status, deadline, "reading positions")?
                    else {
                        break;
                    };
                    let Some(i) = self.servos.iter().position(|s| s.cal.id == p.id) else {
                        self.counters.unexpected_replies += 1;
                        continue;
                    };
                    missing -= 1;
                    if p.error & 0x80 != 0 && self.servos[i].error_bits & 0x80 == 0 {
                        // Alert: the Hardware Error Status says which fault (asked once
                        // every reply of this read is in).
                        alerts.push((i, p.error));
                    } else {
                        self.note_errors(i, u16::from(p.error), dynamixel2::error_names(p.error));
                    }
                    if let Some(v) = p.param_i32() {
                        self.servos[i].measured_units = Some(f64::from(v));
                    }
                }
                for (i, error) in alerts {
                    let names = self.hardware_errors(i)?;
                    self.note_errors(i, u16::from(error), names);
                }
                // Timeouts of the missing ones were counted once for the whole read; count
                // one per servo that did not answer.
                if missing > 1 {
                    self.counters.timeouts += missing as u64 - 1;
                }
                Ok(())
            }
            Protocol::Dynamixel1 => {
                for i in 0..self.servos.len() {
                    let id = self.servos[i].cal.id;
                    let packet = dynamixel1::read(id, dynamixel1::address::PRESENT_POSITION, 2);
                    self.send(&packet, "reading positions")?;
                    let deadline = self.deadline();
                    let Some(p) =
                        self.receive(dynamixel1::decode_status, deadline, "reading positions")?
                    else {
                        continue;
                    };
                    if p.id != id {
                        self.counters.unexpected_replies += 1;
                        continue;
                    }
                    self.note_errors(i, u16::from(p.code), dynamixel1::error_names(p.code));
                    if let Some(v) = p.param_u16() {
                        self.servos[i].measured_units = Some(f64::from(v));
                    }
                }
                Ok(())
            }
            Protocol::Maestro => {
                for i in 0..self.servos.len() {
                    let ch = self.servos[i].cal.id;
                    self.send(&maestro::get_position(ch), "reading positions")?;
                    let deadline = self.deadline();
                    if let Some(q) = self.receive(two_bytes, deadline, "reading positions")? {
                        // 0: the channel outputs no pulse; nothing known.
                        self.servos[i].measured_units = (q > 0).then(|| f64::from(q) / 4.0);
                    }
                }
                Ok(())
            }
            Protocol::Ssc32 => {
                let chans: Vec<u8> = self.servos.iter().map(|s| s.cal.id).collect();
                self.send(&ssc32::query_pulse_widths(&chans), "reading positions")?;
                let deadline = self.deadline();
                let n = chans.len();
                let bytes = self.receive(
                    move |b: &[u8]| {
                        if b.len() >= n {
                            Decoded::Packet {
                                value: b[..n].to_vec(),
                                used: n,
                            }
                        } else {
                            Decoded::Incomplete
                        }
                    },
                    deadline,
                    "reading positions",
                )?;
                if let Some(bytes) = bytes {
                    for (servo, b) in self.servos.iter_mut().zip(bytes) {
                        servo.measured_units =
                            (b > 0).then(|| f64::from(ssc32::decode_pulse_width(b)));
                    }
                }
                Ok(())
            }
        }
    }

    /// Reads a Dynamixel X servo's Hardware Error Status and names its bits.
    fn hardware_errors(&mut self, i: usize) -> Result<Vec<&'static str>, BackendError> {
        let id = self.servos[i].cal.id;
        let packet = dynamixel2::read(id, dynamixel2::address::HARDWARE_ERROR_STATUS, 1);
        self.send(&packet, "reading the hardware error status")?;
        let deadline = self.deadline();
        let reply = self.receive(
            dynamixel2::decode_status,
            deadline,
            "reading the hardware error status",
        )?;
        let mut names = vec!["hardware alert"];
        if let Some(p) = reply.filter(|p| p.id == id)
            && let Some(&status) = p.params.first()
        {
            names.extend(dynamixel2::hardware_error_names(status));
        }
        Ok(names)
    }

    fn torque(&mut self, on: bool) -> Result<(), BackendError> {
        let ids: Vec<u8> = self.servos.iter().map(|s| s.cal.id).collect();
        let what = if on {
            "turning torque on"
        } else {
            "turning torque off"
        };
        match self.protocol() {
            Protocol::Dynamixel2 => self.send(&dynamixel2::sync_write_torque(&ids, on), what),
            Protocol::Dynamixel1 => self.send(&dynamixel1::sync_write_torque(&ids, on), what),
            Protocol::Maestro => {
                if on {
                    let (speed, accel) = (
                        self.config.calibration.speed,
                        self.config.calibration.acceleration,
                    );
                    let mut bytes = Vec::new();
                    for &ch in &ids {
                        bytes.extend(maestro::set_speed(ch, speed));
                        bytes.extend(maestro::set_acceleration(ch, accel));
                    }
                    self.send(&bytes, what)
                } else {
                    let off: Vec<(u8, u16)> = ids.iter().map(|&c| (c, 0)).collect();
                    self.send(&maestro::set_targets(&off), what)
                }
            }
            // Pulses start with the first group move.
            Protocol::Ssc32 if on => Ok(()),
            Protocol::Ssc32 => self.send(&ssc32::pulses_off(&ids), what),
        }
    }

    /// The bytes of one control cycle's goal positions (units already clamped).
    fn goal_packet(&self, units: &[f64]) -> Vec<u8> {
        let ids = self.servos.iter().map(|s| s.cal.id);
        match self.protocol() {
            Protocol::Dynamixel2 => {
                let goals: Vec<(u8, i32)> = ids
                    .zip(units)
                    .map(|(id, &u)| (id, u.round() as i32))
                    .collect();
                dynamixel2::sync_write_goal_positions(&goals)
            }
            Protocol::Dynamixel1 => {
                let goals: Vec<(u8, u16)> = ids
                    .zip(units)
                    .map(|(id, &u)| (id, u.round() as u16))
                    .collect();
                dynamixel1::sync_write_goal_positions(&goals)
            }
            Protocol::Maestro => {
                let goals: Vec<(u8, u16)> = ids
                    .zip(units)
                    .map(|(id, &u)| (id, maestro::quarter_us(u)))
                    .collect();
                maestro::set_targets(&goals)
            }
            Protocol::Ssc32 => {
                let goals: Vec<(u8, u16)> = ids
                    .zip(units)
                    .map(|(id, &u)| (id, ssc32::whole_us(u)))
                    .collect();
                let speed = self
                    .start_move
                    .then_some(self.config.calibration.start_speed_us_s);
                ssc32::group_move_at(&goals, speed, None)
            }
        }
    }

    /// The units actually sent for a value (the wire's rounding).
    fn as_sent(&self, units: f64) -> f64 {
        match self.protocol() {
            Protocol::Dynamixel2 | Protocol::Dynamixel1 => units.round(),
            Protocol::Maestro => f64::from(maestro::quarter_us(units)) / 4.0,
            Protocol::Ssc32 => f64::from(ssc32::whole_us(units)),
        }
    }

    /// The bytes one control cycle puts on the wire (both ways) for these goal units, for
    /// the benchmark and the docs: request bytes, and reply bytes expected.
    pub fn cycle_bytes(&self, units: &[f64]) -> (usize, usize) {
        let out = self.goal_packet(units).len();
        let n = self.servos.len();
        match self.protocol() {
            Protocol::Dynamixel2 => (out + 14 + n, n * 15),
            Protocol::Dynamixel1 => (out + 8 * n, 8 * n),
            Protocol::Maestro | Protocol::Ssc32 => (out, 0),
        }
    }
}

fn two_bytes(b: &[u8]) -> Decoded<u16> {
    match b {
        [lo, hi, ..] => Decoded::Packet {
            value: maestro::decode_reply([*lo, *hi]),
            used: 2,
        },
        _ => Decoded::Incomplete,
    }
}

fn line(b: &[u8]) -> Decoded<Vec<u8>> {
    match b.iter().position(|&c| c == ssc32::CR) {
        Some(p) => Decoded::Packet {
            value: b[..p].to_vec(),
            used: p + 1,
        },
        None => Decoded::Incomplete,
    }
}

impl Backend for SerialBackend {
    fn name(&self) -> &str {
        self.protocol().name()
    }

    fn start_pose(&self) -> Option<Vec<f64>> {
        (!self.protocol().measures()).then(|| {
            self.servos
                .iter()
                .map(|s| s.cal.to_rad(s.cal.rest_units()))
                .collect()
        })
    }

    fn configure(&mut self, joints: &[JointSpec]) -> Result<Option<Vec<f64>>, BackendError> {
        let mut servos = Vec::with_capacity(joints.len());
        for j in joints {
            let Some(cal) = self.config.calibration.joints.get(&j.name) else {
                return Err(BackendError::Joint {
                    backend: self.protocol().name().to_string(),
                    joint: j.name.clone(),
                    why: "not in the calibration file".into(),
                });
            };
            // Keep what was measured before a reconnection.
            let old = self.servos.iter().find(|s| s.joint == j.name);
            servos.push(Servo {
                joint: j.name.clone(),
                cal: *cal,
                error_bits: old.map_or(0, |s| s.error_bits),
                measured_units: None,
                commanded_units: old.and_then(|s| s.commanded_units),
            });
        }
        self.servos = servos;
        self.state = Lifecycle::Unconfigured;
        self.open()?;
        let r = self.ping_all().and_then(|()| self.read_positions());
        if let Err(e) = r {
            // Leave nothing half open.
            self.port = None;
            return Err(e);
        }
        if self.configured_once {
            self.counters.reconnects += 1;
        }
        self.configured_once = true;
        self.last_failure = None;
        self.state = Lifecycle::Inactive;
        let measured: Option<Vec<f64>> = self
            .servos
            .iter()
            .map(|s| s.measured_units.map(|u| s.cal.to_rad(u)))
            .collect();
        if let Some(m) = &measured {
            for (s, &rad) in self.servos.iter_mut().zip(m) {
                s.commanded_units = s.cal.to_units(rad);
            }
        }
        // No pulse out yet: the servos are wherever they are; the first move goes slowly.
        self.start_move = self.protocol() == Protocol::Ssc32 && measured.is_none();
        Ok(measured)
    }

    fn activate(&mut self) -> Result<(), BackendError> {
        match self.state {
            Lifecycle::Inactive | Lifecycle::Active => {
                self.torque(true)?;
                self.state = Lifecycle::Active;
                Ok(())
            }
            state => Err(BackendError::State {
                backend: self.protocol().name().to_string(),
                call: "activate",
                state,
            }),
        }
    }

    fn write(&mut self, _t_s: f64, positions_rad: &[f64]) -> Result<(), BackendError> {
        if self.state != Lifecycle::Active {
            return Err(BackendError::State {
                backend: self.protocol().name().to_string(),
                call: "write",
                state: self.state,
            });
        }
        if positions_rad.len() != self.servos.len() {
            return Err(self.io(format!(
                "{} positions written for {} joints",
                positions_rad.len(),
                self.servos.len()
            )));
        }
        let mut units = Vec::with_capacity(self.servos.len());
        for (s, &rad) in self.servos.iter().zip(positions_rad) {
            let Some(u) = s.cal.to_units(rad) else {
                return Err(self.joint_error(s, format!("position {rad} is not finite: not sent")));
            };
            units.push(u);
        }
        let packet = self.goal_packet(&units);
        self.send(&packet, "writing goal positions")?;
        for (s, u) in self.servos.iter_mut().zip(&units) {
            s.commanded_units = Some(*u);
        }
        for i in 0..self.servos.len() {
            let sent = self.servos[i].commanded_units.map(|u| self.as_sent(u));
            self.servos[i].commanded_units = sent;
        }
        self.counters.cycles += 1;
        // The Maestro keeps its error bits until asked: ask now and then.
        if self.protocol() == Protocol::Maestro && self.counters.cycles.is_multiple_of(50) {
            self.send(&maestro::get_errors(), "asking the Maestro for its errors")?;
            let deadline = self.deadline();
            if let Some(bits) =
                self.receive(two_bytes, deadline, "asking the Maestro for its errors")?
            {
                self.note_errors(0, bits, maestro::error_names(bits));
            }
        }
        Ok(())
    }

    fn read(&mut self, _t_s: f64) -> Result<Reading, BackendError> {
        match self.state {
            Lifecycle::Inactive | Lifecycle::Active => {}
            state => {
                return Err(match &self.last_failure {
                    Some(why) if state == Lifecycle::Error => self.io(why.clone()),
                    _ => BackendError::State {
                        backend: self.protocol().name().to_string(),
                        call: "read",
                        state,
                    },
                });
            }
        }
        let measures = self.protocol().measures();
        if measures {
            self.read_positions()?;
        } else if self.start_move {
            // The SSC-32U's output pulses trail a speed-limited move: the first move is
            // over when they are the commanded ones (10 µs resolution).
            self.read_positions()?;
            if self.servos.iter().all(|s| {
                matches!((s.measured_units, s.commanded_units), (Some(m), Some(c)) if (m - c).abs() <= 10.0)
            }) {
                self.start_move = false;
                self.notices.push(format!(
                    "servos at the rest pose (moved there at {} µs/s); full speed from now",
                    self.config.calibration.start_speed_us_s
                ));
            }
        }
        let positions_rad = self
            .servos
            .iter()
            .map(|s| {
                let u = if measures {
                    s.measured_units.or(s.commanded_units)
                } else {
                    s.commanded_units
                };
                u.map_or(0.0, |u| s.cal.to_rad(u))
            })
            .collect();
        Ok(Reading {
            positions_rad,
            velocities_rad_s: None,
            measured: measures,
        })
    }

    fn deactivate(&mut self) -> Result<(), BackendError> {
        if self.port.is_none() {
            return Ok(());
        }
        let r = self.torque(false);
        if self.state == Lifecycle::Active {
            self.state = Lifecycle::Inactive;
        }
        r
    }

    fn diagnostics(&self) -> Option<Diagnostics> {
        let c = &self.counters;
        let (level, message) = match (self.state, &self.last_failure) {
            (Lifecycle::Error, Some(why)) => (DiagnosticLevel::Error, why.clone()),
            (Lifecycle::Unconfigured, _) => (DiagnosticLevel::Error, "not connected".to_string()),
            _ if self.servos.iter().any(|s| s.error_bits != 0) => {
                (DiagnosticLevel::Warn, "a servo reports errors".to_string())
            }
            _ => (
                DiagnosticLevel::Ok,
                format!("{:?}", self.state).to_lowercase(),
            ),
        };
        let mut values = vec![
            ("protocol".to_string(), self.protocol().name().to_string()),
            ("baud".to_string(), self.config.baud.to_string()),
            ("cycles".to_string(), c.cycles.to_string()),
            ("bytes_sent".to_string(), c.bytes_sent.to_string()),
            ("bytes_received".to_string(), c.bytes_received.to_string()),
            ("timeouts".to_string(), c.timeouts.to_string()),
            ("corrupted".to_string(), c.corrupted.to_string()),
            ("checksum_errors".to_string(), c.checksum_errors.to_string()),
            (
                "unexpected_replies".to_string(),
                c.unexpected_replies.to_string(),
            ),
            ("servo_errors".to_string(), c.servo_errors.to_string()),
            ("port_failures".to_string(), c.port_failures.to_string()),
            ("reconnects".to_string(), c.reconnects.to_string()),
        ];
        for s in self.servos.iter().filter(|s| s.error_bits != 0) {
            values.push((
                format!("error_bits.{}", s.joint),
                format!("0x{:x}", s.error_bits),
            ));
        }
        Some(Diagnostics {
            name: format!("joint_bridge: {} board", self.protocol().name()),
            hardware_id: self.config.port.clone(),
            level,
            message,
            values,
        })
    }

    fn take_notices(&mut self) -> Vec<String> {
        std::mem::take(&mut self.notices)
    }
}
