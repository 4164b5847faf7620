//! ROBOTIS Dynamixel Protocol 1.0 packets (AX-12, Bioloid): pure encode and decode, no I/O.
//!
//! | bytes | field | notes |
//! |---|---|---|
//! | 0-1 | header | `FF FF` |
//! | 2 | id | 0-253; `FE` broadcast (sync write) |
//! | 3 | length | bytes after this field: instruction (or error) + parameters + checksum |
//! | 4 | instruction / error | `01` ping, `02` read, `03` write, `83` sync write; in a status packet, the error bits |
//! | 5.. | parameters | little-endian 2-byte values |
//! | last | checksum | `!(id + length + instruction/error + Σ parameters)`, low byte |
//!
//! Error bits of a status packet: 0 input voltage, 1 angle limit, 2 overheating, 3 range,
//! 4 checksum, 5 overload, 6 instruction.
//!
//! Protocol 1.0 has sync write (to `FE`: address, length L, then id and L data bytes per
//! servo; no reply) but no sync read: positions are read one servo at a time (read:
//! address, length; the status carries the data).
//!
//! AX-12 control table: torque enable 24 (1 byte), goal position 30 and present position 36
//! (2 bytes, 0-1023 over 300°, 512 = centre, 0.29° per tick).

use super::{Corruption, Decoded};

/// The broadcast id (sync write).
pub const BROADCAST_ID: u8 = 0xFE;

/// Instruction codes.
pub mod instruction {
    /// Ping.
    pub const PING: u8 = 0x01;
    /// Read.
    pub const READ: u8 = 0x02;
    /// Write.
    pub const WRITE: u8 = 0x03;
    /// Sync write.
    pub const SYNC_WRITE: u8 = 0x83;
}

/// AX-12 control table addresses.
pub mod address {
    /// Torque Enable, 1 byte.
    pub const TORQUE_ENABLE: u8 = 24;
    /// Goal Position, 2 bytes.
    pub const GOAL_POSITION: u8 = 30;
    /// Present Position, 2 bytes.
    pub const PRESENT_POSITION: u8 = 36;
}

/// The checksum of a packet without its header and checksum (id, length, instruction or
/// error, parameters).
///
/// ```
/// // Ping of id 1: FF FF 01 02 01 FB.
/// assert_eq!(joint_bridge::serial::dynamixel1::checksum(&[0x01, 0x02, 0x01]), 0xFB);
/// ```
pub fn checksum(bytes: &[u8]) -> u8 {
    !bytes.iter().fold(0u8, |s, &b| s.wrapping_add(b))
}

fn packet(id: u8, code: u8, params: &[u8]) -> Vec<u8> {
    // Our packets stay far below 255 bytes.
    let length = u8::try_from(params.len() + 2).unwrap_or(u8::MAX);
    let mut out = Vec::with_capacity(params.len() + 6);
    out.extend_from_slice(&[0xFF, 0xFF, id, length, code]);
    out.extend_from_slice(params);
    out.push(checksum(&out[2..]));
    out
}

/// An instruction packet.
pub fn instruction_packet(id: u8, instruction: u8, params: &[u8]) -> Vec<u8> {
    packet(id, instruction, params)
}

/// A status packet (what a servo sends; for emulators and tests).
pub fn status_packet(id: u8, error: u8, params: &[u8]) -> Vec<u8> {
    packet(id, error, params)
}

/// Ping.
pub fn ping(id: u8) -> Vec<u8> {
    packet(id, instruction::PING, &[])
}

/// Read `length` bytes at `address`.
pub fn read(id: u8, address: u8, length: u8) -> Vec<u8> {
    packet(id, instruction::READ, &[address, length])
}

/// Write `data` at `address`.
pub fn write(id: u8, address: u8, data: &[u8]) -> Vec<u8> {
    let mut params = vec![address];
    params.extend_from_slice(data);
    packet(id, instruction::WRITE, &params)
}

/// Sync write of one `N`-byte value per servo at `address`.
pub fn sync_write<const N: usize>(address: u8, values: &[(u8, [u8; N])]) -> Vec<u8> {
    let mut params = Vec::with_capacity(2 + values.len() * (N + 1));
    params.push(address);
    params.push(u8::try_from(N).unwrap_or(u8::MAX));
    for (id, data) in values {
        params.push(*id);
        params.extend_from_slice(data);
    }
    packet(BROADCAST_ID, instruction::SYNC_WRITE, &params)
}

