//! End to end over pseudo-terminals: the joint bridge with the serial backend drives an
//! emulated board (tests/support) through a whole planned walk, for each protocol; and the
//! faults: unplug / replug mid-walk, garbage and CRC-failing replies, a missing servo, a
//! port absent at start, a servo's error bits.
//!
//! The walk: `gait_planner::plan_walk` of the default robot (4 steps, default gait), each
//! tick's ankle targets through `ik_solver` (`solve_legs`, as the ik_solver node does), the
//! leg joints commanded to the bridge at the tick's time. Expected targets on the wire are
//! the commanded angles through the example calibration (config/calibration_<protocol>.yaml)
//! computed here (zero + direction × units_per_rad × angle, clamped), within one unit.
//! Replies are awaited up to 0.5 s: on a loaded 2-core machine an emulator thread can be
//! descheduled for tens of milliseconds, which a real board never is.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod support;

use std::path::Path;

use gait_planner::{GaitParams, plan_walk};
use ik_solver::BipedModel;
use joint_bridge::serial::{Calibration, Protocol, SerialBackend, SerialConfig};
use joint_bridge::{
    Backend, BackendError, Backoff, BridgeConfig, Event, JointBridge, JointSpec, Lifecycle,
    TimeoutAction,
};
use support::Board;

const RAMP_S: f64 = 0.5;

fn calibration(p: Protocol) -> Calibration {
    let path = format!(
        "{}/../config/calibration_{p}.yaml",
        env!("CARGO_MANIFEST_DIR")
    );
    Calibration::from_file(Path::new(&path)).unwrap()
}

/// The walk: per tick, (t, leg joint names, angles).
struct Walk {
    names: Vec<String>,
    ticks: Vec<(f64, Vec<f64>)>,
}

fn walk(steps: u32) -> Walk {
    let model = BipedModel::from_urdf_str(ik_solver::DEFAULT_URDF, None).unwrap();
    // The slow walk: the board must get exactly the planned angles, and the default walk's
    // swing knee starts each step at 118 rad/s², past the bridge's 100 rad/s² limiter,
    // which smooths it (a unit or two off the plan for a tick).
    let params = GaitParams::slow(&model);
    let samples = plan_walk(model.clone(), params, steps).unwrap();
    let (names, dofs): (Vec<String>, Vec<usize>) = model
        .leg_joints()
        .map(|(_, j)| (j.name.clone(), j.dof))
        .unzip();
    let mut q = vec![0.0; model.robot().dof_count()];
    let ticks = samples
        .iter()
        .map(|s| {
            model
                .solve_legs(&s.targets[0], &s.targets[1], &mut q)
                .unwrap();
            (s.t_s, dofs.iter().map(|&d| q[d]).collect())
        })
        .collect();
    Walk { names, ticks }
}

/// The bridge's joints: the calibrated ones, with their URDF limits.
fn leg_specs(cal: &Calibration) -> Vec<JointSpec> {
    let model = BipedModel::from_urdf_str(ik_solver::DEFAULT_URDF, None).unwrap();
    JointSpec::from_robot(model.robot())
        .into_iter()
        .filter(|j| cal.joints.contains_key(&j.name))
        .collect()
}

fn bridge(p: Protocol, port: &Path) -> JointBridge<SerialBackend> {
    let cal = calibration(p);
    let joints = leg_specs(&cal);
    let backend = SerialBackend::new(SerialConfig {
        port: port.display().to_string(),
        baud: 1_000_000,
        calibration: cal,
        reply_timeout_s: 0.5,
    });
    JointBridge::new(
        backend,
        joints,
        BridgeConfig {
            watchdog_timeout_s: 1e6,
            on_timeout: TimeoutAction::Hold,
            start_ramp_s: RAMP_S,
            reconnect: Some(Backoff {
                first_s: 0.05,
                max_s: 0.2,
            }),
            ..BridgeConfig::default()
        },
    )
}

