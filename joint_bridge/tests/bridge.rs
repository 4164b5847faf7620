//! The joint bridge end to end: lifecycle, command checks, velocity limiting, the watchdog
//! (hold and limp) and backend failures, against the mock backend and a recording backend
//! written here. Every expected value is worked out by hand in the comments.
//!
//! Times are built as `i as f64 / 100.0` (correctly rounded i/100) so that the watchdog's
//! boundaries fall on exactly representable instants (0.5, 0.75, 1.0).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::{names, spec};

use std::sync::{Arc, Mutex};

use joint_bridge::{
    Backend, BackendError, BridgeConfig, Event, FollowEnd, JointBridge, JointSpec, Lifecycle,
    MockBackend, Operator, Reading, TimeoutAction,
};

// ---------------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------------

/// Tick `i` of a 100 Hz clock (s).
fn t(i: u32) -> f64 {
    f64::from(i) / 100.0
}

/// The default robot's 20 joints with their URDF limits.
fn robot_joints() -> Vec<JointSpec> {
    let model = ik_solver::BipedModel::from_urdf_str(ik_solver::DEFAULT_URDF, None).unwrap();
    JointSpec::from_robot(model.robot())
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-12
}

fn positions(r: Result<Reading, BackendError>) -> Vec<f64> {
    r.expect("tick reads the backend").positions_rad
}

/// Velocity limits only (no acceleration limit, ticks of any length): the tests of
/// clamping, refusing and the watchdog count steps of velocity × dt. The acceleration limit
/// and the bounded tick have their own tests below.
fn velocity_only() -> BridgeConfig {
    BridgeConfig {
        acceleration_rad_s2: f64::INFINITY,
        max_tick_s: 1e6,
        ..BridgeConfig::default()
    }
}

/// A watchdog timeout that never trips within these tests.
fn patient() -> BridgeConfig {
    BridgeConfig {
        watchdog_timeout_s: 1e6,
        on_timeout: TimeoutAction::Hold,
        ..velocity_only()
    }
}

/// One backend call, as seen by [`Recorder`].
#[derive(Debug, Clone, PartialEq)]
enum Call {
    Configure(Vec<String>),
    Activate,
    Write(f64, Vec<f64>),
    Deactivate,
}

/// A backend that records every call (except reads) into a log shared with the test, so
/// the log can still be read after the bridge, and the backend inside it, has been dropped.
#[derive(Debug, Default)]
struct Recorder {
    log: Arc<Mutex<Vec<Call>>>,
    /// What `configure` reports as measured.
    measured: Option<Vec<f64>>,
    /// The 1-based number of the write that fails (with an I/O error).
    fail_write: Option<usize>,
    writes: usize,
    last: Vec<f64>,
}

impl Recorder {
    fn new() -> (Self, Arc<Mutex<Vec<Call>>>) {
        let r = Recorder::default();
        let log = Arc::clone(&r.log);
        (r, log)
    }
}

impl Backend for Recorder {
    fn name(&self) -> &str {
        "recorder"
    }
    fn configure(&mut self, joints: &[JointSpec]) -> Result<Option<Vec<f64>>, BackendError> {
        self.log.lock().unwrap().push(Call::Configure(
            joints.iter().map(|j| j.name.clone()).collect(),
        ));
        self.last = vec![0.0; joints.len()];
        Ok(self.measured.clone())
    }
    fn activate(&mut self) -> Result<(), BackendError> {
        self.log.lock().unwrap().push(Call::Activate);
        Ok(())
    }
    fn write(&mut self, t_s: f64, positions_rad: &[f64]) -> Result<(), BackendError> {
        self.log
            .lock()
            .unwrap()
            .push(Call::Write(t_s, positions_rad.to_vec()));
        self.writes += 1;
        if self.fail_write == Some(self.writes) {
            return Err(BackendError::Io {
                backend: "recorder".into(),
                why: "bus timeout".into(),
            });
        }
        self.last = positions_rad.to_vec();
        Ok(())
    }
    fn read(&mut self, _t_s: f64) -> Result<Reading, BackendError> {
        Ok(Reading {
            positions_rad: self.last.clone(),
            velocities_rad_s: None,
            measured: false,
        })
    }
    fn deactivate(&mut self) -> Result<(), BackendError> {
        self.log.lock().unwrap().push(Call::Deactivate);
        Ok(())
    }
}

fn calls(log: &Arc<Mutex<Vec<Call>>>) -> Vec<Call> {
    log.lock().unwrap().clone()
}

fn writes(log: &Arc<Mutex<Vec<Call>>>) -> Vec<(f64, Vec<f64>)> {
    calls(log)
        .into_iter()
        .filter_map(|c| match c {
            Call::Write(t, p) => Some((t, p)),
            _ => None,
        })
        .collect()
}

fn count(log: &Arc<Mutex<Vec<Call>>>, call: &Call) -> usize {
    calls(log).iter().filter(|c| *c == call).count()
}

// ---------------------------------------------------------------------------------------------
// Joint specs from the URDF
// ---------------------------------------------------------------------------------------------

#[test]
fn joint_specs_come_from_the_urdf_limits() {
    let joints = robot_joints();
    // config/biped.urdf: 5 joints per leg, 4 per arm, neck_yaw and head_pitch = 20.
    assert_eq!(joints.len(), 20);
    let by = |n: &str| {
        joints
            .iter()
            .find(|j| j.name == n)
            .unwrap_or_else(|| panic!("no joint {n}"))
    };
    // <limit lower="-0.05" upper="2.3" velocity="6.0"/>
    assert_eq!(*by("l_knee"), spec("l_knee", -0.05, 2.3, 6.0));
    // <limit lower="-2.3" upper="0.1" velocity="6.0"/>
    assert_eq!(*by("r_elbow"), spec("r_elbow", -2.3, 0.1, 6.0));
    // <limit lower="-0.8" upper="0.8" velocity="6.0"/>
    assert_eq!(*by("head_pitch"), spec("head_pitch", -0.8, 0.8, 6.0));
    // The fixed joint is not driven.
    assert!(joints.iter().all(|j| j.name != "torso_fixed"));
}

// ---------------------------------------------------------------------------------------------
// Lifecycle
// ---------------------------------------------------------------------------------------------

