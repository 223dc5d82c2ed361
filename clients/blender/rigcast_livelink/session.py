"""The connection to a rigcast server, run on a background thread; no Blender imports.

The reader thread owns the socket and never touches Blender data. It decodes every message
and keeps, per subject, only the NEWEST pose frame; the Blender timer calls
:meth:`StreamSession.take_frames` once per display tick and applies what it gets. So a sender
faster than the display never builds a backlog: older frames are counted as skipped, not
queued. Control messages (hello, skeleton, mapping, ...) go to a small queue that the timer
drains on the main thread. When the server goes away the thread reports it and reconnects
with a capped back-off until :meth:`stop` is called.
"""

import collections
import json
import socket
import threading
import time

from . import wire
from . import wsclient

DEFAULT_ADDRESS = "127.0.0.1:8717"


def parse_address(address):
    """'host:port' (or 'ws://host:port/...') -> (host, port, path)."""
    text = address.strip()
    path = "/v1/stream"
    if "://" in text:
        text = text.split("://", 1)[1]
    if "/" in text:
        text, rest = text.split("/", 1)
        if rest:
            path = "/" + rest
    host, sep, port_text = text.rpartition(":")
    if not sep:
        host, port_text = text, "8717"
    host = host.strip("[]") or "127.0.0.1"
    try:
        port = int(port_text)
    except ValueError:
        raise ValueError("port %r in address %r is not a number" % (port_text, address))
    if not 0 < port < 65536:
        raise ValueError("port %d out of range in %r" % (port, address))
    return host, port, path


class StreamSession:
    """One server connection with auto-reconnect. Thread-safe accessors for the main thread."""

    def __init__(self, address, auto_reconnect=True, token=""):
        self.host, self.port, self.path = parse_address(address)
        self.auto_reconnect = auto_reconnect
        # The server's control token ("" = read-only: frames and mappings, no overrides).
        self.token = token
        self._lock = threading.Lock()
        self._latest = {}
        self._messages = collections.deque(maxlen=1024)
        self._stop = threading.Event()
        self._ws = None
        self._thread = None
        # Status, written by the reader thread, read by the UI.
        self.state = "idle"
        self.error = ""
        self.connected = False
        self.num_frames_received = 0
        self.num_frames_skipped = 0  # replaced by a newer frame before the display took it
        self.num_frames_missed = 0  # reported by the server (frame header + "lagged")
        self.num_bad_frames = 0
        self.num_connects = 0

    # -- main-thread API -------------------------------------------------------------------

    def start(self):
        self._thread = threading.Thread(target=self._run, name="rigcast-stream", daemon=True)
        self._thread.start()

    def stop(self):
        self._stop.set()
        ws = self._ws
        if ws is not None:
            ws.close()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        self.connected = False
        self.state = "disconnected"

    def take_frames(self):
        """Returns {subject: newest PoseFrame} received since the last call."""
        with self._lock:
            frames = self._latest
            self._latest = {}
        return frames

    def take_messages(self):
        """Returns the JSON control messages (dicts) received since the last call, in order."""
        with self._lock:
            messages = list(self._messages)
            self._messages.clear()
        return messages

    def send(self, message):
        """Sends a JSON message; returns False when not connected (the caller tells the user)."""
        ws = self._ws
        if ws is None or not self.connected:
            return False
        try:
            ws.send_text(json.dumps(message))
            return True
        except OSError:
            return False

    # -- reader thread ---------------------------------------------------------------------

    def _negotiate(self, ws, hello):
        """Asks for version 2 frames (every moving bone's translation, not only bone 0's) when
        the server offers them; an older server keeps sending version 1, which also decodes."""
        offered = hello.get("protocol_versions") or [1]
        if wire.WANTED_PROTOCOL_VERSION in offered:
            try:
                ws.send_text(
                    json.dumps({"type": "set_protocol", "version": wire.WANTED_PROTOCOL_VERSION})
                )
            except OSError:
                pass

    def _run(self):
        backoff_secs = 0.25
        while not self._stop.is_set():
            self.state = "connecting to %s:%d" % (self.host, self.port)
            try:
                ws = wsclient.connect(
                    self.host, self.port, self.path, timeout_secs=2.0, token=self.token
                )
            except (OSError, wsclient.WebSocketError) as exc:
                self.connected = False
                self.error = "cannot connect to %s:%d: %s" % (self.host, self.port, exc)
                self.state = "server unreachable, retrying"
                if not self.auto_reconnect:
                    self.state = "server unreachable"
                    return
                self._stop.wait(backoff_secs)
                backoff_secs = min(backoff_secs * 2.0, 2.0)
                continue
            backoff_secs = 0.25
            self._ws = ws
            self.connected = True
            self.num_connects += 1
            self.error = ""
            self.state = "connected"
            try:
                self._read_loop(ws)
            except (OSError, wsclient.WebSocketError) as exc:
                if not self._stop.is_set():
                    self.error = "connection lost: %s" % exc
            finally:
                self.connected = False
                self._ws = None
                ws.close()
            if self._stop.is_set():
                break
            with self._lock:
                self._messages.append({"type": "_disconnected", "reason": self.error})
            if not self.auto_reconnect:
                self.state = "disconnected: %s" % self.error
                return
            self.state = "server went away, reconnecting"
            self._stop.wait(backoff_secs)
        self.state = "disconnected"

    def _read_loop(self, ws):
        # A short timeout lets the thread notice stop() promptly.
        ws.settimeout(0.5)
        while not self._stop.is_set():
            try:
                opcode, payload = ws.recv_message()
            except socket.timeout:
                continue
            now_nanos = time.time_ns()
            if opcode == wsclient.OP_BINARY:
                try:
                    frame = wire.decode_frame(payload, now_nanos)
                except wire.FrameError as exc:
                    self.num_bad_frames += 1
                    self.error = "bad frame dropped: %s" % exc
                    continue
                with self._lock:
                    if frame.subject in self._latest:
                        self.num_frames_skipped += 1
                    self._latest[frame.subject] = frame
                    self.num_frames_received += 1
                    self.num_frames_missed += frame.missed_frames
            else:
                try:
                    message = json.loads(payload)
                except ValueError:
                    self.num_bad_frames += 1
                    continue
                if not isinstance(message, dict):
                    continue
                if message.get("type") == "hello":
                    self._negotiate(ws, message)
                if message.get("type") == "lagged":
                    missed = message.get("missed", 0)
                    if isinstance(missed, int):
                        self.num_frames_missed += missed
                with self._lock:
                    self._messages.append(message)
