//! The bridge core: commands in, safe positions to the backend, states out.

use std::collections::{HashMap, HashSet};
use std::fmt;

use crate::backend::{Backend, BackendError, Lifecycle, Reading};
use crate::compensation::{GYRO_MAX_AGE_S, GyroDamping, SagCompensation};
use crate::limits::JointSpec;
use crate::motion::{Limiter, MotionLimit};

/// How many unknown joint names the bridge reports (each once) before it stops reporting:
/// a sender making up a new name every message must not grow the bridge without end.
pub const MAX_UNKNOWN_REPORTED: usize = 256;

/// Why the bridge ignores commands, on an operator's request (the node's `~/estop`,
/// `~/set_torque` and lifecycle services). Several may hold at once; the first in this order
/// is the one reported.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Operator {
    /// Emergency stop: holding where the joints came to rest; commands ignored until released.
    Estop,
    /// Torque off on request; commands ignored until the torque is turned on again.
    TorqueOff,
    /// The managed node is inactive: holding, commands ignored until activated.
    Inactive,
}

/// Why a torque request was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TorqueError {
    /// The backend is not running.
    #[error("the backend is {state:?}: start it (or let it reconnect) first")]
    NotRunning {
        /// Its state.
        state: Lifecycle,
    },
    /// An emergency stop is on.
    #[error("an emergency stop is on: release it first")]
    Estop,
    /// The backend failed the request.
    #[error(transparent)]
    Backend(#[from] BackendError),
}

/// What to do when commands stop coming.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TimeoutAction {
    /// Keep holding the last commanded pose (torque on).
    Hold,
    /// Torque off: the joints go limp.
    Limp,
}

impl std::str::FromStr for TimeoutAction {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "hold" => Ok(Self::Hold),
            "limp" => Ok(Self::Limp),
            other => Err(format!("`{other}` is not a watchdog action (hold or limp)")),
        }
    }
}

/// Bridge settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BridgeConfig {
    /// Commands older than this trip the watchdog (s).
    pub watchdog_timeout_s: f64,
    /// What the watchdog does.
    pub on_timeout: TimeoutAction,
    /// After each activation with a measured pose (start, reconnection), the joints go from
    /// that pose to the commanded one over this time (s), on a smooth ramp that begins with
    /// the first command, besides the velocity limits. 0: velocity limits only.
    pub start_ramp_s: f64,
    /// When the backend fails (or cannot start), configure and activate it again after
    /// these delays; `None`: stay in [`Lifecycle::Error`].
    pub reconnect: Option<Backoff>,
    /// Speed limit of joints the URDF leaves unlimited (continuous, or velocity 0) (rad/s).
    pub default_velocity_rad_s: f64,
    /// Acceleration limit of every joint (rad/s²): no output ever changes speed faster.
    pub acceleration_rad_s2: f64,
    /// Longest time one tick may move the joints for (s): after a stall of the control
    /// loop, the joints move as far as in this time, not as far as the stall lasted.
    pub max_tick_s: f64,
    /// A path-keeping emergency stop (stop category 1 along the path): for up to this long
    /// after [`JointBridge::estop`] (s), the bridge reports the stop at once
    /// ([`JointBridge::operator`]: the node's latched `~/holding`) but still follows the
    /// joint commands, which the gait planner, told by `~/holding`, brings to rest along the
    /// walk's own path; then it holds where the joints come to rest. It holds sooner when the
    /// commands are at rest (a new command the same as the one before) or stop coming (none
    /// for [`FOLLOW_SILENCE_S`]): a dead or silent planner gets the immediate hold, only
    /// that much later. 0: hold at once (each joint brakes at its acceleration limit), which
    /// can throw a fast walk over. A lifecycle deactivate ([`JointBridge::stop_along`] with
    /// [`Operator::Inactive`]) follows the same way.
    pub estop_follow_s: f64,
}

impl Default for BridgeConfig {
    fn default() -> Self {
        Self {
            watchdog_timeout_s: 0.25,
            on_timeout: TimeoutAction::Hold,
            start_ramp_s: 0.0,
            reconnect: None,
            default_velocity_rad_s: 2.0,
            acceleration_rad_s2: 100.0,
            max_tick_s: 0.05,
            estop_follow_s: 0.0,
        }
    }
}

