//! What every node of the fleet shares: the ROS 2 command line (`--ros-args`), parameter
//! files, the DDS context from the standard environment variables, QoS profiles, and
//! logging to the console and `/rosout` at once.

use std::collections::BTreeMap;
use std::net::{IpAddr, Ipv4Addr};

use ros2_client::ros2::LogLevel;
use ros2_client::{Context, Name, Node, NodeName, NodeOptions, ParameterValue, rosout};
use serde_norway::{Mapping, Value};

/// Why a node could not start.
#[derive(Debug, thiserror::Error)]
pub enum RosError {
    /// A bad `--ros-args` argument.
    #[error("bad --ros-args: {0}")]
    Args(String),
    /// A parameter file that cannot be read or parsed, or a bad parameter.
    #[error("parameters: {0}")]
    Params(String),
    /// A bad ROS environment variable.
    #[error("environment variable {name}={value}: {why}")]
    Env {
        /// The variable.
        name: &'static str,
        /// Its value.
        value: String,
        /// What is wrong.
        why: String,
    },
    /// DDS or ros2-client refused to create something.
    #[error("{what}: {message}")]
    Dds {
        /// What was being created.
        what: String,
        /// The library's message.
        message: String,
    },
}

/// The ROS part of a node's command line: what follows `--ros-args` (until `--`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RosArgs {
    /// Topic and service remaps `from` → `to` (`-r from:=to`).
    pub remaps: Vec<(String, String)>,
    /// Node name override (`-r __node:=name`).
    pub node_name: Option<String>,
    /// Namespace override (`-r __ns:=/ns`).
    pub namespace: Option<String>,
    /// Parameter files, in order (`--params-file FILE`).
    pub params_files: Vec<String>,
    /// Single parameters (`-p name:=value`), the value parsed as YAML.
    pub params: Vec<(String, Value)>,
    /// `--log-level`.
    pub log_level: Option<String>,
}

impl RosArgs {
    /// Splits a command line into the node's own arguments and the ROS arguments.
    /// Remaps and parameters may be prefixed with `node_name:` to target one node; others are
    /// dropped.
    pub fn parse(
        args: impl IntoIterator<Item = String>,
        node: &str,
    ) -> Result<(Vec<String>, RosArgs), RosError> {
        let mut own = Vec::new();
        let mut ros = RosArgs::default();
        let mut it = args.into_iter();
        let mut in_ros = false;
        while let Some(a) = it.next() {
            if a == "--ros-args" {
                in_ros = true;
                continue;
            }
            if !in_ros {
                own.push(a);
                continue;
            }
            let mut value = |flag: &str| {
                it.next()
                    .ok_or_else(|| RosError::Args(format!("{flag} needs a value")))
            };
            match a.as_str() {
                "--" => in_ros = false,
                "-r" | "--remap" => {
                    let v = value(&a)?;
                    if let Some((from, to)) = targeted(&v, node)? {
                        match from.as_str() {
                            "__node" | "__name" => ros.node_name = Some(to),
                            "__ns" => ros.namespace = Some(to),
                            _ => ros.remaps.push((from, to)),
                        }
                    }
                }
                "-p" | "--param" => {
                    let v = value(&a)?;
                    if let Some((name, text)) = targeted(&v, node)? {
                        let parsed = serde_norway::from_str(&text).map_err(|e| {
                            RosError::Args(format!("-p {v}: value `{text}` is not YAML: {e}"))
                        })?;
                        ros.params.push((name, parsed));
                    }
                }
                "--params-file" => ros.params_files.push(value(&a)?),
                "--log-level" => ros.log_level = Some(value(&a)?),
                "-e" | "--enclave" => {
                    value(&a)?;
                }
                other => return Err(RosError::Args(format!("unknown ROS argument `{other}`"))),
            }
        }
        Ok((own, ros))
    }
}

/// `[node:]from:=to` → `(from, to)` if it is for `node` (or for every node).
fn targeted(arg: &str, node: &str) -> Result<Option<(String, String)>, RosError> {
    let (lhs, rhs) = arg
        .split_once(":=")
        .ok_or_else(|| RosError::Args(format!("`{arg}` is not of the form name:=value")))?;
    let (target, lhs) = match lhs.split_once(':') {
        Some((t, l)) if !t.starts_with('/') || !l.is_empty() => (Some(t), l),
        _ => (None, lhs),
    };
    if lhs.is_empty() {
        return Err(RosError::Args(format!("`{arg}` has an empty name")));
    }
    Ok(match target {
        Some(t) if t != node => None,
        _ => Some((lhs.to_owned(), rhs.to_owned())),
    })
}

