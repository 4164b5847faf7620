//! Starting a node: what it knows before DDS ([`NodeSetup`]: arguments, name, namespace,
//! parameters), the ros2-client node with parameter services and `/rosout`, shutdown on
//! SIGINT/SIGTERM or when `biped launch` is gone, and [`RosNode`]: typed publishers and
//! subscriptions on resolved topic names, logging, and the executor.

use std::collections::BTreeMap;
use std::future::Future;

use biped_msgs::RosMessage;
use ros2_client::{Context, Node, NodeName, NodeOptions, ParameterValue};
use serde_norway::Value;

use crate::affinity::{CPU_AFFINITY_PARAM, bind_this_thread, cpu_affinity_of};
use crate::args::{RosArgs, topic_name};
use crate::context::{SendThread, context_from_env, context_from_env_sending_on};
use crate::cpu_latency::{CPU_DMA_LATENCY_PARAM, CpuLatencyRequest, cpu_dma_latency_of};
use crate::error::RosError;
use crate::local::{Bus, Publisher, RosMessageBound, Subscription};
use crate::log::{Log, Throttle};
use crate::params::{ParameterCheck, node_parameters, read_at_startup_only};
use crate::priority::{
    SCHED_FIFO, THREAD_PRIORITY_PARAM, run_this_thread_realtime, thread_priority_of,
};
use crate::qos;

/// Creates a node with parameter services and `/rosout` on, with the given parameters
/// declared; `use_sim_time` makes its clock follow `/clock`.
pub fn create_node(
    context: &Context,
    name: &str,
    namespace: &str,
    declared: &BTreeMap<String, ParameterValue>,
    on_set: Option<ParameterCheck>,
    use_sim_time: bool,
) -> Result<Node, RosError> {
    let ns = if namespace.starts_with('/') {
        namespace.to_owned()
    } else {
        format!("/{namespace}")
    };
    let node_name = NodeName::new(&ns, name)
        .map_err(|e| RosError::Args(format!("node name `{ns}/{name}`: {e:?}")))?;
    let mut options = NodeOptions::new()
        .enable_rosout(true)
        .start_parameter_services(true);
    for (k, v) in declared {
        options = options.declare_parameter(k, v.clone());
    }
    // ros2-client validates the declared values too as it makes the node: those are the
    // start-up values, which the node has read already. Once it is made, every set goes to
    // the node's check, one back to a start-up value too (else the store would say that
    // value while the node kept the one set before).
    let starting = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(true));
    if let Some(f) = on_set {
        let initial = declared.clone();
        let starting = starting.clone();
        options =
            options.parameter_validator(Box::new(move |name: &str, value: &ParameterValue| {
                if starting.load(std::sync::atomic::Ordering::SeqCst)
                    && initial.get(name) == Some(value)
                {
                    Ok(())
                } else {
                    f(name, value)
                }
            }));
    }
    let node = context
        .new_node(node_name, options)
        .map_err(|e| RosError::Dds {
            what: format!("node {name}"),
            message: format!("{e:?}"),
        })?;
    starting.store(false, std::sync::atomic::Ordering::SeqCst);
    if use_sim_time {
        node.set_parameter("use_sim_time", ParameterValue::Boolean(true))
            .map_err(|e| RosError::Params(format!("use_sim_time: {e}")))?;
    }
    Ok(node)
}

/// What a node knows before it touches DDS: its ROS arguments, name, namespace and
/// parameters (files, then `-p`).
#[derive(Debug, Clone)]
pub struct NodeSetup {
    /// The parsed `--ros-args`.
    pub args: RosArgs,
    /// Arguments before `--ros-args` (nodes take none; `--help` prints usage).
    pub own_args: Vec<String>,
    /// Node name (default, or `-r __node:=`).
    pub name: String,
    /// Namespace (`/`, or `-r __ns:=`).
    pub namespace: String,
    /// This node's parameters from the files and `-p`, dotted names.
    pub params: BTreeMap<String, Value>,
}

impl NodeSetup {
    /// From the process's command line.
    pub fn from_env(default_name: &str) -> Result<Self, RosError> {
        Self::from_args(std::env::args().skip(1), default_name)
    }