/// Retry delays: the first, doubled after each failure up to the longest.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Backoff {
    /// Delay before the first retry (s).
    pub first_s: f64,
    /// Longest delay (s).
    pub max_s: f64,
}

/// The move from the measured pose to the commands after an activation.
#[derive(Debug, Clone)]
struct Ramp {
    from: Vec<f64>,
    /// When it began (the first tick with a command), once it has.
    start_s: Option<f64>,
}

/// How long an emergency stop that follows the commands ([`BridgeConfig::estop_follow_s`])
/// waits for the next one before it holds (s): five periods of a 100 Hz planner, so a
/// command that comes a tick late (the planner's and the bridge's clocks are not in step on
/// hardware) does not end the follow, and a planner that has died ends it within 50 ms.
pub const FOLLOW_SILENCE_S: f64 = 0.05;

/// An emergency stop (or a deactivate) still following the commands
/// ([`BridgeConfig::estop_follow_s`]).
#[derive(Debug, Clone)]
struct Follow {
    /// Who stops: the hold it becomes.
    by: Operator,
    /// When it began (the last tick before the stop) (s).
    from_s: f64,
    /// When it holds at the latest (s).
    until_s: f64,
    /// Whether a usable command came since the last tick.
    commanded: bool,
    /// The target after the last command (NaN before the first after the stop).
    last_target: Vec<f64>,
}

/// Smoothstep: 0 → 0, 1 → 1, zero slope at both ends.
fn smooth(p: f64) -> f64 {
    let p = p.clamp(0.0, 1.0);
    p * p * (3.0 - 2.0 * p)
}

/// Something the bridge noticed, for the node to log.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// A command named a joint the bridge does not drive (reported once per name).
    UnknownJoint {
        /// The name.
        joint: String,
    },
    /// A command's value was NaN or infinite; the joint keeps its previous target.
    NonFinite {
        /// The joint.
        joint: String,
        /// The value.
        value: f64,
    },
    /// A command's value was beyond the joint's URDF limits; clamped.
    Clamped {
        /// The joint.
        joint: String,
        /// The value asked.
        requested_rad: f64,
        /// The value used.
        clamped_rad: f64,
    },
    /// A command whose name and position lists differ in length; ignored.
    Malformed {
        /// Names.
        names: usize,
        /// Positions.
        positions: usize,
    },
    /// Commands stopped for longer than the timeout.
    WatchdogTripped {
        /// Seconds since the last command.
        silence_s: f64,
        /// What was done.
        action: TimeoutAction,
    },
    /// Commands came back after the watchdog tripped.
    Resumed,
    /// The backend failed; it was deactivated (torque off).
    BackendFailed(BackendError),
    /// Sag compensation or gyro damping could not be computed (which, and why); the output
    /// was written without it.
    CompensationFailed(String),
    /// Gyro damping stopped (`false`: no body rate fresher than [`GYRO_MAX_AGE_S`]) or
    /// started again (`true`).
    GyroDamping(bool),
    /// A retry to configure and activate the backend failed; the next one is due later.
    RetryFailed {
        /// Why.
        error: BackendError,
        /// Seconds to the next retry.
        next_in_s: f64,
    },
    /// The backend was configured and activated again after a failure; the joints ramp from
    /// the measured pose to the commands.
    Reconnected,
    /// Something the backend noticed (e.g. a servo's error bits, by name).
    BackendNotice(String),
    /// Commands are ignored while an operator holds the bridge (said once per hold).
    Ignored(Operator),
    /// An emergency stop (or a deactivate) that followed the commands now holds.
    FollowHeld {
        /// Who stopped: [`Operator::Estop`] or [`Operator::Inactive`].
        by: Operator,
        /// How long it followed them (s).
        followed_s: f64,
        /// Why it stopped following.
        why: FollowEnd,
    },
}

/// Why an emergency stop stopped following the commands ([`BridgeConfig::estop_follow_s`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FollowEnd {
    /// The commands came to rest: the walk stopped along its path.
    AtRest,
    /// No command for [`FOLLOW_SILENCE_S`]: the command source is gone.
    Silent,
    /// `estop_follow_s` ran out with the commands still moving.
    TimeUp,
}