/// Sync write of goal positions (ticks).
pub fn sync_write_goal_positions(goals: &[(u8, u16)]) -> Vec<u8> {
    let values: Vec<(u8, [u8; 2])> = goals.iter().map(|&(id, t)| (id, t.to_le_bytes())).collect();
    sync_write(address::GOAL_POSITION, &values)
}

/// Sync write of torque enable (on or off).
pub fn sync_write_torque(ids: &[u8], on: bool) -> Vec<u8> {
    let values: Vec<(u8, [u8; 1])> = ids.iter().map(|&id| (id, [u8::from(on)])).collect();
    sync_write(address::TORQUE_ENABLE, &values)
}

/// A decoded packet. In a status packet `code` is the error byte; in an instruction packet
/// it is the instruction.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Packet {
    /// Servo id.
    pub id: u8,
    /// Error bits (status) or instruction code (instruction).
    pub code: u8,
    /// Parameters.
    pub params: Vec<u8>,
}

impl Packet {
    /// The parameters as a little-endian `u16` (present position).
    pub fn param_u16(&self) -> Option<u16> {
        let b: [u8; 2] = self.params.get(..2)?.try_into().ok()?;
        Some(u16::from_le_bytes(b))
    }
}

/// Parses a packet at the start of `buf`. Status and instruction packets look alike in 1.0;
/// the caller knows which it expects.
///
/// ```
/// use joint_bridge::serial::{Decoded, dynamixel1::decode_packet};
/// // The manual's reply to "read the temperature of id 1": 0x20 = 32 °C.
/// let Decoded::Packet { value, used } = decode_packet(&[0xFF, 0xFF, 0x01, 0x03, 0x00, 0x20, 0xDB]) else { panic!() };
/// assert_eq!((value.id, value.code, value.params, used), (1, 0, vec![0x20], 7));
/// ```
pub fn decode_packet(buf: &[u8]) -> Decoded<Packet> {
    let prefix = buf.len().min(2);
    if buf[..prefix] != [0xFF, 0xFF][..prefix] {
        let skip = buf
            .iter()
            .skip(1)
            .position(|&b| b == 0xFF)
            .map_or(buf.len(), |p| p + 1);
        return Decoded::Invalid {
            skip,
            why: Corruption::NoHeader,
        };
    }
    let (Some(&id), Some(&length)) = (buf.get(2), buf.get(3)) else {
        return Decoded::Incomplete;
    };
    // FF FF FF ...: a longer preamble (or noise); the packet may start one byte later.
    if id == 0xFF || length < 2 {
        return Decoded::Invalid {
            skip: 1,
            why: if id == 0xFF {
                Corruption::NoHeader
            } else {
                Corruption::BadLength
            },
        };
    }
    let total = 4 + usize::from(length);
    let Some(whole) = buf.get(..total) else {
        return Decoded::Incomplete;
    };
    let (body, sum) = whole.split_at(total - 1);
    if checksum(&body[2..]) != sum[0] {
        return Decoded::Invalid {
            skip: 1,
            why: Corruption::BadChecksum,
        };
    }
    Decoded::Packet {
        value: Packet {
            id,
            code: body[4],
            params: body[5..].to_vec(),
        },
        used: total,
    }
}

/// Parses a status packet (same layout as any packet in 1.0).
pub fn decode_status(buf: &[u8]) -> Decoded<Packet> {
    decode_packet(buf)
}

/// The names of the error bits of a status packet.
pub fn error_names(error: u8) -> Vec<&'static str> {
    [
        (0x01, "input voltage error"),
        (0x02, "angle limit error"),
        (0x04, "overheating error"),
        (0x08, "range error"),
        (0x10, "checksum error"),
        (0x20, "overload error"),
        (0x40, "instruction error"),
        (0x80, "unknown error bit 7"),
    ]
    .into_iter()
    .filter(|(bit, _)| error & bit != 0)
    .map(|(_, name)| name)
    .collect()
}
