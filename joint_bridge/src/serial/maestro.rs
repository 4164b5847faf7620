//! Pololu Maestro servo controllers, compact protocol: pure encode and decode, no I/O.
//!
//! Every command starts with a byte ≥ `0x80`; every data byte after it is 7 bits. 14-bit
//! values go low 7 bits first, then the high 7 bits.
//!
//! | command | bytes | reply |
//! |---|---|---|
//! | set target | `84`, channel, target low 7, target high 7 | none |
//! | set multiple targets (Mini Maestro 12/18/24) | `9F`, count, first channel, then low 7 / high 7 per target | none |
//! | set speed | `87`, channel, speed low 7, speed high 7 | none |
//! | set acceleration | `89`, channel, accel low 7, accel high 7 | none |
//! | get position | `90`, channel | 2 bytes, little-endian: the pulse width now output |
//! | get errors | `A1` | 2 bytes, little-endian error bits (reading clears them) |
//!
//! Units: targets in quarter-microseconds of pulse width (6000 = 1500 µs); 0 stops the
//! pulses (the servo goes limp). Speed in 0.25 µs per 10 ms; acceleration in 0.25 µs per
//! 10 ms per 80 ms; 0 = unlimited. No checksum (the optional CRC-7 mode is not used).
//! The Maestro does not measure the servo: "get position" is the pulse it outputs, which
//! trails the target only while a speed or acceleration limit is easing it.
//!
//! Error bits: 0 serial signal, 1 serial overrun, 2 serial buffer full, 3 serial CRC,
//! 4 serial protocol, 5 serial timeout, 6 script stack, 7 script call stack, 8 script
//! program counter.

/// Command bytes.
pub mod command {
    /// Set target.
    pub const SET_TARGET: u8 = 0x84;
    /// Set multiple targets.
    pub const SET_MULTIPLE_TARGETS: u8 = 0x9F;
    /// Set speed.
    pub const SET_SPEED: u8 = 0x87;
    /// Set acceleration.
    pub const SET_ACCELERATION: u8 = 0x89;
    /// Get position.
    pub const GET_POSITION: u8 = 0x90;
    /// Get errors.
    pub const GET_ERRORS: u8 = 0xA1;
}

/// Largest 14-bit value.
pub const MAX_VALUE: u16 = 0x3FFF;

fn split14(v: u16) -> [u8; 2] {
    let v = v.min(MAX_VALUE);
    [(v & 0x7F) as u8, ((v >> 7) & 0x7F) as u8]
}

/// A 14-bit value from its two 7-bit bytes.
pub fn join14(low: u8, high: u8) -> u16 {
    u16::from(low & 0x7F) | (u16::from(high & 0x7F) << 7)
}

/// Microseconds to the wire's quarter-microseconds, rounded, within 14 bits.
pub fn quarter_us(pulse_us: f64) -> u16 {
    let q = (pulse_us * 4.0).round();
    if q.is_nan() || q <= 0.0 {
        0
    } else if q >= f64::from(MAX_VALUE) {
        MAX_VALUE
    } else {
        q as u16
    }
}

/// Set one channel's target (quarter-µs).
///
/// ```
/// // The user's guide example: channel 2 to 1500 µs = 6000 quarter-µs = 0x1770.
/// assert_eq!(joint_bridge::serial::maestro::set_target(2, 6000), [0x84, 0x02, 0x70, 0x2E]);
/// ```
pub fn set_target(channel: u8, target_qus: u16) -> [u8; 4] {
    let [lo, hi] = split14(target_qus);
    [command::SET_TARGET, channel & 0x7F, lo, hi]
}

/// Set consecutive channels' targets from `first_channel` on (quarter-µs).
pub fn set_multiple_targets(first_channel: u8, targets_qus: &[u16]) -> Vec<u8> {
    let mut out = Vec::with_capacity(3 + 2 * targets_qus.len());
    out.push(command::SET_MULTIPLE_TARGETS);
    out.push(u8::try_from(targets_qus.len()).unwrap_or(0x7F) & 0x7F);
    out.push(first_channel & 0x7F);
    for &t in targets_qus {
        out.extend_from_slice(&split14(t));
    }
    out
}

