"""Coordinate conversions at the Blender and VMC edges, on plain tuples (no Blender imports).

Internal space (ours): right-handed, +Y up, metres. Blender: right-handed, +Z up.
ours -> Blender is a +90 degree rotation about X: (x, y, z) -> (x, -z, y). A rotation
q in ours becomes C q C^-1 in Blender, with C that same +90 degree X rotation.
Unity/VMC: left-handed, +Y up, +Z forward like ours (avatars face +Z in both), so the two
differ by a mirror of X: position (-x, y, z), quaternion (x, -y, -z, w) to ours.
Quaternions here are (x, y, z, w) tuples, as on the wire; mathutils uses (w, x, y, z).
"""

import math

_H = math.sqrt(0.5)
# +90 degrees about X, (x, y, z, w)
C_OURS_TO_BLENDER = (_H, 0.0, 0.0, _H)


def qmul(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


def qconj(q):
    return (-q[0], -q[1], -q[2], q[3])


def qrotate(q, v):
    p = qmul(qmul(q, (v[0], v[1], v[2], 0.0)), qconj(q))
    return (p[0], p[1], p[2])


def position_ours_to_blender(p):
    return (p[0], -p[2], p[1])


def position_blender_to_ours(p):
    return (p[0], p[2], -p[1])


def rotation_ours_to_blender(q):
    return qmul(qmul(C_OURS_TO_BLENDER, q), qconj(C_OURS_TO_BLENDER))


def rotation_blender_to_ours(q):
    return qmul(qmul(qconj(C_OURS_TO_BLENDER), q), C_OURS_TO_BLENDER)


def position_unity_to_ours(p):
    return (-p[0], p[1], p[2])


def rotation_unity_to_ours(q):
    return (q[0], -q[1], -q[2], q[3])
