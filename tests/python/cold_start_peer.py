"""One cold start of the fleet with a real ROS 2 Jazzy peer (rclpy + Fast DDS) started at
the same instant, as a user would start `ros2 node list` or `ros2 topic pub` while the fleet
comes up. Run inside a private network namespace (tests/cold_start.rs does it).

    python cold_start_peer.py BIN_DIR [LOG_DIR]

At t = 0 it starts the fleet's node processes, an observer rclpy participant (this process)
and a `ros2 topic pub --once -w 1 /cmd_vel` stand-in (a second process: its own participant,
as the CLI would be), all without waiting for each other. It records when the observer
first sees each node and each fleet endpoint, when data first flows, whether the one
/cmd_vel was published and whether the planner's /gait/phase then left `idle`; prints that
as one JSON object on stdout. The assertions are the Rust test's.

The nodes' stderr goes to LOG_DIR/<node>.log (default: a new temporary folder; set RUST_LOG
for RustDDS' discovery log).
"""

import json
import os
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fleet_peer  # noqa: E402  (the peer, node list and stop helpers of the fleet tests)

# What a ROS tool expects to see of the idle fleet: (topic, "pub" | "sub").
ENDPOINTS = [
    ("/cmd_vel", "sub"), ("/walk_command", "sub"), ("/gait/phase", "pub"),
    ("/gait/ankle_targets", "pub"), ("/gait/ankle_targets", "sub"),
    ("/joint_commands", "pub"), ("/joint_commands", "sub"), ("/joint_states", "pub"),
]
DISCOVERY_TIMEOUT_S = float(os.environ.get("BIPED_COLD_START_TIMEOUT_S", "20"))

# `ros2 topic pub --once -w 1 /cmd_vel geometry_msgs/msg/Twist "{linear: {x: 0.02}}"`, as
# ros2cli does it: wait for one matched subscription, publish once, keep the publisher
# 0.1 s, exit. Prints the time it published (monotonic), or nothing if no match came.
PUB_ONCE = r"""
import sys, time, rclpy
from geometry_msgs.msg import Twist
rclpy.init()
node = rclpy.create_node("cold_start_pub_once")
pub = node.create_publisher(Twist, "/cmd_vel", 10)
end = time.monotonic() + float(sys.argv[1])
while pub.get_subscription_count() < 1 and time.monotonic() < end:
    rclpy.spin_once(node, timeout_sec=0.01)
if pub.get_subscription_count() >= 1:
    msg = Twist()
    msg.linear.x = 0.02
    pub.publish(msg)
    print(time.monotonic(), flush=True)
    time.sleep(0.1)
node.destroy_node()
rclpy.shutdown()
"""


def main():
    bin_dir = sys.argv[1]
    log_dir = sys.argv[2] if len(sys.argv) > 2 else tempfile.mkdtemp(prefix="biped-cold-start-")
    t0 = time.monotonic()
    procs = {}
    for name in fleet_peer.NODES:
        with open(os.path.join(log_dir, f"{name}.log"), "w") as err:
            procs[name] = subprocess.Popen([os.path.join(bin_dir, name), "--ros-args"],
                                           stdout=subprocess.DEVNULL, stderr=err)
        fleet_peer.STARTED.append(procs[name])
    pub_once = subprocess.Popen([sys.executable, "-c", PUB_ONCE, str(DISCOVERY_TIMEOUT_S)],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    fleet_peer.STARTED.append(pub_once)
    peer = fleet_peer.Peer()
    t_peer = time.monotonic() - t0

    nodes_seen, endpoints_seen, first = {}, {}, {}

    def look():
        now = time.monotonic() - t0
        for n in peer.node_names():
            nodes_seen.setdefault(n, now)
        for topic, kind in ENDPOINTS:
            count = peer.node.count_publishers(topic) if kind == "pub" else peer.node.count_subscribers(topic)
            if count > 0:
                endpoints_seen.setdefault(f"{kind} {topic}", now)
        for key, got in (("phase", peer.phases), ("joint_commands", peer.commands), ("joint_states", peer.states)):
            if got:
                first.setdefault(key, now)
        return (all(n in nodes_seen for n in fleet_peer.NODES)
                and len(endpoints_seen) == len(ENDPOINTS) and len(first) == 3)

    everything = peer.spin(DISCOVERY_TIMEOUT_S, look)
    look()
    # The one /cmd_vel: did the planner start walking after it? (The walk starts with
    # `crouch`; idle phases before it are the idle fleet's.)
    try:
        pub_out, pub_err = pub_once.communicate(timeout=DISCOVERY_TIMEOUT_S + 5)
    except subprocess.TimeoutExpired:
        pub_once.kill()
        pub_out, pub_err = pub_once.communicate()
    published_at = float(pub_out.split()[0]) - t0 if pub_out.strip() else None
    walking = lambda: any(p["phase"] != "idle" for p in peer.phases)  # noqa: E731
    walk_started = published_at is not None and peer.spin(10.0, walking)
    walk_t = time.monotonic() - t0 if walk_started else None
    out = {
        "peer_created_s": t_peer,
        "nodes_seen_s": {n: nodes_seen.get(n) for n in fleet_peer.NODES},
        "endpoints_seen_s": {f"{k} {t}": endpoints_seen.get(f"{k} {t}") for t, k in ENDPOINTS},
        "first_data_s": first,
        "everything_seen": everything,
        "cmd_vel_published_s": published_at,
        "pub_once_returncode": pub_once.returncode,
        "pub_once_stderr": pub_err[-2000:],
        "walk_started": walk_started,
        "walk_started_s": walk_t,
    }
    out["exits"] = fleet_peer.stop_nodes(procs)
    for name, exit_ in out["exits"].items():
        with open(os.path.join(log_dir, f"{name}.log"), errors="replace") as f:
            exit_["stderr_tail"] = f.read()[-2000:]
    out["log_dir"] = log_dir
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    try:
        main()
    finally:
        fleet_peer.stop_started()
