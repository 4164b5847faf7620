//! The serial protocols byte for byte: packets written out by hand from the manuals
//! (ROBOTIS e-manual Protocol 1.0 / 2.0, Pololu Maestro user's guide, Lynxmotion SSC-32U
//! manual), encode∘decode round trips as property tests, the status parsers fed arbitrary
//! bytes (no panic, always progress), and calibration validation messages.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use joint_bridge::serial::{
    Calibration, Decoded, Protocol, dynamixel1 as d1, dynamixel2 as d2, maestro, ssc32,
};
use proptest::prelude::*;

fn packet<T: std::fmt::Debug>(d: Decoded<T>) -> (T, usize) {
    match d {
        Decoded::Packet { value, used } => (value, used),
        other => panic!("not a packet: {other:?}"),
    }
}

// ---------------------------------------------------------------------------------------------
// Dynamixel Protocol 2.0 (e-manual examples)
// ---------------------------------------------------------------------------------------------

#[test]
fn d2_ping_of_id_1() {
    assert_eq!(
        d2::ping(1),
        [0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x01, 0x19, 0x4E]
    );
}

#[test]
fn d2_read_present_position_of_id_1() {
    // Address 132 = 0x84, length 4.
    assert_eq!(
        d2::read(1, 132, 4),
        [
            0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x07, 0x00, 0x02, 0x84, 0x00, 0x04, 0x00, 0x1D, 0x15
        ]
    );
}

#[test]
fn d2_write_goal_position_512_to_id_1() {
    // Address 116 = 0x74, 512 = 00 02 00 00.
    assert_eq!(
        d2::write(1, 116, &512i32.to_le_bytes()),
        [
            0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x09, 0x00, 0x03, 0x74, 0x00, 0x00, 0x02, 0x00, 0x00,
            0xCA, 0x89
        ]
    );
}

#[test]
fn d2_sync_write_two_goal_positions() {
    // id 1 → 150 (0x96), id 2 → 170 (0xAA): length 0x11 = 1 instruction + 4 (address,
    // data length) + 2 × 5 + 2 CRC.
    assert_eq!(
        d2::sync_write_goal_positions(&[(1, 150), (2, 170)]),
        [
            0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x11, 0x00, 0x83, 0x74, 0x00, 0x04, 0x00, 0x01, 0x96,
            0x00, 0x00, 0x00, 0x02, 0xAA, 0x00, 0x00, 0x00, 0x82, 0x87
        ]
    );
}

#[test]
fn d2_sync_read_present_positions_of_ids_1_and_2() {
    assert_eq!(
        d2::sync_read(132, 4, &[1, 2]),
        [
            0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x09, 0x00, 0x82, 0x84, 0x00, 0x04, 0x00, 0x01, 0x02,
            0xCE, 0xFA
        ]
    );
}

#[test]
fn d2_status_packets_of_the_manual_decode() {
    // Reply to ping: model 0x0406, firmware 0x26.
    let (p, used) = packet(d2::decode_status(&[
        0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x07, 0x00, 0x55, 0x00, 0x06, 0x04, 0x26, 0x65, 0x5D,
    ]));
    assert_eq!(
        (p.id, p.error, p.params.as_slice(), used),
        (1, 0, &[6, 4, 0x26][..], 14)
    );
    // Replies to the sync read: id 1 at 166 (0xA6), id 2 at 2079 (0x081F).
    let (p, _) = packet(d2::decode_status(&[
        0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x08, 0x00, 0x55, 0x00, 0xA6, 0x00, 0x00, 0x00, 0x8C, 0xC0,
    ]));
    assert_eq!((p.id, p.param_i32()), (1, Some(166)));
    let (p, _) = packet(d2::decode_status(&[
        0xFF, 0xFF, 0xFD, 0x00, 0x02, 0x08, 0x00, 0x55, 0x00, 0x1F, 0x08, 0x00, 0x00, 0xBA, 0xBE,
    ]));
    assert_eq!((p.id, p.param_i32()), (2, Some(2079)));
    // Reply to the write: no parameters.
    let (p, used) = packet(d2::decode_status(&[
        0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x04, 0x00, 0x55, 0x00, 0xA1, 0x0C,
    ]));
    assert_eq!((p.id, p.error, p.params.len(), used), (1, 0, 0, 11));
}

