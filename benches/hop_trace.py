#!/usr/bin/env python3
"""Where the time of the pipeline bench's two DDS hops goes, from a kernel trace.

Record the pipeline bench with the scheduler and socket tracepoints (as root):

    B=$(ls -t target/release/deps/pipeline-* | grep -v '\\.d$' | head -1)
    perf record -a -o /tmp/perf.pipe \\
        -e sched:sched_switch,sched:sched_wakeup \\
        -e syscalls:sys_enter_sendto,syscalls:sys_enter_recvmsg \\
        -- $B --bench --only ik_solver --n-100hz 300 --n-1khz 1000
    perf script -i /tmp/perf.pipe -F comm,tid,cpu,time,event,trace > /tmp/pipe.txt

Then find the five threads (`grep -v '^ *perf ' /tmp/pipe.txt | awk '{print $1, $2}' |
sort | uniq -c`): the bench's main thread (publishes and, since the RustDDS patch "a writer
sends a fresh sample from the writing thread", sends the DATA itself; its tid is the
pipeline process's pid), the bench's "RustDDS Partici" thread (receives the joint
commands), the ik_solver's "RustDDS Partici" thread, the ik_solver's main thread, and the
bench thread that takes the joint commands (the other busy "pipeline-..." thread; the
ik_solver's DDS thread is the one that calls recvmsg right after the bench's main thread
sends a DATA of 204 bytes, len 0xcc), and run

    benches/hop_trace.py /tmp/pipe.txt PUBLISHER BENCH_DDS IK_DDS IK SUBSCRIBER

It follows each message through these events and prints the median of each stage, for the
messages sent after an idle period (the 100 Hz part) and in a fast stream (1 kHz):

    send1     the bench's main thread sends the DATA (sendto, over 100 bytes)
    dds1_run  the ik_solver's DDS thread is switched in (*)
    recv1     it receives the DATA (recvmsg)
    ik_wake   it wakes the ik_solver's main thread (*)
    ik_run    that thread is switched in (*)
    send2     it sends its joint command's DATA (sendto, over 100 bytes)
    dds2_run  the bench's DDS thread is switched in (*)
    recv2     it receives the DATA
    sub_wake  it wakes the bench's subscriber thread (*)
    take      that thread is switched in

(*) A thread that was running already is not switched in, and one that was not blocked is
not woken: such a stage takes no time (it gets the next stage's time).

Tracing slows every stage (each event costs a few microseconds); compare the stages with
each other and with `cargo bench --bench wake_floor`, not with the bench's own figures.
"""

import re
import statistics
import sys

STAGES = [
    "send1", "dds1_run", "recv1", "ik_wake", "ik_run", "send2",
    "dds2_run", "recv2", "sub_wake", "take",
]
OPTIONAL = {"dds1_run", "ik_wake", "ik_run", "dds2_run", "sub_wake"}
LINE = re.compile(r"\s*(.+?)\s+(\d+)\s+\[(\d+)\]\s+([\d.]+):\s+(\S+):\s*(.*)")


def main() -> int:
    if len(sys.argv) != 7:
        print(__doc__)
        return 2
    path = sys.argv[1]
    pub, bench_dds, ik_dds, ik, sub = (int(a) for a in sys.argv[2:])
    messages, cur = [], None

    def data_len(rest: str) -> int:
        m = re.search(r"len: (0x[0-9a-f]+)", rest)
        return int(m.group(1), 16) if m else 0

    def sent_data(tid: int, want_tid: int, event: str, rest: str) -> bool:
        return (
            tid == want_tid
            and event == "syscalls:sys_enter_sendto"
            and data_len(rest) > 100
        )

    for line in open(path, encoding="utf-8", errors="replace"):
        m = LINE.match(line)
        if not m:
            continue
        _, tid, cpu, t, event, rest = m.groups()
        tid, t = int(tid), float(t)
        if sent_data(tid, pub, event, rest):
            if cur is not None and len(cur) == len(STAGES):
                messages.append(cur)
            cur = {"send1": (t, int(cpu))}
            continue
        if cur is None:
            continue
        switched_to = re.search(r"next_pid=(\d+)", rest)
        switched_to = int(switched_to.group(1)) if switched_to else None
        woken = re.search(r"\bpid=(\d+)", rest) if event == "sched:sched_wakeup" else None
        woken = int(woken.group(1)) if woken else None
        hit = {
            "dds1_run": event == "sched:sched_switch" and switched_to == ik_dds,
            "recv1": tid == ik_dds and event == "syscalls:sys_enter_recvmsg",
            "ik_wake": woken == ik,
            "ik_run": event == "sched:sched_switch" and switched_to == ik,
            "send2": sent_data(tid, ik, event, rest),
            "dds2_run": event == "sched:sched_switch" and switched_to == bench_dds,
            "recv2": tid == bench_dds and event == "syscalls:sys_enter_recvmsg",
            "sub_wake": woken == sub,
            "take": event == "sched:sched_switch" and switched_to == sub,
        }
        # The first stage not reached yet that this event is; optional stages before it
        # took no time.
        for i in range(len(cur), len(STAGES)):
            stage = STAGES[i]
            if hit.get(stage, False):
                for skipped in STAGES[len(cur):i]:
                    cur[skipped] = (t, int(cpu))
                cur[stage] = (t, int(cpu))
                break
            if stage not in OPTIONAL:
                break
    if not messages:
        print("no message followed through all stages: check the thread ids")
        return 1
    gaps = [b["send1"][0] - a["send1"][0] for a, b in zip(messages, messages[1:])]
    groups = {
        "after an idle period (>= 5 ms since the last message)": [
            m for g, m in zip(gaps, messages[1:]) if g >= 0.005
        ],
        "in a fast stream (< 2 ms since the last message)": [
            m for g, m in zip(gaps, messages[1:]) if g < 0.002
        ],
    }
    for name, sel in groups.items():
        if not sel:
            continue
        print(f"{len(sel)} messages {name}:")
        for a, b in zip(STAGES, STAGES[1:]):
            d = statistics.median((m[b][0] - m[a][0]) * 1e6 for m in sel)
            same = sum(m[b][1] == m[a][1] for m in sel) / len(sel)
            print(f"  {a:>8} -> {b:<8} {d:7.1f} us   same CPU {same:4.0%}")
        total = statistics.median((m["take"][0] - m["send1"][0]) * 1e6 for m in sel)
        print(f"  {'total':>20} {total:7.1f} us")
    return 0


if __name__ == "__main__":
    sys.exit(main())
