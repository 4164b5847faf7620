#!/usr/bin/env python3
"""Independent checker of a rosbag2 bag (ROS 2 Jazzy format): what two readers that are not
ours say about a bag `biped record` wrote (or tests/python/bag_make.py made).

Usage (through the interpreter scripts/setup-python-env prints):
    biped-python bag_check.py BAG_DIR [--dump FILE] [--strict]

BAG_DIR is a rosbag2 bag directory: metadata.yaml (version 9) and its storage file(s),
MCAP (.mcap) or SQLite (.db3). The bag is read twice, by two independent implementations:
  * rosbags (pure Python): rosbags.rosbag2.Reader, the Jazzy typestore plus biped_msgs'
    types parsed from msgs/msg/*.msg, every message deserialized;
  * for MCAP, the mcap library's reader with mcap-ros2-support's decoder (which decodes with
    the message definitions embedded in the file); for SQLite, Python's sqlite3 module for
    the tables and real rclpy (deserialize_message, the classes rosidl generated) for the
    messages.
Both readers' decoded values must agree message for message, and both must agree with
metadata.yaml. Checks (each failure string starts with the name of its check):
  metadata  metadata.yaml parses; version 9; storage_identifier mcap or sqlite3; the files
            of relative_file_paths exist; message_count, starting_time, duration (last minus
            first log time, as rosbag2 writes it) and the per-topic message counts and types
            match what is in the storage; `files` agrees per file.
  rosbags   rosbags opens the bag and deserializes every message.
  qos       each topic's offered_qos_profiles in metadata.yaml has the version 9 form (a list
            of mappings with keep_last/reliable/volatile/automatic... names) and equals the
            one stored in the storage (MCAP: channel metadata `offered_qos_profiles`, a YAML
            string; SQLite: topics.offered_qos_profiles), compared both as parsed YAML and as
            rosbags parses them.
  type_hash the storage's copy of each topic's type hash (MCAP: channel metadata
            `topic_type_hash`, which Jazzy's recorder writes; SQLite:
            topics.type_description_hash) equals metadata.yaml's type_description_hash.
            A missing `topic_type_hash` (rosbags' MCAP writer does not write it) is only a
            note, unless --strict.
  rihs01    each topic's type_description_hash is what rosbags computes for the type
            (Typestore.hash_rihs01) and, where <prefix>/share/<pkg>/msg/<Type>.json exists
            (installed by rosidl), what rosidl computed.
  mcap      (MCAP) header profile "ros2"; schemas encoded "ros2msg", named after the channel's
            type; channels encoded "cdr"; every message decodes; counts and statistics agree
            with metadata.yaml; the metadata record "rosbag2" holds a serialized_metadata that
            agrees on message_count and topic names; values equal rosbags'.
  sqlite3   (SQLite) schema_version 4 (Jazzy); one message_definitions row per type, encoded
            "ros2msg"; the metadata table (when present) agrees like MCAP's record.
  rclpy     (SQLite) every message deserializes with rclpy; values equal rosbags'.
  dump      --dump FILE could not be written.
An exception inside a check (a reader giving up on a broken file, or a bug here) becomes a
failure of that check: "<check>: <ExceptionType>: <message> (raised at <file>:<line>)".

Answer: one JSON object on stdout, whatever the outcome:
    {
      "bag": "/abs/bag_dir",
      "ok": true,                     # no failures
      "storage": "mcap" | "sqlite3" | null,
      "version": 9,                   # metadata.yaml's
      "ros_distro": "jazzy",          # metadata.yaml's (rosbags writes "rosbags")
      "files": ["bag_0.mcap"],
      "message_count": 123,           # counted by the rosbags reader
      "start_ns": 1700000000000000000,  # first log time, counted (null when no message)
      "end_ns": 1700000001000000000,    # last log time, counted (null when no message)
      "duration_ns": 1000000000,        # end_ns - start_ns (0 when no message)
      "metadata": {"message_count": 123, "start_ns": ..., "duration_ns": ...},  # as written
      "duration_convention": "last-first" | "last-first+1" | null,  # what metadata matches
      "topics": {"/cmd_vel": {"type": "geometry_msgs/msg/Twist",
                              "count": 10,       # counted by the rosbags reader
                              "hash": "RIHS01_...",  # metadata.yaml's type_description_hash
                              "qos": [{"history": "keep_last", "depth": 10, ...}]}},
      "readers": ["rosbags", "mcap"] | ["rosbags", "rclpy"],
      "notes": ["..."],
      "failures": ["metadata: ...", ...]
    }
Each failure is also printed on stderr.

--dump FILE writes every message the rosbags reader decoded as JSON lines, in log-time order
(ties in storage order):
    {"topic": "/joint_commands", "type": "sensor_msgs/msg/JointState", "t_ns": 17000...,
     "msg": {"header": {"stamp": {"sec": 1, "nanosec": 2}, "frame_id": ""}, "name": [...],
             "position": [0.1, ...], ...}}
Messages are plain JSON: nested objects, lists for arrays and sequences (numeric arrays
too), floats printed exactly (shortest repr that reads back to the same double), and the
strings "NaN", "Infinity", "-Infinity" for the floats JSON has no number for.

--strict: a missing MCAP `topic_type_hash` channel metadata entry is a failure (our own
recorder writes it, as Jazzy's does).

Exit codes: 0 every check passed; 1 some check failed (listed in "failures"); 2 bad usage.
"""

import argparse
import array
import dataclasses
import importlib
import json
import keyword
import math
import os
import re
import sqlite3
import sys
import traceback
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import Reader
from rosbags.rosbag2.metadata import parse_qos
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from ruamel.yaml import YAML

