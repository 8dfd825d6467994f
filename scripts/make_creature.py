#!/usr/bin/env python3
"""Writes the project's bundled creature, assets/creatures/hound.glb: a low-poly skinned quadruped with
a neck, a head, four three-bone legs and a three-bone tail.

It is a real skinned mesh, made the way a modelling tool exports one: a glTF 2.0 binary with one mesh
(positions, normals, JOINTS_0, WEIGHTS_0), one skin with inverse bind matrices, a node per bone and the
mesh node beside the armature. Each bone's part of the body is a tapered eight-sided tube from the bone
to its child, with ears on the head; the ring where a part meets its parent is weighted half to each, so
joints along a chain bend smoothly. Units are metres, y up, +z forward, as glTF says; the hound stands 0.62 m tall
and is 1.1 m long from nose to tail tip.

Only the Python standard library is used, and the output is byte-for-byte the same on every run.

    python3 scripts/make_creature.py [OUT]      (default: assets/creatures/hound.glb)
"""

import json
import math
import struct
import sys
from pathlib import Path

# Bones: name, parent, head position (m, y up, +z forward), tube radius at the head and at the tip.
# The tip of a bone is its first child's head, or `tip` for leaves.
BONES = [
    # name, parent, head, tip (leaves only), radius at head, radius at tip
    ("Hips", None, (0.0, 0.46, -0.20), None, 0.10, 0.11),
    ("Spine", "Hips", (0.0, 0.47, -0.02), None, 0.11, 0.11),
    ("Chest", "Spine", (0.0, 0.47, 0.14), None, 0.11, 0.08),
    ("Neck", "Chest", (0.0, 0.50, 0.30), None, 0.06, 0.05),
    ("Head", "Neck", (0.0, 0.58, 0.38), (0.0, 0.56, 0.54), 0.07, 0.04),
    ("Tail1", "Hips", (0.0, 0.48, -0.32), None, 0.04, 0.035),
    ("Tail2", "Tail1", (0.0, 0.45, -0.46), None, 0.035, 0.025),
    ("Tail3", "Tail2", (0.0, 0.41, -0.58), (0.0, 0.38, -0.70), 0.025, 0.01),
]
for side, x in (("L", 0.08), ("R", -0.08)):
    BONES += [
        (f"Thigh.{side}", "Hips", (x, 0.40, -0.16), None, 0.05, 0.04),
        (f"Shin.{side}", f"Thigh.{side}", (x, 0.23, -0.10), None, 0.035, 0.03),
        (f"HindFoot.{side}", f"Shin.{side}", (x, 0.07, -0.20), (x, 0.02, -0.14), 0.03, 0.025),
        (f"UpperArm.{side}", "Chest", (x, 0.40, 0.24), None, 0.045, 0.035),
        (f"Forearm.{side}", f"UpperArm.{side}", (x, 0.23, 0.19), None, 0.032, 0.028),
        (f"FrontFoot.{side}", f"Forearm.{side}", (x, 0.07, 0.23), (x, 0.02, 0.29), 0.028, 0.024),
    ]
SIDES = 8


def sub(a, b):
    return tuple(x - y for x, y in zip(a, b))


def add(a, b):
    return tuple(x + y for x, y in zip(a, b))


def scale(a, s):
    return tuple(x * s for x in a)


def norm(a):
    return math.sqrt(sum(x * x for x in a))


def normalise(a):
    n = norm(a)
    return scale(a, 1.0 / n)


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def frame(axis):
    """Two unit vectors perpendicular to `axis` and to each other."""
    helper = (0.0, 1.0, 0.0) if abs(axis[1]) < 0.9 else (1.0, 0.0, 0.0)
    u = normalise(cross(axis, helper))
    return u, cross(axis, u)


