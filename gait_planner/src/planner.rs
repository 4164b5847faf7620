//! The walk engine: a phase machine stepped with time as an argument, which places the feet
//! on the floor, moves the pelvis so the whole-body CoM follows its path over the support
//! polygon, and turns both ankle positions into joint angles with the closed-form IK.
//!
//! World frame: on the floor at the midpoint between the feet of the initial pose, x forward,
//! y left, z up. The pelvis is kept level, facing between the feet; the feet land where
//! the stride of each step puts them ([`Stride`]: forward or back, sideways, turning).

use ik_solver::support::{Xy, convex_hull, convex_overlap, signed_margin};
use ik_solver::{AnkleTarget, BipedModel, IkIssue, Side, StaticPose};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

use crate::error::GaitError;
use crate::params::{GaitConfig, GaitParams};
use crate::pause::{BrakeBound, PlannedCom, shortest_brake_s};
use crate::phase::{PhaseKind, Support, WalkRequest};
use crate::stride::{Stride, StrideCommand, Velocity};
use crate::timing::FastestTiming;
use crate::trajectory::{min_jerk, min_jerk_accel, swing_advance, swing_height};
use crate::zmp::cart_table_zmp;

/// Times closer than this are the same instant (s); far below any control period.
const TIME_EPSILON_S: f64 = 1e-9;

/// Everything planned for one control tick.
#[derive(Debug, Clone, PartialEq)]
pub struct GaitSample {
    /// Time given to [`GaitPlanner::update`] (s).
    pub t_s: f64,
    /// The phase.
    pub phase: PhaseKind,
    /// Which feet carry the robot.
    pub support: Support,
    /// The foot taken as fixed by leg odometry: the stance foot of a swing, and from the
    /// start of a CoM shift the foot it shifts onto (both feet are down then: the moment to
    /// change the fixed point); other phases keep the last one.
    pub planted: Side,
    /// Number of the swing in progress or last finished (1 = the first half step); 0 before.
    pub step_index: u32,
    /// Progress through the phase, 0 to 1.
    pub progress: f64,
    /// Pose of the base (root) link in the world; level, heading between the feet's.
    pub base_world: Isometry3<f64>,
    /// World position of each ankle-pitch axis, `[left, right]` (m).
    pub ankles_world_m: [Point3<f64>; 2],
    /// Heading of each foot in the world, counter-clockwise from +x, `[left, right]` (rad).
    pub feet_yaw_rad: [f64; 2],
    /// Each ankle relative to its hip point, base axes: what the IK node receives.
    pub targets: [AnkleTarget; 2],
    /// All joint positions (rad), in [`ik_solver::RobotModel::dof_names`] order; joints
    /// outside the legs at 0.
    pub joints_rad: Vec<f64>,
    /// Whole-body centre of mass in the world (m).
    pub com_world_m: Point3<f64>,
    /// Signed distance of the CoM's floor projection to the support polygon's edge (m),
    /// positive inside.
    pub margin_m: f64,
    /// Planned acceleration of the CoM (m/s²): the phase's min-jerk profile, exact for the
    /// CoM-driven phases (shifts, swings, centring); for the pelvis-driven crouch and rise,
    /// the second difference of the planned CoM over one control period.
    pub com_accel_m_s2: Vector3<f64>,
    /// The cart-table ZMP of the planned CoM motion on the floor (m): see [`crate::zmp`].
    pub zmp_xy_m: Xy,
    /// Its signed distance to the support polygon's edge (m), positive inside.
    pub zmp_margin_m: f64,
    /// What the IK had to clamp (empty for a valid plan).
    pub issues: Vec<IkIssue>,
}

impl GaitSample {
    /// The planned pose as ik_solver's statics (and the simulator's sag compensation) take
    /// it: base, joints, CoM and the soles that carry the robot.
    pub fn static_pose(&self) -> StaticPose<'_> {
        StaticPose {
            base_world: &self.base_world,
            joints_rad: &self.joints_rad,
            com_world_m: self.com_world_m,
            stance: self.support.stance(),
        }
    }
}

/// A tick's balance as a viewer draws it (RViz or Foxglove markers, from the node): the
/// support polygon, the CoM over it with its margin, and where the foot in the air lands.
/// World (walk) frame, on the floor.
#[derive(Debug, Clone, PartialEq)]
pub struct BalanceView {
    /// The soles carrying the robot: their convex hull, counter-clockwise.
    pub support_polygon: Vec<Xy>,
    /// The planned CoM's floor projection (m).
    pub com_xy: Xy,
    /// Its signed distance to the polygon's edge (m), positive inside.
    pub margin_m: f64,
    /// The smallest margin the planner allows (`min_com_margin_m`).
    pub min_margin_m: f64,
    /// During a swing, the swinging foot's landing: its side and sole corners
    /// (counter-clockwise); empty otherwise.
    pub footsteps: Vec<(Side, [Xy; 4])>,
}

/// How the pelvis moves within a phase.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Drive {
    /// The pelvis goes from one (x, y) to another; the CoM follows.
    Base { from: Xy, to: Xy },
    /// The CoM goes from one floor point to another; the pelvis is solved to put it there.
    Com { from: Xy, to: Xy },
}

#[derive(Debug, Clone, PartialEq)]
struct Phase {
    kind: PhaseKind,
    start_s: f64,
    duration_s: f64,
    /// The foot in the air, for swings; the foot the CoM moves onto, for shifts.
    side: Option<Side>,
    step_index: u32,
    feet_from: [Point3<f64>; 2],
    feet_to: [Point3<f64>; 2],
    feet_yaw_from: [f64; 2],
    feet_yaw_to: [f64; 2],
    base_z_from: f64,
    base_z_to: f64,
    base_yaw_from: f64,
    base_yaw_to: f64,
    drive: Drive,
}

impl Phase {
    fn end_s(&self) -> f64 {
        self.start_s + self.duration_s
    }
    fn support(&self) -> Support {
        match (self.kind.is_swing(), self.side) {
            (true, Some(swing)) => Support::on(swing.other()),
            _ => Support::Double,
        }
    }
}

/// How many swings are left before the walk closes.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Remaining {
    Swings(u32),
    UntilStop,
}