fn flatten(prefix: &str, value: &Value, out: &mut BTreeMap<String, Value>) {
    match value {
        Value::Mapping(m) => {
            for (k, v) in m {
                let key = k
                    .as_str()
                    .map(String::from)
                    .unwrap_or_else(|| format!("{k:?}"));
                let name = if prefix.is_empty() {
                    key
                } else {
                    format!("{prefix}.{key}")
                };
                flatten(&name, v, out);
            }
        }
        other => {
            out.insert(prefix.to_owned(), other.clone());
        }
    }
}

/// The parameters of node `node` in namespace `namespace` from ROS 2 parameter files (the
/// `/**` wildcard section, then `node`, `/node`, `ns/node` or `/ns/node`, nested mappings as
/// dotted names), then the `-p` overrides. Sections of other nodes are ignored.
pub fn node_parameters(
    args: &RosArgs,
    node: &str,
    namespace: &str,
) -> Result<BTreeMap<String, Value>, RosError> {
    let ns = namespace.trim_matches('/');
    let fqn = if ns.is_empty() {
        format!("/{node}")
    } else {
        format!("/{ns}/{node}")
    };
    let mut out = BTreeMap::new();
    for path in &args.params_files {
        let text = std::fs::read_to_string(path)
            .map_err(|e| RosError::Params(format!("cannot read {path}: {e}")))?;
        let doc: Value =
            serde_norway::from_str(&text).map_err(|e| RosError::Params(format!("{path}: {e}")))?;
        let top = doc.as_mapping().cloned().unwrap_or_else(Mapping::new);
        for pass in 0..2 {
            for (k, v) in &top {
                let key = k.as_str().unwrap_or_default();
                let section = if key.starts_with('/') {
                    key.to_owned()
                } else {
                    format!("/{key}")
                };
                let wildcard = key == "/**";
                let ours = section == fqn
                    || (ns.is_empty() && section == format!("/{node}"))
                    || section == format!("/**/{node}")
                    || key == node;
                if (pass == 0 && !wildcard) || (pass == 1 && !ours) {
                    continue;
                }
                let params = v.get("ros__parameters").ok_or_else(|| {
                    RosError::Params(format!("{path}: section `{key}` has no `ros__parameters`"))
                })?;
                flatten("", params, &mut out);
            }
        }
    }
    for (name, value) in &args.params {
        out.insert(name.clone(), value.clone());
    }
    Ok(out)
}

/// A YAML value as a ROS parameter value.
pub fn to_parameter_value(name: &str, v: &Value) -> Result<ParameterValue, RosError> {
    let bad = || {
        RosError::Params(format!(
            "parameter `{name}`: value {v:?} has no ROS parameter type"
        ))
    };
    Ok(match v {
        Value::Bool(b) => ParameterValue::Boolean(*b),
        Value::Number(n) if n.is_i64() => ParameterValue::Integer(n.as_i64().ok_or_else(bad)?),
        Value::Number(n) => ParameterValue::Double(n.as_f64().ok_or_else(bad)?),
        Value::String(s) => ParameterValue::String(s.clone()),
        Value::Sequence(items) => {
            if items.iter().all(Value::is_bool) {
                ParameterValue::BooleanArray(items.iter().filter_map(Value::as_bool).collect())
            } else if items.iter().all(Value::is_i64) {
                ParameterValue::IntegerArray(items.iter().filter_map(Value::as_i64).collect())
            } else if items.iter().all(Value::is_number) {
                ParameterValue::DoubleArray(items.iter().filter_map(Value::as_f64).collect())
            } else if items.iter().all(Value::is_string) {
                ParameterValue::StringArray(
                    items
                        .iter()
                        .filter_map(|s| s.as_str().map(String::from))
                        .collect(),
                )
            } else {
                return Err(bad());
            }
        }
        _ => return Err(bad()),
    })
}