    /// From a command line (without the program name).
    pub fn from_args(
        args: impl IntoIterator<Item = String>,
        default_name: &str,
    ) -> Result<Self, RosError> {
        let (own_args, args) = RosArgs::parse(args, default_name)?;
        let name = args
            .node_name
            .clone()
            .unwrap_or_else(|| default_name.to_owned());
        let namespace = args.namespace.clone().unwrap_or_else(|| "/".to_owned());
        let params = node_parameters(&args, &name, &namespace)?;
        Ok(Self {
            args,
            own_args,
            name,
            namespace,
            params,
        })
    }

    /// An error naming the arguments before `--ros-args`, if any: the fleet's nodes take
    /// only ROS arguments.
    pub fn only_ros_args(&self) -> Result<(), RosError> {
        if self.own_args.is_empty() {
            Ok(())
        } else {
            Err(RosError::Args(format!(
                "unexpected arguments {:?}; the node takes only --ros-args (see the README)",
                self.own_args
            )))
        }
    }

    /// The `use_sim_time` parameter (false unless set true).
    pub fn use_sim_time(&self) -> bool {
        self.params
            .get("use_sim_time")
            .and_then(Value::as_bool)
            .unwrap_or(false)
    }

    /// The CPUs of the `cpu_affinity` parameter ([`crate::affinity`]); `None`: not bound.
    pub fn cpu_affinity(&self) -> Result<Option<Vec<usize>>, RosError> {
        match self.params.get(CPU_AFFINITY_PARAM) {
            None => Ok(None),
            Some(v) => cpu_affinity_of(v),
        }
    }

    /// The microseconds of the `cpu_dma_latency_us` parameter ([`crate::cpu_latency`]);
    /// `None`: no request.
    pub fn cpu_dma_latency_us(&self) -> Result<Option<u32>, RosError> {
        self.params
            .get(CPU_DMA_LATENCY_PARAM)
            .map(cpu_dma_latency_of)
            .transpose()
    }

    /// The `SCHED_FIFO` priority of the `thread_priority` parameter ([`crate::priority`]);
    /// `None`: the normal scheduler.
    pub fn thread_priority(&self) -> Result<Option<u8>, RosError> {
        self.params
            .get(THREAD_PRIORITY_PARAM)
            .map(thread_priority_of)
            .transpose()
    }

    /// A string parameter, or `default`.
    pub fn str_param(&self, name: &str, default: &str) -> Result<String, RosError> {
        match self.params.get(name) {
            None => Ok(default.to_owned()),
            Some(Value::String(s)) => Ok(s.clone()),
            Some(other) => Err(RosError::Params(format!(
                "parameter `{name}` must be a string, not {other:?}"
            ))),
        }
    }

    /// A boolean parameter, or `default`.
    pub fn bool_param(&self, name: &str, default: bool) -> Result<bool, RosError> {
        match self.params.get(name) {
            None => Ok(default),
            Some(Value::Bool(b)) => Ok(*b),
            Some(other) => Err(RosError::Params(format!(
                "parameter `{name}` must be true or false, not {other:?}"
            ))),
        }
    }

    /// A number parameter, or `default`.
    pub fn f64_param(&self, name: &str, default: f64) -> Result<f64, RosError> {
        match self.params.get(name) {
            None => Ok(default),
            Some(v) => v.as_f64().filter(|x| x.is_finite()).ok_or_else(|| {
                RosError::Params(format!(
                    "parameter `{name}` must be a finite number, not {v:?}"
                ))
            }),
        }
    }
}

/// A start-up error as a node prints it: with its sources (`error: source: ...`), e.g. the
/// kernel's answer under a refused binding or latency request.
pub(crate) fn printed(e: RosError) -> String {
    format!("{:#}", anyhow::Error::new(e))
}

