//! Keeping idle CPUs quick to wake: the `cpu_dma_latency_us` parameter every node takes (an
//! integer of microseconds; unset: no request, the default).
//!
//! A node given it holds a CPU latency request (Linux PM QoS, `/dev/cpu_dma_latency`, as
//! cyclictest and real-time setups do) for as long as its process runs: the kernel then puts no
//! CPU into an idle state slower to leave than that, and at 0 idle CPUs poll instead of
//! halting. A message that wakes a thread on an idle CPU no longer waits for the CPU to come
//! back (a deep C-state on a laptop or a Raspberry Pi; a halted vCPU, a round trip through the
//! hypervisor, on a virtual machine), and the CPU keeps its caches warm between ticks.
//!
//! The request is the whole machine's, not the node's: every CPU, every process, and it costs
//! power (at 0, an idle CPU spins). The kernel keeps the lowest of all requests held and drops
//! one when its holder's file is closed, so when the process ends, however it ends.
//! BENCHMARKS.md ("The p99: ...") has the pipeline measured with and without it.

use std::fs::{File, OpenOptions};
use std::io::{Read as _, Write as _};
use std::path::Path;

use serde_norway::Value;

use crate::error::RosError;

/// The parameter's name.
pub const CPU_DMA_LATENCY_PARAM: &str = "cpu_dma_latency_us";

/// Linux's PM QoS device for the CPU latency of the whole machine.
pub const CPU_DMA_LATENCY_DEVICE: &str = "/dev/cpu_dma_latency";

/// The microseconds of a `cpu_dma_latency_us` value: an integer from 0 to 2^31 − 1 (the
/// kernel's range); an error naming the value for anything else.
pub fn cpu_dma_latency_of(value: &Value) -> Result<u32, RosError> {
    value
        .as_u64()
        .and_then(|us| i32::try_from(us).ok())
        .and_then(|us| u32::try_from(us).ok())
        .ok_or_else(|| {
            RosError::Params(format!(
                "parameter `{CPU_DMA_LATENCY_PARAM}`: {value:?} is not a latency in microseconds \
                 (an integer from 0 to {}); 0 keeps idle CPUs polling",
                i32::MAX
            ))
        })
}

/// A held CPU latency request; dropped, the kernel forgets it.
#[derive(Debug)]
pub struct CpuLatencyRequest {
    _device: File,
    latency_us: u32,
}

impl CpuLatencyRequest {
    /// Asks the kernel to keep every CPU within `latency_us` of waking, until dropped. Needs
    /// write access to [`CPU_DMA_LATENCY_DEVICE`] (root, as a rule); an error names the value,
    /// the device and the kernel's answer.
    pub fn hold(latency_us: u32) -> Result<Self, RosError> {
        let refused = |source| RosError::CpuLatency {
            latency_us,
            device: CPU_DMA_LATENCY_DEVICE,
            source,
        };
        let mut device = OpenOptions::new()
            .write(true)
            .open(CPU_DMA_LATENCY_DEVICE)
            .map_err(refused)?;
        // The kernel takes a 32-bit integer in the machine's byte order.
        let value = i32::try_from(latency_us).unwrap_or(i32::MAX);
        device.write_all(&value.to_ne_bytes()).map_err(refused)?;
        Ok(Self {
            _device: device,
            latency_us,
        })
    }

    /// The latency asked for.
    pub fn latency_us(&self) -> u32 {
        self.latency_us
    }
}

/// The machine's CPU latency limit now: the lowest request any process holds, or the
/// kernel's default (2e9 µs) when none does.
pub fn current_limit_us() -> std::io::Result<i32> {
    let mut bytes = [0u8; 4];
    File::open(CPU_DMA_LATENCY_DEVICE)?.read_exact(&mut bytes)?;
    Ok(i32::from_ne_bytes(bytes))
}

