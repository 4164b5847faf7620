//! The `gait_planner` ROS 2 node: a thin wrapper over the gait_planner library.
//!
//! - subscribes `cmd_vel` (geometry_msgs/msg/Twist, REP-103: `linear.x` forward or back,
//!   `linear.y` sideways, walked as strides within the step limits, a new one taken at the
//!   next swing; a zero Twist, or none for `cmd_vel_timeout_s`, ends the walk at the next
//!   feet-together point: [`gait_planner::teleop`]) and `walk_command`
//!   (biped_msgs/msg/WalkCommand: N steps, or until stopped, at its velocity or straight
//!   ahead);
//! - publishes `gait/phase` (biped_msgs/msg/GaitPhase) and `gait/ankle_targets`
//!   (biped_msgs/msg/AnkleTargets) at `control_rate_hz`, idle or walking;
//! - publishes `gait/markers` (visualization_msgs/msg/MarkerArray) every tick, in the walk's
//!   frame `odom`: the planned support polygon, the CoM with its margin, and the swinging
//!   foot's landing, for RViz and Foxglove;
//! - subscribes `joint_states` and publishes `odom` (nav_msgs/msg/Odometry, frame `odom`,
//!   child the base link, REP-105): leg odometry of the measured joints with the planted
//!   foot of the plan as the fixed point ([`ik_solver::odometry`]), from the first joint
//!   state that names every joint, and the same pose as the TF edge `odom` → base link on
//!   `/tf` (tf2_msgs/msg/TFMessage), unless `publish_odom_tf` is false (another node, e.g.
//!   robot_localization, owns that edge).
//!
//! - serves `~/pause` (std_srvs/srv/SetBool): `true` brings the walk to rest along its
//!   planned path within `pause_brake_time_s` (the plan's clock slows to a stop,
//!   [`gait_planner::pause`]), `false` brings it back to speed from there. Commands
//!   received while paused wait for the walk's time to move again.
//! - subscribes `joint_bridge/holding` (std_msgs/msg/Bool, latched): while the joint bridge
//!   holds (e-stop, torque off, inactive) the walk brakes to a pause the same way, and comes
//!   back to speed when the hold ends; the bridge's e-stop follows that brake before it
//!   holds (its `estop_follow_s`).
//!
//! Parameters: those of `config/gait.yaml` plus `robot_description_file` (URDF path; empty
//! for the built-in robot) and `publish_odom_tf` (default true), both read at start. Bad commands are refused or clamped with a warning on `/rosout`
//! naming the field and value; the walk in progress is unaffected.
//!
//! The planner is stepped with tick times k / control_rate_hz, not with the measured time, so
//! a walk published here is tick for tick the walk `biped plan` writes. Ticks come from the
//! monotonic clock, or with `use_sim_time` from `/clock` (a repeated `/clock` value, which a
//! lockstep simulator sends while it waits, republishes the tick's messages). A
//! `walk_command` with a `start_time` is taken at the first tick at or after it; the same
//! stamped command received again is taken once; a stop, when taken, also cancels the walks
//! still waiting for their start time; at most 64 commands wait (more are dropped, warned).
//! A `walk_command` with new parameters (its `step_length` or `step_duration`) waits for
//! their check walks (and, with durations left at 0, their timing search), and the commands
//! after it wait for it: on the monotonic clock they run on a thread of their own, so the
//! loop keeps publishing the standing robot's ticks meanwhile (on a robot, a stall of the
//! loop longer than the joint bridge's `watchdog_timeout_s` would trip its watchdog); on
//! simulated time only the timing search does, and the check walks run in the loop, so a
//! lockstep walk starts at the same tick however fast the computer.
//!
//! With `plan_ahead` (read at start; needs `use_sim_time`) tick k's messages go out at the
//! `/clock` of tick k - 1, stamped with tick k's time (at the first tick, both): the joint
//! bridge holds a command until the tick it is stamped for, so it has tick k's when `/clock`
//! k comes, and a lockstep simulator's tick waits for one hop (joint_bridge) instead of
//! three (planner → IK → bridge), the planner and the IK working while the simulator steps.
//! The joints get the same targets at the same ticks; what the planner reads (commands,
//! the bridge's hold, `joint_states` for the odometry and the restart guard) it reads one
//! tick earlier, as a planner a period ahead of its robot would.

mod markers;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use crate::pause::PlanClock;
use crate::standing::STANDING_TOLERANCE_RAD;
use crate::{
    GaitParams, GaitPlanner, GaitSample, PhaseKind, StandGuard, Standing, StartQueue, Stride,
    Velocity, VelocityFollower, WalkRequest,
};
use anyhow::Context as _;
use biped_msgs::msg::{
    AnkleTargets, BoolMsg, Covariance6, GaitPhase, Header, JointState, MarkerArray, Odometry,
    Point, Pose, PoseWithCovariance, TFMessage, Twist, TwistWithCovariance, Vector3, WalkCommand,
};
use biped_msgs::srv::{SetBool, TriggerResponse};
use ik_solver::{AnkleTarget, BipedModel, LegOdometry};
use node_runtime::{Host, NodeSetup, RosNode, TickSource};
use ros2_client::ParameterValue;

