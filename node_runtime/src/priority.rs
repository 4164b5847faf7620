//! Real-time scheduling: the `thread_priority` parameter every node takes, as
//! ros2_control_node's (an integer from 1 to 99; unset: the normal scheduler, the default).
//!
//! A node given it runs every thread of its process (its own, the DDS threads, the signal
//! thread) under `SCHED_FIFO` at that priority, as real-time ROS 2 setups run their executors
//! and middleware threads: a thread woken by a message runs at once, ahead of every
//! normally scheduled thread on its CPU (a compiler, a browser, a perception node), and a
//! thread of the fleet runs until it waits, so a message handed from one of its threads to
//! the next is not interrupted midway by the one it woke. The kernel keeps 5 % of each
//! second for normal threads (`/proc/sys/kernel/sched_rt_runtime_us`), so a real-time
//! thread that never waits slows the machine rather than freezing it; our nodes wait
//! between messages.
//!
//! It takes `CAP_SYS_NICE` (root has it) or an `RLIMIT_RTPRIO` at least as high (`ulimit -r`,
//! `rtprio` in `/etc/security/limits.conf`); refused, the node does not start and says which.
//!
//! Use it with `cpu_affinity` where idle CPUs are slow to wake (a virtual machine whose idle
//! vCPUs halt): a woken real-time thread whose CPU runs another of the same priority is handed
//! to an idle CPU rather than queued, and each such hand-off then pays that wake-up.
//! BENCHMARKS.md ("Real-time scheduling") has the pipeline measured with and without it (bound,
//! unbound, beside a busy loop) and the simulated walk.

use serde_norway::Value;
use thread_priority::{
    RealtimeThreadSchedulePolicy, ThreadPriority, ThreadPriorityValue, ThreadSchedulePolicy,
};

use crate::error::RosError;

/// The parameter's name.
pub const THREAD_PRIORITY_PARAM: &str = "thread_priority";

/// Linux's number for the `SCHED_FIFO` policy, as `/proc/<pid>/task/<tid>/stat` shows it (0
/// is the normal scheduler).
pub const SCHED_FIFO: u32 = 1;

/// The priority of a `thread_priority` value: an integer from 1 to 99 (Linux's `SCHED_FIFO`
/// range); an error naming the value for anything else.
pub fn thread_priority_of(value: &Value) -> Result<u8, RosError> {
    value
        .as_u64()
        .and_then(|p| u8::try_from(p).ok())
        .filter(|p| (1..=99).contains(p))
        .ok_or_else(|| {
            RosError::Params(format!(
                "parameter `{THREAD_PRIORITY_PARAM}`: {value:?} is not a real-time priority \
                 (an integer from 1 to 99, as SCHED_FIFO takes; ros2_control's default is 50)"
            ))
        })
}

/// Runs the calling thread, and so every thread it starts afterwards (they inherit it),
/// under `SCHED_FIFO` at `priority` (1 to 99). An error names the priority and the kernel's
/// answer.
pub fn run_this_thread_realtime(priority: u8) -> Result<(), RosError> {
    let value = ThreadPriorityValue::try_from(priority).map_err(|_| {
        RosError::Params(format!(
            "parameter `{THREAD_PRIORITY_PARAM}`: {priority} is not a real-time priority (1 to 99)"
        ))
    })?;
    thread_priority::set_thread_priority_and_policy(
        thread_priority::thread_native_id(),
        ThreadPriority::Crossplatform(value),
        ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo),
    )
    .map_err(|e| RosError::ThreadPriority {
        priority,
        source: match e {
            thread_priority::Error::OS(code) => std::io::Error::from_raw_os_error(code),
            other => std::io::Error::other(other.to_string()),
        },
    })
}

/// The calling thread's scheduling policy and real-time priority, as the kernel reports them
/// in `/proc/thread-self/stat` ([`SCHED_FIFO`], or 0 for the normal scheduler; priority 0 for
/// a normal thread).
pub fn this_thread_policy() -> std::io::Result<(u32, u32)> {
    task_policy(&std::fs::read_to_string("/proc/thread-self/stat")?)
}