/// The `main` of a node alone in its process: its setup from the command line, the process
/// bound to the CPUs of `cpu_affinity` if set, under real-time scheduling at
/// `thread_priority` if set, the CPU latency request of `cpu_dma_latency_us` held if set,
/// its host ([`Host::process`]), then `run` on this thread until it ends; an error is
/// printed as `<name>: error: ...` and fails the process.
pub fn node_main<E: std::fmt::Display, F: Future<Output = Result<(), E>>>(
    name: &str,
    run: impl FnOnce(NodeSetup, Host) -> F,
) -> std::process::ExitCode {
    let result = (|| {
        let setup = NodeSetup::from_env(name).map_err(printed)?;
        // Before any other thread starts: the DDS and signal threads inherit it.
        if let Some(cpus) = setup.cpu_affinity().map_err(printed)? {
            bind_this_thread(&cpus).map_err(printed)?;
        }
        if let Some(priority) = setup.thread_priority().map_err(printed)? {
            run_this_thread_realtime(priority).map_err(printed)?;
        }
        // Held until the process ends (the kernel drops it with the file, however it ends).
        let _latency = setup
            .cpu_dma_latency_us()
            .and_then(|us| us.map(CpuLatencyRequest::hold).transpose())
            .map_err(printed)?;
        let host = Host::process().map_err(printed)?;
        crate::wait::block_on(run(setup, host)).map_err(|e| format!("{e:#}"))
    })();
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("{name}: error: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// The environment variable through which `biped launch` gives its nodes its process id.
pub const LAUNCH_PARENT_ENV: &str = "BIPED_LAUNCH_PARENT";

/// Set by SIGINT or SIGTERM: the node's loops end, torque goes off, DDS says goodbye.
pub fn shutdown_flag() -> Result<std::sync::Arc<std::sync::atomic::AtomicBool>, RosError> {
    let flag = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let f = flag.clone();
    ctrlc::set_handler(move || f.store(true, std::sync::atomic::Ordering::SeqCst)).map_err(
        |e| RosError::Dds {
            what: "signal handler".into(),
            message: e.to_string(),
        },
    )?;
    // Started by `biped launch`: also stop when the launcher is gone, so a launcher killed
    // without a chance to clean up leaves no node running.
    if let Some(parent) = std::env::var(LAUNCH_PARENT_ENV)
        .ok()
        .and_then(|p| p.parse::<u32>().ok())
    {
        let f = flag.clone();
        std::thread::spawn(move || {
            while !f.load(std::sync::atomic::Ordering::SeqCst) {
                if std::os::unix::process::parent_id() != parent {
                    f.store(true, std::sync::atomic::Ordering::SeqCst);
                }
                std::thread::sleep(std::time::Duration::from_millis(200));
            }
        });
    }
    Ok(flag)
}

/// Where a node runs: alone in its process ([`Host::process`]) or composed with others in
/// one ([`Host::composed`]: one DDS participant, messages between them delivered
/// in-process), and the flag that stops it.
#[derive(Clone)]
pub struct Host {
    context: Context,
    bus: Option<std::sync::Arc<Bus>>,
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
}

impl std::fmt::Debug for Host {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Host")
            .field("composed", &self.bus.is_some())
            .field("stop", &self.stop)
            .finish()
    }
}

impl Host {
    /// A node alone in its process: the DDS domain of the environment, stopped by SIGINT or
    /// SIGTERM (or when `biped launch` is gone). Once per process.
    pub fn process() -> Result<Self, RosError> {
        Ok(Self {
            context: context_from_env()?,
            bus: None,
            stop: shutdown_flag()?,
        })
    }

    /// Nodes composed in one process, each with a clone of this host (on one thread or
    /// each on its own): one DDS participant (the environment's domain) for all of them,
    /// and a message one of them publishes reaches the others in-process (and outside
    /// peers on DDS, sent by the participant's DDS thread: [`SendThread::Dds`]). `stop`
    /// ends them all.
    pub fn composed(stop: std::sync::Arc<std::sync::atomic::AtomicBool>) -> Result<Self, RosError> {
        Ok(Self {
            context: context_from_env_sending_on(SendThread::Dds)?,
            bus: Some(std::sync::Arc::new(Bus::default())),
            stop,
        })
    }

    /// Composed with other nodes in one process ([`Host::composed`]).
    pub fn is_composed(&self) -> bool {
        self.bus.is_some()
    }

    /// The flag that stops the node's loops (set: stop).
    pub fn stop_flag(&self) -> std::sync::Arc<std::sync::atomic::AtomicBool> {
        self.stop.clone()
    }

    /// Asks every node of this host to stop.
    pub fn request_stop(&self) {
        self.stop.store(true, std::sync::atomic::Ordering::SeqCst);
    }
}

/// A started node: the DDS context, the ros2-client node, its setup and its log, with
/// helpers that create typed publishers and subscriptions on resolved topic names.
pub struct RosNode {
    /// The node.
    pub node: Node,
    /// What it was started with.
    pub setup: NodeSetup,
    /// Console + `/rosout`.
    pub log: Log,
    // The node's DDS participant (the node keeps it alive through this).
    context: Context,
    /// The process's in-process topics, when composed.
    bus: Option<std::sync::Arc<Bus>>,
    /// The throttled messages: once a second per key.
    throttled: std::sync::Mutex<Throttle>,
}

impl std::fmt::Debug for RosNode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RosNode")
            .field("node", &self.node.fully_qualified_name())
            .finish()
    }
}