/// The gait planner: feed it requests, call [`Self::update`] once per control tick.
///
/// ```
/// use gait_planner::{GaitParams, GaitPlanner, PhaseKind, WalkRequest};
/// let model = ik_solver::BipedModel::from_urdf_str(ik_solver::DEFAULT_URDF, None).unwrap();
/// let mut planner = GaitPlanner::new(model, GaitParams::default()).unwrap();
/// planner.request(WalkRequest::Steps(2));
/// let first = planner.update(0.0).unwrap();
/// assert_eq!(first.phase, PhaseKind::Crouch);
/// assert!(first.margin_m > 0.0);
/// ```
#[derive(Debug, Clone)]
pub struct GaitPlanner {
    model: BipedModel,
    cfg: GaitConfig,
    phase: Phase,
    pending: Option<WalkRequest>,
    remaining: Remaining,
    stop: bool,
    crouched: bool,
    /// Foot to swing next.
    next_swing: Side,
    /// What the next swing does; taken at the start of each swing.
    stride: Stride,
    /// The foot leg odometry holds fixed ([`GaitSample::planted`]).
    planted: Side,
    /// Sideways distance between the ankles of the initial pose (m): the feet never come
    /// closer.
    stance_width_m: f64,
    swings_done: u32,
    /// The base (x, y) of the last solved tick: the warm start of the next solve.
    base_xy: Xy,
    /// CoM (x, y) of the last tick.
    com_xy: Xy,
    last_t_s: f64,
    poses: Vec<Isometry3<f64>>,
    /// The pause brake bound of each check walk that passed (its stride, the bound, and
    /// the phase and time of the tick that needs it): [`Self::settle_brake`] reads the
    /// settled strides' here instead of planning them again.
    brakes: std::cell::RefCell<Vec<(Stride, BrakeBound, PhaseKind, f64)>>,
    /// Parameters with durations at 0 (auto) as given, and the timing search's answer for
    /// them: [`Self::set_params`] with the same parameters does not search again.
    auto_timing: Option<(GaitParams, GaitParams, FastestTiming)>,
    /// Parameters as given and the configuration their check walks settled: the checks
    /// depend on the parameters and the model only, so [`Self::set_params`] with the same
    /// parameters (every walk command between walks, in the node) takes this instead of
    /// walking them again, a stall of the control loop of tens of milliseconds.
    checked: Option<(GaitParams, GaitConfig)>,
}

/// Results of placing the pelvis for given feet.
struct Posture {
    base: Isometry3<f64>,
    targets: [AnkleTarget; 2],
    q: Vec<f64>,
    com: Point3<f64>,
    issues: Vec<IkIssue>,
}

impl GaitPlanner {
    /// A planner standing still at the initial pose, after checking that the parameters
    /// give a walk whose CoM stays inside the support polygon with the configured margin,
    /// within reach and joint limits, at every tick of a check walk that has every kind of
    /// phase. Refuses otherwise, naming the phase and the shortfall.
    ///
    /// The walk is checked at the forward step, at the longest backward step, at the
    /// longest side step to either side alone and together with the longest forward or
    /// backward step, and (with hip yaw) at the largest turn either way, in place, in an arc
    /// and with a side step (combinations at 1/√2 of each). A step limit left at 0 (auto)
    /// whose check fails is lowered until it passes; one set by hand is refused.
    ///
    /// Durations left at 0 (auto) are the fastest the checks allow
    /// ([`GaitParams::with_auto_timing`]; [`Self::auto_timing`] tells what bound each).
    pub fn new(model: BipedModel, params: GaitParams) -> Result<Self, GaitError> {
        let (filled, found) = params.with_auto_timing(&model)?;
        let cfg = filled.resolve(&model)?;
        let mut planner = Self::unchecked(model, cfg);
        planner.check_limits(&params)?;
        planner.checked = Some((params.clone(), planner.cfg.clone()));
        planner.auto_timing = found.map(|f| (params, filled, f));
        Ok(planner)
    }

    /// The timing search behind durations left at 0 (auto), when any was: the durations
    /// found and what bound each.
    pub fn auto_timing(&self) -> Option<&FastestTiming> {
        self.auto_timing.as_ref().map(|(_, _, f)| f)
    }

    /// The durations left at 0 (auto) and what bound each, as `biped plan` and the node log
    /// it (`durations left at 0 (auto), the fastest the checks allow: step 0.580 s
    /// (JointSpeed), ...`); `None` when every duration was set.
    pub fn auto_timing_summary(&self) -> Option<String> {
        let (given, _, f) = self.auto_timing.as_ref()?;
        let auto = [
            given.shift_duration_s,
            given.step_duration_s,
            given.crouch_duration_s,
        ]
        .map(|d| d == 0.0);
        Some(format!(
            "durations left at 0 (auto), the fastest the checks allow: {}",
            f.describe_only(auto)
        ))
    }

    /// True when [`Self::set_params`] with `params` would run the timing search (a duration
    /// left at 0, for parameters neither checked nor searched here): 0.3-1.2 s, to be run
    /// off a control loop ([`Self::new`] on another thread, then [`Self::remember_checks`]).
    pub fn needs_timing_search(&self, params: &GaitParams) -> bool {
        params.has_auto_timing()
            && self.needs_check(params)
            && !matches!(&self.auto_timing, Some((given, _, _)) if given == params)
    }

    /// True when [`Self::set_params`] with `params` would walk the check walks (parameters
    /// other than those last checked here or taken with [`Self::remember_checks`]): tens to
    /// hundreds of milliseconds (and the timing search too, if
    /// [`Self::needs_timing_search`]), which a control loop on the wall clock runs off the
    /// loop as it does the search.
    pub fn needs_check(&self, params: &GaitParams) -> bool {
        !matches!(&self.checked, Some((given, _)) if given == params)
    }

    /// Takes the timing search and the checks `other` made (a planner of the same robot
    /// checked for some parameters, e.g. on another thread) so that [`Self::set_params`]
    /// with those parameters neither searches nor checks again.
    pub fn remember_checks(&mut self, other: &GaitPlanner) {
        if other.auto_timing.is_some() {
            self.auto_timing = other.auto_timing.clone();
        }
        if other.checked.is_some() {
            self.checked = other.checked.clone();
        }
    }

    /// The check walks of [`Self::new`], settling the auto step limits.
    fn check_limits(&mut self, params: &GaitParams) -> Result<(), GaitError> {
        self.brakes.borrow_mut().clear();
        let fwd = if params.step_length_m == 0.0 {
            self.settle_limit("step_length_m", true, self.cfg.step_length_m, |v| {
                vec![Stride::forward(v)]
            })?
        } else {
            // Set by hand: refused for the check walk's own reason, phase and tick.
            self.check_walk(Stride::forward(self.cfg.step_length_m))?;
            self.cfg.step_length_m
        };
        if fwd != self.cfg.step_length_m {
            // The auto back step follows the forward step it derives from.
            if params.back_step_length_m == 0.0 {
                self.cfg.back_step_length_m = crate::params::auto::BACK_STEP_PER_STEP * fwd;
            }
            self.cfg.step_length_m = fwd;
        }
        let back = self.settle_limit(
            "back_step_length_m",
            params.back_step_length_m == 0.0,
            self.cfg.back_step_length_m,
            |v| vec![Stride::forward(-v)],
        )?;
        self.cfg.back_step_length_m = back;
        let side = self.settle_limit(
            "side_step_m",
            params.side_step_m == 0.0,
            self.cfg.side_step_m,
            |v| side_strides(v, fwd, back),
        )?;
        self.cfg.side_step_m = side;
        if self.cfg.turn_step_rad > 0.0 {
            let turn = self.settle_limit(
                "turn_step_rad",
                params.turn_step_rad == 0.0,
                self.cfg.turn_step_rad,
                |v| turn_strides(v, fwd, side),
            )?;
            self.cfg.turn_step_rad = turn;
        }
        self.stride = Stride::forward(self.cfg.step_length_m);
        self.cfg.pause_brake_time_s = self.settle_brake(params.pause_brake_time_s)?;
        Ok(())
    }

