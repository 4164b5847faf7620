//! Lynxmotion SSC-32U servo controller, ASCII protocol: pure encode and decode, no I/O.
//!
//! | command | text | reply |
//! |---|---|---|
//! | group move | `#<ch>P<pw>` for each servo, each optionally `S<µs/s>` (speed), optionally `T<ms>` (move time), then carriage return | none |
//! | pulses off | `#<ch>P0` for each servo, carriage return | none |
//! | query pulse width | `QP <ch>` for each servo (space separated), carriage return | one byte per servo: pulse width / 10 µs |
//! | version | `VER`, carriage return | text ending in a carriage return, e.g. `SSC32-V2.50USB` |
//!
//! Units: pulse width in whole microseconds, 500-2500 (1500 = centre). Every servo of a
//! group move starts and ends its motion together. No checksum: the board ignores a line it
//! cannot parse. The SSC-32U does not measure the servo: a query returns the pulse it
//! outputs, with a resolution of 10 µs.

/// The line terminator.
pub const CR: u8 = b'\r';

/// Microseconds to the wire's whole microseconds, rounded, within 0-2500 (0 = off).
pub fn whole_us(pulse_us: f64) -> u16 {
    let r = pulse_us.round();
    if r.is_nan() || r <= 0.0 {
        0
    } else if r >= 2500.0 {
        2500
    } else {
        r as u16
    }
}

/// A group move of channels to pulse widths (µs), over `time_ms` if given.
///
/// ```
/// let line = joint_bridge::serial::ssc32::group_move(&[(0, 1500), (5, 1750)], Some(100));
/// assert_eq!(line, b"#0P1500#5P1750T100\r");
/// ```
pub fn group_move(targets: &[(u8, u16)], time_ms: Option<u32>) -> Vec<u8> {
    group_move_at(targets, None, time_ms)
}

/// A group move with every servo's speed limited to `speed_us_s` (µs per second), if
/// given: the board moves each output pulse towards its target at that speed.
///
/// ```
/// let line = joint_bridge::serial::ssc32::group_move_at(&[(0, 1500), (5, 1750)], Some(300), None);
/// assert_eq!(line, b"#0P1500S300#5P1750S300\r");
/// ```
pub fn group_move_at(
    targets: &[(u8, u16)],
    speed_us_s: Option<u16>,
    time_ms: Option<u32>,
) -> Vec<u8> {
    let mut s = String::with_capacity(16 * targets.len() + 8);
    for &(ch, pw) in targets {
        s.push_str(&format!("#{ch}P{pw}"));
        if let Some(v) = speed_us_s {
            s.push_str(&format!("S{v}"));
        }
    }
    if let Some(t) = time_ms {
        s.push_str(&format!("T{t}"));
    }
    let mut out = s.into_bytes();
    out.push(CR);
    out
}

/// Stops the pulses of these channels (the servos go limp).
pub fn pulses_off(channels: &[u8]) -> Vec<u8> {
    let targets: Vec<(u8, u16)> = channels.iter().map(|&c| (c, 0)).collect();
    group_move(&targets, None)
}

/// Asks for the pulse widths of these channels.
///
/// ```
/// assert_eq!(joint_bridge::serial::ssc32::query_pulse_widths(&[3, 12]), b"QP 3 QP 12\r");
/// ```
pub fn query_pulse_widths(channels: &[u8]) -> Vec<u8> {
    let parts: Vec<String> = channels.iter().map(|c| format!("QP {c}")).collect();
    let mut out = parts.join(" ").into_bytes();
    out.push(CR);
    out
}

/// Asks for the firmware version (used as a ping).
pub fn version() -> Vec<u8> {
    b"VER\r".to_vec()
}

/// A query reply byte to microseconds.
pub fn decode_pulse_width(byte: u8) -> u16 {
    u16::from(byte) * 10
}

/// A line decoded (the board's side: for emulators and round-trip tests).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Line {
    /// Group move: (channel, pulse µs) and the optional time.
    Move(Vec<(u8, u16)>, Option<u32>),
    /// Group move with speeds: (channel, pulse µs, speed µs/s if given) and the optional time.
    MoveAt(Vec<(u8, u16, Option<u16>)>, Option<u32>),
    /// Query pulse width of channels.
    Query(Vec<u8>),
    /// Version.
    Version,
}

/// Why a line is not understood.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("SSC-32 line {line:?}: {why}")]
pub struct LineError {
    /// The line (lossy text).
    pub line: String,
    /// What is wrong.
    pub why: String,
}

/// Parses one line (without its carriage return).
pub fn decode_line(line: &[u8]) -> Result<Line, LineError> {
    let text = String::from_utf8_lossy(line).to_string();
    let err = |why: &str| LineError {
        line: text.clone(),
        why: why.to_string(),
    };
    let t = text.trim();
    if t == "VER" {
        return Ok(Line::Version);
    }
    if let Some(rest) = t.strip_prefix("QP") {
        let mut chans = Vec::new();
        for part in rest.split("QP") {
            let n: u8 = part.trim().parse().map_err(|_| err("bad channel in QP"))?;
            chans.push(n);
        }
        return Ok(Line::Query(chans));
    }
    let mut moves = Vec::new();
    let mut time = None;
    let mut rest = t;
    while !rest.is_empty() {
        let mut chars = rest.chars();
        let head = chars.next().unwrap_or(' ');
        let tail = chars.as_str();
        let end = tail
            .find(|c: char| !c.is_ascii_digit())
            .unwrap_or(tail.len());
        let (num, after) = tail.split_at(end);
        match head {
            '#' => {
                let ch: u8 = num.parse().map_err(|_| err("bad channel"))?;
                let Some(p) = after.strip_prefix('P') else {
                    return Err(err("channel without P"));
                };
                let end = p.find(|c: char| !c.is_ascii_digit()).unwrap_or(p.len());
                let pw: u16 = p[..end].parse().map_err(|_| err("bad pulse width"))?;
                rest = &p[end..];
                let mut speed = None;
                if let Some(sp) = rest.strip_prefix('S') {
                    let end = sp.find(|c: char| !c.is_ascii_digit()).unwrap_or(sp.len());
                    speed = Some(sp[..end].parse().map_err(|_| err("bad speed"))?);
                    rest = &sp[end..];
                }
                moves.push((ch, pw, speed));
            }
            'T' => {
                time = Some(num.parse().map_err(|_| err("bad time"))?);
                rest = after;
            }
            _ => return Err(err("unknown command")),
        }
    }
    if moves.is_empty() {
        return Err(err("empty move"));
    }
    if moves.iter().all(|m| m.2.is_none()) {
        return Ok(Line::Move(
            moves.into_iter().map(|(c, p, _)| (c, p)).collect(),
            time,
        ));
    }
    Ok(Line::MoveAt(moves, time))
}