const ROBOT_PARAM: &str = "robot_description_file";
const LEG_MAP_PARAM: &str = "leg_map_file";
/// Whether the odometry is also sent as the TF edge odom → base link.
const ODOM_TF_PARAM: &str = "publish_odom_tf";
const STAND_PARAM: &str = "stand_at_start";
/// Whether tick k's messages go out at `/clock` k - 1, a tick ahead (simulated time only).
const AHEAD_PARAM: &str = "plan_ahead";
/// The node's own parameters, beside the gait's ([`GaitParams`]), read at start only.
const NODE_PARAMS: [&str; 5] = [
    ROBOT_PARAM,
    LEG_MAP_PARAM,
    ODOM_TF_PARAM,
    STAND_PARAM,
    AHEAD_PARAM,
];

/// What a check off the control loop answers: the checked planner, or why not.
type CheckResult = Result<GaitPlanner, crate::GaitError>;

/// Runs [`GaitPlanner::new`] for `params` (the check walks, 0.05-0.5 s, with durations left
/// at 0 the timing search before them, 0.3-1.2 s) on its own thread, for the walk command
/// `msg` that waits for it; `None` (logged) if no thread starts.
fn spawn_check(
    ros: &RosNode,
    model: &BipedModel,
    params: GaitParams,
    msg: WalkCommand,
) -> Option<(std::sync::mpsc::Receiver<CheckResult>, WalkCommand)> {
    let (tx, rx) = std::sync::mpsc::channel();
    let model = model.clone();
    let spawned = std::thread::Builder::new()
        .name("gait-check".into())
        .spawn(move || {
            let _ = tx.send(GaitPlanner::new(model, params));
        });
    match spawned {
        Ok(_) => Some((rx, msg)),
        Err(e) => {
            ros.warn(&format!(
                "walk_command refused: no thread to check its parameters on: {e}"
            ));
            None
        }
    }
}

/// The pause brake time in control ticks.
fn brake_ticks(c: &GaitParams) -> u32 {
    (c.pause_brake_time_s * c.control_rate_hz).round() as u32
}

/// Pauses (`on`) or resumes the walk's clock; what was done, for the answer and the log.
fn pause(clock: &mut PlanClock, on: bool, brake_s: f64) -> String {
    let changed = if on { clock.pause() } else { clock.resume() };
    match (on, changed) {
        (true, true) => {
            format!("pause: the walk comes to rest along its path within {brake_s:.2} s")
        }
        (true, false) => "pause: already paused".into(),
        (false, true) => format!("resume: the walk comes back to speed within {brake_s:.2} s"),
        (false, false) => "resume: not paused".into(),
    }
}

/// Answers every `~/pause` request waiting, pausing or resuming the walk's clock.
fn serve_pause(
    ros: &RosNode,
    srv: &ros2_client::Server<biped_msgs::srv::SetBoolRequest, TriggerResponse>,
    clock: &mut PlanClock,
    brake_s: f64,
) {
    while let Ok(Some((id, req))) = srv.receive_request() {
        ros.answer_said(srv, "~/pause", id, pause(clock, req.data, brake_s));
    }
}

/// The gait parameters in the node's parameter map (the robot file, the node's other own
/// parameters and those every node takes aside): what the node reads at start, and what
/// `biped walk` reads from its `--params` file to plan the same walk.
pub fn gait_params(
    params: &std::collections::BTreeMap<String, serde_norway::Value>,
) -> anyhow::Result<GaitParams> {
    let mut map = serde_norway::Mapping::new();
    for (k, v) in params {
        let k_str = k.as_str();
        if !NODE_PARAMS.contains(&k_str) && !node_runtime::COMMON_PARAMS.contains(&k_str) {
            map.insert(serde_norway::Value::String(k.clone()), v.clone());
        }
    }
    serde_norway::from_value(serde_norway::Value::Mapping(map)).context("gait_planner parameters")
}

fn declared(
    params: &GaitParams,
    robot_file: &str,
    leg_map_file: &str,
    odom_tf: bool,
    stand_at_start: bool,
    plan_ahead: bool,
) -> anyhow::Result<std::collections::BTreeMap<String, ParameterValue>> {
    let mut out = std::collections::BTreeMap::new();
    if let serde_norway::Value::Mapping(m) = serde_norway::to_value(params)? {
        for (k, v) in m {
            let name = k.as_str().unwrap_or_default().to_owned();
            out.insert(name.clone(), node_runtime::to_parameter_value(&name, &v)?);
        }
    }
    out.insert(
        ROBOT_PARAM.into(),
        ParameterValue::String(robot_file.into()),
    );
    out.insert(
        LEG_MAP_PARAM.into(),
        ParameterValue::String(leg_map_file.into()),
    );
    out.insert(ODOM_TF_PARAM.into(), ParameterValue::Boolean(odom_tf));
    out.insert(STAND_PARAM.into(), ParameterValue::Boolean(stand_at_start));
    out.insert(AHEAD_PARAM.into(), ParameterValue::Boolean(plan_ahead));
    Ok(out)
}

/// What the node does with a command; pure, so every case is the same whoever sends it.
struct Commands {
    follower: VelocityFollower,
    /// New parameters of a walk command are checked off the control loop even when no
    /// timing search is needed (on the monotonic clock, where the loop must keep ticking);
    /// on simulated time the check walks run in the loop, so that a lockstep walk's start
    /// tick does not depend on how fast the computer is.
    checks_off_loop: bool,
    /// A planner checked for the node's parameters (at start, or by the parameter set that
    /// gave them): a walk command without step values after one with them takes its checks
    /// (and timing search) instead of walking them again.
    base_checks: GaitPlanner,
}

