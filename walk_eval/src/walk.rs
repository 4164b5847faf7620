//! Playing a planned walk open-loop into the simulator, and measuring how it went: the
//! numbers `biped walk` reports.

use gait_planner::{GaitSample, PhaseKind};
use ik_solver::BipedModel;
use nalgebra::{Isometry3, Vector3};
use serde::Serialize;
use sim_bridge::{Sim, SimError, compensated_targets_rad, tilt_rad};

/// A sole carrying more than this share of the weight is standing (for the slip measure).
pub const STANCE_FRACTION: f64 = 0.05;

/// How servo targets change between plan samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Interpolation {
    /// Each sample's targets hold until the next sample: what a servo bus updated at the
    /// plan's rate sees.
    Hold,
    /// Straight lines between samples, updated every physics step.
    Linear,
}

/// The servo targets of a plan, sample by sample.
#[derive(Debug, Clone)]
pub struct Playback {
    /// Sample times from the plan's first sample (s).
    t_s: Vec<f64>,
    targets_rad: Vec<Vec<f64>>,
    phases: Vec<PhaseKind>,
    interpolation: Interpolation,
}

impl Playback {
    /// The targets of every sample of `plan`: the planned joint positions, plus the sag
    /// compensation (static torque / `compensation_kp`) when `compensation_kp` is given.
    /// Refuses an empty plan, times that do not increase, and bad joint vectors.
    pub fn new(
        model: &BipedModel,
        plan: &[GaitSample],
        compensation_kp: Option<f64>,
        interpolation: Interpolation,
    ) -> Result<Self, SimError> {
        let Some(first) = plan.first() else {
            return Err(SimError::Plan("the plan has no samples".into()));
        };
        let mut t_s = Vec::with_capacity(plan.len());
        let mut targets_rad = Vec::with_capacity(plan.len());
        for (k, s) in plan.iter().enumerate() {
            let t = s.t_s - first.t_s;
            if !t.is_finite() || (k > 0 && t <= t_s[k - 1]) {
                return Err(SimError::Plan(format!(
                    "sample {k}: time {} s does not follow {} s",
                    s.t_s,
                    plan[k.saturating_sub(1)].t_s
                )));
            }
            t_s.push(t);
            targets_rad.push(match compensation_kp {
                Some(kp) => compensated_targets_rad(model, &s.static_pose(), kp)?,
                None => {
                    model
                        .robot()
                        .check_joint_vector(&s.joints_rad)
                        .map_err(|e| SimError::Plan(format!("sample {k}: {e}")))?;
                    s.joints_rad.clone()
                }
            });
        }
        Ok(Self {
            t_s,
            targets_rad,
            phases: plan.iter().map(|s| s.phase).collect(),
            interpolation,
        })
    }

    /// Time of the last sample after the first (s).
    pub fn duration_s(&self) -> f64 {
        self.t_s.last().copied().unwrap_or(0.0)
    }

    /// The sample in force at `t_s` (from the first sample): the last one at or before it.
    pub fn index_at(&self, t_s: f64) -> usize {
        self.t_s
            .partition_point(|&x| x <= t_s + 1e-9)
            .saturating_sub(1)
    }

    /// The phase at `t_s`.
    pub fn phase_at(&self, t_s: f64) -> PhaseKind {
        self.phases[self.index_at(t_s)]
    }

    /// The servo targets at `t_s` (rad); before the first sample the first, after the last
    /// the last.
    pub fn targets_at(&self, t_s: f64) -> Vec<f64> {
        let i = self.index_at(t_s);
        let a = &self.targets_rad[i];
        match (self.interpolation, self.targets_rad.get(i + 1)) {
            (Interpolation::Linear, Some(b)) => {
                let f = ((t_s - self.t_s[i]) / (self.t_s[i + 1] - self.t_s[i])).clamp(0.0, 1.0);
                a.iter().zip(b).map(|(x, y)| x + f * (y - x)).collect()
            }
            _ => a.clone(),
        }
    }
}

