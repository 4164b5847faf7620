//! The shortest phase durations a robot's walk allows, found by time scaling.
//!
//! Every phase follows a fixed path in joint space at a pace set by one profile over its
//! duration T: slowing or speeding a phase scales every joint speed by 1/T and the CoM's
//! acceleration, hence the ZMP's distance from the CoM (`crate::zmp`), by 1/T². One
//! reference walk at known durations therefore gives, per phase kind, the shortest
//! duration at which
//! - no joint is faster than its URDF velocity limit: `T ≥ T_ref · max(v / v_limit)`;
//! - the ZMP keeps `min_zmp_margin_m` from every edge of the support polygon: with the
//!   CoM's floor point c and the ZMP's offset e at T_ref, the ZMP at T is `c + s·e` with
//!   `s = (T_ref / T)²`, each edge's distance is linear in s, and `T ≥ T_ref / √s_max`.
//!
//! - with a servo model (`servo_damping_nm_s_per_rad` b, `servo_armature_kg_m2` J), each
//!   joint's torque stays within its URDF effort: the static torque of the pose (the
//!   statics of the sag compensation) plus `b·|q'|·σ + J·|q''|·σ²` with `σ = T_ref / T`.
//!   Link inertia is left out (the rotor's, through the gearbox, dominates a hobby servo).
//!
//! The durations found are rounded up to whole control periods and then verified by the
//! planner's full check walks (every stride the robot is allowed: back, side, turn, at the
//! step limits the reference walk settled: a faster timing never lowers them); a phase
//! kind whose check still fails is lengthened by 5 % until all pass. The crouch, which
//! starts from straight legs where the scaling is not exact, is then bisected against the
//! checks. The search costs one reference walk per check stride and a handful of checked
//! planners.

use ik_solver::support::Xy;

use crate::error::GaitError;
use crate::params::GaitParams;
use crate::phase::PhaseKind;
use crate::planner::{GaitPlanner, GaitSample, joint_speeds};
use ik_solver::BipedModel;

/// The three durations of a walk (s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Timing {
    /// Each CoM shift and the final centring.
    pub shift_duration_s: f64,
    /// Each swing.
    pub step_duration_s: f64,
    /// The crouch and the rise.
    pub crouch_duration_s: f64,
}

/// What limits one duration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Bound {
    /// A joint's velocity limit.
    JointSpeed,
    /// The ZMP margin.
    Zmp,
    /// A joint's torque budget: static torque, servo damping and rotor inertia within its
    /// URDF effort limit (with `servo_damping_nm_s_per_rad`, `servo_armature_kg_m2`).
    Torque,
    /// Pausing anywhere ([`crate::pause`]) within the brake time allowed keeps the ZMP
    /// margin: the CoM is slow enough to stop that quickly.
    Pause,
    /// The smallest duration a parameter may have (0.1 s), or nothing at all.
    Floor,
    /// The full check walks: after the scaling estimate, or (the crouch) by bisection.
    CheckWalk,
}

/// The fastest timing the checks allow, and what binds each duration.
#[derive(Debug, Clone, PartialEq)]
pub struct FastestTiming {
    /// The durations.
    pub timing: Timing,
    /// What limits the shift, the step and the crouch, in that order.
    pub bound: [Bound; 3],
    /// Planners built to verify (each runs the full check walks).
    pub checks: u32,
    /// The longest a pause may take at this timing, as verified (s); `None` when the
    /// search ignored pausing ([`fastest_timing_with_brake`]).
    pub max_pause_brake_s: Option<f64>,
    /// The parameters verified: the given ones with these durations and with the step
    /// limits the reference walk settled (back, side, turn) set explicitly, so that a
    /// faster timing is never bought by lowering an auto step limit.
    pub params: GaitParams,
}

impl FastestTiming {
    /// The durations and what binds each: `shift 0.780 s (Pause), step 0.580 s
    /// (JointSpeed), crouch 0.310 s (CheckWalk)`.
    pub fn describe(&self) -> String {
        self.describe_only([true; 3])
    }

