#!/usr/bin/env python3
"""What a walk's bag says about TF, read by rosbags and checked against Pinocchio.

Usage (through the interpreter scripts/setup-python-env prints):
    biped-python tf_check.py BAG_DIR URDF

Reads the bag with rosbags (Jazzy type store; biped_msgs from msgs/msg/*.msg) and prints one
JSON object (the assertions are the Rust test's):
  links          every URDF link (Pinocchio's body frames)
  root           the URDF root link
  static_edges   [parent, child] of every transform on /tf_static
  moving_edges   [parent, child] of every transform on /tf from the robot state publisher
                 (frame_id not "odom")
  joint_states, joint_states_in_tf_span
                 how many /joint_states messages, and how many of them stamped within the
                 first and last /tf message of the robot state publisher (each topic's
                 recording starts when the recorder discovers it)
  compared       how many /joint_states messages had a /tf message of the same stamp, and
                 were compared
  max_position_error_m, max_rotation_error  over every link of every compared state: the
                 link's pose in the root link's frame composed from /tf_static and the /tf
                 message of that stamp, against Pinocchio's FK of the joint state's
                 positions (fixed base: the root link at the origin); rotation error as the
                 largest entry of the difference of rotation matrices
  missing_links  links the composition could not reach (no edge to the root)
  odom_tf        count of /tf transforms with frame_id "odom", their child frames, how many
                 are stamped within the first and last /odom message (in_odom_span), how
                 many have the /odom message of their stamp, and the largest difference (m)
                 between each and that message
  world_tf       the other /tf transforms (the simulator's ground truth, world -> base_gt):
                 count, edges, and the base's first and last x, y by both
"""

import json
import math
import pathlib
import sys

import numpy as np
import pinocchio as pin
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore, get_types_from_msg

HERE = pathlib.Path(__file__).resolve().parent


def typestore():
    ts = get_typestore(Stores.ROS2_JAZZY)
    for f in sorted((HERE.parent.parent / "msgs" / "msg").glob("*.msg")):
        ts.register(get_types_from_msg(f.read_text(), f"biped_msgs/msg/{f.stem}"))
    return ts


def stamp_ns(header):
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec


def matrix(t):
    """4x4 of a geometry_msgs/Transform."""
    q = t.rotation
    r = pin.Quaternion(q.w, q.x, q.y, q.z).normalized().toRotationMatrix()
    m = np.eye(4)
    m[:3, :3] = r
    m[:3, 3] = [t.translation.x, t.translation.y, t.translation.z]
    return m


