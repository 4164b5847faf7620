//! The phase machine: sequences for a number of steps, stop requests in every phase, new
//! requests during a walk.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::*;
use gait_planner::{GaitParams, GaitSample, PhaseKind, WalkRequest};
use ik_solver::Side;

#[test]
fn one_two_and_seven_steps() {
    assert_eq!(
        sequence(&plan(1, slow())),
        [
            "crouch",
            "shift",
            "half_step(L)",
            "shift",
            "final_half_step(R)",
            "center"
        ]
    );
    assert_eq!(
        sequence(&plan(2, slow())),
        [
            "crouch",
            "shift",
            "half_step(L)",
            "shift",
            "step(R)",
            "shift",
            "final_half_step(L)",
            "center"
        ]
    );
    assert_eq!(sequence(&plan(7, slow())), expected(7, Side::Left));
}

#[test]
fn right_foot_first_and_rise_at_end() {
    let p = GaitParams {
        first_foot: Side::Right,
        rise_at_end: true,
        ..slow()
    };
    let mut want = expected(3, Side::Right);
    want.push("rise".into());
    assert_eq!(sequence(&plan(3, p)), want);
}

#[test]
fn n_steps_advance_n_step_lengths_and_end_feet_together() {
    let samples = plan(5, slow());
    let planner = planner(slow());
    let step = planner.config().step_length_m;
    let last = samples.last().unwrap();
    let [l, r] = last.ankles_world_m;
    assert!(
        (l.x - 5.0 * step).abs() < 1e-12 && (r.x - 5.0 * step).abs() < 1e-12,
        "feet at {} and {}",
        l.x,
        r.x
    );
    assert_eq!(last.phase, PhaseKind::Center);
    assert_eq!(last.progress, 1.0);
}

#[test]
fn phases_last_their_configured_durations() {
    let p = GaitParams {
        step_duration_s: 0.7,
        shift_duration_s: 0.9,
        crouch_duration_s: 0.5,
        ..slow()
    };
    let samples = plan(2, p);
    // 100 Hz; each phase's ticks are (start, end], the crouch also has its t = 0 tick.
    assert_eq!(phase_ticks(&samples, PhaseKind::Crouch), 51);
    assert_eq!(phase_ticks(&samples, PhaseKind::HalfStep), 70);
    assert_eq!(phase_ticks(&samples, PhaseKind::Step), 70);
    assert_eq!(phase_ticks(&samples, PhaseKind::Shift), 3 * 90);
    assert_eq!(phase_ticks(&samples, PhaseKind::Center), 90);
}

/// Walks until stopped, sends Stop at `stop_at_s`, runs until idle.
fn walk_and_stop(stop_at_s: f64) -> Vec<GaitSample> {
    let mut p = planner(slow());
    p.request(WalkRequest::UntilStop);
    let mut out = Vec::new();
    for k in 0..100_000 {
        let t = k as f64 / 100.0;
        if (t - stop_at_s).abs() < 1e-9 {
            p.request(WalkRequest::Stop);
        }
        let s = p.update(t).unwrap();
        if s.phase == PhaseKind::Idle {
            break;
        }
        out.push(s);
    }
    out
}

#[test]
fn stop_in_every_phase_ends_at_the_next_feet_together_point() {
    // Defaults: 1 s crouch and swings, 2 s shifts. Continuous walk: crouch [0,1], shift (1,3],
    // half_step(L) (3,4], shift (4,6], step(R) (6,7], shift (7,9], step(L) (9,10], ...
    let base = [
        "crouch",
        "shift",
        "half_step(L)",
        "shift",
        "step(R)",
        "shift",
        "step(L)",
    ];
    let closing = |upto: usize, tail: &[&str]| -> Vec<String> {
        base[..upto]
            .iter()
            .chain(tail)
            .map(|s| s.to_string())
            .collect()
    };
    let cases: Vec<(f64, Vec<String>)> = vec![
        // In the crouch: the feet are together already; the crouch finishes and the walk ends.
        (0.5, closing(1, &[])),
        // In the first shift: no foot has left; the CoM comes back to the middle.
        (2.0, closing(2, &["center"])),
        // In the half step: the foot lands first, then the trailing foot comes level.
        (3.5, closing(3, &["shift", "final_half_step(R)", "center"])),
        // In the diagonal shift: it finishes, then the final half step instead of a step.
        (5.0, closing(4, &["final_half_step(R)", "center"])),
        // In a full step (right foot in the air): it lands first.
        (6.5, closing(5, &["shift", "final_half_step(L)", "center"])),
        (8.0, closing(6, &["final_half_step(L)", "center"])),
        (9.5, closing(7, &["shift", "final_half_step(R)", "center"])),
    ];
    for (t, want) in cases {
        let samples = walk_and_stop(t);
        assert_eq!(sequence(&samples), want, "stop at t = {t}");
        // Never mid-air: every swing that started ran its full 100 ticks.
        for kind in [
            PhaseKind::HalfStep,
            PhaseKind::Step,
            PhaseKind::FinalHalfStep,
        ] {
            assert_eq!(
                phase_ticks(&samples, kind) % 100,
                0,
                "stop at t = {t}: a {kind} was cut short"
            );
        }
        let last = samples.last().unwrap();
        assert!(
            (last.ankles_world_m[0].x - last.ankles_world_m[1].x).abs() < 1e-12,
            "stop at t = {t}: feet not level"
        );
    }
}

