//! What every ROS 2 node of the fleet shares, above the wire types (`biped_msgs`) and below
//! the node binaries:
//!
//! - [`args`]: the `--ros-args` command line (remaps, `__node`, `__ns`, `--params-file`, `-p`,
//!   `--log-level`) and topic names resolved through the remaps and the namespace;
//! - [`params`]: ROS 2 parameter files and `-p` for one node, YAML ↔ ROS parameter values,
//!   unknown names refused, sets from peers checked;
//! - [`context`]: the DDS context from `ROS_DOMAIN_ID` and `ROS_AUTOMATIC_DISCOVERY_RANGE`
//!   (LOCALHOST keeps DDS on 127.0.0.1);
//! - [`qos`]: the fleet's QoS profiles;
//! - [`log`]: logging to the console and `/rosout` at once;
//! - [`clock`]: control ticks from the monotonic clock or from `/clock` (`use_sim_time`);
//! - [`node`]: start-up ([`NodeSetup`], [`shutdown_flag`]), where a node runs ([`Host`]:
//!   alone in its process, or composed with others in one) and the started node
//!   ([`RosNode`]: typed publishers and subscriptions, logging, the executor);
//! - [`local`]: in-process delivery between nodes composed in one process;
//! - [`on_receive`]: a subscription handled on the DDS thread that receives its messages
//!   (one thread wake-up a message instead of two);
//! - [`affinity`]: the `cpu_affinity` parameter, binding a node's process to CPUs;
//! - [`cpu_latency`]: the `cpu_dma_latency_us` parameter, a CPU latency request held while
//!   the node's process runs, and how the machine's idle CPUs wait
//!   ([`cpu_latency::idle_cpus`], which the benches print);
//! - [`priority`]: the `thread_priority` parameter, the node's process under real-time
//!   scheduling (`SCHED_FIFO`);
//! - [`wait`]: how a node's thread waits: parked on a futex ([`wait::block_on`]), its
//!   deadlines the futex wait's timeout; [`WaitBound`], one deadline kept across a loop's
//!   waits for its next message.
//!
//! ros2-client (pure Rust over RustDDS) underneath; no core crate depends on this one, only
//! the node binaries (each core crate's `node` feature) and the `biped` command.

pub mod affinity;
pub mod args;
pub mod clock;
pub mod context;
pub mod cpu_latency;
mod error;
pub mod local;
pub mod log;
pub mod node;
pub mod on_receive;
pub mod params;
pub mod priority;
pub mod qos;
pub mod wait;

pub use affinity::CPU_AFFINITY_PARAM;
pub use args::{RosArgs, topic_name};
pub use clock::{Tick, TickSource, Ticker};
pub use context::{
    DiscoveryRange, SendThread, context_for, context_from_env, context_from_env_sending_on,
    context_with_peers, ros_environment, ros_environment_from, static_peers_from,
};
pub use cpu_latency::{CPU_DMA_LATENCY_PARAM, CpuLatencyRequest};
pub use error::RosError;
pub use local::{Publisher, Subscription};
pub use log::Log;
pub use node::{
    Host, LAUNCH_PARENT_ENV, NodeSetup, RosNode, create_node, node_main, shutdown_flag,
};
pub use on_receive::{OnReceive, Received, Said};
pub use params::{
    COMMON_PARAMS, ParameterCheck, check_known, from_parameter_value, node_parameters,
    read_at_startup, read_at_startup_only, to_parameter_value,
};
pub use priority::THREAD_PRIORITY_PARAM;
pub use wait::WaitBound;

/// Runs a burst of publishes so that each reader process gets them as one datagram
/// (RustDDS's `coalesce_sends`, our patch: `patches/README.md`). For a node that
/// publishes several topics at one instant, to the same readers: what it saves is the
/// system calls, datagrams and wake-ups of all but one. Samples go out when the burst
/// returns; in-process (composed) readers are not concerned.
pub use ros2_client::dds::rustdds::coalesce_sends;
