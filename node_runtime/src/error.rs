//! The one error type of the node runtime: why a node could not start (or, for a handler
//! on the DDS thread, stopped).

/// Why a node could not start, or why its handler on the DDS thread stopped.
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
    /// The kernel refused to bind the process to the CPUs of `cpu_affinity`.
    #[error("parameter `cpu_affinity`: cannot bind the process to CPUs {cpus:?}")]
    Affinity {
        /// The CPUs asked for.
        cpus: Vec<usize>,
        /// The kernel's answer.
        #[source]
        source: nix::errno::Errno,
    },
    /// The kernel refused the CPU latency request of `cpu_dma_latency_us`.
    #[error(
        "parameter `cpu_dma_latency_us` = {latency_us}: cannot hold a CPU latency request on \
         {device} (it takes write access to the device: root, as a rule)"
    )]
    CpuLatency {
        /// The latency asked for, µs.
        latency_us: u32,
        /// The PM QoS device.
        device: &'static str,
        /// The kernel's answer.
        #[source]
        source: std::io::Error,
    },
    /// The kernel refused the real-time scheduling of `thread_priority`.
    #[error(
        "parameter `thread_priority` = {priority}: cannot run the process under SCHED_FIFO \
         (it takes CAP_SYS_NICE, as root has, or an RLIMIT_RTPRIO of at least {priority}: \
         `ulimit -r`, `rtprio` in /etc/security/limits.conf)"
    )]
    ThreadPriority {
        /// The priority asked for.
        priority: u8,
        /// The kernel's answer.
        #[source]
        source: std::io::Error,
    },
    /// DDS or ros2-client refused to create something.
    #[error("{what}: {message}")]
    Dds {
        /// What was being created.
        what: String,
        /// The library's message.
        message: String,
    },
    /// A handler run on the DDS thread ([`crate::RosNode::serve_on_receive`]) panicked: the
    /// node handles no more messages of the topic.
    #[error("{topic}: the handler panicked on the DDS thread; no more of its messages are handled")]
    HandlerPanicked {
        /// The topic.
        topic: String,
    },
}
