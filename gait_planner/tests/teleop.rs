//! Following a cmd_vel stream with time passed in, as the gait_planner node does at each
//! tick: a stream that stops ends the walk within the timeout plus one phase, a zero command
//! ends it, a new velocity is taken at the next swing, a turn is refused once by name.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::*;
use gait_planner::{GaitPlanner, GaitSample, PhaseKind, Velocity, VelocityFollower};

const RATE_HZ: f64 = 100.0;

fn vel(x: f64, y: f64, z: f64) -> Velocity {
    Velocity {
        x_m_s: x,
        y_m_s: y,
        yaw_rad_s: z,
    }
}

/// Runs the node's tick loop: at tick k, `stream(k)` may give a command; then the
/// follower's tick, then the planner's update. Stops when idle after walking, or at `max_s`.
fn drive(
    planner: &mut GaitPlanner,
    stream: impl Fn(u32) -> Option<Velocity>,
    max_s: f64,
) -> (Vec<GaitSample>, Vec<String>) {
    let mut f = VelocityFollower::new();
    let (mut out, mut log) = (Vec::new(), Vec::new());
    for k in 0.. {
        let t = f64::from(k) / RATE_HZ;
        if let Some(v) = stream(k) {
            log.extend(f.command(planner, v, t));
        }
        log.extend(f.tick(planner, t));
        let s = planner.update(t).unwrap();
        let walked = out.iter().any(|s: &GaitSample| s.phase != PhaseKind::Idle);
        let idle = s.phase == PhaseKind::Idle;
        out.push(s);
        if (walked && idle) || t > max_s {
            break;
        }
    }
    (out, log)
}

/// Start time of every phase of a kind.
fn starts(samples: &[GaitSample], kind: PhaseKind) -> Vec<f64> {
    samples
        .windows(2)
        .filter(|w| {
            w[1].phase == kind && (w[0].phase != kind || w[0].step_index != w[1].step_index)
        })
        .map(|w| w[1].t_s)
        .collect()
}

#[test]
fn a_stream_that_stops_ends_the_walk_within_the_timeout_plus_one_phase() {
    let mut planner = planner(slow());
    let c = planner.config().clone();
    // A teleop at 10 Hz sidestepping left for 10 s, then nothing.
    let last_k = 1000;
    let (samples, log) = drive(
        &mut planner,
        |k| (k % 10 == 0 && k <= last_k).then_some(vel(0.0, 0.004, 0.0)),
        120.0,
    );
    let end = samples.last().unwrap();
    assert_eq!(end.phase, PhaseKind::Idle, "the walk ended by itself");
    let t_last = f64::from(last_k) / RATE_HZ;
    let t_stop = t_last + c.cmd_vel_timeout_s;
    assert!(
        log.iter().any(|m| m.contains("no command for 0.5 s")),
        "{log:?}"
    );
    // No swing but the closing one starts after the timeout ...
    for kind in [PhaseKind::HalfStep, PhaseKind::Step] {
        for t in starts(&samples, kind) {
            assert!(
                t <= t_stop + 1e-9,
                "a {kind} started at {t} s, after {t_stop} s"
            );
        }
    }
    // ... and the closing half step starts within the phase in progress plus one shift.
    let closing = starts(&samples, PhaseKind::FinalHalfStep);
    assert_eq!(closing.len(), 1);
    let bound = t_stop + 1.0 / RATE_HZ + c.step_duration_s + c.shift_duration_s;
    assert!(
        closing[0] <= bound,
        "closing half step at {} s, bound {bound} s",
        closing[0]
    );
    // Standing with the feet level at the standing width. The left foot (on the side of
    // travel) opens by 2 x 12 mm (0.004 m/s x the 3 s step period) at each of its swings;
    // the right one, closing after it, brings the body along.
    let [l0, r0] = samples[0].ankles_world_m;
    let [l, r] = end.ankles_world_m;
    assert!((l.x - r.x).abs() < 1e-12);
    assert!(((l.y - r.y) - (l0.y - r0.y)).abs() < 1e-12);
    let left_swings = samples
        .windows(2)
        .filter(|w| {
            matches!(w[1].phase, PhaseKind::HalfStep | PhaseKind::Step)
                && w[1].support == gait_planner::Support::Right
                && (w[0].phase, w[0].step_index) != (w[1].phase, w[1].step_index)
        })
        .count();
    assert!(left_swings >= 2, "{left_swings}");
    assert!(
        ((l.y - l0.y) - left_swings as f64 * 0.024).abs() < 1e-12,
        "{} after {left_swings} left swings",
        l.y - l0.y
    );
}