impl fmt::Display for Event {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Event::UnknownJoint { joint } => write!(
                f,
                "command for unknown joint `{joint}` ignored (reported once)"
            ),
            Event::NonFinite { joint, value } => write!(
                f,
                "command for joint `{joint}` is {value}, not a finite number: refused, holding its previous target"
            ),
            Event::Clamped {
                joint,
                requested_rad,
                clamped_rad,
            } => {
                write!(
                    f,
                    "command for joint `{joint}` = {requested_rad:.4} rad is beyond its URDF limit: clamped to {clamped_rad:.4} rad"
                )
            }
            Event::Malformed { names, positions } => write!(
                f,
                "command with {names} names and {positions} positions ignored"
            ),
            Event::WatchdogTripped { silence_s, action } => match action {
                TimeoutAction::Hold => write!(
                    f,
                    "watchdog: no joint command for {silence_s:.3} s, holding the last pose"
                ),
                TimeoutAction::Limp => write!(
                    f,
                    "watchdog: no joint command for {silence_s:.3} s, torque off (limp)"
                ),
            },
            Event::Resumed => write!(f, "joint commands resumed"),
            Event::BackendFailed(e) => write!(f, "backend failed, torque off: {e}"),
            Event::CompensationFailed(why) => write!(f, "{why}: skipped this tick"),
            Event::GyroDamping(true) => write!(f, "gyro damping on: the body rate is coming"),
            Event::GyroDamping(false) => write!(
                f,
                "gyro damping off: no body rate (imu/data) for {GYRO_MAX_AGE_S} s"
            ),
            Event::RetryFailed { error, next_in_s } => {
                write!(
                    f,
                    "backend still failing ({error}); next try in {next_in_s:.1} s"
                )
            }
            Event::Reconnected => write!(
                f,
                "backend configured and active again; ramping from the measured pose"
            ),
            Event::BackendNotice(n) => write!(f, "{n}"),
            Event::FollowHeld {
                by,
                followed_s,
                why,
            } => {
                let why = match why {
                    FollowEnd::AtRest => "the commands came to rest",
                    FollowEnd::Silent => "the commands stopped coming",
                    FollowEnd::TimeUp => "estop_follow_s ran out, the commands still moving",
                };
                let who = match by {
                    Operator::Estop => "emergency stop",
                    Operator::Inactive => "inactive",
                    Operator::TorqueOff => "torque off",
                };
                write!(
                    f,
                    "{who}: holding after following the commands for {followed_s:.2} s ({why})"
                )
            }
            Event::Ignored(Operator::Estop) => write!(
                f,
                "joint commands ignored: emergency stop (release it with ~/reset)"
            ),
            Event::Ignored(Operator::TorqueOff) => write!(
                f,
                "joint commands ignored: torque off on request (~/set_torque true to resume)"
            ),
            Event::Ignored(Operator::Inactive) => write!(
                f,
                "joint commands ignored: the managed node is not active (configure and activate it on ~/change_state)"
            ),
        }
    }
}

/// The bridge: a backend with limits, velocity and acceleration limiting and a watchdog
/// around it. Every position written goes through one limiter ([`crate::motion`]), from the
/// measured pose where the backend measures: a start, a resume after a hold or limp, a new
/// command source, the sag offset, a stalled loop all become a move within the limits.
///
/// ```
/// use joint_bridge::{BridgeConfig, JointBridge, JointSpec, MockBackend};
/// let joints = vec![JointSpec { name: "knee".into(), lower_rad: 0.0, upper_rad: 2.0, velocity_rad_s: 1.0 }];
/// let mut bridge = JointBridge::new(MockBackend::default(), joints, BridgeConfig::default());
/// bridge.start().unwrap();
/// bridge.command(0.0, &["knee".to_string()], &[0.5]);
/// bridge.tick(0.0);
/// let (state, _) = bridge.tick(0.01);
/// // From rest, 100 rad/s² for 10 ms: 1 rad/s (the speed limit) at once, 0.01 rad on.
/// assert!((state.unwrap().positions_rad[0] - 0.01).abs() < 1e-12);
/// let (state, _) = bridge.tick(0.02);
/// assert!((state.unwrap().positions_rad[0] - 0.02).abs() < 1e-12);
/// ```
#[derive(Debug)]
pub struct JointBridge<B: Backend> {
    backend: B,
    joints: Vec<JointSpec>,
    index: HashMap<String, usize>,
    config: BridgeConfig,
    /// Where the joints should go (clamped, finite).
    target: Vec<f64>,
    /// The output without the sag offset: what was written, less the offset of its goal.
    output: Vec<f64>,
    /// The one limiter every written position goes through (velocity, acceleration).
    limiter: Limiter,
    /// Its bounds per joint.
    motion: Vec<MotionLimit>,
    /// The last pose the backend measured, if it measures (to resume from limp).
    measured: Option<Vec<f64>>,
    state: Lifecycle,
    last_command_s: Option<f64>,
    last_tick_s: Option<f64>,
    tripped: bool,
    /// Why commands are ignored (empty: they are taken); whether it was said since.
    holds: std::collections::BTreeSet<Operator>,
    said_ignored: bool,
    reported_unknown: HashSet<String>,
    compensation: Option<SagCompensation>,
    /// Gyro damping, and whether it damped at the last tick.
    gyro: Option<(GyroDamping, bool)>,
    /// What was last sent: the output, compensated and clamped.
    written: Vec<f64>,
    ramp: Option<Ramp>,
    /// An emergency stop (or a deactivate) following the commands to rest, while it does.
    follow: Option<Follow>,
    /// Current retry delay and when the next retry is due.
    retry_delay_s: f64,
    retry_at_s: Option<f64>,
}