REPO_ROOT = Path(__file__).resolve().parents[2]
MSGS_DIR = REPO_ROOT / "msgs" / "msg"
MSGS_PACKAGE = "biped_msgs"

STORAGES = {"mcap", "sqlite3"}
JAZZY_SQLITE_SCHEMA = 4
RIHS01 = re.compile(r"^RIHS01_[0-9a-f]{64}$")
# At most this many per-message failures are listed per topic and check; the rest are counted.
MAX_LISTED = 3

# Version 9 offered_qos_profiles entries: the keys, and the names rmw's *_to_str give each
# policy value (plus "unknown", which rosbag2 writes for the UNKNOWN values).
QOS_KEYS = [
    "history", "depth", "reliability", "durability", "deadline", "lifespan", "liveliness",
    "liveliness_lease_duration", "avoid_ros_namespace_conventions",
]
QOS_NAMES = {
    "history": {"system_default", "keep_last", "keep_all", "unknown"},
    "reliability": {"system_default", "reliable", "best_effort", "best_available", "unknown"},
    "durability": {"system_default", "transient_local", "volatile", "best_available", "unknown"},
    "liveliness": {"system_default", "automatic", "manual_by_topic", "best_available", "unknown"},
}
QOS_TIMES = ["deadline", "lifespan", "liveliness_lease_duration"]


# ------------------------------------------------------------------------- types


def make_typestore():
    """The Jazzy typestore of rosbags plus our biped_msgs types, parsed from msgs/msg/*.msg."""
    typestore = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for path in sorted(MSGS_DIR.glob("*.msg")):
        types.update(get_types_from_msg(path.read_text(), f"{MSGS_PACKAGE}/msg/{path.stem}"))
    typestore.register(types)
    return typestore


def share_dirs():
    """Install prefixes' share/ folders: the venv's (AMENT_PREFIX_PATH, set by biped-python)."""
    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    prefixes.append(sys.prefix)
    seen, out = set(), []
    for prefix in prefixes:
        share = Path(prefix) / "share"
        if share.is_dir() and share.resolve() not in seen:
            seen.add(share.resolve())
            out.append(share)
    return out


def rosidl_hash(type_name):
    """(hash, json path) from the type description JSON rosidl installed, or (None, None)."""
    pkg, _, name = type_name.split("/")
    for share in share_dirs():
        path = share / pkg / "msg" / f"{name}.json"
        if path.is_file():
            for entry in json.loads(path.read_text()).get("type_hashes", []):
                if entry.get("type_name") == type_name:
                    return entry.get("hash_string"), path
            return None, path
    return None, None


def rclpy_class(type_name):
    """`pkg/msg/Name` -> the class rosidl generated (importlib, no rosidl_runtime_py)."""
    pkg, kind, name = type_name.split("/")
    return getattr(importlib.import_module(f"{pkg}.{kind}"), name)


# ------------------------------------------------------------------ plain values


