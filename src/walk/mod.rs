//! `biped walk`: the robot walks in MuJoCo, driven over DDS by the same fleet that drives a
//! real robot, and the walk is measured.
//!
//! 1. Starts `joint_bridge` (backend `sim`, sag compensation), `ik_solver` and
//!    `gait_planner`, all on simulated time, with discovery restricted to this host unless
//!    `ROS_AUTOMATIC_DISCOVERY_RANGE` says otherwise.
//! 2. Sends the walk command (`walk_command`, `start_time` = the settling time) once the
//!    planner listens, then starts `sim_bridge` in lockstep: the command is waiting before
//!    simulated time begins, so the walk starts at the same tick on every run.
//! 3. Records what the fleet publishes (`gait/phase`, `joint_commands`, `joint_states`,
//!    `sim/base_pose`, `sim/cop`, `sim/support_polygon`, `sim/fall`) until the planner is
//!    idle again and the robot has stood for `tail_s`, or it fell.
//! 4. Writes `report.json` and the pictures ([`report`], [`pictures`]); stops the fleet.

pub mod pictures;
pub mod record;
pub mod report;
pub mod work;

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::Context;
use biped_msgs::msg::{
    Clock, GaitPhase, JointState, PointStamped, PolygonStamped, PoseStamped, StringMsg, Time,
    WalkCommand,
};
use gait_planner::{GaitParams, GaitPlanner, GaitSample, WalkRequest};
use node_runtime::DiscoveryRange;
use smol::future::FutureExt as _;

use crate::launch::{Fleet, LaunchOptions};
use record::Recording;
use report::StopKind;

/// What `biped walk` does.
#[derive(Debug, Clone)]
pub struct WalkOptions {
    /// Steps (swings before the closing half step).
    pub steps: u32,
    /// The velocity to walk at (scaled into the step limits); `None`: straight ahead at the
    /// full step.
    pub velocity: Option<gait_planner::Velocity>,
    /// Robot URDF; `None` for the built-in robot.
    pub robot: Option<PathBuf>,
    /// Leg map (the leg joints by name); `None` to find the legs by their axes.
    pub leg_map: Option<PathBuf>,
    /// ROS 2 parameter file for every node (gait and simulator parameters).
    pub params: Option<PathBuf>,
    /// A MuJoCo scene of the robot and its joint map, instead of the URDF-built simulation.
    pub scene: Option<(PathBuf, PathBuf)>,
    /// Output folder.
    pub out: PathBuf,
    /// Pace the simulation at real time (else as fast as the fleet answers).
    pub real_time: bool,
    /// Simulated time the robot stands before the walk starts (s).
    pub settle_s: f64,
    /// Simulated time recorded after the walk ends (s).
    pub tail_s: f64,
    /// Wall-clock seconds without any simulated time passing before giving up.
    pub stall_s: f64,
    /// Record every topic of the walk into this rosbag2 bag (MCAP), from before the fleet
    /// starts until it stops.
    pub bag: Option<PathBuf>,
    /// Instants (s from the walk's start, sorted) at which to call the joint bridge's
    /// `~/estop`, each released by `~/reset` [`ESTOP_HOLD_S`] later.
    pub estop_at_s: Vec<f64>,
    /// Instants (s from the walk's start, sorted) at which to call the gait planner's
    /// `~/pause` true, each released by `~/pause` false [`ESTOP_HOLD_S`] later. Not with
    /// `estop_at_s`.
    pub pause_at_s: Vec<f64>,
    /// Run gait_planner, ik_solver, joint_bridge and sim_bridge in one process (`biped
    /// compose`); the simulator starts paused and is released once the walk command is in.
    pub composed: bool,
    /// The gait planner's `plan_ahead` (a tick ahead of `/clock`) set over any parameter
    /// file; `None` leaves it to the files (`config/sim.yaml`: true).
    pub plan_ahead: Option<bool>,
}

impl WalkOptions {
    /// Which stop the walk is stopped with.
    pub fn stop_kind(&self) -> StopKind {
        if self.pause_at_s.is_empty() {
            StopKind::Estop
        } else {
            StopKind::Pause
        }
    }

    /// The instants of the stops.
    pub fn stop_at_s(&self) -> &[f64] {
        match self.stop_kind() {
            StopKind::Estop => &self.estop_at_s,
            StopKind::Pause => &self.pause_at_s,
        }
    }
}

/// How long each `--estop-at` or `--pause-at` stop holds before its release (s of simulated time); the
/// report measures the first [`report::ESTOP_WINDOW_S`] of it.
pub const ESTOP_HOLD_S: f64 = 2.5;

/// How long (wall time) the recording waits, once the clock has passed the end, for the
/// streams the report measures to get there too; then it measures what came, and says so.
const STREAMS_GRACE: Duration = Duration::from_secs(2);