#[test]
fn mock_refuses_write_before_activate_naming_the_call() {
    let joints = vec![spec("a", -1.0, 1.0, 1.0)];
    let mut mock = MockBackend::default();
    assert_eq!(mock.state(), Lifecycle::Unconfigured);

    let e = mock.write(0.0, &[0.1]).unwrap_err();
    assert_eq!(
        e,
        BackendError::State {
            backend: "mock".into(),
            call: "write",
            state: Lifecycle::Unconfigured
        }
    );
    assert_eq!(
        e.to_string(),
        "mock: write is not allowed while Unconfigured"
    );
    let e = mock.read(0.0).unwrap_err();
    assert_eq!(
        e,
        BackendError::State {
            backend: "mock".into(),
            call: "read",
            state: Lifecycle::Unconfigured
        }
    );

    // Configured: may be read (at zero), must not move.
    assert_eq!(mock.configure(&joints).unwrap(), None);
    assert_eq!(mock.state(), Lifecycle::Inactive);
    let e = mock.write(0.0, &[0.1]).unwrap_err();
    assert_eq!(
        e,
        BackendError::State {
            backend: "mock".into(),
            call: "write",
            state: Lifecycle::Inactive
        }
    );
    assert_eq!(e.to_string(), "mock: write is not allowed while Inactive");
    assert_eq!(mock.read(0.0).unwrap().positions_rad, vec![0.0]);

    mock.activate().unwrap();
    assert_eq!(mock.state(), Lifecycle::Active);
    mock.write(0.0, &[0.1]).unwrap();
    assert_eq!(mock.read(0.0).unwrap().positions_rad, vec![0.1]);

    // Torque off: writes refused again.
    mock.deactivate().unwrap();
    assert_eq!(mock.state(), Lifecycle::Inactive);
    let e = mock.write(0.0, &[0.2]).unwrap_err();
    assert!(
        matches!(
            e,
            BackendError::State {
                call: "write",
                state: Lifecycle::Inactive,
                ..
            }
        ),
        "{e:?}"
    );
}

#[test]
fn mock_activate_before_configure_is_refused() {
    let mut mock = MockBackend::default();
    let e = mock.activate().unwrap_err();
    assert_eq!(
        e,
        BackendError::State {
            backend: "mock".into(),
            call: "activate",
            state: Lifecycle::Unconfigured
        }
    );
}

#[test]
fn start_activates_and_stop_turns_the_torque_off() {
    let mut mock = MockBackend::default();
    mock.keep_writes = 100;
    let mut bridge = JointBridge::new(mock, vec![spec("a", -1.0, 1.0, 1.0)], velocity_only());
    assert_eq!(bridge.state(), Lifecycle::Unconfigured);
    assert_eq!(bridge.backend().state(), Lifecycle::Unconfigured);

    bridge.start().unwrap();
    assert_eq!(bridge.state(), Lifecycle::Active);
    assert_eq!(bridge.backend().state(), Lifecycle::Active);
    let (r, ev) = bridge.tick(0.0);
    assert!(ev.is_empty(), "{ev:?}");
    assert_eq!(positions(r), vec![0.0]);
    assert_eq!(bridge.backend().writes.len(), 1);

    bridge.stop().unwrap();
    assert_eq!(bridge.state(), Lifecycle::Inactive);
    assert_eq!(bridge.backend().state(), Lifecycle::Inactive);
    // Stopped: commands and ticks write nothing.
    bridge.command(0.01, &names(&["a"]), &[0.5]);
    let (r, _) = bridge.tick(0.01);
    assert_eq!(positions(r), vec![0.0]);
    let _ = bridge.tick(0.02);
    assert_eq!(bridge.backend().writes.len(), 1);
    assert_eq!(bridge.backend().state(), Lifecycle::Inactive);
}

#[test]
fn start_configures_then_activates_and_stop_deactivates() {
    let (rec, log) = Recorder::new();
    let mut bridge = JointBridge::new(
        rec,
        vec![spec("a", -1.0, 1.0, 1.0), spec("b", -1.0, 1.0, 1.0)],
        patient(),
    );
    assert!(calls(&log).is_empty());
    bridge.start().unwrap();
    assert_eq!(
        calls(&log),
        vec![Call::Configure(names(&["a", "b"])), Call::Activate]
    );
    bridge.stop().unwrap();
    assert_eq!(calls(&log).last(), Some(&Call::Deactivate));
}

#[test]
fn dropping_the_bridge_deactivates_the_backend() {
    let (rec, log) = Recorder::new();
    let mut bridge = JointBridge::new(rec, vec![spec("a", -1.0, 1.0, 1.0)], patient());
    bridge.start().unwrap();
    bridge.command(0.0, &names(&["a"]), &[0.5]);
    let _ = bridge.tick(0.0);
    let _ = bridge.tick(0.1);
    assert_eq!(count(&log, &Call::Deactivate), 0);
    drop(bridge);
    // Configure, Activate, 2 writes, then torque off from Drop.
    let c = calls(&log);
    assert_eq!(c.len(), 5, "{c:?}");
    assert_eq!(c.last(), Some(&Call::Deactivate));
    assert_eq!(count(&log, &Call::Deactivate), 1);
}

#[test]
fn dropping_an_unstarted_or_stopped_bridge_is_safe_and_still_deactivates() {
    let (rec, log) = Recorder::new();
    drop(JointBridge::new(
        rec,
        vec![spec("a", -1.0, 1.0, 1.0)],
        patient(),
    ));
    assert_eq!(calls(&log), vec![Call::Deactivate]);

    let mut bridge = JointBridge::new(
        MockBackend::default(),
        vec![spec("a", -1.0, 1.0, 1.0)],
        patient(),
    );
    bridge.start().unwrap();
    bridge.stop().unwrap();
    drop(bridge); // second deactivate: must not panic
}

#[test]
fn start_begins_at_the_measured_pose() {
    let (mut rec, log) = Recorder::new();
    rec.measured = Some(vec![0.5]);
    let mut bridge = JointBridge::new(rec, vec![spec("a", -1.0, 1.0, 1.0)], patient());
    bridge.start().unwrap();
    // No command yet: the bridge holds the measured 0.5, it does not snap to 0.
    let (r, _) = bridge.tick(0.0);
    assert_eq!(positions(r), vec![0.5]);
    bridge.command(0.0, &names(&["a"]), &[1.0]);
    // 1 rad/s for 0.1 s from 0.5: 0.6.
    let (r, _) = bridge.tick(0.1);
    assert!(close(positions(r)[0], 0.6));
    assert_eq!(writes(&log)[0], (0.0, vec![0.5]));
}

// ---------------------------------------------------------------------------------------------
// Command handling
// ---------------------------------------------------------------------------------------------

#[test]
fn unknown_joints_are_reported_once_per_name_and_known_ones_still_applied() {
    let mut bridge = JointBridge::new(MockBackend::default(), robot_joints(), patient());
    bridge.start().unwrap();
    let knee = bridge
        .joints()
        .iter()
        .position(|j| j.name == "l_knee")
        .unwrap();
    let hip = bridge
        .joints()
        .iter()
        .position(|j| j.name == "r_hip_pitch")
        .unwrap();

    let ev = bridge.command(0.0, &names(&["ghost", "l_knee"]), &[0.3, 0.4]);
    assert_eq!(
        ev,
        vec![Event::UnknownJoint {
            joint: "ghost".into()
        }]
    );
    for k in 1..10 {
        let ev = bridge.command(
            f64::from(k) * 0.01,
            &names(&["l_knee", "ghost"]),
            &[0.4, 9.0],
        );
        assert!(ev.is_empty(), "command {k}: {ev:?}");
    }
    // A second unknown name is reported (once), the first still not again.
    let ev = bridge.command(
        0.1,
        &names(&["ghost", "phantom", "r_hip_pitch", "phantom"]),
        &[0.0, 0.0, -0.2, 0.0],
    );
    assert_eq!(
        ev,
        vec![Event::UnknownJoint {
            joint: "phantom".into()
        }]
    );

    let _ = bridge.tick(0.1);
    // 6 rad/s over 0.1 s = 0.6 rad of travel: both reach their targets.
    let (r, ev) = bridge.tick(0.2);
    assert!(ev.is_empty(), "{ev:?}");
    let p = positions(r);
    assert!(close(p[knee], 0.4), "l_knee at {}", p[knee]);
    assert!(close(p[hip], -0.2), "r_hip_pitch at {}", p[hip]);
    // Everything else stays at 0.
    let others: Vec<_> = p
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != knee && *i != hip)
        .map(|(_, v)| *v)
        .collect();
    assert!(others.iter().all(|v| *v == 0.0), "{p:?}");
}