/// A ROS parameter value as YAML, to feed a node's typed parameter struct.
pub fn from_parameter_value(v: &ParameterValue) -> Value {
    match v {
        ParameterValue::NotSet => Value::Null,
        ParameterValue::Boolean(b) => Value::Bool(*b),
        ParameterValue::Integer(i) => Value::from(*i),
        ParameterValue::Double(d) => Value::from(*d),
        ParameterValue::String(s) => Value::String(s.clone()),
        ParameterValue::ByteArray(b) => {
            Value::Sequence(b.iter().map(|x| Value::from(*x)).collect())
        }
        ParameterValue::BooleanArray(b) => {
            Value::Sequence(b.iter().map(|x| Value::Bool(*x)).collect())
        }
        ParameterValue::IntegerArray(b) => {
            Value::Sequence(b.iter().map(|x| Value::from(*x)).collect())
        }
        ParameterValue::DoubleArray(b) => {
            Value::Sequence(b.iter().map(|x| Value::from(*x)).collect())
        }
        ParameterValue::StringArray(b) => {
            Value::Sequence(b.iter().map(|x| Value::String(x.clone())).collect())
        }
    }
}

/// The DDS discovery range of `ROS_AUTOMATIC_DISCOVERY_RANGE` (and the older
/// `ROS_LOCALHOST_ONLY=1`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DiscoveryRange {
    /// Only this machine (127.0.0.1).
    Localhost,
    /// The default: the local networks.
    Subnet,
}

/// Reads `ROS_DOMAIN_ID` (0–232, default 0) and the discovery range from the environment.
pub fn ros_environment() -> Result<(u16, DiscoveryRange), RosError> {
    ros_environment_from(|name| std::env::var(name).ok())
}

/// [`ros_environment`] over any variable lookup (for tests and embedding).
pub fn ros_environment_from(
    var: impl Fn(&str) -> Option<String>,
) -> Result<(u16, DiscoveryRange), RosError> {
    let domain = match var("ROS_DOMAIN_ID") {
        Some(v) if !v.trim().is_empty() => {
            let id: u16 = v.trim().parse().map_err(|_| RosError::Env {
                name: "ROS_DOMAIN_ID",
                value: v.clone(),
                why: "not a number".into(),
            })?;
            if id > 232 {
                return Err(RosError::Env {
                    name: "ROS_DOMAIN_ID",
                    value: v,
                    why: "must be within 0..=232".into(),
                });
            }
            id
        }
        _ => 0,
    };
    let range = match var("ROS_AUTOMATIC_DISCOVERY_RANGE")
        .unwrap_or_default()
        .to_ascii_uppercase()
        .as_str()
    {
        "LOCALHOST" | "OFF" => DiscoveryRange::Localhost,
        "" | "SYSTEM_DEFAULT" | "SUBNET" => {
            if var("ROS_LOCALHOST_ONLY").as_deref() == Some("1") {
                DiscoveryRange::Localhost
            } else {
                DiscoveryRange::Subnet
            }
        }
        other => {
            return Err(RosError::Env {
                name: "ROS_AUTOMATIC_DISCOVERY_RANGE",
                value: other.to_owned(),
                why: "expected LOCALHOST, SUBNET, OFF or SYSTEM_DEFAULT".into(),
            });
        }
    };
    Ok((domain, range))
}

/// A DDS context for the environment's domain and discovery range. With LOCALHOST, DDS
/// traffic stays on 127.0.0.1.
pub fn context_from_env() -> Result<Context, RosError> {
    let (domain, range) = ros_environment()?;
    context_for(domain, range)
}

/// A DDS context for a domain and discovery range. With LOCALHOST, DDS traffic stays on
/// 127.0.0.1.
pub fn context_for(domain: u16, range: DiscoveryRange) -> Result<Context, RosError> {
    let dds = |what: &str, e: &dyn std::fmt::Display| RosError::Dds {
        what: what.into(),
        message: e.to_string(),
    };
    match range {
        DiscoveryRange::Localhost => {
            let participant = ros2_client::dds::rustdds::DomainParticipantBuilder::new(domain)
                .with_only_networks([IpAddr::V4(Ipv4Addr::LOCALHOST)])
                .build()
                .map_err(|e| dds("DDS participant", &e))?;
            Context::from_domain_participant(participant).map_err(|e| dds("ROS context", &e))
        }
        DiscoveryRange::Subnet => {
            Context::with_options(ros2_client::ContextOptions::new().domain_id(domain))
                .map_err(|e| dds("ROS context", &e))
        }
    }
}

/// QoS profiles of the fleet's topics.
pub mod qos {
    use ros2_client::QosProfile;
    use ros2_client::qos::{Durability, History, Reliability, WhenFull};

