#!/usr/bin/env python3
"""Writes a small robot of our own for the tutorial "ROPES on your own robot": a planar arm
with three revolute joints (shoulder, elbow, wrist) about the y axis, so that it moves in the
x-z plane, standing on a base. Each link's visual is an OBJ mesh this script writes (boxes,
with a crossbar at the hand so that the wrist's angle shows); the URDF names them by
relative path. Written for this workspace; nothing in it comes from elsewhere.

Usage: make_planar_arm.py OUT_DIR     writes OUT_DIR/planar_arm.urdf and OUT_DIR/meshes/*.obj
The same files every time (no randomness, fixed number formatting).
"""
import os
import sys

# name, boxes (centre xyz, size xyz) in the link frame, grey level of its material
LINKS = [
    ("base", [((0.0, 0.0, 0.05), (0.18, 0.18, 0.10))], 0.25),
    ("upper_arm", [((0.0, 0.0, 0.16), (0.07, 0.07, 0.32))], 0.75),
    ("forearm", [((0.0, 0.0, 0.13), (0.05, 0.05, 0.26))], 0.45),
    ("hand", [((0.0, 0.0, 0.07), (0.04, 0.04, 0.14)), ((0.0, 0.0, 0.14), (0.14, 0.04, 0.03))],
     0.15),
]
# name, parent, child, origin z in the parent link, limits (rad)
JOINTS = [
    ("shoulder", "base", "upper_arm", 0.10, (-1.6, 1.6)),
    ("elbow", "upper_arm", "forearm", 0.32, (-2.2, 2.2)),
    ("wrist", "forearm", "hand", 0.26, (-2.2, 2.2)),
]


def box_obj(boxes):
    """The boxes as one OBJ mesh: 8 corners and 12 triangles a box, outward-facing."""
    lines, base = ["# planar arm link, written by make_planar_arm.py"], 0
    faces = [(0, 2, 1), (0, 3, 2), (4, 5, 6), (4, 6, 7), (0, 1, 5), (0, 5, 4),
             (2, 3, 7), (2, 7, 6), (1, 2, 6), (1, 6, 5), (0, 4, 7), (0, 7, 3)]
    for (cx, cy, cz), (sx, sy, sz) in boxes:
        for z in (-1, 1):
            for x, y in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                lines.append(f"v {cx + x * sx / 2:.6f} {cy + y * sy / 2:.6f} {cz + z * sz / 2:.6f}")
        lines += [f"f {base + a + 1} {base + b + 1} {base + c + 1}" for a, b, c in faces]
        base += 8
    return "\n".join(lines) + "\n"


def urdf():
    out = ['<?xml version="1.0"?>', '<robot name="planar_arm">']
    for name, _, grey in LINKS:
        out += [f'  <link name="{name}">', "    <visual>",
                "      <geometry>", f'        <mesh filename="meshes/{name}.obj"/>',
                "      </geometry>",
                f'      <material name="{name}_grey"><color rgba="{grey} {grey} {grey} 1"/>'
                "</material>", "    </visual>", "  </link>"]
    for name, parent, child, z, (lower, upper) in JOINTS:
        out += [f'  <joint name="{name}" type="revolute">',
                f'    <parent link="{parent}"/>', f'    <child link="{child}"/>',
                f'    <origin xyz="0 0 {z}" rpy="0 0 0"/>', '    <axis xyz="0 1 0"/>',
                f'    <limit lower="{lower}" upper="{upper}" effort="10" velocity="2"/>',
                "  </joint>"]
    return "\n".join(out + ["</robot>"]) + "\n"


def main():
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    out = sys.argv[1]
    os.makedirs(os.path.join(out, "meshes"), exist_ok=True)
    for name, boxes, _ in LINKS:
        with open(os.path.join(out, "meshes", name + ".obj"), "w") as f:
            f.write(box_obj(boxes))
    with open(os.path.join(out, "planar_arm.urdf"), "w") as f:
        f.write(urdf())
    print(f"wrote {out}/planar_arm.urdf and {len(LINKS)} meshes in {out}/meshes/")
    return 0


if __name__ == "__main__":
    sys.exit(main())
