"""The ROS 2 side of the bag tests: starts fleet nodes, runs `biped record` / `biped replay`
as a user would, watches the fleet with rclpy, and prints what it saw as one JSON object.
The assertions are the Rust test's (tests/bag_fleet.rs).

    python bag_peer.py record BIN_DIR OUT_DIR     # record the walking fleet, two bags
    python bag_peer.py replay BIN_DIR BAG_DIR     # replay a bag into gait_planner + joint_bridge
    python bag_peer.py replay_all BIN_DIR BAG_DIR # replay every topic of a bag into rclpy

Run inside a private network namespace (the Rust test does it).
"""

import json
import os
import signal
import subprocess
import sys
import time

import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from geometry_msgs.msg import Twist
from sensor_msgs.msg import JointState

from fleet_peer import Peer, start_nodes, stop_nodes, stamp_ns


def receive_ns(info):
    """Fast DDS's reception time of a message (system clock, ns), else now."""
    t = info.get("received_timestamp", 0) if isinstance(info, dict) else getattr(info, "received_timestamp", 0)
    return int(t) if t else time.time_ns()


def spin_while(peer, proc, limit_s):
    """Spins the peer until `proc` exits (or the limit); returns its exit code or None."""
    end = time.monotonic() + limit_s
    while time.monotonic() < end:
        rclpy.spin_once(peer.node, timeout_sec=0.005)
        if proc.poll() is not None:
            return proc.returncode
    return None


def finish(proc, sig=signal.SIGINT, timeout=20):
    if proc.poll() is None:
        proc.send_signal(sig)
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
    return {"returncode": proc.returncode, "stdout": out[-4000:], "stderr": err[-4000:]}


