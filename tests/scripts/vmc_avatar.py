"""An independent VMC Marionette: python-osc decodes what rigcast sends, and the local rotations
are applied, as VMC receivers do, straight onto a +Z-facing Unity humanoid in T-pose (identity
rest rotations, left side at -X, the VRM-normalised rest VMC rotations are relative to).

    python vmc_avatar.py SECONDS

Prints "PORT <n>" once listening on 127.0.0.1, then after SECONDS one JSON line with per-tick
measurements of the avatar (Unity coordinates, metres, degrees). Nothing here comes from
rigcast: the decoder is python-osc, the skeleton and forward kinematics are written below.
"""

import json
import math
import socket
import sys
import time

from pythonosc.osc_packet import OscPacket

# HumanBodyBones: (parent, rest offset from the parent in Unity coordinates). A +Z-facing
# avatar: forward +Z, up +Y, its right at +X, so its left limbs are at -X.
AVATAR = {
    "Hips": (None, (0.0, 0.95, 0.0)),
    "Spine": ("Hips", (0.0, 0.10, 0.0)),
    "Chest": ("Spine", (0.0, 0.12, 0.0)),
    "UpperChest": ("Chest", (0.0, 0.12, 0.0)),
    "Neck": ("UpperChest", (0.0, 0.14, 0.0)),
    "Head": ("Neck", (0.0, 0.10, 0.0)),
    "LeftShoulder": ("UpperChest", (-0.02, 0.10, 0.0)),
    "LeftUpperArm": ("LeftShoulder", (-0.10, 0.0, 0.0)),
    "LeftLowerArm": ("LeftUpperArm", (-0.27, 0.0, 0.0)),
    "LeftHand": ("LeftLowerArm", (-0.25, 0.0, 0.0)),
    "RightShoulder": ("UpperChest", (0.02, 0.10, 0.0)),
    "RightUpperArm": ("RightShoulder", (0.10, 0.0, 0.0)),
    "RightLowerArm": ("RightUpperArm", (0.27, 0.0, 0.0)),
    "RightHand": ("RightLowerArm", (0.25, 0.0, 0.0)),
    "LeftUpperLeg": ("Hips", (-0.09, -0.05, 0.0)),
    "LeftLowerLeg": ("LeftUpperLeg", (0.0, -0.42, 0.0)),
    "LeftFoot": ("LeftLowerLeg", (0.0, -0.42, 0.0)),
    "LeftToes": ("LeftFoot", (0.0, -0.06, 0.12)),
    "RightUpperLeg": ("Hips", (0.09, -0.05, 0.0)),
    "RightLowerLeg": ("RightUpperLeg", (0.0, -0.42, 0.0)),
    "RightFoot": ("RightLowerLeg", (0.0, -0.42, 0.0)),
    "RightToes": ("RightFoot", (0.0, -0.06, 0.12)),
}
ORDER = list(AVATAR)  # parents before children


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def qmul(a, b):
    """Hamilton product in vector form: (wa vb + wb va + va x vb, wa wb - va . vb)."""
    va, wa, vb, wb = a[:3], a[3], b[:3], b[3]
    v = add(add(tuple(wa * c for c in vb), tuple(wb * c for c in va)), cross(va, vb))
    return v + (wa * wb - dot(va, vb),)


def rotate(q, v):
    # Unity's Quaternion * Vector3 is the same formula: q v q*.
    x, y, z, w = q
    p = qmul(qmul(q, (v[0], v[1], v[2], 0.0)), (-x, -y, -z, w))
    return p[:3]


def sub(a, b):
    return tuple(x - y for x, y in zip(a, b))


def add(a, b):
    return tuple(x + y for x, y in zip(a, b))


def dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def norm(a):
    n = math.sqrt(dot(a, a))
    return tuple(x / n for x in a) if n > 0 else a


def angle_deg(a, b):
    c = max(-1.0, min(1.0, dot(norm(a), norm(b))))
    return math.degrees(math.acos(c))


def pose_avatar(bones):
    """World (rotation, position) of every avatar bone from the received local transforms."""
    world = {}
    for name in ORDER:
        parent, offset = AVATAR[name]
        position, rotation = bones.get(name, (None, (0.0, 0.0, 0.0, 1.0)))
        if parent is None:
            # The root's Bone/Pos is its placement (Root/Pos stays at the origin).
            world[name] = (rotation, position if position is not None else offset)
        else:
            pr, pp = world[parent]
            world[name] = (qmul(pr, rotation), add(pp, rotate(pr, offset)))
    return world


def measure(world):
    hips_rotation, hips = world["Hips"]
    forward = rotate(hips_rotation, (0.0, 0.0, 1.0))
    right = rotate(hips_rotation, (1.0, 0.0, 0.0))
    horizontal = norm((forward[0], 0.0, forward[2]))
    out = {"hips_y": hips[1], "facing": [forward[0], forward[2]]}

    def limb(a, b, c):
        p0, p1, p2 = world[a][1], world[b][1], world[c][1]
        d1, d2 = sub(p1, p0), sub(p2, p1)
        flex = angle_deg(d1, d2)
        # Where the distal segment turns, along the avatar's own forward direction.
        along = dot(sub(norm(d2), norm(d1)), horizontal)
        return flex, along

    for side in ("Left", "Right"):
        out[side + "Knee"] = limb(side + "UpperLeg", side + "LowerLeg", side + "Foot")
        out[side + "Elbow"] = limb(side + "UpperArm", side + "LowerArm", side + "Hand")
        out[side + "FootSide"] = dot(sub(world[side + "Foot"][1], hips), right)
    return out


def main():
    seconds = float(sys.argv[1])
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(0.2)
    print("PORT %d" % sock.getsockname()[1], flush=True)
    ticks = []
    bones = None
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        try:
            data = sock.recv(65536)
        except socket.timeout:
            continue
        for timed in OscPacket(data).messages:
            m = timed.message
            if m.address == "/VMC/Ext/T":
                # A new tick begins: the previous one is complete.
                if bones:
                    ticks.append(measure(pose_avatar(bones)))
                bones = {}
            elif m.address == "/VMC/Ext/Bone/Pos" and bones is not None and len(m.params) >= 8:
                name = m.params[0]
                position = tuple(float(v) for v in m.params[1:4])
                rotation = tuple(float(v) for v in m.params[4:8])
                bones[name] = (position, rotation)
    print(json.dumps({"ticks": ticks}), flush=True)


if __name__ == "__main__":
    main()