/// How often (wall time) the recording asks whether a process of the fleet has exited.
const FLEET_LOOK_EVERY: Duration = Duration::from_millis(100);

/// How often (wall time) the recording of a walk faster than real time takes what came: a
/// few ticks of the lockstep (0.2-0.6 ms each), far fewer than its readers keep.
const RECORD_EVERY: Duration = Duration::from_millis(5);

/// The walk's outcome: the report and the files written.
#[derive(Debug)]
pub struct WalkOutcome {
    /// What was measured.
    pub report: report::WalkSummary,
    /// Files written.
    pub files: Vec<PathBuf>,
}

/// The walk's DDS domain, discovery range and the variables the nodes need for them.
struct DdsEnvironment {
    domain: u16,
    range: DiscoveryRange,
    node_env: Vec<(String, String)>,
}

/// Samples a topic the walk's own readers keep until taken: 10 s of ticks at 100 Hz, as
/// the bag recorder (and rosbag2) subscribe.
const RECORDER_DEPTH: usize = 1000;

/// The DDS environment of the walk: the user's, with discovery on this host by default.
fn environment() -> anyhow::Result<DdsEnvironment> {
    let range_set = std::env::var("ROS_AUTOMATIC_DISCOVERY_RANGE").is_ok_and(|v| !v.is_empty());
    let var = |k: &str| {
        if k == "ROS_AUTOMATIC_DISCOVERY_RANGE" && !range_set {
            Some("LOCALHOST".to_owned())
        } else {
            std::env::var(k).ok()
        }
    };
    let (domain, range) = node_runtime::ros_environment_from(var)?;
    crate::launch::refuse_discovery_off(range)?;
    let mut env = Vec::new();
    if !range_set {
        env.push(("ROS_AUTOMATIC_DISCOVERY_RANGE".into(), "LOCALHOST".into()));
    }
    Ok(DdsEnvironment {
        domain,
        range,
        node_env: env,
    })
}

/// The gait parameters the gait_planner node will read from a parameter file (its own and
/// wildcard sections; defaults for what the file does not set).
fn gait_params_of(path: &std::path::Path) -> anyhow::Result<GaitParams> {
    let args = node_runtime::RosArgs {
        params_files: vec![path.display().to_string()],
        ..Default::default()
    };
    let params = node_runtime::node_parameters(&args, "gait_planner", "/")?;
    gait_planner::node::gait_params(&params).with_context(|| path.display().to_string())
}

/// The highest `thread_priority` a parameter file gives any node of the walk's fleet
/// (`None`: none runs under real-time scheduling).
fn fleet_thread_priority(path: &std::path::Path) -> anyhow::Result<Option<u8>> {
    let args = node_runtime::RosArgs {
        params_files: vec![path.display().to_string()],
        ..Default::default()
    };
    let mut highest = None;
    for node in crate::launch::FLEET_NODES {
        let params = node_runtime::node_parameters(&args, node, "/")?;
        if let Some(v) = params.get(node_runtime::THREAD_PRIORITY_PARAM) {
            let p = node_runtime::priority::thread_priority_of(v)
                .with_context(|| format!("{node}'s parameters in {}", path.display()))?;
            highest = highest.max(Some(p));
        }
    }
    Ok(highest)
}

type TriggerClient =
    ros2_client::Client<biped_msgs::srv::TriggerRequest, biped_msgs::srv::TriggerResponse>;
type SetBoolClient =
    ros2_client::Client<biped_msgs::srv::SetBoolRequest, biped_msgs::srv::TriggerResponse>;

/// A client of service `S` at `/<node>/<name>`.
fn service_client<S: biped_msgs::srv::RosService>(
    node: &mut ros2_client::Node,
    of: &str,
    name: &str,
) -> anyhow::Result<ros2_client::Client<S::Request, S::Response>> {
    let qos = node_runtime::qos::service();
    let service = ros2_client::Name::new(&format!("/{of}"), name)
        .map_err(|e| anyhow::anyhow!("service name /{of}/{name}: {e:?}"))?;
    node.create_client(
        ros2_client::ServiceMapping::Enhanced,
        &service,
        &S::service_type_name(),
        qos.clone(),
        qos,
    )
    .map_err(|e| anyhow::anyhow!("client of /{of}/{name}: {e:?}"))
}

/// The services a stop is asked and released with.
enum StopClients {
    /// The joint bridge's `~/estop`, released by `~/reset`.
    Estop {
        estop: TriggerClient,
        reset: Box<TriggerClient>,
    },
    /// The gait planner's `~/pause`: true, released by false.
    Pause(SetBoolClient),
}

