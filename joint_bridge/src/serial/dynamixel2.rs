//! ROBOTIS Dynamixel Protocol 2.0 packets (X series): pure encode and decode, no I/O.
//!
//! Instruction packet (host → servo) and status packet (servo → host):
//!
//! | bytes | field | notes |
//! |---|---|---|
//! | 0-3 | header | `FF FF FD 00` |
//! | 4 | id | 0-252; `FE` broadcast (sync read/write) |
//! | 5-6 | length | little-endian: bytes after this field, i.e. instruction + (stuffed) parameters + 2 CRC bytes |
//! | 7 | instruction | `01` ping, `02` read, `03` write, `82` sync read, `83` sync write; `55` status |
//! | 8 | error (status only) | bit 7 alert (see Hardware Error Status), bits 0-6 an error number |
//! | 8.. / 9.. | parameters | little-endian multi-byte values |
//! | last 2 | CRC | CRC-16 (polynomial `0x8005`, initial 0, not reflected) of every byte before it, header included, little-endian |
//!
//! **Byte stuffing**: in the instruction/error/parameter region, every `FF FF FD` is sent
//! as `FF FF FD FD` so that no header appears inside a packet; the length and the CRC
//! count the stuffed bytes. The receiver drops the extra `FD`.
//!
//! Instructions used here, parameters in order:
//! - ping: none; the status carries model number (2 bytes) and firmware version (1 byte).
//! - read: address (2), length (2); the status carries the data.
//! - write: address (2), data; the status carries nothing.
//! - sync write, to id `FE`: address (2), length L of each servo's data (2), then for each
//!   servo its id and L data bytes. No status packet.
//! - sync read, to id `FE`: address (2), length (2), the ids; every servo answers with its
//!   own status packet, in the order of the ids.
//!
//! X-series control table (the addresses and units the backend uses): torque enable 64
//! (1 byte, 0/1), hardware error status 70 (1 byte), goal position 116 and present
//! position 132 (4 bytes, signed, 4096 ticks per turn, 2048 = centre, 0.088° per tick).

use super::{Corruption, Decoded};

/// The packet header.
pub const HEADER: [u8; 4] = [0xFF, 0xFF, 0xFD, 0x00];
/// The broadcast id (sync read, sync write).
pub const BROADCAST_ID: u8 = 0xFE;
/// Longest length field accepted in a status packet: far more than any reply we ask for;
/// a corrupted length beyond it is dropped at once instead of waiting for bytes.
pub const MAX_STATUS_LENGTH: usize = 1024;

/// Instruction codes.
pub mod instruction {
    /// Ping.
    pub const PING: u8 = 0x01;
    /// Read.
    pub const READ: u8 = 0x02;
    /// Write.
    pub const WRITE: u8 = 0x03;
    /// Status (reply).
    pub const STATUS: u8 = 0x55;
    /// Sync read.
    pub const SYNC_READ: u8 = 0x82;
    /// Sync write.
    pub const SYNC_WRITE: u8 = 0x83;
}

/// X-series control table addresses.
pub mod address {
    /// Torque Enable, 1 byte.
    pub const TORQUE_ENABLE: u16 = 64;
    /// Hardware Error Status, 1 byte.
    pub const HARDWARE_ERROR_STATUS: u16 = 70;
    /// Goal Position, 4 bytes.
    pub const GOAL_POSITION: u16 = 116;
    /// Present Position, 4 bytes.
    pub const PRESENT_POSITION: u16 = 132;
}

const CRC_TABLE: [u16; 256] = crc_table();

const fn crc_table() -> [u16; 256] {
    let mut table = [0u16; 256];
    let mut i = 0;
    while i < 256 {
        let mut crc = (i as u16) << 8;
        let mut bit = 0;
        while bit < 8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ 0x8005
            } else {
                crc << 1
            };
            bit += 1;
        }
        table[i] = crc;
        i += 1;
    }
    table
}

/// CRC-16 of Protocol 2.0 (polynomial 0x8005, initial value 0, MSB first).
///
/// ```
/// // Ping of id 1: FF FF FD 00 01 03 00 01, CRC 0x4E19 sent as 19 4E.
/// let crc = joint_bridge::serial::dynamixel2::crc16(&[0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x01]);
/// assert_eq!(crc, 0x4E19);
/// ```
pub fn crc16(bytes: &[u8]) -> u16 {
    bytes.iter().fold(0u16, |crc, &b| {
        let i = usize::from(((crc >> 8) as u8) ^ b);
        (crc << 8) ^ CRC_TABLE[i]
    })
}

