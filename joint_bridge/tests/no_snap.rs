//! No snap on any state change (#27): every written position goes through one velocity and
//! acceleration limiter, from the measured pose where the backend measures. Each test here
//! is a path that snapped before the limiter: resume after limp, a new command source after
//! a hold, the sag offset at start, a stalled control loop, a joint without a speed limit.
//! Then the operator's holds (emergency stop, torque off, the managed node's transitions),
//! and a property over random command streams with all of these: no step ever exceeds the
//! limits.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::{names, spec};

use ik_solver::{BipedModel, DEFAULT_URDF};
use joint_bridge::managed;
use joint_bridge::{
    Backend, BackendError, BridgeConfig, Event, JointBridge, JointSpec, Lifecycle, Operator,
    Reading, SagCompensation, TimeoutAction, TorqueError,
};
use proptest::prelude::*;

/// A servo bus that measures: it reads back what was written while the torque is on; with
/// the torque off, its joints fall to `limp_pose` (gravity).
#[derive(Debug)]
struct Servos {
    pose: Vec<f64>,
    torque: bool,
    limp_pose: Vec<f64>,
    writes: Vec<(f64, Vec<f64>)>,
}

impl Servos {
    fn new(pose: Vec<f64>, limp_pose: Vec<f64>) -> Self {
        Self {
            pose,
            torque: false,
            limp_pose,
            writes: Vec::new(),
        }
    }
}

impl Backend for Servos {
    fn name(&self) -> &str {
        "servos"
    }
    fn configure(&mut self, _: &[JointSpec]) -> Result<Option<Vec<f64>>, BackendError> {
        Ok(Some(self.pose.clone()))
    }
    fn activate(&mut self) -> Result<(), BackendError> {
        self.torque = true;
        Ok(())
    }
    fn write(&mut self, t_s: f64, positions_rad: &[f64]) -> Result<(), BackendError> {
        assert!(self.torque, "write with the torque off");
        self.pose = positions_rad.to_vec();
        self.writes.push((t_s, positions_rad.to_vec()));
        Ok(())
    }
    fn read(&mut self, _: f64) -> Result<Reading, BackendError> {
        if !self.torque {
            self.pose = self.limp_pose.clone();
        }
        Ok(Reading {
            positions_rad: self.pose.clone(),
            velocities_rad_s: None,
            measured: true,
        })
    }
    fn deactivate(&mut self) -> Result<(), BackendError> {
        self.torque = false;
        Ok(())
    }
}

/// Largest step of the written positions between consecutive writes (rad), and largest
/// change of velocity between consecutive steps (rad/s), for writes every `dt` s.
fn worst_steps(writes: &[(f64, Vec<f64>)], joint: usize) -> (f64, f64) {
    let x: Vec<(f64, f64)> = writes.iter().map(|(t, w)| (*t, w[joint])).collect();
    let v: Vec<f64> = x
        .windows(2)
        .map(|p| (p[1].1 - p[0].1) / (p[1].0 - p[0].0))
        .collect();
    let dx = x
        .windows(2)
        .map(|p| (p[1].1 - p[0].1).abs())
        .fold(0.0, f64::max);
    let dv = v
        .windows(2)
        .map(|p| (p[1] - p[0]).abs())
        .fold(0.0, f64::max);
    (dx, dv)
}

fn config() -> BridgeConfig {
    BridgeConfig {
        watchdog_timeout_s: 0.25,
        on_timeout: TimeoutAction::Hold,
        acceleration_rad_s2: 20.0,
        ..BridgeConfig::default()
    }
}

#[test]
fn resuming_after_limp_starts_from_the_measured_pose_not_the_last_output() {
    // Out to 0.75 rad, silence, limp; gravity takes the joint to 0.2 rad; a new command
    // resumes. The first write after resuming is next to 0.2 (where the joint is), not 0.75.
    let servos = Servos::new(vec![0.0], vec![0.2]);
    let cfg = BridgeConfig {
        on_timeout: TimeoutAction::Limp,
        ..config()
    };
    let mut b = JointBridge::new(servos, vec![spec("a", -1.5, 1.5, 1.0)], cfg);
    b.start().unwrap();
    for i in 0..=100 {
        let t = f64::from(i) * 0.01;
        b.command(t, &names(&["a"]), &[0.75]);
        let _ = b.tick(t);
    }
    assert!((b.written_rad()[0] - 0.75).abs() < 1e-9);
    for i in 101..=140 {
        let _ = b.tick(f64::from(i) * 0.01);
    }
    assert!(b.watchdog_tripped());
    b.command(1.41, &names(&["a"]), &[0.75]);
    let _ = b.tick(1.41);
    let first = b.backend().writes.last().unwrap().1[0];
    assert!(
        (first - 0.2).abs() < 0.01,
        "first write after resuming: {first} rad, the joint is at 0.2"
    );
}