/// How the machine's idle CPUs wait, which sets what a message costs that wakes a thread on
/// an idle CPU (BENCHMARKS.md, "Where the default four-process tick waits"): the cpuidle
/// driver, its governor and idle states, and with the haltpoll governor (a KVM guest's) how
/// long an idle vCPU polls before it halts (`guest_halt_poll_ns`; 0: it halts at once, and
/// the host must wake it). `sys` is the sysfs root (`/sys`). One line, for a benchmark's
/// machine line; what cannot be read is left out or `?`.
pub fn idle_cpus(sys: &Path) -> String {
    let read = |p: &str| {
        std::fs::read_to_string(sys.join(p))
            .ok()
            .map(|s| s.trim().to_owned())
            .filter(|s| !s.is_empty())
    };
    let Some(driver) = read("devices/system/cpu/cpuidle/current_driver") else {
        return "idle CPUs: no cpuidle driver".into();
    };
    let governor = read("devices/system/cpu/cpuidle/current_governor")
        .or_else(|| read("devices/system/cpu/cpuidle/current_governor_ro"))
        .unwrap_or_else(|| "?".into());
    let states: Vec<String> = (0..16)
        .map_while(|i| read(&format!("devices/system/cpu/cpu0/cpuidle/state{i}/name")))
        .collect();
    let poll = match read("module/haltpoll/parameters/guest_halt_poll_ns") {
        Some(ns) if governor == "haltpoll" => format!(", polling {ns} ns before halting"),
        _ => String::new(),
    };
    format!(
        "idle CPUs: cpuidle {driver} (governor {governor}{poll}; states {})",
        if states.is_empty() {
            "?".into()
        } else {
            states.join(" ")
        }
    )
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]

    use super::*;
    use crate::params::tests::yaml;

    #[test]
    fn microseconds_from_zero_to_the_kernels_largest() {
        assert_eq!(cpu_dma_latency_of(&yaml("0")).unwrap(), 0);
        assert_eq!(cpu_dma_latency_of(&yaml("50")).unwrap(), 50);
        assert_eq!(
            cpu_dma_latency_of(&yaml("2147483647")).unwrap(),
            2_147_483_647
        );
    }

    #[test]
    fn anything_else_is_refused_naming_it() {
        for (text, named) in [
            ("-1", "-1"),
            ("2147483648", "2147483648"),
            ("0.5", "0.5"),
            ("fast", "fast"),
            ("[0]", "Sequence"),
        ] {
            let e = cpu_dma_latency_of(&yaml(text)).unwrap_err().to_string();
            assert!(
                e.contains(CPU_DMA_LATENCY_PARAM) && e.contains(named),
                "{text}: {e}"
            );
        }
    }

    /// A refused request names the value, the device and the kernel's answer, as a node
    /// prints it when it cannot start.
    #[test]
    fn a_refusal_names_the_value_the_device_and_the_kernels_answer() {
        let e = RosError::CpuLatency {
            latency_us: 7,
            device: CPU_DMA_LATENCY_DEVICE,
            source: std::io::Error::from(std::io::ErrorKind::PermissionDenied),
        };
        let text = crate::node::printed(e);
        assert!(
            text.starts_with(
                "parameter `cpu_dma_latency_us` = 7: cannot hold a CPU latency request on \
                 /dev/cpu_dma_latency"
            ) && text.ends_with(": permission denied"),
            "{text}"
        );
    }

    /// The kernel's limit follows the request while it is held and lets go when it is dropped
    /// (this machine's tests run as root; no other test holds a request this low: the fleet
    /// test's node holds 50 µs).
    #[test]
    fn a_held_request_lowers_the_machines_limit_until_dropped() {
        let before = current_limit_us().unwrap();
        assert!(before > 3, "someone already holds {before} µs");
        let request = CpuLatencyRequest::hold(3).unwrap();
        assert_eq!(request.latency_us(), 3);
        assert!(current_limit_us().unwrap() <= 3);
        drop(request);
        assert!(current_limit_us().unwrap() > 3);
    }

    /// A sysfs tree under a fresh folder with `files` (path, contents).
    fn sys(name: &str, files: &[(&str, &str)]) -> std::path::PathBuf {
        let root = std::env::temp_dir().join(format!("biped-idle-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        for (path, text) in files {
            let p = root.join(path);
            if let Some(dir) = p.parent() {
                std::fs::create_dir_all(dir).unwrap();
            }
            std::fs::write(p, text).unwrap();
        }
        root
    }

    #[test]
    fn a_kvm_guest_says_how_long_its_idle_vcpus_poll() {
        let root = sys(
            "haltpoll",
            &[
                ("devices/system/cpu/cpuidle/current_driver", "haltpoll\n"),
                (
                    "devices/system/cpu/cpuidle/current_governor_ro",
                    "haltpoll\n",
                ),
                ("devices/system/cpu/cpu0/cpuidle/state0/name", "POLL\n"),
                (
                    "devices/system/cpu/cpu0/cpuidle/state1/name",
                    "haltpoll idle\n",
                ),
                ("module/haltpoll/parameters/guest_halt_poll_ns", "0\n"),
            ],
        );
        assert_eq!(
            idle_cpus(&root),
            "idle CPUs: cpuidle haltpoll (governor haltpoll, polling 0 ns before halting; states POLL haltpoll idle)"
        );
        let _ = std::fs::remove_dir_all(root);
    }

    #[test]
    fn a_machine_without_cpuidle_or_haltpoll_says_so() {
        let root = sys(
            "menu",
            &[
                ("devices/system/cpu/cpuidle/current_driver", "intel_idle\n"),
                ("devices/system/cpu/cpuidle/current_governor", "menu\n"),
                ("devices/system/cpu/cpu0/cpuidle/state0/name", "POLL\n"),
                ("devices/system/cpu/cpu0/cpuidle/state1/name", "C1\n"),
                ("devices/system/cpu/cpu0/cpuidle/state2/name", "C6\n"),
                // Loaded but not the governor: no poll window said.
                ("module/haltpoll/parameters/guest_halt_poll_ns", "200000\n"),
            ],
        );
        assert_eq!(
            idle_cpus(&root),
            "idle CPUs: cpuidle intel_idle (governor menu; states POLL C1 C6)"
        );
        let none = sys("none", &[("devices/system/cpu/online", "0-1\n")]);
        assert_eq!(idle_cpus(&none), "idle CPUs: no cpuidle driver");
        let _ = std::fs::remove_dir_all(root);
        let _ = std::fs::remove_dir_all(none);
    }
}