/// How [`run_plan`] plays a plan.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlayOptions {
    /// Add the sag compensation (static torque / kp) to the targets.
    pub compensate: bool,
    /// How targets change between samples.
    pub interpolation: Interpolation,
    /// How long to hold the last targets after the plan ends, still measured (s).
    pub tail_s: f64,
}

impl Default for PlayOptions {
    fn default() -> Self {
        Self {
            compensate: true,
            interpolation: Interpolation::Hold,
            tail_s: 1.0,
        }
    }
}

/// The smallest centre-of-pressure margin seen in one kind of phase.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PhaseMargin {
    /// The phase.
    pub phase: PhaseKind,
    /// Smallest signed distance of the measured centre of pressure to the support polygon's
    /// edge (m), positive inside.
    pub min_cop_margin_m: f64,
    /// Physics steps measured in this phase with a centre of pressure.
    pub samples: u64,
    /// Smallest margin of the planned (cart-table) ZMP in this phase kind (m), when the
    /// report was given the plan ([`WalkReport::with_planned_zmp`]): the margin the plan
    /// promised against the one measured.
    pub planned_min_zmp_margin_m: Option<f64>,
}

/// A fall, as reported.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FallReport {
    /// Time from the start of the plan (s).
    pub t_s: f64,
    /// The planned phase at that time.
    pub phase: PhaseKind,
    /// Why it counts as a fall.
    pub reason: String,
}

/// What happened when a plan was played (what `biped walk` writes to report.json).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WalkReport {
    /// The first fall, if the robot fell (playing stops there).
    pub fell: Option<FallReport>,
    /// Time measured: the plan and the tail, or up to the fall (s).
    pub duration_s: f64,
    /// Largest tilt of the base from upright (deg).
    pub max_tilt_deg: f64,
    /// Largest change of the base's heading from the start (deg).
    pub heading_drift_deg: f64,
    /// How far the base moved along its starting heading (m).
    pub distance_m: f64,
    /// How far the plan moves the base (m).
    pub planned_distance_m: f64,
    /// How far the base moved to the left of its starting heading (m).
    pub left_m: f64,
    /// How far the plan moves the base to the left (m).
    pub planned_left_m: f64,
    /// The base's heading at the end, from the start, counter-clockwise (deg).
    pub final_heading_deg: f64,
    /// How far the point between the feet moved, `[forward, left]` of the base's starting
    /// heading (m): where the robot stands, whatever its posture (the crouched walking pose
    /// holds the pelvis a little off the standing one).
    pub feet_moved_m: [f64; 2],
    /// Largest horizontal drift of a foot while it carried the robot (m), over all stances.
    pub max_foot_slip_m: f64,
    /// Share of the physics steps with a centre of pressure in which it lay inside the
    /// support polygon of the loaded soles.
    pub cop_inside_fraction: f64,
    /// Physics steps with a centre of pressure.
    pub cop_samples: u64,
    /// Smallest centre-of-pressure margin per phase kind, in order of first appearance.
    pub min_cop_margin_per_phase: Vec<PhaseMargin>,
}

impl WalkReport {
    /// The report with each phase kind's smallest planned ZMP margin beside its measured
    /// CoP margin.
    pub fn with_planned_zmp(mut self, plan: &[GaitSample]) -> Self {
        for p in &mut self.min_cop_margin_per_phase {
            p.planned_min_zmp_margin_m = plan
                .iter()
                .filter(|s| s.phase == p.phase)
                .map(|s| s.zmp_margin_m)
                .reduce(f64::min);
        }
        self
    }
}

/// Heading of a pose on the floor: the angle of its x axis from the world's x, counter-
/// clockwise (rad).
pub fn heading_rad(pose: &Isometry3<f64>) -> f64 {
    let x = pose.rotation * Vector3::x();
    x.y.atan2(x.x)
}

/// How far `to` is turned from `from` on the floor, counter-clockwise, in (-π, π] (rad).
pub fn heading_change_rad(from: &Isometry3<f64>, to: &Isometry3<f64>) -> f64 {
    let r = (heading_rad(to) - heading_rad(from)).rem_euclid(std::f64::consts::TAU);
    if r > std::f64::consts::PI {
        r - std::f64::consts::TAU
    } else {
        r
    }
}