/// The velocity of a Twist (the axes a walker uses), after checking that every one of its
/// six numbers is finite: the error names the first that is not (`{prefix}linear.x = NaN`).
fn velocity_of(tw: &Twist, prefix: &str) -> Result<Velocity, String> {
    for (field, v) in [
        ("linear.x", tw.linear.x),
        ("linear.y", tw.linear.y),
        ("linear.z", tw.linear.z),
        ("angular.x", tw.angular.x),
        ("angular.y", tw.angular.y),
        ("angular.z", tw.angular.z),
    ] {
        if !v.is_finite() {
            return Err(format!("{prefix}{field} = {v} is not a finite number"));
        }
    }
    Ok(Velocity {
        x_m_s: tw.linear.x,
        y_m_s: tw.linear.y,
        yaw_rad_s: tw.angular.z,
    })
}

impl Commands {
    fn cmd_vel(&mut self, planner: &mut GaitPlanner, tw: &Twist, now_s: f64) -> Vec<String> {
        match velocity_of(tw, "") {
            Ok(v) => self
                .follower
                .command(planner, v, now_s)
                .into_iter()
                .collect(),
            Err(e) => vec![format!("cmd_vel refused: {e}")],
        }
    }

    /// Takes a walk command on the node's parameters `base`: its own `step_length` and
    /// `step_duration` are for the walk it starts (a 0 is `base`'s, the configured value, not
    /// a previous command's), so `base` stays what `ros2 param get` says. Returns warnings
    /// to log, and the parameters that must be checked off
    /// the loop before it can walk, if any (a timing search, [`GaitPlanner::needs_timing_search`];
    /// with `checks_off_loop` any check, [`GaitPlanner::needs_check`]): the command waits for
    /// it, nothing else of it is done yet.
    fn walk_command(
        &mut self,
        planner: &mut GaitPlanner,
        c: &WalkCommand,
        base: &GaitParams,
    ) -> (Vec<String>, Option<GaitParams>) {
        let mut check = None;
        let warnings = self.walk_command_or_check(planner, c, base, &mut check);
        (warnings, check)
    }

    fn walk_command_or_check(
        &mut self,
        planner: &mut GaitPlanner,
        c: &WalkCommand,
        base: &GaitParams,
        check: &mut Option<GaitParams>,
    ) -> Vec<String> {
        let mut warnings = Vec::new();
        if c.stop {
            planner.request(WalkRequest::Stop);
            self.follower.release();
            return warnings;
        }
        for (field, v) in [
            ("step_length", c.step_length),
            ("step_duration", c.step_duration),
        ] {
            if !v.is_finite() || v < 0.0 {
                warnings.push(format!(
                    "walk_command refused: {field} = {v} is not a finite number >= 0"
                ));
                return warnings;
            }
        }
        let velocity = match velocity_of(&c.velocity, "velocity.") {
            Ok(v) => v,
            Err(e) => {
                warnings.push(format!("walk_command refused: {e}"));
                return warnings;
            }
        };
        let by_velocity = velocity != Velocity::default();
        if by_velocity && c.step_length > 0.0 {
            warnings.push(format!(
                "walk_command refused: step_length = {} and a velocity are both set; the velocity sets the steps",
                c.step_length
            ));
            return warnings;
        }
        if planner.phase() != PhaseKind::Idle {
            // Parameters change between walks only: the walk in progress keeps its steps. A
            // command asking for other ones is not taken at all (its steps would otherwise
            // change the walk); one giving the walk's own values, or none, goes on.
            let walk = planner.config();
            let other = |given: f64, walking: f64| given > 0.0 && given != walking;
            if other(c.step_length, walk.step_length_m)
                || other(c.step_duration, walk.step_duration_s)
            {
                warnings.push(format!(
                    "walk_command refused: step_length = {}, step_duration = {}: the walk in progress keeps its steps ({} m, {} s); send it again once the walk has ended",
                    c.step_length, c.step_duration, walk.step_length_m, walk.step_duration_s
                ));
                return warnings;
            }
        } else {
            let mut params = base.clone();
            if c.step_length > 0.0 {
                params.step_length_m = c.step_length;
            }
            if c.step_duration > 0.0 {
                params.step_duration_s = c.step_duration;
            }
            if params == *base && planner.needs_check(&params) {
                planner.remember_checks(&self.base_checks);
            }
            if planner.needs_timing_search(&params)
                || (self.checks_off_loop && planner.needs_check(&params))
            {
                *check = Some(params);
                return warnings;
            }
            if let Err(e) = planner.set_params(params) {
                warnings.push(format!(
                    "walk_command refused: step_length = {}, step_duration = {}: {e}",
                    c.step_length, c.step_duration
                ));
                return warnings;
            }
        }
        // A walk command walks at its velocity, or straight ahead at the configured step,
        // and does not time out as a cmd_vel walk does.
        let stride = if by_velocity {
            match planner.stride_for(velocity) {
                Ok(cmd) => {
                    if let Some(l) = cmd.limited_to {
                        warnings.push(format!(
                            "walk_command: velocity linear.x = {}, linear.y = {} m/s is beyond the step limits; walking {:.4}, {:.4} m/s",
                            velocity.x_m_s, velocity.y_m_s, l.x_m_s, l.y_m_s
                        ));
                    }
                    cmd.stride
                }
                Err(e) => {
                    warnings.push(format!("walk_command refused: velocity: {e}"));
                    return warnings;
                }
            }
        } else {
            Stride::forward(planner.config().step_length_m)
        };
        if let Err(e) = planner.set_stride(stride) {
            warnings.push(format!("walk_command refused: {e}"));
            return warnings;
        }
        self.follower.release();
        planner.request(if c.steps == 0 {
            WalkRequest::UntilStop
        } else {
            WalkRequest::Steps(c.steps)
        });
        warnings
    }
}