impl StopClients {
    fn new(node: &mut ros2_client::Node, kind: StopKind) -> anyhow::Result<Self> {
        use biped_msgs::srv::{SetBool, Trigger};
        Ok(match kind {
            StopKind::Estop => Self::Estop {
                estop: service_client::<Trigger>(node, "joint_bridge", "estop")?,
                reset: Box::new(service_client::<Trigger>(node, "joint_bridge", "reset")?),
            },
            StopKind::Pause => {
                Self::Pause(service_client::<SetBool>(node, "gait_planner", "pause")?)
            }
        })
    }

    /// The service names, for messages.
    fn names(&self) -> &'static str {
        match self {
            Self::Estop { .. } => "/joint_bridge/estop and /joint_bridge/reset",
            Self::Pause(_) => "/gait_planner/pause",
        }
    }

    /// Waits until every service is matched (calls sent before would be lost); false after
    /// 60 s.
    async fn wait(&self, node: &ros2_client::Node) -> bool {
        match self {
            Self::Estop { estop, reset } => {
                within_a_minute(estop.wait_for_service(node)).await
                    && within_a_minute(reset.wait_for_service(node)).await
            }
            Self::Pause(c) => within_a_minute(c.wait_for_service(node)).await,
        }
    }

    /// Asks the stop (`release` false) or its release.
    fn call(&self, release: bool) -> anyhow::Result<ros2_client::RmwRequestId> {
        let failed = |e| anyhow::anyhow!("call {}: {e:?}", self.names());
        match (self, release) {
            (Self::Estop { estop, .. }, false) => {
                estop.send_request(Default::default()).map_err(failed)
            }
            (Self::Estop { reset, .. }, true) => {
                reset.send_request(Default::default()).map_err(failed)
            }
            (Self::Pause(c), _) => c
                .send_request(biped_msgs::srv::SetBoolRequest { data: !release })
                .map_err(failed),
        }
    }

    /// True once the answer to `id` (the stop or its release) came.
    fn answered(&self, release: bool, id: &ros2_client::RmwRequestId) -> bool {
        let got = match (self, release) {
            (Self::Estop { estop, .. }, false) => estop.receive_response(),
            (Self::Estop { reset, .. }, true) => reset.receive_response(),
            (Self::Pause(c), _) => c.receive_response(),
        };
        matches!(got, Ok(Some((got, _))) if got == *id)
    }
}

/// True if `fut` ends within 60 s.
async fn within_a_minute(fut: impl Future<Output = ()>) -> bool {
    async {
        fut.await;
        true
    }
    .or(async {
        smol::Timer::after(Duration::from_secs(60)).await;
        false
    })
    .await
}

/// Where the stops of `--estop-at` or `--pause-at` are.
enum StopState {
    /// Waiting for the next instant.
    Idle,
    /// The stop asked, not answered yet.
    Asked(ros2_client::RmwRequestId),
    /// Holding since the answer.
    Holding,
    /// The release asked, not answered yet.
    Releasing(ros2_client::RmwRequestId),
}

/// The walk time lost so far to the stops (ns): from each call to its release's answer, all
/// of it while the bridge holds; for a pause, the brake's half of its time and the resume's
/// other half add up to the same.
fn held_ns(rec: &Recording) -> i64 {
    rec.stops
        .iter()
        .filter_map(|e| e.reset_ns.map(|r| r - e.requested_ns))
        .sum()
}

/// When the stop held now is released (ns): [`ESTOP_HOLD_S`] after its answer.
fn release_ns(rec: &Recording) -> i64 {
    let since = rec.stops.last().and_then(|e| e.answered_ns);
    since.map_or(rec.clock_ns, |s| s + (ESTOP_HOLD_S * 1e9).round() as i64)
}

/// Asks a stop at each instant and its release [`ESTOP_HOLD_S`] after its answer. The
/// simulator (`wait_for_run_until`) runs only to the next of these instants, on
/// `/sim_bridge/run_until`, and waits there while a call is out: each call goes at the first
/// tick at or after its instant, once the fleet has answered that tick, and is answered
/// before the next tick, however loaded the machine (the nodes answer at the simulator's
/// repeats of the tick and act from the next one).
struct StopDriver {
    /// The instants, in simulated time had nothing held (ns): each hold (the planner
    /// pauses) puts the later ones off by its length.
    at_ns: std::collections::VecDeque<i64>,
    clients: StopClients,
    state: StopState,
    /// The simulator's bound, `/sim_bridge/run_until` (latched).
    run_until: ros2_client::Publisher<Clock>,
    /// The bound last sent (ns).
    sent_ns: Option<i64>,
    /// The joint bridge's answers to the simulator's ticks (`/sim/joint_commands`).
    answers: ros2_client::Subscription<JointState>,
    /// The newest tick answered (ns): the planner, IK and bridge are done with it.
    answered_tick_ns: i64,
}

