//! `report.json`: the measures of a recorded walk.
//!
//! Each tick from the walk's first phase to the end of the recording is one
//! [`walk_eval::Observation`], built from the recorded topics alone: the base pose
//! (`sim/base_pose`), the measured joints (`joint_states`) through the URDF's forward
//! kinematics for the feet, the centre of pressure (`sim/cop`) against the support polygon
//! of the loaded soles (`sim/support_polygon`). A foot stands when its sole centre lies
//! inside that polygon. [`walk_eval::WalkMonitor`] turns them into the measures.

use std::collections::BTreeMap;

use anyhow::Context;
use biped_msgs::msg::JointState;
use gait_planner::{GaitPlanner, GaitSample, PhaseKind};
use ik_solver::support::signed_margin;
use ik_solver::{BipedModel, LegOdometry, Side};
use nalgebra::Isometry3;
use serde::Serialize;
use walk_eval::{Observation, WalkMonitor, WalkReport};

use super::WalkOptions;
use super::record::Recording;

/// What `biped walk` writes to `report.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WalkSummary {
    /// The robot's URDF name.
    pub robot: String,
    /// Steps commanded.
    pub steps: u32,
    /// Step length (m): the configured forward step.
    pub step_length_m: f64,
    /// The stride walked, per step (m): forward (negative: back) ...
    pub stride_forward_m: f64,
    /// ... and to the left (negative: right), from `--twist` or the full step ahead.
    pub stride_left_m: f64,
    /// Simulated time of the walk's first tick (s).
    pub walk_started_s: f64,
    /// From the walk's first tick to the planner's idle again (s).
    pub walk_duration_s: f64,
    /// Distance over walk duration (m/s).
    pub speed_m_s: f64,
    /// The measures (distance, fall, tilt, heading, slip, centre of pressure).
    #[serde(flatten)]
    pub measured: WalkReport,
    /// Leg odometry of the measured joints (ik_solver's, as the gait_planner node computes
    /// it, with the plan's planted foot), started at the true base pose: how far its final
    /// base is from the true one, on the floor (m) ...
    pub odometry_error_m: f64,
    /// ... and in heading (deg).
    pub odometry_yaw_error_deg: f64,
    /// Smallest margin of the planned CoM to the planned support polygon (m).
    pub planned_min_com_margin_m: f64,
    /// The margin the planner was asked to keep (m).
    pub required_com_margin_m: f64,
    /// Smallest margin of the planned (cart-table) ZMP to the planned support polygon (m);
    /// per phase in `min_cop_margin_per_phase`, beside the measured CoP's.
    pub planned_min_zmp_margin_m: f64,
    /// The ZMP margin the planner was asked to keep (m).
    pub required_zmp_margin_m: f64,
    /// Largest difference between a measured leg joint and the command of the same tick
    /// during the walk (rad): the servos' lag and sag after compensation.
    pub max_joint_tracking_error_rad: f64,
    /// The joint where it happened.
    pub max_joint_tracking_error_joint: String,
    /// Simulated time recorded (s).
    pub simulated_s: f64,
    /// Wall-clock time of the run, start-up included (s).
    pub wall_s: f64,
    /// Simulated seconds per wall-clock second, from the first `/clock` to the end.
    pub real_time_factor: f64,
    /// What one tick cost the machine, averaged from the first `/clock` to the end: CPU
    /// time and context switches of every process of the run (the nodes,
    /// robot_state_publisher and `biped walk` with its recorder), and UDP datagrams sent in
    /// the network namespace; `null` where `/proc` cannot tell.
    pub work_per_tick: Option<super::work::TickWork>,
    /// Messages that could not be decoded, by topic.
    pub unreadable_messages: BTreeMap<String, u64>,
    /// Stop anywhere, measured: one entry per `--estop-at` e-stop or `--pause-at` pause.
    pub stops: Vec<StopMeasure>,
    /// Over the stops, the most a sole carrying the robot at the call lifted or slid
    /// during the measured hold (m); `null` without stops.
    pub stop_anywhere_worst_sole_m: Option<f64>,
    /// Over the stops, the most a sole carrying the robot at the call moved from 0.5 s
    /// after the call to the end of the measured hold (m): at rest once stopped, or not;
    /// `null` without stops.
    pub stop_anywhere_worst_sole_late_m: Option<f64>,
    /// Over the stops, the most the base moved from 0.5 s after the call to the end of
    /// the measured hold (m): still or not; `null` without stops.
    pub stop_anywhere_worst_base_late_m: Option<f64>,
}