#[test]
fn unknown_names_are_remembered_up_to_a_bound() {
    // A sender making up a new name every message: reported up to the bound, then no more
    // (and nothing more is kept); known joints are still applied.
    let mut bridge = JointBridge::new(MockBackend::default(), robot_joints(), patient());
    bridge.start().unwrap();
    let mut reported = 0;
    for k in 0..joint_bridge::MAX_UNKNOWN_REPORTED + 50 {
        let ev = bridge.command(0.0, &[format!("ghost_{k}"), "l_knee".into()], &[0.0, 0.5]);
        reported += ev
            .iter()
            .filter(|e| matches!(e, Event::UnknownJoint { .. }))
            .count();
    }
    assert_eq!(reported, joint_bridge::MAX_UNKNOWN_REPORTED);
    let _ = bridge.tick(0.0);
    let _ = bridge.tick(10.0);
    let knee = robot_joints()
        .iter()
        .position(|j| j.name == "l_knee")
        .unwrap();
    assert!(close(bridge.written_rad()[knee], 0.5));
}

#[test]
fn non_finite_values_are_refused_by_name_and_the_joint_keeps_its_target() {
    let joints = vec![
        spec("a", -1.0, 1.0, 10.0),
        spec("b", -1.0, 1.0, 10.0),
        spec("c", -1.0, 1.0, 10.0),
        spec("d", -1.0, 1.0, 10.0),
    ];
    let mut bridge = JointBridge::new(MockBackend::default(), joints, patient());
    bridge.start().unwrap();
    let all = names(&["a", "b", "c", "d"]);
    assert!(bridge.command(0.0, &all, &[0.5, 0.5, 0.5, 0.5]).is_empty());
    let _ = bridge.tick(0.0);
    // 10 rad/s × 0.1 s = 1 rad ≥ 0.5: all at 0.5.
    let (r, _) = bridge.tick(0.1);
    assert_eq!(positions(r), vec![0.5, 0.5, 0.5, 0.5]);

    let ev = bridge.command(
        0.1,
        &all,
        &[f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 0.7],
    );
    assert_eq!(
        ev.len(),
        3,
        "one NonFinite each for a, b, c, nothing else (no Clamped for ±inf): {ev:?}"
    );
    assert!(
        matches!(&ev[0], Event::NonFinite { joint, value } if joint == "a" && value.is_nan()),
        "{ev:?}"
    );
    assert_eq!(
        ev[1],
        Event::NonFinite {
            joint: "b".into(),
            value: f64::INFINITY
        }
    );
    assert_eq!(
        ev[2],
        Event::NonFinite {
            joint: "c".into(),
            value: f64::NEG_INFINITY
        }
    );
    assert!(ev[0].to_string().contains("`a`"), "{}", ev[0]);

    // d moves 0.5 → 0.7 (0.2 rad < 1 rad of travel); a, b, c hold 0.5.
    let (r, _) = bridge.tick(0.2);
    let p = positions(r);
    assert_eq!(&p[..3], &[0.5, 0.5, 0.5]);
    assert!(close(p[3], 0.7), "{p:?}");
    let (r, _) = bridge.tick(0.3);
    let p = positions(r);
    assert_eq!(&p[..3], &[0.5, 0.5, 0.5]);
    assert!(p.iter().all(|v| v.is_finite()));
}

#[test]
fn values_beyond_the_urdf_limits_are_clamped_with_an_event() {
    let mut bridge = JointBridge::new(MockBackend::default(), robot_joints(), patient());
    bridge.start().unwrap();
    let idx = |b: &JointBridge<MockBackend>, n: &str| {
        b.joints().iter().position(|j| j.name == n).unwrap()
    };
    let (knee, rknee, elbow, hip, head) = (
        idx(&bridge, "l_knee"),
        idx(&bridge, "r_knee"),
        idx(&bridge, "l_elbow"),
        idx(&bridge, "l_hip_roll"),
        idx(&bridge, "head_pitch"),
    );

    let ev = bridge.command(
        0.0,
        &names(&["l_knee", "r_knee", "l_elbow", "l_hip_roll", "head_pitch"]),
        &[3.0, -0.5, 1.0, -0.6, 0.3],
    );
    // l_knee [-0.05, 2.3]: 3.0 → 2.3; r_knee [-0.05, 2.3]: -0.5 → -0.05;
    // l_elbow [-2.3, 0.1]: 1.0 → 0.1; l_hip_roll -0.6 is exactly its lower limit and
    // head_pitch 0.3 is inside [-0.8, 0.8]: neither is reported.
    assert_eq!(
        ev,
        vec![
            Event::Clamped {
                joint: "l_knee".into(),
                requested_rad: 3.0,
                clamped_rad: 2.3
            },
            Event::Clamped {
                joint: "r_knee".into(),
                requested_rad: -0.5,
                clamped_rad: -0.05
            },
            Event::Clamped {
                joint: "l_elbow".into(),
                requested_rad: 1.0,
                clamped_rad: 0.1
            },
        ]
    );
    let _ = bridge.tick(0.0);
    // 6 rad/s × 1 s = 6 rad of travel: every joint reaches its (clamped) target.
    let (r, _) = bridge.tick(1.0);
    let p = positions(r);
    assert_eq!(
        (p[knee], p[rknee], p[elbow], p[hip], p[head]),
        (2.3, -0.05, 0.1, -0.6, 0.3)
    );
}

#[test]
fn a_length_mismatch_is_malformed_and_nothing_is_applied() {
    let joints = vec![spec("a", -1.0, 1.0, 10.0), spec("b", -1.0, 1.0, 10.0)];
    let mut bridge = JointBridge::new(MockBackend::default(), joints, patient());
    bridge.start().unwrap();
    let _ = bridge.tick(0.0);

    let ev = bridge.command(0.0, &names(&["a", "b"]), &[0.5]);
    assert_eq!(
        ev,
        vec![Event::Malformed {
            names: 2,
            positions: 1
        }]
    );
    let ev = bridge.command(0.0, &names(&["a"]), &[0.5, 0.6]);
    assert_eq!(
        ev,
        vec![Event::Malformed {
            names: 1,
            positions: 2
        }]
    );
    // An unknown name in a malformed message is not looked at either.
    let ev = bridge.command(0.0, &names(&["ghost", "a"]), &[0.5, 0.5, 0.5]);
    assert_eq!(
        ev,
        vec![Event::Malformed {
            names: 2,
            positions: 3
        }]
    );

    // 10 rad/s × 1 s would reach anything: still at 0, 0.
    let (r, _) = bridge.tick(1.0);
    assert_eq!(positions(r), vec![0.0, 0.0]);
}