/// Standard deviation of the odometry's velocity (m/s, rad/s): finite differences of leg
/// odometry at the control rate, servo noise included.
const ODOM_TWIST_SIGMA: (f64, f64) = (0.01, 0.05);

/// `odom`: leg odometry of the measured joints (`joint_states`), with the planted foot of
/// the plan as the fixed point, from the first complete joint state on (the base then is
/// where the plan has it: the odom frame is the walk frame).
struct OdomPublisher {
    q: Vec<f64>,
    seen: Vec<bool>,
    odo: Option<LegOdometry>,
    nonfinite_reported: bool,
}

impl OdomPublisher {
    fn new(model: &BipedModel) -> Self {
        let n = model.robot().dof_count();
        Self {
            q: vec![0.0; n],
            seen: vec![false; n],
            odo: None,
            nonfinite_reported: false,
        }
    }

    /// Takes a measured joint state; returns a warning once for values that are not
    /// finite (the message is then ignored).
    fn joint_states(&mut self, model: &BipedModel, js: &JointState) -> Option<String> {
        if let Some((name, v)) = js
            .name
            .iter()
            .zip(&js.position)
            .find(|(_, v)| !v.is_finite())
        {
            if !self.nonfinite_reported {
                self.nonfinite_reported = true;
                return Some(format!(
                    "odom: joint_states has {name} = {v}; such messages are ignored (reported once)"
                ));
            }
            return None;
        }
        for (name, &v) in js.name.iter().zip(&js.position) {
            if let Some(d) = model.robot().dof_index(name) {
                self.q[d] = v;
                self.seen[d] = true;
            }
        }
        None
    }

    /// The odometry of this tick, once every joint has been measured.
    fn tick(
        &mut self,
        model: &BipedModel,
        sample: &GaitSample,
        dt_s: f64,
        header: Header,
        base_frame: &str,
    ) -> anyhow::Result<Option<Odometry>> {
        if !self.seen.iter().all(|&s| s) {
            return Ok(None);
        }
        let (prev, base) = match &mut self.odo {
            None => {
                let odo = LegOdometry::new(model, sample.base_world, &self.q, sample.planted)?;
                let b = *odo.base();
                self.odo = Some(odo);
                (b, b)
            }
            Some(odo) => {
                let prev = *odo.base();
                (prev, odo.update(model, &self.q, sample.planted)?)
            }
        };
        let Some(odo) = &self.odo else {
            return Ok(None);
        };
        // Velocity in the base frame (REP-105: the twist is in child_frame_id).
        let v =
            base.rotation.inverse() * (base.translation.vector - prev.translation.vector) / dt_s;
        let w = (prev.rotation.inverse() * base.rotation).scaled_axis() / dt_s;
        let mut twist_cov = [0.0; 36];
        for i in 0..6 {
            let sigma = if i < 3 {
                ODOM_TWIST_SIGMA.0
            } else {
                ODOM_TWIST_SIGMA.1
            };
            twist_cov[i * 6 + i] = sigma * sigma;
        }
        Ok(Some(Odometry {
            header: Header {
                frame_id: "odom".into(),
                ..header
            },
            child_frame_id: base_frame.to_owned(),
            pose: PoseWithCovariance {
                pose: Pose::from(&base),
                covariance: Covariance6(odo.covariance()),
            },
            twist: TwistWithCovariance {
                twist: Twist {
                    linear: Vector3 {
                        x: v.x,
                        y: v.y,
                        z: v.z,
                    },
                    angular: Vector3 {
                        x: w.x,
                        y: w.y,
                        z: w.z,
                    },
                },
                covariance: Covariance6(twist_cov),
            },
        }))
    }
}

/// The tick's phase, and the ankle targets `targets` (the sample's, or the held measured
/// pose's; `None`: no targets this tick) as messages.
fn to_msgs(
    s: &GaitSample,
    targets: Option<&[AnkleTarget; 2]>,
    stamp: biped_msgs::msg::Time,
    base_frame: &str,
) -> (GaitPhase, Option<AnkleTargets>) {
    let header = Header {
        stamp,
        frame_id: base_frame.to_owned(),
    };
    let p = |v: &nalgebra::Vector3<f64>| Point {
        x: v.x,
        y: v.y,
        z: v.z,
    };
    let b = &s.base_world.translation.vector;
    (
        GaitPhase {
            header: header.clone(),
            phase: s.phase.as_str().into(),
            support: s.support.as_str().into(),
            step_index: s.step_index,
            progress: s.progress,
        },
        targets.map(|[l, r]| AnkleTargets {
            header,
            left_ankle: p(&l.ankle_in_hip_m),
            right_ankle: p(&r.ankle_in_hip_m),
            left_foot_yaw: l.foot_yaw_rad,
            right_foot_yaw: r.foot_yaw_rad,
            pelvis: p(b),
        }),
    )
}