/// The part of each stop's hold that is measured, from the call (s).
pub const ESTOP_WINDOW_S: f64 = 2.0;

/// Which stop a walk is stopped with, anywhere.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StopKind {
    /// The joint bridge's `~/estop` (the joints brake at their limits and hold), released
    /// by `~/reset`.
    Estop,
    /// The gait planner's `~/pause` (the walk's clock slows to a stop along the plan),
    /// released by `~/pause` false.
    Pause,
}

/// What one stop did to the standing robot, from the call over [`ESTOP_WINDOW_S`]:
/// ground truth (base pose) and forward kinematics of the measured joints.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StopMeasure {
    /// Which stop.
    pub kind: StopKind,
    /// When `~/estop` was called, from the walk's start (s of simulated time less the
    /// earlier holds, from call to reset: the walk's own time, which stands still while held).
    pub t_s: f64,
    /// Simulated time from the call to its answer (s): the stop lands within it. 0 in a
    /// `biped walk` (its simulator holds simulated time while a call is out).
    pub answer_delay_s: f64,
    /// The planner's phase at the call.
    pub phase: PhaseKind,
    /// Which soles carried the robot at the call, `[left, right]`: those whose centre lies
    /// in the support polygon of the soles carrying more than 1 % of the weight.
    pub loaded: [bool; 2],
    /// Largest rise of a bottom corner of each sole (m).
    pub lift_m: [f64; 2],
    /// Largest horizontal drift of the centre of each sole's bottom face (m).
    pub slide_m: [f64; 2],
    /// How far each sole moved from 0.5 s after the call to the end of the window (m):
    /// the largest corner rise or centre drift from where it was at 0.5 s (at rest or not,
    /// once the stop's own motion is over).
    pub sole_late_m: [f64; 2],
    /// How far the base moved in the first 0.5 s (m): the braking ...
    pub base_early_m: f64,
    /// ... and from 0.5 s to the end of the window (m): at rest or not.
    pub base_late_m: f64,
}

const MEASURED_FK: &str = "forward kinematics of the measured joints";

/// The link poses of a recorded tick: base pose and measured joints.
fn measured_poses(
    model: &BipedModel,
    base: &Isometry3<f64>,
    js: &JointState,
) -> anyhow::Result<Vec<Isometry3<f64>>> {
    let q = joints_in_model_order(model, &js.name, &js.position)?;
    model.robot().link_poses(base, &q).context(MEASURED_FK)
}

/// The bottom corners of both soles, `[left, right]` (m).
type SoleCorners = [[nalgebra::Point3<f64>; 4]; 2];

/// How far a sole moved from `from` to `to` (its bottom corners): the largest corner rise
/// and the horizontal drift of its centre (m).
fn sole_motion(from: &[nalgebra::Point3<f64>; 4], to: &[nalgebra::Point3<f64>; 4]) -> (f64, f64) {
    let (mut rise, mut dx, mut dy) = (f64::NEG_INFINITY, 0.0, 0.0);
    for (a, b) in from.iter().zip(to) {
        rise = rise.max(b.z - a.z);
        dx += (b.x - a.x) / 4.0;
        dy += (b.y - a.y) / 4.0;
    }
    (rise, f64::hypot(dx, dy))
}