#[test]
fn a_new_command_source_after_a_hold_accelerates_within_the_limit() {
    // Holding at 0 (the old source died); a restarted source commands 1 rad at once. At
    // 20 rad/s² the speed grows 0.2 rad/s per 10 ms tick: never the 1 rad/s limit at once.
    let mut b = JointBridge::new(
        Servos::new(vec![0.0], vec![0.0]),
        vec![spec("a", -1.5, 1.5, 1.0)],
        config(),
    );
    b.start().unwrap();
    b.command(0.0, &names(&["a"]), &[0.0]);
    for i in 0..=50 {
        let _ = b.tick(f64::from(i) * 0.01);
    }
    assert!(b.watchdog_tripped());
    for i in 51..=200 {
        let t = f64::from(i) * 0.01;
        b.command(t, &names(&["a"]), &[1.0]);
        let _ = b.tick(t);
    }
    let (dx, dv) = worst_steps(&b.backend().writes, 0);
    assert!(dx <= 1.0 * 0.01 + 1e-12, "step {dx} rad in 10 ms");
    assert!(
        dv <= 20.0 * 0.01 + 1e-9,
        "speed changed by {dv} rad/s in one tick"
    );
    assert!(
        (b.written_rad()[0] - 1.0).abs() < 1e-9,
        "{:?}",
        b.written_rad()
    );
}

#[test]
fn the_sag_offset_at_start_goes_through_the_limiter() {
    // The default robot measured crouched and commanded to stay so, sag compensation at a
    // soft 3 N·m/rad: the crouch's offsets are large. The first write is the measured pose;
    // the offset is taken on within the limits.
    let model = BipedModel::from_urdf_str(DEFAULT_URDF, None).unwrap();
    let joints = JointSpec::from_robot(model.robot());
    let crouch: Vec<f64> = joints
        .iter()
        .map(|j| match j.name.as_str() {
            "l_hip_pitch" | "r_hip_pitch" | "l_ankle_pitch" | "r_ankle_pitch" => -0.4,
            "l_knee" | "r_knee" => 0.8,
            _ => 0.0,
        })
        .collect();
    let comp = SagCompensation::new(model, 3.0, &joints).unwrap();
    let mut b = JointBridge::new(
        Servos::new(crouch.clone(), crouch.clone()),
        joints.clone(),
        config(),
    )
    .with_sag_compensation(comp);
    b.start().unwrap();
    let all: Vec<String> = joints.iter().map(|j| j.name.clone()).collect();
    for i in 0..=100 {
        let t = f64::from(i) * 0.01;
        b.command(t, &all, &crouch);
        let _ = b.tick(t);
    }
    let w = &b.backend().writes;
    let largest_offset = b
        .written_rad()
        .iter()
        .zip(&crouch)
        .fold(0.0f64, |m, (w, c)| m.max((w - c).abs()));
    assert!(
        largest_offset > 0.02,
        "offsets too small to test: {largest_offset}"
    );
    assert_eq!(w[0].1, crouch, "the first write is the measured pose");
    for (j, spec) in joints.iter().enumerate() {
        let (dx, dv) = worst_steps(w, j);
        assert!(
            dx <= spec.velocity_rad_s * 0.01 + 1e-12,
            "{}: {dx}",
            spec.name
        );
        assert!(dv <= 20.0 * 0.01 + 1e-9, "{}: {dv}", spec.name);
    }
}

#[test]
fn a_stalled_control_loop_moves_the_joints_one_bounded_tick_not_the_stall() {
    // A 1 s stall between two ticks: the step is at most v_max × max_tick_s (1 × 0.05).
    let mut b = JointBridge::new(
        Servos::new(vec![0.0], vec![0.0]),
        vec![spec("a", -1.5, 1.5, 1.0)],
        BridgeConfig {
            watchdog_timeout_s: 10.0,
            ..config()
        },
    );
    b.start().unwrap();
    for i in 0..=20 {
        let t = f64::from(i) * 0.01;
        b.command(t, &names(&["a"]), &[1.0]);
        let _ = b.tick(t);
    }
    let before = b.written_rad()[0];
    b.command(1.2, &names(&["a"]), &[1.0]);
    let _ = b.tick(1.2);
    let step = b.written_rad()[0] - before;
    assert!(step > 0.0 && step <= 0.05 + 1e-12, "{step} rad in one tick");
}

