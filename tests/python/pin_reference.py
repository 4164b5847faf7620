#!/usr/bin/env python3
"""Independent forward-kinematics / centre-of-mass reference using Pinocchio.

Used by the Rust integration tests to cross-check our own kinematics.

Usage:
    python pin_reference.py URDF_PATH  < request.json  > answer.json

Request (one JSON object on stdin, or a JSON list of such objects; every key
is optional):
    {
      "base":   {"xyz": [x, y, z], "rpy": [roll, pitch, yaw]},
      "q":      {"joint_name": value, ...},
      "frames": ["link_name", ...]
    }
  * "base" places the root link as a floating base in the world frame.
    rpy is URDF/ROS fixed-axis roll-pitch-yaw: R = Rz(yaw) Ry(pitch) Rx(roll).
    Missing "base" (or a missing "xyz"/"rpy" in it) means identity.
  * "q" maps URDF joint names to positions (rad for revolute/continuous,
    m for prismatic). Joints not named are 0. Fixed joints cannot be set.
  * "frames" lists URDF link names whose world placement is wanted. Links
    attached through fixed joints are fine (Pinocchio keeps them as frames).

Answer (one JSON object on stdout; for a list of requests, a list of answers
in the same order, the URDF loaded once):
    {
      "com":    [x, y, z],           # whole-robot centre of mass, world frame
      "mass":   total_mass,          # kg, sum over all links
      "frames": {"link_name": {"xyz": [x, y, z],
                               "rotation": [[r00, r01, r02],
                                            [r10, r11, r12],
                                            [r20, r21, r22]]}}
    }
  "rotation" is the link-to-world rotation matrix, row-major; "xyz" the link
  origin in the world frame (i.e. the URDF link frame, not its inertial frame).

Exit codes: 0 ok; 2 bad request (unknown joint or link, malformed JSON,
wrong types, unsupported joint type), message on stderr; 1 anything else.
"""

import json
import math
import sys

import numpy as np
import pinocchio as pin

ROOT_JOINT = "root_joint"  # name Pinocchio gives the added free-flyer joint


class RequestError(Exception):
    """Problem with the caller's request: exit code 2."""


def _vec3(value, what):
    if (
        not isinstance(value, list)
        or len(value) != 3
        or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
    ):
        raise RequestError(f"{what} must be a list of 3 numbers, got {json.dumps(value)}")
    if not all(math.isfinite(v) for v in value):
        raise RequestError(f"{what} must be finite, got {json.dumps(value)}")
    return np.array(value, dtype=float)


