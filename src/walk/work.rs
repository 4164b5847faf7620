//! What the processes of a run cost the machine between two instants: the CPU time and
//! context switches of every thread (Linux: `/proc/PID/task/TID/schedstat` and `status`),
//! and the UDP datagrams sent in the network namespace (`/proc/net/snmp`). `biped walk`
//! takes one snapshot at the first `/clock` and one at the end, so the report says what a
//! lockstep tick costs in messaging work: a count, where the real-time factor follows the
//! host's load. Per process too (`by_process`, by the name the run gives it): where a
//! tick's CPU time goes.

use std::collections::BTreeMap;

use serde::Serialize;

/// Cumulative counters at one instant.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Work {
    /// On-CPU time of every thread of the processes (ns).
    pub cpu_ns: u64,
    /// Voluntary and involuntary context switches of every thread of the processes.
    pub context_switches: u64,
    /// UDP datagrams sent in this network namespace (every process of it).
    pub udp_datagrams: u64,
    /// The same two counters for each process, by its name.
    pub by_process: BTreeMap<String, ProcessWork>,
}

/// One process's cumulative counters (every thread of it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ProcessWork {
    /// Its process id (a process of the same name with another id is another process: one
    /// restarted).
    pub pid: u32,
    /// On-CPU time (ns).
    pub cpu_ns: u64,
    /// Voluntary and involuntary context switches.
    pub context_switches: u64,
}

/// One process's share of a tick's work.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ProcessTickWork {
    /// CPU time per tick (ms).
    pub cpu_ms: f64,
    /// Context switches per tick.
    pub context_switches: f64,
}

/// The work of one tick, averaged over the ticks between two snapshots.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TickWork {
    /// Ticks the averages are over.
    pub ticks: u64,
    /// CPU time of the run's processes per tick (ms).
    pub cpu_ms: f64,
    /// Context switches of the run's processes per tick.
    pub context_switches: f64,
    /// UDP datagrams sent in the network namespace per tick (every process of it: the
    /// run's alone in a private namespace, as the tests and the benches use).
    pub udp_datagrams: f64,
    /// Each process's CPU time and context switches per tick, by its name (a process not
    /// running at both snapshots, one restarted included, is left out).
    pub by_process: BTreeMap<String, ProcessTickWork>,
}

impl Work {
    /// The counters now, summed over every thread of each `(name, pid)` and over all of
    /// them (a process that is gone, or a thread that ends while it is read, counts
    /// nothing).
    pub fn now(processes: &[(&str, u32)]) -> std::io::Result<Work> {
        let snmp = std::fs::read_to_string("/proc/net/snmp")?;
        let udp_datagrams = out_datagrams(&snmp).ok_or_else(|| {
            std::io::Error::other("/proc/net/snmp has no Udp: OutDatagrams counter")
        })?;
        let mut w = Work {
            udp_datagrams,
            ..Work::default()
        };
        for &(name, pid) in processes {
            let Ok(tasks) = std::fs::read_dir(format!("/proc/{pid}/task")) else {
                continue;
            };
            let mut p = ProcessWork {
                pid,
                ..ProcessWork::default()
            };
            for task in tasks.flatten() {
                let read = |f: &str| std::fs::read_to_string(task.path().join(f)).ok();
                p.cpu_ns += read("schedstat").and_then(|s| on_cpu_ns(&s)).unwrap_or(0);
                p.context_switches += read("status")
                    .and_then(|s| context_switches(&s))
                    .unwrap_or(0);
            }
            w.cpu_ns += p.cpu_ns;
            w.context_switches += p.context_switches;
            w.by_process.insert(name.to_owned(), p);
        }
        Ok(w)
    }

    /// The work per tick from `earlier` to `self`, over `ticks` ticks; `None` without a
    /// tick or if a counter went back (another set of processes).
    pub fn per_tick_since(&self, earlier: &Work, ticks: u64) -> Option<TickWork> {
        if ticks == 0 {
            return None;
        }
        let n = ticks as f64;
        let by_process = self
            .by_process
            .iter()
            .filter_map(|(name, now)| {
                let then = earlier.by_process.get(name).filter(|t| t.pid == now.pid)?;
                Some((
                    name.clone(),
                    ProcessTickWork {
                        cpu_ms: now.cpu_ns.checked_sub(then.cpu_ns)? as f64 * 1e-6 / n,
                        context_switches: now.context_switches.checked_sub(then.context_switches)?
                            as f64
                            / n,
                    },
                ))
            })
            .collect();
        Some(TickWork {
            ticks,
            cpu_ms: self.cpu_ns.checked_sub(earlier.cpu_ns)? as f64 * 1e-6 / n,
            context_switches: self
                .context_switches
                .checked_sub(earlier.context_switches)? as f64
                / n,
            udp_datagrams: self.udp_datagrams.checked_sub(earlier.udp_datagrams)? as f64 / n,
            by_process,
        })
    }
}

/// The first field of a thread's `schedstat`: its time on a CPU (ns).
fn on_cpu_ns(schedstat: &str) -> Option<u64> {
    schedstat.split_whitespace().next()?.parse().ok()
}