    /// rclpy's default for publishers and subscriptions (depth 10): reliable, volatile,
    /// keep last 10. Used for every command and state topic, as ROS tools expect.
    pub fn default() -> QosProfile {
        QosProfile::publisher_default()
            .durability(Durability::Volatile)
            .history(History::KeepLast { depth: 10 })
    }

    /// What the fleet's publishers use: [`default`] as the other side sees it (reliable,
    /// volatile), with 1 s of unacknowledged samples at 100 Hz in the send window, and a full
    /// window fails the publish at once instead of waiting: a slow observer (a loaded
    /// rclpy, RViz or Foxglove) costs that observer samples, never the control loop its
    /// time.
    pub fn publisher() -> QosProfile {
        default()
            .history(History::KeepLast { depth: 100 })
            .reliability(Reliability::Reliable {
                when_full: WhenFull::Fail,
            })
    }
}

/// A parameter validator: `Err(reason)` refuses a set from a ROS peer.
pub type ParameterCheck = Box<dyn Fn(&str, &ParameterValue) -> Result<(), String> + Send + Sync>;

/// The check of a node whose parameters are all read at start-up: a set from a peer is
/// refused with the reason (`use_sim_time` aside).
pub fn read_at_startup() -> ParameterCheck {
    Box::new(|name: &str, _: &ParameterValue| {
        if name == "use_sim_time" {
            Ok(())
        } else {
            Err(format!(
                "{name} is read at start-up; restart the node to change it"
            ))
        }
    })
}

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
    if let Some(f) = on_set {
        // ros2-client validates the declared values too: those are the start-up values.
        let initial = declared.clone();
        options =
            options.parameter_validator(Box::new(move |name: &str, value: &ParameterValue| {
                if initial.get(name) == Some(value) {
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
    if use_sim_time {
        node.set_parameter("use_sim_time", ParameterValue::Boolean(true))
            .map_err(|e| RosError::Params(format!("use_sim_time: {e}")))?;
    }
    Ok(node)
}

/// A topic name after the node's remaps, resolved in its namespace: `cmd_vel` in `/` is
/// `/cmd_vel`, in `/robot1` it is `/robot1/cmd_vel`; absolute names stay as they are.
pub fn topic_name(args: &RosArgs, namespace: &str, name: &str) -> Result<Name, RosError> {
    let ns = namespace.trim_end_matches('/');
    let resolve = |n: &str| {
        if n.starts_with('/') {
            n.to_owned()
        } else {
            format!("{ns}/{n}")
        }
    };
    let full = resolve(name);
    let mapped = args
        .remaps
        .iter()
        .rev()
        .find(|(from, _)| resolve(from) == full)
        .map(|(_, to)| resolve(to))
        .unwrap_or(full);
    Name::parse(&mapped).map_err(|e| RosError::Args(format!("topic name `{mapped}`: {e:?}")))
}

/// Logging to the console (stderr) and `/rosout` at once.
#[derive(Debug, Clone)]
pub struct Log {
    /// The node's fully qualified name, for the console.
    pub node: String,
    /// Least level printed and sent.
    pub min_level: LogLevel,
}

fn level_rank(l: LogLevel) -> u8 {
    match l {
        LogLevel::Debug => 0,
        LogLevel::Info => 1,
        LogLevel::Warn => 2,
        LogLevel::Error => 3,
        LogLevel::Fatal => 4,
    }
}

impl Log {
    /// For a node; `--log-level` (debug, info, warn, error) sets the least level.
    pub fn new(node: &Node, args: &RosArgs) -> Self {
        let min_level = match args
            .log_level
            .as_deref()
            .map(str::to_ascii_lowercase)
            .as_deref()
        {
            Some("debug") => LogLevel::Debug,
            Some("warn") => LogLevel::Warn,
            Some("error") => LogLevel::Error,
            Some("fatal") => LogLevel::Fatal,
            _ => LogLevel::Info,
        };
        Self {
            node: node.fully_qualified_name(),
            min_level,
        }
    }
    /// Logs a line.
    pub fn log(&self, node: &Node, level: LogLevel, msg: &str) {
        if level_rank(level) < level_rank(self.min_level) {
            return;
        }
        let tag = match level {
            LogLevel::Debug => "DEBUG",
            LogLevel::Info => "INFO",
            LogLevel::Warn => "WARN",
            LogLevel::Error => "ERROR",
            LogLevel::Fatal => "FATAL",
        };
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap_or_default();
        eprintln!(
            "[{tag}] [{}.{:09}] [{}]: {msg}",
            now.as_secs(),
            now.subsec_nanos(),
            self.node
        );
        rosout!(*node, level, "{msg}");
    }
    /// Info.
    pub fn info(&self, node: &Node, msg: &str) {
        self.log(node, LogLevel::Info, msg);
    }
    /// Warning.
    pub fn warn(&self, node: &Node, msg: &str) {
        self.log(node, LogLevel::Warn, msg);
    }
    /// Error.
    pub fn error(&self, node: &Node, msg: &str) {
        self.log(node, LogLevel::Error, msg);
    }
}

/// Rejects any parameter not in `known` (besides ROS's own `use_sim_time`), naming it.
pub fn check_known(params: &BTreeMap<String, Value>, known: &[&str]) -> Result<(), RosError> {
    for k in params.keys() {
        if k != "use_sim_time" && !known.contains(&k.as_str()) {
            return Err(RosError::Params(format!(
                "unknown parameter `{k}` (known: {})",
                known.join(", ")
            )));
        }
    }
    Ok(())
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

    /// The `use_sim_time` parameter (false unless set true).
    pub fn use_sim_time(&self) -> bool {
        self.params
            .get("use_sim_time")
            .and_then(Value::as_bool)
            .unwrap_or(false)
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

/// Fixed-rate ticks on the monotonic clock, without drift: tick k is due at start + k·period.
#[derive(Debug)]
pub struct Ticker {
    start: std::time::Instant,
    period: std::time::Duration,
    k: u64,
}

impl Ticker {
    /// Ticks at `rate_hz`.
    pub fn new(rate_hz: f64) -> Self {
        Self {
            start: std::time::Instant::now(),
            period: std::time::Duration::from_secs_f64(1.0 / rate_hz),
            k: 0,
        }
    }
    /// Waits for the next tick and returns its index. A late tick is not made up for twice:
    /// after a stall the schedule restarts from now.
    pub async fn next(&mut self) -> u64 {
        let due = self.start + self.period * (self.k as u32);
        let now = std::time::Instant::now();
        if due > now {
            smol::Timer::at(due).await;
        } else if now - due > self.period * 10 {
            self.start = now - self.period * (self.k as u32);
        }
        self.k += 1;
        self.k - 1
    }
}

/// One control tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tick {
    /// Tick index: the tick is due at k / rate (s) on the node's time line.
    pub k: u64,
    /// The simulated time of the tick, under `use_sim_time` (the `/clock` value it came
    /// from); `None` on the monotonic clock.
    pub sim_time: Option<crate::msg::Time>,
    /// The same `/clock` value again: the simulator, in lockstep, asks for this tick's
    /// output once more (a peer may have joined late). Republish, do not step.
    pub repeat: bool,
}

/// Where a node's control ticks come from: the monotonic clock, or `/clock` under
/// `use_sim_time`. On simulated time, tick k is the first `/clock` value at or after k / rate
/// (with the simulator publishing at the control rate, every `/clock` message is a tick), so
/// a node stepped by a lockstep simulator computes exactly what it would in real time.
pub enum TickSource {
    /// Monotonic clock.
    Wall(Ticker),
    /// `/clock` messages.
    Sim {
        /// The `/clock` subscription.
        clock: Box<ros2_client::Subscription<crate::msg::Clock>>,
        /// Tick period (ns).
        period_ns: i64,
        /// The last tick's index and `/clock` value (ns).
        last: Option<(u64, i64)>,
    },
}

impl std::fmt::Debug for TickSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            TickSource::Wall(t) => f.debug_tuple("Wall").field(t).finish(),
            TickSource::Sim {
                period_ns, last, ..
            } => f
                .debug_struct("Sim")
                .field("period_ns", period_ns)
                .field("last", last)
                .finish(),
        }
    }
}

impl TickSource {
    /// Ticks at `rate_hz`, from `/clock` when the node has `use_sim_time`.
    pub fn new(ros: &mut RosNode, rate_hz: f64) -> Result<Self, RosError> {
        if ros.setup.use_sim_time() {
            Ok(TickSource::Sim {
                clock: Box::new(ros.subscription::<crate::msg::Clock>("/clock")?),
                period_ns: (1e9 / rate_hz).round() as i64,
                last: None,
            })
        } else {
            Ok(TickSource::Wall(Ticker::new(rate_hz)))
        }
    }

    /// True on simulated time.
    pub fn simulated(&self) -> bool {
        matches!(self, TickSource::Sim { .. })
    }

    /// Waits for the next tick. `None` after 100 ms without one (on simulated time, when
    /// the clock stands still), so the caller can check for shutdown.
    pub async fn next(&mut self) -> Option<Tick> {
        match self {
            TickSource::Wall(t) => Some(Tick {
                k: t.next().await,
                sim_time: None,
                repeat: false,
            }),
            TickSource::Sim {
                clock,
                period_ns,
                last,
            } => {
                use smol::future::FutureExt as _;
                loop {
                    let msg = async { Some(clock.async_take().await) }.or(async {
                        smol::Timer::after(std::time::Duration::from_millis(100)).await;
                        None
                    });
                    let Ok((msg, _)) = msg.await? else { continue };
                    let ns = msg.clock.to_nanos();
                    if ns < 0 {
                        continue;
                    }
                    // Tick k is due at k·period; 1 µs of slack for clocks computed in floats.
                    let k = ((ns + 1_000) / *period_ns) as u64;
                    match *last {
                        Some((last_k, last_ns)) if ns == last_ns => {
                            return Some(Tick {
                                k: last_k,
                                sim_time: Some(msg.clock),
                                repeat: true,
                            });
                        }
                        // The clock went back (the simulation restarted): start over.
                        Some((_, last_ns)) if ns < last_ns => *last = None,
                        _ => {}
                    }
                    if last.is_none_or(|(last_k, _)| k > last_k) {
                        *last = Some((k, ns));
                        return Some(Tick {
                            k,
                            sim_time: Some(msg.clock),
                            repeat: false,
                        });
                    }
                }
            }
        }
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
    // The node keeps its DDS participant alive through this.
    _context: Context,
    /// When each throttled message was last logged, and how many were held back since.
    throttled: std::sync::Mutex<BTreeMap<String, (std::time::Instant, u64)>>,
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
    /// Joins the DDS domain of the environment and creates the node with its declared
    /// parameters and parameter check.
    pub fn start(
        setup: NodeSetup,
        declared: &BTreeMap<String, ParameterValue>,
        check: Option<ParameterCheck>,
    ) -> Result<Self, RosError> {
        let context = context_from_env()?;
        let node = create_node(
            &context,
            &setup.name,
            &setup.namespace,
            declared,
            check,
            setup.use_sim_time(),
        )?;
        let log = Log::new(&node, &setup.args);
        Ok(Self {
            node,
            setup,
            log,
            _context: context,
            throttled: std::sync::Mutex::new(BTreeMap::new()),
        })
    }

    fn topic<M: crate::RosMessage>(
        &self,
        name: &str,
    ) -> Result<ros2_client::dds::rustdds::Topic, RosError> {
        let resolved = topic_name(&self.setup.args, &self.setup.namespace, name)?;
        self.node
            .create_topic(&resolved, M::message_type_name(), &qos::default())
            .map_err(dds_err(format!("topic {name}")))
    }

    /// A publisher of `M` on topic `name` (remapped, in the namespace), default QoS.
    pub fn publisher<M: crate::RosMessage>(
        &mut self,
        name: &str,
    ) -> Result<ros2_client::Publisher<M>, RosError> {
        let topic = self.topic::<M>(name)?;
        self.node
            .create_publisher::<M>(&topic, Some(qos::publisher()))
            .map_err(dds_err(format!("publisher {name}")))
    }

    /// A subscription to `M` on topic `name` (remapped, in the namespace), default QoS.
    pub fn subscription<M: crate::RosMessage + 'static>(
        &mut self,
        name: &str,
    ) -> Result<ros2_client::Subscription<M>, RosError> {
        let topic = self.topic::<M>(name)?;
        self.node
            .create_subscription::<M>(&topic, None)
            .map_err(dds_err(format!("subscription {name}")))
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
        let Ok(mut t) = self.throttled.lock() else {
            return self.error(msg);
        };
        let now = std::time::Instant::now();
        match t.get_mut(key) {
            Some((last, held)) if now.duration_since(*last) < std::time::Duration::from_secs(1) => {
                *held += 1;
            }
            entry => {
                let held = entry.map_or(0, |e| e.1);
                t.insert(key.to_owned(), (now, 0));
                drop(t);
                if held > 0 {
                    self.error(&format!("{msg} ({held} more like it in the last second)"));
                } else {
                    self.error(msg);
                }
            }
        }
    }
}