#[test]
fn commands_with_nothing_usable_do_not_feed_the_watchdog() {
    // Timeout 0.25 s, hold. The one good command is at t = 0.5.
    let joints = vec![spec("a", -1.0, 1.0, 1.0)];
    let mut bridge = JointBridge::new(MockBackend::default(), joints, velocity_only());
    bridge.start().unwrap();
    bridge.command(0.5, &names(&["a"]), &[0.1]);
    let _ = bridge.tick(0.5);
    // Every 10 ms from 0.51 on: NaN, an unknown joint, a malformed message in turn.
    let mut tripped_at = None;
    for i in 51..=80 {
        match i % 3 {
            0 => bridge.command(t(i), &names(&["a"]), &[f64::NAN]),
            1 => bridge.command(t(i), &names(&["ghost"]), &[0.2]),
            _ => bridge.command(t(i), &names(&["a"]), &[]),
        };
        let (_, ev) = bridge.tick(t(i));
        if ev
            .iter()
            .any(|e| matches!(e, Event::WatchdogTripped { .. }))
        {
            tripped_at = Some(i);
            break;
        }
    }
    // 0.75 - 0.5 = 0.25 is not more than 0.25; 0.76 is the first tick beyond.
    assert_eq!(tripped_at, Some(76));
}

// ---------------------------------------------------------------------------------------------
// Velocity limiting
// ---------------------------------------------------------------------------------------------

#[test]
fn a_step_is_approached_at_the_velocity_limit_without_overshoot() {
    // a: 2 rad/s, step 0 → 1 rad: 0.02 rad per 10 ms tick, 1 / 0.02 = 50 ticks.
    // b: 1 rad/s, step 0 → -0.5 rad: -0.01 rad per tick, 0.5 / 0.01 = 50 ticks.
    let joints = vec![spec("a", -1.5, 1.5, 2.0), spec("b", -1.5, 1.5, 1.0)];
    let mut mock = MockBackend::default();
    mock.keep_writes = 1000;
    let mut bridge = JointBridge::new(mock, joints, velocity_only());
    bridge.start().unwrap();
    let ab = names(&["a", "b"]);
    bridge.command(0.0, &ab, &[1.0, -0.5]);
    // First tick: no elapsed time, no motion.
    let (r, _) = bridge.tick(0.0);
    assert_eq!(positions(r), vec![0.0, 0.0]);
    for i in 1..=70 {
        // The command keeps coming at 100 Hz (the watchdog stays fed).
        assert!(bridge.command(t(i), &ab, &[1.0, -0.5]).is_empty());
        let (r, ev) = bridge.tick(t(i));
        assert!(ev.is_empty(), "tick {i}: {ev:?}");
        let p = positions(r);
        let k = f64::from(i.min(50));
        let want = [0.02 * k, -0.01 * k];
        assert!(
            close(p[0], want[0]) && close(p[1], want[1]),
            "tick {i}: {p:?}, want {want:?}"
        );
        assert!(p[0] <= 1.0 && p[1] >= -0.5, "tick {i} overshoots: {p:?}");
        if i < 50 {
            assert!(
                p[0] < 1.0 - 0.01 && p[1] > -0.5 + 0.005,
                "tick {i} arrived early: {p:?}"
            );
        }
        if i >= 51 {
            // At the target: exactly.
            assert_eq!(p, vec![1.0, -0.5], "tick {i}");
        }
    }
    // Written what was read: 71 writes, the 26th (tick 25) at 0.5, -0.25.
    let w = &bridge.backend().writes;
    assert_eq!(w.len(), 71);
    assert!(
        close(w[25].1[0], 0.5) && close(w[25].1[1], -0.25),
        "{:?}",
        w[25]
    );
    // Per-tick increments never exceed the limits (2 × 0.01, 1 × 0.01).
    for pair in w.windows(2) {
        assert!((pair[1].1[0] - pair[0].1[0]).abs() <= 0.02 + 1e-12);
        assert!((pair[1].1[1] - pair[0].1[1]).abs() <= 0.01 + 1e-12);
    }
}

#[test]
fn the_step_size_comes_from_the_tick_times() {
    // 2 rad/s toward 1 rad. Ticks at 0, 0.01, 0.03, 0.035, 0.1:
    // dt = -, 0.01, 0.02, 0.005, 0.065 → steps 0, 0.02, 0.04, 0.01, 0.13
    // → 0, 0.02, 0.06, 0.07, 0.20.
    // A repeated time (dt 0) and a time going backwards (dt clamped to 0) do not move it.
    let mut bridge = JointBridge::new(
        MockBackend::default(),
        vec![spec("a", -1.5, 1.5, 2.0)],
        velocity_only(),
    );
    bridge.start().unwrap();
    bridge.command(0.0, &names(&["a"]), &[1.0]);
    for (tick, want) in [
        (0.0, 0.0),
        (0.01, 0.02),
        (0.03, 0.06),
        (0.035, 0.07),
        (0.1, 0.20),
        (0.1, 0.20),
        (0.09, 0.20),
    ] {
        let (r, ev) = bridge.tick(tick);
        assert!(ev.is_empty(), "{ev:?}");
        let p = positions(r)[0];
        assert!(close(p, want), "at t = {tick}: {p}, want {want}");
    }
}

#[test]
fn a_joint_without_a_speed_limit_moves_at_the_default_speed_not_straight_to_its_target() {
    // A continuous joint with no <limit>: JointSpec::from_robot gives it ±inf position limits
    // and an infinite speed limit (the URDF's velocity 0 means "none"). Once it went straight
    // to its target (a snap); now it moves at `default_velocity_rad_s`.
    const URDF: &str = r#"<?xml version="1.0"?>
<robot name="wheel">
  <link name="body"/>
  <joint name="spin" type="continuous">
    <parent link="body"/><child link="wheel"/>
    <axis xyz="0 0 1"/>
  </joint>
  <link name="wheel"/>
</robot>
"#;
    let robot = ik_solver::RobotModel::from_urdf_str(URDF).unwrap();
    let joints = JointSpec::from_robot(&robot);
    assert_eq!(
        joints,
        vec![spec(
            "spin",
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::INFINITY
        )]
    );

    let mut bridge = JointBridge::new(MockBackend::default(), joints, velocity_only());
    bridge.start().unwrap();
    // No limits: 10 rad is not clamped.
    assert!(bridge.command(0.0, &names(&["spin"]), &[10.0]).is_empty());
    // The first tick has dt = 0: inf × 0 is NaN, and f64::clamp(NaN, NaN) panics.
    let (r, _) = bridge.tick(0.0);
    assert!(positions(r)[0].is_finite());
    // 10 ms at 2 rad/s (the default speed), not at the target.
    let (r, _) = bridge.tick(0.01);
    assert!(close(positions(r)[0], 0.02), "{:?}", bridge.written_rad());
}