#[test]
fn a_joint_without_a_speed_limit_moves_at_the_default_speed() {
    // A continuous joint (no URDF speed limit) told to go 3 rad: at most
    // default_velocity_rad_s (2 rad/s) x 10 ms per tick, not the whole way at once.
    let mut b = JointBridge::new(
        Servos::new(vec![0.0], vec![0.0]),
        vec![spec(
            "wheel",
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::INFINITY,
        )],
        config(),
    );
    b.start().unwrap();
    for i in 0..=300 {
        let t = f64::from(i) * 0.01;
        b.command(t, &names(&["wheel"]), &[3.0]);
        let _ = b.tick(t);
    }
    // The measured start pose, at rest, is where the writes begin.
    let mut writes = vec![(-0.01, vec![0.0])];
    writes.extend(b.backend().writes.iter().cloned());
    let (dx, dv) = worst_steps(&writes, 0);
    assert!(dx <= 2.0 * 0.01 + 1e-12, "step {dx} rad in 10 ms");
    assert!(dv <= 20.0 * 0.01 + 1e-9, "{dv}");
    assert!(
        (b.written_rad()[0] - 3.0).abs() < 1e-9,
        "{:?}",
        b.written_rad()
    );
}

#[test]
fn an_emergency_stop_brakes_to_a_hold_ignores_commands_until_released_then_moves_smoothly() {
    let mut b = JointBridge::new(
        Servos::new(vec![0.0], vec![0.0]),
        vec![spec("a", -1.5, 1.5, 1.0)],
        config(),
    );
    b.start().unwrap();
    let mut t = 0.0;
    let mut run = |b: &mut JointBridge<Servos>, goal: f64, ticks: u32| {
        let mut events = Vec::new();
        for _ in 0..ticks {
            t += 0.01;
            events.extend(b.command(t, &names(&["a"]), &[goal]));
            events.extend(b.tick(t).1);
        }
        events
    };
    run(&mut b, 1.0, 40);
    let moving = b.backend().writes.len();
    b.estop();
    assert_eq!(b.operator(), Some(Operator::Estop));
    let events = run(&mut b, -1.0, 100);
    // Said once; the joint brakes (no turning back) and then holds, torque on, no watchdog.
    assert_eq!(events, vec![Event::Ignored(Operator::Estop)], "{events:?}");
    let held: Vec<f64> = b.backend().writes[moving..]
        .iter()
        .map(|w| w.1[0])
        .collect();
    assert!(
        held.windows(2).all(|w| w[1] >= w[0] - 1e-12),
        "turned back: {held:?}"
    );
    let rest = held[held.len() - 1];
    assert!(
        held[held.len() - 30..].iter().all(|&x| x == rest),
        "still moving"
    );
    assert_eq!(b.state(), Lifecycle::Active);
    assert!(b.release_estop());
    assert!(!b.release_estop(), "released twice");
    run(&mut b, -1.0, 200);
    let (_, dv) = worst_steps(&b.backend().writes, 0);
    assert!(dv <= 20.0 * 0.01 + 1e-9, "{dv}");
    assert!(
        (b.written_rad()[0] + 1.0).abs() < 1e-9,
        "{:?}",
        b.written_rad()
    );
}

#[test]
fn torque_off_on_request_ignores_commands_and_torque_on_holds_the_measured_pose() {
    let mut b = JointBridge::new(
        Servos::new(vec![0.0], vec![-0.3]),
        vec![spec("a", -1.5, 1.5, 1.0)],
        config(),
    );
    b.start().unwrap();
    for i in 0..50 {
        let t = f64::from(i) * 0.01;
        b.command(t, &names(&["a"]), &[0.5]);
        let _ = b.tick(t);
    }
    b.set_torque(false).unwrap();
    assert!(!b.backend().torque);
    let writes = b.backend().writes.len();
    assert_eq!(
        b.command(0.6, &names(&["a"]), &[0.5]),
        vec![Event::Ignored(Operator::TorqueOff)]
    );
    let _ = b.tick(0.6); // reads the fallen pose, -0.3
    assert_eq!(
        b.backend().writes.len(),
        writes,
        "wrote with the torque off"
    );
    // An emergency stop meanwhile keeps it off.
    b.estop();
    assert_eq!(b.set_torque(true), Err(TorqueError::Estop));
    assert!(b.release_estop());
    b.set_torque(true).unwrap();
    assert!(b.backend().torque);
    let _ = b.tick(0.61);
    assert_eq!(b.written_rad(), [-0.3], "holds the measured pose, not 0.5");
    // Commands are taken again, approached smoothly.
    for i in 62..200 {
        let t = f64::from(i) * 0.01;
        b.command(t, &names(&["a"]), &[0.5]);
        let _ = b.tick(t);
    }
    assert!((b.written_rad()[0] - 0.5).abs() < 1e-9);
    let after = &b.backend().writes[writes..];
    let (_, dv) = worst_steps(after, 0);
    assert!(dv <= 20.0 * 0.01 + 1e-9, "{dv}");
}