/// The scheduling policy and real-time priority in a `/proc/<pid>/task/<tid>/stat` line (its
/// 41st and 40th fields, counted after the parenthesised command name, which may hold
/// spaces).
pub fn task_policy(stat: &str) -> std::io::Result<(u32, u32)> {
    let bad = || std::io::Error::other(format!("not a /proc stat line: {stat:?}"));
    // The fields after the command name start at the 3rd (state).
    let rest = stat.rsplit_once(')').ok_or_else(bad)?.1;
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let field = |n: usize| -> std::io::Result<u32> {
        fields
            .get(n - 3)
            .and_then(|f| f.parse().ok())
            .ok_or_else(bad)
    };
    Ok((field(41)?, field(40)?))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]

    use super::*;
    use crate::params::tests::yaml;

    #[test]
    fn priorities_from_1_to_99() {
        assert_eq!(thread_priority_of(&yaml("1")).unwrap(), 1);
        assert_eq!(thread_priority_of(&yaml("50")).unwrap(), 50);
        assert_eq!(thread_priority_of(&yaml("99")).unwrap(), 99);
    }

    #[test]
    fn anything_else_is_refused_naming_it() {
        for (text, named) in [
            ("0", "0"),
            ("100", "100"),
            ("256", "256"),
            ("-1", "-1"),
            ("50.5", "50.5"),
            ("high", "high"),
            ("[50]", "Sequence"),
        ] {
            let e = thread_priority_of(&yaml(text)).unwrap_err().to_string();
            assert!(
                e.contains(THREAD_PRIORITY_PARAM) && e.contains(named),
                "{text}: {e}"
            );
        }
    }

    /// A refusal names the priority, what it takes and the kernel's answer, as a node prints
    /// it when it cannot start.
    #[test]
    fn a_refusal_names_the_priority_and_the_kernels_answer() {
        let e = RosError::ThreadPriority {
            priority: 50,
            source: std::io::Error::from_raw_os_error(1),
        };
        let text = crate::node::printed(e);
        assert!(
            text.starts_with(
                "parameter `thread_priority` = 50: cannot run the process under SCHED_FIFO"
            ) && text.contains("CAP_SYS_NICE")
                && text.ends_with("Operation not permitted (os error 1)"),
            "{text}"
        );
    }

    /// The fields of a stat line whose command name holds spaces and parentheses (a DDS
    /// thread's is `RustDDS Participant`), written out by hand.
    #[test]
    fn the_policy_of_a_stat_line() {
        let fields: Vec<String> = (4..=52)
            .map(|n| match n {
                40 => "50".to_owned(),
                41 => "1".to_owned(),
                n => n.to_string(),
            })
            .collect();
        let line = format!("4242 (RustDDS (x) Pa) S {}\n", fields.join(" "));
        assert_eq!(task_policy(&line).unwrap(), (SCHED_FIFO, 50));
        assert!(task_policy("4242 RustDDS").is_err());
    }

    /// A thread put under SCHED_FIFO is, and a thread it starts inherits it (this machine's
    /// tests run as root). On a thread of its own: the test harness's stay as they are.
    #[test]
    fn a_realtime_thread_and_the_threads_it_starts_run_under_sched_fifo() {
        let (own, child) = std::thread::spawn(|| {
            run_this_thread_realtime(7).unwrap();
            let own = this_thread_policy().unwrap();
            let child = std::thread::spawn(|| this_thread_policy().unwrap())
                .join()
                .unwrap();
            (own, child)
        })
        .join()
        .unwrap();
        assert_eq!(own, (SCHED_FIFO, 7));
        assert_eq!(child, (SCHED_FIFO, 7));
        assert_eq!(this_thread_policy().unwrap(), (0, 0));
    }
}