/// `voluntary_ctxt_switches` plus `nonvoluntary_ctxt_switches` of a thread's `status`.
fn context_switches(status: &str) -> Option<u64> {
    let field = |name: &str| -> Option<u64> {
        status
            .lines()
            .find_map(|l| l.strip_prefix(name))?
            .trim()
            .parse()
            .ok()
    };
    Some(field("voluntary_ctxt_switches:")? + field("nonvoluntary_ctxt_switches:")?)
}

/// `OutDatagrams` of `/proc/net/snmp`'s two `Udp:` lines (names, then values).
fn out_datagrams(snmp: &str) -> Option<u64> {
    let mut udp = snmp.lines().filter(|l| l.starts_with("Udp:"));
    let (names, values) = (udp.next()?, udp.next()?);
    let i = names.split_whitespace().position(|n| n == "OutDatagrams")?;
    values.split_whitespace().nth(i)?.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_counters_are_read_from_the_kernel_s_text() {
        assert_eq!(on_cpu_ns("123456789 2000 17\n"), Some(123_456_789));
        assert_eq!(on_cpu_ns(""), None);
        let status = "Name:\tik_solver\nState:\tS (sleeping)\n\
                      voluntary_ctxt_switches:\t812\nnonvoluntary_ctxt_switches:\t31\n";
        assert_eq!(context_switches(status), Some(843));
        assert_eq!(context_switches("Name:\tx\n"), None);
        // The Udp: lines after an Ip: and Tcp: pair, UdpLite: after them (not taken).
        let snmp = "Ip: Forwarding DefaultTTL\nIp: 1 64\n\
                    Tcp: RtoAlgorithm ActiveOpens\nTcp: 1 9\n\
                    Udp: InDatagrams NoPorts InErrors OutDatagrams RcvbufErrors\n\
                    Udp: 76161 280 0 76441 0\n\
                    UdpLite: InDatagrams NoPorts InErrors OutDatagrams\nUdpLite: 0 0 0 5\n";
        assert_eq!(out_datagrams(snmp), Some(76441));
        assert_eq!(out_datagrams("Ip: Forwarding\nIp: 1\n"), None);
    }

    #[test]
    fn the_work_of_a_tick_is_the_difference_over_the_ticks() {
        let process = |pid, cpu_ns, context_switches| ProcessWork {
            pid,
            cpu_ns,
            context_switches,
        };
        let start = Work {
            cpu_ns: 1_000_000,
            context_switches: 100,
            udp_datagrams: 50,
            by_process: [
                ("sim_bridge".to_owned(), process(10, 600_000, 60)),
                ("ik_solver".to_owned(), process(11, 400_000, 40)),
                // Restarted between the snapshots (another id), its new counters higher.
                ("gait_planner".to_owned(), process(12, 9_000, 9)),
            ]
            .into(),
        };
        let end = Work {
            cpu_ns: 3_000_000_000,
            context_switches: 40_100,
            udp_datagrams: 34_050,
            by_process: [
                ("sim_bridge".to_owned(), process(10, 2_000_600_000, 30_060)),
                ("ik_solver".to_owned(), process(11, 999_400_000, 10_040)),
                ("gait_planner".to_owned(), process(13, 500_000, 300)),
                // Not there at the start.
                ("joint_bridge".to_owned(), process(14, 7_000, 7)),
            ]
            .into(),
        };
        // 2000 ticks: 2.999 s of CPU, 40 000 switches, 34 000 datagrams; sim_bridge 2 s
        // and 30 000 switches of them, ik_solver 0.999 s and 10 000.
        assert_eq!(
            end.per_tick_since(&start, 2000),
            Some(TickWork {
                ticks: 2000,
                cpu_ms: 1.4995,
                context_switches: 20.0,
                udp_datagrams: 17.0,
                by_process: [
                    (
                        "ik_solver".to_owned(),
                        ProcessTickWork {
                            cpu_ms: 0.4995,
                            context_switches: 5.0,
                        }
                    ),
                    (
                        "sim_bridge".to_owned(),
                        ProcessTickWork {
                            cpu_ms: 1.0,
                            context_switches: 15.0,
                        }
                    ),
                ]
                .into(),
            })
        );
        assert_eq!(end.per_tick_since(&start, 0), None);
        assert_eq!(start.per_tick_since(&end, 10), None, "counters went back");
    }

    #[test]
    fn this_process_is_counted() {
        let me = Work::now(&[("me", std::process::id())]).unwrap();
        // Spin 20 ms on this thread: its on-CPU time grows (by how much depends on how
        // busy the machine is).
        let t = std::time::Instant::now();
        while t.elapsed() < std::time::Duration::from_millis(20) {
            std::hint::black_box(0u64);
        }
        let later = Work::now(&[("me", std::process::id())]).unwrap();
        assert!(later.cpu_ns > me.cpu_ns, "{me:?} -> {later:?}");
        assert!(later.context_switches >= me.context_switches);
        // The process's own counters are the totals (it is the only one).
        assert_eq!(later.by_process["me"].pid, std::process::id());
        assert_eq!(later.by_process["me"].cpu_ns, later.cpu_ns);
        assert_eq!(
            later.by_process["me"].context_switches,
            later.context_switches
        );
        let none = Work::now(&[("gone", u32::MAX)]).unwrap();
        assert_eq!(none.cpu_ns, 0, "no such process");
        assert!(none.by_process.is_empty(), "{none:?}");
    }
}