impl<B: Backend> JointBridge<B> {
    /// A bridge for these joints (typically [`JointSpec::from_robot`]).
    pub fn new(backend: B, joints: Vec<JointSpec>, config: BridgeConfig) -> Self {
        let index = joints
            .iter()
            .enumerate()
            .map(|(i, j)| (j.name.clone(), i))
            .collect();
        let zeros: Vec<f64> = joints.iter().map(|j| j.clamp(0.0)).collect();
        let motion = joints
            .iter()
            .map(|j| MotionLimit {
                velocity_rad_s: if j.velocity_rad_s.is_finite() && j.velocity_rad_s > 0.0 {
                    j.velocity_rad_s
                } else {
                    config.default_velocity_rad_s
                },
                acceleration_rad_s2: config.acceleration_rad_s2,
            })
            .collect();
        Self {
            backend,
            index,
            config,
            target: zeros.clone(),
            written: zeros.clone(),
            limiter: Limiter::at_rest(&zeros),
            motion,
            measured: None,
            output: zeros,
            joints,
            state: Lifecycle::Unconfigured,
            last_command_s: None,
            last_tick_s: None,
            tripped: false,
            holds: Default::default(),
            said_ignored: false,
            reported_unknown: HashSet::new(),
            compensation: None,
            gyro: None,
            ramp: None,
            follow: None,
            retry_delay_s: config.reconnect.map_or(0.0, |b| b.first_s),
            retry_at_s: None,
        }
    }

    /// Adds servo-sag compensation (see [`SagCompensation`]): what is written is the output
    /// plus the static torque of its pose over the servos' stiffness, within the URDF limits.
    pub fn with_sag_compensation(mut self, compensation: SagCompensation) -> Self {
        self.compensation = Some(compensation);
        self
    }

    /// Adds gyro damping (see [`GyroDamping`]), fed by [`Self::set_body_rate`]: what is
    /// written is also offset against the body's rotation, while the rate is fresh.
    pub fn with_gyro_damping(mut self, damping: GyroDamping) -> Self {
        self.gyro = Some((damping, false));
        self
    }

    /// The body's angular velocity (rad/s, base frame) measured at `t_s` (the bridge's
    /// time), for the gyro damping; ignored without it.
    pub fn set_body_rate(&mut self, t_s: f64, rate_rad_s: nalgebra::Vector3<f64>) {
        if let Some((g, _)) = &mut self.gyro {
            g.set_body_rate(t_s, rate_rad_s);
        }
    }

    /// The positions last written to the backend (rad): the goal plus its sag offset,
    /// through the velocity and acceleration limits, within the joint limits.
    pub fn written_rad(&self) -> &[f64] {
        &self.written
    }

    /// The output the bridge is holding (rad), without the sag offset.
    pub fn output_rad(&self) -> &[f64] {
        &self.output
    }

    /// Configures and activates the backend. The output starts at the measured pose where
    /// the backend can measure it, so the first command is approached at the velocity limits.
    ///
    /// If it fails and [`BridgeConfig::reconnect`] is set, the bridge is in
    /// [`Lifecycle::Error`] and [`Self::tick`] retries with backoff.
    pub fn start(&mut self) -> Result<(), BackendError> {
        let r = self.configure_and_activate();
        if r.is_err() && self.config.reconnect.is_some() {
            let _ = self.backend.deactivate();
            self.state = Lifecycle::Error;
            self.retry_at_s = None;
        }
        r
    }

