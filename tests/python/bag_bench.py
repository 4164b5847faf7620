"""The rclpy ends of benches/bag_replay.rs (replay timing): the receiver that time-stamps what a
replayer sends, and the comparison replayer, a straightforward Python `ros2 bag play` without
rosbag2 (not on PyPI): rosbags' Reader + rclpy publishers.

    biped-python bag_bench.py receive TOPIC COUNT [--timeout S]
    biped-python bag_bench.py play BAG_DIR [--wait-for-subscribers S] [--delay S] [--deserialize]

receive: subscribes TOPIC (sensor_msgs/msg/JointState; reliable, volatile, keep last 10000 so
that nothing is dropped on our side) and prints one JSON line when the subscription exists
({"ready": true, "versions": "..."}), then, when COUNT messages with distinct header stamps
have arrived (or on SIGINT, or after --timeout, default 120 s), one JSON line
{"arrivals": [[stamp_ns, received_ns, source_ns], ...]}: the message's header stamp, Fast DDS's
reception time of the sample (system clock; set by its receive thread, so this script's own
Python speed does not blur it) and the writer's source time stamp.

play: reads every message of the bag into memory first, one publisher per topic with the
topic's first recorded QoS profile (keep last 10 where the history was not recorded, as
`ros2 bag play` and `biped replay` do), waits until every publisher has a subscriber (at most
--wait-for-subscribers, default 10 s) and then --delay (default 1 s), and plays: message i is
published at start + (t_i - t_0), sleeping (time.sleep) until that deadline; the serialized
CDR bytes are published as they are (rclpy's publish of bytes, as rosbag2 publishes
serialized messages), or with --deserialize, messages deserialized beforehand and published
as rclpy messages. Prints one JSON line at the end: {"sent": N, "max_late_ms": X} (the latest
a message was published after its due time).

Run by the bench inside its private network namespace.
"""

import argparse
import importlib
import json
import sys
import time
from importlib.metadata import PackageNotFoundError, version

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from rclpy.utilities import get_rmw_implementation_identifier
from sensor_msgs.msg import JointState


def dist_version(name):
    try:
        return version(name)
    except PackageNotFoundError:
        return "?"


def versions():
    return (f"rclpy {dist_version('ros-rclpy')} on {get_rmw_implementation_identifier()} "
            f"(Fast DDS {dist_version('ros-fastrtps')}), rosbags {dist_version('rosbags')}")


def get_message(type_name):
    """The rclpy class of `pkg/msg/Name` (rosidl_runtime_py's helper is not on PyPI)."""
    pkg, kind, name = type_name.split("/")
    return getattr(importlib.import_module(f"{pkg}.{kind}"), name)


def stamp_ns(header):
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec


def info_ns(info, key):
    t = info.get(key, 0) if isinstance(info, dict) else getattr(info, key, 0)
    return int(t) if t else 0


def receive(topic, count, timeout_s):
    rclpy.init()
    node = rclpy.create_node("bag_bench_receiver")
    arrivals = []
    seen = set()

    def on_message(msg, info):
        stamp = stamp_ns(msg.header)
        received = info_ns(info, "received_timestamp") or time.time_ns()
        arrivals.append([stamp, received, info_ns(info, "source_timestamp")])
        seen.add(stamp)

    qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10000,
                     reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
    node.create_subscription(JointState, topic, on_message, qos)
    print(json.dumps({"ready": True, "versions": versions()}), flush=True)
    end = time.monotonic() + timeout_s
    try:
        while len(seen) < count and time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.05)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    print(json.dumps({"arrivals": arrivals}), flush=True)


def qos_of(connection):
    """The connection's first recorded QoS profile as an rclpy profile."""
    profiles = getattr(connection.ext, "offered_qos_profiles", None) or []
    if isinstance(profiles, str) or not profiles:
        return QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    p = profiles[0]
    keep_all = p.history.name == "KEEP_ALL"
    return QoSProfile(
        history=HistoryPolicy.KEEP_ALL if keep_all else HistoryPolicy.KEEP_LAST,
        depth=p.depth or 10,
        reliability=(ReliabilityPolicy.BEST_EFFORT if p.reliability.name == "BEST_EFFORT"
                     else ReliabilityPolicy.RELIABLE),
        durability=(DurabilityPolicy.TRANSIENT_LOCAL if p.durability.name == "TRANSIENT_LOCAL"
                    else DurabilityPolicy.VOLATILE),
    )


def play(bag_dir, wait_s, delay_s, deserialize):
    from rosbags.rosbag2 import Reader

    rclpy.init()
    node = rclpy.create_node("bag_bench_player")
    publishers = {}
    messages = []
    with Reader(bag_dir) as reader:
        for c in reader.connections:
            if c.topic not in publishers:
                publishers[c.topic] = (node.create_publisher(get_message(c.msgtype), c.topic, qos_of(c)),
                                       get_message(c.msgtype))
        for c, t, raw in reader.messages():
            pub, msg_type = publishers[c.topic]
            data = deserialize_message(bytes(raw), msg_type) if deserialize else bytes(raw)
            messages.append((t, pub, data))
    messages.sort(key=lambda m: m[0])

    end = time.monotonic() + wait_s
    while time.monotonic() < end and any(p.get_subscription_count() == 0 for p, _ in publishers.values()):
        time.sleep(0.02)
    time.sleep(delay_s)

    t0 = messages[0][0] if messages else 0
    start = time.monotonic()
    max_late = 0.0
    sent = 0
    for t, pub, data in messages:
        due = start + (t - t0) * 1e-9
        left = due - time.monotonic()
        if left > 0:
            time.sleep(left)
        max_late = max(max_late, time.monotonic() - due)
        pub.publish(data)
        sent += 1
    # Let reliable writers deliver what is still in flight, as biped replay does.
    time.sleep(0.2)
    node.destroy_node()
    rclpy.try_shutdown()
    print(json.dumps({"sent": sent, "max_late_ms": max_late * 1e3}), flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    r = sub.add_parser("receive")
    r.add_argument("topic")
    r.add_argument("count", type=int)
    r.add_argument("--timeout", type=float, default=120.0)
    p = sub.add_parser("play")
    p.add_argument("bag_dir")
    p.add_argument("--wait-for-subscribers", type=float, default=10.0)
    p.add_argument("--delay", type=float, default=1.0)
    p.add_argument("--deserialize", action="store_true")
    args = parser.parse_args()
    if args.command == "receive":
        receive(args.topic, args.count, args.timeout)
    else:
        play(args.bag_dir, args.wait_for_subscribers, args.delay, args.deserialize)
    return 0


if __name__ == "__main__":
    sys.exit(main())