// ---------------------------------------------------------------------------------------------
// Watchdog: hold
// ---------------------------------------------------------------------------------------------

#[test]
fn watchdog_hold_trips_on_the_first_tick_past_the_timeout_and_keeps_writing_the_pose() {
    assert_eq!(
        BridgeConfig::default(),
        BridgeConfig {
            watchdog_timeout_s: 0.25,
            on_timeout: TimeoutAction::Hold,
            start_ramp_s: 0.0,
            reconnect: None,
            default_velocity_rad_s: 2.0,
            acceleration_rad_s2: 100.0,
            max_tick_s: 0.05,
            estop_follow_s: 0.0,
        }
    );
    let (rec, log) = Recorder::new();
    let mut bridge = JointBridge::new(rec, vec![spec("a", -1.0, 1.0, 2.0)], velocity_only());
    bridge.start().unwrap();

    // Commands at 100 Hz from 0 to 0.5 s (51 of them), to 0.3 rad: at 2 rad/s reached at
    // tick 15 (0.3 / 0.02).
    for i in 0..=50 {
        assert!(bridge.command(t(i), &names(&["a"]), &[0.3]).is_empty());
        let (_, ev) = bridge.tick(t(i));
        assert!(ev.is_empty(), "tick {i}: {ev:?}");
    }
    // Silence. The last command was at 0.5; 0.75 - 0.5 = 0.25 is not > 0.25, so the first
    // tick that trips is 0.76, after 0.26 s of silence.
    let mut trips = Vec::new();
    for i in 51..=99 {
        let (r, ev) = bridge.tick(t(i));
        assert!(close(positions(r)[0], 0.3), "tick {i}");
        for e in ev {
            match e {
                Event::WatchdogTripped { silence_s, action } => trips.push((i, silence_s, action)),
                other => panic!("tick {i}: unexpected {other:?}"),
            }
        }
        assert_eq!(bridge.watchdog_tripped(), i >= 76, "tick {i}");
    }
    assert_eq!(trips.len(), 1, "reported once: {trips:?}");
    assert_eq!(trips[0].0, 76);
    assert!((trips[0].1 - 0.26).abs() < 1e-9, "{trips:?}");
    assert_eq!(trips[0].2, TimeoutAction::Hold);

    // Torque still on: no deactivate, and every tick wrote the same pose.
    assert_eq!(bridge.state(), Lifecycle::Active);
    assert_eq!(count(&log, &Call::Deactivate), 0);
    let w = writes(&log);
    assert_eq!(w.len(), 100, "ticks 0..=99 all wrote");
    for (tw, p) in &w[76..] {
        assert!(close(p[0], 0.3), "write at {tw}: {p:?}");
    }
    let held = w[76].1[0];
    assert!(
        w[76..].iter().all(|(_, p)| p[0] == held),
        "held pose constant"
    );

    // A new command: resumed, and the joint moves on at 2 rad/s from 0.3.
    let ev = bridge.command(t(100), &names(&["a"]), &[0.5]);
    assert_eq!(ev, vec![Event::Resumed]);
    assert!(!bridge.watchdog_tripped());
    let (r, ev) = bridge.tick(t(100));
    assert!(ev.is_empty(), "{ev:?}");
    assert!(close(positions(r)[0], 0.32));
    bridge.command(t(101), &names(&["a"]), &[0.5]);
    let (r, _) = bridge.tick(t(101));
    assert!(close(positions(r)[0], 0.34));
    // Only the first command after the trip reports Resumed.
    assert!(bridge.command(t(102), &names(&["a"]), &[0.5]).is_empty());
}

#[test]
fn watchdog_hold_freezes_where_the_output_is_not_at_the_far_target() {
    // 1 rad/s toward 1 rad, one command at t = 0, ticks every 10 ms. By tick 0.25 the output
    // is 0.25 (25 × 0.01); the tick at 0.26 trips (0.26 > 0.25) and holds 0.25 from then on.
    let mut bridge = JointBridge::new(
        MockBackend::default(),
        vec![spec("a", -1.5, 1.5, 1.0)],
        velocity_only(),
    );
    bridge.start().unwrap();
    bridge.command(0.0, &names(&["a"]), &[1.0]);
    let mut tripped_at = None;
    for i in 0..=150 {
        let (r, ev) = bridge.tick(t(i));
        if ev.iter().any(|e| {
            matches!(
                e,
                Event::WatchdogTripped {
                    action: TimeoutAction::Hold,
                    ..
                }
            )
        }) {
            assert!(tripped_at.is_none());
            tripped_at = Some(i);
        }
        let p = positions(r)[0];
        let want = 0.01 * f64::from(i.min(25));
        assert!(close(p, want), "tick {i}: {p}, want {want}");
    }
    assert_eq!(tripped_at, Some(26));
    assert_eq!(bridge.state(), Lifecycle::Active);
}

// ---------------------------------------------------------------------------------------------
// Watchdog: limp
// ---------------------------------------------------------------------------------------------

#[test]
fn watchdog_limp_turns_the_torque_off_and_a_command_resumes_from_the_output() {
    let config = BridgeConfig {
        watchdog_timeout_s: 0.25,
        on_timeout: TimeoutAction::Limp,
        ..velocity_only()
    };
    let (rec, log) = Recorder::new();
    let mut bridge = JointBridge::new(rec, vec![spec("a", -1.5, 1.5, 1.0)], config);
    bridge.start().unwrap();

    // 1 rad/s toward 1 rad, commanded at 100 Hz up to 0.5 s: 0.5 at tick 0.5, then it keeps
    // going toward the target while silent: 0.75 at tick 0.75.
    for i in 0..=50 {
        bridge.command(t(i), &names(&["a"]), &[1.0]);
        let _ = bridge.tick(t(i));
    }
    let mut trips = Vec::new();
    for i in 51..=99 {
        let (_, ev) = bridge.tick(t(i));
        for e in ev {
            match e {
                Event::WatchdogTripped { silence_s, action } => trips.push((i, silence_s, action)),
                other => panic!("tick {i}: unexpected {other:?}"),
            }
        }
    }
    // Trips at 0.76 (first tick more than 0.25 s after 0.5), once.
    assert_eq!(trips.len(), 1, "{trips:?}");
    assert_eq!((trips[0].0, trips[0].2), (76, TimeoutAction::Limp));
    assert!((trips[0].1 - 0.26).abs() < 1e-9, "{trips:?}");
    assert_eq!(bridge.state(), Lifecycle::Inactive);
    assert!(bridge.watchdog_tripped());

    // Writes: ticks 0..=75 (76 of them), the last at 0.75 with 0.75; none after; then the
    // torque off, exactly once.
    let w = writes(&log);
    assert_eq!(w.len(), 76);
    assert_eq!(w[75].0, 0.75);
    assert!(close(w[75].1[0], 0.75), "{:?}", w[75]);
    let c = calls(&log);
    let write_75 = c
        .iter()
        .position(|x| *x == Call::Write(w[75].0, w[75].1.clone()))
        .unwrap();
    assert_eq!(&c[write_75 + 1..], &[Call::Deactivate]);

    // A new command: torque back on and Resumed.
    let ev = bridge.command(t(100), &names(&["a"]), &[1.0]);
    assert_eq!(ev, vec![Event::Resumed]);
    assert_eq!(bridge.state(), Lifecycle::Active);
    assert!(!bridge.watchdog_tripped());
    assert_eq!(calls(&log).last(), Some(&Call::Activate));
    assert_eq!(count(&log, &Call::Activate), 2);
    // Resumes from where the output was (0.75), 0.01 per 10 ms tick: 0.76, 0.77.
    let (r, ev) = bridge.tick(t(100));
    assert!(ev.is_empty(), "{ev:?}");
    assert!(close(positions(r)[0], 0.76));
    bridge.command(t(101), &names(&["a"]), &[1.0]);
    let (r, _) = bridge.tick(t(101));
    assert!(close(positions(r)[0], 0.77));
    let w = writes(&log);
    assert_eq!(w.len(), 78);
    assert_eq!(w[76].0, 1.0);
}