#[test]
fn a_restart_or_reconnection_leaves_the_torque_the_operator_turned_off_off() {
    let mut b = JointBridge::new(
        Servos::new(vec![0.0], vec![0.4]),
        vec![spec("a", -1.5, 1.5, 1.0)],
        config(),
    );
    b.start().unwrap();
    for i in 0..20 {
        let t = f64::from(i) * 0.01;
        b.command(t, &names(&["a"]), &[1.2]);
        let _ = b.tick(t);
    }
    b.set_torque(false).unwrap();
    let writes = b.backend().writes.len();
    b.stop().unwrap();
    b.start().unwrap();
    for i in 20..60 {
        let _ = b.tick(f64::from(i) * 0.01);
    }
    assert!(!b.backend().torque, "a restart turned the torque back on");
    assert_eq!(b.state(), Lifecycle::Inactive);
    assert_eq!(
        b.backend().writes.len(),
        writes,
        "wrote with the torque off"
    );
    // On again: it holds where the joint fell, not the command from before (1.2).
    b.set_torque(true).unwrap();
    for i in 60..120 {
        let _ = b.tick(f64::from(i) * 0.01);
    }
    assert_eq!(b.written_rad(), [0.4]);
}

#[test]
fn torque_requests_before_start_are_refused_naming_the_state() {
    let mut b = JointBridge::new(
        Servos::new(vec![0.0], vec![0.0]),
        vec![spec("a", -1.5, 1.5, 1.0)],
        config(),
    );
    let e = b.set_torque(true).unwrap_err();
    assert!(e.to_string().contains("Unconfigured"), "{e}");
}

#[test]
fn the_managed_transitions_hold_release_and_turn_the_torque_off() {
    use joint_bridge::managed::{ManagedState, apply, find};
    let mut b = JointBridge::new(
        Servos::new(vec![0.0], vec![-0.3]),
        vec![spec("a", -1.5, 1.5, 1.0)],
        config(),
    );
    b.start().unwrap();
    let mut state = ManagedState::Active;
    let mut go = |b: &mut JointBridge<Servos>, label: &str| {
        let tr = find(state, 0, label).unwrap();
        state = apply(b, tr).unwrap();
        state
    };
    let mut t = 0.0;
    let mut run = |b: &mut JointBridge<Servos>, goal: f64, ticks: u32| {
        for _ in 0..ticks {
            t += 0.01;
            b.command(t, &names(&["a"]), &[goal]);
            let _ = b.tick(t);
        }
    };
    run(&mut b, 0.4, 100);
    assert_eq!(go(&mut b, "deactivate"), ManagedState::Inactive);
    run(&mut b, -1.0, 50);
    assert!(
        (b.written_rad()[0] - 0.4).abs() < 1e-9,
        "moved while inactive"
    );
    assert!(b.backend().torque, "inactive holds with the torque on");
    assert_eq!(go(&mut b, "cleanup"), ManagedState::Unconfigured);
    assert!(!b.backend().torque);
    run(&mut b, -1.0, 5); // the joint falls to -0.3
    assert_eq!(go(&mut b, "configure"), ManagedState::Inactive);
    let configured = b.backend().writes.len();
    run(&mut b, -1.0, 5);
    assert!(
        (b.written_rad()[0] + 0.3).abs() < 1e-9,
        "configure holds the measured pose"
    );
    assert_eq!(go(&mut b, "activate"), ManagedState::Active);
    run(&mut b, 0.2, 200);
    assert!((b.written_rad()[0] - 0.2).abs() < 1e-9);
    // From the configured hold on (the joint fell while the torque was off).
    let (_, dv) = worst_steps(&b.backend().writes[configured..], 0);
    assert!(dv <= 20.0 * 0.01 + 1e-9, "{dv}");
    assert_eq!(go(&mut b, "shutdown"), ManagedState::Finalized);
    assert!(!b.backend().torque);
}

