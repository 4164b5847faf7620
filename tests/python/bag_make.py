#!/usr/bin/env python3
"""Writes a rosbag2 bag (ROS 2 Jazzy format, metadata.yaml version 9) from a JSON spec, with
rosbags' writer: the stand-in for `ros2 bag record` in our tests (rosbag2 is not on PyPI).

Usage (through the interpreter scripts/setup-python-env prints):
    biped-python bag_make.py OUT_DIR --storage mcap|sqlite3 --spec SPEC.json [--topic-type-hash]

OUT_DIR must not exist; it becomes the bag directory (metadata.yaml + OUT_DIR_NAME.mcap or
.db3). SPEC.json ("-" for stdin):
    {
      "topics": [
        {"name": "/cmd_vel", "type": "geometry_msgs/msg/Twist",
         "qos": {"reliability": "reliable", "durability": "volatile",
                 "history": "keep_last", "depth": 10}},
        ...
      ],
      "messages": [
        {"topic": "/cmd_vel", "t_ns": 1700000000000000000,
         "msg": {"linear": {"x": 0.02, "y": 0, "z": 0}, "angular": {"z": 0.1}}},
        ...
      ]
    }
Types: the rosbags Jazzy typestore (std, geometry, sensor msgs...) plus biped_msgs from
msgs/msg/*.msg. Messages are built from nested JSON objects: nested messages as objects
(a Header as {"stamp": {"sec": 1, "nanosec": 2}, "frame_id": "base_link"}), arrays and
sequences as lists, floats as numbers or "NaN"/"Infinity"/"-Infinity". Omitted fields take the
message defaults (0, 0.0, false, "", empty sequences, fixed arrays of defaults); unknown fields
are an error. Messages are written in the order given (log time = t_ns).

QoS: "qos" is one profile or a list of them (one per publisher; omitted: no profile). Keys and
defaults: history "keep_last", depth 10, reliability "reliable", durability "volatile",
liveliness "automatic", deadline / lifespan / liveliness_lease_duration {"sec", "nsec"}
(default INFINITE_TIME below), avoid_ros_namespace_conventions false. Names are those of
version 9 metadata: keep_last/keep_all/system_default, reliable/best_effort/best_available,
volatile/transient_local, automatic/manual_by_topic...

--topic-type-hash (MCAP only): also write the channel metadata entry topic_type_hash, as
Jazzy's recorder does and rosbags' writer does not, so that the bag passes
`bag_check.py --strict`.

Prints one JSON line: {"bag": "/abs/OUT_DIR", "storage": "mcap", "message_count": N}.
Exit codes: 0 ok; 2 bad usage or spec (message on stderr); 1 anything else.
"""

import argparse
import json
import math
import sys
from io import BytesIO
from pathlib import Path