    fn configure_and_activate(&mut self) -> Result<(), BackendError> {
        self.ramp = None;
        let valid = |p: &Vec<f64>| p.len() == self.joints.len() && p.iter().all(|v| v.is_finite());
        let measured = self.backend.configure(&self.joints)?.filter(valid);
        let is_measured = measured.is_some();
        // A backend that cannot measure starts from its rest pose, which it moves to slowly.
        if let Some(measured) = measured.or_else(|| self.backend.start_pose().filter(valid)) {
            self.rest_at(&measured);
            if is_measured {
                self.measured = Some(measured.clone());
            }
            if self.state == Lifecycle::Unconfigured
                || self.last_command_s.is_none()
                || !self.holds.is_empty()
            {
                // No command yet, or an operator holds: hold the measured pose (never
                // resume towards a command given before the hold).
                self.target = measured.clone();
            }
            if self.config.start_ramp_s > 0.0 {
                self.ramp = Some(Ramp {
                    from: measured,
                    start_s: None,
                });
            }
        }
        self.state = Lifecycle::Inactive;
        if self.holds.contains(&Operator::TorqueOff) {
            // The operator turned the torque off: a start or a reconnection leaves it off
            // (configured, measuring) until `set_torque(true)`.
            return Ok(());
        }
        self.backend.activate()?;
        self.state = Lifecycle::Active;
        Ok(())
    }

    /// In Error with reconnection on: retry when due.
    fn retry(&mut self, t_s: f64, events: &mut Vec<Event>) {
        let Some(backoff) = self.config.reconnect else {
            return;
        };
        let Some(at) = self.retry_at_s else {
            self.retry_at_s = Some(t_s + self.retry_delay_s);
            return;
        };
        if t_s < at {
            return;
        }
        match self.configure_and_activate() {
            Ok(()) => {
                self.retry_delay_s = backoff.first_s;
                self.retry_at_s = None;
                self.tripped = false;
                events.push(Event::Reconnected);
            }
            Err(error) => {
                let _ = self.backend.deactivate();
                self.state = Lifecycle::Error;
                self.retry_delay_s = (self.retry_delay_s * 2.0).min(backoff.max_s);
                self.retry_at_s = Some(t_s + self.retry_delay_s);
                events.push(Event::RetryFailed {
                    error,
                    next_in_s: self.retry_delay_s,
                });
            }
        }
    }

    /// Torque off (on shutdown, signals, errors).
    pub fn stop(&mut self) -> Result<(), BackendError> {
        let r = self.backend.deactivate();
        // Stopped on purpose: no later command may turn the torque back on, nor a stop still
        // following the commands move the joints.
        self.tripped = false;
        self.follow = None;
        if self.state != Lifecycle::Unconfigured {
            self.state = Lifecycle::Inactive;
        }
        r
    }

    /// The driven joints, in order.
    pub fn joints(&self) -> &[JointSpec] {
        &self.joints
    }
    /// The lifecycle state.
    pub fn state(&self) -> Lifecycle {
        self.state
    }
    /// True while the watchdog holds or has let go.
    pub fn watchdog_tripped(&self) -> bool {
        self.tripped
    }
    /// The backend.
    pub fn backend(&self) -> &B {
        &self.backend
    }
    /// The backend, to change (tests, diagnostics).
    pub fn backend_mut(&mut self) -> &mut B {
        &mut self.backend
    }
    /// True while the start ramp moves the joints from the measured pose.
    pub fn ramping(&self) -> bool {
        self.ramp.is_some()
    }

    /// The joints are at `pose` (measured), at rest: what is written and output restart there.
    fn rest_at(&mut self, pose: &[f64]) {
        self.output.copy_from_slice(pose);
        self.written.copy_from_slice(pose);
        self.limiter.reset(pose);
    }