fn dds_err(what: String) -> impl FnOnce(ros2_client::ros2::CreateError) -> RosError {
    move |e| RosError::Dds {
        what,
        message: format!("{e:?}"),
    }
}

impl RosNode {
    /// Creates the node on its host's DDS participant, with its declared parameters and
    /// parameter check.
    pub fn start(
        host: &Host,
        setup: NodeSetup,
        declared: &BTreeMap<String, ParameterValue>,
        check: Option<ParameterCheck>,
    ) -> Result<Self, RosError> {
        let context = host.context.clone();
        // `cpu_affinity`, `cpu_dma_latency_us` and `thread_priority` (applied at start-up by
        // `node_main`, or `biped compose`) are declared, so a peer sees them, and a set from a
        // peer is refused.
        let mut declared = declared.clone();
        if let Some(cpus) = setup.cpu_affinity()? {
            declared.insert(
                CPU_AFFINITY_PARAM.to_owned(),
                ParameterValue::IntegerArray(cpus.iter().map(|&c| c as i64).collect()),
            );
        }
        let latency_us = setup.cpu_dma_latency_us()?;
        if let Some(us) = latency_us {
            declared.insert(
                CPU_DMA_LATENCY_PARAM.to_owned(),
                ParameterValue::Integer(i64::from(us)),
            );
        }
        if let Some(priority) = setup.thread_priority()? {
            declared.insert(
                THREAD_PRIORITY_PARAM.to_owned(),
                ParameterValue::Integer(i64::from(priority)),
            );
        }
        let check: ParameterCheck = Box::new(move |name: &str, value: &ParameterValue| {
            if [
                CPU_AFFINITY_PARAM,
                CPU_DMA_LATENCY_PARAM,
                THREAD_PRIORITY_PARAM,
            ]
            .contains(&name)
            {
                Err(read_at_startup_only(name))
            } else {
                check.as_ref().map_or(Ok(()), |f| f(name, value))
            }
        });
        let node = create_node(
            &context,
            &setup.name,
            &setup.namespace,
            &declared,
            Some(check),
            setup.use_sim_time(),
        )?;
        let log = Log::new(&node, &setup.args);
        // What the kernel runs this thread under, said once (the policy, not the parameter:
        // `biped compose` may have set a higher priority than this node's).
        if let Ok((SCHED_FIFO, priority)) = crate::priority::this_thread_policy() {
            log.info(
                &node,
                &format!("real-time scheduling: SCHED_FIFO at priority {priority}"),
            );
        }
        // And the CPU latency request with the machine's limit it left (the lowest request
        // any process holds), read back from the device.
        if let Some(us) = latency_us
            && let Ok(limit_us) = crate::cpu_latency::current_limit_us()
        {
            log.info(
                &node,
                &format!("CPU latency request: {us} µs; the machine's limit is now {limit_us} µs"),
            );
        }
        Ok(Self {
            node,
            setup,
            log,
            context,
            bus: host.bus.clone(),
            throttled: std::sync::Mutex::new(Throttle::new(std::time::Duration::from_secs(1))),
        })
    }

    fn topic<M: RosMessage>(
        &self,
        name: &str,
    ) -> Result<ros2_client::dds::rustdds::Topic, RosError> {
        let resolved = self.resolve(name)?;
        self.node
            .create_topic(&resolved, M::message_type_name(), &qos::default())
            .map_err(dds_err(format!("topic {name}")))
    }

