//! Serial servo boards: Dynamixel Protocol 2.0 and 1.0 bus servos, Pololu Maestro and
//! Lynxmotion SSC-32U PWM servo controllers.
//!
//! Layout: one pure encode/decode module per protocol ([`dynamixel2`], [`dynamixel1`],
//! [`maestro`], [`ssc32`]; bytes in, bytes out, no I/O), the per-joint [`calibration`]
//! (radians ↔ servo units), and [`SerialBackend`], the [`crate::Backend`] that drives one
//! board over a serial port with them.
//!
//! | protocol | position unit | feedback | per cycle on the wire |
//! |---|---|---|---|
//! | `dynamixel2` | tick (X series: 4096 per turn) | measured (sync read) | one sync write, one sync read and a status packet per servo |
//! | `dynamixel1` | tick (AX-12: 1024 per 300°) | measured (a read per servo) | one sync write, a read and a status packet per servo |
//! | `maestro` | µs of pulse (sent in quarter-µs) | none (commanded) | set multiple targets, one packet per run of consecutive channels |
//! | `ssc32` | µs of pulse | none (commanded) | one ASCII group move |

pub mod calibration;
pub mod dynamixel1;
pub mod dynamixel2;
pub mod maestro;
pub mod ssc32;

mod backend;

pub use backend::{SerialBackend, SerialConfig, SerialCounters};
pub use calibration::{Calibration, CalibrationError, JointCalibration};

use std::fmt;

/// The serial protocols the bridge speaks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Protocol {
    /// ROBOTIS Dynamixel Protocol 2.0 (X series).
    Dynamixel2,
    /// ROBOTIS Dynamixel Protocol 1.0 (AX-12, Bioloid).
    Dynamixel1,
    /// Pololu Maestro, compact protocol.
    Maestro,
    /// Lynxmotion SSC-32U, ASCII.
    Ssc32,
}

impl Protocol {
    /// Every protocol, in the order the docs list them.
    pub const ALL: [Protocol; 4] = [
        Protocol::Dynamixel2,
        Protocol::Dynamixel1,
        Protocol::Maestro,
        Protocol::Ssc32,
    ];

    /// The name used in parameters and calibration files.
    pub fn name(self) -> &'static str {
        match self {
            Protocol::Dynamixel2 => "dynamixel2",
            Protocol::Dynamixel1 => "dynamixel1",
            Protocol::Maestro => "maestro",
            Protocol::Ssc32 => "ssc32",
        }
    }

    /// Whether the board reports measured positions.
    pub fn measures(self) -> bool {
        matches!(self, Protocol::Dynamixel2 | Protocol::Dynamixel1)
    }

    /// The range of servo ids (bus ids, or channels) the protocol can address.
    pub fn id_range(self) -> (u8, u8) {
        match self {
            // 253 (2.0) / 254 are broadcast; 0xFD is reserved in 2.0.
            Protocol::Dynamixel2 => (0, 252),
            Protocol::Dynamixel1 => (0, 253),
            Protocol::Maestro => (0, 23),
            Protocol::Ssc32 => (0, 31),
        }
    }

    /// The range of position values the wire can carry, in calibration units (ticks or µs).
    pub fn unit_range(self) -> (f64, f64) {
        match self {
            Protocol::Dynamixel2 => (0.0, 4095.0),
            Protocol::Dynamixel1 => (0.0, 1023.0),
            // 14 bits of quarter-microseconds; 0 means "off".
            Protocol::Maestro => (1.0, 4095.75),
            Protocol::Ssc32 => (500.0, 2500.0),
        }
    }

    /// What a calibration unit is, for messages.
    pub fn unit_name(self) -> &'static str {
        match self {
            Protocol::Dynamixel2 | Protocol::Dynamixel1 => "ticks",
            Protocol::Maestro | Protocol::Ssc32 => "µs",
        }
    }
}

impl fmt::Display for Protocol {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Protocol {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Protocol::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| {
                format!("`{s}` is not a serial protocol (dynamixel2, dynamixel1, maestro, ssc32)")
            })
    }
}

/// What a status-packet parser makes of the bytes received so far.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Decoded<T> {
    /// Not enough bytes yet for a whole packet.
    Incomplete,
    /// A packet, and how many bytes of the buffer it used.
    Packet {
        /// The packet.
        value: T,
        /// Bytes used from the start of the buffer.
        used: usize,
    },
    /// The buffer does not start with a valid packet: drop `skip` bytes (at least 1) and
    /// parse again.
    Invalid {
        /// Bytes to drop.
        skip: usize,
        /// What was wrong.
        why: Corruption,
    },
}

/// Why received bytes were dropped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Corruption {
    /// Bytes before a packet header.
    NoHeader,
    /// A length field that no valid packet has.
    BadLength,
    /// The checksum or CRC does not match.
    BadChecksum,
    /// A well-formed packet that is not a status packet.
    NotStatus,
}

impl fmt::Display for Corruption {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Corruption::NoHeader => "bytes before a packet header",
            Corruption::BadLength => "impossible length field",
            Corruption::BadChecksum => "checksum/CRC mismatch",
            Corruption::NotStatus => "not a status packet",
        })
    }
}
