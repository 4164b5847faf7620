#!/usr/bin/env python3
"""Writes the OP3-layout test robot: op3_layout.urdf, op3_layout_scene.xml (a MuJoCo scene
of the same robot under other names) and op3_layout_scene_map.yaml (URDF names -> scene
names), next to this script. Rerun after changing a number here; the three files are
committed so the tests need no Python.

The robot is ours (numbers chosen for the tests, no vendor file used). Its legs have the
layout of the ROBOTIS OP3 / Darwin-OP family, which the closed-form IK must take as the
URDF stands (ALGORITHM.md, "Leg layouts of real servo humanoids"):
- the hip roll joint sits 24 mm behind and 28 mm below the hip yaw joint: the two origins
  are apart, the axes still cross (H, the hip point, is 28 mm below the yaw joint);
- the hip pitch axis is 3 mm ahead of H (a_h), 4 mm below the roll axis (h_h), and the
  pitch plane 16 mm outward of the roll axis;
- the knee sits 2 mm ahead of the hip pitch axis (a thigh tilted at zero angles), the ankle
  pitch axis back under the hip;
- the ankle roll joint sits 22 mm behind and 10 mm inward of the ankle pitch joint: the
  ankle axes cross, and the sideways offsets do not cancel (e = 16 - 10 = 6 mm outward);
- axis signs as servo robots have them: both hip rolls about -x, the right leg's pitch
  joints about -y;
- 20 joints: 12 leg, 6 arm, 2 head; 2.94 kg.
"""

import os

HERE = os.path.dirname(os.path.abspath(__file__))


def box_inertia(m, sx, sy, sz):
    return (m * (sy * sy + sz * sz) / 12, m * (sx * sx + sz * sz) / 12, m * (sx * sx + sy * sy) / 12)


def f(v):
    return " ".join(f"{x:.6g}" if abs(x) > 1e-15 else "0" for x in v)


# A link: (name, mass, com, box size of the mass, collision box (origin, size) or None).
# A joint: (name, type, parent, child, origin, axis, (lower, upper)).
LINKS = []
JOINTS = []


def mirror(v, side):
    return (v[0], v[1] * side, v[2])


def leg(p, side):
    """One leg; side +1 left, -1 right (y mirrored). Pitch axes +y on the left, -y on the right."""
    pa = (0, side, 0)
    # Hip flexion (thigh forward) is a negative angle about +y.
    hip_lim = (-1.6, 0.6) if side > 0 else (-0.6, 1.6)
    knee_lim = (-0.05, 2.3) if side > 0 else (-2.3, 0.05)
    ankle_lim = (-1.4, 1.4)
    JOINTS.extend([
        (f"{p}_hip_yaw", "revolute", "base_link", f"{p}_hip_yaw_link", mirror((0.005, 0.035, -0.035), side), (0, 0, 1), (-1.0, 1.0)),
        (f"{p}_hip_roll", "revolute", f"{p}_hip_yaw_link", f"{p}_hip_roll_link", (-0.024, 0, -0.028), (-1, 0, 0), (-0.6, 0.6)),
        (f"{p}_hip_pitch", "revolute", f"{p}_hip_roll_link", f"{p}_thigh", mirror((0.027, 0.016, -0.004), side), pa, hip_lim),
        (f"{p}_knee", "revolute", f"{p}_thigh", f"{p}_shin", (0.002, 0, -0.100), pa, knee_lim),
        (f"{p}_ankle_pitch", "revolute", f"{p}_shin", f"{p}_ankle_link", (-0.002, 0, -0.100), pa, ankle_lim),
        (f"{p}_ankle_roll", "revolute", f"{p}_ankle_link", f"{p}_foot", mirror((-0.022, -0.010, 0), side), (1, 0, 0), (-0.6, 0.6)),
    ])
    LINKS.extend([
        (f"{p}_hip_yaw_link", 0.03, mirror((-0.012, 0, -0.014), side), (0.02, 0.02, 0.02), None),
        (f"{p}_hip_roll_link", 0.14, mirror((0.0, 0.008, 0), side), (0.05, 0.04, 0.03), None),
        (f"{p}_thigh", 0.16, (0.001, 0, -0.05), (0.03, 0.035, 0.08), ((0.001, 0, -0.05), (0.03, 0.035, 0.07))),
        (f"{p}_shin", 0.10, (-0.001, 0, -0.05), (0.03, 0.03, 0.08), ((-0.001, 0, -0.05), (0.03, 0.03, 0.07))),
        (f"{p}_ankle_link", 0.14, mirror((-0.011, -0.005, 0), side), (0.05, 0.04, 0.03), None),
        # The sole: 110 x 66 mm, 8 mm ahead of the ankle point and 3 mm inward, 34 mm below it.
        (f"{p}_foot", 0.08, mirror((0.030, -0.003, -0.026), side), (0.11, 0.066, 0.008),
         (mirror((0.030, -0.003, -0.030), side), (0.11, 0.066, 0.008))),
    ])


