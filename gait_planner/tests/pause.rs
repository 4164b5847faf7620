//! Pausing anywhere (`gait_planner::pause`): the brake time the planner settles keeps the
//! ZMP margin when pauses and resumes are played through the planner tick by tick (the ZMP
//! from second differences of the CoM path computed here, not the planner's model), and a
//! shorter brake breaks it; brake times set by hand are checked the same way.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::*;
use gait_planner::pause::PlanClock;
use gait_planner::zmp::GRAVITY_M_S2;
use gait_planner::{GaitError, GaitParams, GaitPlanner, WalkRequest};
use ik_solver::support::signed_margin;

/// 1 kHz so that second differences are the acceleration to well under a millimetre of ZMP.
fn fast_params() -> GaitParams {
    GaitParams {
        control_rate_hz: 1000.0,
        shift_duration_s: 1.0,
        step_duration_s: 0.6,
        ..slow()
    }
}

/// The least ZMP margin (m) over pauses starting every `every` ticks of a 2-step walk, each
/// braking over `brake_ticks`, held 20 ticks, then resumed: the CoM of every tick played
/// through the planner with a [`PlanClock`], differentiated twice, the cart-table ZMP of
/// that against the tick's support polygon. Returns (margin, start tick of the worst).
fn least_pause_margin(planner: &GaitPlanner, brake_ticks: u32, every: usize) -> (f64, u64) {
    let rate = planner.config().control_rate_hz;
    let dt = 1.0 / rate;
    let mut walk = planner.clone();
    walk.request(WalkRequest::Steps(2));
    let mut clock = PlanClock::new(brake_ticks);
    let mut worst = (f64::INFINITY, 0);
    for k0 in 0u64.. {
        let s = walk.update(clock.plan_ticks(k0, false) / rate).unwrap();
        if s.phase == gait_planner::PhaseKind::Idle && k0 > 10 {
            break;
        }
        if k0 % every as u64 != 0 {
            continue;
        }
        let (mut w, mut c) = (walk.clone(), clock.clone());
        c.pause();
        let mut ticks = Vec::new();
        let n = 2 * u64::from(brake_ticks) + 40;
        for j in 1..=n {
            if j == u64::from(brake_ticks) + 20 {
                assert!(c.at_rest(), "not at rest after the brake");
                c.resume();
            }
            let s = w.update(c.plan_ticks(k0 + j, false) / rate).unwrap();
            let poly = w.support_polygon(s.support, &s.ankles_world_m, &s.feet_yaw_rad);
            ticks.push((s.com_world_m, poly));
        }
        for t in ticks.windows(3) {
            let (a, b, c) = (t[0].0, t[1].0, t[2].0);
            let acc = (a.coords - 2.0 * b.coords + c.coords) / (dt * dt);
            let scale = b.z / (GRAVITY_M_S2 + acc.z);
            let zmp = [b.x - scale * acc.x, b.y - scale * acc.y];
            let m = signed_margin(&t[1].1, zmp);
            if m < worst.0 {
                worst = (m, k0);
            }
        }
    }
    worst
}

#[test]
fn pausing_anywhere_keeps_the_zmp_margin_and_a_shorter_brake_does_not() {
    let planner = GaitPlanner::new(default_model(), fast_params()).unwrap();
    let c = planner.config();
    let brake_ticks = (c.pause_brake_time_s * c.control_rate_hz).round() as u32;
    // Moving 1 s shifts stop in a few tenths of a second, not at once.
    assert!(
        (0.05..0.5).contains(&c.pause_brake_time_s),
        "brake {} s",
        c.pause_brake_time_s
    );
    let (kept, at) = least_pause_margin(&planner, brake_ticks, 25);
    // The ramp is checked at 41 points, the ZMP here at every tick: within 0.3 mm.
    assert!(
        kept > c.min_zmp_margin_m - 3e-4,
        "a pause at tick {at} leaves a ZMP margin {kept} m < {} m",
        c.min_zmp_margin_m
    );
    let short = (brake_ticks as f64 * 0.7).round() as u32;
    let (broken, at_short) = least_pause_margin(&planner, short, 25);
    eprintln!(
        "brake {brake_ticks} ticks: least ZMP margin {kept} m (start tick {at}); {short} ticks: {broken} m (start tick {at_short}); required {} m",
        c.min_zmp_margin_m
    );
    assert!(
        broken < c.min_zmp_margin_m - 1e-3,
        "a brake of {short} ticks still keeps {broken} m (worst at tick {at_short})"
    );
}

#[test]
fn a_brake_time_set_by_hand_is_checked_and_named_when_too_short() {
    let auto = GaitPlanner::new(default_model(), fast_params()).unwrap();
    let needed = auto.config().pause_brake_time_s;
    let longer = GaitParams {
        pause_brake_time_s: needed + 0.1,
        ..fast_params()
    };
    let p = GaitPlanner::new(default_model(), longer).unwrap();
    assert!((p.config().pause_brake_time_s - needed - 0.1).abs() < 1e-12);
    let shorter = GaitParams {
        pause_brake_time_s: needed / 2.0,
        ..fast_params()
    };
    let err = GaitPlanner::new(default_model(), shorter).unwrap_err();
    let GaitError::PauseBrake {
        brake_s, needed_s, ..
    } = &err
    else {
        panic!("{err}");
    };
    assert_eq!(*brake_s, needed / 2.0);
    // The auto value is the shortest rounded up to a whole tick.
    assert!(
        *needed_s <= needed && *needed_s > needed - 1e-3,
        "{needed_s} vs {needed}"
    );
    let text = err.to_string();
    assert!(
        text.contains("pause_brake_time_s") && text.contains("at least"),
        "{text}"
    );
}

/// Slower shifts move the CoM more slowly: a shorter brake suffices. A robot standing still
/// between steps would need none, but every walk moves: never 0.
#[test]
fn the_brake_shortens_as_the_walk_slows() {
    let brake = |shift_s: f64| {
        let p = GaitParams {
            shift_duration_s: shift_s,
            ..slow()
        };
        GaitPlanner::new(default_model(), p)
            .unwrap()
            .config()
            .pause_brake_time_s
    };
    let (slow, fast) = (brake(2.0), brake(1.0));
    assert!(
        slow > 0.0 && slow < fast,
        "2 s shifts: {slow} s, 1 s shifts: {fast} s"
    );
}