#[test]
fn d2_a_flipped_crc_bit_is_a_checksum_error_and_one_byte_is_dropped() {
    let mut bytes = d2::status_packet(1, 0, &[0xA6, 0, 0, 0]);
    let n = bytes.len();
    bytes[n - 1] ^= 0x01;
    assert_eq!(
        d2::decode_status(&bytes),
        Decoded::Invalid {
            skip: 1,
            why: joint_bridge::serial::Corruption::BadChecksum
        }
    );
}

#[test]
fn d2_byte_stuffing_inserts_fd_after_ff_ff_fd() {
    // Goal position 0x00FDFFFF: data bytes FF FF FD 00; the stuffed region gets FD after them.
    let bytes = d2::write(1, 116, &[0xFF, 0xFF, 0xFD, 0x00]);
    // Region: 03 74 00 FF FF FD [FD] 00 → 7 bytes + 1 stuffed + 2 CRC = length 10.
    assert_eq!(&bytes[5..7], &[10, 0]);
    assert_eq!(
        &bytes[7..15],
        &[0x03, 0x74, 0x00, 0xFF, 0xFF, 0xFD, 0xFD, 0x00]
    );
    let (p, _) = packet(d2::decode_packet(&bytes));
    assert_eq!(p.params, vec![0x74, 0x00, 0xFF, 0xFF, 0xFD, 0x00]);
}

#[test]
fn d2_error_byte_names() {
    assert_eq!(d2::error_names(0x00), Vec::<&str>::new());
    assert_eq!(d2::error_names(0x03), vec!["CRC error"]);
    assert_eq!(d2::error_names(0x80), vec!["hardware alert"]);
    assert_eq!(
        d2::hardware_error_names(0x24),
        vec!["overheating error", "overload error"]
    );
}

// ---------------------------------------------------------------------------------------------
// Dynamixel Protocol 1.0
// ---------------------------------------------------------------------------------------------

#[test]
fn d1_manual_packets() {
    // Ping id 1: checksum !(01 + 02 + 01) = !04 = FB.
    assert_eq!(d1::ping(1), [0xFF, 0xFF, 0x01, 0x02, 0x01, 0xFB]);
    // Read the temperature of id 1 (address 0x2B, 1 byte): !(01+04+02+2B+01) = !33 = CC.
    assert_eq!(
        d1::read(1, 0x2B, 1),
        [0xFF, 0xFF, 0x01, 0x04, 0x02, 0x2B, 0x01, 0xCC]
    );
    // Write 0x40 0x00 at 0x30 of id 0: !(00+05+03+30+40+00) = !78 = 87.
    assert_eq!(
        d1::write(0, 0x30, &[0x40, 0x00]),
        [0xFF, 0xFF, 0x00, 0x05, 0x03, 0x30, 0x40, 0x00, 0x87]
    );
    // Status "FF FF 00 02 08 F5": id 0, range error.
    let (p, _) = packet(d1::decode_status(&[0xFF, 0xFF, 0x00, 0x02, 0x08, 0xF5]));
    assert_eq!((p.id, p.code), (0, 0x08));
    assert_eq!(d1::error_names(p.code), vec!["range error"]);
}

#[test]
fn d1_sync_write_of_the_manual() {
    // Four servos, goal position and speed (4 bytes at 0x1E): id 0 → 0x010, 0x150;
    // id 1 → 0x220, 0x360; id 2 → 0x030, 0x170; id 3 → 0x220, 0x380.
    // Length (4 + 1) × 4 + 4 = 0x18; checksum worked out below.
    let v: [(u8, [u8; 4]); 4] = [
        (0, [0x10, 0x00, 0x50, 0x01]),
        (1, [0x20, 0x02, 0x60, 0x03]),
        (2, [0x30, 0x00, 0x70, 0x01]),
        (3, [0x20, 0x02, 0x80, 0x03]),
    ];
    // Sum: FE+18+83+1E+04 = 0x1BB; data and ids: 0x00+0x10+0x00+0x50+0x01 = 0x61,
    // 0x01+0x20+0x02+0x60+0x03 = 0x86, 0x02+0x30+0x00+0x70+0x01 = 0xA3,
    // 0x03+0x20+0x02+0x80+0x03 = 0xA8; total 0x1BB+0x61+0x86+0xA3+0xA8 = 0x3ED; !0xED = 0x12.
    assert_eq!(
        d1::sync_write(0x1E, &v),
        [
            0xFF, 0xFF, 0xFE, 0x18, 0x83, 0x1E, 0x04, 0x00, 0x10, 0x00, 0x50, 0x01, 0x01, 0x20,
            0x02, 0x60, 0x03, 0x02, 0x30, 0x00, 0x70, 0x01, 0x03, 0x20, 0x02, 0x80, 0x03, 0x12
        ]
    );
}