/// Targets for any channels: one set-multiple-targets packet per run of consecutive
/// channels (so a board wired 0-4 and 6-10 needs two packets).
pub fn set_targets(targets: &[(u8, u16)]) -> Vec<u8> {
    let mut sorted = targets.to_vec();
    sorted.sort_by_key(|&(c, _)| c);
    let mut out = Vec::new();
    let mut i = 0;
    while i < sorted.len() {
        let first = sorted[i].0;
        let mut run = vec![sorted[i].1];
        while let Some(&(c, t)) = sorted.get(i + run.len()) {
            if usize::from(c) != usize::from(first) + run.len() {
                break;
            }
            run.push(t);
        }
        i += run.len();
        out.extend(set_multiple_targets(first, &run));
    }
    out
}

/// Set a channel's speed limit (0.25 µs per 10 ms; 0 = none).
pub fn set_speed(channel: u8, speed: u16) -> [u8; 4] {
    let [lo, hi] = split14(speed);
    [command::SET_SPEED, channel & 0x7F, lo, hi]
}

/// Set a channel's acceleration limit (0.25 µs per 10 ms per 80 ms; 0 = none).
pub fn set_acceleration(channel: u8, acceleration: u16) -> [u8; 4] {
    let [lo, hi] = split14(acceleration);
    [command::SET_ACCELERATION, channel & 0x7F, lo, hi]
}

/// Ask for a channel's pulse width.
pub fn get_position(channel: u8) -> [u8; 2] {
    [command::GET_POSITION, channel & 0x7F]
}

/// Ask for (and clear) the error bits.
pub fn get_errors() -> [u8; 1] {
    [command::GET_ERRORS]
}

/// The 2-byte reply to get position or get errors, little-endian.
pub fn decode_reply(reply: [u8; 2]) -> u16 {
    u16::from_le_bytes(reply)
}

/// The names of the error bits.
pub fn error_names(errors: u16) -> Vec<&'static str> {
    [
        "serial signal error",
        "serial overrun error",
        "serial buffer full",
        "serial CRC error",
        "serial protocol error",
        "serial timeout error",
        "script stack error",
        "script call stack error",
        "script program counter error",
    ]
    .into_iter()
    .enumerate()
    .filter(|(bit, _)| errors & (1 << bit) != 0)
    .map(|(_, name)| name)
    .collect()
}

/// A command decoded (the board's side: for emulators and round-trip tests).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Command {
    /// Set target: channel, quarter-µs.
    SetTarget(u8, u16),
    /// Set multiple targets: first channel, quarter-µs each.
    SetMultipleTargets(u8, Vec<u16>),
    /// Set speed: channel, value.
    SetSpeed(u8, u16),
    /// Set acceleration: channel, value.
    SetAcceleration(u8, u16),
    /// Get position of a channel.
    GetPosition(u8),
    /// Get errors.
    GetErrors,
}

/// Parses one command at the start of `buf`.
pub fn decode_command(buf: &[u8]) -> super::Decoded<Command> {
    use super::{Corruption, Decoded};
    let Some(&cmd) = buf.first() else {
        return Decoded::Incomplete;
    };
    let need = match cmd {
        command::SET_TARGET | command::SET_SPEED | command::SET_ACCELERATION => 4,
        command::GET_POSITION => 2,
        command::GET_ERRORS => 1,
        command::SET_MULTIPLE_TARGETS => match buf.get(1) {
            Some(&n) => 3 + 2 * usize::from(n),
            None => return Decoded::Incomplete,
        },
        _ => {
            return Decoded::Invalid {
                skip: 1,
                why: Corruption::NoHeader,
            };
        }
    };
    let Some(b) = buf.get(..need) else {
        return Decoded::Incomplete;
    };
    if b[1..].iter().any(|&x| x >= 0x80) {
        return Decoded::Invalid {
            skip: 1,
            why: Corruption::BadLength,
        };
    }
    let value = match cmd {
        command::SET_TARGET => Command::SetTarget(b[1], join14(b[2], b[3])),
        command::SET_SPEED => Command::SetSpeed(b[1], join14(b[2], b[3])),
        command::SET_ACCELERATION => Command::SetAcceleration(b[1], join14(b[2], b[3])),
        command::GET_POSITION => Command::GetPosition(b[1]),
        command::GET_ERRORS => Command::GetErrors,
        _ => Command::SetMultipleTargets(
            b[2],
            b[3..].chunks(2).map(|c| join14(c[0], c[1])).collect(),
        ),
    };
    Decoded::Packet { value, used: need }
}