    /// Torque on after it was off: start from the measured pose (ramping to the commands
    /// like a start), else from the output (a backend that cannot measure), at rest.
    fn torque_on_from_measured(&mut self) -> Result<(), BackendError> {
        if let Some(m) = self.measured.clone() {
            self.rest_at(&m);
            if self.config.start_ramp_s > 0.0 {
                self.ramp = Some(Ramp {
                    from: m,
                    start_s: None,
                });
            }
        } else {
            let at = self.limiter.position_rad().to_vec();
            self.limiter.reset(&at);
        }
        self.backend.activate()?;
        self.state = Lifecycle::Active;
        Ok(())
    }

    /// The target becomes where the joints come to rest braking now (less the sag offset
    /// the written pose carries): a hold never turns a joint back.
    fn hold_where_heading(&mut self) {
        let stop = self.limiter.stopping_point_rad(&self.motion);
        for ((t, (s, w)), (o, spec)) in self
            .target
            .iter_mut()
            .zip(stop.iter().zip(&self.written))
            .zip(self.output.iter().zip(&self.joints))
        {
            *t = spec.clamp(s - (w - o));
        }
    }

    /// Why commands are ignored, if they are: the first operator hold ([`Operator`] order).
    pub fn operator(&self) -> Option<Operator> {
        self.holds.first().copied()
    }

    /// Holds where the joints come to rest and ignores commands until `why` is released
    /// (an emergency stop, the node going inactive). The torque stays as it is.
    pub fn hold(&mut self, why: Operator) {
        self.follow = None;
        if self.state == Lifecycle::Active {
            self.hold_where_heading();
        }
        self.ramp = None;
        self.holds.insert(why);
        self.said_ignored = false;
    }

    /// Releases `why`; once nothing holds, commands are taken again, approached from where
    /// the joints hold through the limiter. Returns false if `why` was not holding.
    pub fn release(&mut self, why: Operator) -> bool {
        if !self.holds.remove(&why) {
            return false;
        }
        if self.follow.as_ref().is_some_and(|f| f.by == why) {
            self.follow = None;
        }
        self.said_ignored = false;
        if self.holds.is_empty() {
            // The watchdog starts afresh: silence during the hold is no timeout.
            self.last_command_s = None;
            self.tripped = false;
        }
        true
    }

    /// Emergency stop: [`Self::hold`] until [`Self::release_estop`], at once or, with
    /// [`BridgeConfig::estop_follow_s`], after following a commanded stop along the path
    /// while the commands keep coming and moving (while nothing else holds the bridge). A
    /// second stop while it follows holds at once.
    pub fn estop(&mut self) {
        self.stop_along(Operator::Estop);
    }

    /// [`Self::hold`] for `by`, at once or, with [`BridgeConfig::estop_follow_s`], after
    /// following a commanded stop along the path as [`Self::estop`] does (while nothing
    /// else holds the bridge; otherwise at once). The lifecycle's deactivate uses it with
    /// [`Operator::Inactive`]: a walk deactivated mid-step is braked along its path, not
    /// frozen under a moving body.
    pub fn stop_along(&mut self, by: Operator) {
        let following = self.config.estop_follow_s > 0.0
            && self.state == Lifecycle::Active
            && self.holds.is_empty()
            && !self.tripped
            && self.last_command_s.is_some();
        match self.last_tick_s {
            Some(t_s) if following => {
                // The first command after the stop is a move (NaN matches nothing): the
                // node ticks right after a stop it serves, with the tick's command taken.
                self.follow = Some(Follow {
                    by,
                    from_s: t_s,
                    until_s: t_s + self.config.estop_follow_s,
                    commanded: false,
                    last_target: vec![f64::NAN; self.target.len()],
                });
                self.holds.insert(by);
                self.said_ignored = false;
            }
            _ => self.hold(by),
        }
    }

    /// True while an emergency stop still follows the commands to rest.
    pub fn estop_following(&self) -> bool {
        self.following() == Some(Operator::Estop)
    }

    /// Who stops along the path ([`Self::stop_along`]) while the commands are still
    /// followed to rest.
    pub fn following(&self) -> Option<Operator> {
        self.follow.as_ref().map(|f| f.by)
    }

    /// Releases an emergency stop. Returns false if none was on.
    pub fn release_estop(&mut self) -> bool {
        self.release(Operator::Estop)
    }