// ---------------------------------------------------------------------------------------------
// Pololu Maestro
// ---------------------------------------------------------------------------------------------

#[test]
fn maestro_commands_by_hand() {
    // 1500 µs = 6000 quarter-µs = 0x1770: low 7 bits 0x70, high 7 bits 0x2E.
    assert_eq!(
        maestro::set_target(2, maestro::quarter_us(1500.0)),
        [0x84, 0x02, 0x70, 0x2E]
    );
    // Channels 3 and 4 to 1500 and 1000 µs (4000 = 0x0FA0: 0x20, 0x1F).
    assert_eq!(
        maestro::set_multiple_targets(3, &[6000, 4000]),
        [0x9F, 0x02, 0x03, 0x70, 0x2E, 0x20, 0x1F]
    );
    // Channels 0, 1 and 5: two runs.
    assert_eq!(
        maestro::set_targets(&[(5, 6000), (0, 4000), (1, 6000)]),
        [
            0x9F, 0x02, 0x00, 0x20, 0x1F, 0x70, 0x2E, 0x9F, 0x01, 0x05, 0x70, 0x2E
        ]
    );
    // Speed 140 = 0x8C: 0x0C, 0x01.
    assert_eq!(maestro::set_speed(5, 140), [0x87, 0x05, 0x0C, 0x01]);
    assert_eq!(maestro::set_acceleration(5, 4), [0x89, 0x05, 0x04, 0x00]);
    assert_eq!(maestro::get_position(1), [0x90, 0x01]);
    // Reply 0x70 0x17 = 0x1770 = 6000.
    assert_eq!(maestro::decode_reply([0x70, 0x17]), 6000);
    assert_eq!(
        maestro::error_names(0x0011),
        vec!["serial signal error", "serial protocol error"]
    );
    // Quarter-µs rounding: 1500.1 µs → 6000.4 → 6000; 1500.2 → 6000.8 → 6001.
    assert_eq!(maestro::quarter_us(1500.1), 6000);
    assert_eq!(maestro::quarter_us(1500.2), 6001);
}

// ---------------------------------------------------------------------------------------------
// Lynxmotion SSC-32U
// ---------------------------------------------------------------------------------------------

#[test]
fn ssc32_lines_by_hand() {
    assert_eq!(
        ssc32::group_move(&[(5, 1600), (10, 750)], Some(2500)),
        b"#5P1600#10P750T2500\r"
    );
    assert_eq!(ssc32::group_move(&[(0, 1500)], None), b"#0P1500\r");
    assert_eq!(ssc32::pulses_off(&[1, 2]), b"#1P0#2P0\r");
    assert_eq!(ssc32::query_pulse_widths(&[0]), b"QP 0\r");
    // 150 → 1500 µs.
    assert_eq!(ssc32::decode_pulse_width(150), 1500);
    assert_eq!(
        ssc32::decode_line(b"#5P1600#10P750T2500").unwrap(),
        ssc32::Line::Move(vec![(5, 1600), (10, 750)], Some(2500))
    );
    assert!(
        ssc32::decode_line(b"#5X1600")
            .unwrap_err()
            .to_string()
            .contains("#5X1600")
    );
}

// ---------------------------------------------------------------------------------------------
// Property tests: round trips, and arbitrary bytes into the parsers
// ---------------------------------------------------------------------------------------------

