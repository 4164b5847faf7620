#!/usr/bin/env python3
"""Reference side of tests/ros_msgs.rs: what real ROS 2 (rclpy, rosidl, Fast-CDR) says
about our message types.

Used by the Rust integration tests to check biped_msgs' Rust types, field by field and
byte by byte, against the classes rosidl generates (for the standard packages, from the
wheels; for biped_msgs, from msgs/msg/*.msg by scripts/setup-python-env) and against
rclpy's own CDR serializer (rmw_fastrtps_cpp, Fast-CDR). No DDS traffic, no rclpy.init().

Usage (through the interpreter scripts/setup-python-env prints):
    biped-python msg_check.py  < request.json  > answer.json

Request: one JSON object; both keys optional.
    {
      "schema": ["sensor_msgs/msg/JointState", ...],
      "cdr": {
        "samples_file": "/abs/path/tests/data/cdr_samples.json",
        "encoded": {"sensor_msgs/msg/JointState": ["0001000012345678...", ...], ...}
      }
    }
  * "schema": ROS type names; the answer gives each one's fields.
  * "cdr": the samples file maps ROS type names to lists of sample values (JSON objects
    with every field of the type; see "Values" below). "encoded" holds, for some of those
    types, one hex string per sample, in order: that sample encoded by the other side (the
    4-byte encapsulation header included).

Answer: one JSON object.
    {
      "schema": {"pkg/msg/Name": {"fields": [["name", "rosidl type"], ...]}
                                 or {"error": "..."}},
      "cdr": {"pkg/msg/Name": [
        {"decoded": VALUE or null,  # rclpy's deserialize_message of the given bytes
         "decode_error": null or "...",
         "cdr": "hex" or null,      # rclpy's serialize_message of the sample value
         "encode_error": null or "...",
         "size": n,                 # byte length of the sample's CDR encoding, header
                                    #   included, worked out here from the rosidl types
         "padding": [i, ...],       # offsets (header included) of the alignment
                                    #   padding bytes in that encoding
         "rmw_size": n},            # the length of "cdr" (see below)
        ...]}
    }
  "fields" is get_fields_and_field_types() in declaration order. Fast-CDR does not write
  alignment padding (those bytes keep whatever was in the buffer), so "padding" tells the
  caller which bytes of "cdr" carry no information. Neither do the bytes of "cdr" past
  "size": rclpy returns the buffer length rmw_fastrtps_cpp estimated ("rmw_size", see
  rmw_size() below), which can exceed what Fast-CDR wrote. "size" and "padding" follow the
  XCDR1 rules (primitives aligned to their size, at most 8, relative to the byte after
  the header; strings and sequences as a uint32 length, strings with their NUL).

Values: JSON objects with exactly the message's fields (missing or unknown fields are
errors); nested messages as objects; sequences and arrays as lists; integers as JSON
integers, booleans as true/false, floats as numbers, where the strings "NaN", "Infinity"
and "-Infinity" stand for the special values JSON has no numbers for. -0.0 stays -0.0.

Exit codes: 0 ok (per-sample problems are reported in the answer); 2 bad request
(malformed JSON, unknown keys, sample counts that do not match), message on stderr;
1 anything else.
"""

import importlib
import json
import math
import sys

from rclpy.serialization import deserialize_message, serialize_message
import rosidl_parser.definition as rosidl

SPECIAL_FLOATS = {"NaN": math.nan, "Infinity": math.inf, "-Infinity": -math.inf}
# XCDR1 sizes (and alignments) of the basic types.
BASIC_SIZES = {
    "boolean": 1, "octet": 1, "char": 1, "int8": 1, "uint8": 1,
    "int16": 2, "uint16": 2, "short": 2, "unsigned short": 2, "wchar": 2,
    "int32": 4, "uint32": 4, "long": 4, "unsigned long": 4, "float": 4,
    "int64": 8, "uint64": 8, "long long": 8, "unsigned long long": 8, "double": 8,
}
HEADER = 4  # encapsulation header: 00 01 00 00 (CDR, little endian)


class RequestError(Exception):
    """Problem with the caller's request: exit code 2."""


class SampleError(Exception):
    """A sample value that does not fit its message type: reported per sample."""


def message_class(type_name):
    """`pkg/msg/Name` -> the generated class."""
    parts = type_name.split("/")
    if len(parts) != 3 or parts[1] != "msg" or not all(parts):
        raise RequestError(f"not a message type name (pkg/msg/Name): {type_name!r}")
    module = importlib.import_module(f"{parts[0]}.msg")
    return getattr(module, parts[2])


def namespaced_class(slot_type):
    module = importlib.import_module(".".join(slot_type.namespaces))
    return getattr(module, slot_type.name)


def fields_of(cls):
    """[(name, rosidl type string, rosidl_parser slot type)] in declaration order."""
    fields = list(cls.get_fields_and_field_types().items())
    if len(fields) != len(cls.SLOT_TYPES):
        raise RuntimeError(f"{cls.__name__}: fields and SLOT_TYPES disagree")
    return [(name, ty, slot) for (name, ty), slot in zip(fields, cls.SLOT_TYPES)]