def arm(p, side):
    JOINTS.extend([
        (f"{p}_shoulder_pitch", "revolute", "chest", f"{p}_shoulder", mirror((0, 0.075, 0.04), side), (0, 1, 0), (-2.5, 2.5)),
        (f"{p}_shoulder_roll", "revolute", f"{p}_shoulder", f"{p}_upper_arm", mirror((0, 0.015, 0), side), (-1, 0, 0), (-1.5, 1.5)),
        (f"{p}_elbow", "revolute", f"{p}_upper_arm", f"{p}_forearm", (0, 0, -0.09), (0, side, 0), (-2.0, 2.0)),
    ])
    LINKS.extend([
        (f"{p}_shoulder", 0.03, (0, 0, 0), (0.02, 0.02, 0.02), None),
        (f"{p}_upper_arm", 0.08, (0, 0, -0.045), (0.025, 0.025, 0.08), ((0, 0, -0.045), (0.025, 0.025, 0.06))),
        (f"{p}_forearm", 0.07, (0, 0, -0.04), (0.02, 0.02, 0.08), ((0, 0, -0.04), (0.02, 0.02, 0.07))),
    ])


LINKS.append(("base_link", 0.35, (0, 0, 0), (0.08, 0.12, 0.04), ((0, 0, 0), (0.08, 0.12, 0.04))))
LINKS.append(("chest", 0.75, (0, 0, 0), (0.08, 0.13, 0.12), ((0, 0, 0), (0.08, 0.13, 0.12))))
JOINTS.append(("chest_fixed", "fixed", "base_link", "chest", (0, 0, 0.09), None, None))
leg("l", 1)
leg("r", -1)
arm("l", 1)
arm("r", -1)
JOINTS.extend([
    ("head_pan", "revolute", "chest", "neck", (0, 0, 0.065), (0, 0, 1), (-1.5, 1.5)),
    ("head_tilt", "revolute", "neck", "head", (0, 0, 0.02), (0, 1, 0), (-0.8, 0.8)),
])
LINKS.extend([
    ("neck", 0.03, (0, 0, 0.01), (0.02, 0.02, 0.02), None),
    ("head", 0.15, (0, 0, 0.03), (0.06, 0.07, 0.06), ((0, 0, 0.03), (0.06, 0.07, 0.06))),
])

TOTAL = sum(l[1] for l in LINKS)


def urdf():
    out = ['<?xml version="1.0"?>',
           "<!-- Written by tests/data/make_op3_layout.py (see there what it is); do not edit by hand. -->",
           f'<!-- {len([j for j in JOINTS if j[1] != "fixed"])} joints, {TOTAL:.2f} kg. -->',
           '<robot name="op3_layout">']
    for name, m, com, size, col in LINKS:
        ixx, iyy, izz = box_inertia(m, *size)
        out.append(f'  <link name="{name}">')
        out.append(f'    <inertial><origin xyz="{f(com)}" rpy="0 0 0"/><mass value="{m}"/>'
                   f'<inertia ixx="{ixx:.6g}" ixy="0" ixz="0" iyy="{iyy:.6g}" iyz="0" izz="{izz:.6g}"/></inertial>')
        if col:
            out.append(f'    <collision><origin xyz="{f(col[0])}" rpy="0 0 0"/><geometry><box size="{f(col[1])}"/></geometry></collision>')
        out.append("  </link>")
    for name, kind, parent, child, xyz, axis, lim in JOINTS:
        out.append(f'  <joint name="{name}" type="{kind}">')
        out.append(f'    <parent link="{parent}"/><child link="{child}"/>')
        out.append(f'    <origin xyz="{f(xyz)}" rpy="0 0 0"/>')
        if kind != "fixed":
            out.append(f'    <axis xyz="{f(axis)}"/>')
            out.append(f'    <limit lower="{lim[0]}" upper="{lim[1]}" effort="4.0" velocity="6.0"/>')
        out.append("  </joint>")
    out.append("</robot>")
    return "\n".join(out) + "\n"