def plain(value):
    """A decoded message (rosbags dataclass, mcap_ros2 object or rclpy message) as plain JSON
    data: dicts keyed by ROS field names, lists, ints, exact floats, strings."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        # rosbags: dataclass fields (and __msgtype__, which is no field of the message),
        # Python keywords suffixed with "_".
        out = {}
        for field in dataclasses.fields(value):
            name = field.name
            if name.startswith("__"):
                continue
            if name.isupper():
                # A constant (ROS field names are lower case, constants upper case): part of
                # the type, not of the message, and absent from a definition without them.
                continue
            if name.endswith("_") and keyword.iskeyword(name[:-1]):
                name = name[:-1]
            out[name] = plain(getattr(value, field.name))
        return out
    if hasattr(type(value), "get_fields_and_field_types"):
        # rclpy (rosidl generated class).
        return {name: plain(getattr(value, name)) for name in value.get_fields_and_field_types()}
    if hasattr(type(value), "_full_text") and hasattr(type(value), "__slots__"):
        # mcap_ros2 dynamic class.
        return {name: plain(getattr(value, name)) for name in type(value).__slots__}
    if isinstance(value, np.ndarray):
        return [plain(v) for v in value.tolist()]
    if isinstance(value, (bytes, bytearray)):
        # rclpy: uint8[] may come as bytes, a `byte` as a 1-byte bytes object.
        return value[0] if len(value) == 1 and not isinstance(value, bytearray) else list(value)
    if isinstance(value, (list, tuple, array.array)):
        return [plain(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        if math.isnan(value):
            return "NaN"
        if math.isinf(value):
            return "Infinity" if value > 0 else "-Infinity"
        return value
    if isinstance(value, str):
        return value
    raise TypeError(f"cannot turn a {type(value).__name__} into JSON: {value!r}")


def qos_diff(a, b):
    """Where two offered_qos_profiles lists (of mappings) differ, briefly."""
    if not (isinstance(a, list) and isinstance(b, list)):
        return f"{a!r} vs {b!r}"
    if len(a) != len(b):
        return f"{len(a)} profile(s) vs {len(b)}"
    diffs = []
    for i, (pa, pb) in enumerate(zip(a, b)):
        if not (isinstance(pa, dict) and isinstance(pb, dict)):
            if pa != pb:
                diffs.append(f"[{i}] {pa!r} vs {pb!r}")
            continue
        for key in sorted(set(pa) | set(pb)):
            if pa.get(key, "<absent>") != pb.get(key, "<absent>"):
                diffs.append(f"[{i}].{key} {pa.get(key, '<absent>')!r} vs {pb.get(key, '<absent>')!r}")
    return ", ".join(diffs)


def canonical(value):
    """One string per plain value, to compare what two readers decoded."""
    return json.dumps(value, sort_keys=True)


# ------------------------------------------------------------------------ YAML


def load_yaml(text):
    return YAML(typ="safe").load(text)


class MetadataError(Exception):
    """metadata.yaml lacks a key or has one of the wrong kind."""


def need(mapping, *keys, kind=None, where="rosbag2_bagfile_information"):
    """mapping[k1][k2]...; a MetadataError naming the path when missing or of another kind."""
    value = mapping
    for key in keys:
        where = f"{where}.{key}"
        if not isinstance(value, dict) or key not in value:
            raise MetadataError(f"metadata.yaml has no {where}")
        value = value[key]
    if kind is not None and not (isinstance(value, kind) and not (kind is int and isinstance(value, bool))):
        names = kind.__name__ if isinstance(kind, type) else "/".join(k.__name__ for k in kind)
        raise MetadataError(f"metadata.yaml {where} is not a {names}: {value!r}")
    return value


# --------------------------------------------------------------------- checker


class Checker:
    def __init__(self, bag_dir, strict, dump):
        self.bag_dir = Path(bag_dir).resolve()
        self.strict = strict
        self.dump_path = dump
        self.failures = []
        self.notes = []
        self.typestore = make_typestore()
        self.meta = None           # rosbag2_bagfile_information mapping
        self.meta_topics = {}      # name -> topic_with_message_count entry
        self.storage = None
        self.paths = []            # storage files, absolute
        self.readers = ["rosbags"]
        # What the rosbags pass read: topic -> type, and per topic [(t, canonical value)].
        self.counted = None        # topic -> count (None: the rosbags pass did not run)
        self.file_counts = []      # per file: (count, first t, last t)
        self.values = {}
        self.times = []
        self.dumped = []           # (t, seq, topic, type, plain value)
        self.duration_convention = None

    # --- reporting

    def fail(self, check, detail):
        self.failures.append(f"{check}: {detail}")

    def note(self, detail):
        self.notes.append(detail)

    def guarded(self, check, fn):
        """Runs one check; an exception becomes a failure named after it (with where it was
        raised), not a traceback: a reader giving up on a broken file is a finding."""
        try:
            fn()
            return True
        except MetadataError as exc:
            self.fail("metadata", str(exc))
        except Exception as exc:  # noqa: BLE001
            frame = traceback.extract_tb(exc.__traceback__)[-1]
            where = f"{Path(frame.filename).parent.name}/{Path(frame.filename).name}:{frame.lineno}"
            self.fail(check, f"{type(exc).__name__}: {exc} (raised at {where})")
        return False

    def run(self):
        if not self.guarded("metadata", self.check_metadata_file):
            return
        self.guarded("metadata", self.check_topic_list)
        self.guarded("rosbags", self.read_with_rosbags)
        if self.counted is not None:  # rosbags read the storage
            self.guarded("metadata", self.check_counts_and_times)
        self.guarded("rihs01", self.check_rihs01)
        if self.storage == "mcap":
            self.readers.append("mcap")
            self.guarded("mcap", self.check_mcap)
        else:
            self.readers.append("rclpy")
            self.guarded("sqlite3", self.check_sqlite)
        if self.dump_path is not None:
            self.guarded("dump", self.write_dump)

    # --- a. metadata.yaml

    def check_metadata_file(self):
        path = self.bag_dir / "metadata.yaml"
        if not path.is_file():
            raise MetadataError(f"no metadata.yaml in {self.bag_dir}")
        try:
            doc = load_yaml(path.read_text())
        except Exception as exc:  # noqa: BLE001 - ruamel has several error classes
            raise MetadataError(f"metadata.yaml does not parse: {type(exc).__name__}: {exc}") from None
        self.meta = need(doc, "rosbag2_bagfile_information", kind=dict, where="metadata.yaml")
        version = need(self.meta, "version", kind=int)
        if version != 9:
            self.fail("metadata", f"version is {version}, expected 9 (Jazzy)")
        self.storage = need(self.meta, "storage_identifier", kind=str)
        if self.storage not in STORAGES:
            storage, self.storage = self.storage, None
            raise MetadataError(f"storage_identifier is {storage!r}, expected one of {sorted(STORAGES)}")
        for key in ("compression_mode", "compression_format"):
            if self.meta.get(key):
                raise MetadataError(f"{key} is {self.meta[key]!r}: compressed bags are not checked here")
        files = need(self.meta, "relative_file_paths", kind=list)
        if not files:
            raise MetadataError("relative_file_paths is empty")
        suffix = ".mcap" if self.storage == "mcap" else ".db3"
        for name in files:
            if not isinstance(name, str):
                raise MetadataError(f"relative_file_paths holds a non-string: {name!r}")
            file = self.bag_dir / name
            if not file.is_file():
                raise MetadataError(f"storage file {name} (relative_file_paths) does not exist")
            if file.suffix != suffix:
                self.fail("metadata", f"storage file {name} does not end in {suffix} ({self.storage})")
            self.paths.append(file)

    def check_topic_list(self):
        need(self.meta, "message_count", kind=int)
        need(self.meta, "starting_time", "nanoseconds_since_epoch", kind=int)
        need(self.meta, "duration", "nanoseconds", kind=int)
        for i, entry in enumerate(need(self.meta, "topics_with_message_count", kind=list)):
            where = f"rosbag2_bagfile_information.topics_with_message_count[{i}]"
            name = need(entry, "topic_metadata", "name", kind=str, where=where)
            need(entry, "topic_metadata", "type", kind=str, where=where)
            need(entry, "message_count", kind=int, where=where)
            fmt = need(entry, "topic_metadata", "serialization_format", kind=str, where=where)
            if fmt != "cdr":
                self.fail("metadata", f"{name}: serialization_format is {fmt!r}, expected 'cdr'")
            need(entry, "topic_metadata", "type_description_hash", kind=str, where=where)
            qos = need(entry, "topic_metadata", "offered_qos_profiles", where=where)
            self.check_qos_form(name, qos)
            if name in self.meta_topics:
                self.fail("metadata", f"topic {name} is listed twice in topics_with_message_count")
            self.meta_topics[name] = entry

    def check_qos_form(self, topic, profiles):
        """The version 9 form: a YAML list of mappings, policies by name."""
        if not isinstance(profiles, list):
            self.fail("qos", f"{topic}: metadata.yaml offered_qos_profiles is a {type(profiles).__name__}, "
                      "expected a list of mappings (version 9; version 8 wrote a YAML string)")
            return
        for i, profile in enumerate(profiles):
            where = f"{topic}: offered_qos_profiles[{i}]"
            if not isinstance(profile, dict):
                self.fail("qos", f"{where} is not a mapping: {profile!r}")
                continue
            if list(profile) != QOS_KEYS and sorted(profile) != sorted(QOS_KEYS):
                self.fail("qos", f"{where} has keys {list(profile)}, expected {QOS_KEYS}")
                continue
            for policy, names in QOS_NAMES.items():
                if profile[policy] not in names:
                    self.fail("qos", f"{where}.{policy} is {profile[policy]!r}, "
                              f"expected one of {sorted(names)}")
            depth = profile["depth"]
            if not isinstance(depth, int) or isinstance(depth, bool) or depth < 0:
                self.fail("qos", f"{where}.depth is {depth!r}, expected an integer >= 0")
            for key in QOS_TIMES:
                t = profile[key]
                if not (isinstance(t, dict) and sorted(t) == ["nsec", "sec"]
                        and all(isinstance(t[k], int) and not isinstance(t[k], bool) and t[k] >= 0 for k in t)):
                    self.fail("qos", f"{where}.{key} is {t!r}, expected {{sec: int, nsec: int}}")
            if not isinstance(profile["avoid_ros_namespace_conventions"], bool):
                self.fail("qos", f"{where}.avoid_ros_namespace_conventions is not a boolean")

    # --- b. rosbags

    def read_with_rosbags(self):
        reader = Reader(self.bag_dir)
        try:
            reader.open()
        except Exception as exc:  # noqa: BLE001
            self.fail("rosbags", f"cannot open the bag: {type(exc).__name__}: {exc}")
            return
        try:
            self.read_storages(reader)
        finally:
            reader.close()

    def read_storages(self, reader):
        # reader.connections come from metadata.yaml; each storage's from the file itself.
        # The storages are read one by one, with their own connections: the unified reader
        # pairs the two by (topic, type, QoS...) and would silently skip the messages of a
        # topic whose metadata.yaml entry disagrees with the storage.
        meta_conns = {c.topic: c for c in reader.connections}
        storages = reader.storage.storages
        counted, seq = {}, 0
        failures = {}  # topic -> [count, listed details]
        for path, storage in zip(self.paths, storages):
            file_count, first, last = 0, None, None
            for conn in storage.connections:
                counted.setdefault(conn.topic, 0)
                self.compare_connection(path.name, conn, meta_conns.get(conn.topic))
            for conn, t, data in storage.messages(storage.connections):
                counted[conn.topic] += 1
                file_count += 1
                first = t if first is None else min(first, t)
                last = t if last is None else max(last, t)
                self.times.append(t)
                try:
                    msg = self.typestore.deserialize_cdr(data, conn.msgtype)
                    value = plain(msg)
                except Exception as exc:  # noqa: BLE001 - every bad message is reported
                    bad = failures.setdefault(conn.topic, [0, []])
                    bad[0] += 1
                    if len(bad[1]) < MAX_LISTED:
                        bad[1].append(f"message {counted[conn.topic]} at t={t}: {type(exc).__name__}: {exc}")
                    continue
                self.values.setdefault(conn.topic, []).append((t, canonical(value)))
                self.dumped.append((t, seq, conn.topic, conn.msgtype, value))
                seq += 1
            self.file_counts.append((file_count, first, last))
        for topic, (n, listed) in failures.items():
            more = f" (and {n - len(listed)} more)" if n > len(listed) else ""
            self.fail("rosbags", f"{topic}: {n} message(s) do not deserialize: {'; '.join(listed)}{more}")
        self.counted = counted

    def compare_connection(self, file, conn, meta_conn):
        """A topic of the storage against its metadata.yaml entry (as rosbags parsed both)."""
        if meta_conn is None:
            self.fail("metadata", f"topic {conn.topic} is in {file} but not in topics_with_message_count")
            return
        if conn.msgtype != meta_conn.msgtype:
            self.fail("metadata", f"{conn.topic}: type is {meta_conn.msgtype} in metadata.yaml, "
                      f"{conn.msgtype} in {file}")
        if conn.ext.serialization_format != meta_conn.ext.serialization_format:
            self.fail("metadata", f"{conn.topic}: serialization_format {meta_conn.ext.serialization_format!r} "
                      f"in metadata.yaml, {conn.ext.serialization_format!r} in {file}")
        if conn.ext.offered_qos_profiles != meta_conn.ext.offered_qos_profiles:
            as_dicts = [[q._asdict() for q in c.ext.offered_qos_profiles] for c in (meta_conn, conn)]
            self.fail("qos", f"{conn.topic}: offered_qos_profiles differ between metadata.yaml and {file} "
                      f"as rosbags parses them: {qos_diff(*as_dicts)}")

    def check_counts_and_times(self):
        counted = self.counted
        for name, entry in self.meta_topics.items():
            if name not in counted:
                self.fail("metadata", f"topic {name} is in topics_with_message_count but in no storage file")
                continue
            want = entry["message_count"]
            if want != counted[name]:
                self.fail("metadata", f"{name}: message_count is {want} in metadata.yaml, "
                          f"the storage holds {counted[name]}")
        total = sum(counted.values())
        want_total = need(self.meta, "message_count", kind=int)
        if want_total != total:
            self.fail("metadata", f"message_count is {want_total} in metadata.yaml, the storage holds {total}")
        listed = sum(e["message_count"] for e in self.meta_topics.values())
        if listed != want_total:
            self.fail("metadata", f"message_count is {want_total} but the topics' message_count "
                      f"add up to {listed}")

        start = need(self.meta, "starting_time", "nanoseconds_since_epoch", kind=int)
        duration = need(self.meta, "duration", "nanoseconds", kind=int)
        if self.times:
            first, last = min(self.times), max(self.times)
            if start != first:
                self.fail("metadata", f"starting_time is {start}, the first message is at {first} "
                          f"({start - first:+d} ns)")
            self.check_duration("duration", duration, first, last)
        elif total == 0:
            self.note("the bag holds no message: starting_time and duration not checked")

        # Per-file entries (rosbag2 writes one per storage file).
        files = self.meta.get("files")
        if files is None:
            self.fail("metadata", "no `files` list (rosbag2 writes one since version 5)")
            return
        if not isinstance(files, list) or len(files) != len(self.paths):
            self.fail("metadata", f"`files` has {len(files) if isinstance(files, list) else files!r} "
                      f"entries, relative_file_paths {len(self.paths)}")
            return
        for i, (entry, path, (count, first, last)) in enumerate(zip(files, self.paths, self.file_counts)):
            where = f"rosbag2_bagfile_information.files[{i}]"
            name = need(entry, "path", kind=str, where=where)
            if name != self.meta["relative_file_paths"][i]:
                self.fail("metadata", f"{where}.path is {name!r}, relative_file_paths[{i}] is "
                          f"{self.meta['relative_file_paths'][i]!r}")
            n = need(entry, "message_count", kind=int, where=where)
            if n != count:
                self.fail("metadata", f"{where}.message_count is {n}, {path.name} holds {count}")
            if count:
                s = need(entry, "starting_time", "nanoseconds_since_epoch", kind=int, where=where)
                if s != first:
                    self.fail("metadata", f"{where}.starting_time is {s}, the first message of "
                              f"{path.name} is at {first}")
                d = need(entry, "duration", "nanoseconds", kind=int, where=where)
                self.check_duration(f"{where}.duration", d, first, last)

    def check_duration(self, what, duration, first, last):
        """rosbag2 writes duration = last - first log time (so one message: 0)."""
        span = last - first
        convention = "last-first" if duration == span else "last-first+1" if duration == span + 1 else None
        if what == "duration":
            self.duration_convention = convention
        if convention == "last-first":
            return
        hint = (" (that is last - first + 1, the end-exclusive convention of rosbags' Reader.duration;"
                " rosbag2 writes last - first)") if convention else ""
        self.fail("metadata", f"{what} is {duration} ns, the messages span {span} ns "
                  f"(last {last} - first {first}){hint}")

    # --- d. RIHS01

    def check_rihs01(self):
        for name, entry in self.meta_topics.items():
            type_name = entry["topic_metadata"]["type"]
            have = entry["topic_metadata"]["type_description_hash"]
            if not RIHS01.match(have):
                self.fail("rihs01", f"{name}: type_description_hash {have!r} is not RIHS01_ + 64 hex digits")
            if type_name not in self.typestore.fielddefs:
                self.fail("rihs01", f"{name}: type {type_name} is unknown to the typestore "
                          "(Jazzy + biped_msgs)")
                continue
            ours = self.typestore.hash_rihs01(type_name)
            if have != ours:
                self.fail("rihs01", f"{name}: type_description_hash of {type_name} is {have}, "
                          f"rosbags computes {ours}")
            ref, path = rosidl_hash(type_name)
            if path is not None:
                if ref is None:
                    self.fail("rihs01", f"{path} has no type_hashes entry for {type_name}")
                elif have != ref:
                    self.fail("rihs01", f"{name}: type_description_hash of {type_name} is {have}, "
                              f"rosidl's {path} says {ref}")

    # --- c, e. the storage read a second way

    def check_storage_topic(self, check, name, type_name, fmt, qos_text, type_hash, file, hash_key):
        """One storage topic (read raw) against metadata.yaml: type, format, QoS, type hash."""
        entry = self.meta_topics.get(name)
        if entry is None:
            return  # reported by the rosbags pass (or by check_topics_present)
        meta = entry["topic_metadata"]
        if type_name != meta["type"]:
            self.fail(check, f"{name}: type {type_name} in {file}, {meta['type']} in metadata.yaml")
        if fmt != "cdr":
            self.fail(check, f"{name}: message encoding {fmt!r} in {file}, expected 'cdr'")
        # QoS, as parsed YAML: both sides are written with the version 9 encoding.
        if qos_text is None:
            self.fail("qos", f"{name}: {file} stores no offered_qos_profiles")
        else:
            try:
                stored = load_yaml(qos_text) if qos_text.strip() else []
            except Exception as exc:  # noqa: BLE001
                self.fail("qos", f"{name}: offered_qos_profiles in {file} is not YAML: {exc}")
            else:
                if stored is None:
                    stored = []
                if stored != meta["offered_qos_profiles"]:
                    self.fail("qos", f"{name}: offered_qos_profiles differ between metadata.yaml and {file} "
                              f"as YAML: {qos_diff(meta['offered_qos_profiles'], stored)}")
                else:
                    try:
                        parse_qos(qos_text)
                    except Exception as exc:  # noqa: BLE001
                        self.fail("qos", f"{name}: rosbags cannot parse offered_qos_profiles in {file}: {exc}")
        # Type hash.
        if type_hash is None:
            detail = f"{name}: no {hash_key} in {file} (not written by rosbag2/biped)"
            if self.strict:
                self.fail("type_hash", detail)
            else:
                self.note(detail)
        elif type_hash != meta["type_description_hash"]:
            self.fail("type_hash", f"{name}: {hash_key} in {file} is {type_hash!r}, metadata.yaml's "
                      f"type_description_hash is {meta['type_description_hash']!r}")

    def compare_values(self, reader, decoded, file_desc):
        """What the second reader decoded against what rosbags decoded, per topic."""
        for topic in sorted(set(decoded) | set(self.values)):
            ours, theirs = sorted(self.values.get(topic, [])), sorted(decoded.get(topic, []))
            if len(ours) != len(theirs):
                continue  # the counts are reported already
            diff = [(a, b) for a, b in zip(ours, theirs) if a != b]
            if diff:
                (t1, v1), (t2, v2) = diff[0]
                self.fail(reader, f"{topic}: {len(diff)} message(s) of {file_desc} decode differently from "
                          f"rosbags; first: rosbags t={t1} {v1}, {reader} t={t2} {v2}")

    def check_serialized_metadata(self, reader, text, where):
        """The copy of the bag's metadata the storage carries: same message_count and topics."""
        try:
            doc = load_yaml(text)
        except Exception as exc:  # noqa: BLE001
            self.fail(reader, f"{where} does not parse as YAML: {exc}")
            return
        if isinstance(doc, dict) and "rosbag2_bagfile_information" in doc:
            doc = doc["rosbag2_bagfile_information"]
        if not isinstance(doc, dict):
            self.fail(reader, f"{where} is not a mapping")
            return
        if doc.get("message_count") != self.meta.get("message_count"):
            self.fail(reader, f"{where} says message_count {doc.get('message_count')!r}, "
                      f"metadata.yaml {self.meta.get('message_count')!r}")
        try:
            names = sorted(t["topic_metadata"]["name"] for t in doc["topics_with_message_count"])
        except (KeyError, TypeError) as exc:
            self.fail(reader, f"{where} has no topic list: {exc!r}")
            return
        if names != sorted(self.meta_topics):
            self.fail(reader, f"{where} lists topics {names}, metadata.yaml {sorted(self.meta_topics)}")

    def check_topics_present(self, reader, topics, file):
        for name in self.meta_topics:
            if len(self.paths) == 1 and name not in topics:
                what = "channel" if reader == "mcap" else "topics row"
                self.fail(reader, f"topic {name} of metadata.yaml has no {what} in {file}")

    def check_counts(self, reader, counts, file_desc):
        for name, entry in self.meta_topics.items():
            n = counts.get(name, 0)
            if n != entry["message_count"]:
                self.fail(reader, f"{name}: {reader} reads {n} message(s) in {file_desc}, "
                          f"metadata.yaml says {entry['message_count']}")
        for name, n in counts.items():
            if name not in self.meta_topics:
                self.fail(reader, f"{reader} reads {n} message(s) on {name}, "
                          "a topic metadata.yaml does not list")

    # MCAP: mcap + mcap_ros2.

    def check_mcap(self):
        from mcap.reader import make_reader

        counts, decoded = {}, {}
        desc = ", ".join(p.name for p in self.paths)
        for path in self.paths:
            with path.open("rb") as f:
                self.check_mcap_file(make_reader(f), path.name, counts, decoded)
        self.check_counts("mcap", counts, desc)
        self.compare_values("mcap", decoded, desc)

    def check_mcap_file(self, reader, file, counts, decoded):
        header = reader.get_header()
        if header.profile != "ros2":
            self.fail("mcap", f"{file}: header profile is {header.profile!r}, expected 'ros2'")
        summary = reader.get_summary()
        if summary is None:
            self.fail("mcap", f"{file} has no summary section (rosbag2 writes one)")
            return
        for schema in summary.schemas.values():
            if schema.encoding != "ros2msg":
                self.fail("mcap", f"{file}: schema {schema.name} is encoded {schema.encoding!r}, "
                          "expected 'ros2msg'")
        topics = {}
        for channel in summary.channels.values():
            schema = summary.schemas.get(channel.schema_id)
            topics[channel.topic] = channel
            self.check_storage_topic(
                "mcap", channel.topic, schema.name if schema else None, channel.message_encoding,
                channel.metadata.get("offered_qos_profiles"), channel.metadata.get("topic_type_hash"),
                file, "channel metadata topic_type_hash")
            if schema is None:
                self.fail("mcap", f"{file}: channel {channel.topic} has no schema (id {channel.schema_id})")
        self.check_topics_present("mcap", topics, file)

        # Every message, decoded with the schema text the file carries.
        n, first, last, bad = 0, None, None, {}
        for schema, channel, message, msg in iter_decoded_guarded(reader, bad):
            n += 1
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            first = message.log_time if first is None else min(first, message.log_time)
            last = message.log_time if last is None else max(last, message.log_time)
            decoded.setdefault(channel.topic, []).append((message.log_time, canonical(plain(msg))))
        for topic, (k, listed) in bad.items():
            more = f" (and {k - len(listed)} more)" if k > len(listed) else ""
            self.fail("mcap", f"{file}: {topic}: {k} message(s) do not decode: {'; '.join(listed)}{more}")

        # The statistics record against what was read.
        stats = summary.statistics
        if stats is None:
            self.fail("mcap", f"{file} has no statistics record (rosbag2 writes one)")
        else:
            read_n = n + sum(k for k, _ in bad.values())
            if stats.message_count != read_n:
                self.fail("mcap", f"{file}: statistics say {stats.message_count} messages, {read_n} read")
            for cid, k in stats.channel_message_counts.items():
                channel = summary.channels.get(cid)
                name = channel.topic if channel else f"channel {cid}"
                want = self.meta_topics.get(name, {}).get("message_count")
                if want is not None and len(self.paths) == 1 and k != want:
                    self.fail("mcap", f"{file}: statistics count {k} message(s) on {name}, metadata.yaml "
                              f"{self.meta_topics[name]['message_count']}")
            if n and (stats.message_start_time, stats.message_end_time) != (first, last):
                self.fail("mcap", f"{file}: statistics span {stats.message_start_time}..{stats.message_end_time}, "
                          f"messages {first}..{last}")

        # The "rosbag2" metadata record.
        records = [m for m in reader.iter_metadata() if m.name == "rosbag2"]
        if not records:
            self.fail("mcap", f"{file} has no metadata record named 'rosbag2'")
        for record in records:
            text = record.metadata.get("serialized_metadata")
            if text is None:
                self.fail("mcap", f"{file}: metadata record 'rosbag2' has no key serialized_metadata")
            elif len(self.paths) == 1:
                self.check_serialized_metadata("mcap", text, f"{file}: serialized_metadata")

    # SQLite: sqlite3 + rclpy.

    def check_sqlite(self):
        from rclpy.serialization import deserialize_message

        counts, decoded = {}, {}
        desc = ", ".join(p.name for p in self.paths)
        for path in self.paths:
            db = sqlite3.connect(f"{path.as_uri()}?mode=ro", uri=True)
            try:
                self.check_sqlite_file(db, path.name, counts, decoded, deserialize_message)
            finally:
                db.close()
        self.check_counts("sqlite3", counts, desc)
        self.compare_values("rclpy", decoded, desc)

    def check_sqlite_file(self, db, file, counts, decoded, deserialize_message):
        tables = {r[0] for r in db.execute("SELECT name FROM sqlite_master WHERE type='table'")}
        for table in ("schema", "topics", "messages", "message_definitions"):
            if table not in tables:
                self.fail("sqlite3", f"{file} has no {table} table (Jazzy's schema {JAZZY_SQLITE_SCHEMA} has)")
        if "schema" in tables:
            rows = db.execute("SELECT schema_version FROM schema").fetchall()
            if [r[0] for r in rows] != [JAZZY_SQLITE_SCHEMA]:
                self.fail("sqlite3", f"{file}: schema_version is {[r[0] for r in rows]}, "
                          f"expected [{JAZZY_SQLITE_SCHEMA}]")
        if "topics" not in tables or "messages" not in tables:
            return

        topic_rows = db.execute(
            "SELECT id, name, type, serialization_format, offered_qos_profiles, type_description_hash"
            " FROM topics"
        ).fetchall()
        by_id, topics = {}, {}
        for tid, name, type_name, fmt, qos_text, type_hash in topic_rows:
            if name in topics:
                self.fail("sqlite3", f"{file}: topic {name} has two rows in topics")
            by_id[tid] = (name, type_name)
            topics[name] = tid
            self.check_storage_topic("sqlite3", name, type_name, fmt, qos_text, type_hash or None, file,
                                     "topics.type_description_hash")
        self.check_topics_present("sqlite3", topics, file)

        if "message_definitions" in tables:
            defs = {}
            for type_name, encoding, text, type_hash in db.execute(
                "SELECT topic_type, encoding, encoded_message_definition, type_description_hash"
                " FROM message_definitions"
            ):
                if type_name in defs:
                    self.fail("sqlite3", f"{file}: message_definitions has two rows for {type_name}")
                defs[type_name] = (encoding, text, type_hash)
            for type_name in sorted({t for _, t in by_id.values()}):
                if type_name not in defs:
                    self.fail("sqlite3", f"{file}: message_definitions has no row for {type_name}")
                    continue
                encoding, text, type_hash = defs[type_name]
                if encoding != "ros2msg":
                    self.fail("sqlite3", f"{file}: message_definitions row of {type_name} is encoded "
                              f"{encoding!r}, expected 'ros2msg'")
                if not text:
                    self.fail("sqlite3", f"{file}: message_definitions row of {type_name} "
                              "has an empty definition")
                # Optional there (may be empty); when given, the type's RIHS01.
                ours = self.typestore.hash_rihs01(type_name) if type_name in self.typestore.fielddefs else None
                if type_hash and ours and type_hash != ours:
                    self.fail("type_hash", f"{file}: message_definitions.type_description_hash of "
                              f"{type_name} is {type_hash}, rosbags computes {ours}")
            for type_name in sorted(set(defs) - {t for _, t in by_id.values()}):
                self.fail("sqlite3", f"{file}: message_definitions has a row for {type_name}, "
                          "which no topic uses")

        if "metadata" in tables and len(self.paths) == 1:
            rows = db.execute("SELECT metadata_version, metadata FROM metadata ORDER BY id").fetchall()
            if rows:
                version, text = rows[-1]
                if version != 9:
                    self.fail("sqlite3", f"{file}: metadata table has metadata_version {version}, expected 9")
                self.check_serialized_metadata("sqlite3", text, f"{file}: metadata table")

        # Every message, decoded by rclpy with the classes rosidl generated.
        classes, bad = {}, {}
        for tid, t, data in db.execute("SELECT topic_id, timestamp, data FROM messages ORDER BY timestamp, id"):
            if tid not in by_id:
                self.fail("sqlite3", f"{file}: a message at t={t} has topic_id {tid}, "
                          "which is in no topics row")
                continue
            name, type_name = by_id[tid]
            counts[name] = counts.get(name, 0) + 1
            try:
                if type_name not in classes:
                    classes[type_name] = rclpy_class(type_name)
                value = plain(deserialize_message(bytes(data), classes[type_name]))
            except Exception as exc:  # noqa: BLE001 - every bad message is reported
                entry = bad.setdefault(name, [0, []])
                entry[0] += 1
                if len(entry[1]) < MAX_LISTED:
                    entry[1].append(f"message {counts[name]} at t={t}: {type(exc).__name__}: {exc}")
                continue
            decoded.setdefault(name, []).append((t, canonical(value)))
        for topic, (k, listed) in bad.items():
            more = f" (and {k - len(listed)} more)" if k > len(listed) else ""
            self.fail("rclpy", f"{file}: {topic}: {k} message(s) do not deserialize: {'; '.join(listed)}{more}")

    # --- output

    def write_dump(self):
        with open(self.dump_path, "w") as out:
            for t, _, topic, type_name, value in sorted(self.dumped, key=lambda m: (m[0], m[1])):
                out.write(json.dumps({"topic": topic, "type": type_name, "t_ns": t, "msg": value},
                                     allow_nan=False) + "\n")

    def summary(self):
        meta = self.meta if isinstance(self.meta, dict) else {}
        times = self.times
        topics = {}
        for name, entry in self.meta_topics.items():
            tm = entry["topic_metadata"]
            topics[name] = {
                "type": tm["type"],
                "count": self.counted.get(name, 0) if self.counted is not None else None,
                "hash": tm["type_description_hash"],
                "qos": tm["offered_qos_profiles"],
            }
        for name, n in (self.counted or {}).items():
            if name not in topics:
                topics[name] = {"type": None, "count": n, "hash": None, "qos": None}
        first, last = (min(times), max(times)) if times else (None, None)

        def nested(*keys):
            value = meta
            for key in keys:
                value = value.get(key) if isinstance(value, dict) else None
            return value

        return {
            "bag": str(self.bag_dir),
            "ok": not self.failures,
            "storage": self.storage,
            "version": meta.get("version"),
            "ros_distro": meta.get("ros_distro"),
            "files": [p.name for p in self.paths],
            "message_count": sum(self.counted.values()) if self.counted is not None else None,
            "start_ns": first,
            "end_ns": last,
            "duration_ns": (last - first) if times else 0,
            "metadata": {
                "message_count": meta.get("message_count"),
                "start_ns": nested("starting_time", "nanoseconds_since_epoch"),
                "duration_ns": nested("duration", "nanoseconds"),
            },
            "duration_convention": self.duration_convention,
            "topics": topics,
            "readers": self.readers,
            "notes": self.notes,
            "failures": self.failures,
        }