// ---------------------------------------------------------------------------------------------
// Backend failures
// ---------------------------------------------------------------------------------------------

#[test]
fn a_failing_write_reports_backend_failed_goes_to_error_and_turns_the_torque_off() {
    let (mut rec, log) = Recorder::new();
    rec.fail_write = Some(3);
    let mut bridge = JointBridge::new(rec, vec![spec("a", -1.0, 1.0, 1.0)], patient());
    bridge.start().unwrap();
    bridge.command(0.0, &names(&["a"]), &[0.5]);
    assert!(bridge.tick(0.0).0.is_ok());
    assert!(bridge.tick(0.01).0.is_ok());
    let (r, ev) = bridge.tick(0.02);
    let io = BackendError::Io {
        backend: "recorder".into(),
        why: "bus timeout".into(),
    };
    assert_eq!(r, Err(io.clone()));
    assert_eq!(ev, vec![Event::BackendFailed(io)]);
    assert!(ev[0].to_string().contains("bus timeout"), "{}", ev[0]);
    assert_eq!(bridge.state(), Lifecycle::Error);
    // The failing write was followed by torque off.
    let c = calls(&log);
    assert_eq!(c.len(), 6, "{c:?}"); // Configure, Activate, 3 writes, Deactivate
    assert_eq!(c[5], Call::Deactivate);

    // In Error: no more writes, and a command does not bring it back.
    let ev = bridge.command(0.03, &names(&["a"]), &[0.6]);
    assert!(ev.is_empty(), "{ev:?}");
    let _ = bridge.tick(0.03);
    let _ = bridge.tick(0.04);
    assert_eq!(writes(&log).len(), 3);
    assert_eq!(count(&log, &Call::Activate), 1);
    assert_eq!(bridge.state(), Lifecycle::Error);
}

#[test]
fn a_failing_write_while_holding_stays_in_error_on_the_next_command() {
    // Hold trips at 0.76 (as above); the write at 0.80 fails. A command at 0.81 must not
    // report Resumed nor turn the torque back on: the backend failed.
    let (mut rec, log) = Recorder::new();
    rec.fail_write = Some(81); // ticks 0..=80: the 81st write is tick 0.80
    let mut bridge = JointBridge::new(rec, vec![spec("a", -1.0, 1.0, 2.0)], velocity_only());
    bridge.start().unwrap();
    for i in 0..=50 {
        bridge.command(t(i), &names(&["a"]), &[0.3]);
        let _ = bridge.tick(t(i));
    }
    for i in 51..=80 {
        let _ = bridge.tick(t(i));
    }
    assert_eq!(bridge.state(), Lifecycle::Error);
    let ev = bridge.command(t(81), &names(&["a"]), &[0.3]);
    assert!(!ev.contains(&Event::Resumed), "{ev:?}");
    assert_eq!(bridge.state(), Lifecycle::Error);
    assert_eq!(count(&log, &Call::Activate), 1);
}

#[test]
fn a_command_after_stop_does_not_turn_the_torque_back_on_even_after_the_watchdog_tripped() {
    // Hold trips at 0.76; the node then shuts down (stop, torque off). A late command at
    // 0.80 must not re-activate the backend.
    let (rec, log) = Recorder::new();
    let mut bridge = JointBridge::new(rec, vec![spec("a", -1.0, 1.0, 2.0)], velocity_only());
    bridge.start().unwrap();
    for i in 0..=50 {
        bridge.command(t(i), &names(&["a"]), &[0.3]);
        let _ = bridge.tick(t(i));
    }
    for i in 51..=78 {
        let _ = bridge.tick(t(i));
    }
    assert!(bridge.watchdog_tripped());
    bridge.stop().unwrap();
    let before = writes(&log).len();

    bridge.command(t(80), &names(&["a"]), &[0.3]);
    let _ = bridge.tick(t(80));
    assert_eq!(
        bridge.state(),
        Lifecycle::Inactive,
        "stopped bridge came back"
    );
    assert_eq!(
        count(&log, &Call::Activate),
        1,
        "activate called after stop: {:?}",
        &calls(&log)[calls(&log).len() - 4..]
    );
    assert_eq!(writes(&log).len(), before, "wrote after stop");
}

// ---------------------------------------------------------------------------------------------
// TimeoutAction parsing
// ---------------------------------------------------------------------------------------------

#[test]
fn timeout_action_parses_hold_and_limp_and_names_a_bad_value() {
    assert_eq!("hold".parse::<TimeoutAction>(), Ok(TimeoutAction::Hold));
    assert_eq!("limp".parse::<TimeoutAction>(), Ok(TimeoutAction::Limp));
    for bad in ["stop", "", "hold "] {
        let e = bad.parse::<TimeoutAction>().unwrap_err();
        assert!(
            e.contains(&format!("`{bad}`")),
            "error does not name {bad:?}: {e}"
        );
        assert!(
            e.contains("hold") && e.contains("limp"),
            "error does not list the choices: {e}"
        );
    }
}

// ---------------------------------------------------------------------------------------------
// The path-keeping emergency stop (estop_follow_s)
// ---------------------------------------------------------------------------------------------

/// One joint commanded along a ramp of 5 mrad per tick (0.5 rad/s) up to tick 50 (0.25 rad),
/// then an emergency stop with `follow_s`: the bridge and its recording.
fn walking_then_estop(follow_s: f64) -> (JointBridge<Recorder>, Arc<Mutex<Vec<Call>>>) {
    walking_then(follow_s, JointBridge::estop)
}