import numpy as np
from rosbags.interfaces import (
    Nodetype,
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2 import storage_mcap
from rosbags.typesys.base import normalize_fieldname

# Same directory: the typestore both scripts use (Jazzy + biped_msgs from msgs/msg).
from bag_check import make_typestore

# The "infinite" duration written for deadline, lifespan and liveliness_lease_duration when the
# spec gives none: Fast DDS's old infinite (0x7FFFFFFF s, 0xFFFFFFFF ns), which rosbag2 still
# reads as infinite. (rmw's RMW_DURATION_INFINITE, what a Jazzy rmw reports for a default
# publisher, is {sec: 9223372036, nsec: 854775807}; give it per topic to write that instead.)
INFINITE_TIME = {"sec": 2147483647, "nsec": 4294967295}
QOS_DEFAULTS = {
    "history": "keep_last", "depth": 10, "reliability": "reliable", "durability": "volatile",
    "liveliness": "automatic", "deadline": INFINITE_TIME, "lifespan": INFINITE_TIME,
    "liveliness_lease_duration": INFINITE_TIME, "avoid_ros_namespace_conventions": False,
}
SPECIAL_FLOATS = {"NaN": math.nan, "Infinity": math.inf, "-Infinity": -math.inf}
# ROS basic type -> numpy dtype, for the numeric arrays rosbags keeps as numpy arrays.
NUMPY_TYPES = {
    "bool": np.bool_, "byte": np.uint8, "char": np.uint8, "octet": np.uint8,
    "int8": np.int8, "uint8": np.uint8, "int16": np.int16, "uint16": np.uint16,
    "int32": np.int32, "uint32": np.uint32, "int64": np.int64, "uint64": np.uint64,
    "float32": np.float32, "float64": np.float64,
}
INT_RANGES = {
    "byte": (0, 255), "char": (0, 255), "octet": (0, 255),
    "int8": (-2**7, 2**7 - 1), "uint8": (0, 2**8 - 1), "int16": (-2**15, 2**15 - 1),
    "uint16": (0, 2**16 - 1), "int32": (-2**31, 2**31 - 1), "uint32": (0, 2**32 - 1),
    "int64": (-2**63, 2**63 - 1), "uint64": (0, 2**64 - 1),
}


class SpecError(Exception):
    """A spec that cannot be written: exit code 2."""


# ------------------------------------------------------------------ messages


def build(typestore, type_name, value, where):
    """A typestore message object from a JSON object (omitted fields: defaults)."""
    if type_name not in typestore.fielddefs:
        raise SpecError(f"{where}: unknown message type {type_name}")
    if not isinstance(value, dict):
        raise SpecError(f"{where}: expected an object for {type_name}, got {json.dumps(value)}")
    fields = typestore.fielddefs[type_name][1]
    unknown = sorted(set(value) - {name for name, _ in fields})
    if unknown:
        raise SpecError(f"{where}: {type_name} has no field(s) {unknown}; fields are {[n for n, _ in fields]}")
    kwargs = {
        normalize_fieldname(name): convert(typestore, desc, value.get(name), f"{where}.{name}")
        for name, desc in fields
    }
    return typestore.types[type_name](**kwargs)


def convert(typestore, desc, value, where):
    """One field's value (None: the default) as rosbags wants it."""
    kind, rest = desc
    if kind == Nodetype.NAME:
        return build(typestore, rest, {} if value is None else value, where)
    if kind == Nodetype.BASE:
        return basic(rest[0], value, where)
    # ARRAY (fixed length) or SEQUENCE (bound 0: unbounded).
    (sub_kind, sub_rest), size = rest
    if value is None:
        value = [None] * size if kind == Nodetype.ARRAY else []
    if not isinstance(value, list):
        raise SpecError(f"{where}: expected a list, got {json.dumps(value)}")
    if kind == Nodetype.ARRAY and len(value) != size:
        raise SpecError(f"{where}: expected {size} elements, got {len(value)}")
    if kind == Nodetype.SEQUENCE and size and len(value) > size:
        raise SpecError(f"{where}: at most {size} elements, got {len(value)}")
    items = [convert(typestore, (sub_kind, sub_rest), v, f"{where}[{i}]") for i, v in enumerate(value)]
    if sub_kind == Nodetype.BASE and sub_rest[0] in NUMPY_TYPES:
        return np.array(items, dtype=NUMPY_TYPES[sub_rest[0]])
    return items


def basic(ros_type, value, where):
    if ros_type in ("string", "wstring"):
        if value is None:
            return ""
        if not isinstance(value, str):
            raise SpecError(f"{where}: expected a string, got {json.dumps(value)}")
        return value
    if ros_type == "bool":
        if value is None:
            return False
        if not isinstance(value, bool):
            raise SpecError(f"{where}: expected true/false, got {json.dumps(value)}")
        return value
    if ros_type in ("float32", "float64"):
        if value is None:
            return 0.0
        if isinstance(value, str) and value in SPECIAL_FLOATS:
            return SPECIAL_FLOATS[value]
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise SpecError(f"{where}: expected a number, got {json.dumps(value)}")
        return float(value)
    if ros_type in INT_RANGES:
        if value is None:
            return 0
        lo, hi = INT_RANGES[ros_type]
        if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
            raise SpecError(f"{where}: expected a {ros_type} ({lo}..{hi}), got {json.dumps(value)}")
        return value
    raise SpecError(f"{where}: unsupported basic type {ros_type}")


# ----------------------------------------------------------------------- QoS


def enum_value(enum, key, name, where):
    if not isinstance(name, str) or name.upper() not in enum.__members__:
        names = [m.lower() for m in enum.__members__]
        raise SpecError(f"{where}.{key}: {json.dumps(name)} is not one of {names}")
    return enum.__members__[name.upper()]


def qos_time(value, where):
    if not (isinstance(value, dict) and sorted(value) == ["nsec", "sec"]
            and all(isinstance(v, int) and not isinstance(v, bool) and v >= 0 for v in value.values())):
        raise SpecError(f"{where}: expected {{\"sec\": int, \"nsec\": int}}, got {json.dumps(value)}")
    return QosTime(value["sec"], value["nsec"])


def make_qos(spec, where):
    """rosbags Qos from one spec profile, defaults filled in."""
    if not isinstance(spec, dict):
        raise SpecError(f"{where}: expected an object, got {json.dumps(spec)}")
    unknown = sorted(set(spec) - set(QOS_DEFAULTS))
    if unknown:
        raise SpecError(f"{where}: unknown QoS key(s) {unknown}; keys are {list(QOS_DEFAULTS)}")
    p = {**QOS_DEFAULTS, **spec}
    depth = p["depth"]
    if isinstance(depth, bool) or not isinstance(depth, int) or depth < 0:
        raise SpecError(f"{where}.depth: expected an integer >= 0, got {json.dumps(depth)}")
    if not isinstance(p["avoid_ros_namespace_conventions"], bool):
        raise SpecError(f"{where}.avoid_ros_namespace_conventions: expected true/false")
    return Qos(
        history=enum_value(QosHistory, "history", p["history"], where),
        depth=depth,
        reliability=enum_value(QosReliability, "reliability", p["reliability"], where),
        durability=enum_value(QosDurability, "durability", p["durability"], where),
        deadline=qos_time(p["deadline"], f"{where}.deadline"),
        lifespan=qos_time(p["lifespan"], f"{where}.lifespan"),
        liveliness=enum_value(QosLiveliness, "liveliness", p["liveliness"], where),
        liveliness_lease_duration=qos_time(
            p["liveliness_lease_duration"], f"{where}.liveliness_lease_duration"),
        avoid_ros_namespace_conventions=p["avoid_ros_namespace_conventions"],
    )


# ---------------------------------------------------------------------- writer


class JazzyMcapWriter(storage_mcap.McapWriter):
    """rosbags' MCAP storage writer, plus the channel metadata entry topic_type_hash that
    Jazzy's rosbag2_storage_mcap writes next to offered_qos_profiles. Written against the
    module's record helpers of the pinned rosbags (0.11.9)."""

    def add_connection(self, connection, offered_qos_profiles):
        metadata = BytesIO()
        entries = (("offered_qos_profiles", offered_qos_profiles), ("topic_type_hash", connection.digest))
        for key, value in entries:
            storage_mcap.write_string(metadata, key)
            storage_mcap.write_string(metadata, value)
        self.channels.append(storage_mcap.Channel(
            connection.id, connection.msgtype, connection.topic,
            connection.ext.serialization_format, metadata.getvalue(),
        ))
        self.channel_stats[connection.id] = 0
        storage_mcap.write_channel(self.chunk.bio, self.channels[-1], self.schemas)


class JazzyWriter(Writer):
    STORAGE_PLUGINS = {**Writer.STORAGE_PLUGINS, StoragePlugin.MCAP: JazzyMcapWriter}


def load_spec(path):
    try:
        text = sys.stdin.read() if path == "-" else Path(path).read_text()
        spec = json.loads(text)
    except (OSError, ValueError) as exc:
        raise SpecError(f"cannot read the spec {path}: {exc}") from None
    if not isinstance(spec, dict) or sorted(spec) != ["messages", "topics"]:
        raise SpecError('the spec must be an object with exactly the keys "topics" and "messages"')
    if not isinstance(spec["topics"], list) or not isinstance(spec["messages"], list):
        raise SpecError('"topics" and "messages" must be lists')
    return spec


def write_bag(out_dir, storage, spec, topic_type_hash):
    typestore = make_typestore()

    # Everything is checked and serialized before the bag directory is created.
    topics = {}
    for i, topic in enumerate(spec["topics"]):
        where = f"topics[{i}]"
        keys = set(topic) if isinstance(topic, dict) else set()
        if not {"name", "type"} <= keys or keys - {"name", "type", "qos"}:
            raise SpecError(f'{where}: expected {{"name", "type"[, "qos"]}}, got {json.dumps(topic)}')
        name, type_name = topic["name"], topic["type"]
        if name in topics:
            raise SpecError(f"{where}: topic {name} given twice")
        if type_name not in typestore.fielddefs:
            raise SpecError(f"{where}: unknown message type {type_name}")
        qos = topic.get("qos", [])
        profiles = qos if isinstance(qos, list) else [qos]
        topics[name] = (type_name, [make_qos(p, f"{where}.qos") for p in profiles])

    messages = []
    for i, m in enumerate(spec["messages"]):
        where = f"messages[{i}]"
        if not isinstance(m, dict) or sorted(m) != ["msg", "t_ns", "topic"]:
            raise SpecError(f'{where}: expected {{"topic", "t_ns", "msg"}}, got {json.dumps(m)[:200]}')
        if m["topic"] not in topics:
            raise SpecError(f"{where}: topic {m['topic']} is not in \"topics\"")
        t = m["t_ns"]
        if isinstance(t, bool) or not isinstance(t, int) or not 0 <= t < 2**63:
            raise SpecError(f"{where}.t_ns: expected a non-negative int64 nanosecond time, got {json.dumps(t)}")
        type_name = topics[m["topic"]][0]
        msg = build(typestore, type_name, m["msg"], f"{where}.msg")
        messages.append((m["topic"], t, bytes(typestore.serialize_cdr(msg, type_name))))

    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    writer_class = JazzyWriter if topic_type_hash else Writer
    with writer_class(out_dir, version=9, storage_plugin=plugin) as writer:
        connections = {
            name: writer.add_connection(name, type_name, typestore=typestore, offered_qos_profiles=qos)
            for name, (type_name, qos) in topics.items()
        }
        for name, t, data in messages:
            writer.write(connections[name], t, data)
    return len(messages)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("out_dir", metavar="OUT_DIR", help="bag directory to create (must not exist)")
    parser.add_argument("--storage", choices=["mcap", "sqlite3"], required=True)
    parser.add_argument("--spec", metavar="SPEC.json", required=True,
                        help='the bag\'s topics and messages ("-": stdin)')
    parser.add_argument("--topic-type-hash", action="store_true",
                        help="MCAP: also write the topic_type_hash channel metadata, as Jazzy's recorder does")
    args = parser.parse_args()
    out_dir = Path(args.out_dir).resolve()
    if args.topic_type_hash and args.storage != "mcap":
        parser.error("--topic-type-hash is for --storage mcap (SQLite bags keep the hash in topics)")
    if out_dir.exists():
        parser.error(f"{out_dir} exists already")

    try:
        count = write_bag(out_dir, args.storage, load_spec(args.spec), args.topic_type_hash)
    except SpecError as exc:
        print(f"bag_make: {exc}", file=sys.stderr)
        return 2
    print(json.dumps({"bag": str(out_dir), "storage": args.storage, "message_count": count}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
