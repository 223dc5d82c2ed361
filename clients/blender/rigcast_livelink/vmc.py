"""VMC (OSC over UDP) receive, the alternative transport; no Blender imports.

A VMC Performer sends, per frame, `/VMC/Ext/Root/Pos` and one `/VMC/Ext/Bone/Pos` per bone
(Unity HumanBodyBones names, local pose in Unity coordinates: left-handed, +Y up). Unknown
addresses and extra arguments are ignored; messages with too few or mistyped arguments are
dropped and counted, as the VMC spec asks of receivers.
"""

import socket
import struct
import time

from . import convert


class OscError(ValueError):
    """A malformed OSC packet."""


def _read_string(data, pos):
    end = data.find(b"\0", pos)
    if end < 0:
        raise OscError("unterminated string at offset %d" % pos)
    text = data[pos:end].decode("utf-8", "replace")
    # Strings are padded with NULs to a multiple of 4 bytes, counting the terminator.
    return text, (end + 4) & ~3


def parse_message(data):
    """Returns (address, [args]) of one OSC message."""
    address, pos = _read_string(data, 0)
    if not address.startswith("/"):
        raise OscError("address %r does not start with '/'" % address)
    if pos >= len(data):
        return address, []
    tags, pos = _read_string(data, pos)
    if not tags.startswith(","):
        raise OscError("type tag string %r does not start with ','" % tags)
    args = []
    for tag in tags[1:]:
        if tag == "f":
            if pos + 4 > len(data):
                raise OscError("float argument past end at offset %d" % pos)
            args.append(struct.unpack_from(">f", data, pos)[0])
            pos += 4
        elif tag == "i":
            if pos + 4 > len(data):
                raise OscError("int argument past end at offset %d" % pos)
            args.append(struct.unpack_from(">i", data, pos)[0])
            pos += 4
        elif tag == "s":
            text, pos = _read_string(data, pos)
            args.append(text)
        elif tag == "T":
            args.append(True)
        elif tag == "F":
            args.append(False)
        else:
            # Unknown types have unknown sizes: keep what we parsed so far.
            break
    return address, args


def iter_messages(data):
    """Yields (address, args) for a message or every message of a (nested) bundle."""
    if data.startswith(b"#bundle\0"):
        pos = 16  # "#bundle\0" + 8-byte time tag
        while pos + 4 <= len(data):
            (size,) = struct.unpack_from(">i", data, pos)
            pos += 4
            if size <= 0 or pos + size > len(data):
                raise OscError("bundle element size %d at offset %d overruns packet" % (size, pos - 4))
            yield from iter_messages(data[pos : pos + size])
            pos += size
    else:
        yield parse_message(data)


def _pack_string(text):
    raw = text.encode("utf-8") + b"\0"
    return raw + b"\0" * ((4 - len(raw) % 4) % 4)


def encode_message(address, args):
    """Builds an OSC message (tests and the development sender only)."""
    tags = ","
    payload = b""
    for arg in args:
        if isinstance(arg, float):
            tags += "f"
            payload += struct.pack(">f", arg)
        elif isinstance(arg, int):
            tags += "i"
            payload += struct.pack(">i", arg)
        else:
            tags += "s"
            payload += _pack_string(str(arg))
    return _pack_string(address) + _pack_string(tags) + payload


def encode_bundle(messages):
    out = b"#bundle\0" + struct.pack(">Q", 1)
    for message in messages:
        out += struct.pack(">i", len(message)) + message
    return out


class VmcPose:
    """The latest VMC pose, converted to our space: bone name -> (position, rotation)."""

    def __init__(self):
        self.bones = {}
        self.root = None
        self.seq = 0
        self.received_nanos = 0


class VmcReceiver:
    """Non-blocking UDP receiver; `poll()` drains every pending packet and keeps the newest values."""

    def __init__(self, port, host="0.0.0.0"):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.bind((host, port))
        self.sock.setblocking(False)
        self.pose = VmcPose()
        self.num_packets = 0
        self.num_dropped = 0

    def poll(self):
        """Returns True if at least one bone or root update arrived since the last poll."""
        updated = False
        while True:
            try:
                data = self.sock.recv(65536)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:
                break
            self.num_packets += 1
            try:
                for address, args in iter_messages(data):
                    if self._handle(address, args):
                        updated = True
            except OscError:
                self.num_dropped += 1
        if updated:
            self.pose.seq += 1
            self.pose.received_nanos = time.time_ns()
        return updated

    def _handle(self, address, args):
        if address not in ("/VMC/Ext/Bone/Pos", "/VMC/Ext/Root/Pos"):
            return False
        if len(args) < 8 or not isinstance(args[0], str) or not all(
            isinstance(a, float) for a in args[1:8]
        ):
            self.num_dropped += 1
            return False
        position = convert.position_unity_to_ours(args[1:4])
        rotation = convert.rotation_unity_to_ours(args[4:8])
        if address == "/VMC/Ext/Root/Pos":
            self.pose.root = (position, rotation)
        else:
            self.pose.bones[args[0]] = (position, rotation)
        return True

    def close(self):
        self.sock.close()