/// A floor displacement `[dx, dy]` in the frame of a heading: `[forward, left]`.
fn in_heading(heading_rad: f64, d: [f64; 2]) -> [f64; 2] {
    let (s, c) = heading_rad.sin_cos();
    [c * d[0] + s * d[1], -s * d[0] + c * d[1]]
}

/// One measurement of the robot, from the simulator itself ([`Observation::of_sim`]) or
/// from what a simulator publishes.
#[derive(Debug, Clone, PartialEq)]
pub struct Observation {
    /// Time (s).
    pub t_s: f64,
    /// Pose of the base in the world.
    pub base: Isometry3<f64>,
    /// Signed distance of the centre of pressure to the support polygon's edge (m), positive
    /// inside; `None` when the floor does not carry the robot.
    pub cop_margin_m: Option<f64>,
    /// Each foot's position on the floor (world x, y, m), `[left, right]`.
    pub feet_xy_m: [[f64; 2]; 2],
    /// Whether each foot carries the robot, `[left, right]`.
    pub standing: [bool; 2],
    /// The first fall so far: time (s) and reason.
    pub fall: Option<(f64, String)>,
}

impl Observation {
    /// The simulator's present state; a foot stands when its sole carries more than
    /// [`STANCE_FRACTION`] of the weight.
    pub fn of_sim(sim: &Sim) -> Self {
        let c = sim.contacts();
        let feet = sim.foot_positions_m();
        Self {
            t_s: sim.time_s(),
            base: sim.base_pose(),
            cop_margin_m: c.cop_margin_m(),
            feet_xy_m: feet.map(|f| [f.x, f.y]),
            standing: c.sole_force_n.map(|f| f > STANCE_FRACTION * sim.weight_n()),
            fall: sim.fallen().map(|f| (f.t_s, f.reason.to_string())),
        }
    }
}

/// Accumulates the walk measures, one observation at a time.
#[derive(Debug, Clone)]
pub struct WalkMonitor {
    start_base: Isometry3<f64>,
    start_t_s: f64,
    max_tilt_rad: f64,
    max_heading_rad: f64,
    cop_samples: u64,
    cop_inside: u64,
    per_phase: Vec<PhaseMargin>,
    stance_start: [Option<[f64; 2]>; 2],
    max_slip_m: f64,
    fell: Option<FallReport>,
    /// The point between the feet at the first and the last observation.
    feet_mid: Option<([f64; 2], [f64; 2])>,
}

impl WalkMonitor {
    /// Starts measuring from the simulator's present state.
    pub fn new(sim: &Sim) -> Self {
        Self::starting_at(sim.time_s(), sim.base_pose())
    }

    /// Starts measuring at `t_s` with the base at `base`.
    pub fn starting_at(t_s: f64, base: Isometry3<f64>) -> Self {
        Self {
            start_base: base,
            start_t_s: t_s,
            max_tilt_rad: 0.0,
            max_heading_rad: 0.0,
            cop_samples: 0,
            cop_inside: 0,
            per_phase: Vec::new(),
            stance_start: [None, None],
            max_slip_m: 0.0,
            fell: None,
            feet_mid: None,
        }
    }

    /// Measures the simulator's present state, during `phase`.
    pub fn observe(&mut self, sim: &Sim, phase: PhaseKind) {
        self.observe_state(&Observation::of_sim(sim), phase);
    }

