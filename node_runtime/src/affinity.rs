//! Binding a node's process to CPUs: the `cpu_affinity` parameter every node takes, as
//! ros2_control_node's (an integer or a list of integers; unset or empty: not bound, the
//! default).
//!
//! On a machine whose idle CPUs are slow to wake (a virtual machine that halts an idle vCPU,
//! a laptop in a deep C-state), a message handed from a thread on one CPU to a thread
//! asleep on another pays that wake-up on every hop; binding the processes of a pipeline to
//! one CPU keeps the hand-offs on it. It also takes the other CPUs away from them: for a
//! fleet that needs more than one CPU of work (the simulator in lockstep) it is slower.
//! BENCHMARKS.md ("Where a DDS hop's time goes") has both measured.

use serde_norway::Value;

use crate::error::RosError;

/// The parameter's name.
pub const CPU_AFFINITY_PARAM: &str = "cpu_affinity";

/// The CPUs of a `cpu_affinity` value: `None` for an empty list (not bound); an error naming
/// the value for anything but non-negative integers.
pub fn cpu_affinity_of(value: &Value) -> Result<Option<Vec<usize>>, RosError> {
    let bad = |what: &Value| {
        RosError::Params(format!(
            "parameter `{CPU_AFFINITY_PARAM}`: {what:?} is not a CPU number (0, 1, ...); \
             give a CPU or a list of CPUs, e.g. [0] or [2, 3]"
        ))
    };
    let items: Vec<&Value> = match value {
        Value::Sequence(items) => items.iter().collect(),
        one => vec![one],
    };
    let mut cpus = items
        .into_iter()
        .map(|v| {
            v.as_u64()
                .and_then(|c| usize::try_from(c).ok())
                .ok_or_else(|| bad(v))
        })
        .collect::<Result<Vec<usize>, RosError>>()?;
    cpus.sort_unstable();
    cpus.dedup();
    Ok((!cpus.is_empty()).then_some(cpus))
}

/// Binds the calling thread, and so every thread it starts afterwards, to `cpus`. Each
/// must be a CPU this process may run on now; an error names the ones that are not.
pub fn bind_this_thread(cpus: &[usize]) -> Result<(), RosError> {
    use nix::sched::{CpuSet, sched_getaffinity, sched_setaffinity};
    use nix::unistd::Pid;
    let kernel = |source| RosError::Affinity {
        cpus: cpus.to_vec(),
        source,
    };
    let allowed = sched_getaffinity(Pid::from_raw(0)).map_err(kernel)?;
    let allowed: Vec<usize> = (0..CpuSet::count())
        .filter(|&c| allowed.is_set(c).unwrap_or(false))
        .collect();
    let refused: Vec<usize> = cpus
        .iter()
        .copied()
        .filter(|c| !allowed.contains(c))
        .collect();
    if !refused.is_empty() {
        return Err(RosError::Params(format!(
            "parameter `{CPU_AFFINITY_PARAM}`: CPU {refused:?} is not one this process may run \
             on (it may run on {allowed:?})"
        )));
    }
    let mut set = CpuSet::new();
    for &c in cpus {
        set.set(c).map_err(kernel)?;
    }
    sched_setaffinity(Pid::from_raw(0), &set).map_err(kernel)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]

    use super::*;
    use crate::params::tests::yaml;
    use nix::sched::{CpuSet, sched_getaffinity};
    use nix::unistd::Pid;

    #[test]
    fn a_cpu_or_a_list_of_cpus_and_empty_is_not_bound() {
        assert_eq!(cpu_affinity_of(&yaml("1")).unwrap(), Some(vec![1]));
        assert_eq!(
            cpu_affinity_of(&yaml("[3, 0, 3]")).unwrap(),
            Some(vec![0, 3])
        );
        assert_eq!(cpu_affinity_of(&yaml("[]")).unwrap(), None);
    }

    #[test]
    fn anything_but_cpu_numbers_is_refused_naming_it() {
        for (text, named) in [
            ("[-1]", "-1"),
            ("[0.5]", "0.5"),
            ("zero", "zero"),
            ("[0, true]", "true"),
        ] {
            let e = cpu_affinity_of(&yaml(text)).unwrap_err().to_string();
            assert!(
                e.contains("cpu_affinity") && e.contains(named),
                "{text}: {e}"
            );
        }
    }

    #[test]
    fn a_thread_is_bound_and_threads_it_starts_inherit_it() {
        // On a thread of its own: the test harness's threads keep their CPUs.
        let (own, child) = std::thread::spawn(|| {
            bind_this_thread(&[0]).unwrap();
            let child = std::thread::spawn(|| sched_getaffinity(Pid::from_raw(0)).unwrap())
                .join()
                .unwrap();
            (sched_getaffinity(Pid::from_raw(0)).unwrap(), child)
        })
        .join()
        .unwrap();
        for set in [own, child] {
            let on: Vec<usize> = (0..CpuSet::count())
                .filter(|&c| set.is_set(c).unwrap())
                .collect();
            assert_eq!(on, vec![0]);
        }
    }

    #[test]
    fn a_cpu_the_process_may_not_use_is_refused_naming_it_and_nothing_changes() {
        let before = std::thread::spawn(|| {
            let before = sched_getaffinity(Pid::from_raw(0)).unwrap();
            let e = bind_this_thread(&[0, 1023]).unwrap_err().to_string();
            assert!(e.contains("1023") && e.contains("cpu_affinity"), "{e}");
            (before, sched_getaffinity(Pid::from_raw(0)).unwrap())
        })
        .join()
        .unwrap();
        assert_eq!(before.0, before.1);
    }
}
