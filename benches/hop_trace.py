#!/usr/bin/env python3
"""Where the time of the pipeline bench's two DDS hops goes, from a kernel trace.

Record the pipeline bench with the scheduler and socket tracepoints (as root):

    B=$(ls -t target/release/deps/pipeline-* | grep -v '\\.d$' | head -1)
    perf record -a -o /tmp/perf.pipe \\
        -e sched:sched_switch,sched:sched_wakeup \\
        -e syscalls:sys_enter_sendto,syscalls:sys_enter_recvmsg,syscalls:sys_enter_write \\
        -- $B --bench --only ik_solver --n-100hz 300 --n-1khz 1000
    perf script -i /tmp/perf.pipe -F comm,tid,cpu,time,event,trace > /tmp/pipe.txt

Then find the five threads (`grep -v '^ *perf ' /tmp/pipe.txt | awk '{print $1, $2}' |
sort | uniq -c`): the bench's main thread (publishes; its tid is the pipeline process's
pid), the bench's "RustDDS Partici" thread (sends the ankle targets, receives the joint
commands), the ik_solver's "RustDDS Partici" thread, the ik_solver's main thread, and the
bench thread that takes the joint commands (the other busy "pipeline-..." thread), and run

    benches/hop_trace.py /tmp/pipe.txt PUBLISHER BENCH_DDS IK_DDS IK SUBSCRIBER

It follows each message through eight events and prints the median of each stage, for the
messages sent after an idle period (the 100 Hz part) and in a fast stream (1 kHz):

    publish   the bench's main thread writes to its DDS thread's wake-up (eventfd)
    send1     the bench's DDS thread sends the DATA (sendto, over 100 bytes)
    recv1     the ik_solver's DDS thread receives it (recvmsg)
    ik_run    the ik_solver's main thread is switched in
    ik_pub    it hands its joint command to its DDS thread (write to the eventfd)
    send2     that thread sends the DATA
    recv2     the bench's DDS thread receives it
    take      the bench's subscriber thread is switched in

Tracing slows every stage (each event costs a few microseconds); compare the stages with
each other and with `cargo bench --bench wake_floor`, not with the bench's own figures.
"""

import re
import statistics
import sys

STAGES = ["publish", "send1", "recv1", "ik_run", "ik_pub", "send2", "recv2", "take"]
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

    for line in open(path, encoding="utf-8", errors="replace"):
        m = LINE.match(line)
        if not m:
            continue
        _, tid, _, t, event, rest = m.groups()
        tid, t = int(tid), float(t)
        if tid == pub and event == "syscalls:sys_enter_write":
            if cur is not None and len(cur) == len(STAGES):
                messages.append(cur)
            cur = {"publish": t}
            continue
        if cur is None:
            continue
        want = STAGES[len(cur)] if len(cur) < len(STAGES) else None
        switched_to = re.search(r"next_pid=(\d+)", rest)
        switched_to = int(switched_to.group(1)) if switched_to else None
        hit = {
            "send1": tid == bench_dds
            and event == "syscalls:sys_enter_sendto"
            and data_len(rest) > 100,
            "recv1": tid == ik_dds and event == "syscalls:sys_enter_recvmsg",
            "ik_run": event == "sched:sched_switch" and switched_to == ik,
            "ik_pub": tid == ik and event == "syscalls:sys_enter_write",
            "send2": tid == ik_dds
            and event == "syscalls:sys_enter_sendto"
            and data_len(rest) > 100,
            "recv2": tid == bench_dds and event == "syscalls:sys_enter_recvmsg",
            "take": event == "sched:sched_switch" and switched_to == sub,
        }.get(want, False)
        if hit:
            cur[want] = t
    if not messages:
        print("no message followed through all stages: check the thread ids")
        return 1
    gaps = [b["publish"] - a["publish"] for a, b in zip(messages, messages[1:])]
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
            d = statistics.median((m[b] - m[a]) * 1e6 for m in sel)
            print(f"  {a:>8} -> {b:<8} {d:7.1f} us")
        total = statistics.median((m["take"] - m["publish"]) * 1e6 for m in sel)
        print(f"  {'total':>20} {total:7.1f} us")
    return 0


if __name__ == "__main__":
    sys.exit(main())