#[test]
fn a_zero_command_ends_the_walk_and_a_new_velocity_is_taken_at_the_next_swing() {
    let mut planner = planner(slow());
    let step_s = planner.config().step_period_s();
    // Forward 10 mm per step until 8 s, then 9 mm per step back, zero at 20 s.
    let (samples, _) = drive(
        &mut planner,
        |k| match k {
            0..=799 if k % 10 == 0 => Some(vel(0.01 / step_s, 0.0, 0.0)),
            800..=1999 if k % 10 == 0 => Some(vel(-0.009 / step_s, 0.0, 0.0)),
            2000 => Some(vel(0.0, 0.0, 0.0)),
            _ => None,
        },
        120.0,
    );
    assert_eq!(samples.last().unwrap().phase, PhaseKind::Idle);
    // Each swing lands its foot (ahead of or behind) the other by the stride in force when
    // it started: 10 mm before 8 s, -9 mm from then on, 0 for the closing half step.
    let mut landed = 0;
    for w in samples.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        if a.phase.is_swing() && !b.phase.is_swing() {
            let start = samples
                .iter()
                .find(|s| s.phase == a.phase && s.step_index == a.step_index)
                .unwrap()
                .t_s;
            let [l, r] = a.ankles_world_m;
            let (swing, stance) = match a.support {
                gait_planner::Support::Right => (l, r),
                _ => (r, l),
            };
            let want = if a.phase == PhaseKind::FinalHalfStep {
                0.0
            } else if start < 8.0 {
                0.01
            } else {
                -0.009
            };
            assert!(
                ((swing.x - stance.x) - want).abs() < 1e-12,
                "swing started at {start} s landed {} m from the stance foot, want {want}",
                swing.x - stance.x
            );
            landed += 1;
        }
    }
    assert!(landed >= 6, "{landed} swings");
    // The zero command at 20 s: no new step starts after it.
    for t in starts(&samples, PhaseKind::Step) {
        assert!(t <= 20.0 + 1e-9, "step started at {t}");
    }
}

#[test]
fn a_turn_is_refused_once_by_name_and_the_robot_stays_put() {
    let mut planner = planner(slow());
    let (samples, log) = drive(
        &mut planner,
        |k| (k % 10 == 0).then_some(vel(0.005, 0.0, 0.3)),
        5.0,
    );
    assert!(samples.iter().all(|s| s.phase == PhaseKind::Idle));
    assert_eq!(log.len(), 1, "{log:?}");
    assert!(
        log[0].contains("angular.z = 0.3") && log[0].contains("no hip yaw"),
        "{log:?}"
    );
}

#[test]
fn a_steady_command_beyond_the_limits_is_walked_at_the_limit_and_warned_once() {
    let mut planner = planner(slow());
    let (samples, log) = drive(
        &mut planner,
        |k| (k % 10 == 0 && k < 1500).then_some(vel(1.0, 0.0, 0.0)),
        120.0,
    );
    assert_eq!(
        log.iter()
            .filter(|m| m.contains("beyond the step limits"))
            .count(),
        1,
        "{log:?}"
    );
    // The full step (45 mm) every swing.
    let step = samples
        .iter()
        .map(|s| s.ankles_world_m[0].x)
        .fold(0.0, f64::max);
    let swings =
        starts(&samples, PhaseKind::HalfStep).len() + starts(&samples, PhaseKind::Step).len();
    assert!(swings >= 2);
    let last = samples.last().unwrap().ankles_world_m;
    assert!(
        (last[0].x - swings as f64 * 0.045).abs() < 1e-12,
        "{} {step}",
        last[0].x
    );
}

#[test]
fn a_nan_command_is_refused_by_name_every_time_and_the_walk_times_out() {
    let mut planner = planner(slow());
    let (samples, log) = drive(
        &mut planner,
        |k| match k {
            0 => Some(vel(0.01, 0.0, 0.0)),
            20 | 30 => Some(vel(f64::NAN, 0.0, 0.0)),
            _ => None,
        },
        60.0,
    );
    assert_eq!(
        log.iter().filter(|m| m.contains("linear.x = NaN")).count(),
        2,
        "{log:?}"
    );
    assert!(log.iter().any(|m| m.contains("ending the walk")));
    assert_eq!(samples.last().unwrap().phase, PhaseKind::Idle);
}