/// What a test stream does at one tick.
#[derive(Debug, Clone)]
enum Act {
    /// A command (may be NaN, infinite or far outside the limits).
    Command(f64),
    /// No command this tick.
    Silence,
    /// A gap of this many seconds before the tick (a stall).
    Stall(f64),
    /// Stop (torque off) and start again.
    Restart,
    /// The operator's emergency stop, or its release.
    Estop(bool),
    /// The operator's torque request (off: limp; on: hold the measured pose).
    Torque(bool),
    /// A lifecycle manager's transition, by id (1 configure, 2 cleanup, 3 activate,
    /// 4 deactivate, 5-7 shutdown); refused when not available from the state.
    Managed(u8),
}

fn act() -> impl Strategy<Value = Act> {
    prop_oneof![
        6 => (-3.0..3.0f64).prop_map(Act::Command),
        1 => prop_oneof![Just(f64::NAN), Just(f64::INFINITY), Just(-1e9)].prop_map(Act::Command),
        3 => Just(Act::Silence),
        1 => (0.0..2.0f64).prop_map(Act::Stall),
        1 => Just(Act::Restart),
        1 => any::<bool>().prop_map(Act::Estop),
        1 => any::<bool>().prop_map(Act::Torque),
        2 => (1u8..=7).prop_map(Act::Managed),
    ]
}

/// Cases of the property: 300 in `scripts/test`; `PROPTEST_CASES` sets it (a long run:
/// `PROPTEST_CASES=100000 cargo test --release -p joint_bridge --test no_snap no_write_ever`).
fn cases() -> u32 {
    std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(300)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), ..ProptestConfig::default() })]

    /// Random streams of commands, jumps, NaN, silences (the watchdog holds or goes limp),
    /// stalls, restarts, emergency stops (holding at once, or following the commands first),
    /// torque requests and lifecycle transitions (a
    /// shutdown ends the stream's writes): every write is finite, within the joint limits, and between two
    /// writes the speed stays within v_max and changes by at most a_max x dt; after a limp or
    /// a restart the next write continues from the measured pose within the same limits.
    #[test]
    fn no_write_ever_exceeds_the_velocity_and_acceleration_limits(
        acts in prop::collection::vec(act(), 1..400),
        limp in any::<bool>(),
        follow in any::<bool>(),
        gravity in -0.5..0.5f64,
    ) {
        let (vmax, amax, lo, hi) = (1.5, 15.0, -1.0, 1.2);
        let cfg = BridgeConfig {
            watchdog_timeout_s: 0.05,
            on_timeout: if limp { TimeoutAction::Limp } else { TimeoutAction::Hold },
            acceleration_rad_s2: amax,
            // An e-stop following the commands for up to 5 ticks, or holding at once.
            estop_follow_s: if follow { 0.05 } else { 0.0 },
            ..BridgeConfig::default()
        };
        let mut b = JointBridge::new(Servos::new(vec![0.3], vec![gravity]), vec![spec("a", lo, hi, vmax)], cfg);
        b.start().unwrap();
        let mut t = 0.0;
        // (time, position, velocity) of the joint as last written, or measured at rest.
        let mut last = (0.0, 0.3, 0.0);
        let mut managed_state = managed::ManagedState::Active;
        for a in &acts {
            let prev_t = t;
            t += 0.01;
            let limp_before = !b.backend().torque;
            match a {
                Act::Command(x) => { b.command(t, &names(&["a"]), &[*x]); }
                Act::Silence => {}
                Act::Stall(s) => t += s,
                Act::Restart => {
                    b.stop().unwrap();
                    let _ = b.backend_mut().read(t);
                    b.start().unwrap();
                    last = (prev_t, b.backend().pose[0], 0.0);
                }
                Act::Estop(true) => b.estop(),
                Act::Estop(false) => { b.release_estop(); }
                // Refused during an emergency stop: nothing changes then.
                Act::Torque(on) => { let _ = b.set_torque(*on); }
                Act::Managed(id) => {
                    if let Ok(tr) = managed::find(managed_state, *id, "") {
                        managed_state = managed::apply(&mut b, tr).unwrap();
                    }
                }
            }
            if limp_before {
                // The joint lay where gravity took it, at rest.
                last = (prev_t, gravity, 0.0);
            }
            let writes_before = b.backend().writes.len();
            let _ = b.tick(t);
            if b.backend().writes.len() == writes_before {
                continue;
            }
            let x = b.written_rad()[0];
            prop_assert!(x.is_finite() && (lo..=hi).contains(&x), "write {x} at {t}");
            let (t0, x0, v0) = last;
            let dt = (t - t0).min(0.05);
            let v = (x - x0) / dt;
            prop_assert!(v.abs() <= vmax + 1e-9, "speed {v} at t = {t}");
            prop_assert!((v - v0).abs() <= amax * dt + 1e-6, "speed {v0} -> {v} in {dt} s at t = {t}");
            last = (t, x, v);
        }
    }
}