    /// The CoM motion of consecutive `samples` as the pause check takes it: the velocity by
    /// central differences (one-sided at the ends), the support polygon of each tick.
    pub(crate) fn planned_coms(&self, samples: &[GaitSample]) -> Vec<PlannedCom> {
        let dt = self.cfg.dt_s();
        let n = samples.len();
        (0..n)
            .map(|k| {
                let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
                let span = (b - a) as f64 * dt;
                let s = &samples[k];
                PlannedCom {
                    com_m: s.com_world_m,
                    velocity_m_s: if span > 0.0 {
                        (samples[b].com_world_m - samples[a].com_world_m) / span
                    } else {
                        Vector3::zeros()
                    },
                    accel_m_s2: s.com_accel_m_s2,
                    polygon: self.support_polygon(s.support, &s.ankles_world_m, &s.feet_yaw_rad),
                }
            })
            .collect()
    }

    /// The pause brake time: the shortest that keeps the ZMP margin pausing or resuming at
    /// any tick of the check walks ([`crate::pause::shortest_brake_s`]), in whole control
    /// periods, for 0 (auto); a value set by hand, if it is at least that.
    fn settle_brake(&self, given_s: f64) -> Result<f64, GaitError> {
        let mut worst: Option<(BrakeBound, PhaseKind, f64)> = None;
        for stride in self.check_strides() {
            let cached = self
                .brakes
                .borrow()
                .iter()
                .rev()
                .find(|b| b.0 == stride)
                .copied();
            let (_, b, phase, t_s) = match cached {
                Some(found) => found,
                None => self.brake_bound(stride, &self.plan_stride(stride)?),
            };
            if worst.as_ref().is_none_or(|w| b.brake_s > w.0.brake_s) {
                worst = Some((b, phase, t_s));
            }
        }
        let Some((bound, phase, t_s)) = worst else {
            return Ok(given_s);
        };
        let refuse = |brake_s: f64| GaitError::PauseBrake {
            brake_s,
            needed_s: bound.brake_s,
            phase,
            t_s,
            resuming: bound.resuming,
        };
        if !bound.brake_s.is_finite() {
            return Err(refuse(given_s));
        }
        if given_s == 0.0 {
            let rate = self.cfg.control_rate_hz;
            Ok((bound.brake_s * rate - 1e-9).ceil().max(0.0) / rate)
        } else if given_s < bound.brake_s {
            Err(refuse(given_s))
        } else {
            Ok(given_s)
        }
    }

    /// The strides of the check walks of [`Self::new`], at the settled step limits.
    pub(crate) fn check_strides(&self) -> Vec<Stride> {
        let c = &self.cfg;
        let mut out = vec![
            Stride::forward(c.step_length_m),
            Stride::forward(-c.back_step_length_m),
        ];
        out.extend(side_strides(
            c.side_step_m,
            c.step_length_m,
            c.back_step_length_m,
        ));
        if c.turn_step_rad > 0.0 {
            out.extend(turn_strides(
                c.turn_step_rad,
                c.step_length_m,
                c.side_step_m,
            ));
        }
        out
    }