def rpy_to_matrix(roll, pitch, yaw):
    """URDF fixed-axis RPY: R = Rz(yaw) @ Ry(pitch) @ Rx(roll)."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def build_configuration(model, base, joint_values):
    q = pin.neutral(model)  # continuous joints neutral = (cos 0, sin 0) = (1, 0)

    # Free-flyer: q[0:3] translation, q[3:7] quaternion (x, y, z, w).
    root_id = model.getJointId(ROOT_JOINT)
    if root_id >= model.njoints or model.joints[root_id].nq != 7:
        raise RuntimeError(f"model has no free-flyer joint named {ROOT_JOINT!r}")
    root = model.joints[root_id]
    if not isinstance(base, dict):
        raise RequestError('"base" must be an object with "xyz" and "rpy"')
    unknown = set(base) - {"xyz", "rpy"}
    if unknown:
        raise RequestError(f'unknown key(s) in "base": {", ".join(sorted(unknown))}')
    xyz = _vec3(base.get("xyz", [0.0, 0.0, 0.0]), "base.xyz")
    rpy = _vec3(base.get("rpy", [0.0, 0.0, 0.0]), "base.rpy")
    quat = pin.Quaternion(rpy_to_matrix(*rpy))
    quat.normalize()
    i = root.idx_q
    q[i : i + 3] = xyz
    q[i + 3 : i + 7] = quat.coeffs()  # coeffs() is (x, y, z, w)

    if not isinstance(joint_values, dict):
        raise RequestError('"q" must be an object {joint_name: value}')
    for name, value in joint_values.items():
        if name == ROOT_JOINT or not model.existJointName(name):
            raise RequestError(
                f"unknown joint {name!r} (not a movable joint of the URDF; "
                "fixed joints cannot be set, the base pose goes in \"base\")"
            )
        if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
            raise RequestError(f"joint {name!r}: value must be a finite number, got {json.dumps(value)}")
        joint = model.joints[model.getJointId(name)]
        i = joint.idx_q
        if joint.nq == 1 and joint.nv == 1:  # revolute (any axis) or prismatic
            q[i] = value
        elif joint.nq == 2 and joint.nv == 1:  # continuous: (cos, sin)
            q[i] = math.cos(value)
            q[i + 1] = math.sin(value)
        else:
            raise RequestError(
                f"joint {name!r}: unsupported joint type {joint.shortname()} "
                f"(nq={joint.nq}, nv={joint.nv})"
            )
    return q


def main(argv):
    if len(argv) != 2 or argv[1] in ("-h", "--help"):
        print(__doc__, file=sys.stderr)
        return 2
    urdf_path = argv[1]

    try:
        request = json.load(sys.stdin)
    except json.JSONDecodeError as e:
        raise RequestError(f"stdin is not valid JSON: {e}") from None
    batch = isinstance(request, list)
    requests = request if batch else [request]
    for k, r in enumerate(requests):
        where = f"request {k}" if batch else "request"
        if not isinstance(r, dict):
            raise RequestError("stdin must hold one JSON object or a list of JSON objects")
        unknown = set(r) - {"base", "q", "frames"}
        if unknown:
            raise RequestError(f"unknown key(s) in {where}: {', '.join(sorted(unknown))}")

    try:
        model = pin.buildModelFromUrdf(urdf_path, pin.JointModelFreeFlyer(), ROOT_JOINT)
    except (ValueError, RuntimeError, OSError) as e:
        print(f"pin_reference: cannot load URDF {urdf_path!r}: {e}", file=sys.stderr)
        return 1
    data = model.createData()

    answers = []
    for k, r in enumerate(requests):
        try:
            answers.append(answer(model, data, r))
        except RequestError as e:
            raise RequestError(f"request {k}: {e}" if batch else str(e)) from None
    json.dump(answers if batch else answers[0], sys.stdout)
    sys.stdout.write("\n")
    return 0


def answer(model, data, request):
    """Evaluates one request object into one answer object."""
    q = build_configuration(model, request.get("base", {}), request.get("q", {}))

    frames = request.get("frames", [])
    if not isinstance(frames, list) or not all(isinstance(f, str) for f in frames):
        raise RequestError('"frames" must be a list of link names')
    frame_ids = {}
    for name in frames:
        # getFrameId returns len(model.frames) for an unknown name, no exception.
        if not model.existFrame(name, pin.BODY):
            raise RequestError(f"unknown link {name!r} (no body frame of that name in the URDF)")
        frame_ids[name] = model.getFrameId(name, pin.BODY)

    pin.forwardKinematics(model, data, q)
    pin.updateFramePlacements(model, data)
    com = pin.centerOfMass(model, data, q)
    mass = float(data.mass[0])  # total mass (subtree of the universe)

    out = {
        "com": [float(c) for c in com],
        "mass": mass,
        "frames": {},
    }
    for name, fid in frame_ids.items():
        placement = data.oMf[fid]
        out["frames"][name] = {
            "xyz": [float(v) for v in placement.translation],
            "rotation": [[float(v) for v in row] for row in placement.rotation],
        }
    return out


if __name__ == "__main__":
    try:
        sys.exit(main(sys.argv))
    except RequestError as e:
        print(f"pin_reference: {e}", file=sys.stderr)
        sys.exit(2)