/// Inserts the stuffing byte `FD` after every `FF FF FD`.
pub fn stuff(region: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(region.len() + 4);
    for &b in region {
        out.push(b);
        let n = out.len();
        if n >= 3 && out[n - 3..] == [0xFF, 0xFF, 0xFD] {
            out.push(0xFD);
        }
    }
    out
}

/// Removes the stuffing byte `FD` that follows every `FF FF FD`.
pub fn unstuff(region: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(region.len());
    let mut i = 0;
    while i < region.len() {
        let b = region[i];
        out.push(b);
        let n = out.len();
        if n >= 3 && out[n - 3..] == [0xFF, 0xFF, 0xFD] && region.get(i + 1) == Some(&0xFD) {
            i += 1;
        }
        i += 1;
    }
    out
}

/// A whole packet: header, id, length, the stuffed `region` (instruction or status,
/// error, parameters), CRC.
fn packet(id: u8, region: &[u8]) -> Vec<u8> {
    let body = stuff(region);
    // Parameters of our own packets are at most a few hundred bytes: fits in u16.
    let length = u16::try_from(body.len() + 2).unwrap_or(u16::MAX);
    let mut out = Vec::with_capacity(body.len() + 9);
    out.extend_from_slice(&HEADER);
    out.push(id);
    out.extend_from_slice(&length.to_le_bytes());
    out.extend_from_slice(&body);
    let crc = crc16(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

/// An instruction packet.
pub fn instruction_packet(id: u8, instruction: u8, params: &[u8]) -> Vec<u8> {
    let mut region = Vec::with_capacity(params.len() + 1);
    region.push(instruction);
    region.extend_from_slice(params);
    packet(id, &region)
}

/// A status packet (what a servo sends; for emulators and tests).
pub fn status_packet(id: u8, error: u8, params: &[u8]) -> Vec<u8> {
    let mut region = Vec::with_capacity(params.len() + 2);
    region.push(instruction::STATUS);
    region.push(error);
    region.extend_from_slice(params);
    packet(id, &region)
}

/// Ping.
pub fn ping(id: u8) -> Vec<u8> {
    instruction_packet(id, instruction::PING, &[])
}

/// Read `length` bytes at `address`.
pub fn read(id: u8, address: u16, length: u16) -> Vec<u8> {
    let [a0, a1] = address.to_le_bytes();
    let [l0, l1] = length.to_le_bytes();
    instruction_packet(id, instruction::READ, &[a0, a1, l0, l1])
}

/// Write `data` at `address`.
pub fn write(id: u8, address: u16, data: &[u8]) -> Vec<u8> {
    let mut params = address.to_le_bytes().to_vec();
    params.extend_from_slice(data);
    instruction_packet(id, instruction::WRITE, &params)
}

/// Sync write of one `N`-byte value per servo at `address`.
pub fn sync_write<const N: usize>(address: u16, values: &[(u8, [u8; N])]) -> Vec<u8> {
    let mut params = Vec::with_capacity(4 + values.len() * (N + 1));
    params.extend_from_slice(&address.to_le_bytes());
    params.extend_from_slice(&u16::try_from(N).unwrap_or(u16::MAX).to_le_bytes());
    for (id, data) in values {
        params.push(*id);
        params.extend_from_slice(data);
    }
    instruction_packet(BROADCAST_ID, instruction::SYNC_WRITE, &params)
}

/// Sync write of goal positions (ticks), one packet for every servo.
///
/// ```
/// use joint_bridge::serial::dynamixel2::sync_write_goal_positions;
/// // The e-manual's example: id 1 to 150, id 2 to 170.
/// let bytes = sync_write_goal_positions(&[(1, 150), (2, 170)]);
/// assert_eq!(&bytes[..8], &[0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x11, 0x00, 0x83]);
/// ```
pub fn sync_write_goal_positions(goals: &[(u8, i32)]) -> Vec<u8> {
    let values: Vec<(u8, [u8; 4])> = goals.iter().map(|&(id, t)| (id, t.to_le_bytes())).collect();
    sync_write(address::GOAL_POSITION, &values)
}

/// Sync write of torque enable (on or off) to these servos.
pub fn sync_write_torque(ids: &[u8], on: bool) -> Vec<u8> {
    let values: Vec<(u8, [u8; 1])> = ids.iter().map(|&id| (id, [u8::from(on)])).collect();
    sync_write(address::TORQUE_ENABLE, &values)
}

/// Sync read of `length` bytes at `address` from these servos.
pub fn sync_read(address: u16, length: u16, ids: &[u8]) -> Vec<u8> {
    let mut params = Vec::with_capacity(4 + ids.len());
    params.extend_from_slice(&address.to_le_bytes());
    params.extend_from_slice(&length.to_le_bytes());
    params.extend_from_slice(ids);
    instruction_packet(BROADCAST_ID, instruction::SYNC_READ, &params)
}

/// A decoded packet: an instruction (host → servo) or a status (servo → host).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Packet {
    /// Servo id (or broadcast).
    pub id: u8,
    /// Instruction code (`55` for a status packet).
    pub instruction: u8,
    /// Status packets: the error byte; instructions: 0.
    pub error: u8,
    /// Parameters, unstuffed.
    pub params: Vec<u8>,
}

impl Packet {
    /// A status packet's parameters as a little-endian `i32` (present position).
    pub fn param_i32(&self) -> Option<i32> {
        let b: [u8; 4] = self.params.get(..4)?.try_into().ok()?;
        Some(i32::from_le_bytes(b))
    }
}

/// Parses any packet at the start of `buf` (both directions).
pub fn decode_packet(buf: &[u8]) -> Decoded<Packet> {
    let prefix = buf.len().min(HEADER.len());
    if buf[..prefix] != HEADER[..prefix] {
        // Resynchronise on the next possible header start.
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
    let (Some(&id), Some(&l0), Some(&l1)) = (buf.get(4), buf.get(5), buf.get(6)) else {
        return Decoded::Incomplete;
    };
    let length = usize::from(u16::from_le_bytes([l0, l1]));
    if !(3..=MAX_STATUS_LENGTH).contains(&length) {
        return Decoded::Invalid {
            skip: 1,
            why: Corruption::BadLength,
        };
    }
    let total = 7 + length;
    let Some(whole) = buf.get(..total) else {
        return Decoded::Incomplete;
    };
    let (body, crc) = whole.split_at(total - 2);
    if crc16(body) != u16::from_le_bytes([crc[0], crc[1]]) {
        return Decoded::Invalid {
            skip: 1,
            why: Corruption::BadChecksum,
        };
    }
    let region = unstuff(&body[7..]);
    let Some((&instruction, rest)) = region.split_first() else {
        return Decoded::Invalid {
            skip: total,
            why: Corruption::BadLength,
        };
    };
    let (error, params) = if instruction == instruction::STATUS {
        match rest.split_first() {
            Some((&e, p)) => (e, p.to_vec()),
            None => {
                return Decoded::Invalid {
                    skip: total,
                    why: Corruption::BadLength,
                };
            }
        }
    } else {
        (0, rest.to_vec())
    };
    Decoded::Packet {
        value: Packet {
            id,
            instruction,
            error,
            params,
        },
        used: total,
    }
}

/// Parses a status packet at the start of `buf`; other packets are [`Corruption::NotStatus`].
///
/// ```
/// use joint_bridge::serial::{Decoded, dynamixel2::decode_status};
/// // The e-manual's reply to a ping of id 1: model 1030 (XM430-W350), firmware 38.
/// let reply = [0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x07, 0x00, 0x55, 0x00, 0x06, 0x04, 0x26, 0x65, 0x5D];
/// let Decoded::Packet { value, used } = decode_status(&reply) else { panic!() };
/// assert_eq!((value.id, value.error, value.params, used), (1, 0, vec![0x06, 0x04, 0x26], 14));
/// ```
pub fn decode_status(buf: &[u8]) -> Decoded<Packet> {
    match decode_packet(buf) {
        Decoded::Packet { value, used } if value.instruction != instruction::STATUS => {
            Decoded::Invalid {
                skip: used,
                why: Corruption::NotStatus,
            }
        }
        other => other,
    }
}

/// The names of the errors in a status packet's error byte (empty when there is none).
pub fn error_names(error: u8) -> Vec<&'static str> {
    let mut out = Vec::new();
    if error & 0x80 != 0 {
        out.push("hardware alert");
    }
    match error & 0x7F {
        0 => {}
        1 => out.push("result fail"),
        2 => out.push("instruction error"),
        3 => out.push("CRC error"),
        4 => out.push("data range error"),
        5 => out.push("data length error"),
        6 => out.push("data limit error"),
        7 => out.push("access error"),
        _ => out.push("unknown error number"),
    }
    out
}

/// The names of the bits of the X series' Hardware Error Status (address 70).
pub fn hardware_error_names(status: u8) -> Vec<&'static str> {
    [
        (0x01, "input voltage error"),
        (0x04, "overheating error"),
        (0x08, "motor encoder error"),
        (0x10, "electrical shock error"),
        (0x20, "overload error"),
    ]
    .into_iter()
    .filter(|(bit, _)| status & bit != 0)
    .map(|(_, name)| name)
    .collect()
}