    /// A topic or service name as the node uses it: `~/x` is the node's private `<node>/x`;
    /// then remapped, in the namespace.
    fn resolve(&self, name: &str) -> Result<ros2_client::Name, RosError> {
        let private = name
            .strip_prefix("~/")
            .map(|rest| format!("{}/{rest}", self.setup.name));
        topic_name(
            &self.setup.args,
            &self.setup.namespace,
            private.as_deref().unwrap_or(name),
        )
    }

    /// A server of service `S` on `name`: `~/x` is the node's private `<node>/x`; remapped,
    /// in the namespace; ROS's service QoS, the names and types ROS 2 tools call.
    pub fn service<S: biped_msgs::srv::RosService>(
        &mut self,
        name: &str,
    ) -> Result<ros2_client::Server<S::Request, S::Response>, RosError> {
        let resolved = self.resolve(name)?;
        let qos = qos::service();
        self.node
            .create_server::<S::Request, S::Response>(
                ros2_client::ServiceMapping::Enhanced,
                &resolved,
                &S::service_type_name(),
                qos.clone(),
                qos,
            )
            .map_err(dds_err(format!("service {name}")))
    }

    /// A publisher of `M` on topic `name` (`~/x`: the node's private `<node>/x`; remapped, in
    /// the namespace), default QoS.
    pub fn publisher<M: RosMessageBound>(&mut self, name: &str) -> Result<Publisher<M>, RosError> {
        self.publisher_with(name, qos::publisher(), false)
    }

    /// A latched publisher of `M` on topic `name` ([`qos::latched`]: reliable, transient
    /// local, keep last 1), for state a late subscriber must still get.
    pub fn latched_publisher<M: RosMessageBound>(
        &mut self,
        name: &str,
    ) -> Result<Publisher<M>, RosError> {
        self.publisher_with(name, qos::latched(), true)
    }

    fn publisher_with<M: RosMessageBound>(
        &mut self,
        name: &str,
        qos: ros2_client::QosProfile,
        latched: bool,
    ) -> Result<Publisher<M>, RosError> {
        let topic = self.topic::<M>(name)?;
        let dds = self
            .node
            .create_publisher::<M>(&topic, Some(qos))
            .map_err(dds_err(format!("publisher {name}")))?;
        Publisher::new(
            dds,
            self.bus.as_deref(),
            &self.resolve(name)?.to_string(),
            latched,
        )
    }

    /// A subscription to `M` on topic `name` (remapped, in the namespace), default QoS.
    pub fn subscription<M: RosMessageBound>(
        &mut self,
        name: &str,
    ) -> Result<Subscription<M>, RosError> {
        self.subscription_with(name, None, 10, false)
    }

    /// A subscription to `/clock`-like state `M` on topic `name` with [`qos::clock`] (best
    /// effort: it matches best-effort and reliable publishers alike).
    pub fn best_effort_subscription<M: RosMessageBound>(
        &mut self,
        name: &str,
    ) -> Result<Subscription<M>, RosError> {
        self.subscription_with(name, Some(qos::clock()), 100, false)
    }

    /// A subscription to latched state `M` on topic `name` (reliable, transient local, keep
    /// last 1): it gets the last message published before it joined.
    pub fn latched_subscription<M: RosMessageBound>(
        &mut self,
        name: &str,
    ) -> Result<Subscription<M>, RosError> {
        self.subscription_with(name, Some(qos::latched()), 1, true)
    }