    /// Torque off (commands ignored until it is on again) or on: from the measured pose,
    /// holding it, commands taken again. Refused in [`Lifecycle::Unconfigured`] and
    /// [`Lifecycle::Error`] (start or reconnect first) and while an emergency stop is on.
    pub fn set_torque(&mut self, on: bool) -> Result<(), TorqueError> {
        match (on, self.state) {
            (_, Lifecycle::Unconfigured | Lifecycle::Error) => {
                return Err(TorqueError::NotRunning { state: self.state });
            }
            (true, _) if self.holds.contains(&Operator::Estop) => return Err(TorqueError::Estop),
            (false, _) => {
                self.follow = None;
                self.backend.deactivate()?;
                self.state = Lifecycle::Inactive;
                self.holds.insert(Operator::TorqueOff);
                self.said_ignored = false;
                self.ramp = None;
            }
            (true, Lifecycle::Active) => {
                self.release(Operator::TorqueOff);
            }
            (true, _) => {
                self.torque_on_from_measured()?;
                // Hold the pose found; the next command moves on from it.
                self.target.copy_from_slice(self.limiter.position_rad());
                for (t, spec) in self.target.iter_mut().zip(&self.joints) {
                    *t = spec.clamp(*t);
                }
                self.ramp = None;
                self.release(Operator::TorqueOff);
                self.last_command_s = None;
                self.tripped = false;
            }
        }
        Ok(())
    }

    /// Takes a command received at `t_s`: joint names and positions (rad). Joints not named
    /// keep their targets. Ignored while an operator holds the bridge ([`Operator`]).
    pub fn command(&mut self, t_s: f64, names: &[String], positions_rad: &[f64]) -> Vec<Event> {
        let mut events = Vec::new();
        if self.follow.is_none()
            && let Some(why) = self.operator()
        {
            if !self.said_ignored {
                self.said_ignored = true;
                events.push(Event::Ignored(why));
            }
            return events;
        }
        if names.len() != positions_rad.len() {
            events.push(Event::Malformed {
                names: names.len(),
                positions: positions_rad.len(),
            });
            return events;
        }
        let mut any = false;
        for (name, &value) in names.iter().zip(positions_rad) {
            let Some(&i) = self.index.get(name) else {
                // Remembered to report each once, up to a bound; beyond it, no more reports.
                if self.reported_unknown.len() < MAX_UNKNOWN_REPORTED
                    && self.reported_unknown.insert(name.clone())
                {
                    events.push(Event::UnknownJoint {
                        joint: name.clone(),
                    });
                }
                continue;
            };
            if !value.is_finite() {
                events.push(Event::NonFinite {
                    joint: name.clone(),
                    value,
                });
                continue;
            }
            let clamped = self.joints[i].clamp(value);
            if clamped != value {
                events.push(Event::Clamped {
                    joint: name.clone(),
                    requested_rad: value,
                    clamped_rad: clamped,
                });
            }
            self.target[i] = clamped;
            any = true;
        }
        if any {
            self.last_command_s = Some(t_s);
            if let Some(f) = &mut self.follow {
                f.commanded = true;
            }
            if self.tripped && self.state != Lifecycle::Error {
                self.tripped = false;
                if self.state == Lifecycle::Inactive {
                    // Back from limp: torque on again, from where the joints are now.
                    if let Err(e) = self.torque_on_from_measured() {
                        events.push(Event::BackendFailed(e));
                        return events;
                    }
                }
                events.push(Event::Resumed);
            }
        }
        events
    }