proptest! {
    #[test]
    fn d2_any_instruction_round_trips(id in 0u8..=252, inst in any::<u8>(), params in proptest::collection::vec(any::<u8>(), 0..64)) {
        let bytes = d2::instruction_packet(id, inst, &params);
        let (p, used) = packet(d2::decode_packet(&bytes));
        prop_assert_eq!(used, bytes.len());
        prop_assert_eq!(p.id, id);
        prop_assert_eq!(p.instruction, inst);
        if inst == d2::instruction::STATUS {
            prop_assert_eq!(params.first().copied().unwrap_or(0), p.error);
        } else {
            prop_assert_eq!(p.params, params);
        }
    }

    #[test]
    fn d2_any_status_round_trips_even_after_garbage(id in 0u8..=252, error in any::<u8>(), params in proptest::collection::vec(any::<u8>(), 0..64), junk in proptest::collection::vec(0u8..0xFF, 0..8)) {
        let mut bytes = junk.clone();
        bytes.extend(d2::status_packet(id, error, &params));
        let mut buf = bytes.as_slice();
        loop {
            match d2::decode_status(buf) {
                Decoded::Invalid { skip, .. } => buf = &buf[skip..],
                Decoded::Packet { value, used } => {
                    prop_assert_eq!(used, buf.len());
                    prop_assert_eq!((value.id, value.error, value.params), (id, error, params));
                    break;
                }
                Decoded::Incomplete => prop_assert!(false, "incomplete"),
            }
        }
    }

    #[test]
    fn d2_goal_positions_round_trip(goals in proptest::collection::vec((0u8..=252, 0i32..=4095), 1..20)) {
        let bytes = d2::sync_write_goal_positions(&goals);
        let (p, _) = packet(d2::decode_packet(&bytes));
        prop_assert_eq!(p.instruction, d2::instruction::SYNC_WRITE);
        let got: Vec<(u8, i32)> = p.params[4..].chunks(5).map(|c| (c[0], i32::from_le_bytes([c[1], c[2], c[3], c[4]]))).collect();
        prop_assert_eq!(got, goals);
    }

    #[test]
    fn d1_any_packet_round_trips(id in 0u8..=253, code in any::<u8>(), params in proptest::collection::vec(any::<u8>(), 0..100)) {
        let bytes = d1::status_packet(id, code, &params);
        let (p, used) = packet(d1::decode_status(&bytes));
        prop_assert_eq!(used, bytes.len());
        prop_assert_eq!((p.id, p.code, p.params), (id, code, params));
    }

    #[test]
    fn maestro_targets_round_trip(targets in proptest::collection::vec((0u8..24, 0u16..=0x3FFF), 1..24)) {
        let mut unique = targets.clone();
        unique.sort_by_key(|t| t.0);
        unique.dedup_by_key(|t| t.0);
        let bytes = maestro::set_targets(&unique);
        let mut got = Vec::new();
        let mut buf = bytes.as_slice();
        while !buf.is_empty() {
            let (cmd, used) = packet(maestro::decode_command(buf));
            let maestro::Command::SetMultipleTargets(first, ts) = cmd else { panic!("{cmd:?}") };
            for (k, t) in ts.into_iter().enumerate() {
                got.push((first + k as u8, t));
            }
            buf = &buf[used..];
        }
        prop_assert_eq!(got, unique);
    }

    #[test]
    fn ssc32_group_moves_round_trip(moves in proptest::collection::vec((0u8..32, 500u16..=2500), 1..32), t in proptest::option::of(0u32..65535)) {
        let line = ssc32::group_move(&moves, t);
        prop_assert_eq!(line.last(), Some(&b'\r'));
        prop_assert_eq!(ssc32::decode_line(&line[..line.len() - 1]).unwrap(), ssc32::Line::Move(moves, t));
    }

    /// Fuzz: arbitrary bytes never panic any parser, and an invalid verdict always drops at
    /// least one byte and never more than there are (so a read loop always progresses).
    #[test]
    fn parsers_survive_arbitrary_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..300)) {
        let verdicts = [
            d2::decode_status(&bytes).map_skip(),
            d2::decode_packet(&bytes).map_skip(),
            d1::decode_status(&bytes).map_skip(),
            maestro::decode_command(&bytes).map_skip(),
        ];
        for (skip, used) in verdicts.into_iter().flatten() {
            prop_assert!(skip.max(used) >= 1 && skip.max(used) <= bytes.len(), "skip {skip} used {used} of {}", bytes.len());
        }
        let _ = ssc32::decode_line(&bytes);
    }

    /// Fuzz with a valid header in front, where the length and checksum paths are reached.
    #[test]
    fn d2_parser_survives_arbitrary_bodies(body in proptest::collection::vec(any::<u8>(), 0..300)) {
        let mut bytes = d2::HEADER.to_vec();
        bytes.extend(&body);
        if let Decoded::Packet { used, .. } | Decoded::Invalid { skip: used, .. } = d2::decode_status(&bytes) {
            prop_assert!(used >= 1 && used <= bytes.len());
        }
        let mut bytes = vec![0xFF, 0xFF];
        bytes.extend(&body);
        if let Decoded::Packet { used, .. } | Decoded::Invalid { skip: used, .. } = d1::decode_status(&bytes) {
            prop_assert!(used >= 1 && used <= bytes.len());
        }
    }
}