/// The measures of each stop of the recording.
fn stop_measures(
    model: &BipedModel,
    rec: &Recording,
    start_ns: i64,
    kind: StopKind,
) -> anyhow::Result<Vec<StopMeasure>> {
    let mut out = Vec::new();
    let mut held_ns = 0i64;
    for e in &rec.stops {
        let window_ns = (ESTOP_WINDOW_S * 1e9).round() as i64;
        let ticks: Vec<(i64, &JointState)> = rec
            .states
            .range(e.requested_ns..=e.requested_ns + window_ns)
            .map(|(&t, js)| (t, js))
            .collect();
        let Some(&(t0, _)) = ticks.first() else {
            continue;
        };
        // Both soles' bottom corners and the base position at the call.
        let mut first: Option<(SoleCorners, nalgebra::Vector3<f64>)> = None;
        let (mut lift_m, mut slide_m) = ([0.0f64; 2], [0.0f64; 2]);
        let (mut base_early_m, mut base_late_m) = (0.0f64, 0.0f64);
        let mut base_half: Option<nalgebra::Vector3<f64>> = None;
        let mut soles_half: Option<SoleCorners> = None;
        let mut sole_late_m = [0.0f64; 2];
        let mut loaded = [false; 2];
        for (t, js) in &ticks {
            let Some(base) = rec.base.get(t) else {
                continue;
            };
            let poses = measured_poses(model, base, js)?;
            let soles = Side::BOTH.map(|s| model.sole_corners_world(&poses, s));
            let b = base.translation.vector;
            let Some((soles0, b0)) = &first else {
                let poly = rec.support.get(t).filter(|p| !p.is_empty());
                loaded = Side::BOTH.map(|s| {
                    let c = model.sole_centre_world(&poses, s);
                    poly.is_some_and(|poly| signed_margin(poly, [c.x, c.y]) > 0.0)
                });
                first = Some((soles, b));
                continue;
            };
            for k in 0..2 {
                let (rise, drift) = sole_motion(&soles0[k], &soles[k]);
                lift_m[k] = lift_m[k].max(rise);
                slide_m[k] = slide_m[k].max(drift);
            }
            if *t - t0 <= 500_000_000 {
                base_early_m = base_early_m.max((b - b0).norm());
            } else {
                let h = *base_half.get_or_insert(b);
                base_late_m = base_late_m.max((b - h).norm());
                let half = soles_half.get_or_insert(soles);
                for k in 0..2 {
                    let (rise, drift) = sole_motion(&half[k], &soles[k]);
                    sole_late_m[k] = sole_late_m[k].max(rise.max(drift));
                }
            }
        }
        let phase = rec
            .phases()
            .range(..=t0)
            .next_back()
            .map_or(PhaseKind::Idle, |(_, p)| p.kind);
        out.push(StopMeasure {
            kind,
            t_s: (e.requested_ns - start_ns - held_ns) as f64 * 1e-9,
            answer_delay_s: e
                .answered_ns
                .map_or(f64::NAN, |a| (a - e.requested_ns) as f64 * 1e-9),
            phase,
            loaded,
            lift_m,
            slide_m,
            sole_late_m,
            base_early_m,
            base_late_m,
        });
        if let Some(r) = e.reset_ns {
            held_ns += r - e.requested_ns;
        }
    }
    Ok(out)
}

/// The measured joint vector of a `joint_states` message, in the model's dof order.
pub fn joints_in_model_order(
    model: &BipedModel,
    names: &[String],
    positions: &[f64],
) -> anyhow::Result<Vec<f64>> {
    let by_name: BTreeMap<&str, f64> = names
        .iter()
        .map(String::as_str)
        .zip(positions.iter().copied())
        .collect();
    model
        .robot()
        .dof_names()
        .map(|n| {
            by_name
                .get(n)
                .copied()
                .with_context(|| format!("joint_states lacks joint `{n}`"))
        })
        .collect()
}

/// What a run cost: its wall-clock times (s) and, over the stepping span, its work per tick.
#[derive(Debug, Clone, PartialEq)]
pub struct WallTimes {
    /// From `biped walk`'s start to the end of recording.
    pub total_s: f64,
    /// From the first `/clock` to the end of recording: the simulation's own time.
    pub stepping_s: f64,
    /// The messaging work of a tick over the same span; `None` where it cannot be read.
    pub work_per_tick: Option<super::work::TickWork>,
}