/// Servos of the calibration at their zero (a robot standing straight).
fn servos_at_zero(cal: &Calibration) -> Vec<(u8, f64)> {
    cal.joints.values().map(|j| (j.id, j.zero)).collect()
}

/// What the board should receive for `angles` (bridge joint order).
fn expected_units(cal: &Calibration, names: &[String], angles: &[f64]) -> Vec<(u8, f64)> {
    let mut v: Vec<(u8, f64)> = names
        .iter()
        .zip(angles)
        .map(|(n, &a)| {
            let j = cal.joints[n];
            let u = (j.zero + f64::from(j.direction) * j.units_per_rad * a).clamp(j.min, j.max);
            (j.id, u)
        })
        .collect();
    v.sort_by_key(|x| x.0);
    v
}

fn sorted(mut g: Vec<(u8, f64)>) -> Vec<(u8, f64)> {
    g.sort_by_key(|x| x.0);
    g
}

/// The angles of a walk tick in the bridge's joint order.
fn in_bridge_order(walk: &Walk, joints: &[JointSpec], angles: &[f64]) -> Vec<f64> {
    joints
        .iter()
        .map(|j| angles[walk.names.iter().position(|n| *n == j.name).unwrap()])
        .collect()
}

/// Waits (up to 10 s) until the board has logged `n` goal packets.
fn wait_goals(board: &Board, n: usize) -> Vec<Vec<(u8, f64)>> {
    for _ in 0..1000 {
        let g = board.with(|s| s.goals.clone());
        if g.len() >= n {
            return g;
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    board.with(|s| s.goals.clone())
}

fn assert_within_one_unit(p: Protocol, got: &[(u8, f64)], want: &[(u8, f64)], what: &str) {
    // One unit on the wire: a tick, a quarter-µs (Maestro), a µs (SSC-32U).
    let unit = match p {
        Protocol::Maestro => 0.25,
        _ => 1.0,
    };
    assert_eq!(got.len(), want.len(), "{what}");
    for (g, w) in got.iter().zip(want) {
        assert_eq!(g.0, w.0, "{what}");
        assert!(
            (g.1 - w.1).abs() <= unit,
            "{what}: id {} got {} want {}",
            g.0,
            g.1,
            w.1
        );
    }
}

fn whole_walk(p: Protocol) {
    let dir = support::temp_dir(&format!("walk-{p}"));
    let dev = dir.join("ttyBOARD");
    let cal = calibration(p);
    let board = Board::new(p, &dev, &servos_at_zero(&cal));
    let w = walk(4);
    let mut b = bridge(p, &dev);
    b.start().unwrap();
    assert_eq!(b.state(), Lifecycle::Active);
    let joints = b.joints().to_vec();
    let names: Vec<String> = joints.iter().map(|j| j.name.clone()).collect();
    let mut measured = None;
    for (t, angles) in &w.ticks {
        let ev = b.command(*t, &w.names, angles);
        assert!(ev.is_empty(), "{ev:?}");
        let (r, ev) = b.tick(*t);
        assert!(ev.is_empty(), "{ev:?}");
        measured = Some(r.unwrap().measured);
    }
    assert_eq!(measured, Some(p.measures()));
    let goals = wait_goals(&board, w.ticks.len());
    assert_eq!(goals.len(), w.ticks.len(), "one goal packet per tick");
    // After the start ramp, every tick's targets are the commanded angles through the
    // calibration (the plan stays within the URDF speed limits, so nothing is slowed).
    let after_ramp = w
        .ticks
        .iter()
        .position(|(t, _)| *t > w.ticks[0].0 + RAMP_S + 1e-9)
        .unwrap();
    for (k, ((_, angles), g)) in w.ticks.iter().zip(&goals).enumerate().skip(after_ramp) {
        let want = expected_units(&cal, &names, &in_bridge_order(&w, &joints, angles));
        assert_within_one_unit(p, &sorted(g.clone()), &want, &format!("{p} tick {k}"));
    }
    let c = b.backend().counters();
    assert_eq!(c.cycles as usize, w.ticks.len());
    assert_eq!(
        (c.timeouts, c.corrupted, c.checksum_errors, c.port_failures),
        (0, 0, 0, 0),
        "{c:?}"
    );
    // Torque off on stop.
    b.stop().unwrap();
    board.wait_until(|s| {
        s.commands
            .iter()
            .filter(|c| (c.starts_with("torque") && c.ends_with(" 0")) || c.starts_with("off"))
            .count()
            >= if p.measures() { 10 } else { 1 }
    });
    let cmds = board.with(|s| s.commands.clone());
    match p {
        Protocol::Dynamixel2 | Protocol::Dynamixel1 => {
            assert!(
                cmds.iter()
                    .any(|c| c.starts_with("torque") && c.ends_with(" 1")),
                "{cmds:?}"
            );
            assert_eq!(
                cmds.iter()
                    .filter(|c| c.starts_with("torque") && c.ends_with(" 0"))
                    .count(),
                10,
                "{cmds:?}"
            );
            assert!(board.with(|s| s.servos.values().all(|s| !s.torque)));
        }
        Protocol::Maestro => {
            assert!(cmds.contains(&"speed 0 200".to_string()), "{cmds:?}");
            assert_eq!(cmds.last().unwrap(), "off 10");
        }
        Protocol::Ssc32 => assert_eq!(cmds.last().unwrap(), "off 10"),
    }
}

#[test]
fn dynamixel2_walk_reaches_the_board_through_the_calibration() {
    whole_walk(Protocol::Dynamixel2);
}
#[test]
fn dynamixel1_walk_reaches_the_board_through_the_calibration() {
    whole_walk(Protocol::Dynamixel1);
}
#[test]
fn maestro_walk_reaches_the_board_through_the_calibration() {
    whole_walk(Protocol::Maestro);
}
#[test]
fn ssc32_walk_reaches_the_board_through_the_calibration() {
    whole_walk(Protocol::Ssc32);
}

#[test]
fn the_start_ramps_from_the_measured_pose_never_a_snap() {
    // Servos start up to 300 ticks off their zero (within their calibrated limits); the
    // first command is the walk's first pose.
    let p = Protocol::Dynamixel2;
    let dir = support::temp_dir("ramp");
    let dev = dir.join("ttyBOARD");
    let cal = calibration(p);
    let start: Vec<(u8, f64)> = cal
        .joints
        .values()
        .map(|j| (j.id, (j.zero + 300.0).min(j.max)))
        .collect();
    let board = Board::new(p, &dev, &start);
    let w = walk(1);
    let mut b = bridge(p, &dev);
    b.start().unwrap();
    let n = (RAMP_S * 100.0) as usize + 5;
    for (t, angles) in w.ticks.iter().take(n) {
        b.command(*t, &w.names, angles);
        b.tick(*t).0.unwrap();
    }
    let goals = wait_goals(&board, n);
    // The first packet is the measured pose (the ramp starts there), and no step between
    // packets is larger than the smoothstep's steepest: 1.5 × 300 ticks × 0.01 s / 0.5 s
    // = 9 ticks, plus the walk's own motion (≤ 6 rad/s × 0.01 s × 652 ticks/rad ≈ 39).
    for (id, u) in sorted(goals[0].clone()) {
        let j = cal.joints.values().find(|j| j.id == id).unwrap();
        assert_eq!(u, (j.zero + 300.0).min(j.max), "id {id}");
    }
    for pair in goals.windows(2) {
        for (a, b) in sorted(pair[0].clone()).iter().zip(sorted(pair[1].clone())) {
            assert!((a.1 - b.1).abs() <= 9.0 + 39.2, "{a:?} → {b:?}");
        }
    }
    assert!(!b.ramping());
}

#[test]
fn unplug_mid_walk_reconnects_reconfigures_and_resumes() {
    let p = Protocol::Dynamixel2;
    let dir = support::temp_dir("unplug");
    let dev = dir.join("ttyBOARD");
    let cal = calibration(p);
    let mut board = Board::new(p, &dev, &servos_at_zero(&cal));
    let w = walk(4);
    let mut b = bridge(p, &dev);
    b.start().unwrap();
    let joints = b.joints().to_vec();
    let names: Vec<String> = joints.iter().map(|j| j.name.clone()).collect();
    let mut events = Vec::new();
    let mut reconnected_at = None;
    for (k, (t, angles)) in w.ticks.iter().enumerate() {
        if k == 300 {
            board.unplug();
        }
        if k == 400 {
            board.plug();
        }
        b.command(*t, &w.names, angles);
        let (r, ev) = b.tick(*t);
        if (300..400).contains(&k) {
            assert!(r.is_err(), "tick {k}: read while unplugged must fail");
        }
        if ev.contains(&Event::Reconnected) {
            reconnected_at = Some(k);
        }
        events.extend(ev);
    }
    // Failed once, retried with backoff while unplugged, came back after the replug.
    let failed = events
        .iter()
        .filter(|e| matches!(e, Event::BackendFailed(_)))
        .count();
    assert_eq!(failed, 1, "{events:?}");
    let retries: Vec<f64> = events
        .iter()
        .filter_map(|e| match e {
            Event::RetryFailed { next_in_s, .. } => Some(*next_in_s),
            _ => None,
        })
        .collect();
    assert!(retries.len() >= 4, "{retries:?}");
    assert_eq!(
        &retries[..3],
        &[0.1, 0.2, 0.2],
        "doubling backoff capped at 0.2 s"
    );
    let k = reconnected_at.expect("reconnected");
    assert!((400..=421).contains(&k), "reconnected at tick {k}");
    assert_eq!(b.state(), Lifecycle::Active);
    let c = b.backend().counters();
    assert_eq!((c.port_failures, c.reconnects), (1, 1), "{c:?}");
    // After the reconnection's ramp, the targets are the commands again, to the end.
    let goals = board.with(|s| s.goals.clone());
    let after = w.ticks.len() - (w.ticks.len() - k - (RAMP_S * 100.0) as usize - 2);
    let tail = w.ticks.len() - after;
    for (j, ((_, angles), g)) in w.ticks[after..]
        .iter()
        .zip(&goals[goals.len() - tail..])
        .enumerate()
    {
        let want = expected_units(&cal, &names, &in_bridge_order(&w, &joints, angles));
        assert_within_one_unit(p, &sorted(g.clone()), &want, &format!("tick {}", after + j));
    }
}

#[test]
fn garbage_and_crc_failing_replies_are_dropped_counted_and_the_walk_goes_on() {
    for p in [Protocol::Dynamixel2, Protocol::Dynamixel1] {
        let dir = support::temp_dir(&format!("garbage-{p}"));
        let dev = dir.join("ttyBOARD");
        let cal = calibration(p);
        let board = Board::new(p, &dev, &servos_at_zero(&cal));
        let w = walk(1);
        let mut b = bridge(p, &dev);
        b.start().unwrap();
        for (k, (t, angles)) in w.ticks.iter().enumerate() {
            if k == 100 {
                board.with(|s| {
                    s.garbage_replies = 5;
                    s.corrupt_replies = 5;
                });
            }
            b.command(*t, &w.names, angles);
            let (r, ev) = b.tick(*t);
            assert!(ev.is_empty(), "{p} tick {k}: {ev:?}");
            assert!(r.unwrap().measured);
        }
        let c = b.backend().counters();
        assert_eq!(b.state(), Lifecycle::Active);
        assert!(c.checksum_errors >= 5, "{p}: {c:?}");
        assert!(c.corrupted + c.checksum_errors >= 10, "{p}: {c:?}");
        assert!(c.timeouts >= 1, "{p}: {c:?}");
        assert_eq!(c.port_failures, 0);
        assert_eq!(
            wait_goals(&board, w.ticks.len()).len(),
            w.ticks.len(),
            "{p}: every tick written"
        );
        let d = b.backend().diagnostics().unwrap();
        let get = |k: &str| d.values.iter().find(|(n, _)| n == k).unwrap().1.clone();
        assert_eq!(get("checksum_errors"), c.checksum_errors.to_string());
        assert_eq!(get("timeouts"), c.timeouts.to_string());
    }
}

#[test]
fn a_missing_servo_is_an_error_naming_its_joint_and_the_bridge_retries_until_it_answers() {
    for p in [Protocol::Dynamixel2, Protocol::Dynamixel1] {
        let dir = support::temp_dir(&format!("missing-{p}"));
        let dev = dir.join("ttyBOARD");
        let cal = calibration(p);
        let knee = cal.joints["l_knee"];
        let servos: Vec<(u8, f64)> = servos_at_zero(&cal)
            .into_iter()
            .filter(|s| s.0 != knee.id)
            .collect();
        let board = Board::new(p, &dev, &servos);
        let mut b = bridge(p, &dev);
        let e = b.start().unwrap_err();
        let BackendError::Joint { joint, why, .. } = &e else {
            panic!("{e:?}")
        };
        assert_eq!(joint, "l_knee");
        assert!(
            why.contains(&format!("id {}", knee.id)) && why.contains("no reply to ping"),
            "{why}"
        );
        assert_eq!(b.state(), Lifecycle::Error);
        // Still missing: retries fail with the same message.
        let mut t = 0.0;
        let mut failed = 0;
        for _ in 0..20 {
            t += 0.01;
            for ev in b.tick(t).1 {
                if let Event::RetryFailed { error, .. } = ev {
                    assert_eq!(error, e);
                    failed += 1;
                }
            }
        }
        assert!(failed >= 1);
        board.with(|s| {
            s.servos.insert(
                knee.id,
                support::Servo {
                    position: knee.zero,
                    ..Default::default()
                },
            )
        });
        let mut back = false;
        for _ in 0..50 {
            t += 0.01;
            back |= b.tick(t).1.contains(&Event::Reconnected);
        }
        assert!(back, "{p}");
        assert_eq!(b.state(), Lifecycle::Active);
    }
}

#[test]
fn a_port_absent_at_start_is_a_clear_error_and_is_retried_until_it_appears() {
    let p = Protocol::Maestro;
    let dir = support::temp_dir("absent");
    let dev = dir.join("ttyACM7");
    let mut b = bridge(p, &dev);
    let e = b.start().unwrap_err();
    assert!(matches!(e, BackendError::Open { .. }), "{e:?}");
    assert!(e.to_string().contains("ttyACM7"), "{e}");
    let mut t = 0.0;
    for _ in 0..10 {
        t += 0.01;
        assert!(b.tick(t).0.is_err());
    }
    assert_eq!(b.state(), Lifecycle::Error);
    let cal = calibration(p);
    let _board = Board::new(p, &dev, &servos_at_zero(&cal));
    let mut back = false;
    for _ in 0..50 {
        t += 0.01;
        back |= b.tick(t).1.contains(&Event::Reconnected);
    }
    assert!(back);
    assert_eq!(b.state(), Lifecycle::Active);
}

#[test]
fn servo_error_bits_are_reported_by_name_once() {
    let p = Protocol::Dynamixel2;
    let dir = support::temp_dir("errbits");
    let dev = dir.join("ttyBOARD");
    let cal = calibration(p);
    let board = Board::new(p, &dev, &servos_at_zero(&cal));
    let mut b = bridge(p, &dev);
    b.start().unwrap();
    let hip = cal.joints["r_hip_pitch"].id;
    let mut notices = Vec::new();
    for k in 0..30 {
        if k == 10 {
            board.with(|s| {
                let servo = s.servos.get_mut(&hip).unwrap();
                servo.error = 0x80;
                servo.hardware_error = 0x24;
            });
        }
        if k == 20 {
            board.with(|s| s.servos.get_mut(&hip).unwrap().error = 0);
        }
        for e in b.tick(f64::from(k) / 100.0).1 {
            if let Event::BackendNotice(n) = e {
                notices.push(n);
            }
        }
    }
    assert_eq!(
        notices,
        vec![
            format!(
                "joint `r_hip_pitch` (servo id {hip}) reports: hardware alert, overheating error, overload error"
            ),
            format!("joint `r_hip_pitch` (servo id {hip}): errors cleared"),
        ]
    );
    assert!(b.backend().counters().servo_errors >= 10);
}

#[test]
fn nan_is_never_sent_the_backend_refuses_it_naming_the_joint() {
    let p = Protocol::Ssc32;
    let dir = support::temp_dir("nan");
    let dev = dir.join("ttyBOARD");
    let cal = calibration(p);
    let board = Board::new(p, &dev, &servos_at_zero(&cal));
    let mut backend = SerialBackend::new(SerialConfig {
        port: dev.display().to_string(),
        baud: 115_200,
        calibration: cal.clone(),
        reply_timeout_s: 0.5,
    });
    let joints = leg_specs(&cal);
    backend.configure(&joints).unwrap();
    backend.activate().unwrap();
    let mut q = vec![0.0; joints.len()];
    q[2] = f64::NAN;
    let e = backend.write(0.0, &q).unwrap_err();
    assert!(
        e.to_string().contains(&format!("`{}`", joints[2].name)) && e.to_string().contains("NaN"),
        "{e}"
    );
    std::thread::sleep(std::time::Duration::from_millis(50));
    assert!(board.with(|s| s.goals.is_empty()), "nothing sent");
}

/// A PWM board that outputs no pulse yet cannot tell where the servos are (#27): the bridge
/// starts from the calibration's rest pose, the SSC-32U moves there at the calibration's
/// start speed (every move carries `S` until the board's output pulses are the commanded
/// ones, then full speed), and the move from the rest pose to the first command is the
/// bridge's start ramp.
#[test]
fn an_ssc32_that_outputs_no_pulse_starts_from_the_rest_pose_at_the_start_speed() {
    let p = Protocol::Ssc32;
    let dir = support::temp_dir("rest");
    let dev = dir.join("ttyBOARD");
    // The rest pose: knees bent 0.3 rad (hand values: zero ± 0.3 × 636.6198 µs).
    let text = std::fs::read_to_string(format!(
        "{}/../config/calibration_ssc32.yaml",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap()
    .replace(
        "l_knee: { id: 2, zero: 1000,",
        "l_knee: { id: 2, rest: 1190.986, zero: 1000,",
    )
    .replace(
        "r_knee: { id: 18, zero: 2000,",
        "r_knee: { id: 18, rest: 1809.014, zero: 2000,",
    );
    let cal = Calibration::from_yaml_str(&format!("{text}\nstart_speed: 250\n"), "test").unwrap();
    assert_eq!(
        cal.joints["l_knee"].rest,
        Some(1190.986),
        "the test edits the file"
    );
    assert_eq!(
        cal.joints["r_knee"].rest,
        Some(1809.014),
        "the test edits the file"
    );
    // Power-up: no pulse on any channel (a query answers 0).
    let off: Vec<(u8, f64)> = cal.joints.values().map(|j| (j.id, 0.0)).collect();
    let board = Board::new(p, &dev, &off);
    let joints = leg_specs(&cal);
    let backend = SerialBackend::new(SerialConfig {
        port: dev.display().to_string(),
        baud: 115_200,
        calibration: cal.clone(),
        reply_timeout_s: 0.5,
    });
    let mut b = JointBridge::new(
        backend,
        joints.clone(),
        BridgeConfig {
            watchdog_timeout_s: 1e6,
            start_ramp_s: RAMP_S,
            ..BridgeConfig::default()
        },
    );
    b.start().unwrap();
    // No command yet: the bridge holds the rest pose. The emulated board's output pulses
    // follow at once, so the read after this first move already ends the slow start.
    let (_, ev) = b.tick(0.0);
    assert_eq!(
        ev.iter().map(ToString::to_string).collect::<Vec<_>>(),
        ["servos at the rest pose (moved there at 250 µs/s); full speed from now"]
    );
    let first = wait_goals(&board, 1);
    for (id, u) in sorted(first[0].clone()) {
        let j = cal.joints.values().find(|j| j.id == id).unwrap();
        assert_eq!(u, j.rest.unwrap_or(j.zero).round(), "channel {id}");
    }
    let cmds = board.with(|s| s.commands.clone());
    assert_eq!(
        cmds.iter()
            .filter(|c| c.starts_with("speed ") && c.ends_with(" 250"))
            .count(),
        10,
        "every channel's first move at 250 µs/s: {cmds:?}"
    );
    // Then the walk's first pose, reached through the start ramp; no move carries a speed.
    let w = walk(1);
    let n = (RAMP_S * 100.0) as usize + 5;
    for (k, (_, angles)) in w.ticks.iter().take(n).enumerate() {
        let t = 0.01 + k as f64 * 0.01;
        b.command(t, &w.names, angles);
        b.tick(t).0.unwrap();
    }
    let goals = wait_goals(&board, n + 1);
    let speeds = board.with(|s| {
        s.commands
            .iter()
            .filter(|c| c.starts_with("speed "))
            .count()
    });
    assert_eq!(speeds, 10, "only the first move is slowed");
    // Knee: from the rest pose (1191 µs) towards the walk's pose, never a jump: the ramp's
    // steepest step (1.5 × distance × 0.01 s / 0.5 s) plus the walk's own motion.
    let knee = cal.joints["l_knee"].id;
    let track: Vec<f64> = goals
        .iter()
        .map(|g| g.iter().find(|(c, _)| *c == knee).unwrap().1)
        .collect();
    assert_eq!(track[0], 1191.0);
    for w2 in track.windows(2) {
        assert!((w2[1] - w2[0]).abs() <= 40.0, "knee {} → {}", w2[0], w2[1]);
    }
}

#[test]
fn a_rest_pose_outside_the_limits_or_for_a_measuring_board_is_refused_by_name() {
    let dxl = "protocol: dynamixel2\njoints:\n  l_knee: { id: 2, rest: 2000, zero: 2048, direction: 1, units_per_rad: 651.9, min: 1000, max: 3000 }\n";
    let e = Calibration::from_yaml_str(dxl, "t")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("joint `l_knee`, key `rest`") && e.contains("starts from the measured pose"),
        "{e}"
    );
    let out = "protocol: ssc32\njoints:\n  l_knee: { id: 2, rest: 2200, zero: 1500, direction: 1, units_per_rad: 636.6, min: 900, max: 2100 }\n";
    let e = Calibration::from_yaml_str(out, "t")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("key `rest`: 2200 is outside [min, max] = [900, 2100]"),
        "{e}"
    );
    let maestro = "protocol: maestro\nstart_speed: 100\njoints:\n  l_knee: { id: 2, zero: 1500, direction: 1, units_per_rad: 636.6, min: 900, max: 2100 }\n";
    let e = Calibration::from_yaml_str(maestro, "t")
        .unwrap_err()
        .to_string();
    assert!(e.contains("key `start_speed`: only for ssc32"), "{e}");
}
