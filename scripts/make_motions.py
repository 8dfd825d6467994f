#!/usr/bin/env python3
"""Writes the project-authored sample clips in assets/motions/ (walk, wave, reach).

These are procedural, hand-keyed motions made by the project (no captured data), so they can ship
with it. They use a LAFAN1/Mixamo-style skeleton in centimetres, Y up, facing +Z, at 30 fps, so the
importer's unit, up-axis and naming detection is exercised by the demo too.

    python3 scripts/make_motions.py            # rewrites assets/motions/*.bvh
"""
import math
import os

FPS = 30
# (name, parent, offset cm) in hierarchy order; the rest pose stands upright with arms hanging down.
SKELETON = [
    ("Hips", None, (0.0, 95.0, 0.0)),
    ("Spine", "Hips", (0.0, 10.0, 0.0)),
    ("Spine1", "Spine", (0.0, 12.0, 0.0)),
    ("Spine2", "Spine1", (0.0, 12.0, 0.0)),
    ("Neck", "Spine2", (0.0, 15.0, 0.0)),
    ("Head", "Neck", (0.0, 10.0, 0.0)),
    ("LeftShoulder", "Spine2", (3.0, 12.0, 0.0)),
    ("LeftArm", "LeftShoulder", (14.0, 0.0, 0.0)),
    ("LeftForeArm", "LeftArm", (0.0, -28.0, 0.0)),
    ("LeftHand", "LeftForeArm", (0.0, -26.0, 0.0)),
    ("RightShoulder", "Spine2", (-3.0, 12.0, 0.0)),
    ("RightArm", "RightShoulder", (-14.0, 0.0, 0.0)),
    ("RightForeArm", "RightArm", (0.0, -28.0, 0.0)),
    ("RightHand", "RightForeArm", (0.0, -26.0, 0.0)),
    ("LeftUpLeg", "Hips", (9.0, -3.0, 0.0)),
    ("LeftLeg", "LeftUpLeg", (0.0, -42.0, 0.0)),
    ("LeftFoot", "LeftLeg", (0.0, -42.0, 0.0)),
    ("LeftToe", "LeftFoot", (0.0, -6.0, 14.0)),
    ("RightUpLeg", "Hips", (-9.0, -3.0, 0.0)),
    ("RightLeg", "RightUpLeg", (0.0, -42.0, 0.0)),
    ("RightFoot", "RightLeg", (0.0, -42.0, 0.0)),
    ("RightToe", "RightFoot", (0.0, -6.0, 14.0)),
]
END_SITES = {"Head": (0.0, 18.0, 0.0), "LeftHand": (0.0, -18.0, 0.0), "RightHand": (0.0, -18.0, 0.0),
             "LeftToe": (0.0, 0.0, 5.0), "RightToe": (0.0, 0.0, 5.0)}


def hierarchy():
    children = {}
    for name, parent, _ in SKELETON:
        children.setdefault(parent, []).append(name)
    offsets = {name: off for name, _, off in SKELETON}
    lines = ["HIERARCHY"]

    def emit(name, depth):
        pad = "  " * depth
        kind = "ROOT" if depth == 0 else "JOINT"
        lines.append(f"{pad}{kind} {name}")
        lines.append(f"{pad}{{")
        x, y, z = offsets[name]
        lines.append(f"{pad}  OFFSET {x:.4f} {y:.4f} {z:.4f}")
        if depth == 0:
            lines.append(f"{pad}  CHANNELS 6 Xposition Yposition Zposition Yrotation Xrotation Zrotation")
        else:
            lines.append(f"{pad}  CHANNELS 3 Zrotation Xrotation Yrotation")
        for c in children.get(name, []):
            emit(c, depth + 1)
        if name in END_SITES:
            ex, ey, ez = END_SITES[name]
            lines.extend([f"{pad}  End Site", f"{pad}  {{", f"{pad}    OFFSET {ex:.4f} {ey:.4f} {ez:.4f}", f"{pad}  }}"])
        lines.append(f"{pad}}}")

    emit("Hips", 0)
    return lines


def smooth(x):
    """0 → 1 smoothstep on [0, 1], clamped."""
    x = min(max(x, 0.0), 1.0)
    return x * x * (3.0 - 2.0 * x)