impl StopDriver {
    /// Where the simulator may run to now (ns): the next instant while idle, the release's
    /// instant while holding, where it is while a call is out; no bound after the last stop.
    fn bound_ns(&self, rec: &Recording) -> i64 {
        let held_ns = held_ns(rec);
        match self.state {
            StopState::Idle => self.at_ns.front().map_or(i64::MAX, |t| t + held_ns),
            StopState::Holding => release_ns(rec),
            StopState::Asked(_) | StopState::Releasing(_) => rec.clock_ns,
        }
    }

    /// Sends the simulator's bound if it changed.
    fn send_bound(&mut self, rec: &Recording) -> anyhow::Result<()> {
        let b = self.bound_ns(rec);
        if self.sent_ns != Some(b) {
            self.run_until
                .publish(Clock {
                    clock: Time::from_nanos(b),
                })
                .map_err(|e| anyhow::anyhow!("publish /sim_bridge/run_until: {e:?}"))?;
            self.sent_ns = Some(b);
        }
        Ok(())
    }

    fn poll(&mut self, rec: &mut Recording) -> anyhow::Result<()> {
        self.step(rec)?;
        self.send_bound(rec)
    }

    fn step(&mut self, rec: &mut Recording) -> anyhow::Result<()> {
        let now = rec.clock_ns;
        let held_ns = held_ns(rec);
        while let Ok(Some((m, _))) = self.answers.take() {
            self.answered_tick_ns = self.answered_tick_ns.max(m.header.stamp.to_nanos());
        }
        // A call goes once the fleet is done with the tick the simulator holds: the nodes then
        // take it at a repeat of that tick and act from the next, whichever way the messages
        // race (taken during the tick, it would act from this one on some runs).
        let tick_done = self.answered_tick_ns >= now;
        match &self.state {
            StopState::Idle => {
                if tick_done && self.at_ns.front().is_some_and(|&t| now - held_ns >= t) {
                    self.at_ns.pop_front();
                    let id = self.clients.call(false)?;
                    rec.stops.push(record::StopEvent {
                        requested_ns: now,
                        answered_ns: None,
                        reset_ns: None,
                    });
                    self.state = StopState::Asked(id);
                }
            }
            StopState::Asked(id) => {
                if self.clients.answered(false, id) {
                    if let Some(e) = rec.stops.last_mut() {
                        e.answered_ns = Some(now);
                    }
                    self.state = StopState::Holding;
                }
            }
            StopState::Holding => {
                if tick_done && now >= release_ns(rec) {
                    self.state = StopState::Releasing(self.clients.call(true)?);
                }
            }
            StopState::Releasing(id) => {
                if self.clients.answered(true, id) {
                    if let Some(e) = rec.stops.last_mut() {
                        e.reset_ns = Some(now);
                    }
                    self.state = StopState::Idle;
                }
            }
        }
        Ok(())
    }
}

/// The work so far of the fleet's processes and this one (its recorder), and the datagrams
/// of the network namespace; `None` where `/proc` cannot tell (not Linux).
fn run_work(fleet: &Fleet) -> Option<work::Work> {
    let mut processes = fleet.named_pids();
    processes.push(("biped_walk", std::process::id()));
    work::Work::now(&processes).ok()
}