/// [`walking_then_estop`] with another stop.
fn walking_then(
    follow_s: f64,
    stop: impl FnOnce(&mut JointBridge<Recorder>),
) -> (JointBridge<Recorder>, Arc<Mutex<Vec<Call>>>) {
    let (rec, log) = Recorder::new();
    let config = BridgeConfig {
        estop_follow_s: follow_s,
        ..patient()
    };
    let mut bridge = JointBridge::new(rec, vec![spec("a", -1.0, 1.0, 2.0)], config);
    bridge.start().unwrap();
    for i in 0..=50 {
        bridge.command(t(i), &names(&["a"]), &[0.005 * f64::from(i)]);
        let _ = bridge.tick(t(i));
    }
    stop(&mut bridge);
    (bridge, log)
}

/// The written position of tick `i` (the recording holds one write per tick from tick 0).
fn written_at(log: &Arc<Mutex<Vec<Call>>>, i: u32) -> f64 {
    let w = writes(log);
    let (tw, p) = &w[i as usize];
    assert!(close(*tw, t(i)), "write {i} at {tw}");
    p[0]
}

/// The command at tick `i` is ignored, said as held by `by`, and the joint stays at `at_rad`.
fn assert_ignored(
    b: &mut JointBridge<Recorder>,
    log: &Arc<Mutex<Vec<Call>>>,
    i: u32,
    by: Operator,
    at_rad: f64,
) {
    assert_eq!(
        b.command(t(i), &names(&["a"]), &[0.9]),
        vec![Event::Ignored(by)]
    );
    let _ = b.tick(t(i));
    assert!(close(written_at(log, i), at_rad), "tick {i}");
}

#[test]
fn an_estop_or_a_deactivate_follows_the_commands_to_rest_then_holds_and_ignores_them() {
    type Stop = fn(&mut JointBridge<Recorder>);
    for (by, stop, said) in [
        (
            Operator::Estop,
            JointBridge::estop as Stop,
            "emergency stop",
        ),
        (Operator::Inactive, deactivate as Stop, "inactive"),
    ] {
        let (mut b, log) = walking_then(0.3, stop);
        // Reported at once (the node's ~/holding: the planner brakes), yet still following.
        assert_eq!(b.operator(), Some(by));
        assert_eq!(b.following(), Some(by));
        assert_eq!(b.estop_following(), by == Operator::Estop);
        // The planner's brake: +4, +3, +2, +1 mrad, then the same command (at rest).
        let braking = [0.254, 0.257, 0.259, 0.26, 0.26];
        let mut held = Vec::new();
        for (i, &q) in (51..).zip(&braking) {
            let ev = b.command(t(i), &names(&["a"]), &[q]);
            assert!(ev.is_empty(), "tick {i}: {ev:?}");
            let (_, ev) = b.tick(t(i));
            held.extend(ev.into_iter().map(|e| (i, e)));
        }
        // Said once, at tick 55: followed from tick 50's time for 0.05 s, at rest.
        let want = Event::FollowHeld {
            by,
            followed_s: t(55) - t(50),
            why: FollowEnd::AtRest,
        };
        assert_eq!(held, vec![(55, want.clone())]);
        assert_eq!(
            want.to_string(),
            format!(
                "{said}: holding after following the commands for 0.05 s (the commands came to rest)"
            )
        );
        // Followed exactly through tick 54; tick 55's command equals tick 54's: held.
        for (i, q) in (51..=55).zip(braking) {
            assert!(close(written_at(&log, i), q), "tick {i}");
        }
        assert_eq!(b.following(), None);
        // From then on commands are ignored (said once) and the joint stays at 0.26.
        assert_ignored(&mut b, &log, 56, by, 0.26);
        for i in 57..=70 {
            assert!(b.command(t(i), &names(&["a"]), &[0.9]).is_empty());
            let _ = b.tick(t(i));
            assert!(close(written_at(&log, i), 0.26), "tick {i}");
        }
        // Released: the commands move the joint again, at 2 rad/s.
        assert!(b.release(by));
        b.command(t(71), &names(&["a"]), &[0.9]);
        let _ = b.tick(t(71));
        assert!(close(written_at(&log, 71), 0.28));
    }
}

#[test]
fn an_estop_follows_no_longer_than_its_time() {
    // Commands that never slow down: followed while t < 0.5 + 0.105 (ticks 51-60, 0.3 rad
    // at tick 60), held from tick 61 where the joint is (no acceleration limit: at once).
    let (mut b, log) = walking_then_estop(0.105);
    for i in 51..=80 {
        b.command(t(i), &names(&["a"]), &[0.005 * f64::from(i)]);
        let (_, ev) = b.tick(t(i));
        if i == 61 {
            assert!(
                matches!(ev[..], [Event::FollowHeld { why: FollowEnd::TimeUp, followed_s, .. }] if (followed_s - 0.11).abs() < 1e-12),
                "{ev:?}"
            );
        }
        let expected = 0.005 * f64::from(i.min(60));
        assert!(
            (written_at(&log, i) - expected).abs() < 1e-12,
            "tick {i}: {} rad, expected {expected}",
            written_at(&log, i)
        );
    }
    assert!(!b.estop_following());
}

#[test]
fn an_estop_holds_when_the_commands_stop_coming() {
    // A dead planner: no command after the stop (the last at 0.5 s). Still following 40 ms
    // on (tick 54), held once the silence passes FOLLOW_SILENCE_S (50 ms; by tick 56), and
    // the joint never moved from 0.25 rad.
    assert_eq!(joint_bridge::FOLLOW_SILENCE_S, 0.05);
    let (mut b, log) = walking_then_estop(0.3);
    let mut held = Vec::new();
    for i in 51..=60 {
        let (_, ev) = b.tick(t(i));
        held.extend(ev);
        assert!(close(written_at(&log, i), 0.25), "tick {i}");
        if i == 54 {
            assert!(b.estop_following(), "tick {i}");
        }
        if i == 56 {
            assert!(!b.estop_following(), "tick {i}");
        }
    }
    assert!(
        matches!(
            held[..],
            [Event::FollowHeld {
                why: FollowEnd::Silent,
                ..
            }]
        ),
        "{held:?}"
    );
}

#[test]
fn an_estop_follows_commands_that_come_every_other_tick() {
    // A planner at half the bridge's rate (or a tick late now and then, clocks not in step):
    // 10 mrad every other tick, still moving at tick 70 (0.35 rad), still followed exactly.
    let (mut b, log) = walking_then_estop(0.3);
    for i in 51..=70 {
        if i % 2 == 0 {
            b.command(t(i), &names(&["a"]), &[0.25 + 0.005 * f64::from(i - 50)]);
        }
        let _ = b.tick(t(i));
        assert!(b.estop_following(), "tick {i}");
    }
    assert!(
        (written_at(&log, 70) - 0.35).abs() < 1e-12,
        "{}",
        written_at(&log, 70)
    );
}

#[test]
fn a_second_estop_while_following_holds_at_once() {
    // The operator presses again: stop now. The next command is ignored, the joint stays.
    let (mut b, log) = walking_then_estop(0.3);
    b.command(t(51), &names(&["a"]), &[0.254]);
    let _ = b.tick(t(51));
    assert!(b.estop_following());
    b.estop();
    assert!(!b.estop_following());
    assert_ignored(&mut b, &log, 52, Operator::Estop, 0.254);
}