    /// One control period at `t_s`: watchdog, limited write, read back. A tick moves the
    /// joints for at most [`BridgeConfig::max_tick_s`], however long since the last one.
    pub fn tick(&mut self, t_s: f64) -> (Result<Reading, BackendError>, Vec<Event>) {
        let mut events = Vec::new();
        let dt = self
            .last_tick_s
            .map_or(0.0, |l| (t_s - l).max(0.0))
            .min(self.config.max_tick_s);
        self.last_tick_s = Some(t_s);
        if self.state == Lifecycle::Error {
            self.retry(t_s, &mut events);
        }
        if let Some(f) = &mut self.follow {
            // Hold once the time is up, the commands stopped coming or came to rest.
            let silent = self
                .last_command_s
                .is_none_or(|c| t_s - c > FOLLOW_SILENCE_S);
            let at_rest = f.commanded && f.last_target == self.target;
            let end = if at_rest {
                Some(FollowEnd::AtRest)
            } else if silent {
                Some(FollowEnd::Silent)
            } else if t_s >= f.until_s {
                Some(FollowEnd::TimeUp)
            } else {
                None
            };
            if let Some(why) = end {
                let by = f.by;
                events.push(Event::FollowHeld {
                    by,
                    followed_s: t_s - f.from_s,
                    why,
                });
                self.hold(by);
            } else if f.commanded {
                f.commanded = false;
                f.last_target.copy_from_slice(&self.target);
            }
        }
        if self.state == Lifecycle::Active
            && !self.tripped
            && self.holds.is_empty()
            && let Some(last) = self.last_command_s
        {
            let silence = t_s - last;
            if silence > self.config.watchdog_timeout_s {
                self.tripped = true;
                // Hold where the joints come to rest braking now, not where they were heading.
                self.hold_where_heading();
                events.push(Event::WatchdogTripped {
                    silence_s: silence,
                    action: self.config.on_timeout,
                });
                if self.config.on_timeout == TimeoutAction::Limp {
                    if let Err(e) = self.backend.deactivate() {
                        events.push(Event::BackendFailed(e));
                    }
                    self.state = Lifecycle::Inactive;
                }
            }
        }
        if self.state == Lifecycle::Active {
            // The start ramp: from the measured pose to the target, smoothly, beginning at
            // the first tick with a command.
            let mut goal = self.target.clone();
            if let Some(ramp) = &mut self.ramp {
                if ramp.start_s.is_none() && self.last_command_s.is_some() && !self.tripped {
                    ramp.start_s = Some(t_s);
                }
                let a = ramp
                    .start_s
                    .map_or(0.0, |s0| smooth((t_s - s0) / self.config.start_ramp_s));
                for (g, &from) in goal.iter_mut().zip(&ramp.from) {
                    *g = from + (*g - from) * a;
                }
                if a >= 1.0 {
                    self.ramp = None;
                }
            }
            // The sag offset belongs to the goal, and goes through the limiter with it.
            let mut aim = goal.clone();
            if let Some(c) = &mut self.compensation
                && let Err(why) = c.add_to(&goal, &mut aim)
            {
                aim.copy_from_slice(&goal);
                events.push(Event::CompensationFailed(format!(
                    "sag compensation: {why}"
                )));
            }
            if let Some((g, damping)) = &mut self.gyro {
                let on = match g.add_to(t_s, &goal, &mut aim) {
                    Ok(on) => on,
                    Err(why) => {
                        events.push(Event::CompensationFailed(format!("gyro damping: {why}")));
                        false
                    }
                };
                if on != *damping {
                    *damping = on;
                    events.push(Event::GyroDamping(on));
                }
            }
            for (a, spec) in aim.iter_mut().zip(&self.joints) {
                *a = spec.clamp(*a);
            }
            self.limiter.step(&aim, &self.motion, dt);
            for ((w, &x), spec) in self
                .written
                .iter_mut()
                .zip(self.limiter.position_rad())
                .zip(&self.joints)
            {
                *w = spec.clamp(x);
            }
            for ((o, &w), (&a, &g)) in self
                .output
                .iter_mut()
                .zip(&self.written)
                .zip(aim.iter().zip(&goal))
            {
                *o = w - (a - g);
            }
            if let Err(e) = self.backend.write(t_s, &self.written) {
                let _ = self.backend.deactivate();
                self.state = Lifecycle::Error;
                self.retry_at_s = None;
                self.retry_delay_s = self.config.reconnect.map_or(0.0, |b| b.first_s);
                events.extend(
                    self.backend
                        .take_notices()
                        .into_iter()
                        .map(Event::BackendNotice),
                );
                events.push(Event::BackendFailed(e.clone()));
                return (Err(e), events);
            }
        }
        let reading = self.backend.read(t_s);
        if let Ok(r) = &reading
            && r.measured
            && r.positions_rad.len() == self.joints.len()
            && r.positions_rad.iter().all(|v| v.is_finite())
        {
            match &mut self.measured {
                Some(m) => m.copy_from_slice(&r.positions_rad),
                None => self.measured = Some(r.positions_rad.clone()),
            }
        }
        events.extend(
            self.backend
                .take_notices()
                .into_iter()
                .map(Event::BackendNotice),
        );
        (reading, events)
    }
}

impl<B: Backend> Drop for JointBridge<B> {
    fn drop(&mut self) {
        // Torque off whatever happened.
        let _ = self.backend.deactivate();
    }
}