def iter_decoded_guarded(reader, bad):
    """What mcap's iter_decoded_messages does (mcap_ros2's DecoderFactory picks a decoder per
    channel from its schema; messages in log-time order), except that a message that does not
    decode does not end the iteration: it is counted in bad[topic] = [count, [details]]."""
    from mcap_ros2.decoder import DecoderFactory

    factory = DecoderFactory()
    for schema, channel, message in reader.iter_messages(log_time_order=True):
        try:
            decoder = factory.decoder_for(channel.message_encoding, schema)
            if decoder is None:
                raise ValueError(f"no ros2msg/cdr decoder for encoding {channel.message_encoding!r}, "
                                 f"schema {schema.encoding if schema else None!r}")
            msg = decoder(message.data)
        except Exception as exc:  # noqa: BLE001
            entry = bad.setdefault(channel.topic, [0, []])
            entry[0] += 1
            if len(entry[1]) < MAX_LISTED:
                entry[1].append(f"t={message.log_time}: {type(exc).__name__}: {exc}")
            continue
        yield schema, channel, message, msg


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("bag_dir", metavar="BAG_DIR", help="rosbag2 bag directory (metadata.yaml + storage)")
    parser.add_argument("--dump", metavar="FILE", help="write every message as JSON lines, in log-time order")
    parser.add_argument("--strict", action="store_true",
                        help="a missing MCAP topic_type_hash channel metadata entry is a failure")
    args = parser.parse_args()

    checker = Checker(args.bag_dir, args.strict, args.dump)
    checker.run()
    json.dump(checker.summary(), sys.stdout, indent=1, allow_nan=False)
    sys.stdout.write("\n")
    for failure in checker.failures:
        print(f"bag_check: FAIL {failure}", file=sys.stderr)
    return 1 if checker.failures else 0


if __name__ == "__main__":
    sys.exit(main())