#[test]
fn a_torque_off_during_the_follow_ends_it() {
    // Another hold while following: the bridge holds for both, commands ignored.
    let (mut b, _log) = walking_then_estop(0.3);
    b.set_torque(false).unwrap();
    assert!(!b.estop_following());
    assert_eq!(b.operator(), Some(Operator::Estop));
    assert_eq!(
        b.command(t(51), &names(&["a"]), &[0.255]),
        vec![Event::Ignored(Operator::Estop)]
    );
}

/// The lifecycle's deactivate, as `ros2 lifecycle set /joint_bridge deactivate` takes it.
fn deactivate(b: &mut JointBridge<Recorder>) {
    use joint_bridge::managed::{ManagedState, apply, find};
    let tr = find(ManagedState::Active, 4, "").unwrap();
    assert_eq!(apply(b, tr).unwrap(), ManagedState::Inactive);
}

#[test]
fn an_activate_or_an_estop_while_a_deactivate_follows() {
    use joint_bridge::managed::{ManagedState, apply, find};
    // Activated again while following: the follow ends, commands are taken as before.
    let (mut b, log) = walking_then(0.3, deactivate);
    b.command(t(51), &names(&["a"]), &[0.254]);
    let _ = b.tick(t(51));
    let tr = find(ManagedState::Inactive, 3, "").unwrap();
    assert_eq!(apply(&mut b, tr).unwrap(), ManagedState::Active);
    assert_eq!((b.following(), b.operator()), (None, None));
    assert!(b.command(t(52), &names(&["a"]), &[0.258]).is_empty());
    let _ = b.tick(t(52));
    assert!(close(written_at(&log, 52), 0.258));
    // An e-stop while a deactivate follows: stop now, held at once for both.
    let (mut b, log) = walking_then(0.3, deactivate);
    b.command(t(51), &names(&["a"]), &[0.254]);
    let _ = b.tick(t(51));
    b.estop();
    assert_eq!(b.following(), None);
    assert_ignored(&mut b, &log, 52, Operator::Estop, 0.254);
}

#[test]
fn a_cleanup_right_after_a_deactivate_ends_its_follow() {
    use joint_bridge::managed::{ManagedState, apply, find};
    let (mut b, _log) = walking_then(0.3, deactivate);
    assert_eq!(b.following(), Some(Operator::Inactive));
    let tr = find(ManagedState::Inactive, 2, "").unwrap();
    assert_eq!(apply(&mut b, tr).unwrap(), ManagedState::Unconfigured);
    assert_eq!(b.following(), None);
}

#[test]
fn without_a_follow_time_an_estop_or_a_deactivate_holds_at_once() {
    type Stop = fn(&mut JointBridge<Recorder>);
    for (by, stop) in [
        (Operator::Estop, JointBridge::estop as Stop),
        (Operator::Inactive, deactivate as Stop),
    ] {
        let (mut b, log) = walking_then(0.0, stop);
        assert_eq!(b.following(), None);
        assert_ignored(&mut b, &log, 51, by, 0.25);
    }
}

// ---------------------------------------------------------------------------------------------
// Gyro damping
// ---------------------------------------------------------------------------------------------

/// The default robot standing at zero angles, servos of 30 N·m/rad, 0.6 N·m·s/rad of gyro
/// damping: 0.02 s of offset per rad/s. Rolling at 0.5 rad/s and pitching at -0.2 rad/s
/// (turning at 0.3 rad/s, which is left alone), every roll joint of both legs aims 0.01 rad
/// further, every pitch joint -0.004 rad (the URDF's axes are +x and +y); arms not at all.
/// Without a body rate for more than 0.05 s the offsets go (said once), and come back with it.
#[test]
fn gyro_damping_offsets_the_standing_legs_while_the_body_rate_is_fresh() {
    let model = ik_solver::BipedModel::from_urdf_str(ik_solver::DEFAULT_URDF, None).unwrap();
    let joints = robot_joints();
    let all: Vec<String> = joints.iter().map(|j| j.name.clone()).collect();
    let zeros = vec![0.0; joints.len()];
    let gyro = joint_bridge::GyroDamping::new(model, 0.6, 30.0, &joints).unwrap();
    assert!(close(gyro.gain_s(), 0.02));
    let mut b =
        JointBridge::new(MockBackend::default(), joints.clone(), patient()).with_gyro_damping(gyro);
    b.start().unwrap();
    let rate = nalgebra::Vector3::new(0.5, -0.2, 0.3);
    let mut said = Vec::new();
    for i in 0..=50 {
        b.command(t(i), &all, &zeros);
        b.set_body_rate(t(i), rate);
        // A NaN from a broken IMU is not taken: the last good rate stands.
        b.set_body_rate(t(i), nalgebra::Vector3::new(f64::NAN, 0.0, 0.0));
        said.extend(b.tick(t(i)).1);
    }
    let want = |name: &str| match name {
        "l_hip_roll" | "l_ankle_roll" | "r_hip_roll" | "r_ankle_roll" => 0.01,
        "l_hip_pitch" | "l_knee" | "l_ankle_pitch" | "r_hip_pitch" | "r_knee" | "r_ankle_pitch" => {
            -0.004
        }
        _ => 0.0,
    };
    for (w, j) in b.written_rad().iter().zip(&joints) {
        assert!(close(*w, want(&j.name)), "{}: wrote {w}", j.name);
    }
    assert_eq!(said, vec![Event::GyroDamping(true)]);
    // The IMU goes quiet after t(50): the rate is fresh up to t(55), gone at t(56).
    said.clear();
    for i in 51..=100 {
        b.command(t(i), &all, &zeros);
        said.extend(b.tick(t(i)).1);
        if i == 55 {
            assert!(b.written_rad().iter().any(|w| *w != 0.0), "off too soon");
        }
    }
    assert!(
        b.written_rad().iter().all(|w| *w == 0.0),
        "{:?}",
        b.written_rad()
    );
    assert_eq!(said, vec![Event::GyroDamping(false)]);
    b.set_body_rate(t(101), rate);
    b.command(t(101), &all, &zeros);
    assert_eq!(b.tick(t(101)).1, vec![Event::GyroDamping(true)]);
}

#[test]
fn gyro_damping_needs_a_stiffness_and_a_damping() {
    let model = ik_solver::BipedModel::from_urdf_str(ik_solver::DEFAULT_URDF, None).unwrap();
    let joints = robot_joints();
    let e = joint_bridge::GyroDamping::new(model.clone(), 0.6, 0.0, &joints)
        .unwrap_err()
        .to_string();
    assert!(e.contains("stiffness 0"), "{e}");
    let e = joint_bridge::GyroDamping::new(model, f64::NAN, 30.0, &joints)
        .unwrap_err()
        .to_string();
    assert!(e.contains("gyro damping: NaN"), "{e}");
}