# ------------------------------------------------------------- JSON value -> message


def from_json(cls, value, where):
    """Builds a message from a JSON value, strictly (every field, nothing else)."""
    if not isinstance(value, dict):
        raise SampleError(f"{where}: expected an object for {cls.__name__}, got {json.dumps(value)}")
    fields = fields_of(cls)
    names = [name for name, _, _ in fields]
    missing = [n for n in names if n not in value]
    unknown = sorted(set(value) - set(names))
    if missing or unknown:
        raise SampleError(
            f"{where}: {cls.__name__} fields are {names}; missing {missing}, unknown {unknown}"
        )
    msg = cls()
    for name, _, slot in fields:
        setattr(msg, name, convert_in(slot, value[name], f"{where}.{name}"))
    return msg


def convert_in(slot, value, where):
    if isinstance(slot, rosidl.NamespacedType):
        return from_json(namespaced_class(slot), value, where)
    if isinstance(slot, rosidl.AbstractGenericString):
        if not isinstance(value, str):
            raise SampleError(f"{where}: expected a string, got {json.dumps(value)}")
        return value
    if isinstance(slot, (rosidl.AbstractSequence, rosidl.Array)):
        if not isinstance(value, list):
            raise SampleError(f"{where}: expected a list, got {json.dumps(value)}")
        return [convert_in(slot.value_type, v, f"{where}[{i}]") for i, v in enumerate(value)]
    if isinstance(slot, rosidl.BasicType):
        t = slot.typename
        if t == "boolean":
            if not isinstance(value, bool):
                raise SampleError(f"{where}: expected true/false, got {json.dumps(value)}")
            return value
        if t in rosidl.FLOATING_POINT_TYPES:
            if isinstance(value, str) and value in SPECIAL_FLOATS:
                return SPECIAL_FLOATS[value]
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise SampleError(f"{where}: expected a number, got {json.dumps(value)}")
            return float(value)
        if t == "octet":
            # rclpy holds a `byte` field as a bytes object of length 1.
            if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 255:
                raise SampleError(f"{where}: expected a byte 0..255, got {json.dumps(value)}")
            return bytes([value])
        if t in BASIC_SIZES and t not in ("char", "wchar", "octet"):
            if isinstance(value, bool) or not isinstance(value, int):
                raise SampleError(f"{where}: expected an integer, got {json.dumps(value)}")
            return value
    raise SampleError(f"{where}: field type {type(slot).__name__} not supported here")


# ------------------------------------------------------------- message -> JSON value


def to_json(msg):
    return {name: convert_out(slot, getattr(msg, name)) for name, _, slot in fields_of(type(msg))}


def convert_out(slot, value):
    if isinstance(slot, rosidl.NamespacedType):
        return to_json(value)
    if isinstance(slot, rosidl.AbstractGenericString):
        return str(value)
    if isinstance(slot, (rosidl.AbstractSequence, rosidl.Array)):
        return [convert_out(slot.value_type, v) for v in value]
    if isinstance(slot, rosidl.BasicType):
        t = slot.typename
        if t == "boolean":
            return bool(value)
        if t == "octet":
            return value[0] if isinstance(value, (bytes, bytearray)) else int(value)
        if t in rosidl.FLOATING_POINT_TYPES:
            value = float(value)
            if math.isnan(value):
                return "NaN"
            if math.isinf(value):
                return "Infinity" if value > 0 else "-Infinity"
            return value
        return int(value)
    raise RuntimeError(f"field type {type(slot).__name__} not supported here")


# ------------------------------------------------------------- CDR layout


class Layout:
    """Walks a message as XCDR1 lays it out: total size and alignment padding offsets.

    With estimate=True it walks as rmw_fastrtps_cpp's size estimate does instead (the
    generated get_serialized_size of rosidl_typesupport_fastrtps): that one aligns for the
    elements of a sequence of primitives even when the sequence is empty, where the
    encoder writes nothing.
    """

    def __init__(self, estimate=False):
        self.estimate = estimate
        self.pos = 0  # relative to the byte after the encapsulation header
        self.padding = []

    def align(self, n):
        while self.pos % n:
            self.padding.append(HEADER + self.pos)
            self.pos += 1

    def basic(self, typename):
        n = BASIC_SIZES[typename]
        self.align(n)
        self.pos += n

    def message(self, msg):
        for name, _, slot in fields_of(type(msg)):
            self.value(slot, getattr(msg, name))

    def value(self, slot, value):
        if isinstance(slot, rosidl.NamespacedType):
            self.message(value)
        elif isinstance(slot, rosidl.AbstractWString):
            raise RuntimeError("wstring layout not supported here")
        elif isinstance(slot, rosidl.AbstractString):
            self.basic("uint32")
            self.pos += len(value.encode("utf-8")) + 1
        elif isinstance(slot, rosidl.AbstractSequence):
            self.basic("uint32")
            if self.estimate and isinstance(slot.value_type, rosidl.BasicType):
                self.align(BASIC_SIZES[slot.value_type.typename])
            for v in value:
                self.value(slot.value_type, v)
        elif isinstance(slot, rosidl.Array):
            for v in value:
                self.value(slot.value_type, v)
        elif isinstance(slot, rosidl.BasicType):
            self.basic(slot.typename)
        else:
            raise RuntimeError(f"field type {type(slot).__name__} not supported here")