def main(bag_dir, urdf):
    model = pin.buildModelFromUrdf(urdf)
    data = model.createData()
    links = [f.name for f in model.frames if f.type == pin.BODY]
    # The root link: the body frame whose parent frame is the universe's.
    root = next(f.name for f in model.frames if f.type == pin.BODY and f.parentFrame == 0)

    states, tf_by_stamp, static, odom_tf, world_tf, odom = {}, {}, {}, [], [], {}
    with AnyReader([pathlib.Path(bag_dir)], default_typestore=typestore()) as reader:
        for conn, _, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic == "/joint_states":
                states[stamp_ns(msg.header)] = dict(zip(msg.name, msg.position))
            elif conn.topic == "/tf_static":
                for t in msg.transforms:
                    static[t.child_frame_id] = (t.header.frame_id, matrix(t.transform))
            elif conn.topic == "/tf":
                for t in msg.transforms:
                    if t.header.frame_id == "odom":
                        odom_tf.append(t)
                    elif t.header.frame_id not in links:
                        world_tf.append(t)
                    else:
                        edges = tf_by_stamp.setdefault(stamp_ns(t.header), {})
                        edges[t.child_frame_id] = (t.header.frame_id, matrix(t.transform))
            elif conn.topic == "/odom":
                odom[stamp_ns(msg.header)] = msg

    moving_edges = sorted({(p, c) for edges in tf_by_stamp.values() for c, (p, _) in edges.items()})
    frame_ids = {name: model.getFrameId(name, pin.BODY) for name in links}
    compared, max_pos, max_rot, missing = 0, 0.0, 0.0, set()
    for stamp, positions in sorted(states.items()):
        edges = tf_by_stamp.get(stamp)
        if edges is None:
            continue
        compared += 1
        q = pin.neutral(model)
        for name, value in positions.items():
            if not model.existJointName(name):
                continue
            j = model.joints[model.getJointId(name)]
            if j.nq == 1:
                q[j.idx_q] = value
            else:
                q[j.idx_q], q[j.idx_q + 1] = math.cos(value), math.sin(value)
        pin.framesForwardKinematics(model, data, q)
        every = dict(static)
        every.update(edges)

        def pose(link, depth=0):
            if link == root:
                return np.eye(4)
            if link not in every or depth > 100:
                return None
            parent, m = every[link]
            p = pose(parent, depth + 1)
            return None if p is None else p @ m

        for name in links:
            ours = pose(name)
            if ours is None:
                missing.add(name)
                continue
            ref = data.oMf[frame_ids[name]]
            max_pos = max(max_pos, float(np.abs(ours[:3, 3] - ref.translation).max()))
            max_rot = max(max_rot, float(np.abs(ours[:3, :3] - ref.rotation).max()))

    # The recorder subscribes each topic as it discovers it, so each stream begins at its
    # own time: pairs are looked for only where both streams were recorded.
    tf_span = (min(tf_by_stamp), max(tf_by_stamp)) if tf_by_stamp else (0, -1)
    states_in_tf_span = sum(1 for s in states if tf_span[0] <= s <= tf_span[1])
    odom_span = (min(odom), max(odom)) if odom else (0, -1)
    odom_tf_in_span = sum(1 for t in odom_tf if odom_span[0] <= stamp_ns(t.header) <= odom_span[1])
    odom_diff = 0.0
    odom_matched = 0
    for t in odom_tf:
        o = odom.get(stamp_ns(t.header))
        if o is None:
            continue
        odom_matched += 1
        p, r = o.pose.pose.position, o.pose.pose.orientation
        tr, rr = t.transform.translation, t.transform.rotation
        odom_diff = max(odom_diff, abs(p.x - tr.x), abs(p.y - tr.y), abs(p.z - tr.z),
                        abs(r.x - rr.x), abs(r.y - rr.y), abs(r.z - rr.z), abs(r.w - rr.w))
    # Where the ground truth and the odometry put the base, first and last (x, y).
    def xy(t):
        return [t.transform.translation.x, t.transform.translation.y]
    start_xy = {"world": xy(world_tf[0]) if world_tf else None, "odom": xy(odom_tf[0]) if odom_tf else None}
    end_xy = {"world": xy(world_tf[-1]) if world_tf else None, "odom": xy(odom_tf[-1]) if odom_tf else None}
    json.dump({
        "links": links,
        "root": root,
        "static_edges": sorted([p, c] for c, (p, _) in static.items()),
        "moving_edges": [list(e) for e in moving_edges],
        "joint_states": len(states),
        "joint_states_in_tf_span": states_in_tf_span,
        "compared": compared,
        "max_position_error_m": max_pos,
        "max_rotation_error": max_rot,
        "missing_links": sorted(missing),
        "odom_tf": {"count": len(odom_tf), "children": sorted({t.child_frame_id for t in odom_tf}),
                    "in_odom_span": odom_tf_in_span, "matched_odom": odom_matched,
                    "max_difference": odom_diff},
        "world_tf": {"count": len(world_tf),
                     "edges": sorted({(t.header.frame_id, t.child_frame_id) for t in world_tf}),
                     "start_xy": start_xy, "end_xy": end_xy},
    }, sys.stdout)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    main(sys.argv[1], sys.argv[2])
