"""A minimal WebSocket client (RFC 6455) on the Python standard library.

Why our own: Blender ships its own Python and users cannot be expected to install
`websocket-client` into it. We only need what the rigcast stream uses: one client
connection, text and binary messages, ping/pong and close. Client frames are masked as
the RFC requires; server frames are not.

The socket is used from one reader thread (``recv_message``) while another thread may
``send_text``; sends are serialised with a lock.
"""

import base64
import hashlib
import os
import socket
import struct
import threading

_GUID = "258EAFA5-E914-47DA-95CA-C5AB0DC85B11"

OP_CONT = 0x0
OP_TEXT = 0x1
OP_BINARY = 0x2
OP_CLOSE = 0x8
OP_PING = 0x9
OP_PONG = 0xA

# Refuse absurd frames instead of trying to allocate them (a bad peer must not exhaust memory).
MAX_MESSAGE_BYTES = 16 * 1024 * 1024


class WebSocketError(Exception):
    """The connection failed, closed, or the peer broke the protocol."""


class WebSocket:
    """One client connection. Create with :func:`connect`."""

    def __init__(self, sock):
        self._sock = sock
        self._buf = bytearray()
        self._send_lock = threading.Lock()
        self.closed = False
        # Fragments of a message in progress survive a timeout between frames.
        self._parts = []
        self._message_opcode = None

    # -- receiving -----------------------------------------------------------------------

    def _parse_frame(self):
        """Parses one frame from the buffer, or returns None if it is incomplete.

        Nothing is consumed until the whole frame is present, so a socket timeout while
        waiting for more bytes never loses data.
        """
        buf = self._buf
        if len(buf) < 2:
            return None
        b0, b1 = buf[0], buf[1]
        length = b1 & 0x7F
        pos = 2
        if length == 126:
            if len(buf) < 4:
                return None
            (length,) = struct.unpack_from("!H", buf, 2)
            pos = 4
        elif length == 127:
            if len(buf) < 10:
                return None
            (length,) = struct.unpack_from("!Q", buf, 2)
            pos = 10
        if length > MAX_MESSAGE_BYTES:
            raise WebSocketError("frame of %d bytes exceeds limit" % length)
        mask = None
        if b1 & 0x80:
            if len(buf) < pos + 4:
                return None
            mask = bytes(buf[pos : pos + 4])
            pos += 4
        if len(buf) < pos + length:
            return None
        payload = bytes(buf[pos : pos + length])
        del buf[: pos + length]
        if mask:
            payload = _apply_mask(payload, mask)
        return bool(b0 & 0x80), b0 & 0x0F, payload

    def _read_frame(self):
        while True:
            frame = self._parse_frame()
            if frame is not None:
                return frame
            chunk = self._sock.recv(65536)
            if not chunk:
                self.closed = True
                raise WebSocketError("server closed the connection")
            self._buf += chunk

    def recv_message(self):
        """Blocks (subject to the socket timeout) until one whole message arrives.

        Returns ``(opcode, payload)`` with opcode OP_TEXT (payload str) or OP_BINARY (bytes).
        Control frames are handled here: pings are answered, a close raises.
        A socket timeout propagates as ``socket.timeout``; buffered bytes are kept.
        """
        while True:
            fin, opcode, payload = self._read_frame()
            if opcode == OP_PING:
                self._send_frame(OP_PONG, payload)
                continue
            if opcode == OP_PONG:
                continue
            if opcode == OP_CLOSE:
                self.closed = True
                code = struct.unpack("!H", payload[:2])[0] if len(payload) >= 2 else 1005
                try:
                    self._send_frame(OP_CLOSE, payload[:2])
                except OSError:
                    pass
                raise WebSocketError("server closed the stream (code %d)" % code)
            if opcode in (OP_TEXT, OP_BINARY):
                self._message_opcode = opcode
                self._parts = [payload]
            elif opcode == OP_CONT and self._message_opcode is not None:
                self._parts.append(payload)
            else:
                raise WebSocketError("unexpected opcode %d" % opcode)
            if fin:
                data = b"".join(self._parts)
                message_opcode = self._message_opcode
                self._parts = []
                self._message_opcode = None
                if message_opcode == OP_TEXT:
                    return OP_TEXT, data.decode("utf-8")
                return OP_BINARY, data

    # -- sending -------------------------------------------------------------------------

    def _send_frame(self, opcode, payload):
        header = bytearray([0x80 | opcode])
        length = len(payload)
        if length < 126:
            header.append(0x80 | length)
        elif length < 65536:
            header.append(0x80 | 126)
            header += struct.pack("!H", length)
        else:
            header.append(0x80 | 127)
            header += struct.pack("!Q", length)
        mask = os.urandom(4)
        frame = bytes(header) + mask + _apply_mask(payload, mask)
        with self._send_lock:
            self._sock.sendall(frame)

    def send_text(self, text):
        self._send_frame(OP_TEXT, text.encode("utf-8"))

    def send_binary(self, data):
        self._send_frame(OP_BINARY, bytes(data))

    def settimeout(self, seconds):
        self._sock.settimeout(seconds)

    def close(self):
        if not self.closed:
            self.closed = True
            try:
                self._send_frame(OP_CLOSE, struct.pack("!H", 1000))
            except OSError:
                pass
        try:
            self._sock.close()
        except OSError:
            pass


