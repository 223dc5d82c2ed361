"""Unit tests of the add-on's bpy-free modules: WebSocket client, session, wire, VMC, conversions.

Run inside Blender (what the test suite does):
    blender -b --factory-startup --python-exit-code 1 --python clients/blender/tests/run_unit_tests.py
or with any Python 3:  python3 -m unittest discover -s clients/blender/tests -p 'test_*.py'
"""

import base64
import hashlib
import json
import math
import os
import socket
import struct
import sys
import threading
import time
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from rigcast_livelink import convert, session, vmc, wire, wsclient  # noqa: E402

GUID = b"258EAFA5-E914-47DA-95CA-C5AB0DC85B11"


def server_frame(opcode, payload, fin=True):
    """A server->client frame (unmasked), written independently of the client's encoder."""
    n = len(payload)
    head = bytes([(0x80 if fin else 0) | opcode])
    if n < 126:
        head += bytes([n])
    elif n < 65536:
        head += bytes([126]) + struct.pack("!H", n)
    else:
        head += bytes([127]) + struct.pack("!Q", n)
    return head + payload


def read_client_frame(conn):
    """Reads one masked client frame: (opcode, unmasked payload)."""

    def take(n):
        data = b""
        while len(data) < n:
            chunk = conn.recv(n - len(data))
            if not chunk:
                raise EOFError
            data += chunk
        return data

    b0, b1 = take(2)
    assert b1 & 0x80, "client frames must be masked"
    n = b1 & 0x7F
    if n == 126:
        (n,) = struct.unpack("!H", take(2))
    elif n == 127:
        (n,) = struct.unpack("!Q", take(8))
    mask = take(4)
    payload = bytes(b ^ mask[i % 4] for i, b in enumerate(take(n)))
    return b0 & 0x0F, payload


class FakeServer:
    """One-connection-at-a-time WebSocket server; `script(conn)` runs per connection."""

    def __init__(self, script, port=0):
        self.sock = socket.socket()
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.bind(("127.0.0.1", port))
        self.sock.listen()
        self.port = self.sock.getsockname()[1]
        self.script = script
        self.received = []
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self):
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            request = b""
            while b"\r\n\r\n" not in request:
                request += conn.recv(4096)
            key = [
                line.split(b":", 1)[1].strip()
                for line in request.split(b"\r\n")
                if line.lower().startswith(b"sec-websocket-key")
            ][0]
            accept = base64.b64encode(hashlib.sha1(key + GUID).digest())
            conn.sendall(
                b"HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\n"
                b"Connection: Upgrade\r\nSec-WebSocket-Accept: " + accept + b"\r\n\r\n"
            )
            try:
                self.script(self, conn)
            except (OSError, EOFError):
                pass
            conn.close()

    def close(self):
        self.sock.close()


def wait_until(predicate, timeout_secs=5.0):
    deadline = time.monotonic() + timeout_secs
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.01)
    return False


class WebSocketClientTest(unittest.TestCase):
    def test_messages_fragments_ping_and_masked_send(self):
        big = os.urandom(70000)  # needs the 64-bit length form

        def script(server, conn):
            conn.sendall(server_frame(wsclient.OP_TEXT, b'{"type":"hello"}'))
            conn.sendall(server_frame(wsclient.OP_PING, b"p1"))
            # A binary message in two fragments, split across TCP writes mid-header.
            frame = server_frame(wsclient.OP_BINARY, b"abc", fin=False) + server_frame(wsclient.OP_CONT, b"def")
            conn.sendall(frame[:3])
            time.sleep(0.05)
            conn.sendall(frame[3:])
            conn.sendall(server_frame(wsclient.OP_BINARY, big))
            server.received.append(read_client_frame(conn))  # the pong
            server.received.append(read_client_frame(conn))  # the client's text
            conn.sendall(server_frame(wsclient.OP_CLOSE, struct.pack("!H", 1000)))
            time.sleep(0.1)

        server = FakeServer(script)
        ws = wsclient.connect("127.0.0.1", server.port)
        ws.settimeout(5.0)
        self.assertEqual(ws.recv_message(), (wsclient.OP_TEXT, '{"type":"hello"}'))
        self.assertEqual(ws.recv_message(), (wsclient.OP_BINARY, b"abcdef"))
        self.assertEqual(ws.recv_message(), (wsclient.OP_BINARY, big))
        ws.send_text('{"type":"ping","nonce":7}')
        with self.assertRaises(wsclient.WebSocketError):
            ws.recv_message()
        ws.close()
        server.close()
        self.assertEqual(server.received[0], (wsclient.OP_PONG, b"p1"))
        self.assertEqual(server.received[1], (wsclient.OP_TEXT, b'{"type":"ping","nonce":7}'))

    def test_timeout_mid_frame_loses_nothing(self):
        def script(server, conn):
            frame = server_frame(wsclient.OP_TEXT, b"x" * 300)
            conn.sendall(frame[:5])
            time.sleep(0.4)
            conn.sendall(frame[5:])
            time.sleep(0.2)

        server = FakeServer(script)
        ws = wsclient.connect("127.0.0.1", server.port)
        ws.settimeout(0.1)
        with self.assertRaises(socket.timeout):
            ws.recv_message()
        ws.settimeout(2.0)
        self.assertEqual(ws.recv_message(), (wsclient.OP_TEXT, "x" * 300))
        ws.close()
        server.close()

    def test_refused_handshake_is_an_error(self):
        listener = socket.socket()
        listener.bind(("127.0.0.1", 0))
        listener.listen()
        port = listener.getsockname()[1]

        def reply():
            conn, _ = listener.accept()
            conn.recv(4096)
            conn.sendall(b"HTTP/1.1 404 Not Found\r\nContent-Length: 0\r\n\r\n")
            conn.close()

        threading.Thread(target=reply, daemon=True).start()
        with self.assertRaises(wsclient.WebSocketError):
            wsclient.connect("127.0.0.1", port)
        listener.close()


