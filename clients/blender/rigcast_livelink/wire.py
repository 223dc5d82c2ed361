"""Decoding of the rigcast stream (see protocol/PROTOCOL.md); no Blender imports.

Binary pose frame, little-endian. Both versions share the first 44 bytes::

    0  "RGCF"   4 u16 version  6 u16 flags  8 u32 subject  12 u32 num_bones
    16 u64 seq  24 u64 capture_nanos  32 u64 send_nanos  40 u32 missed_frames

Version 1::

    44 u32 reserved  48 bone 0 translation 3 x f32
    60 num_bones x (x, y, z, w) f32 local rotations (internal space: right-handed, +Y up, m)

Version 2 (asked for with ``{"type": "set_protocol", "version": 2}``)::

    44 u32 num_translations (m)
    48 num_bones x (x, y, z, w) f32 local rotations
    48 + 16 n: m x (x, y, z) f32 local translations of the bones the skeleton message marks
    ``translated``, in bone order
"""

import struct

FRAME_MAGIC = b"RGCF"
FRAME_VERSION = 1
FRAME_VERSION_2 = 2
PROTOCOL_VERSION = 1
# The version the add-on asks for when the server offers it.
WANTED_PROTOCOL_VERSION = 2
HEADER = struct.Struct("<4sHHIIQQQII3f")
HEADER_BYTES = HEADER.size  # 60
COMMON = struct.Struct("<4sHHIIQQQII")
V2_HEADER_BYTES = COMMON.size  # 48


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
        "translations",
        "version",
        "received_nanos",
    )

    def rotation(self, bone_index):
        i = 4 * bone_index
        return self.rotations[i : i + 4]

    def translation(self, k):
        """The k-th carried translation (version 1: k = 0 is bone 0's)."""
        i = 3 * k
        return self.translations[i : i + 3]


def _check_finite(values, what):
    for v in values:
        if v != v or v in (float("inf"), float("-inf")):
            raise FrameError("non-finite %s value %r" % (what, v))


def decode_frame(data, received_nanos=0):
    """Decodes a version 1 or version 2 frame."""
    if len(data) >= 6 and data[:4] == FRAME_MAGIC and struct.unpack_from("<H", data, 4)[0] == 2:
        return _decode_v2(data, received_nanos)
    return _decode_v1(data, received_nanos)


def _decode_v2(data, received_nanos):
    if len(data) < V2_HEADER_BYTES:
        raise FrameError("frame is %d bytes, header needs %d" % (len(data), V2_HEADER_BYTES))
    (_, version, flags, subject, num_bones, seq, capture_nanos, send_nanos, missed, num_t) = (
        COMMON.unpack_from(data, 0)
    )
    expected = V2_HEADER_BYTES + 16 * num_bones + 12 * num_t
    if len(data) != expected:
        raise FrameError(
            "v2 frame for %d bones and %d translations is %d bytes, expected %d"
            % (num_bones, num_t, len(data), expected)
        )
    frame = _header_frame(version, flags, subject, num_bones, seq, capture_nanos, send_nanos, missed)
    frame.rotations = struct.unpack_from("<%df" % (4 * num_bones), data, V2_HEADER_BYTES)
    frame.translations = struct.unpack_from(
        "<%df" % (3 * num_t), data, V2_HEADER_BYTES + 16 * num_bones
    )
    _check_finite(frame.rotations, "rotation")
    _check_finite(frame.translations, "translation")
    frame.root_translation = tuple(frame.translations[0:3]) if num_t else (0.0, 0.0, 0.0)
    frame.received_nanos = received_nanos
    return frame


def _header_frame(version, flags, subject, num_bones, seq, capture_nanos, send_nanos, missed):
    """A PoseFrame holding the header fields both versions share."""
    frame = PoseFrame()
    frame.version = version
    frame.subject = subject
    frame.num_bones = num_bones
    frame.seq = seq
    frame.capture_nanos = capture_nanos
    frame.send_nanos = send_nanos
    frame.missed_frames = missed
    frame.flags = flags
    return frame


def _decode_v1(data, received_nanos):
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
        raise FrameError("unsupported frame version %d at offset 4, expected 1 or 2" % version)
    expected = HEADER_BYTES + 16 * num_bones
    if len(data) != expected:
        raise FrameError(
            "frame for %d bones is %d bytes, expected %d" % (num_bones, len(data), expected)
        )
    frame = _header_frame(version, flags, subject, num_bones, seq, capture_nanos, send_nanos, missed)
    frame.root_translation = (rx, ry, rz)
    frame.translations = (rx, ry, rz)
    frame.rotations = struct.unpack_from("<%df" % (4 * num_bones), data, HEADER_BYTES)
    frame.received_nanos = received_nanos
    return frame


def encode_frame(subject, seq, capture_nanos, root_translation, rotations, send_nanos=0, missed=0):
    """Builds a frame; used by tests and the development server, never per frame in Blender."""
    num_bones = len(rotations)
    fields = (FRAME_MAGIC, FRAME_VERSION, 0, subject, num_bones, seq, capture_nanos, send_nanos, missed, 0)
    out = bytearray(HEADER.pack(*fields, *root_translation))
    for q in rotations:
        out += struct.pack("<4f", *q)
    return bytes(out)


def encode_frame_v2(subject, seq, capture_nanos, rotations, translations, send_nanos=0, missed=0):
    """Builds a version 2 frame (``translations``: the marked bones' (x, y, z), in bone order);
    used by tests, never per frame in Blender."""
    fields = (FRAME_MAGIC, FRAME_VERSION_2, 0, subject, len(rotations), seq, capture_nanos)
    out = bytearray(COMMON.pack(*fields, send_nanos, missed, len(translations)))
    for q in rotations:
        out += struct.pack("<4f", *q)
    for t in translations:
        out += struct.pack("<3f", *t)
    return bytes(out)