def _apply_mask(payload, mask):
    # XOR through big integers: far faster in pure Python than a per-byte loop.
    if not payload:
        return b""
    n = len(payload)
    repeated = (mask * (n // 4 + 1))[:n]
    return (int.from_bytes(payload, "little") ^ int.from_bytes(repeated, "little")).to_bytes(
        n, "little"
    )


def connect(host, port, path="/v1/stream", timeout_secs=3.0, token=""):
    """Opens a TCP connection and performs the HTTP upgrade handshake.

    A non-empty ``token`` (the server's control token) goes out as an
    ``Authorization: Bearer`` header: needed to change the server (mapping overrides), and to
    connect at all to a server listening beyond loopback.
    """
    if any(c in token for c in "\r\n"):
        raise WebSocketError("the token must be a single line")
    sock = socket.create_connection((host, port), timeout=timeout_secs)
    try:
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        key = base64.b64encode(os.urandom(16)).decode("ascii")
        authorization = "Authorization: Bearer %s\r\n" % token if token else ""
        request = (
            "GET %s HTTP/1.1\r\n"
            "Host: %s:%d\r\n"
            "Upgrade: websocket\r\n"
            "Connection: Upgrade\r\n"
            "Sec-WebSocket-Key: %s\r\n"
            "Sec-WebSocket-Version: 13\r\n"
            "User-Agent: rigcast-livelink\r\n"
            "%s"
            "\r\n" % (path, host, port, key, authorization)
        )
        sock.sendall(request.encode("ascii"))
        response = bytearray()
        while b"\r\n\r\n" not in response:
            chunk = sock.recv(4096)
            if not chunk:
                raise WebSocketError("connection closed during handshake")
            response += chunk
            if len(response) > 65536:
                raise WebSocketError("handshake response too long")
        head, _, rest = bytes(response).partition(b"\r\n\r\n")
        lines = head.decode("latin-1").split("\r\n")
        status = lines[0].split(" ", 2)
        if len(status) < 2 or status[1] != "101":
            raise WebSocketError("handshake refused: %s" % lines[0])
        headers = {}
        for line in lines[1:]:
            name, _, value = line.partition(":")
            headers[name.strip().lower()] = value.strip()
        expected = base64.b64encode(
            hashlib.sha1((key + _GUID).encode("ascii")).digest()
        ).decode("ascii")
        if headers.get("sec-websocket-accept") != expected:
            raise WebSocketError("handshake: bad Sec-WebSocket-Accept")
        ws = WebSocket(sock)
        ws._buf += rest
        return ws
    except BaseException:
        sock.close()
        raise