/// The measures of the recorded walk.
pub fn summarize(
    model: &BipedModel,
    planner: &GaitPlanner,
    plan: &[GaitSample],
    rec: &Recording,
    o: &WalkOptions,
    wall: WallTimes,
) -> anyhow::Result<WalkSummary> {
    let start_ns = rec
        .walk_start_ns()
        .context("the planner never started the walk (no phase other than idle on gait/phase)")?;
    let end_ns = rec.walk_end_ns();
    let phase_at = |t: i64| {
        rec.phases()
            .range(..=t)
            .next_back()
            .map_or(PhaseKind::Idle, |(_, p)| p.kind)
    };
    let mut monitor: Option<WalkMonitor> = None;
    let mut odometry: Option<LegOdometry> = None;
    let dt_ns = 1e9 / planner.config().control_rate_hz;
    let planted_at = |t: i64| {
        let k = ((t - start_ns) as f64 / dt_ns).round().max(0.0) as usize;
        plan.get(k.min(plan.len().saturating_sub(1)))
            .map_or(Side::Left, |s| s.planted)
    };
    let mut last: Option<(f64, Isometry3<f64>)> = None;
    let (mut worst_err, mut worst_joint) = (0.0f64, String::new());
    let stop_ns = rec.end_ns(o.tail_s).unwrap_or(i64::MAX);
    // The last tick observed, and how many were not (a tick without its joint states or
    // base pose): the slip is not measured across them.
    let (mut last_seen_ns, mut missed_ticks): (Option<i64>, u64) = (None, 0);
    for (&t, js) in rec.states.range(start_ns..=stop_ns) {
        let Some(base) = rec.base.get(&t) else {
            continue;
        };
        if let Some(prev) = last_seen_ns.replace(t) {
            let gap = ((t - prev) as f64 / dt_ns).round() as u64;
            if gap > 1 {
                missed_ticks += gap - 1;
                if let Some(m) = &mut monitor {
                    m.missed();
                }
            }
        }
        let q = joints_in_model_order(model, &js.name, &js.position)?;
        let poses = model.robot().link_poses(base, &q).context(MEASURED_FK)?;
        let poly = rec.support.get(&t).filter(|p| !p.is_empty());
        let inside = |p: [f64; 2]| poly.is_some_and(|poly| signed_margin(poly, p) > 0.0);
        let feet = Side::BOTH.map(|s| {
            let f = poses[model.leg(s).foot_link].translation.vector;
            [f.x, f.y]
        });
        let standing = Side::BOTH.map(|s| {
            let c = model.sole_centre_world(&poses, s);
            inside([c.x, c.y])
        });
        let t_s = t as f64 * 1e-9;
        let obs = Observation {
            t_s,
            base: *base,
            cop_margin_m: match (rec.cop.get(&t), poly) {
                (Some(&c), Some(poly)) => Some(signed_margin(poly, c)),
                _ => None,
            },
            feet_xy_m: feet,
            standing,
            fall: rec
                .fall
                .as_ref()
                .filter(|(tf, _)| *tf <= t)
                .map(|(tf, why)| (*tf as f64 * 1e-9, why.clone())),
        };
        monitor
            .get_or_insert_with(|| WalkMonitor::starting_at(t_s, *base))
            .observe_state(&obs, phase_at(t));
        match &mut odometry {
            None => {
                odometry = Some(
                    LegOdometry::new(model, *base, &q, planted_at(t))
                        .context("leg odometry of the measured joints")?,
                );
            }
            Some(odo) => {
                odo.update(model, &q, planted_at(t))
                    .context("leg odometry of the measured joints")?;
            }
        }
        last = Some((t_s, *base));
        // Tracking: during the walk, measured against the command of the same tick.
        if end_ns.is_none_or(|e| t < e)
            && let Some(cmd) = rec.commands.get(&t)
        {
            for (name, commanded) in cmd {
                if let Some(i) = js.name.iter().position(|n| n == name)
                    && let Some(measured) = js.position.get(i)
                {
                    let err = (measured - commanded).abs();
                    if err > worst_err {
                        worst_err = err;
                        worst_joint = name.clone();
                    }
                }
            }
        }
    }
    let (Some(monitor), Some((t_end, base_end))) = (monitor, last) else {
        anyhow::bail!("no joint_states and base pose were recorded during the walk");
    };
    if missed_ticks > 0 {
        eprintln!(
            "biped walk: {missed_ticks} ticks of the walk came without their joint states or \
             base pose; the report measures the others (no slip across a gap)"
        );
    }
    let c = planner.config();
    // Where the plan puts the feet: the midpoint between them, first tick to last (the
    // plan's world frame faces the walk's starting heading).
    let feet_mid = |s: &GaitSample| (s.ankles_world_m[0].coords + s.ankles_world_m[1].coords) / 2.0;
    let planned_m = match (plan.first(), plan.last()) {
        (Some(a), Some(b)) => {
            let d = feet_mid(b) - feet_mid(a);
            [d.x, d.y]
        }
        _ => [0.0, 0.0],
    };
    let measured = monitor
        .report_at(t_end, &base_end, planned_m)
        .with_planned_zmp(plan);
    let (odometry_error_m, odometry_yaw_error_deg) = match &odometry {
        Some(odo) => {
            let e = odo.base().translation.vector - base_end.translation.vector;
            let dyaw = walk_eval::heading_change_rad(&base_end, odo.base());
            (e.xy().norm(), dyaw.abs().to_degrees())
        }
        None => (f64::NAN, f64::NAN),
    };
    let walk_duration_s = end_ns.map_or(t_end, |e| e as f64 * 1e-9) - start_ns as f64 * 1e-9;
    let stops = stop_measures(model, rec, start_ns, o.stop_kind())?;
    let simulated_s = rec.clock_ns.min(stop_ns) as f64 * 1e-9;
    Ok(WalkSummary {
        robot: model.robot().name().to_owned(),
        steps: o.steps,
        step_length_m: c.step_length_m,
        stride_forward_m: planner.stride().forward_m,
        stride_left_m: planner.stride().left_m,
        walk_started_s: start_ns as f64 * 1e-9,
        walk_duration_s,
        speed_m_s: if walk_duration_s > 0.0 {
            measured.distance_m / walk_duration_s
        } else {
            0.0
        },
        odometry_error_m,
        odometry_yaw_error_deg,
        planned_min_com_margin_m: plan
            .iter()
            .map(|s| s.margin_m)
            .fold(f64::INFINITY, f64::min),
        required_com_margin_m: c.min_com_margin_m,
        planned_min_zmp_margin_m: plan
            .iter()
            .map(|s| s.zmp_margin_m)
            .fold(f64::INFINITY, f64::min),
        required_zmp_margin_m: c.min_zmp_margin_m,
        measured,
        max_joint_tracking_error_rad: worst_err,
        max_joint_tracking_error_joint: worst_joint,
        simulated_s,
        wall_s: wall.total_s,
        real_time_factor: if wall.stepping_s > 0.0 {
            simulated_s / wall.stepping_s
        } else {
            0.0
        },
        work_per_tick: wall.work_per_tick,
        unreadable_messages: rec
            .unreadable
            .iter()
            .map(|(k, v)| ((*k).to_owned(), *v))
            .collect(),
        stop_anywhere_worst_sole_m: stops
            .iter()
            .flat_map(|e| {
                (0..2)
                    .filter(|&k| e.loaded[k])
                    .map(|k| e.lift_m[k].max(e.slide_m[k]))
            })
            .reduce(f64::max),
        stop_anywhere_worst_sole_late_m: stops
            .iter()
            .flat_map(|e| (0..2).filter(|&k| e.loaded[k]).map(|k| e.sole_late_m[k]))
            .reduce(f64::max),
        stop_anywhere_worst_base_late_m: stops.iter().map(|e| e.base_late_m).reduce(f64::max),
        stops,
    })
}