def quat_axis_angle(axis, angle):
    s = math.sin(angle / 2)
    return (axis[0] * s, axis[1] * s, axis[2] * s, math.cos(angle / 2))


class SessionTest(unittest.TestCase):
    def test_newest_frame_wins_and_reconnects_after_server_loss(self):
        connections = []

        def script(server, conn):
            connections.append(conn)
            conn.sendall(server_frame(wsclient.OP_TEXT, json.dumps({"type": "hello", "subjects": []}).encode()))
            if len(connections) == 1:
                for seq in range(10):
                    rotations = [(0.0, 0.0, 0.0, 1.0)] * 2
                    conn.sendall(server_frame(wsclient.OP_BINARY, wire.encode_frame(3, seq, 1000 + seq, (0, 1, 0), rotations)))
                conn.sendall(server_frame(wsclient.OP_TEXT, b'{"type":"lagged","missed":4}'))
                time.sleep(0.3)
                return  # drop the connection: the server "goes away"
            time.sleep(1.0)

        server = FakeServer(script)
        stream = session.StreamSession("127.0.0.1:%d" % server.port)
        stream.start()
        try:
            self.assertTrue(wait_until(lambda: stream.num_frames_received == 10))
            frames = stream.take_frames()
            self.assertEqual(list(frames), [3])
            self.assertEqual(frames[3].seq, 9)
            self.assertEqual(stream.num_frames_skipped, 9)
            self.assertTrue(wait_until(lambda: stream.num_connects == 2))
            messages = [m["type"] for m in stream.take_messages()]
            self.assertEqual(messages, ["hello", "lagged", "_disconnected", "hello"])
            self.assertEqual(stream.num_frames_missed, 4)
            self.assertEqual(stream.state, "connected")
        finally:
            stream.stop()
            server.close()

    def test_unreachable_server_is_reported(self):
        probe = socket.socket()
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
        probe.close()  # nothing listens there now
        stream = session.StreamSession("127.0.0.1:%d" % port)
        stream.start()
        try:
            self.assertTrue(wait_until(lambda: "unreachable" in stream.state))
            self.assertIn("cannot connect", stream.error)
        finally:
            stream.stop()

    def test_parse_address(self):
        self.assertEqual(session.parse_address("127.0.0.1:8717"), ("127.0.0.1", 8717, "/v1/stream"))
        self.assertEqual(session.parse_address("ws://host:9/x/y"), ("host", 9, "/x/y"))
        self.assertEqual(session.parse_address("host"), ("host", 8717, "/v1/stream"))
        with self.assertRaises(ValueError):
            session.parse_address("host:notaport")
        with self.assertRaises(ValueError):
            session.parse_address("host:70000")


class WireTest(unittest.TestCase):
    def test_decode_matches_layout(self):
        # Built by hand from the documented layout, not by the encoder under test.
        data = b"RGCF" + struct.pack("<HHIIQQQII", 1, 0, 7, 1, 42, 123456789, 987654321, 3, 0)
        data += struct.pack("<3f", 0.5, 1.0, -2.0) + struct.pack("<4f", 0.0, 0.5, 0.0, 0.75)
        frame = wire.decode_frame(data)
        self.assertEqual((frame.subject, frame.num_bones, frame.seq), (7, 1, 42))
        self.assertEqual((frame.capture_nanos, frame.send_nanos, frame.missed_frames), (123456789, 987654321, 3))
        self.assertEqual(frame.root_translation, (0.5, 1.0, -2.0))
        self.assertEqual(frame.rotation(0), (0.0, 0.5, 0.0, 0.75))

    def test_decode_v2_matches_layout(self):
        # Version 2, by hand: 48-byte header (44: translation count), rotations, translations.
        data = b"RGCF" + struct.pack("<HHIIQQQII", 2, 0, 7, 2, 42, 1, 2, 0, 1)
        data += struct.pack("<4f", 0.0, 0.5, 0.0, 0.75) + struct.pack("<4f", 0.0, 0.0, 0.0, 1.0)
        data += struct.pack("<3f", 0.25, 0.9, -0.5)
        frame = wire.decode_frame(data)
        self.assertEqual((frame.version, frame.subject, frame.num_bones, frame.seq), (2, 7, 2, 42))
        self.assertEqual(frame.rotation(1), (0.0, 0.0, 0.0, 1.0))
        self.assertEqual(frame.translation(0), (0.25, 0.8999999761581421, -0.5))
        self.assertEqual(wire.encode_frame_v2(7, 42, 1, [(0, 0.5, 0, 0.75), (0, 0, 0, 1)], [(0.25, 0.9, -0.5)], 2), data)
        for bad in (data[:40], data + b"\0", data[:44] + struct.pack("<I", 2) + data[48:]):
            with self.assertRaises(wire.FrameError):
                wire.decode_frame(bad)
        nan = data[:-4] + struct.pack("<f", float("nan"))
        with self.assertRaises(wire.FrameError):
            wire.decode_frame(nan)

    def test_bad_frames_are_errors(self):
        good = wire.encode_frame(0, 1, 2, (0, 0, 0), [(0, 0, 0, 1)])
        for bad, words in (
            (good[:30], "header"),
            (b"XXXX" + good[4:], "magic"),
            (good[:4] + struct.pack("<H", 9) + good[6:], "version"),
            (good + b"\0", "expected"),
        ):
            with self.assertRaises(wire.FrameError) as caught:
                wire.decode_frame(bad)
            self.assertIn(words, str(caught.exception))


