"""Decoding of the rigcast stream (see protocol/PROTOCOL.md); no Blender imports.

Binary pose frame, little-endian::

    0  "RGCF"   4 u16 version  6 u16 flags  8 u32 subject  12 u32 num_bones
    16 u64 seq  24 u64 capture_nanos  32 u64 send_nanos  40 u32 missed_frames  44 u32 reserved
    48 root translation 3 x f32
    60 num_bones x (x, y, z, w) f32 local rotations (internal space: right-handed, +Y up, m)
"""

import struct

FRAME_MAGIC = b"RGCF"
FRAME_VERSION = 1
PROTOCOL_VERSION = 1
HEADER = struct.Struct("<4sHHIIQQQII3f")
HEADER_BYTES = HEADER.size  # 60


class FrameError(ValueError):
    """A binary frame that does not follow the layout; the frame is dropped and counted."""


class PoseFrame:
    """One decoded frame. ``rotations`` is a flat tuple of 4 * num_bones floats (x, y, z, w)."""

    __slots__ = (
        "subject",
        "num_bones",
        "seq",
        "capture_nanos",
        "send_nanos",
        "missed_frames",
        "flags",
        "root_translation",
        "rotations",
        "received_nanos",
    )

    def rotation(self, bone_index):
        i = 4 * bone_index
        return self.rotations[i : i + 4]


def decode_frame(data, received_nanos=0):
    if len(data) < HEADER_BYTES:
        raise FrameError("frame is %d bytes, header needs %d" % (len(data), HEADER_BYTES))
    (
        magic,
        version,
        flags,
        subject,
        num_bones,
        seq,
        capture_nanos,
        send_nanos,
        missed,
        _reserved,
        rx,
        ry,
        rz,
    ) = HEADER.unpack_from(data, 0)
    if magic != FRAME_MAGIC:
        raise FrameError("bad magic %r at offset 0, expected %r" % (magic, FRAME_MAGIC))
    if version != FRAME_VERSION:
        raise FrameError("unsupported frame version %d at offset 4, expected 1" % version)
    expected = HEADER_BYTES + 16 * num_bones
    if len(data) != expected:
        raise FrameError(
            "frame for %d bones is %d bytes, expected %d" % (num_bones, len(data), expected)
        )
    frame = PoseFrame()
    frame.subject = subject
    frame.num_bones = num_bones
    frame.seq = seq
    frame.capture_nanos = capture_nanos
    frame.send_nanos = send_nanos
    frame.missed_frames = missed
    frame.flags = flags
    frame.root_translation = (rx, ry, rz)
    frame.rotations = struct.unpack_from("<%df" % (4 * num_bones), data, HEADER_BYTES)
    frame.received_nanos = received_nanos
    return frame


def encode_frame(subject, seq, capture_nanos, root_translation, rotations, send_nanos=0, missed=0):
    """Builds a frame; used by tests and the development server, never per frame in Blender."""
    num_bones = len(rotations)
    out = bytearray(
        HEADER.pack(
            FRAME_MAGIC,
            FRAME_VERSION,
            0,
            subject,
            num_bones,
            seq,
            capture_nanos,
            send_nanos,
            missed,
            0,
            *root_translation,
        )
    )
    for q in rotations:
        out += struct.pack("<4f", *q)
    return bytes(out)
