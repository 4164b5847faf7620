//! The planned ZMP (cart-table model): hand-computed peaks, agreement with the second
//! difference of the planned CoM path computed here, and walks whose ZMP leaves the
//! support polygon refused by phase and tick.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::*;
use gait_planner::{GaitError, GaitParams, GaitPlanner, PhaseKind};

const G: f64 = 9.80665;

/// The first shift moves the CoM sideways by D with the min-jerk profile over T: its
/// acceleration peaks at 10/√3 · D/T², so the ZMP runs ahead of or behind the CoM by
/// z/g · 10/√3 · D/T² (z the CoM height) and meets it again at the ends and the middle.
#[test]
fn the_first_shift_moves_the_zmp_off_the_com_by_the_min_jerk_peak() {
    let shift_s = 1.2;
    let samples = plan(
        1,
        GaitParams {
            shift_duration_s: shift_s,
            ..slow()
        },
    );
    let shift: Vec<_> = samples
        .iter()
        .skip_while(|s| s.phase != PhaseKind::Shift)
        .take_while(|s| s.phase == PhaseKind::Shift)
        .collect();
    assert_eq!(shift.len(), 120);
    let (first, last) = (shift[0], shift[shift.len() - 1]);
    let d_m = (last.com_world_m.y - first.com_world_m.y).abs();
    assert!(d_m > 0.02, "the shift moves the CoM {d_m} m");
    let z_m = first.com_world_m.z;
    let expected_m = z_m / G * 10.0 / 3f64.sqrt() * d_m / (shift_s * shift_s);
    let offsets: Vec<f64> = shift
        .iter()
        .map(|s| s.zmp_xy_m[1] - s.com_world_m.y)
        .collect();
    let peak = offsets.iter().fold(0.0f64, |m, o| m.max(o.abs()));
    // Ticks every 10 ms miss the exact peak by at most (0.01/1.2)² of the curvature there.
    assert!(
        (peak - expected_m).abs() < 0.01 * expected_m,
        "peak ZMP offset {peak} m, expected {expected_m} m"
    );
    // At rest at the ends: the ZMP is the CoM.
    assert!(offsets[offsets.len() - 1].abs() < 1e-12);
    // The CoM accelerates towards the stance foot first (ZMP behind it: outside of the
    // other foot), then brakes (ZMP beyond it: towards the stance sole's outer edge).
    let towards = (last.com_world_m.y - first.com_world_m.y).signum();
    assert!(offsets[20] * towards < 0.0 && offsets[100] * towards > 0.0);
}

/// The reported ZMP against the ZMP of the planned CoM path differentiated here (central
/// second differences, 1 kHz): within 0.1 mm at every tick away from the phase ends (where
/// the profile's jerk jumps and a difference across the boundary is wrong, not the plan).
#[test]
fn the_reported_zmp_is_the_cart_table_zmp_of_the_planned_com_path() {
    let params = GaitParams {
        control_rate_hz: 1000.0,
        shift_duration_s: 1.0,
        step_duration_s: 0.6,
        ..slow()
    };
    let s = plan(2, params);
    let dt = 1e-3;
    let mut worst = (0.0f64, 0.0, PhaseKind::Idle);
    let mut checked = 0;
    for k in 2..s.len() - 2 {
        let same_phase = s[k - 2..=k + 2]
            .iter()
            .all(|x| x.phase == s[k].phase && x.step_index == s[k].step_index);
        if !same_phase || s[k].phase == PhaseKind::Crouch {
            continue;
        }
        let (a, b, c) = (s[k - 1].com_world_m, s[k].com_world_m, s[k + 1].com_world_m);
        let acc = (a.coords - 2.0 * b.coords + c.coords) / (dt * dt);
        let scale = b.z / (G + acc.z);
        let zmp = [b.x - scale * acc.x, b.y - scale * acc.y];
        let err = (zmp[0] - s[k].zmp_xy_m[0]).hypot(zmp[1] - s[k].zmp_xy_m[1]);
        checked += 1;
        if err > worst.0 {
            worst = (err, s[k].t_s, s[k].phase);
        }
    }
    assert!(checked > 4000, "{checked} ticks checked");
    assert!(
        worst.0 < 1e-4,
        "ZMP off by {} m at t = {} s ({})",
        worst.0,
        worst.1,
        worst.2
    );
}

/// The crouch is driven by the pelvis, not the CoM: its reported ZMP is still that of
/// the planned CoM path (second differences over the control period, as the targets
/// change), the first tick too, where the knees start forward from straight legs.
#[test]
fn the_crouch_zmp_is_that_of_the_planned_com_path() {
    let s = plan(1, slow());
    let dt = 0.01;
    let crouch: Vec<_> = s.iter().filter(|x| x.phase == PhaseKind::Crouch).collect();
    assert_eq!(crouch.len(), 101);
    let mut worst = 0.0f64;
    let mut peak = 0.0f64;
    for k in 1..crouch.len() - 1 {
        let (a, b, c) = (
            crouch[k - 1].com_world_m,
            crouch[k].com_world_m,
            crouch[k + 1].com_world_m,
        );
        let acc = (a.coords - 2.0 * b.coords + c.coords) / (dt * dt);
        let scale = b.z / (G + acc.z);
        let zmp_x = b.x - scale * acc.x;
        worst = worst.max((zmp_x - crouch[k].zmp_xy_m[0]).abs());
        peak = peak.max((crouch[k].zmp_xy_m[0] - b.x).abs());
    }
    assert!(worst < 1e-9, "crouch ZMP off by {worst} m");
    // The knees move the CoM forward as they bend: the ZMP is off the CoM.
    assert!(peak > 1e-4, "ZMP never leaves the CoM: {peak} m");
}

/// Shifts of 0.5 s accelerate the CoM so hard that the ZMP passes the support polygon's
/// edge margin although the CoM never does: refused naming the phase and the tick. The
/// same walk with the ZMP margin at 0 (still inside) but the CoM margin kept is accepted
/// as long as the ZMP stays inside at all.
#[test]
fn a_shift_too_fast_for_the_zmp_is_refused_naming_phase_and_tick() {
    let fast = GaitParams {
        shift_duration_s: 0.5,
        step_duration_s: 0.45,
        ..slow()
    };
    let err = GaitPlanner::new(default_model(), fast.clone()).unwrap_err();
    match &err {
        GaitError::ZmpOutside {
            phase,
            t_s,
            margin_m,
            min_m,
            accel_m_s2,
            ..
        } => {
            assert_eq!(*phase, PhaseKind::Shift);
            // Crouch 1 s, shift 0.5 s, half step 0.45 s: the diagonal shift from 1.95 s.
            assert!(*t_s > 1.95 && *t_s < 2.45, "t = {t_s}");
            assert_eq!(*min_m, 0.01);
            assert!(*margin_m < 0.01, "{margin_m}");
            assert!(*accel_m_s2 > 0.5, "{accel_m_s2}");
        }
        other => panic!("wanted ZmpOutside, got {other:?}"),
    }
    let msg = err.to_string();
    assert!(
        msg.contains("`shift`") && msg.contains("ZMP margin"),
        "{msg}"
    );
    // Twice as long, a quarter of the acceleration: accepted.
    let slower = GaitParams {
        shift_duration_s: 1.0,
        ..fast
    };
    let samples = plan(3, slower);
    let min = samples
        .iter()
        .map(|s| s.zmp_margin_m)
        .fold(f64::INFINITY, f64::min);
    assert!(min >= 0.01, "{min}");
}