fn publish(
    ros: &RosNode,
    targets_pub: &node_runtime::Publisher<AnkleTargets>,
    phase_pub: &node_runtime::Publisher<GaitPhase>,
    (phase, targets): &(GaitPhase, Option<AnkleTargets>),
) {
    // One datagram to each reader process for both (`node_runtime::coalesce_sends`).
    node_runtime::coalesce_sends(|| {
        if let Some(targets) = targets
            && let Err(e) = targets_pub.publish(targets.clone())
        {
            ros.error_throttled(
                "publish gait/ankle_targets",
                &format!("publish gait/ankle_targets: {e}"),
            );
        }
        if let Err(e) = phase_pub.publish(phase.clone()) {
            ros.error_throttled("publish gait/phase", &format!("publish gait/phase: {e}"));
        }
    });
}

/// Runs the node with `setup` (its arguments and parameters) on `host` until the host
/// stops: alone in its process (the `gait_planner` binary) or composed with others in one.
pub async fn run(setup: NodeSetup, host: Host) -> anyhow::Result<()> {
    setup.only_ros_args()?;
    let robot_file = setup.str_param(ROBOT_PARAM, "")?;
    let leg_map_file = setup.str_param(LEG_MAP_PARAM, "")?;
    let odom_tf = setup.bool_param(ODOM_TF_PARAM, true)?;
    let stand_at_start = setup.bool_param(STAND_PARAM, true)?;
    let plan_ahead = setup.bool_param(AHEAD_PARAM, false)?;
    let use_sim_time = setup.use_sim_time();
    if plan_ahead && !use_sim_time {
        anyhow::bail!(
            "parameter `{AHEAD_PARAM}` = true needs `use_sim_time` = true: a tick ahead of a lockstep simulator's `/clock`; on the monotonic clock the joint bridge takes each command when it comes, so set `{AHEAD_PARAM}: false` there (`config/sim.yaml`, the defaults of `biped walk` and `biped launch --backend sim`, sets it true)"
        );
    }
    let model = BipedModel::from_parameter_files(&robot_file, &leg_map_file)?;
    let mut params = gait_params(&setup.params)?;
    let mut planner = GaitPlanner::new(model.clone(), params.clone())?;
    let rate = planner.config().control_rate_hz;
    let base_frame = model.robot().links()[model.robot().root()].name.clone();

    // Parameter sets from peers: checked here (a refused set returns its reason to the
    // peer), applied by the loop between walks.
    let walking = Arc::new(AtomicBool::new(false));
    let shared = Arc::new(Mutex::new(params.clone()));
    let (tx, rx) = std::sync::mpsc::channel::<(GaitParams, GaitPlanner)>();
    let check = {
        let (walking, shared, model) = (walking.clone(), shared.clone(), model.clone());
        move |name: &str, value: &ParameterValue| -> Result<(), String> {
            if NODE_PARAMS.contains(&name) {
                return Err(node_runtime::read_at_startup_only(name));
            }
            if name == "use_sim_time" {
                return Ok(());
            }
            if name == "control_rate_hz" {
                return Err(
                    "control_rate_hz is fixed while the node runs; restart it to change the rate"
                        .into(),
                );
            }
            if walking.load(Ordering::SeqCst) {
                return Err(format!(
                    "{name}: gait parameters can change only between walks"
                ));
            }
            let mut candidate = shared.lock().map_err(|e| e.to_string())?.clone();
            let mut map = match serde_norway::to_value(&candidate) {
                Ok(serde_norway::Value::Mapping(m)) => m,
                _ => return Err("internal: parameters do not serialise".into()),
            };
            map.insert(
                serde_norway::Value::String(name.into()),
                node_runtime::from_parameter_value(value),
            );
            candidate = serde_norway::from_value(serde_norway::Value::Mapping(map))
                .map_err(|e| format!("{name}: {e}"))?;
            // The check a walk start does, on a scratch planner (with durations on auto, the
            // timing search too, which the loop then reuses); applied between walks.
            let scratch =
                GaitPlanner::new(model.clone(), candidate.clone()).map_err(|e| e.to_string())?;
            *shared.lock().map_err(|e| e.to_string())? = candidate.clone();
            tx.send((candidate, scratch)).map_err(|e| e.to_string())
        }
    };
    let declared = declared(
        &params,
        &robot_file,
        &leg_map_file,
        odom_tf,
        stand_at_start,
        plan_ahead,
    )?;
    let mut ros = RosNode::start(&host, setup, &declared, Some(Box::new(check)))?;
    let stop = host.stop_flag();
    let phase_pub = ros.publisher::<GaitPhase>("gait/phase")?;
    let targets_pub = ros.publisher::<AnkleTargets>("gait/ankle_targets")?;
    let cmd_vel = ros.subscription::<Twist>("cmd_vel")?;
    let walk_cmd = ros.subscription::<WalkCommand>("walk_command")?;
    let joint_states = ros.subscription::<JointState>("joint_states")?;
    let bridge_holding = ros.latched_subscription::<BoolMsg>("joint_bridge/holding")?;
    let odom_pub = ros.publisher::<Odometry>("odom")?;
    let markers_pub = ros.publisher::<MarkerArray>("gait/markers")?;
    let pause_srv = ros.service::<SetBool>("~/pause")?;
    let tf_pub = if odom_tf {
        Some(ros.publisher::<TFMessage>("/tf")?)
    } else {
        None
    };
    let mut odom = OdomPublisher::new(&model);
    // Not standing the robot up at start (a restart): hold the measured pose until it stands.
    let mut guard = (!stand_at_start).then(|| StandGuard::new(STANDING_TOLERANCE_RAD));
    let mut ticks = TickSource::new(&mut ros, rate)?;
    let executor = ros.executor()?;
    let c = planner.config();
    ros.info(&format!(
            "ready: robot {}, step {:.4} m, {} Hz{}; send biped_msgs/msg/WalkCommand on walk_command or geometry_msgs/msg/Twist on cmd_vel",
            model.robot().name(),
            c.step_length_m,
            c.control_rate_hz,
            if plan_ahead {
                ", a tick ahead of /clock (plan_ahead)"
            } else {
                ""
            }
        ),
    );
    if let Some(auto) = planner.auto_timing_summary() {
        ros.info(&auto);
    }

    let mut commands = Commands {
        follower: VelocityFollower::new(),
        checks_off_loop: !use_sim_time,
        base_checks: planner.clone(),
    };
    let result: anyhow::Result<()> = executor.run(async {
        let mut last_phase = None;
        // Walk commands with a start time still ahead (bounded; a stop empties it).
        let mut pending: StartQueue<WalkCommand> = StartQueue::default();
        let mut last_stamped: Option<WalkCommand> = None;
        // A walk command whose new parameters are being checked (timing searched) off the loop.
        let mut checking: Option<(std::sync::mpsc::Receiver<CheckResult>, WalkCommand)> = None;
        let mut last_sent: Option<(GaitPhase, Option<AnkleTargets>)> = None;
        // The last tick planned, and the tick period on simulated time (ns).
        let mut planned: Option<u64> = None;
        let period_ns = (1e9 / rate).round() as i64;
        // When the joint bridge holds (e-stop, torque off, inactive) the walk's time slows to
        // a stop along the plan, as `~/pause` does: the bridge's e-stop follows the commands
        // (and a deactivate) to that rest before it holds (`estop_follow_s`), so the walk
        // resumes where the joints were held. (A torque-off holds at once: the plan moves on
        // by the rest of the brake, which the bridge's limiter catches up with on release.)
        let mut bridge_holds = false;
        let mut paused_for_bridge = false;
        let mut clock = PlanClock::new(brake_ticks(planner.config()));
        // Ticks since this node started (k counts from the clock's origin).
        let (mut said_waiting, mut ticks_here) = (false, 0u64);
        while !stop.load(Ordering::SeqCst) {
            let Some(tick) = ticks.next().await else {
                continue;
            };
            if tick.repeat {
                // The lockstep simulator asks again for this tick: same messages. A pause
                // asked meanwhile is answered now and brakes from the next tick (a simulator
                // held at `~/run_until` waits for the answer).
                serve_pause(
                    &ros,
                    &pause_srv,
                    &mut clock,
                    planner.config().pause_brake_time_s,
                );
                if let Some(sent) = &last_sent {
                    publish(&ros, &targets_pub, &phase_pub, sent);
                }
                continue;
            }
            // The ticks to plan: this one, and with `plan_ahead` the next too (only the next
            // once the one ahead was planned at the previous tick).
            let last = tick.k + u64::from(plan_ahead);
            let from = match planned {
                Some(p) if p >= tick.k && p < last => p + 1,
                _ => tick.k,
            };
            for k in from..=last {
                let now: biped_msgs::msg::Time = match tick.sim_time {
                    Some(t) => biped_msgs::msg::Time::from_nanos(
                        t.to_nanos() + (k - tick.k) as i64 * period_ns,
                    ),
                    None => ros.node.time_now().into(),
                };
                while let Ok((p, checked)) = rx.try_recv() {
                    planner.remember_checks(&checked);
                    match planner.set_params(p.clone()) {
                        Ok(()) => {
                            params = p;
                            commands.base_checks = checked;
                            clock.set_brake_ticks(brake_ticks(planner.config()));
                            ros.info("parameters changed");
                        }
                        Err(e) => ros.warn(&format!("parameter change not applied: {e}")),
                    }
                }
                if let Some(why) = guard.as_ref().and_then(StandGuard::refusal) {
                    while ros.take_next(&walk_cmd, "walk_command").is_some() {
                        ros.warn(&format!("walk_command refused: {why}"));
                    }
                    while ros.take_next(&cmd_vel, "cmd_vel").is_some() {
                        ros.warn_throttled("cmd_vel refused", &format!("cmd_vel refused: {why}"));
                    }
                }
                while let Some(msg) = ros.take_next(&walk_cmd, "walk_command") {
                    // A stamped command sent again (a sender making sure it arrives) is the same
                    // command: take it once.
                    let repeat = msg.start_time.to_nanos() != 0 && last_stamped.as_ref() == Some(&msg);
                    if !repeat {
                        if msg.start_time.to_nanos() != 0 {
                            last_stamped = Some(msg.clone());
                        }
                        if let Err(e) = pending.push(msg.start_time.to_nanos(), msg) {
                            ros.warn(&format!("walk_command: {e}"));
                        }
                    }
                }
                // A walk command waiting for its parameters' check or timing search (on its own
                // thread, so that the loop keeps ticking): when passed, it is taken as if it
                // came now.
                if let Some((rx, msg)) = checking.take() {
                    match rx.try_recv() {
                        Err(std::sync::mpsc::TryRecvError::Empty) => checking = Some((rx, msg)),
                        Err(std::sync::mpsc::TryRecvError::Disconnected) => {
                            ros.warn("walk_command refused: the check of its parameters stopped");
                        }
                        Ok(Err(e)) => ros.warn(&format!(
                            "walk_command refused: step_length = {}, step_duration = {}: {e}",
                            msg.step_length, msg.step_duration
                        )),
                        Ok(Ok(checked)) => {
                            planner.remember_checks(&checked);
                            match checked.auto_timing_summary() {
                                Some(auto) => ros.info(&auto),
                                None => ros.info(&format!(
                                    "walk_command: step_length = {}, step_duration = {}: the parameters passed their check",
                                    msg.step_length, msg.step_duration
                                )),
                            }
                            let (warnings, again) =
                                commands.walk_command(&mut planner, &msg, &params);
                            for w in warnings {
                                ros.warn(&w);
                            }
                            // Parameters changed meanwhile (a parameter set): check again for
                            // the command on the new ones.
                            if let Some(p) = again {
                                checking = spawn_check(&ros, planner.model(), p, msg);
                            }
                        }
                    }
                }
                // In arrival order, each at its start time (zero: now). A stop also cancels the
                // walks still waiting for their start time: a stop means stop.
                while checking.is_none()
                    && let Some(msg) = pending.take_due(now.to_nanos())
                {
                    if msg.stop {
                        let n = pending.cancel_all();
                        if n > 0 {
                            ros.warn(&format!(
                                "walk_command stop: {n} walk command(s) waiting for their start time cancelled"
                            ));
                        }
                    }
                    let (warnings, check) = commands.walk_command(&mut planner, &msg, &params);
                    for w in warnings {
                        ros.warn(&w);
                    }
                    if let Some(p) = check {
                        ros.info(if planner.needs_timing_search(&p) {
                            "walk_command: new parameters with durations left at 0 (auto): searching their timing; the walk starts when it is found"
                        } else {
                            "walk_command: parameters not checked yet: checking them off the control loop; the walk starts when they pass"
                        });
                        // The commands after it wait for it, in order (the loop's condition).
                        checking = spawn_check(&ros, planner.model(), p, msg);
                    }
                }
                while let Some(h) = ros.take_next(&bridge_holding, "joint_bridge/holding") {
                    if h.data != bridge_holds {
                        bridge_holds = h.data;
                        // A pause the operator asked for stays until the operator resumes.
                        if bridge_holds {
                            paused_for_bridge = clock.pause();
                        } else if paused_for_bridge {
                            paused_for_bridge = false;
                            clock.resume();
                        }
                        ros.warn(if bridge_holds {
                            "the joint bridge holds (e-stop, torque off or inactive): the walk brakes to a pause along its path"
                        } else {
                            "the joint bridge takes commands again: the walk goes on from where it paused"
                        });
                    }
                }
                serve_pause(
                    &ros,
                    &pause_srv,
                    &mut clock,
                    planner.config().pause_brake_time_s,
                );
                ticks_here += 1;
                // Frozen while the bridge holds and the walk is not pausing (an operator resumed
                // it meanwhile): the bridge ignores the commands, so the plan must not move on.
                let t_s = clock.plan_ticks(k, bridge_holds && !clock.pausing()) / rate;
                while let Some(msg) = ros.take_next(&cmd_vel, "cmd_vel") {
                    for w in commands.cmd_vel(&mut planner, &msg, t_s) {
                        ros.warn(&w);
                    }
                }
                if let Some(m) = commands.follower.tick(&mut planner, t_s) {
                    ros.info(&m);
                }
                let sample = match planner.update(t_s) {
                    Ok(s) => s,
                    Err(e) => {
                        ros.error(&format!("planner: {e}"));
                        continue;
                    }
                };
                walking.store(sample.phase != PhaseKind::Idle, Ordering::SeqCst);
                if last_phase != Some((sample.phase, sample.step_index)) {
                    ros.info(&format!(
                        "phase {} ({} support, step {})",
                        sample.phase, sample.support, sample.step_index
                    ));
                    last_phase = Some((sample.phase, sample.step_index));
                }
                while let Some(js) = ros.take_next(&joint_states, "joint_states") {
                    if let Some(w) = odom.joint_states(&model, &js) {
                        ros.warn(&w);
                    }
                    if let Some(g) = &mut guard
                        && let Some(said) =
                            g.measured(&model, &sample.joints_rad, &js.name, &js.position)
                    {
                        if g.clear() {
                            ros.info(&said);
                        } else {
                            ros.warn(&said);
                        }
                    }
                }
                if let Some(g) = &guard
                    && !said_waiting
                    && *g.state() == Standing::Unknown
                    && ticks_here as f64 > 2.0 * rate
                {
                    said_waiting = true;
                    ros.warn("stand_at_start is false and no complete joint_states came in 2 s: publishing no ankle targets until the robot's pose is measured");
                }
                // Not standing yet (a restart): the held measured pose, or (unknown) nothing.
                let targets = match guard.as_ref().filter(|g| !g.clear()) {
                    Some(g) => g.held_targets(),
                    None => Some(&sample.targets),
                };
                let sent = to_msgs(&sample, targets, now, &base_frame);
                publish(&ros, &targets_pub, &phase_pub, &sent);
                let header = Header {
                    stamp: now,
                    frame_id: "odom".into(),
                };
                // Built only while someone looks: the markers are for viewers alone.
                let markers = (markers_pub.subscription_count(&ros) > 0)
                    .then(|| markers::balance_markers(&planner.balance_view(&sample), &header));
                let odom_now = odom.tick(
                    &model,
                    &sample,
                    1.0 / rate,
                    sent.0.header.clone(),
                    &base_frame,
                );
                // The observers' topics: one datagram to each reader process.
                node_runtime::coalesce_sends(|| {
                    if let Some(m) = markers
                        && let Err(e) = markers_pub.publish(m)
                    {
                        ros.error_throttled(
                            "publish gait/markers",
                            &format!("publish gait/markers: {e}"),
                        );
                    }
                    match odom_now {
                        Ok(Some(o)) => {
                            if let Some(tf_pub) = &tf_pub {
                                let tf = TFMessage {
                                    transforms: vec![o.transform()],
                                };
                                if let Err(e) = tf_pub.publish(tf) {
                                    ros.error_throttled(
                                        "publish /tf",
                                        &format!("publish /tf: {e}"),
                                    );
                                }
                            }
                            if let Err(e) = odom_pub.publish(o) {
                                ros.error_throttled(
                                    "publish odom",
                                    &format!("publish odom: {e}"),
                                );
                            }
                        }
                        Ok(None) => {}
                        Err(e) => ros.error_throttled("odom", &format!("odom: {e}")),
                    }
                });
                last_sent = Some(sent);
                planned = Some(k);
            }
        }
        Ok(())
    })
    .await;
    ros.info("shutting down");
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    fn steps(n: u32, step_length: f64) -> WalkCommand {
        WalkCommand {
            steps: n,
            step_length,
            ..WalkCommand::default()
        }
    }

    /// Ticks the planner at 100 Hz from `*t` until it is idle again.
    fn walk_to_the_end(planner: &mut GaitPlanner, t: &mut f64) {
        for _ in 0..100_000 {
            *t += 0.01;
            planner.update(*t).unwrap();
            if planner.is_idle() {
                return;
            }
        }
        panic!("the walk did not end");
    }

    /// A walk command's step values are for the walk it starts, checked in the loop on
    /// simulated time and handed to the check thread on the monotonic clock; during a walk
    /// its own values (or none) go on and others are refused, naming both; after it, a
    /// command without values walks the node's parameters on the checks made for them.
    #[test]
    fn a_walk_commands_step_values_are_for_its_walk_and_a_walk_keeps_its_own() {
        let model = BipedModel::from_urdf_str(ik_solver::DEFAULT_URDF, None).unwrap();
        let base = GaitParams::slow(&model);
        let mut planner = GaitPlanner::new(model, base.clone()).unwrap();
        let mut commands = Commands {
            follower: VelocityFollower::new(),
            checks_off_loop: false,
            base_checks: planner.clone(),
        };
        let (w, check) = commands.walk_command(&mut planner, &steps(2, 0.03), &base);
        assert!(w.is_empty() && check.is_none(), "{w:?}");
        assert_eq!(planner.config().step_length_m, 0.03);
        let mut t = 0.0;
        planner.update(t).unwrap();
        assert_ne!(planner.phase(), PhaseKind::Idle);

        for same in [steps(2, 0.03), steps(2, 0.0)] {
            let (w, check) = commands.walk_command(&mut planner, &same, &base);
            assert!(w.is_empty() && check.is_none(), "{w:?}");
        }
        let (w, check) = commands.walk_command(&mut planner, &steps(2, 0.04), &base);
        assert!(check.is_none());
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].contains("refused: step_length = 0.04") && w[0].contains("(0.03 m"),
            "{w:?}"
        );
        assert_eq!(planner.config().step_length_m, 0.03);
        walk_to_the_end(&mut planner, &mut t);

        commands.checks_off_loop = true;
        let (w, check) = commands.walk_command(&mut planner, &steps(1, 0.035), &base);
        assert!(w.is_empty(), "{w:?}");
        assert_eq!(check.map(|p| p.step_length_m), Some(0.035));
        assert_eq!(planner.config().step_length_m, 0.03);
        // The node's parameters: the checks made for them at start, none to walk again.
        let (w, check) = commands.walk_command(&mut planner, &steps(1, 0.0), &base);
        assert!(w.is_empty() && check.is_none(), "{w:?} {check:?}");
        assert_eq!(planner.config().step_length_m, base.step_length_m);
    }
}