#[test]
fn stop_in_the_closing_phases_changes_nothing() {
    let full = plan(1, slow());
    // One step: crouch [0,1], shift (1,3], half_step (3,4], shift (4,6], final_half_step
    // (6,7], center (7,9].
    for stop_at in [6.5, 8.0] {
        let mut p = planner(slow());
        p.request(WalkRequest::Steps(1));
        let mut out = Vec::new();
        for k in 0..10_000 {
            let t = k as f64 / 100.0;
            if (t - stop_at).abs() < 1e-9 {
                p.request(WalkRequest::Stop);
            }
            let s = p.update(t).unwrap();
            if s.phase == PhaseKind::Idle {
                break;
            }
            out.push(s);
        }
        assert_eq!(out, full, "stop at {stop_at}");
    }
}

#[test]
fn a_new_step_count_during_a_walk_counts_from_the_next_swing() {
    let mut p = planner(slow());
    p.request(WalkRequest::Steps(2));
    let mut out = Vec::new();
    for k in 0..100_000 {
        let t = k as f64 / 100.0;
        if k == 350 {
            // During the half step (3 s to 4 s): 3 more swings after it.
            p.request(WalkRequest::Steps(3));
        }
        let s = p.update(t).unwrap();
        if s.phase == PhaseKind::Idle {
            break;
        }
        out.push(s);
    }
    assert_eq!(sequence(&out), expected(4, Side::Left));
}

#[test]
fn idle_planner_holds_still_and_a_later_walk_starts_without_a_second_crouch() {
    let mut p = planner(slow());
    let a = p.update(0.0).unwrap();
    let b = p.update(5.0).unwrap();
    assert_eq!(a.phase, PhaseKind::Idle);
    assert_eq!(a.joints_rad, b.joints_rad);
    let first = p.plan(WalkRequest::Steps(1)).unwrap();
    assert_eq!(first[0].phase, PhaseKind::Crouch);
    let second = p.plan(WalkRequest::Steps(1)).unwrap();
    assert_eq!(second[0].phase, PhaseKind::Shift, "already crouched");
    // The second walk starts where the first ended.
    let (e, s) = (first.last().unwrap(), &second[0]);
    assert!((e.base_world.translation.vector - s.base_world.translation.vector).norm() < 1e-6);
}

#[test]
fn time_going_backwards_or_nan_is_refused() {
    let mut p = planner(slow());
    p.update(1.0).unwrap();
    assert!(matches!(
        p.update(0.5),
        Err(gait_planner::GaitError::Time { .. })
    ));
    assert!(matches!(
        p.update(f64::NAN),
        Err(gait_planner::GaitError::Time { .. })
    ));
    assert!(p.update(1.0).is_ok());
}

#[test]
fn a_walk_started_at_any_tick_has_the_ticks_of_the_offline_plan() {
    // The node starts walks at whatever tick the command arrives, t0 = k0 / rate; rounding in
    // t0 + duration must not move a boundary tick into the next phase.
    let offline: Vec<(PhaseKind, u32)> = plan(2, slow())
        .iter()
        .map(|s| (s.phase, s.step_index))
        .collect();
    for k0 in (1..400).step_by(7).chain([357, 1234, 98_765]) {
        let mut p = planner(slow());
        for k in 0..k0 {
            p.update(k as f64 / 100.0).unwrap();
        }
        p.request(WalkRequest::Steps(2));
        let mut live = Vec::new();
        for k in k0.. {
            let s = p.update(k as f64 / 100.0).unwrap();
            if s.phase == PhaseKind::Idle {
                break;
            }
            live.push((s.phase, s.step_index));
        }
        assert_eq!(live, offline, "walk started at tick {k0}");
    }
}