    /// A step limit whose check walks all pass: the value itself, or for an auto value
    /// the largest passing one below it, found by bisection to 1/64 of it (0 when none
    /// passes: that way is not walked; for the forward step, refused as at the auto value).
    fn settle_limit(
        &self,
        key: &'static str,
        auto: bool,
        value_m: f64,
        strides: impl Fn(f64) -> Vec<Stride>,
    ) -> Result<f64, GaitError> {
        let fails = |v: f64| {
            strides(v)
                .into_iter()
                .find_map(|st| self.check_walk(st).err())
        };
        match fails(value_m) {
            None => Ok(value_m),
            Some(e) if !auto => Err(GaitError::StepLimit {
                key,
                value_m,
                cause: Box::new(e),
            }),
            Some(e) => {
                let (mut lo, mut hi) = (0.0, value_m);
                for _ in 0..crate::params::auto::BISECTIONS {
                    let mid = (lo + hi) / 2.0;
                    if fails(mid).is_none() {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                // No forward step at all is no walk: refused for why the auto one failed.
                if lo == 0.0 && key == "step_length_m" {
                    return Err(e);
                }
                Ok(lo)
            }
        }
    }

    /// The stride of the next swings (see [`Stride`]); the walk is unchanged until then.
    /// Refused, naming the value, when not finite or beyond the configured step limits.
    ///
    /// A new stride is first walked on a copy of the planner from where it is, through the
    /// next swing (the first to take it) and the shift after it, with the checks of a check
    /// walk: the limits are checked walking steadily, a change of stride is checked here.
    /// If that step fails, the stride is halved (up to 3 times, then no motion: stepping in
    /// place); the stride taken is returned.
    pub fn set_stride(&mut self, stride: Stride) -> Result<Stride, GaitError> {
        let c = &self.cfg;
        // Within a part per billion: a velocity scaled onto a limit lands on it.
        let within = |v: f64, lo: f64, hi: f64| {
            v.is_finite() && v >= lo - 1e-9 * lo.abs() && v <= hi + 1e-9 * hi.abs()
        };
        for (field, v, lo, hi, unit) in [
            (
                "forward_m",
                stride.forward_m,
                -c.back_step_length_m,
                c.step_length_m,
                "m",
            ),
            ("left_m", stride.left_m, -c.side_step_m, c.side_step_m, "m"),
            (
                "turn_rad",
                stride.turn_rad,
                -c.turn_step_rad,
                c.turn_step_rad,
                "rad",
            ),
        ] {
            if !within(v, lo, hi) {
                return Err(GaitError::Request(format!(
                    "stride {field} = {v} {unit} is outside [{lo}, {hi}] {unit} (step_length_m, back_step_length_m, side_step_m, turn_step_rad)"
                )));
            }
        }
        if stride == self.stride {
            return Ok(stride);
        }
        let mut s = stride;
        for _ in 0..3 {
            if self.check_next_step(s).is_ok() {
                self.stride = s;
                return Ok(s);
            }
            s = Stride {
                forward_m: s.forward_m / 2.0,
                left_m: s.left_m / 2.0,
                turn_rad: s.turn_rad / 2.0,
            };
        }
        self.stride = Stride::default();
        Ok(self.stride)
    }

    /// Walks `stride` on a copy of this planner, from its last update through the next
    /// swing and the shift after it, then a stop (the closing half step and the centring),
    /// and checks every tick. Checking the way back too keeps every accepted stride
    /// stoppable and leaves a stride of zero (what a refused stride falls back to) feasible
    /// at the next swing: a stride whose next swing is fine but whose feet cannot be brought
    /// together again is lowered before it is taken.
    fn check_next_step(&self, stride: Stride) -> Result<(), GaitError> {
        let mut sim = self.clone();
        sim.stride = stride;
        if sim.is_idle() {
            sim.request(WalkRequest::UntilStop);
        }
        let t0 = if self.last_t_s.is_finite() {
            self.last_t_s
        } else {
            0.0
        };
        let first_new = self.phase.step_index + 1;
        let c = &self.cfg;
        let dt = c.dt_s();
        let mut samples = Vec::new();
        // At most the rest of this phase, a crouch, a shift, the new swing, a shift, the
        // closing half step, the centring and a rise.
        let limit =
            ((2.0 * c.crouch_duration_s + 4.0 * c.shift_duration_s + 3.0 * c.step_duration_s) / dt)
                .ceil() as u64
                + 4;
        let mut stopping = false;
        for k in 1..=limit {
            let s = sim.update(t0 + k as f64 * dt)?;
            // Asked during the new swing, the stop is taken when it lands.
            if !stopping && s.step_index >= first_new {
                sim.request(WalkRequest::Stop);
                stopping = true;
            }
            let done = s.phase == PhaseKind::Idle && k > 1;
            samples.push(s);
            if done {
                break;
            }
        }
        self.check_samples(&samples)
    }

    /// The stride the next swing takes.
    pub fn stride(&self) -> Stride {
        self.stride
    }

    /// A velocity as a stride of this robot, within its step limits: see
    /// [`GaitConfig::stride_for`].
    pub fn stride_for(&self, v: Velocity) -> Result<StrideCommand, GaitError> {
        let has_yaw = Side::BOTH.iter().all(|&s| self.model.leg(s).has_yaw());
        self.cfg.stride_for(v, has_yaw)
    }

    fn unchecked(model: BipedModel, cfg: GaitConfig) -> Self {
        let feet = Self::initial_feet(&model);
        let stance_width_m = (feet[0].y - feet[1].y).abs();
        let z_stand = Self::stand_base_z(&model);
        let base_xy = Self::initial_base_xy(&model);
        let phase = Phase {
            kind: PhaseKind::Idle,
            start_s: 0.0,
            duration_s: f64::INFINITY,
            side: None,
            step_index: 0,
            feet_from: feet,
            feet_to: feet,
            feet_yaw_from: [0.0; 2],
            feet_yaw_to: [0.0; 2],
            base_z_from: z_stand,
            base_z_to: z_stand,
            base_yaw_from: 0.0,
            base_yaw_to: 0.0,
            drive: Drive::Base {
                from: base_xy,
                to: base_xy,
            },
        };
        Self {
            next_swing: cfg.first_foot,
            stride: Stride::forward(cfg.step_length_m),
            planted: cfg.first_foot.other(),
            stance_width_m,
            model,
            cfg,
            phase,
            pending: None,
            remaining: Remaining::Swings(0),
            stop: false,
            crouched: false,
            swings_done: 0,
            base_xy,
            com_xy: [0.0, 0.0],
            last_t_s: f64::NEG_INFINITY,
            poses: Vec::new(),
            brakes: Default::default(),
            auto_timing: None,
            checked: None,
        }
    }

    /// True when the soles, each turned to its heading, share area.
    fn soles_overlap(&self, ankles: &[Point3<f64>; 2], feet_yaw: &[f64; 2]) -> bool {
        let sole = |s: Side| {
            self.model.leg(s).sole.corners(
                [ankles[s.index()].x, ankles[s.index()].y],
                feet_yaw[s.index()],
            )
        };
        convex_overlap(&sole(Side::Left), &sole(Side::Right))
    }

    /// Changes the parameters between walks, after the same check as [`Self::new`] (not
    /// walked again for the parameters last checked, here or by the planner given to
    /// [`Self::remember_checks`]), and starts the next walk from the configured first
    /// foot and forward stride. Refused during a walk, and for the hip height (while
    /// crouched) and the control rate, which would make the pose or the tick times jump.
    pub fn set_params(&mut self, params: GaitParams) -> Result<(), GaitError> {
        if self.phase.kind != PhaseKind::Idle || self.pending.is_some() {
            return Err(GaitError::Request(
                "parameters can change only between walks (the planner is walking)".into(),
            ));
        }
        let checked = match &self.checked {
            Some((given, cfg)) if *given == params => Some(cfg.clone()),
            _ => None,
        };
        let (cfg, auto_timing) = match checked {
            // Checked already: the same configuration, and the timing search kept with it.
            Some(cfg) => {
                self.check_rate_and_height(&cfg)?;
                let kept = self
                    .auto_timing
                    .take()
                    .filter(|(given, _, _)| *given == params);
                (cfg, kept)
            }
            None => {
                let (filled, found) = match &self.auto_timing {
                    Some((given, filled, f)) if *given == params => {
                        (filled.clone(), Some(f.clone()))
                    }
                    _ => params.with_auto_timing(&self.model)?,
                };
                let cfg = filled.resolve(&self.model)?;
                self.check_rate_and_height(&cfg)?;
                let mut fresh = Self::unchecked(self.model.clone(), cfg);
                fresh.check_limits(&params)?;
                (fresh.cfg, found.map(|f| (params.clone(), filled, f)))
            }
        };
        self.auto_timing = auto_timing;
        self.checked = Some((params, cfg.clone()));
        self.next_swing = cfg.first_foot;
        self.stride = Stride::forward(cfg.step_length_m);
        self.cfg = cfg;
        Ok(())
    }

    /// What [`Self::set_params`] refuses whatever the check walks say: another control rate,
    /// or another hip height while crouched.
    fn check_rate_and_height(&self, cfg: &GaitConfig) -> Result<(), GaitError> {
        if cfg.control_rate_hz != self.cfg.control_rate_hz {
            return Err(GaitError::Param {
                key: "control_rate_hz",
                value: cfg.control_rate_hz,
                why: format!(
                    "fixed at {} Hz while running; restart to change it",
                    self.cfg.control_rate_hz
                ),
            });
        }
        if self.crouched && cfg.hip_height_m != self.cfg.hip_height_m {
            return Err(GaitError::Param {
                key: "hip_height_m",
                value: cfg.hip_height_m,
                why: format!(
                    "cannot change from {} m while crouched",
                    self.cfg.hip_height_m
                ),
            });
        }
        Ok(())
    }

    /// The resolved parameters.
    pub fn config(&self) -> &GaitConfig {
        &self.cfg
    }

    /// The robot model.
    pub fn model(&self) -> &BipedModel {
        &self.model
    }

    /// The phase of the last update.
    pub fn phase(&self) -> PhaseKind {
        self.phase.kind
    }

    /// True when idle with no request waiting.
    pub fn is_idle(&self) -> bool {
        self.phase.kind == PhaseKind::Idle && self.pending.is_none()
    }

    /// Asks for a walk or a stop; taken at the next phase boundary (at once when idle).
    pub fn request(&mut self, request: WalkRequest) {
        // A stop while idle has nothing to stop.
        if request == WalkRequest::Stop && self.phase.kind == PhaseKind::Idle {
            self.pending = None;
            return;
        }
        self.pending = Some(request);
    }

    fn initial_feet(model: &BipedModel) -> [Point3<f64>; 2] {
        let mid = Self::hips_mid(model);
        Side::BOTH.map(|s| {
            // Straight legs, no hip roll: each ankle point where the leg's offsets put it.
            let leg = model.leg(s);
            let ankle = leg.hip_in_base_m + leg.straight_ankle_in_hip_m();
            Point3::new(ankle.x - mid.x, ankle.y - mid.y, leg.ankle_to_sole_m)
        })
    }

    fn hips_mid(model: &BipedModel) -> Vector3<f64> {
        (model.leg(Side::Left).hip_in_base_m + model.leg(Side::Right).hip_in_base_m) / 2.0
    }

    fn initial_base_xy(model: &BipedModel) -> Xy {
        let mid = Self::hips_mid(model);
        [-mid.x, -mid.y]
    }

    /// Base height for a hip-point height above the floor.
    fn base_z(model: &BipedModel, hip_height_m: f64) -> f64 {
        hip_height_m - Self::hips_mid(model).z
    }

    /// Base height with straight legs, ankles below the hips.
    fn stand_base_z(model: &BipedModel) -> f64 {
        let leg = model.leg(Side::Left);
        Self::base_z(
            model,
            leg.ankle_to_sole_m + leg.hip_roll_to_pitch_m + leg.thigh_m + leg.shin_m,
        )
    }

    fn walk_base_z(&self) -> f64 {
        Self::base_z(&self.model, self.cfg.hip_height_m)
    }

    /// Centre of a foot's sole on the floor, for an ankle position and foot heading.
    fn sole_centre(&self, side: Side, ankle: &Point3<f64>, yaw_rad: f64) -> Xy {
        let r = &self.model.leg(side).sole;
        let (cx, cy) = ((r.x_min_m + r.x_max_m) / 2.0, (r.y_min_m + r.y_max_m) / 2.0);
        let (s, c) = yaw_rad.sin_cos();
        [ankle.x + c * cx - s * cy, ankle.y + s * cx + c * cy]
    }

    /// The support polygon for the feet carrying the robot, each sole turned to its heading.
    pub fn support_polygon(
        &self,
        support: Support,
        ankles: &[Point3<f64>; 2],
        feet_yaw_rad: &[f64; 2],
    ) -> Vec<Xy> {
        let corners = |s: Side| {
            self.model.leg(s).sole.corners(
                [ankles[s.index()].x, ankles[s.index()].y],
                feet_yaw_rad[s.index()],
            )
        };
        match support {
            Support::Left => corners(Side::Left).to_vec(),
            Support::Right => corners(Side::Right).to_vec(),
            Support::Double => {
                let mut all = corners(Side::Left).to_vec();
                all.extend(corners(Side::Right));
                convex_hull(&all)
            }
        }
    }

    /// The balance of `sample`, the tick just planned by [`Self::update`], for a viewer.
    pub fn balance_view(&self, sample: &GaitSample) -> BalanceView {
        let ph = &self.phase;
        let footsteps = match (ph.kind.is_swing(), ph.side) {
            (true, Some(swing)) => {
                let k = swing.index();
                let ankle = ph.feet_to[k];
                vec![(
                    swing,
                    self.model
                        .leg(swing)
                        .sole
                        .corners([ankle.x, ankle.y], ph.feet_yaw_to[k]),
                )]
            }
            _ => Vec::new(),
        };
        BalanceView {
            support_polygon: self.support_polygon(
                sample.support,
                &sample.ankles_world_m,
                &sample.feet_yaw_rad,
            ),
            com_xy: [sample.com_world_m.x, sample.com_world_m.y],
            margin_m: sample.margin_m,
            min_margin_m: self.cfg.min_com_margin_m,
            footsteps,
        }
    }

    /// Places the pelvis at (x, y, z) with a heading and solves both legs for the feet.
    fn posture(
        &mut self,
        base_xy: Xy,
        base_z: f64,
        base_yaw: f64,
        feet: &[Point3<f64>; 2],
        feet_yaw: &[f64; 2],
    ) -> Result<Posture, GaitError> {
        // Heading 0 exactly the identity, so straight walks keep their exact numbers.
        let rotation = if base_yaw == 0.0 {
            UnitQuaternion::identity()
        } else {
            UnitQuaternion::from_euler_angles(0.0, 0.0, base_yaw)
        };
        let base =
            Isometry3::from_parts(Translation3::new(base_xy[0], base_xy[1], base_z), rotation);
        let targets = Side::BOTH.map(|s| {
            let hip = base.translation.vector + rotation * self.model.leg(s).hip_in_base_m;
            AnkleTarget {
                ankle_in_hip_m: rotation.inverse() * (feet[s.index()].coords - hip),
                foot_yaw_rad: feet_yaw[s.index()] - base_yaw,
            }
        });
        let mut q = vec![0.0; self.model.robot().dof_count()];
        let issues = self
            .model
            .solve_legs(&targets[0], &targets[1], &mut q)
            .map_err(|e| GaitError::Unreachable {
                phase: self.phase.kind,
                t_s: self.last_t_s,
                issue: e.to_string(),
            })?;
        self.model
            .robot()
            .link_poses_into(&base, &q, &mut self.poses)
            .map_err(|e| GaitError::Unreachable {
                phase: self.phase.kind,
                t_s: self.last_t_s,
                issue: e.to_string(),
            })?;
        let com = self.model.robot().center_of_mass(&self.poses);
        Ok(Posture {
            base,
            targets,
            q,
            com,
            issues,
        })
    }

    /// The CoM's acceleration at progress `p` of the current pelvis-driven phase (m/s²):
    /// the central second difference of the CoM of the poses one control period before
    /// and after. The legs bend as the pelvis moves, so the CoM does not follow the
    /// pelvis's profile; from straight legs the knees even start forward like √t (a crouch
    /// has an infinite CoM acceleration at its start in the limit), so the difference is
    /// taken over the period at which the targets change.
    fn pelvis_drive_com_accel(
        &mut self,
        p: f64,
        com: Point3<f64>,
    ) -> Result<Vector3<f64>, GaitError> {
        let h_s = self.cfg.dt_s();
        let ph = self.phase.clone();
        let Drive::Base { from, to } = ph.drive else {
            return Ok(Vector3::zeros());
        };
        let dp = h_s / ph.duration_s;
        let mut com_at = |q: f64| -> Result<Point3<f64>, GaitError> {
            // min_jerk holds still outside [0, 1], as the robot does before and after.
            let r = min_jerk(q);
            let lerp = |a: f64, b: f64| a + (b - a) * r;
            let base = [lerp(from[0], to[0]), lerp(from[1], to[1])];
            let z = lerp(ph.base_z_from, ph.base_z_to);
            let yaw = lerp(ph.base_yaw_from, ph.base_yaw_to);
            Ok(self
                .posture(base, z, yaw, &ph.feet_from, &ph.feet_yaw_from)?
                .com)
        };
        let (before, after) = (com_at(p - dp)?, com_at(p + dp)?);
        Ok((before.coords - 2.0 * com.coords + after.coords) / (h_s * h_s))
    }

    /// Finds the pelvis (x, y) that puts the whole-body CoM over `com_goal`, by secant steps
    /// per axis from the last tick's pelvis (the CoM moves almost linearly with the pelvis,
    /// a little less since the feet stay put).
    fn posture_for_com(
        &mut self,
        com_goal: Xy,
        base_z: f64,
        base_yaw: f64,
        feet: &[Point3<f64>; 2],
        feet_yaw: &[f64; 2],
    ) -> Result<Posture, GaitError> {
        let mut b = self.base_xy;
        let mut gain = [0.8, 0.8];
        let mut prev: Option<(Xy, Xy)> = None;
        let mut best = self.posture(b, base_z, base_yaw, feet, feet_yaw)?;
        for _ in 0..30 {
            let c = [best.com.x, best.com.y];
            let err = [com_goal[0] - c[0], com_goal[1] - c[1]];
            if err[0].abs() < 1e-11 && err[1].abs() < 1e-11 {
                break;
            }
            if let Some((pb, pc)) = prev {
                for k in 0..2 {
                    let db = b[k] - pb[k];
                    if db.abs() > 1e-14 {
                        let g = (c[k] - pc[k]) / db;
                        if g.is_finite() && g > 0.1 && g < 2.0 {
                            gain[k] = g;
                        }
                    }
                }
            }
            prev = Some((b, c));
            b = [b[0] + err[0] / gain[0], b[1] + err[1] / gain[1]];
            best = self.posture(b, base_z, base_yaw, feet, feet_yaw)?;
        }
        Ok(best)
    }

    /// Where the swing foot lands for a stride, and its heading. The frame of the step is
    /// the point between the feet when they stand together (the standing width apart,
    /// both at the stance foot's heading). The foot on the side of the turn turns by twice
    /// the stride's turn (the other comes back parallel), and lands `forward_m` ahead of
    /// that point at half the standing width from it in its new heading, plus twice
    /// `left_m` outwards when it swings towards the side of travel (the other foot closes
    /// back to the standing width). A turn in place thus turns the robot about that point.
    fn landing(
        &self,
        feet: &[Point3<f64>; 2],
        feet_yaw: &[f64; 2],
        swing: Side,
        stride: Stride,
    ) -> (Point3<f64>, f64) {
        let st = swing.other();
        let (stance, stance_yaw) = (feet[st.index()], feet_yaw[st.index()]);
        let open = if stride.left_m * swing.sign() > 0.0 {
            2.0 * stride.left_m.abs()
        } else {
            0.0
        };
        let turn = if stride.turn_rad * swing.sign() > 0.0 {
            2.0 * stride.turn_rad
        } else {
            0.0
        };
        let half = self.stance_width_m / 2.0;
        let rot = |yaw: f64, x: f64, y: f64| {
            let (s, c) = yaw.sin_cos();
            (c * x - s * y, s * x + c * y)
        };
        // The point between the feet standing together.
        let (mx, my) = rot(stance_yaw, 0.0, swing.sign() * half);
        let yaw = stance_yaw + turn;
        let (dx, dy) = rot(yaw, stride.forward_m, swing.sign() * (half + open));
        (
            Point3::new(
                stance.x + mx + dx,
                stance.y + my + dy,
                feet[swing.index()].z,
            ),
            yaw,
        )
    }

    /// The feet and their headings at progress `p` of the phase: the swing foot along its
    /// curve, turning as it advances; the others where they are.
    fn swing_feet(&self, p: f64) -> ([Point3<f64>; 2], [f64; 2]) {
        let ph = &self.phase;
        let (from, to) = (ph.feet_from, ph.feet_to);
        match (ph.kind.is_swing(), ph.side) {
            (true, Some(swing)) => {
                let (mut feet, mut yaw) = (from, ph.feet_yaw_from);
                let k = swing.index();
                let (a, b) = (from[k], to[k]);
                let u = swing_advance(p);
                feet[k] = Point3::new(
                    a.x + (b.x - a.x) * u,
                    a.y + (b.y - a.y) * u,
                    a.z + (b.z - a.z) * u + self.cfg.foot_lift_m * swing_height(p),
                );
                yaw[k] = ph.feet_yaw_from[k] + (ph.feet_yaw_to[k] - ph.feet_yaw_from[k]) * u;
                (feet, yaw)
            }
            _ => (from, ph.feet_yaw_from),
        }
    }

    /// The plan for time `t_s` (s, non-decreasing between calls; any origin).
    pub fn update(&mut self, t_s: f64) -> Result<GaitSample, GaitError> {
        if !t_s.is_finite() || t_s < self.last_t_s {
            return Err(GaitError::Time {
                t_s,
                previous_s: self.last_t_s,
            });
        }
        self.last_t_s = t_s;
        if self.phase.kind == PhaseKind::Idle && self.pending.is_some() {
            self.phase.start_s = t_s;
            self.phase.duration_s = 0.0;
            self.advance();
        }
        // The tick at a phase's end time belongs to that phase (progress 1). Times within
        // a nanosecond count as equal: a walk started at tick k0 has its boundaries at
        // k0/rate + duration, which rounding can put a hair before tick (k0 + n)/rate.
        while t_s > self.phase.end_s() + TIME_EPSILON_S {
            self.advance();
            if self.phase.kind == PhaseKind::Idle {
                break;
            }
        }
        let ph = self.phase.clone();
        let p = if ph.duration_s > 0.0 && ph.duration_s.is_finite() {
            ((t_s - ph.start_s) / ph.duration_s).clamp(0.0, 1.0)
        } else {
            1.0
        };
        let r = min_jerk(p);
        // d²r/dt² (1/s²): the profile's second derivative over the duration squared.
        let r_dd = if ph.duration_s > 0.0 && ph.duration_s.is_finite() {
            min_jerk_accel(p) / (ph.duration_s * ph.duration_s)
        } else {
            0.0
        };
        let (feet, feet_yaw) = self.swing_feet(p);
        let base_z = ph.base_z_from + (ph.base_z_to - ph.base_z_from) * r;
        let base_yaw = ph.base_yaw_from + (ph.base_yaw_to - ph.base_yaw_from) * r;
        let lerp = |a: Xy, b: Xy| [a[0] + (b[0] - a[0]) * r, a[1] + (b[1] - a[1]) * r];
        let posture = match ph.drive {
            Drive::Base { from, to } => {
                self.posture(lerp(from, to), base_z, base_yaw, &feet, &feet_yaw)?
            }
            Drive::Com { from, to } => {
                self.posture_for_com(lerp(from, to), base_z, base_yaw, &feet, &feet_yaw)?
            }
        };
        self.base_xy = [posture.base.translation.x, posture.base.translation.y];
        self.com_xy = [posture.com.x, posture.com.y];
        let support = ph.support();
        let poly = self.support_polygon(support, &feet, &feet_yaw);
        // A CoM drive moves the CoM along the phase's profile; a pelvis drive moves the
        // pelvis so, and the CoM as the bending legs make it.
        let com_accel_m_s2 = match ph.drive {
            Drive::Com { from, to } => Vector3::new(
                (to[0] - from[0]) * r_dd,
                (to[1] - from[1]) * r_dd,
                (ph.base_z_to - ph.base_z_from) * r_dd,
            ),
            Drive::Base { from, to }
                if (from == to && ph.base_z_from == ph.base_z_to) || !ph.duration_s.is_finite() =>
            {
                Vector3::zeros()
            }
            Drive::Base { .. } => self.pelvis_drive_com_accel(p, posture.com)?,
        };
        let zmp_xy_m = cart_table_zmp(posture.com, com_accel_m_s2);
        self.planted = match (ph.kind, ph.side) {
            (PhaseKind::Shift, Some(onto)) => onto,
            (kind, Some(swing)) if kind.is_swing() => swing.other(),
            _ => self.planted,
        };
        Ok(GaitSample {
            t_s,
            phase: ph.kind,
            support,
            planted: self.planted,
            step_index: ph.step_index,
            progress: p,
            base_world: posture.base,
            ankles_world_m: feet,
            feet_yaw_rad: feet_yaw,
            targets: posture.targets,
            joints_rad: posture.q,
            com_world_m: posture.com,
            margin_m: signed_margin(&poly, self.com_xy),
            com_accel_m_s2,
            zmp_xy_m,
            zmp_margin_m: signed_margin(&poly, zmp_xy_m),
            issues: posture.issues,
        })
    }

    /// Takes a waiting request into the walk state.
    fn take_request(&mut self) {
        match self.pending.take() {
            Some(WalkRequest::Steps(n)) => {
                self.remaining = Remaining::Swings(n);
                self.stop = n == 0;
            }
            Some(WalkRequest::UntilStop) => {
                self.remaining = Remaining::UntilStop;
                self.stop = false;
            }
            Some(WalkRequest::Stop) => self.stop = true,
            None => {}
        }
    }

    fn closing(&self) -> bool {
        self.stop || self.remaining == Remaining::Swings(0)
    }

    /// Ends the current phase and starts the next.
    fn advance(&mut self) {
        let ended = self.phase.clone();
        let feet = ended.feet_to;
        let feet_yaw = ended.feet_yaw_to;
        let yaw_now = ended.base_yaw_to;
        // The pelvis faces between the feet once both are down.
        let yaw_between = (feet_yaw[0] + feet_yaw[1]) / 2.0;
        let start_s = ended.end_s();
        // Count the swing that just landed before taking a request, so a new `Steps(n)`
        // counts from the next swing.
        if let (PhaseKind::HalfStep | PhaseKind::Step, Remaining::Swings(n)) =
            (ended.kind, &mut self.remaining)
        {
            *n = n.saturating_sub(1);
        }
        self.take_request();
        let stance_centre =
            |me: &Self, s: Side| me.sole_centre(s, &feet[s.index()], feet_yaw[s.index()]);
        let z = self.walk_base_z();
        let com_now = self.com_xy;
        let next = match ended.kind {
            PhaseKind::Idle if self.closing() => None,
            PhaseKind::Idle if !self.crouched => Some((PhaseKind::Crouch, None)),
            PhaseKind::Idle | PhaseKind::Crouch => {
                if self.closing() {
                    if ended.kind == PhaseKind::Crouch {
                        None
                    } else {
                        Some((PhaseKind::Center, None))
                    }
                } else {
                    // Feet level: a side step (or a turn) starts with the foot on the side
                    // of travel (of the turn), the only one that can open.
                    let lead = if self.stride.left_m != 0.0 {
                        self.stride.left_m
                    } else {
                        self.stride.turn_rad
                    };
                    if lead != 0.0 {
                        self.next_swing = if lead > 0.0 { Side::Left } else { Side::Right };
                    }
                    Some((PhaseKind::Shift, Some(self.next_swing.other())))
                }
            }
            PhaseKind::Shift => match (self.swings_done > 0, self.closing()) {
                // Feet still level (no swing yet in this walk): the first swing is a half step.
                (false, true) => Some((PhaseKind::Center, None)),
                (false, false) => Some((PhaseKind::HalfStep, Some(self.next_swing))),
                (true, true) => Some((PhaseKind::FinalHalfStep, Some(self.next_swing))),
                (true, false) => Some((PhaseKind::Step, Some(self.next_swing))),
            },
            PhaseKind::HalfStep | PhaseKind::Step => {
                let landed = ended.side.unwrap_or(Side::Left);
                Some((PhaseKind::Shift, Some(landed)))
            }
            PhaseKind::FinalHalfStep => Some((PhaseKind::Center, None)),
            PhaseKind::Center if self.cfg.rise_at_end => Some((PhaseKind::Rise, None)),
            PhaseKind::Center | PhaseKind::Rise => None,
        };
        let Some((kind, side)) = next else {
            if ended.kind == PhaseKind::Rise {
                self.crouched = false;
            }
            // The next walk starts from level feet: with a half step.
            self.swings_done = 0;
            self.stop = false;
            self.remaining = Remaining::Swings(0);
            self.phase = Phase {
                kind: PhaseKind::Idle,
                start_s,
                duration_s: f64::INFINITY,
                side: None,
                step_index: ended.step_index,
                feet_from: feet,
                feet_to: feet,
                feet_yaw_from: feet_yaw,
                feet_yaw_to: feet_yaw,
                base_z_from: ended.base_z_to,
                base_z_to: ended.base_z_to,
                base_yaw_from: yaw_now,
                base_yaw_to: yaw_now,
                drive: Drive::Base {
                    from: self.base_xy,
                    to: self.base_xy,
                },
            };
            // A request that came during the closing phases starts a new walk now.
            return;
        };
        let cfg = &self.cfg;
        let mut phase = Phase {
            kind,
            start_s,
            duration_s: cfg.shift_duration_s,
            side,
            step_index: ended.step_index,
            feet_from: feet,
            feet_to: feet,
            feet_yaw_from: feet_yaw,
            feet_yaw_to: feet_yaw,
            base_z_from: z,
            base_z_to: z,
            base_yaw_from: yaw_now,
            base_yaw_to: yaw_now,
            drive: Drive::Base {
                from: self.base_xy,
                to: self.base_xy,
            },
        };
        match kind {
            PhaseKind::Crouch | PhaseKind::Rise => {
                let (from, to) = if kind == PhaseKind::Crouch {
                    (Self::stand_base_z(&self.model), z)
                } else {
                    (z, Self::stand_base_z(&self.model))
                };
                (phase.base_z_from, phase.base_z_to) = (from, to);
                phase.duration_s = cfg.crouch_duration_s;
                if kind == PhaseKind::Rise {
                    // Straight legs reach only straight down: end with the hips over the ankles.
                    let mid = if yaw_now == 0.0 {
                        Self::hips_mid(&self.model)
                    } else {
                        UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_now)
                            * Self::hips_mid(&self.model)
                    };
                    let over = [
                        (feet[0].x + feet[1].x) / 2.0 - mid.x,
                        (feet[0].y + feet[1].y) / 2.0 - mid.y,
                    ];
                    phase.drive = Drive::Base {
                        from: self.base_xy,
                        to: over,
                    };
                }
                if kind == PhaseKind::Crouch {
                    self.crouched = true;
                    self.swings_done = 0;
                }
            }
            PhaseKind::Shift => {
                let onto = side.unwrap_or(Side::Left);
                phase.drive = Drive::Com {
                    from: com_now,
                    to: stance_centre(self, onto),
                };
                // The stance hip unwinds: the pelvis turns to face between the feet.
                phase.base_yaw_to = yaw_between;
            }
            PhaseKind::HalfStep | PhaseKind::Step | PhaseKind::FinalHalfStep => {
                let swing = side.unwrap_or(Side::Left);
                let stance = swing.other();
                let stride = match kind {
                    PhaseKind::FinalHalfStep => Stride::default(),
                    _ => self.stride,
                };
                let mut to = feet;
                let mut to_yaw = feet_yaw;
                (to[swing.index()], to_yaw[swing.index()]) =
                    self.landing(&feet, &feet_yaw, swing, stride);
                phase.feet_to = to;
                phase.feet_yaw_to = to_yaw;
                phase.duration_s = cfg.step_duration_s;
                phase.step_index = ended.step_index + 1;
                let c = stance_centre(self, stance);
                phase.drive = Drive::Com { from: c, to: c };
                self.next_swing = stance;
                self.swings_done += 1;
            }
            PhaseKind::Center => {
                let mid = {
                    let (l, r) = (
                        stance_centre(self, Side::Left),
                        stance_centre(self, Side::Right),
                    );
                    [(l[0] + r[0]) / 2.0, (l[1] + r[1]) / 2.0]
                };
                phase.drive = Drive::Com {
                    from: com_now,
                    to: mid,
                };
                phase.base_yaw_to = yaw_between;
                self.next_swing = cfg.first_foot;
            }
            PhaseKind::Idle => {}
        }
        self.phase = phase;
    }

    /// Runs a whole check walk with every kind of phase on a copy of this planner and
    /// refuses parameters that leave the CoM margin below the minimum, need an unreachable
    /// ankle position or a joint limit, or move a joint faster than its limit.
    fn check_walk(&self, stride: Stride) -> Result<(), GaitError> {
        let samples = self.plan_stride(stride)?;
        self.check_samples(&samples)?;
        let found = self.brake_bound(stride, &samples);
        self.brakes.borrow_mut().push(found);
        Ok(())
    }

    /// The shortest pause brake of a check walk's `samples` (see [`Self::settle_brake`]).
    fn brake_bound(
        &self,
        stride: Stride,
        samples: &[GaitSample],
    ) -> (Stride, BrakeBound, PhaseKind, f64) {
        let b = shortest_brake_s(&self.planned_coms(samples), self.cfg.min_zmp_margin_m);
        let (phase, t_s) = samples
            .get(b.tick)
            .map_or((PhaseKind::Idle, 0.0), |s| (s.phase, s.t_s));
        (stride, b, phase, t_s)
    }

    /// The check walk of one stride, not checked: three steps from the initial pose.
    pub(crate) fn plan_stride(&self, stride: Stride) -> Result<Vec<GaitSample>, GaitError> {
        let mut check = Self::unchecked(self.model.clone(), self.cfg.clone());
        check.stride = stride;
        check.plan(WalkRequest::Steps(3))
    }

    /// The checks of a check walk on consecutive samples: no clamped joint, no overlapping
    /// soles, the CoM margin, joint speeds.
    fn check_samples(&self, samples: &[GaitSample]) -> Result<(), GaitError> {
        let dt = self.cfg.dt_s();
        let robot = self.model.robot();
        for (k, s) in samples.iter().enumerate() {
            if let Some(issue) = s.issues.first() {
                return Err(GaitError::Unreachable {
                    phase: s.phase,
                    t_s: s.t_s,
                    issue: issue.to_string(),
                });
            }
            if self.soles_overlap(&s.ankles_world_m, &s.feet_yaw_rad) {
                return Err(GaitError::SolesOverlap {
                    phase: s.phase,
                    t_s: s.t_s,
                });
            }
            let detail = || match s.support {
                Support::Double => "both feet on the floor".to_string(),
                Support::Left => "right foot swinging".to_string(),
                Support::Right => "left foot swinging".to_string(),
            };
            if s.margin_m < self.cfg.min_com_margin_m {
                return Err(GaitError::Unstable {
                    phase: s.phase,
                    detail: detail(),
                    t_s: s.t_s,
                    margin_m: s.margin_m,
                    min_m: self.cfg.min_com_margin_m,
                });
            }
            if s.zmp_margin_m < self.cfg.min_zmp_margin_m {
                return Err(GaitError::ZmpOutside {
                    phase: s.phase,
                    detail: detail(),
                    t_s: s.t_s,
                    margin_m: s.zmp_margin_m,
                    min_m: self.cfg.min_zmp_margin_m,
                    accel_m_s2: s.com_accel_m_s2.xy().norm(),
                });
            }
            if k > 0 {
                for (j, v) in joint_speeds(robot, &samples[k - 1].joints_rad, &s.joints_rad, dt) {
                    if let Some(l) = j.limits.filter(|l| v > l.velocity) {
                        return Err(GaitError::TooFast {
                            phase: s.phase,
                            t_s: s.t_s,
                            joint: j.name.clone(),
                            velocity_rad_s: v,
                            limit_rad_s: l.velocity,
                        });
                    }
                }
            }
        }
        Ok(())
    }

    /// Plans a whole walk offline: from the first tick of `request` at t = 0 to the tick at
    /// which the planner is idle again, one sample per control period.
    pub fn plan(&mut self, request: WalkRequest) -> Result<Vec<GaitSample>, GaitError> {
        if let WalkRequest::Steps(0) | WalkRequest::Stop | WalkRequest::UntilStop = request {
            return Err(GaitError::Request(format!(
                "{request:?}: an offline plan needs a number of steps of at least 1"
            )));
        }
        self.request(request);
        let rate = self.cfg.control_rate_hz;
        let mut out = Vec::new();
        let t0 = if self.last_t_s.is_finite() {
            self.last_t_s
        } else {
            0.0
        };
        for k in 0.. {
            // k / rate, not k * dt: exact for decimal rates, so times print as written.
            let s = self.update(t0 + k as f64 / rate)?;
            let done = s.phase == PhaseKind::Idle;
            if done {
                break;
            }
            out.push(s);
            if k > 10_000_000 {
                break;
            }
        }
        Ok(out)
    }
}

/// Each joint's speed (rad/s, or m/s) between two consecutive ticks `dt` apart, with the
/// joint: `from` and `to` in [`ik_solver::RobotModel::dof_names`] order.
pub(crate) fn joint_speeds<'a>(
    robot: &'a ik_solver::RobotModel,
    from: &'a [f64],
    to: &'a [f64],
    dt: f64,
) -> impl Iterator<Item = (&'a ik_solver::Joint, f64)> + 'a {
    from.iter()
        .zip(to)
        .enumerate()
        .map(move |(d, (&a, &b))| (&robot.joints()[robot.dof_joints()[d]], (b - a).abs() / dt))
}

/// The side-step check strides at a side step of `v`: alone and together with the longest
/// forward or backward step, either way (combinations at 1/√2 of each).
fn side_strides(v: f64, fwd: f64, back: f64) -> Vec<Stride> {
    let diag = std::f64::consts::FRAC_1_SQRT_2;
    [1.0, -1.0]
        .into_iter()
        .flat_map(|sign| {
            let left_m = sign * v;
            [(0.0, 1.0), (fwd, diag), (-back, diag)].map(|(x, k)| Stride {
                forward_m: x * k,
                left_m: left_m * k,
                turn_rad: 0.0,
            })
        })
        .collect()
}

/// The turn check strides at a turn of `v`: in place, in an arc, and with a side step
/// either way (combinations at 1/√2 of each).
fn turn_strides(v: f64, fwd: f64, side: f64) -> Vec<Stride> {
    let diag = std::f64::consts::FRAC_1_SQRT_2;
    [1.0, -1.0]
        .into_iter()
        .flat_map(|sign| {
            let t = sign * v;
            [
                (0.0, 0.0, 1.0),
                (fwd, 0.0, diag),
                (0.0, side, diag),
                (0.0, -side, diag),
            ]
            .map(|(x, y, k)| Stride {
                forward_m: x * k,
                left_m: y * k,
                turn_rad: t * k,
            })
        })
        .collect()
}

/// Plans `steps` steps of the default walk for a robot and parameters: the samples of every
/// tick from the start of the crouch to the end of the closing phase.
pub fn plan_walk(
    model: BipedModel,
    params: GaitParams,
    steps: u32,
) -> Result<Vec<GaitSample>, GaitError> {
    GaitPlanner::new(model, params)?.plan(WalkRequest::Steps(steps))
}