    /// Takes one observation, made during `phase`.
    pub fn observe_state(&mut self, o: &Observation, phase: PhaseKind) {
        self.max_tilt_rad = self.max_tilt_rad.max(tilt_rad(&o.base));
        let mid = [
            (o.feet_xy_m[0][0] + o.feet_xy_m[1][0]) / 2.0,
            (o.feet_xy_m[0][1] + o.feet_xy_m[1][1]) / 2.0,
        ];
        let first = self.feet_mid.map_or(mid, |(f, _)| f);
        self.feet_mid = Some((first, mid));
        let heading = heading_change_rad(&self.start_base, &o.base).abs();
        self.max_heading_rad = self.max_heading_rad.max(heading);
        if let Some(margin) = o.cop_margin_m {
            self.cop_samples += 1;
            if margin > 0.0 {
                self.cop_inside += 1;
            }
            match self.per_phase.iter_mut().find(|p| p.phase == phase) {
                Some(p) => {
                    p.min_cop_margin_m = p.min_cop_margin_m.min(margin);
                    p.samples += 1;
                }
                None => self.per_phase.push(PhaseMargin {
                    phase,
                    min_cop_margin_m: margin,
                    samples: 1,
                    planned_min_zmp_margin_m: None,
                }),
            }
        }
        for ((&p, &standing), start) in o
            .feet_xy_m
            .iter()
            .zip(&o.standing)
            .zip(self.stance_start.iter_mut())
        {
            match (standing, *start) {
                (true, None) => *start = Some(p),
                (true, Some(p0)) => {
                    let d = (p[0] - p0[0]).hypot(p[1] - p0[1]);
                    self.max_slip_m = self.max_slip_m.max(d);
                }
                (false, _) => *start = None,
            }
        }
        if self.fell.is_none()
            && let Some((t_s, reason)) = &o.fall
        {
            self.fell = Some(FallReport {
                t_s: t_s - self.start_t_s,
                phase,
                reason: reason.clone(),
            });
        }
    }

    /// Observations were missed since the last one (ticks the measurement never saw): each
    /// foot's stance is measured again from its next observation, since the foot may have
    /// been lifted and set down meanwhile; a slip is never measured across the gap.
    pub fn missed(&mut self) {
        self.stance_start = [None, None];
    }

    /// True once a fall was observed.
    pub fn fell(&self) -> bool {
        self.fell.is_some()
    }

    /// The measures so far, ending at the simulator's present state; `planned_m` is how far
    /// the plan moves the base, `[forward, left]` of its starting heading.
    pub fn report(&self, sim: &Sim, planned_m: [f64; 2]) -> WalkReport {
        self.report_at(sim.time_s(), &sim.base_pose(), planned_m)
    }

    /// The measures so far, ending at `t_s` with the base at `base`.
    pub fn report_at(&self, t_s: f64, base: &Isometry3<f64>, planned_m: [f64; 2]) -> WalkReport {
        let [distance_m, left_m] = along_heading(&self.start_base, &base.translation.vector);
        WalkReport {
            fell: self.fell.clone(),
            duration_s: t_s - self.start_t_s,
            max_tilt_deg: self.max_tilt_rad.to_degrees(),
            heading_drift_deg: self.max_heading_rad.to_degrees(),
            distance_m,
            planned_distance_m: planned_m[0],
            left_m,
            planned_left_m: planned_m[1],
            final_heading_deg: heading_change_rad(&self.start_base, base).to_degrees(),
            feet_moved_m: self.feet_mid.map_or([0.0, 0.0], |(a, b)| {
                in_heading(heading_rad(&self.start_base), [b[0] - a[0], b[1] - a[1]])
            }),
            max_foot_slip_m: self.max_slip_m,
            cop_inside_fraction: if self.cop_samples > 0 {
                self.cop_inside as f64 / self.cop_samples as f64
            } else {
                0.0
            },
            cop_samples: self.cop_samples,
            min_cop_margin_per_phase: self.per_phase.clone(),
        }
    }
}

