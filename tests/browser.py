"""Headless Chromium for the browser tests: a small DevTools-protocol client and the start/stop of
the browser around it.

Chromium (Debian's ``chromium`` package, ``/usr/bin/chromium``, or ``POSE_UNCERTAINTY_CHROMIUM``) is
driven over the Chrome DevTools Protocol with a WebSocket client written on the standard library
(:class:`CDP`). :func:`open_chromium` starts it on a free loopback port with its own profile,
waits for its page target, yields the client and always stops the browser, whatever the test did.
The session fixture ``chromium`` (``tests/conftest.py``) fails with instructions, not a skip, where
the binary is missing.
"""

from __future__ import annotations

import base64
import contextlib
import json
import os
import socket
import struct
import subprocess
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

CHROMIUM = os.environ.get("POSE_UNCERTAINTY_CHROMIUM", "/usr/bin/chromium")
FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-dev-shm-usage",
    "--hide-scrollbars",
    "--window-size=1400,1000",
]


class CDP:
    """A minimal Chrome DevTools Protocol client over one WebSocket (RFC 6455, client side)."""

    def __init__(self, ws_url: str, timeout: float = 30.0) -> None:
        assert ws_url.startswith("ws://"), ws_url
        hostport, _, path = ws_url[5:].partition("/")
        host, _, port = hostport.partition(":")
        self.sock = socket.create_connection((host, int(port)), timeout=timeout)
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall(
            (
                f"GET /{path} HTTP/1.1\r\nHost: {hostport}\r\nUpgrade: websocket\r\n"
                f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n"
            ).encode()
        )
        head = b""
        while b"\r\n\r\n" not in head:
            chunk = self.sock.recv(4096)
            if not chunk:
                raise ConnectionError("DevTools closed the connection during the handshake")
            head += chunk
        status = head.split(b"\r\n", 1)[0]
        assert b" 101 " in status, f"WebSocket handshake failed: {status!r}"
        self.buf = head.split(b"\r\n\r\n", 1)[1]
        self.next_id = 0
        self.events: list[dict[str, Any]] = []

    def _recv_exact(self, n: int) -> bytes:
        while len(self.buf) < n:
            chunk = self.sock.recv(1 << 20)
            if not chunk:
                raise ConnectionError("DevTools closed the connection")
            self.buf += chunk
        out, self.buf = self.buf[:n], self.buf[n:]
        return out

    def _send_frame(self, payload: bytes) -> None:
        header = bytearray([0x81])  # FIN + text frame
        n = len(payload)
        if n < 126:
            header.append(0x80 | n)
        elif n < 1 << 16:
            header.append(0x80 | 126)
            header += struct.pack("!H", n)
        else:
            header.append(0x80 | 127)
            header += struct.pack("!Q", n)
        mask = os.urandom(4)
        header += mask
        self.sock.sendall(bytes(header) + bytes(b ^ mask[i % 4] for i, b in enumerate(payload)))

    def _recv_message(self) -> dict[str, Any]:
        data = b""
        while True:
            b0, b1 = self._recv_exact(2)
            n = b1 & 0x7F
            if n == 126:
                n = struct.unpack("!H", self._recv_exact(2))[0]
            elif n == 127:
                n = struct.unpack("!Q", self._recv_exact(8))[0]
            payload = self._recv_exact(n)
            opcode = b0 & 0x0F
            if opcode == 0x8:
                raise ConnectionError("DevTools closed the WebSocket")
            if opcode in (0x9, 0xA):  # ping/pong: ignore
                continue
            data += payload
            if b0 & 0x80:
                return json.loads(data.decode("utf-8"))

    def call(self, method: str, **params: Any) -> dict[str, Any]:
        """Send a command and wait for its result, keeping the events that arrive meanwhile."""
        self.next_id += 1
        mid = self.next_id
        self._send_frame(json.dumps({"id": mid, "method": method, "params": params}).encode())
        while True:
            msg = self._recv_message()
            if msg.get("id") == mid:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg.get("result", {})
            if "method" in msg:
                self.events.append(msg)

    def wait_event(self, method: str, timeout: float, after: int = 0) -> dict[str, Any]:
        """The first event ``method`` among the events from index ``after`` on (those kept, then new ones)."""
        deadline = time.monotonic() + timeout
        for ev in self.events[after:]:
            if ev["method"] == method:
                return ev
        while time.monotonic() < deadline:
            msg = self._recv_message()
            if "method" in msg:
                self.events.append(msg)
                if msg["method"] == method:
                    return msg
        raise TimeoutError(f"no {method} within {timeout} s")

    def navigate(self, url: str, timeout: float) -> None:
        """Open ``url`` in the page and wait until it has loaded (its own load event, not an earlier page's;
        the Page domain enabled)."""
        mark = len(self.events)
        self.call("Page.navigate", url=url)
        self.wait_event("Page.loadEventFired", timeout, after=mark)

    def close(self) -> None:
        self.sock.close()


def free_port() -> int:
    """A TCP port of 127.0.0.1 free at the time of the call."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@contextlib.contextmanager
def open_chromium(chromium: str, folder: Path, *, window: str = "1400,1000", timeout: float = 30.0) -> Iterator[CDP]:
    """Start headless ``chromium`` (its profile and ``chromium.log`` in ``folder``, the window
    ``window`` px), wait for its page target and yield a :class:`CDP` client on it (``timeout`` s per
    message); the browser is stopped on exit, whatever happened. The client's ``events`` stay
    readable after the block."""
    flags = [f for f in FLAGS if not f.startswith("--window-size")] + [f"--window-size={window}"]
    log = folder / "chromium.log"
    port = free_port()
    with open(log, "wb") as errlog:
        proc = subprocess.Popen([chromium, *flags, f"--user-data-dir={folder / 'profile'}",
                                 f"--remote-debugging-port={port}", "about:blank"],
                                stdout=subprocess.DEVNULL, stderr=errlog)  # fmt: skip
        cdp = None
        try:
            targets: list[dict[str, Any]] = []
            deadline = time.monotonic() + 30
            while not targets and time.monotonic() < deadline:
                try:
                    with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=2) as r:
                        targets = [t for t in json.load(r) if t.get("type") == "page"]
                except OSError:
                    pass
                if not targets:
                    time.sleep(0.2)
            assert targets, f"Chromium did not open a DevTools page target:\n{log.read_text(errors='replace')[-2000:]}"
            cdp = CDP(targets[0]["webSocketDebuggerUrl"], timeout=timeout)
            yield cdp
        finally:
            if cdp is not None:
                cdp.close()
            proc.terminate()
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout=10)