/// Runs the walk.
pub fn walk(o: &WalkOptions) -> anyhow::Result<WalkOutcome> {
    if !o.estop_at_s.is_empty() && !o.pause_at_s.is_empty() {
        anyhow::bail!("--estop-at and --pause-at: one kind of stop per walk");
    }
    let role_map = crate::leg_map_of(o.leg_map.as_deref())?;
    let model = crate::model_of(o.robot.as_deref(), role_map.as_ref())?;
    let params = match &o.params {
        Some(p) => gait_params_of(p)?,
        None => GaitParams::default(),
    };
    // A parameter out of its bounds is refused before anything starts.
    params.check_bounds(&model)?;
    // The offline plan of the same walk: what the planner node will publish, tick for tick.
    // Built on another thread while the fleet starts: the planner node runs the same timing
    // search at its start, and on two cores the two no longer wait for each other (the first
    // tick comes ~0.45 s sooner). A plan refused here stops the fleet started meanwhile.
    let planning = {
        let (model, velocity, steps) = (model.clone(), o.velocity, o.steps);
        std::thread::spawn(move || -> anyhow::Result<(GaitPlanner, Vec<GaitSample>)> {
            let mut planner = GaitPlanner::new(model, params)?;
            if let Some(v) = velocity {
                // The same conversion the planner node makes of the command's velocity.
                crate::plan::apply_twist(&mut planner, v)?;
            }
            let plan = planner.plan(WalkRequest::Steps(steps))?;
            Ok((planner, plan))
        })
    };
    std::fs::create_dir_all(&o.out)
        .with_context(|| format!("cannot create output folder {}", o.out.display()))?;
    // The recorder is the walk's measuring instrument: with the fleet's nodes under real-time
    // scheduling it would fall behind them on a busy machine and miss samples (the fleet's
    // publishers drop what a slow observer cannot take). It runs at their priority, its DDS
    // threads too (started below, they inherit it), and so do the nodes it starts, unless
    // their own `thread_priority` says otherwise.
    if let Some(priority) = o
        .params
        .as_deref()
        .map(fleet_thread_priority)
        .transpose()?
        .flatten()
    {
        node_runtime::priority::run_this_thread_realtime(priority)
            .context("the walk's recorder, at the fleet's `thread_priority`")?;
    }

    let DdsEnvironment {
        domain,
        range,
        node_env: env,
    } = environment()?;
    let mut node_params = vec![(
        "sim_bridge".to_string(),
        format!(
            "real_time_factor:={}",
            if o.real_time { "1.0" } else { "0.0" }
        ),
    )];
    if o.composed {
        // The simulator starts with the other nodes in their process: it waits at t = 0
        // until the walk command is in (step 1 below releases it).
        node_params.push(("sim_bridge".into(), "start_paused:=true".into()));
    }
    if let Some(ahead) = o.plan_ahead {
        node_params.push(("gait_planner".into(), format!("plan_ahead:={ahead}")));
    }
    if !o.stop_at_s().is_empty() {
        // The stops hold simulated time while their calls are out ([`StopDriver`]).
        node_params.push(("sim_bridge".into(), "wait_for_run_until:=true".into()));
    }
    if let Some((scene, map_file)) = &o.scene {
        // Checked here, so a bad scene is refused before anything starts; its servos'
        // stiffness is the joint bridge's compensation stiffness.
        let urdf = match &o.robot {
            Some(p) => std::fs::read_to_string(p)
                .with_context(|| format!("cannot read robot {}", p.display()))?,
            None => ik_solver::DEFAULT_URDF.to_owned(),
        };
        let map = sim_bridge::JointMap::from_yaml_file(map_file)
            .with_context(|| format!("joint map {}", map_file.display()))?;
        let sim = sim_bridge::Sim::from_mjcf_file(
            scene,
            &map,
            &urdf,
            role_map.as_ref(),
            &Default::default(),
        )
        .with_context(|| {
            format!(
                "scene {} with joint map {}",
                scene.display(),
                map_file.display()
            )
        })?;
        let abs = |p: &PathBuf| {
            std::fs::canonicalize(p).with_context(|| format!("{} not found", p.display()))
        };
        node_params.push((
            "sim_bridge".into(),
            format!("mjcf_file:={}", abs(scene)?.display()),
        ));
        node_params.push((
            "sim_bridge".into(),
            format!("joint_map_file:={}", abs(map_file)?.display()),
        ));
        node_params.push((
            "joint_bridge".into(),
            format!("sag_compensation_kp:={}", sim.config().kp_nm_per_rad),
        ));
    }
    let recording = match &o.bag {
        Some(dir) => Some(crate::bag::record::Background::start(
            crate::bag::record::RecordOptions {
                dir: dir.clone(),
                topics: Vec::new(),
                all: true,
                duration_s: None,
                storage: crate::bag::storage::StorageKind::Mcap,
                progress_period_s: 0.0,
            },
            domain,
            range,
        )?),
        None => None,
    };
    let options = LaunchOptions {
        backend: "sim".into(),
        robot: o.robot.clone(),
        leg_map: o.leg_map.clone(),
        params: o.params.clone(),
        namespace: "/".into(),
        log_dir: o.out.join("logs"),
        node_params,
        env,
        serial: Default::default(),
        // A walk is a measurement: a node that dies fails it.
        respawn: None,
        composed: o.composed,
    };
    // The simulator last, once the planner has the walk command (below).
    let nodes = options.nodes();
    let mut fleet = Fleet::new(options)?;
    for node in nodes.into_iter().filter(|n| *n != "sim_bridge") {
        fleet.spawn(node)?;
    }
    let planned = planning
        .join()
        .map_err(|_| anyhow::anyhow!("the walk's offline plan panicked"))
        .and_then(|p| p);
    let (planner, plan) = match planned {
        Ok(p) => p,
        Err(e) => {
            // Refused (the planner node refuses it too): nothing left running, the bag closed.
            fleet.stop(false);
            if let Some(r) = recording {
                let _ = r.finish();
            }
            return Err(e);
        }
    };
    let plan_duration_s = plan.last().map_or(0.0, |s| s.t_s) - plan.first().map_or(0.0, |s| s.t_s);

    let context = node_runtime::context_for(domain, range)?;
    let mut node = node_runtime::create_node(
        &context,
        "biped_walk",
        "/",
        &Default::default(),
        None,
        false,
    )?;
    let qos = node_runtime::qos::default();
    // The walk's measurements read every tick: the simulator does not wait for this
    // process, so its readers keep up to RECORDER_DEPTH samples a topic (as the bag
    // recorder's), not the default 10 that a stall of this process's thread on a busy
    // machine overflows (a CI run lost two seconds of simulated ticks so).
    let deep = qos.clone().history(ros2_client::qos::History::KeepLast {
        depth: RECORDER_DEPTH,
    });
    macro_rules! sub {
        ($ty:ty, $name:literal) => {{
            let topic = node
                .create_topic(
                    &node_runtime::topic_name(&Default::default(), "/", $name)?,
                    <$ty as biped_msgs::RosMessage>::message_type_name(),
                    &qos,
                )
                .map_err(|e| anyhow::anyhow!("topic {}: {e:?}", $name))?;
            node.create_subscription::<$ty>(&topic, Some(deep.clone()))
                .map_err(|e| anyhow::anyhow!("subscription {}: {e:?}", $name))?
        }};
    }
    let clock = sub!(Clock, "/clock");
    let phase = sub!(GaitPhase, "/gait/phase");
    let commands = sub!(JointState, "/joint_commands");
    let states = sub!(JointState, "/joint_states");
    let base = sub!(PoseStamped, "/sim/base_pose");
    let cop = sub!(PointStamped, "/sim/cop");
    let support = sub!(PolygonStamped, "/sim/support_polygon");
    let fall = sub!(StringMsg, "/sim/fall");
    let walk_topic = node
        .create_topic(
            &node_runtime::topic_name(&Default::default(), "/", "/walk_command")?,
            <WalkCommand as biped_msgs::RosMessage>::message_type_name(),
            &qos,
        )
        .map_err(|e| anyhow::anyhow!("topic /walk_command: {e:?}"))?;
    let walk_pub = node
        .create_publisher::<WalkCommand>(&walk_topic, None)
        .map_err(|e| anyhow::anyhow!("publisher /walk_command: {e:?}"))?;
    let mut rec = Recording::default();
    let mut stops = if o.stop_at_s().is_empty() {
        None
    } else {
        let start_ns = (o.settle_s * 1e9).round() as i64;
        let topic = node
            .create_topic(
                &node_runtime::topic_name(&Default::default(), "/", "/sim_bridge/run_until")?,
                <Clock as biped_msgs::RosMessage>::message_type_name(),
                &node_runtime::qos::latched(),
            )
            .map_err(|e| anyhow::anyhow!("topic /sim_bridge/run_until: {e:?}"))?;
        let run_until = node
            .create_publisher::<Clock>(&topic, None)
            .map_err(|e| anyhow::anyhow!("publisher /sim_bridge/run_until: {e:?}"))?;
        let mut d = StopDriver {
            at_ns: o
                .stop_at_s()
                .iter()
                .map(|t| start_ns + (t * 1e9).round() as i64)
                .collect(),
            clients: StopClients::new(&mut node, o.stop_kind())?,
            state: StopState::Idle,
            run_until,
            sent_ns: None,
            answers: sub!(JointState, "/sim/joint_commands"),
            answered_tick_ns: i64::MIN,
        };
        // The first bound, before the simulator starts (it waits at t = 0 without one).
        d.send_bound(&rec)?;
        Some(d)
    };
    let sim_pause = if o.composed {
        Some(service_client::<biped_msgs::srv::SetBool>(
            &mut node,
            "sim_bridge",
            "pause",
        )?)
    } else {
        None
    };
    let spinner = node
        .spinner()
        .map_err(|e| anyhow::anyhow!("spinner: {e:?}"))?;
    let executor = smol::LocalExecutor::new();
    executor.spawn(spinner.spin()).detach();

    // Ctrl-C or SIGTERM ends the walk as a failure, but cleanly: the fleet is stopped and a
    // bag being recorded is closed, complete.
    let interrupted = node_runtime::shutdown_flag()?;
    let wall0 = Instant::now();
    let mut first_clock_wall: Option<Instant> = None;
    // The run's processes' work at the first `/clock`, that clock (ns), and the shortest
    // step of `/clock` since: the tick (a reader may miss a value, never see a shorter one).
    let mut work0: Option<(work::Work, i64)> = None;
    let mut tick_ns: Option<i64> = None;
    let result: anyhow::Result<()> = node_runtime::wait::block_on(executor.run(async {
        // 1. The planner listens: send the command, a few times (it ignores repeats of a
        //    stamped command), then start the simulator. Another subscriber of walk_command
        //    (a recorder, a user's tool) can make the count non-zero before the planner's
        //    subscription matches, so the command is also resent until simulated time
        //    reaches its start time (step 2): by then the planner is ticking.
        let deadline = Instant::now() + Duration::from_secs(60);
        while walk_pub.get_subscription_count(&node) == 0 {
            if interrupted.load(std::sync::atomic::Ordering::SeqCst) {
                anyhow::bail!("interrupted before the walk started");
            }
            if let Some(why) = fleet.failed() {
                anyhow::bail!("{why}");
            }
            if Instant::now() > deadline {
                anyhow::bail!(
                    "the gait_planner did not subscribe walk_command within 60 s; see {}",
                    o.out.join("logs").display()
                );
            }
            smol::Timer::after(Duration::from_millis(50)).await;
        }
        let velocity = o.velocity.unwrap_or_default();
        let command = WalkCommand {
            steps: o.steps,
            start_time: Time::from_nanos((o.settle_s * 1e9).round() as i64),
            velocity: biped_msgs::msg::Twist {
                linear: biped_msgs::msg::Vector3 {
                    x: velocity.x_m_s,
                    y: velocity.y_m_s,
                    z: 0.0,
                },
                angular: biped_msgs::msg::Vector3 {
                    x: 0.0,
                    y: 0.0,
                    z: velocity.yaw_rad_s,
                },
            },
            ..WalkCommand::default()
        };
        for _ in 0..3 {
            walk_pub
                .publish(command.clone())
                .map_err(|e| anyhow::anyhow!("publish walk_command: {e:?}"))?;
            smol::Timer::after(Duration::from_millis(100)).await;
        }
        if let Some(d) = &stops
            && !d.clients.wait(&node).await
        {
            anyhow::bail!("the services {} were not found within 60 s", d.clients.names());
        }
        match &sim_pause {
            None => fleet.spawn("sim_bridge")?,
            Some(c) => {
                // Composed, the simulator runs already, paused at t = 0: let it go.
                if !within_a_minute(c.wait_for_service(&node)).await {
                    anyhow::bail!("the service /sim_bridge/pause was not found within 60 s");
                }
                let id = c
                    .send_request(biped_msgs::srv::SetBoolRequest { data: false })
                    .map_err(|e| anyhow::anyhow!("call /sim_bridge/pause: {e:?}"))?;
                let deadline = Instant::now() + Duration::from_secs(60);
                while !matches!(c.receive_response(), Ok(Some((got, _))) if got == id) {
                    if let Some(why) = fleet.failed() {
                        anyhow::bail!("{why}");
                    }
                    if Instant::now() > deadline {
                        anyhow::bail!("/sim_bridge/pause did not answer within 60 s");
                    }
                    smol::Timer::after(Duration::from_millis(5)).await;
                }
            }
        }
        println!(
            "walking {} steps in simulation (lockstep{}); the walk starts at t = {:.2} s",
            o.steps,
            if o.real_time { ", real time" } else { "" },
            o.settle_s
        );

        // 2. Record until the walk is over, or the robot fell.
        let mut last_clock_wall = Instant::now();
        let mut last_progress_s = -1.0;
        let mut last_resend = Instant::now();
        // Since when the clock has passed the end while a stream has not (wall time).
        let mut streams_wait: Option<Instant> = None;
        let end_by_s = o.settle_s
            + plan_duration_s
            + o.tail_s
            + 10.0
            + o.stop_at_s().len() as f64 * (ESTOP_HOLD_S + 5.0);
        // In real time, deadlines and the fleet are looked at, without a `/clock`, every
        // 200 ms.
        let mut bound = node_runtime::WaitBound::every(Duration::from_millis(200));
        // The fleet's processes, every `FLEET_LOOK_EVERY` rather than at every `/clock`
        // (a system call per process: five a tick, where ticks come every half millisecond).
        let mut fleet_looked_at = Instant::now();
        let mut clocks = Vec::new();
        loop {
            // Faster than real time, what came is taken every `RECORD_EVERY` (a few ticks
            // at once) rather than at each `/clock`: the readers keep it (RECORDER_DEPTH),
            // and this thread, which nothing in the lockstep waits for, then takes a CPU
            // from the fleet's tick a few times less.
            if o.real_time {
                if let Some(Ok((c, _))) = bound.within(clock.async_take()).await {
                    clocks.push(c.clock.to_nanos());
                }
            } else {
                smol::Timer::after(RECORD_EVERY).await;
            }
            while let Ok(Some((c, _))) = clock.take() {
                clocks.push(c.clock.to_nanos());
            }
            let first = first_clock_wall.is_none() && !clocks.is_empty();
            for ns in clocks.drain(..) {
                if first_clock_wall.is_some() && ns > rec.clock_ns {
                    tick_ns = Some(tick_ns.map_or(ns - rec.clock_ns, |t| t.min(ns - rec.clock_ns)));
                }
                rec.clock_ns = rec.clock_ns.max(ns);
                last_clock_wall = Instant::now();
                first_clock_wall.get_or_insert(last_clock_wall);
            }
            if first {
                // Read now, the work counts from the newest clock taken.
                work0 = run_work(&fleet).map(|w| (w, rec.clock_ns));
            }
            rec.drain(&phase, &commands, &states, &base, &cop, &support, &fall);
            if let Some(d) = &mut stops {
                d.poll(&mut rec)?;
            }
            if interrupted.load(std::sync::atomic::Ordering::SeqCst) {
                anyhow::bail!(
                    "interrupted at t = {:.2} s of simulated time",
                    rec.clock_ns as f64 * 1e-9
                );
            }
            if rec.clock_ns < command.start_time.to_nanos()
                && last_resend.elapsed() >= Duration::from_millis(20)
            {
                last_resend = Instant::now();
                walk_pub
                    .publish(command.clone())
                    .map_err(|e| anyhow::anyhow!("publish walk_command: {e:?}"))?;
            }
            if fleet_looked_at.elapsed() >= FLEET_LOOK_EVERY {
                fleet_looked_at = Instant::now();
                if let Some(why) = fleet.failed() {
                    anyhow::bail!("{why}");
                }
            }
            let t = rec.clock_ns as f64 * 1e-9;
            if t - last_progress_s >= 2.0 {
                last_progress_s = t;
                println!("  {}", rec.progress_line());
            }
            if let Some(end_ns) = rec.end_ns(o.tail_s)
                && rec.clock_ns >= end_ns
            {
                // The clock can overtake the streams it stamps: the report measures every
                // tick up to the end, so wait for them (in lockstep the simulator runs on
                // meanwhile, and they come within a few ticks).
                if rec.received_through(end_ns) {
                    break;
                }
                let waited = *streams_wait.get_or_insert_with(Instant::now);
                if waited.elapsed() > STREAMS_GRACE {
                    eprintln!(
                        "warning: the recording ends at t = {:.2} s without every stream \
                         there (joint states to {}); the report measures what came",
                        end_ns as f64 * 1e-9,
                        rec.states
                            .last_key_value()
                            .map_or("none".to_owned(), |(t, _)| format!("{:.2} s", *t as f64 * 1e-9))
                    );
                    break;
                }
            }
            // (While it waits for the streams after the end, the simulator may run past this.)
            if t > end_by_s && streams_wait.is_none() {
                anyhow::bail!(
                    "the walk did not end by t = {end_by_s:.1} s of simulated time (planned {plan_duration_s:.1} s); see {}",
                    o.out.join("logs").display()
                );
            }
            if last_clock_wall.elapsed() > Duration::from_secs_f64(o.stall_s) {
                anyhow::bail!(
                    "simulated time stood still at {t:.2} s for {:.0} s; see {}",
                    o.stall_s,
                    o.out.join("logs").display()
                );
            }
        }
        Ok(())
    }));
    let wall_s = wall0.elapsed().as_secs_f64();
    let stepping_wall_s = first_clock_wall.map_or(wall_s, |t| t.elapsed().as_secs_f64());
    let work_per_tick = work0.and_then(|(w0, clock0_ns)| {
        let ticks = u64::try_from((rec.clock_ns - clock0_ns) / tick_ns?).ok()?;
        run_work(&fleet)?.per_tick_since(&w0, ticks)
    });
    fleet.stop(false);
    // Close the bag even when the walk failed: it is how the failure is looked at.
    let recorded = recording.map(|r| r.finish()).transpose();
    result?;
    let recorded = recorded?;
    let summary = report::summarize(
        &model,
        &planner,
        &plan,
        &rec,
        o,
        report::WallTimes {
            total_s: wall_s,
            stepping_s: stepping_wall_s,
            work_per_tick,
        },
    )?;
    let mut files = Vec::new();
    let report_path = o.out.join("report.json");
    std::fs::write(
        &report_path,
        serde_json::to_string_pretty(&summary).context("report to JSON")? + "\n",
    )
    .with_context(|| format!("cannot write {}", report_path.display()))?;
    files.push(report_path);
    files.extend(pictures::write_pictures(
        &o.out, &model, &planner, &plan, &rec, &summary,
    )?);
    if let (Some(dir), Some(r)) = (&o.bag, &recorded) {
        println!(
            "recorded {} messages on {} topics into {}",
            r.total,
            r.counts.len(),
            dir.display()
        );
        files.push(dir.join("metadata.yaml"));
    }
    Ok(WalkOutcome {
        report: summary,
        files,
    })
}