def scenario_record(bin_dir, out_dir):
    biped = os.path.join(bin_dir, "biped")
    from sensor_msgs.msg import Imu

    nodes = start_nodes(bin_dir, None)
    peer = Peer()
    # A type that is not in biped's own table (a user's IMU driver): the recorder reads its
    # definition from sensor_msgs' installed .msg files (AMENT_PREFIX_PATH, which this
    # interpreter's wrapper sets, as a sourced ROS 2 setup would).
    imu_pub = peer.node.create_publisher(Imu, "/imu", 10)
    imu_sent = []

    def send_imu():
        m = Imu()
        m.header.frame_id = "imu_link"
        m.header.stamp.sec = len(imu_sent)
        m.linear_acceleration.z = 9.81 + 0.001 * len(imu_sent)
        m.orientation_covariance[0] = -1.0
        imu_pub.publish(m)
        imu_sent.append(m.linear_acceleration.z)

    peer.node.create_timer(0.05, send_imu)
    out = {"flow": peer.wait_for_flow()}
    mcap_bag = os.path.join(out_dir, "fleet_mcap")
    sqlite_bag = os.path.join(out_dir, "fleet_sqlite")
    rec_all = subprocess.Popen([biped, "record", mcap_bag, "--all"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    rec_sql = subprocess.Popen([biped, "record", sqlite_bag, "--storage", "sqlite3", "--duration", "12",
                                "--topics", "/joint_commands", "/gait/phase", "/cmd_vel", "/walk_command"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # The recorders subscribe to what they discover; give discovery a moment, then walk.
    peer.spin(3.0)
    peer.wait_for_subscribers(peer.walk_pub)
    peer.walk(1)
    out["walked"] = peer.spin(40.0, peer.idle_after_walking)
    peer.cmd_vel_pub.publish(Twist())  # stop: a no-op when idle, recorded on /cmd_vel
    peer.spin(1.0)
    # Ctrl-C the --all recorder mid-stream: the bag must still be complete.
    out["record_all"] = finish(rec_all)
    rc = spin_while(peer, rec_sql, 30.0)
    out["record_sqlite"] = finish(rec_sql)
    out["record_sqlite"]["ended_by_duration"] = rc == 0
    out["bags"] = {"mcap": mcap_bag, "sqlite3": sqlite_bag}
    out["nodes"] = stop_nodes(nodes)
    out["imu_sent"] = len(imu_sent)
    # The IMU topic replayed from the bag alone (its stored definition describes the type to
    # `biped replay`), renamed, into an rclpy subscriber.
    replayed = []
    peer.node.create_subscription(Imu, "/imu_replayed", lambda m: replayed.append(
        {"frame": m.header.frame_id, "sec": m.header.stamp.sec, "az": m.linear_acceleration.z,
         "cov0": m.orientation_covariance[0]}), QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE))
    replay = subprocess.Popen([biped, "replay", mcap_bag, "--topics", "/imu", "--remap", "/imu:=/imu_replayed",
                               "--wait-for-subscribers", "20"],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    spin_while(peer, replay, 120.0)
    peer.spin(1.0)
    out["imu_replay"] = finish(replay)
    out["imu_replayed"] = replayed
    return out


def scenario_replay(bin_dir, bag_dir):
    biped = os.path.join(bin_dir, "biped")
    # No ik_solver: the bag's joint commands are the only ones the bridge gets.
    nodes = start_nodes(bin_dir, None, only=["gait_planner", "joint_bridge"])
    peer = Peer()
    qos = QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE)
    arrivals = {"/cmd_vel": [], "/joint_commands": []}
    # Reception times of what the replay sends, stamped by Fast DDS on arrival.
    peer.node.create_subscription(Twist, "/cmd_vel", lambda m, info: arrivals["/cmd_vel"].append(
        {"recv_ns": receive_ns(info), "x": m.linear.x}), qos)
    peer.node.create_subscription(JointState, "/joint_commands", lambda m, info: arrivals["/joint_commands"].append(
        {"recv_ns": receive_ns(info), "stamp": stamp_ns(m.header)}), qos)
    out = {"states_flowing": peer.spin(30.0, lambda: len(peer.states) > 5)}
    states_before = len(peer.states)
    replay = subprocess.Popen([biped, "replay", bag_dir], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    spin_while(peer, replay, 60.0)
    peer.spin(1.5)
    out["replay"] = finish(replay)
    out["arrivals"] = arrivals
    out["phases"] = sorted({p["phase"] for p in peer.phases})
    out["states_after"] = peer.states[states_before:][-1:] + peer.states[states_before:][:1]
    out["nodes"] = stop_nodes(nodes)
    return out


def scenario_replay_all(bin_dir, bag_dir):
    """`biped replay` of every topic of a bag (slowed to a quarter: rclpy's spinning is the
    bottleneck) into an rclpy node subscribed to every topic with its type, transient local
    where the bag recorded it so. Per topic: what the bag holds (rosbags reads the raw CDR,
    rclpy decodes it) and what arrived (rclpy decodes it), each as msg_check's JSON of the
    decoded message, so the Rust test can match one against the other."""
    import yaml
    from rclpy.qos import DurabilityPolicy
    from rclpy.serialization import deserialize_message
    from rosbags.rosbag2 import Reader

    from msg_check import message_class, to_json

    with open(os.path.join(bag_dir, "metadata.yaml")) as f:
        meta = yaml.safe_load(f)["rosbag2_bagfile_information"]
    topics = {}
    for t in meta["topics_with_message_count"]:
        md = t["topic_metadata"]
        latched = any(q.get("durability") == "transient_local" for q in md["offered_qos_profiles"])
        topics[md["name"]] = (md["type"], latched)
    out = {"topics": {}, "undecodable": []}
    recorded = {name: [] for name in topics}
    with Reader(bag_dir) as reader:
        for conn, _, raw in reader.messages():
            cls = message_class(topics[conn.topic][0])
            recorded[conn.topic].append(json.dumps(to_json(deserialize_message(bytes(raw), cls)), sort_keys=True))
    peer = Peer()
    received = {name: [] for name in topics}

    def on(name, cls):
        def cb(raw):
            try:
                received[name].append(json.dumps(to_json(deserialize_message(raw, cls)), sort_keys=True))
            except Exception as e:  # noqa: BLE001 - reported, asserted on by the test
                out["undecodable"].append(f"{name}: {e}")
        return cb

    for name, (type_name, latched) in topics.items():
        qos = QoSProfile(depth=20000, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)
        peer.node.create_subscription(message_class(type_name), name, on(name, message_class(type_name)), qos, raw=True)
    peer.spin(1.0)
    biped = os.path.join(bin_dir, "biped")
    replay = subprocess.Popen([biped, "replay", bag_dir, "--rate", "0.25", "--wait-for-subscribers", "30"],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    spin_while(peer, replay, 240.0)
    peer.spin(2.0)
    out["replay"] = finish(replay)
    for name, (type_name, latched) in topics.items():
        out["topics"][name] = {"type": type_name, "latched": latched,
                               "recorded": recorded[name], "received": received[name]}
    return out


def main():
    scenario, bin_dir, path = sys.argv[1], sys.argv[2], sys.argv[3]
    result = {"record": scenario_record, "replay": scenario_replay,
              "replay_all": scenario_replay_all}[scenario](bin_dir, path)
    json.dump(result, sys.stdout)


if __name__ == "__main__":
    main()