/// Plays `plan` open-loop: resets the simulator to the first sample's pose, holds its targets
/// for `settle_s` (the robot settles on its feet), then sets the targets of the plan at each
/// physics step for the plan's duration and holds the last ones for `tail_s`, measuring
/// every physics step from the end of the settling. Stops early if the robot falls.
///
/// ```
/// # fn main() -> Result<(), Box<dyn std::error::Error>> {
/// use ik_solver::{BipedModel, DEFAULT_URDF};
/// let model = BipedModel::from_urdf_str(DEFAULT_URDF, None)?;
/// let plan = gait_planner::plan_walk(model, Default::default(), 2)?;
/// let mut sim = sim_bridge::Sim::from_urdf_str(DEFAULT_URDF, None, &Default::default())?;
/// let report = walk_eval::run_plan(&mut sim, &plan, &Default::default())?;
/// assert!(report.fell.is_none());
/// # Ok(()) }
/// ```
pub fn run_plan(
    sim: &mut Sim,
    plan: &[GaitSample],
    options: &PlayOptions,
) -> Result<WalkReport, SimError> {
    if !(options.tail_s.is_finite() && options.tail_s >= 0.0) {
        return Err(SimError::Plan(format!(
            "tail_s {} s is not a non-negative time",
            options.tail_s
        )));
    }
    let kp = sim.config().kp_nm_per_rad;
    let playback = Playback::new(
        sim.biped(),
        plan,
        options.compensate.then_some(kp),
        options.interpolation,
    )?;
    let (Some(first), Some(last)) = (plan.first(), plan.last()) else {
        return Err(SimError::Plan("the plan has no samples".into()));
    };
    let planned_m = along_heading(&first.base_world, &last.base_world.translation.vector);

    sim.reset(&first.base_world, &first.joints_rad)?;
    sim.set_targets(&playback.targets_at(0.0))?;
    sim.step(sim.config().settle_s)?;

    let dt = sim.config().timestep_s;
    let n_play = (playback.duration_s() / dt).round() as u64;
    let n_tail = (options.tail_s / dt).round() as u64;
    let mut monitor = WalkMonitor::new(sim);
    for k in 0..n_play + n_tail {
        let t = k.min(n_play) as f64 * dt;
        sim.set_targets(&playback.targets_at(t))?;
        sim.physics_steps(1)?;
        monitor.observe(sim, playback.phase_at(t));
        if monitor.fell() {
            break;
        }
    }
    Ok(monitor.report(sim, planned_m).with_planned_zmp(plan))
}

/// How far `to` is from `start`, `[forward, left]` of the start's heading on the floor (m).
pub fn along_heading(start: &Isometry3<f64>, to: &Vector3<f64>) -> [f64; 2] {
    let moved = to - start.translation.vector;
    in_heading(heading_rad(start), [moved.x, moved.y])
}

#[cfg(test)]
mod tests {
    use nalgebra::Isometry3;

    use super::{Observation, PhaseKind, WalkMonitor};

    /// The left foot standing at `x` (m), the right lifted.
    fn left_standing_at(t_s: f64, x: f64) -> Observation {
        Observation {
            t_s,
            base: Isometry3::identity(),
            cop_margin_m: Some(0.02),
            feet_xy_m: [[x, 0.05], [0.1, -0.05]],
            standing: [true, false],
            fall: None,
        }
    }

    #[test]
    fn a_slip_is_measured_within_a_stance_but_not_across_missed_observations() {
        let mut m = WalkMonitor::starting_at(0.0, Isometry3::identity());
        m.observe_state(&left_standing_at(0.00, 0.0), PhaseKind::Shift);
        m.observe_state(&left_standing_at(0.01, 0.0005), PhaseKind::Shift);
        let mut bridged = WalkMonitor::starting_at(0.0, Isometry3::identity());
        bridged.observe_state(&left_standing_at(0.00, 0.0), PhaseKind::Shift);
        bridged.observe_state(&left_standing_at(0.01, 0.0005), PhaseKind::Shift);
        // Two seconds unseen, in which the foot stepped 17 mm: measured across the gap it
        // would be a 17 mm slip; after `missed`, the stance starts again where it is seen.
        m.missed();
        m.observe_state(&left_standing_at(2.01, 0.0170), PhaseKind::Step);
        bridged.observe_state(&left_standing_at(2.01, 0.0170), PhaseKind::Step);
        m.observe_state(&left_standing_at(2.02, 0.0180), PhaseKind::Step);
        let slip = |m: &WalkMonitor| {
            m.report_at(2.02, &Isometry3::identity(), [0.0, 0.0])
                .max_foot_slip_m
        };
        assert!((slip(&m) - 0.0010).abs() < 1e-12, "{}", slip(&m));
        assert!(
            (slip(&bridged) - 0.0170).abs() < 1e-12,
            "{}",
            slip(&bridged)
        );
    }
}