def build():
    index = {b[0]: i for i, b in enumerate(BONES)}
    heads = {b[0]: b[2] for b in BONES}
    children = {b[0]: [c[0] for c in BONES if c[1] == b[0]] for b in BONES}
    positions, normals, joints, weights, indices = [], [], [], [], []

    def ring(centre, axis, radius, bone_weights):
        u, v = frame(axis)
        start = len(positions)
        for k in range(SIDES):
            a = 2.0 * math.pi * k / SIDES
            n = add(scale(u, math.cos(a)), scale(v, math.sin(a)))
            positions.append(add(centre, scale(n, radius)))
            normals.append(n)
            js = [j for j, _ in bone_weights] + [0] * (4 - len(bone_weights))
            ws = [w for _, w in bone_weights] + [0.0] * (4 - len(bone_weights))
            joints.append(js)
            weights.append(ws)
        return start

    def cap(centre, axis, ring_start, bone_weights, outward):
        """A fan closing a ring, its apex pushed `outward` along the axis."""
        apex = len(positions)
        positions.append(add(centre, scale(axis, outward)))
        normals.append(axis if outward >= 0 else scale(axis, -1.0))
        joints.append([j for j, _ in bone_weights] + [0] * (4 - len(bone_weights)))
        weights.append([w for _, w in bone_weights] + [0.0] * (4 - len(bone_weights)))
        for k in range(SIDES):
            a, b = ring_start + k, ring_start + (k + 1) % SIDES
            indices.extend((a, b, apex) if outward >= 0 else (b, a, apex))

    for name, parent, head, tip, r0, r1 in BONES:
        me = index[name]
        end = heads[children[name][0]] if children[name] else tip
        axis = normalise(sub(end, head))
        # Along a chain (knee, ankle, neck, tail) the joint ring bends with both bones; where limbs leave
        # the torso, each part follows its own bone, so the torso's bones deform only the torso.
        chain = parent is not None and len(children[parent]) == 1
        start_weights = [(me, 0.5), (index[parent], 0.5)] if chain else [(me, 1.0)]
        # The rump reaches a little behind the hips.
        a = sub(head, scale(axis, 0.04)) if name == "Hips" else head
        b = end
        r_start = ring(a, axis, r0, start_weights)
        r_end = ring(b, axis, r1, [(me, 1.0)])
        for k in range(SIDES):
            i0, i1 = r_start + k, r_start + (k + 1) % SIDES
            j0, j1 = r_end + k, r_end + (k + 1) % SIDES
            indices.extend((i0, i1, j1, i0, j1, j0))
        if not children[name]:
            cap(b, axis, r_end, [(me, 1.0)], 0.5 * r1)
        if name == "Hips":
            cap(a, axis, r_start, start_weights, -0.6 * r0)
        if name == "Head":
            # Ears: two small cones on the head bone.
            for x in (0.04, -0.04):
                base = add(head, (x, 0.05, 0.02))
                e = ring(base, (0.0, 1.0, 0.0), 0.02, [(me, 1.0)])
                cap(base, (0.0, 1.0, 0.0), e, [(me, 1.0)], 0.06)

    # Nodes: the armature "Hound" holds the root bone; the skinned mesh node is a scene root of its own,
    # as glTF asks (its transform would be ignored anyway).
    nodes = [{"name": "Hound", "children": [1]}]
    for name, parent, head, _, _, _ in BONES:
        origin = heads[parent] if parent else (0.0, 0.0, 0.0)
        node = {"name": name, "translation": [round(x, 6) for x in sub(head, origin)]}
        kids = [1 + index[c] for c in children[name]]
        if kids:
            node["children"] = kids
        nodes.append(node)
    nodes.append({"name": "HoundMesh", "mesh": 0, "skin": 0})

    # Binary buffer: positions, normals, joints (u8), weights, indices (u16), inverse bind matrices.
    blobs, views, accessors = [], [], []

    def push(data, target=None):
        offset = sum(len(b) for b in blobs)
        pad = (-offset) % 4
        if pad:
            blobs.append(b"\0" * pad)
            offset += pad
        blobs.append(data)
        view = {"buffer": 0, "byteOffset": offset, "byteLength": len(data)}
        if target:
            view["target"] = target
        views.append(view)
        return len(views) - 1

    def accessor(view, component, count, kind, **extra):
        accessors.append({"bufferView": view, "componentType": component, "count": count, "type": kind, **extra})
        return len(accessors) - 1

    # Positions as the file stores them (f32), so that the declared bounds are exact.
    packed = struct.pack(f"<{3 * len(positions)}f", *(c for p in positions for c in p))
    stored = list(struct.iter_unpack("<3f", packed))
    lo = [min(p[i] for p in stored) for i in range(3)]
    hi = [max(p[i] for p in stored) for i in range(3)]
    pos = accessor(push(packed, 34962), 5126, len(positions), "VEC3", min=lo, max=hi)
    flat = [c for n in normals for c in n]
    nor = accessor(push(struct.pack(f"<{len(flat)}f", *flat), 34962), 5126, len(normals), "VEC3")
    flat = [c for j in joints for c in j]
    jnt = accessor(push(struct.pack(f"<{len(flat)}B", *flat), 34962), 5121, len(joints), "VEC4")
    flat = [c for w in weights for c in w]
    wgt = accessor(push(struct.pack(f"<{len(flat)}f", *flat), 34962), 5126, len(weights), "VEC4")
    idx = accessor(push(struct.pack(f"<{len(indices)}H", *indices), 34963), 5123, len(indices), "SCALAR")
    ibm = []
    for name, *_ in BONES:
        x, y, z = heads[name]
        # Bones are not rotated at rest: the bind matrix is a translation (column-major).
        ibm += [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, -x, -y, -z, 1]
    inv = accessor(push(struct.pack(f"<{len(ibm)}f", *ibm)), 5126, len(BONES), "MAT4")

    binary = b"".join(blobs)
    binary += b"\0" * ((-len(binary)) % 4)
    doc = {
        "asset": {"version": "2.0", "generator": "ACE for Bevy scripts/make_creature.py"},
        "scene": 0,
        "scenes": [{"name": "Hound", "nodes": [0, len(nodes) - 1]}],
        "nodes": nodes,
        "meshes": [{
            "name": "Hound",
            "primitives": [{
                "attributes": {"POSITION": pos, "NORMAL": nor, "JOINTS_0": jnt, "WEIGHTS_0": wgt},
                "indices": idx,
                "material": 0,
            }],
        }],
        "materials": [{
            "name": "Fur",
            "pbrMetallicRoughness": {"baseColorFactor": [0.62, 0.42, 0.25, 1.0], "metallicFactor": 0.0,
                                     "roughnessFactor": 0.85},
        }],
        "skins": [{"name": "Armature", "joints": [1 + i for i in range(len(BONES))], "skeleton": 1,
                   "inverseBindMatrices": inv}],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": len(binary)}],
    }
    text = json.dumps(doc, separators=(",", ":"), sort_keys=True).encode()
    text += b" " * ((-len(text)) % 4)
    return (struct.pack("<III", 0x46546C67, 2, 12 + 8 + len(text) + 8 + len(binary))
            + struct.pack("<II", len(text), 0x4E4F534A) + text
            + struct.pack("<II", len(binary), 0x004E4942) + binary)


def main():
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent.parent / "assets/creatures/hound.glb"
    out.parent.mkdir(parents=True, exist_ok=True)
    data = build()
    tmp = out.with_suffix(".glb.tmp")
    tmp.write_bytes(data)
    tmp.replace(out)
    print(f"wrote {out} ({len(data)} bytes, {len(BONES)} bones)")


if __name__ == "__main__":
    main()