def is_fixed_size(cls):
    """No string or sequence anywhere inside (rmw_fastrtps calls such types plain)."""
    def fixed(slot):
        if isinstance(slot, rosidl.NamespacedType):
            return is_fixed_size(namespaced_class(slot))
        if isinstance(slot, rosidl.Array):
            return fixed(slot.value_type)
        return isinstance(slot, rosidl.BasicType)
    return all(fixed(slot) for _, _, slot in fields_of(cls))


def rmw_size(msg):
    """The byte length rclpy's serialize_message returns: rmw_fastrtps_cpp's rmw_serialize
    sizes the buffer by its estimate and reports that, not what Fast-CDR wrote. For a
    fixed-size type the estimate is the maximum serialized size (here: the size) plus the
    header, rounded up to a multiple of 4; otherwise the header plus get_serialized_size.
    The bytes past the encoded message are never written."""
    if is_fixed_size(type(msg)):
        layout = Layout()
        layout.message(msg)
        return (HEADER + layout.pos + 3) // 4 * 4
    layout = Layout(estimate=True)
    layout.message(msg)
    return HEADER + layout.pos


# ------------------------------------------------------------- requests


def answer_schema(type_names):
    if not isinstance(type_names, list) or not all(isinstance(t, str) for t in type_names):
        raise RequestError('"schema" must be a list of type names')
    out = {}
    for type_name in type_names:
        try:
            cls = message_class(type_name)
            out[type_name] = {"fields": [[n, t] for n, t, _ in fields_of(cls)]}
        except (ImportError, AttributeError) as e:
            out[type_name] = {"error": f"{type(e).__name__}: {e}"}
    return out


def check_sample(cls, sample, encoded_hex, where):
    result = {"decoded": None, "decode_error": None, "cdr": None, "encode_error": None,
              "size": None, "padding": None, "rmw_size": None}
    try:
        msg = from_json(cls, sample, where)
        result["cdr"] = serialize_message(msg).hex()
        layout = Layout()
        layout.message(msg)
        result["size"] = HEADER + layout.pos
        result["padding"] = layout.padding
        result["rmw_size"] = rmw_size(msg)
    except Exception as e:  # noqa: BLE001 - reported to the caller, per sample
        result["encode_error"] = f"{type(e).__name__}: {e}"
    if encoded_hex is not None:
        try:
            result["decoded"] = to_json(deserialize_message(bytes.fromhex(encoded_hex), cls))
        except Exception as e:  # noqa: BLE001
            result["decode_error"] = f"{type(e).__name__}: {e}"
    return result


def answer_cdr(request):
    if not isinstance(request, dict) or set(request) - {"samples_file", "encoded"}:
        raise RequestError('"cdr" must be an object with "samples_file" and "encoded"')
    try:
        with open(request["samples_file"], encoding="utf-8") as f:
            samples = json.load(f)
    except (KeyError, OSError, json.JSONDecodeError) as e:
        raise RequestError(f"cannot read the samples file: {e}") from None
    encoded = request.get("encoded", {})
    if not isinstance(samples, dict) or not isinstance(encoded, dict):
        raise RequestError("the samples file and \"encoded\" must be objects keyed by type name")
    unknown = sorted(set(encoded) - set(samples))
    if unknown:
        raise RequestError(f'"encoded" has types the samples file does not: {unknown}')
    out = {}
    for type_name, values in samples.items():
        if type_name.startswith("_"):  # "_comment" and the like
            continue
        if not isinstance(values, list):
            raise RequestError(f"samples of {type_name}: expected a list")
        hexes = encoded.get(type_name)
        if hexes is not None and len(hexes) != len(values):
            raise RequestError(
                f"{type_name}: {len(values)} samples but {len(hexes)} encoded values"
            )
        try:
            cls = message_class(type_name)
        except (ImportError, AttributeError) as e:
            raise RequestError(f"samples file: unknown message type {type_name}: {e}") from None
        out[type_name] = [
            check_sample(cls, v, None if hexes is None else hexes[i], f"{type_name}[{i}]")
            for i, v in enumerate(values)
        ]
    return out


def main(argv):
    if len(argv) != 1:
        print(__doc__, file=sys.stderr)
        return 2
    try:
        request = json.load(sys.stdin)
    except json.JSONDecodeError as e:
        raise RequestError(f"stdin is not valid JSON: {e}") from None
    if not isinstance(request, dict) or set(request) - {"schema", "cdr"}:
        raise RequestError('the request must be an object with "schema" and/or "cdr"')
    answer = {}
    if "schema" in request:
        answer["schema"] = answer_schema(request["schema"])
    if "cdr" in request:
        answer["cdr"] = answer_cdr(request["cdr"])
    json.dump(answer, sys.stdout, ensure_ascii=False, allow_nan=False)
    sys.stdout.write("\n")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main(sys.argv))
    except RequestError as e:
        print(f"msg_check: {e}", file=sys.stderr)
        sys.exit(2)