class ConvertTest(unittest.TestCase):
    def assertClose(self, a, b, tol=1e-6):
        self.assertTrue(all(abs(x - y) < tol for x, y in zip(a, b)), "%r != %r" % (a, b))

    def test_up_axis(self):
        # Ours +Y up is Blender +Z up; ours +Z (forward) is Blender -Y.
        self.assertClose(convert.position_ours_to_blender((0, 1, 0)), (0, 0, 1))
        self.assertClose(convert.position_ours_to_blender((0, 0, 1)), (0, -1, 0))
        # A turn about ours' up axis is a turn about Blender's up axis by the same angle.
        q = quat_axis_angle((0, 1, 0), 0.7)
        self.assertClose(convert.rotation_ours_to_blender(q), quat_axis_angle((0, 0, 1), 0.7))

    def test_rotation_conversion_agrees_with_position_conversion(self):
        q = quat_axis_angle((0.267, 0.535, 0.802), 1.1)
        v = (0.3, -0.2, 0.9)
        rotated_then_converted = convert.position_ours_to_blender(convert.qrotate(q, v))
        converted_then_rotated = convert.qrotate(convert.rotation_ours_to_blender(q), convert.position_ours_to_blender(v))
        self.assertClose(rotated_then_converted, converted_then_rotated)
        self.assertClose(convert.rotation_blender_to_ours(convert.rotation_ours_to_blender(q)), q)

    def test_unity_mirror(self):
        # Unity is ours mirrored in X (both face +Z): a rotation must commute with that mirror.
        self.assertEqual(convert.position_unity_to_ours((1.0, 2.0, 3.0)), (-1.0, 2.0, 3.0))
        q_unity = quat_axis_angle((0.6, 0.0, 0.8), 0.9)
        v_unity = (0.1, 0.7, 0.4)
        expected = convert.position_unity_to_ours(convert.qrotate(q_unity, v_unity))
        got = convert.qrotate(convert.rotation_unity_to_ours(q_unity), convert.position_unity_to_ours(v_unity))
        self.assertClose(expected, got)


class VmcTest(unittest.TestCase):
    def test_bundle_is_received_converted_and_bad_input_counted(self):
        receiver = vmc.VmcReceiver(0, host="127.0.0.1")
        port = receiver.sock.getsockname()[1]
        sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            q = quat_axis_angle((0.0, 1.0, 0.0), 0.5)
            bundle = vmc.encode_bundle(
                [
                    vmc.encode_message("/VMC/Ext/OK", [1]),
                    vmc.encode_message("/VMC/Ext/Root/Pos", ["root", 1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0]),
                    vmc.encode_message("/VMC/Ext/Bone/Pos", ["Hips", 0.0, 0.9, 0.1] + list(q)),
                    vmc.encode_message("/VMC/Ext/Bone/Pos", ["Spine", 0.0, 0.1]),  # too few: dropped
                ]
            )
            sender.sendto(bundle, ("127.0.0.1", port))
            sender.sendto(b"#bundle\0" + b"\0" * 8 + struct.pack(">i", 9999), ("127.0.0.1", port))
            self.assertTrue(wait_until(receiver.poll))
            wait_until(lambda: receiver.poll() or receiver.num_packets >= 2, 1.0)
            position, rotation = receiver.pose.bones["Hips"]
            self.assertEqual(position, (-0.0, 0.8999999761581421, 0.10000000149011612))
            expected = convert.rotation_unity_to_ours(q)
            self.assertTrue(all(abs(a - b) < 1e-6 for a, b in zip(rotation, expected)))
            self.assertEqual(receiver.pose.root[0], (-1.0, 2.0, 3.0))
            self.assertNotIn("Spine", receiver.pose.bones)
            self.assertEqual(receiver.num_dropped, 2)
        finally:
            sender.close()
            receiver.close()


if __name__ == "__main__":
    unittest.main()
