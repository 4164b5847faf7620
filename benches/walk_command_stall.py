#!/usr/bin/env python3
"""How long the gait planner's control loop goes without publishing when a walk command
brings new parameters: the longest gap between the arrivals of consecutive `/gait/phase`
messages at a peer, from the command to the walk's first step, on the monotonic clock (a
robot's). (Arrivals, not stamps: a loop that stalls stamps the ticks it missed with their
own times as it catches up, sending them in a burst.)

    ROS_DOMAIN_ID=90 unshare -n sh -c 'ip link set lo up && exec "$@"' sh \\
        $BIPED_PYTHON benches/walk_command_stall.py BIN_DIR [PARAMS] [ROUNDS]

BIN_DIR holds the gait_planner binary (target/release); PARAMS defaults to
tests/data/gait_slow.yaml (durations set: a new step length needs the check walks, no
timing search); each of ROUNDS (default 5) one-step walks asks for another step length.
Prints one JSON line: the longest gap (ms) of each round, and the median gap between the
phases that arrived before the first command (the period the loop keeps standing, ms).
"""
import json
import os
import statistics
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "python"))
import fleet_peer as fp  # noqa: E402


def main():
    bin_dir = sys.argv[1]
    root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
    params = sys.argv[2] if len(sys.argv) > 2 else os.path.join(root, "tests", "data", "gait_slow.yaml")
    rounds = int(sys.argv[3]) if len(sys.argv) > 3 else 5
    procs = fp.start_nodes(bin_dir, params, only=["gait_planner"])
    peer = fp.Peer()
    arrivals = []
    peer.node.create_subscription(fp.GaitPhase, "/gait/phase", lambda m: arrivals.append((time.monotonic_ns(), m.phase)),
                                  fp.QoSProfile(depth=1000, reliability=fp.ReliabilityPolicy.RELIABLE))
    ok = peer.spin(30.0, lambda: len(peer.phases) > 20)
    gaps_ms = []
    # The period the loop keeps standing, before any command.
    steady = [t for t, _ in arrivals]
    steady = [(y - x) / 1e6 for x, y in zip(steady, steady[1:])]
    for r in range(rounds if ok else 0):
        sent = time.monotonic_ns()
        # Another step length each round, none the planner was checked for.
        peer.walk(1, step_length=0.030 + 0.002 * r)
        if not peer.spin(60.0, lambda: any(ph != "idle" for t, ph in arrivals if t > sent)):
            break
        # From the last phase before the command to the walk's first.
        start = max(i for i, (t, _) in enumerate(arrivals) if t <= sent)
        end = next(i for i, (t, ph) in enumerate(arrivals) if t > sent and ph != "idle")
        got = [t for t, _ in arrivals[start:end + 1]]
        gaps = [(y - x) / 1e6 for x, y in zip(got, got[1:])]
        gaps_ms.append(round(max(gaps), 2))
        peer.spin(60.0, lambda: peer.phases[-1]["phase"] == "idle")
        peer.spin(0.3)
    exits = fp.stop_nodes(procs)
    print(json.dumps({
        "bin_dir": bin_dir,
        "params": os.path.basename(params),
        "longest_gap_ms_per_round": gaps_ms,
        "standing_median_gap_ms": round(statistics.median(steady), 2) if steady else None,
        "planner_exit": exits["gait_planner"]["returncode"],
    }))


if __name__ == "__main__":
    main()