    /// [`Self::describe`] of the shift, step and crouch where `which` is true.
    pub fn describe_only(&self, which: [bool; 3]) -> String {
        let t = &self.timing;
        let secs = [t.shift_duration_s, t.step_duration_s, t.crouch_duration_s];
        ["shift", "step", "crouch"]
            .iter()
            .enumerate()
            .filter(|(i, _)| which[*i])
            .map(|(i, name)| format!("{name} {:.3} s ({:?})", secs[i], self.bound[i]))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// Smallest duration a parameter may have (s), as [`GaitParams::resolve`] bounds it.
const MIN_DURATION_S: f64 = 0.1;
/// Lengthening of a duration whose check walk still fails.
const BACKOFF: f64 = 1.05;
/// Verification rounds before giving up.
const MAX_CHECKS: u32 = 40;
/// Bisections of the crouch duration (to 1/32 of its estimate, or a control period).
const CROUCH_BISECTIONS: u32 = 5;

/// Which duration a phase kind takes: 0 shift, 1 step, 2 crouch.
fn slot(kind: PhaseKind) -> Option<usize> {
    match kind {
        PhaseKind::Shift | PhaseKind::Center => Some(0),
        PhaseKind::HalfStep | PhaseKind::Step | PhaseKind::FinalHalfStep => Some(1),
        PhaseKind::Crouch | PhaseKind::Rise => Some(2),
        PhaseKind::Idle => None,
    }
}

/// The largest factor s ≥ 0 for which `c + s·e` keeps `min_m` from every edge of the
/// convex, counter-clockwise polygon (infinite when no edge gets closer); 0 when `c`
/// itself does not keep it.
pub fn zmp_scale_limit(poly: &[Xy], c: Xy, e: Xy, min_m: f64) -> f64 {
    // s = σ² of the quadratic bound without its linear term.
    quadratic_scale_limit(poly, c, e, [0.0, 0.0], min_m).powi(2)
}

/// The edges of a convex, counter-clockwise polygon as (unit inward normal `n`, offset
/// `d`): a point `p` is `n·p - d` inside each. Made once per polygon for the many points
/// checked against it.
#[derive(Debug, Clone, PartialEq)]
pub struct Edges(Vec<(Xy, f64)>);

impl Edges {
    /// The edges of `poly` (zero-length ones left out).
    pub fn of(poly: &[Xy]) -> Self {
        Self(
            (0..poly.len())
                .filter_map(|i| {
                    let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
                    let (ux, uy) = (b[0] - a[0], b[1] - a[1]);
                    let len = ux.hypot(uy);
                    (len > 0.0).then(|| {
                        let n = [-uy / len, ux / len];
                        (n, n[0] * a[0] + n[1] * a[1])
                    })
                })
                .collect(),
        )
    }
}

/// The largest factor σ ≥ 0 for which `c + σ²·a + σ·b` keeps `min_m` from every edge of the
/// convex, counter-clockwise polygon for every factor up to σ (infinite when no edge
/// gets closer); 0 when `c` itself does not keep it. With `b = 0` this is the square root
/// of [`zmp_scale_limit`].
pub fn quadratic_scale_limit(poly: &[Xy], c: Xy, a: Xy, b: Xy, min_m: f64) -> f64 {
    quadratic_scale_limit_on(&Edges::of(poly), c, a, b, min_m)
}

/// [`quadratic_scale_limit`] against edges made once.
pub fn quadratic_scale_limit_on(edges: &Edges, c: Xy, a: Xy, b: Xy, min_m: f64) -> f64 {
    let dot = |n: Xy, v: Xy| n[0] * v[0] + n[1] * v[1];
    let mut s_max = f64::INFINITY;
    for &(n, d) in &edges.0 {
        let spare = dot(n, c) - d - min_m;
        if spare < 0.0 {
            return 0.0;
        }
        // The edge is kept while g(σ) = qa σ² + qb σ - spare ≤ 0 (qa, qb: how fast the
        // point approaches the edge); g(0) ≤ 0, so the first positive root, if any.
        let (qa, qb) = (-dot(n, a), -dot(n, b));
        let disc = qb * qb + 4.0 * qa * spare;
        let root = if disc < 0.0 || (qa <= 0.0 && qb <= 0.0) {
            f64::INFINITY
        } else {
            // 2·spare / (qb + √disc), the root (-qb + √disc) / (2·qa) without its
            // cancellation when qa is tiny (a tick at rest, the start of a ramp): that form
            // gave 0 there, an impossible duration.
            let sq = disc.sqrt();
            if qb + sq > 0.0 {
                2.0 * spare / (qb + sq)
            } else {
                // spare = 0, qb < 0 < qa: inside at once, back on the edge at -qb / qa.
                (-qb + sq) / (2.0 * qa)
            }
        };
        s_max = s_max.min(root);
    }
    s_max
}

/// The largest speed-up σ = T_ref / T at which a servo holding `static_nm` with speed
/// `v_rad_s` and acceleration `a_rad_s2` (at T_ref) stays within `effort_nm`:
/// `static + b·v·σ + J·a·σ² ≤ effort`. Infinite without dynamic terms; 0 when the static
/// torque alone exceeds the effort.
pub fn torque_speedup_limit(
    static_nm: f64,
    v_rad_s: f64,
    a_rad_s2: f64,
    damping_nm_s_per_rad: f64,
    armature_kg_m2: f64,
    effort_nm: f64,
) -> f64 {
    let spare = effort_nm - static_nm.abs();
    if spare <= 0.0 {
        return 0.0;
    }
    let (b, j) = (
        damping_nm_s_per_rad * v_rad_s.abs(),
        armature_kg_m2 * a_rad_s2.abs(),
    );
    if j > 0.0 {
        // The positive root of j·σ² + b·σ = spare, as 2·spare / (b + √(b² + 4·j·spare)):
        // (-b + √...) / (2·j) cancels to 0 when j·spare is tiny beside b².
        2.0 * spare / (b + (b * b + 4.0 * j * spare).sqrt())
    } else if b > 0.0 {
        spare / b
    } else {
        f64::INFINITY
    }
}

/// Static joint torques of a planned tick (N·m), dof order.
fn static_torques(planner: &GaitPlanner, s: &GaitSample) -> Option<Vec<f64>> {
    let model = planner.model();
    let poses = model
        .robot()
        .link_poses(&s.base_world, &s.joints_rad)
        .ok()?;
    let weight_n = model.robot().total_mass_kg() * crate::zmp::GRAVITY_M_S2;
    let loads = model.static_foot_loads(&poses, s.com_world_m, s.support.stance(), weight_n);
    Some(model.static_torques_nm(&poses, &loads))
}

/// The shortest durations of each phase kind that the joint speed limits, the ZMP margin
/// and (with a servo model) the torque budget allow, estimated from `samples` (a walk
/// planned with `planner`'s durations).
fn scaled_minimum(
    planner: &GaitPlanner,
    samples: &[GaitSample],
    max_brake_s: Option<f64>,
) -> [(f64, Bound); 3] {
    let c = planner.config();
    let t_ref = [c.shift_duration_s, c.step_duration_s, c.crouch_duration_s];
    let dt = c.dt_s();
    let robot = planner.model().robot();
    let mut speed_ratio = [0.0f64; 3];
    let mut zmp_scale = [f64::INFINITY; 3];
    let mut torque_speedup = [f64::INFINITY; 3];
    let mut pause_speedup = [f64::INFINITY; 3];
    let coms = max_brake_s.map(|_| planner.planned_coms(samples));
    let servo_model = c.servo_damping_nm_s_per_rad > 0.0 || c.servo_armature_kg_m2 > 0.0;
    for (k, s) in samples.iter().enumerate() {
        let Some(i) = slot(s.phase) else { continue };
        // Joint speed and acceleration by central differences within the phase.
        if servo_model
            && k > 0
            && k + 1 < samples.len()
            && samples[k - 1].phase == s.phase
            && samples[k + 1].phase == s.phase
            && let Some(tau) = static_torques(planner, s)
        {
            let (prev, next) = (&samples[k - 1].joints_rad, &samples[k + 1].joints_rad);
            for (d, &t) in tau.iter().enumerate() {
                let j = &robot.joints()[robot.dof_joints()[d]];
                let Some(l) = j.limits.filter(|l| l.effort > 0.0) else {
                    continue;
                };
                let v = (next[d] - prev[d]) / (2.0 * dt);
                let a = (next[d] - 2.0 * s.joints_rad[d] + prev[d]) / (dt * dt);
                torque_speedup[i] = torque_speedup[i].min(torque_speedup_limit(
                    t,
                    v,
                    a,
                    c.servo_damping_nm_s_per_rad,
                    c.servo_armature_kg_m2,
                    l.effort,
                ));
            }
        }
        if k > 0 && samples[k - 1].phase == s.phase {
            for (j, v) in joint_speeds(robot, &samples[k - 1].joints_rad, &s.joints_rad, dt) {
                if let Some(l) = j.limits.filter(|l| l.velocity > 0.0) {
                    speed_ratio[i] = speed_ratio[i].max(v / l.velocity);
                }
            }
        }
        let poly = planner.support_polygon(s.support, &s.ankles_world_m, &s.feet_yaw_rad);
        let com = [s.com_world_m.x, s.com_world_m.y];
        let e = [s.zmp_xy_m[0] - com[0], s.zmp_xy_m[1] - com[1]];
        zmp_scale[i] = zmp_scale[i].min(zmp_scale_limit(&poly, com, e, c.min_zmp_margin_m));
        // A pause braking within `max_brake_s` at time scale σ: the ZMP is
        // c - z/g·(c''·σ²·r² + c'·σ·r'), r' = ∓min_jerk_rate(u)/T_b (crate::pause).
        if let (Some(brake_s), Some(coms)) = (max_brake_s, &coms) {
            let p = &coms[k];
            let kz = p.com_m.z / crate::zmp::GRAVITY_M_S2;
            let edges = Edges::of(&p.polygon);
            for (r, r_rate) in crate::pause::ramp_points() {
                let a = [-kz * p.accel_m_s2.x * r * r, -kz * p.accel_m_s2.y * r * r];
                let b = [
                    -kz * p.velocity_m_s.x * r_rate / brake_s,
                    -kz * p.velocity_m_s.y * r_rate / brake_s,
                ];
                pause_speedup[i] = pause_speedup[i].min(quadratic_scale_limit_on(
                    &edges,
                    com,
                    a,
                    b,
                    c.min_zmp_margin_m,
                ));
            }
        }
    }
    std::array::from_fn(|i| {
        let by_speed = t_ref[i] * speed_ratio[i];
        let by_zmp = if zmp_scale[i] > 0.0 {
            t_ref[i] / zmp_scale[i].sqrt()
        } else {
            f64::INFINITY
        };
        let by_torque = if torque_speedup[i] > 0.0 {
            t_ref[i] / torque_speedup[i]
        } else {
            f64::INFINITY
        };
        let by_pause = if pause_speedup[i] > 0.0 {
            t_ref[i] / pause_speedup[i]
        } else {
            f64::INFINITY
        };
        let (t, bound) = [
            (by_speed, Bound::JointSpeed),
            (by_zmp, Bound::Zmp),
            (by_torque, Bound::Torque),
            (by_pause, Bound::Pause),
        ]
        .into_iter()
        .fold(
            (0.0, Bound::Floor),
            |best, c| if c.0 > best.0 { c } else { best },
        );
        if t <= MIN_DURATION_S {
            (MIN_DURATION_S, Bound::Floor)
        } else {
            // Whole control periods, so the check's ticks fall as the scaling assumed.
            ((t / dt).ceil() * dt, bound)
        }
    })
}

/// The longest a pause may take to bring the walk to rest in the fastest timing, when
/// `pause_brake_time_s` is auto (s): half of the 0.5 s after which a stopped robot must be
/// at rest (#16), the other half for the servos to settle.
pub const PAUSE_BRAKE_BUDGET_S: f64 = 0.25;

/// The fastest timing of the walk of `params` (its step length, lift, margins; its
/// durations are the reference the scaling starts from and must themselves pass the
/// checks) for `model` that can still pause anywhere within `pause_brake_time_s`
/// ([`PAUSE_BRAKE_BUDGET_S`] when auto): see the module documentation.
pub fn fastest_timing(model: &BipedModel, params: &GaitParams) -> Result<FastestTiming, GaitError> {
    let brake_s = if params.pause_brake_time_s > 0.0 {
        params.pause_brake_time_s
    } else {
        PAUSE_BRAKE_BUDGET_S
    };
    fastest_timing_with_brake(model, params, Some(brake_s))
}

/// [`fastest_timing`] with pauses braking within `max_brake_s`, or (`None`) as fast as the
/// other bounds allow, however long a pause then takes: the speed that stopping anywhere
/// costs.
pub fn fastest_timing_with_brake(
    model: &BipedModel,
    params: &GaitParams,
    max_brake_s: Option<f64>,
) -> Result<FastestTiming, GaitError> {
    let reference = GaitPlanner::new(model.clone(), params.clone())?;
    let settled = reference.config();
    let fixed = GaitParams {
        step_length_m: settled.step_length_m,
        back_step_length_m: settled.back_step_length_m,
        side_step_m: settled.side_step_m,
        turn_step_rad: settled.turn_step_rad,
        // Verified with the brake time allowed set by hand: refused if a pause needs more.
        pause_brake_time_s: max_brake_s.unwrap_or(0.0),
        ..params.clone()
    };
    let strides = reference.check_strides();
    // The longest duration any check stride needs (an infinite one stays).
    let mut est = [(0.0, Bound::Floor); 3];
    for stride in strides {
        let samples = reference.plan_stride(stride)?;
        for (i, e) in scaled_minimum(&reference, &samples, max_brake_s)
            .into_iter()
            .enumerate()
        {
            if e.0 > est[i].0 {
                est[i] = e;
            }
        }
    }
    if let Some(i) = est.iter().position(|e| !e.0.is_finite()) {
        let why = match est[i].1 {
            Bound::Torque => "a joint's static torque alone exceeds its URDF effort limit",
            _ => "the CoM itself comes closer than min_zmp_margin_m to the support polygon's edge",
        };
        return Err(GaitError::Request(format!(
            "no {} duration passes the time scaling: {why}",
            ["shift", "step", "crouch"][i]
        )));
    }
    let mut timing = est.map(|e| e.0);
    let mut bound = est.map(|e| e.1);
    let dt = reference.config().dt_s();
    let mut checks = 0;
    let mut verified = loop {
        checks += 1;
        let trial = GaitParams {
            shift_duration_s: timing[0],
            step_duration_s: timing[1],
            crouch_duration_s: timing[2],
            ..fixed.clone()
        };
        match GaitPlanner::new(model.clone(), trial.clone()) {
            Ok(_) => break trial,
            Err(e) if checks < MAX_CHECKS => {
                let i = e.phase().and_then(slot).unwrap_or(0);
                timing[i] = ((timing[i] * BACKOFF) / dt).ceil() * dt;
                bound[i] = Bound::CheckWalk;
            }
            Err(e) => return Err(e),
        }
    };
    // The crouch starts from straight legs, where the knees move like √t: its CoM
    // acceleration grows more slowly than 1/T² as T shrinks, so the scaling estimate is
    // conservative. Bisect it against the checks instead, down to half the estimate.
    if bound[2] != Bound::Floor {
        let (mut lo, mut hi) = ((timing[2] / 2.0).max(MIN_DURATION_S), timing[2]);
        for _ in 0..CROUCH_BISECTIONS {
            let mid = ((lo + hi) / 2.0 / dt).round() * dt;
            if mid <= lo || mid >= hi {
                break;
            }
            checks += 1;
            let trial = GaitParams {
                crouch_duration_s: mid,
                ..verified.clone()
            };
            match GaitPlanner::new(model.clone(), trial.clone()) {
                Ok(_) => {
                    hi = mid;
                    verified = trial;
                    bound[2] = Bound::CheckWalk;
                }
                Err(_) => lo = mid,
            }
        }
        timing[2] = verified.crouch_duration_s;
    }
    // The brake time as given (auto: the shortest, within the budget just verified).
    verified.pause_brake_time_s = params.pause_brake_time_s;
    Ok(FastestTiming {
        timing: Timing {
            shift_duration_s: timing[0],
            step_duration_s: timing[1],
            crouch_duration_s: timing[2],
        },
        bound,
        checks,
        max_pause_brake_s: max_brake_s,
        params: verified,
    })
}

/// Step lengths [`fastest_walk`] tries when `step_length_m` is left at 0, as fractions of
/// the leg (thigh + shin): from the auto default (0.25) to past where the hip pitch joints of
/// small robots run out of range.
pub const WALK_STEP_PER_LEG: [f64; 5] = [0.25, 0.30, 0.35, 0.40, 0.45];
/// Hip heights [`fastest_walk`] tries when `hip_height_m` is left at 0: the hip pitch axis
/// this many legs above the ankle point (0.85 the auto default; lower hips, straighter
/// swings, more knee torque).
pub const WALK_HIP_DROP_PER_LEG: [f64; 3] = [0.85, 0.75, 0.65];

/// Bisections of the step length between the fastest walk of the grid and the next longer
/// step, refused, at the same hip height (to 1/8 of the grid's spacing, in whole mm).
pub const WALK_STEP_BISECTIONS: u32 = 3;

/// One walk [`fastest_walk`] tried.
#[derive(Debug, Clone, PartialEq)]
pub struct WalkTrial {
    /// Its step length (m).
    pub step_length_m: f64,
    /// Its hip height (m).
    pub hip_height_m: f64,
    /// Its planned speed (step length / (shift + step duration), m/s) and durations, or why
    /// the planner refused it.
    pub outcome: Result<(f64, Timing), String>,
}

/// The fastest walk the planning checks allow, and every walk tried.
#[derive(Debug, Clone, PartialEq)]
pub struct FastestWalk {
    /// The parameters of the fastest: the given ones with its step length, hip height and
    /// durations set.
    pub params: GaitParams,
    /// Its planned speed over a long walk: step length / (shift + step duration) (m/s).
    pub speed_m_s: f64,
    /// Every walk tried, in order.
    pub trials: Vec<WalkTrial>,
}

/// The fastest walk of `model` the planning checks allow: for each step length and hip
/// height left at 0 in `params` ([`WALK_STEP_PER_LEG`] x [`WALK_HIP_DROP_PER_LEG`], in whole
/// millimetres; a value
/// set stays the only one tried), the durations left at 0 found by [`fastest_timing`] (set
/// ones stay), kept if the planner accepts the walk; the fastest by planned speed wins
/// (ties: the higher hip, then the shorter step). When the next longer step at the winner's
/// hip height was refused, [`WALK_STEP_BISECTIONS`] bisections between the two find the
/// longest step accepted there (each a trial; the fastest of all wins). Foot lift, margins and brake time are
/// those of `params`: the clearance and the stability asked for. A planning answer, as
/// [`fastest_timing`]'s: whether the robot keeps up is a physics question. Costs one
/// timing search per walk tried (18 at most).
pub fn fastest_walk(model: &BipedModel, params: &GaitParams) -> Result<FastestWalk, GaitError> {
    use crate::params::{hip_height_for, leg_length_m};
    // Lengths tried in whole millimetres: what a parameter file says and a user reads.
    let mm = |v: f64| (v * 1000.0).round() / 1000.0;
    let steps: Vec<f64> = if params.step_length_m == 0.0 {
        let leg = leg_length_m(model);
        WALK_STEP_PER_LEG.iter().map(|r| mm(r * leg)).collect()
    } else {
        vec![params.step_length_m]
    };
    let hips: Vec<f64> = if params.hip_height_m == 0.0 {
        WALK_HIP_DROP_PER_LEG
            .iter()
            .map(|&r| mm(hip_height_for(model, r)))
            .collect()
    } else {
        vec![params.hip_height_m]
    };
    // One walk: accepted (planned speed and durations) or refused (why).
    let try_walk = |step_length_m: f64, hip_height_m: f64| {
        let trial = GaitParams {
            step_length_m,
            hip_height_m,
            ..params.clone()
        };
        let outcome = GaitPlanner::new(model.clone(), trial)
            .map(|planner| {
                let c = planner.config();
                let timing = Timing {
                    shift_duration_s: c.shift_duration_s,
                    step_duration_s: c.step_duration_s,
                    crouch_duration_s: c.crouch_duration_s,
                };
                (c.step_length_m / c.step_period_s(), timing)
            })
            .map_err(|e| e.to_string());
        WalkTrial {
            step_length_m,
            hip_height_m,
            outcome,
        }
    };
    // The fastest accepted so far (the first of equals: the higher hip, the shorter step).
    let fastest = |trials: &[WalkTrial]| {
        trials
            .iter()
            .filter_map(|t| t.outcome.as_ref().ok().map(|(v, d)| (*v, t, *d)))
            .fold(None, |best: Option<(f64, &WalkTrial, Timing)>, x| {
                if best.is_some_and(|b| b.0 >= x.0) {
                    best
                } else {
                    Some(x)
                }
            })
            .map(|(v, t, d)| (v, t.step_length_m, t.hip_height_m, d))
    };
    let mut trials: Vec<WalkTrial> = hips
        .iter()
        .flat_map(|&hip| steps.iter().map(move |&step| (step, hip)))
        .map(|(step, hip)| try_walk(step, hip))
        .collect();
    // The fastest is mostly the longest step its hip height allows: when the next longer
    // step of the grid was refused, bisect between them at that hip height.
    if let Some((_, step, hip, _)) = fastest(&trials)
        && let Some(i) = steps.iter().position(|&v| v == step)
        && let Some(&next) = steps.get(i + 1)
        && trials
            .iter()
            .any(|t| t.step_length_m == next && t.hip_height_m == hip && t.outcome.is_err())
    {
        let (mut lo, mut hi) = (step, next);
        for _ in 0..WALK_STEP_BISECTIONS {
            let mid = mm((lo + hi) / 2.0);
            if mid <= lo || mid >= hi {
                break;
            }
            let t = try_walk(mid, hip);
            if t.outcome.is_ok() {
                lo = mid;
            } else {
                hi = mid;
            }
            trials.push(t);
        }
    }
    match fastest(&trials) {
        Some((speed_m_s, step_length_m, hip_height_m, d)) => Ok(FastestWalk {
            params: GaitParams {
                step_length_m,
                hip_height_m,
                shift_duration_s: d.shift_duration_s,
                step_duration_s: d.step_duration_s,
                crouch_duration_s: d.crouch_duration_s,
                ..params.clone()
            },
            speed_m_s,
            trials,
        }),
        None => Err(GaitError::Request(format!(
            "no walk passes the checks: {}",
            trials
                .iter()
                .map(|t| format!(
                    "step {:.3} m, hip {:.3} m: {}",
                    t.step_length_m,
                    t.hip_height_m,
                    t.outcome.as_ref().err().map_or("", |e| e.as_str())
                ))
                .collect::<Vec<_>>()
                .join("; ")
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SQUARE: [Xy; 4] = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];

    #[test]
    fn the_torque_speedup_limit_solves_the_budget() {
        // 0.5 N·m held, 1.5 N·m servo, damping 0.25 at 2 rad/s: 1 N·m spare, 0.5 N·m per
        // unit of speed-up: twice as fast.
        assert!((torque_speedup_limit(0.5, 2.0, 0.0, 0.25, 0.0, 1.5) - 2.0).abs() < 1e-12);
        // With 0.005 kg·m² at 100 rad/s² (0.5 N·m, growing as σ²): σ = 1 exactly,
        // 0.5 + 0.5 + 0.5 = 1.5.
        assert!((torque_speedup_limit(-0.5, -2.0, 100.0, 0.25, 0.005, 1.5) - 1.0).abs() < 1e-12);
        // No servo model: unlimited; the static torque above the effort: 0.
        assert_eq!(
            torque_speedup_limit(0.5, 2.0, 10.0, 0.0, 0.0, 1.5),
            f64::INFINITY
        );
        assert_eq!(torque_speedup_limit(1.6, 0.0, 0.0, 0.25, 0.0, 1.5), 0.0);
        // A joint barely accelerating: the damping's limit, not 0 by cancellation.
        let s = torque_speedup_limit(0.5, 2.0, 1e-20, 0.25, 0.005, 1.5);
        assert!((s - 2.0).abs() < 1e-9, "{s}");
    }

    #[test]
    fn the_quadratic_scale_limit_is_the_first_root_per_edge() {
        // From the centre, 0.8 of room to the x = 1 edge (margin 0.2): c + σ²·(0.1, 0) +
        // σ·(0.3, 0) meets it at 0.1σ² + 0.3σ = 0.8: σ = (-0.3 + √(0.09 + 0.32)) / 0.2.
        let s = quadratic_scale_limit(&SQUARE, [0.0, 0.0], [0.1, 0.0], [0.3, 0.0], 0.2);
        let want = (-0.3 + (0.09f64 + 0.32).sqrt()) / 0.2;
        assert!((s - want).abs() < 1e-12, "{s} vs {want}");
        // Without the linear term it is √ of the ZMP scale limit.
        let s = quadratic_scale_limit(&SQUARE, [0.1, 0.0], [0.5, 0.25], [0.0, 0.0], 0.0);
        assert!((s - (0.9f64 / 0.5).sqrt()).abs() < 1e-12, "{s}");
        // Pulled back first, then pushed out: -0.4σ + 0.1σ² = 0.8 at σ = 2 + √12, not
        // before (the square term wins only then).
        let s = quadratic_scale_limit(&SQUARE, [0.0, 0.0], [0.1, 0.0], [-0.4, 0.0], 0.2);
        assert!((s - (2.0 + 12f64.sqrt())).abs() < 1e-12, "{s}");
        // Pushed towards x = 1, then pulled back before reaching it (0.5σ - 0.1σ² peaks
        // at 0.625 < 0.8): the far edge binds, reached at 0.1σ² - 0.5σ = 0.8.
        let s = quadratic_scale_limit(&SQUARE, [0.0, 0.0], [-0.1, 0.0], [0.5, 0.0], 0.2);
        assert!((s - (0.5 + 0.57f64.sqrt()) / 0.2).abs() < 1e-12, "{s}");
        // Along an edge: never.
        let s = quadratic_scale_limit(&SQUARE, [0.0, 0.0], [0.0, 0.0], [0.0, 0.0], 0.2);
        assert!(s.is_infinite(), "{s}");
        let s = quadratic_scale_limit(&SQUARE, [0.0, 0.0], [-0.1, 0.0], [1.0, 0.0], 0.2);
        assert!(
            (s - (1.0 - (1.0f64 - 0.32).sqrt()) / 0.2).abs() < 1e-12,
            "{s}"
        );
        // A tiny square term beside the linear one (a tick at rest, the start of a ramp):
        // the linear root, not 0 by cancellation.
        let s = quadratic_scale_limit(&SQUARE, [0.0, 0.0], [1e-25, 0.0], [1e-3, 0.0], 0.2);
        assert!((s - 800.0).abs() < 1e-9, "{s}");
        // The point already short of the margin: 0.
        assert_eq!(
            quadratic_scale_limit(&SQUARE, [0.95, 0.0], [0.0, 0.0], [0.0, 0.0], 0.1),
            0.0
        );
    }

    #[test]
    fn the_zmp_scale_limit_is_where_the_offset_meets_the_margin() {
        // From the centre, 1 to the edge; margin 0.2 leaves 0.8; offset 0.4 along +x: s = 2.
        assert!((zmp_scale_limit(&SQUARE, [0.0, 0.0], [0.4, 0.0], 0.2) - 2.0).abs() < 1e-12);
        // Diagonal offset: the nearer edge in each axis binds, x here (0.5 of 0.9 left).
        let s = zmp_scale_limit(&SQUARE, [0.1, 0.0], [0.5, 0.25], 0.0);
        assert!((s - 0.9 / 0.5).abs() < 1e-12, "{s}");
        // No offset: unlimited; the CoM short of the margin: 0.
        assert_eq!(
            zmp_scale_limit(&SQUARE, [0.0, 0.0], [0.0, 0.0], 0.1),
            f64::INFINITY
        );
        assert_eq!(zmp_scale_limit(&SQUARE, [0.95, 0.0], [0.0, 0.0], 0.1), 0.0);
    }
}