def walk(t):
    """Walks forward at 1.2 m/s with a 1.1 s stride cycle, turning gently left after 2 s."""
    phase = 2.0 * math.pi * t / 1.1
    heading = 20.0 * smooth((t - 2.0) / 1.5)  # degrees about Y
    speed = 120.0  # cm/s
    # integrate the heading for the root path
    steps = max(1, int(t * FPS))
    x = z = 0.0
    for k in range(steps):
        tk = k / FPS
        h = math.radians(20.0 * smooth((tk - 2.0) / 1.5))
        x += math.sin(h) * speed / FPS
        z += math.cos(h) * speed / FPS
    rot = {}
    hip = 28.0 * math.sin(phase)
    rot["LeftUpLeg"] = (0.0, -hip, 0.0)
    rot["RightUpLeg"] = (0.0, hip, 0.0)
    # knees flex during swing (the half cycle in which the thigh moves forward)
    rot["LeftLeg"] = (0.0, 55.0 * max(0.0, math.cos(phase)) ** 2 + 5.0, 0.0)
    rot["RightLeg"] = (0.0, 55.0 * max(0.0, -math.cos(phase)) ** 2 + 5.0, 0.0)
    rot["LeftFoot"] = (0.0, 0.6 * hip - 5.0, 0.0)
    rot["RightFoot"] = (0.0, -0.6 * hip - 5.0, 0.0)
    rot["LeftArm"] = (8.0, 22.0 * math.sin(phase), 0.0)
    rot["RightArm"] = (-8.0, -22.0 * math.sin(phase), 0.0)
    rot["LeftForeArm"] = (0.0, -15.0 - 10.0 * max(0.0, math.sin(phase)), 0.0)
    rot["RightForeArm"] = (0.0, -15.0 - 10.0 * max(0.0, -math.sin(phase)), 0.0)
    rot["Spine1"] = (0.0, 4.0, 4.0 * math.sin(phase))
    # the pelvis drops as the legs spread so the stance foot stays on the ground
    root = (x, 92.0 - 84.0 * (1.0 - math.cos(math.radians(hip))), z)
    return root, (1.5 * math.sin(phase), 3.0, heading), rot


def wave(t):
    """Stands, raises the right arm and waves the hand three times, then lowers it."""
    up = smooth(t / 0.8) * (1.0 - smooth((t - 3.4) / 0.6))
    rot = {}
    rot["RightArm"] = (-150.0 * up, 0.0, 0.0)
    rot["RightForeArm"] = (-35.0 * up * math.sin(2.0 * math.pi * 1.6 * t) - 20.0 * up, 0.0, 0.0)
    rot["LeftArm"] = (6.0, 0.0, 0.0)
    rot["Spine1"] = (6.0 * up, 0.0, 0.0)
    rot["Head"] = (0.0, 0.0, -10.0 * up)
    rot["LeftLeg"] = (0.0, 4.0, 0.0)
    rot["RightLeg"] = (0.0, 4.0, 0.0)
    root = (2.0 * math.sin(0.8 * t), 95.0 - 1.0, 0.0)
    return root, (0.0, 0.0, 0.0), rot


def reach(t):
    """Bends and reaches forward with the right hand, first high then low, stepping back upright."""
    a = smooth(t / 0.9) * (1.0 - smooth((t - 1.6) / 0.7))  # high reach
    b = smooth((t - 2.4) / 0.9) * (1.0 - smooth((t - 3.9) / 0.7))  # low reach
    rot = {}
    rot["RightArm"] = (0.0, -110.0 * a - 70.0 * b, 0.0)
    rot["RightForeArm"] = (0.0, -10.0 * a, 0.0)
    rot["LeftArm"] = (0.0, 10.0 * (a + b), 0.0)
    rot["Spine"] = (0.0, 8.0 * a + 25.0 * b, 0.0)
    rot["Spine1"] = (0.0, 6.0 * a + 20.0 * b, 0.0)
    rot["Head"] = (0.0, -10.0 * a - 20.0 * b, 0.0)
    knee = 35.0 * b
    for side in ("Left", "Right"):
        rot[side + "UpLeg"] = (0.0, -knee * 0.9, 0.0)
        rot[side + "Leg"] = (0.0, knee * 1.8, 0.0)
        rot[side + "Foot"] = (0.0, -knee * 0.9, 0.0)
    # the pelvis drops as the knees bend: two 42 cm segments at the bend angles above
    drop = 84.0 * (1.0 - math.cos(math.radians(knee * 0.9)))
    root = (0.0, 95.0 - drop, -6.0 * b)
    return root, (0.0, 0.0, 0.0), rot


def clip(fn, seconds):
    frames = []
    names = [name for name, _, _ in SKELETON]
    for k in range(int(seconds * FPS)):
        t = k / FPS
        (x, y, z), (rz, rx, ry), rot = fn(t)
        values = [x, y, z, ry, rx, rz]  # the root turns about Y outermost
        for name in names[1:]:
            values += list(rot.get(name, (0.0, 0.0, 0.0)))
        frames.append(" ".join(f"{v:.4f}" for v in values))
    # Joint Euler tuples are (Z, X, Y), the channel order hierarchy() writes.
    return hierarchy() + ["MOTION", f"Frames: {len(frames)}", f"Frame Time: {1.0 / FPS:.6f}"] + frames


def main():
    out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "assets", "motions")
    os.makedirs(out, exist_ok=True)
    for name, fn, seconds in (("walk", walk, 5.0), ("wave", wave, 4.0), ("reach", reach, 4.6)):
        path = os.path.join(out, f"{name}.bvh")
        with open(path, "w") as f:
            f.write("\n".join(clip(fn, seconds)) + "\n")
        print("wrote", os.path.normpath(path))


if __name__ == "__main__":
    main()