trait Skip {
    fn map_skip(self) -> Option<(usize, usize)>;
}
impl<T> Skip for Decoded<T> {
    fn map_skip(self) -> Option<(usize, usize)> {
        match self {
            Decoded::Incomplete => None,
            Decoded::Packet { used, .. } => Some((0, used)),
            Decoded::Invalid { skip, .. } => Some((skip, 0)),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Calibration
// ---------------------------------------------------------------------------------------------

#[test]
fn the_example_calibrations_load_and_cover_the_leg_joints() {
    let legs = [
        "l_hip_roll",
        "l_hip_pitch",
        "l_knee",
        "l_ankle_pitch",
        "l_ankle_roll",
        "r_hip_roll",
        "r_hip_pitch",
        "r_knee",
        "r_ankle_pitch",
        "r_ankle_roll",
    ];
    for p in Protocol::ALL {
        let path = format!(
            "{}/../config/calibration_{p}.yaml",
            env!("CARGO_MANIFEST_DIR")
        );
        let c = Calibration::from_file(std::path::Path::new(&path)).unwrap();
        assert_eq!(c.protocol, p);
        let names: Vec<&str> = c.joints.keys().map(String::as_str).collect();
        let mut want = legs.to_vec();
        want.sort();
        assert_eq!(names, want, "{path}");
    }
}

#[test]
fn calibration_conversion_by_hand() {
    let c = Calibration::from_yaml_str(
        "protocol: dynamixel2\njoints:\n  r_knee: { id: 8, zero: 2048, direction: -1, units_per_rad: 651.8986, min: 500, max: 2100 }\n",
        "t",
    )
    .unwrap();
    let k = c.joints["r_knee"];
    // 1 rad: 2048 − 651.8986 = 1396.1014; 2 rad: 2048 − 1303.7972 = 744.2028.
    assert!((k.to_units(1.0).unwrap() - 1396.1014).abs() < 1e-9);
    // −0.5 rad: 2048 + 325.9493 = 2373.9493, clamped to max 2100.
    assert_eq!(k.to_units(-0.5), Some(2100.0));
    assert_eq!(k.to_units(f64::NAN), None);
    assert!((k.to_rad(1396.1014) - 1.0).abs() < 1e-12);
}

#[test]
fn calibration_errors_name_the_joint_and_key() {
    let cases = [
        ("protocol: dynamixel3\njoints: {}\n", "key `protocol`"),
        (
            "protocol: ssc32\njoints:\n  a: { id: 40, zero: 1500, direction: 1, units_per_rad: 600, min: 900, max: 2100 }\n",
            "joint `a`, key `id`: 40 is outside 0..=31",
        ),
        (
            "protocol: ssc32\njoints:\n  a: { id: 1, zero: 1500, direction: 1, units_per_rad: 600, min: 900, max: 2100 }\n  b: { id: 1, zero: 1500, direction: 1, units_per_rad: 600, min: 900, max: 2100 }\n",
            "joint `b`, key `id`: 1 is also the id of joint `a`",
        ),
        (
            "protocol: ssc32\njoints:\n  a: { id: 1, zero: 1500, direction: 1, units_per_rad: -600, min: 900, max: 2100 }\n",
            "joint `a`, key `units_per_rad`",
        ),
        (
            "protocol: ssc32\njoints:\n  a: { id: 1, zero: 1500, direction: 1, units_per_rad: 600, min: 300, max: 2100 }\n",
            "joint `a`, key `min`: 300 µs is outside",
        ),
        (
            "protocol: dynamixel1\njoints:\n  a: { id: 1, zero: 512, direction: 1, units_per_rad: 195, min: 600, max: 500 }\n",
            "joint `a`, key `max`: 500 is not above min 600",
        ),
        (
            "protocol: dynamixel1\njoints:\n  a: { id: 1, zero: 100, direction: 1, units_per_rad: 195, min: 200, max: 500 }\n",
            "joint `a`, key `zero`",
        ),
        (
            "protocol: dynamixel2\nspeed: 3\njoints:\n  a: { id: 1, zero: 100, direction: 1, units_per_rad: 195, min: 0, max: 500 }\n",
            "key `speed`: only for maestro",
        ),
        (
            "protocol: dynamixel2\njoints:\n  a: { id: 1, zero: 100, direction: 1, units_per_rad: 195, min: 0, max: 500, offset: 3 }\n",
            "unknown field `offset`",
        ),
    ];
    for (text, want) in cases {
        let e = Calibration::from_yaml_str(text, "case.yaml")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(want) && e.contains("case.yaml"),
            "{e}\n  wanted: {want}"
        );
    }
}