def scene_name(urdf_name):
    """The scene's own names: `l_hip_yaw` -> `HipYawL`, `base_link` -> `pelvis`."""
    if urdf_name == "base_link":
        return "pelvis"
    side = ""
    if urdf_name[:2] in ("l_", "r_"):
        side, urdf_name = urdf_name[0].upper(), urdf_name[2:]
    return "".join(w.capitalize() for w in urdf_name.split("_")) + side


def scene():
    children = {}
    for j in JOINTS:
        children.setdefault(j[2], []).append(j)
    links = {l[0]: l for l in LINKS}
    out = ["<!--",
           "  The OP3-layout test robot as a MuJoCo scene, written by tests/data/make_op3_layout.py",
           "  from the same numbers as op3_layout.urdf, under other names (op3_layout_scene_map.yaml),",
           "  with its own floor, contacts and servos (kp 40 N*m/rad, kv 0.3 N*m*s/rad, 3 N*m).",
           "  Contacts: soles (class \"sole\") collide with the floor and each other, every other",
           "  geom with the floor only.",
           "-->",
           '<mujoco model="op3_layout_scene">',
           '  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>',
           '  <option timestep="0.001" integrator="implicitfast" cone="pyramidal"/>',
           "  <default>",
           '    <joint armature="0.005"/>',
           '    <geom contype="0" conaffinity="1" friction="1 0.005 0.0001"/>',
           '    <position kp="40" kv="0.3" forcerange="-3 3"/>',
           '    <default class="sole">',
           '      <geom contype="2" conaffinity="3"/>',
           "    </default>",
           "  </default>",
           "  <worldbody>",
           '    <geom name="ground" type="plane" size="5 5 0.1" contype="1" conaffinity="2"/>',
           '    <light name="sun" pos="0 0 3" dir="0 0 -1" directional="true"/>']
    actuators = []

    def body(link, pos, joint, indent):
        """A body and its subtree; `joint` is "free", "welded" or a JOINTS entry."""
        pad = "  " * indent
        name, m, com, size, col = links[link]
        out.append(f'{pad}<body name="{scene_name(link)}" pos="{f(pos)}">')
        if joint == "free":
            out.append(f'{pad}  <freejoint name="floating_base"/>')
        elif joint != "welded":
            jn = scene_name(joint[0])
            out.append(f'{pad}  <joint name="{jn}" axis="{f(joint[5])}" range="{joint[6][0]} {joint[6][1]}"/>')
            actuators.append(jn)
        ixx, iyy, izz = box_inertia(m, *size)
        out.append(f'{pad}  <inertial pos="{f(com)}" mass="{m}" diaginertia="{ixx:.6g} {iyy:.6g} {izz:.6g}"/>')
        if col:
            cls = ' class="sole"' if link.endswith("_foot") else ""
            gname = "Sole" + scene_name(link)[-1] if link.endswith("_foot") else scene_name(link) + "Box"
            half = tuple(x / 2 for x in col[1])
            out.append(f'{pad}  <geom name="{gname}"{cls} type="box" pos="{f(col[0])}" size="{f(half)}"/>')
        for j in children.get(link, []):
            body(j[3], j[4], "welded" if j[1] == "fixed" else j, indent + 1)
        out.append(f"{pad}</body>")

    body("base_link", (0, 0, 0.30), "free", 2)
    actuator_lines = [f'    <position name="act_{a}" joint="{a}"/>' for a in actuators]
    return "\n".join(out) + "\n  </worldbody>\n  <actuator>\n" + "\n".join(actuator_lines) + "\n  </actuator>\n</mujoco>\n"


def joint_map():
    out = ["# Joint map of op3_layout_scene.xml: URDF (op3_layout.urdf) names -> scene names.",
           "# Written by tests/data/make_op3_layout.py.",
           "links:",
           "  base_link: pelvis",
           "  l_foot: FootL",
           "  r_foot: FootR",
           "soles:",
           "  l_foot: SoleL",
           "  r_foot: SoleR",
           "floor_geom: ground",
           "joints:"]
    for j in JOINTS:
        if j[1] != "fixed":
            s = scene_name(j[0])
            out.append(f"  {j[0]}: {{joint: {s}, actuator: act_{s}}}")
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    for name, text in [("op3_layout.urdf", urdf()), ("op3_layout_scene.xml", scene()),
                       ("op3_layout_scene_map.yaml", joint_map())]:
        with open(os.path.join(HERE, name), "w") as fh:
            fh.write(text)
    print(f"{len(LINKS)} links, {TOTAL:.3f} kg")