    /// `depth`: the in-process queue's, as the QoS's keep last.
    fn subscription_with<M: RosMessageBound>(
        &mut self,
        name: &str,
        qos: Option<ros2_client::QosProfile>,
        depth: usize,
        latched: bool,
    ) -> Result<Subscription<M>, RosError> {
        let mut topic = self.topic::<M>(name)?;
        if self.bus.is_some() {
            // Composed, the bus delivers what the other nodes of the process publish: the
            // DDS reader matches only writers of other participants (RustDDS's QoS
            // IgnoreLocal, patches/README.md), as rclcpp's intra-process subscriptions
            // ignore local publications. ros2-client's QoS profile cannot say it; the
            // topic's QoS can, and the reader's QoS starts from the topic's.
            use ros2_client::dds::rustdds::dds::qos::HasQoSPolicy;
            use ros2_client::dds::rustdds::{QosPolicyBuilder, TopicDescription, policy};
            let ignore_local = QosPolicyBuilder::new()
                .ignore_local(policy::IgnoreLocal::Participant)
                .build();
            topic = self
                .context
                .domain_participant()
                .create_topic(
                    topic.name(),
                    topic.get_type().name().to_owned(),
                    &topic.qos().modify_by(&ignore_local),
                    topic.kind(),
                )
                .map_err(|e| RosError::Dds {
                    what: format!("topic {name}"),
                    message: format!("{e:?}"),
                })?;
        }
        let dds = self
            .node
            .create_subscription::<M>(&topic, qos)
            .map_err(dds_err(format!("subscription {name}")))?;
        Subscription::new(
            dds,
            self.bus.as_deref(),
            &self.resolve(name)?.to_string(),
            depth,
            latched,
        )
    }

    /// The next message of `sub` (topic `topic`), or `None` when `bound` fires first so that
    /// the caller can look at its stop flag. An unreadable message is logged, naming the
    /// topic, and skipped (`None`).
    pub async fn take_within<M: RosMessageBound>(
        &self,
        sub: &Subscription<M>,
        topic: &str,
        bound: &mut crate::WaitBound,
    ) -> Option<M> {
        match bound.within(sub.async_take()).await? {
            Ok((m, _)) => Some(m),
            Err(e) => {
                self.warn(&format!("{topic}: unreadable message dropped: {e:?}"));
                None
            }
        }
    }

    /// The next message of `sub` (topic `topic`) already waiting, if any; an unreadable one is
    /// logged, naming the topic, and skipped.
    pub fn take_next<M: RosMessageBound>(&self, sub: &Subscription<M>, topic: &str) -> Option<M> {
        loop {
            match sub.take() {
                Ok(Some((m, _))) => return Some(m),
                Ok(None) => return None,
                Err(e) => self.warn(&format!("{topic}: unreadable message dropped: {e:?}")),
            }
        }
    }

    /// An executor running the node's spinner (discovery, parameter services, `/clock`).
    pub fn executor(&mut self) -> Result<smol::LocalExecutor<'static>, RosError> {
        let spinner = self.node.spinner().map_err(|e| RosError::Dds {
            what: "spinner".into(),
            message: format!("{e:?}"),
        })?;
        let executor = smol::LocalExecutor::new();
        executor.spawn(spinner.spin()).detach();
        Ok(executor)
    }

    /// Answers request `id` of a trigger-like `server` (a `~/pause`) with `said`, a success,
    /// and logs it; an answer that cannot be sent is logged naming `service`.
    pub fn answer_said<Q: ros2_client::Message + 'static>(
        &self,
        server: &ros2_client::Server<Q, biped_msgs::srv::TriggerResponse>,
        service: &str,
        id: ros2_client::RmwRequestId,
        said: String,
    ) {
        self.info(&said);
        let answer = biped_msgs::srv::TriggerResponse {
            success: true,
            message: said,
        };
        if let Err(e) = server.send_response(id, answer) {
            self.error(&format!("{service}: answer not sent: {e:?}"));
        }
    }

    /// Logs at info.
    pub fn info(&self, msg: &str) {
        self.log.info(&self.node, msg);
    }
    /// Logs a warning.
    pub fn warn(&self, msg: &str) {
        self.log.warn(&self.node, msg);
    }
    /// Logs an error.
    pub fn error(&self, msg: &str) {
        self.log.error(&self.node, msg);
    }

    /// Logs an error at most once a second per `key`, saying how many were held back.
    pub fn error_throttled(&self, key: &str, msg: &str) {
        self.throttled(key, msg, Self::error);
    }

    /// Logs a warning at most once a second per `key`, saying how many were held back.
    pub fn warn_throttled(&self, key: &str, msg: &str) {
        self.throttled(key, msg, Self::warn);
    }

    fn throttled(&self, key: &str, msg: &str, log: fn(&Self, &str)) {
        let Ok(mut t) = self.throttled.lock() else {
            return log(self, msg);
        };
        let line = t.admit(key, msg, std::time::Instant::now());
        drop(t);
        if let Some(line) = line {
            log(self, &line);
        }
    }
}
