"""The live server's front door: who may connect (``Origin``), and a client that stops reading.

foxglove-sdk's WebSocket server has neither an ``Origin`` check nor a bound on how long its
``stop()`` waits for a client that no longer reads (a viewer that subscribed and then stalled
kept ``thermoskin run`` from ever ending). :class:`Gate` listens on the public ``HOST:PORT``
in front of it and relays each accepted connection to the SDK's server, which listens on a
random port of a random loopback address (``127.a.b.c``, which Linux routes to this machine
without configuration: a web page that would scan for it has 2**40 places to try; 127.0.0.1
where no other loopback address can be bound).

- **Origin** (:class:`OriginRule`): a browser sends the page's origin with every WebSocket
  handshake and every cross-site request; a page on another site, open in the lab's
  browser, could otherwise read the stream from 127.0.0.1. Accepted: no ``Origin`` header
  (Foxglove desktop, Lichtblick, scripts), the live page's own origin
  (``http://HOST:PORT+1``, with ``HOST`` any name of this machine's address the page was
  opened at, never a name a DNS record could point elsewhere), the WebSocket's own
  (``http://HOST:PORT``: what scripts written with ``websocket-client`` send, and no page can
  come from there but ours), and the origins given with
  ``--live-allow-origin`` (a hosted viewer, ``https://app.foxglove.dev``; ``*`` for any).
  Others get ``403 Forbidden`` and the connection is closed.
- **A client that stops reading** is dropped, never waited for: the gate always reads what
  the SDK sends (so the SDK's own queue never fills and its ``stop()`` never waits), and
  holds at most :data:`MAX_PENDING` bytes for a client; more than that, or a client that
  took nothing for :data:`STALL_S` s while bytes waited for it, and the connection is closed.
- **Bounded**: a request head of at most :data:`MAX_HEAD` bytes within :data:`HEAD_S` s, at
  most :data:`MAX_CLIENTS` connections; :meth:`Gate.close` ends within :data:`CLOSE_S` s.

One thread serves every connection (``selectors``), so 50 viewers are 50 sockets, not 100
threads.
"""

from __future__ import annotations

import contextlib
import ipaddress
import random
import selectors
import socket
import threading
import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from urllib.parse import urlsplit

#: Bytes held for one client before it is dropped (about 40 s of a run's live topics at 100 Hz).
MAX_PENDING = 4 << 20
#: Seconds a client may take nothing while bytes wait for it before it is dropped.
STALL_S = 5.0
#: Largest request head (the HTTP upgrade request) and the time it may take to arrive.
MAX_HEAD = 16 << 10
HEAD_S = 5.0
#: Connections served at once; more are refused (closed at once).
MAX_CLIENTS = 256
#: Seconds :meth:`Gate.close` waits for its thread.
CLOSE_S = 0.5
_CHUNK = 1 << 16

FORBIDDEN = (b"HTTP/1.1 403 Forbidden\r\nContent-Type: text/plain; charset=utf-8\r\n"
             b"Content-Length: %d\r\nConnection: close\r\n\r\n%s")


def forbidden(origin: str) -> bytes:
    """The ``403`` response to a refused ``Origin``."""
    body = (f"origin {origin[:200]!r} is not allowed here: start the server with "
            "--live-allow-origin ORIGIN to allow it\n").encode("ascii", "backslashreplace")
    return FORBIDDEN % (len(body), body)


def _is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _is_ip(host: str) -> bool:
    try:
        ipaddress.ip_address(host)
    except ValueError:
        return False
    return True


def normal_origin(text: str) -> str | None:
    """``scheme://host[:port]`` in lower case, the default port left out; None if not an origin."""
    try:
        u = urlsplit(text.strip())
        port = u.port
    except ValueError:
        return None
    if u.scheme not in ("http", "https") or not u.hostname or u.path not in ("", "/") or u.query:
        return None
    host = u.hostname.lower()
    port_txt = "" if port is None or port == {"http": 80, "https": 443}[u.scheme] else f":{port}"
    return f"{u.scheme}://{f'[{host}]' if ':' in host else host}{port_txt}"


@dataclass(frozen=True)
class OriginRule:
    """Which ``Origin`` headers the live servers accept (module doc).

    ``host``: the address the servers listen on; ``page_port``: the live page's port (the
    WebSocket's is ``page_port - 1``); ``allow``: more origins (``--live-allow-origin``; ``*``
    for any).
    """

    host: str
    page_port: int
    allow: tuple[str, ...] = ()
    _extra: frozenset[str] = field(init=False, repr=False, default=frozenset())

    def __post_init__(self) -> None:
        extra = set()
        for a in self.allow:
            if a == "*":
                extra.add("*")
                continue
            n = normal_origin(a)
            if n is None:
                raise ValueError(f"--live-allow-origin {a!r}: not an origin (scheme://host[:port], "
                                 "e.g. https://app.foxglove.dev), nor *")
            extra.add(n)
        object.__setattr__(self, "_extra", frozenset(extra))

    def page_hosts_ok(self, host: str) -> bool:
        """Whether a page opened at ``host`` is the live page of a server on :attr:`host`."""
        bound = self.host.lower().strip("[]")
        if host == bound:
            return True
        if _is_loopback(bound):
            return _is_loopback(host)
        if bound in ("", "0.0.0.0", "::"):  # every address of this machine
            return _is_ip(host) or host == "localhost" or host == socket.gethostname().lower()
        return False

    def allows(self, origin: str | None) -> bool:
        """Whether a request with this ``Origin`` header (None: no header) is served."""
        if origin is None:
            return True
        if "*" in self._extra:
            return True
        n = normal_origin(origin)
        if n is None:
            return False  # "null" (a file or a sandboxed frame), garbage
        if n in self._extra:
            return True
        u = urlsplit(n)
        return (u.scheme == "http" and u.port in (self.page_port, self.page_port - 1)
                and self.page_hosts_ok(u.hostname or ""))


def header(head: bytes, name: str) -> list[str]:
    """The values of the header ``name`` (any case) in an HTTP request head."""
    want = name.lower().encode()
    out = []
    for line in head.split(b"\r\n")[1:]:
        k, sep, v = line.partition(b":")
        if sep and k.strip().lower() == want:
            out.append(v.strip().decode("latin-1"))
    return out


def origin_of(head: bytes) -> tuple[bool, str | None]:
    """``(well formed, Origin)`` of a request head: two Origin headers are not well formed."""
    values = header(head, "origin")
    if len(values) > 1:
        return False, ", ".join(values)
    return True, values[0] if values else None


def private_loopback() -> str:
    """A random loopback address ``127.a.b.c`` this machine lets a socket bind (127.0.0.1 if none)."""
    rng = random.SystemRandom()
    for _ in range(8):
        host = f"127.{rng.randrange(1, 255)}.{rng.randrange(0, 256)}.{rng.randrange(2, 255)}"
        with socket.socket() as s:
            try:
                s.bind((host, 0))
            except OSError:
                continue
        return host
    return "127.0.0.1"


class _Conn:
    __slots__ = ("client", "deadline", "head", "idle_since", "to_client", "to_up", "up")

    def __init__(self, client: socket.socket) -> None:
        self.client = client
        self.up: socket.socket | None = None
        self.head = bytearray()
        self.to_up = bytearray()
        self.to_client = bytearray()
        self.deadline = time.monotonic() + HEAD_S
        self.idle_since = 0.0


class Gate:
    """Listens on ``(host, port)``; relays to ``upstream`` what :class:`OriginRule` lets in.

    Counts: ``refused`` (403), ``dropped`` (a client that stopped reading), ``accepted``.
    Raises ``OSError`` if the address cannot be bound.
    """

    def __init__(self, host: str, port: int, upstream: tuple[str, int], rule: OriginRule, *,
                 max_pending: int = MAX_PENDING, stall_s: float = STALL_S) -> None:
        self.upstream = upstream
        self.rule = rule
        self.max_pending = max_pending
        self.stall_s = stall_s
        self.accepted = self.refused = self.dropped = 0
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        self._listen = socket.socket(family, socket.SOCK_STREAM)
        try:
            self._listen.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            self._listen.bind((host, port))
            self._listen.listen(64)
            self._listen.setblocking(False)
        except OSError:
            self._listen.close()
            raise
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._closing = False
        self._sel = selectors.DefaultSelector()
        self._sel.register(self._listen, selectors.EVENT_READ, None)
        self._sel.register(self._wake_r, selectors.EVENT_READ, None)
        self._conns: set[_Conn] = set()
        self._thread = threading.Thread(target=self._serve, name="thermoskin-live-gate", daemon=True)
        self._thread.start()

    @property
    def clients(self) -> int:
        """Connections open now."""
        return len(self._conns)

    # ------------------------------------------------------------------ the loop
    def _serve(self) -> None:
        try:
            while not self._closing:
                for key, mask in self._sel.select(timeout=0.25):
                    if key.fileobj is self._listen:
                        self._accept()
                    elif key.fileobj is self._wake_r:
                        with contextlib.suppress(OSError):
                            self._wake_r.recv(4096)
                    else:
                        conn, side = key.data
                        if conn in self._conns:
                            self._event(conn, side, mask)
                self._check_times()
        finally:
            for conn in list(self._conns):
                self._drop(conn)
            for s in (self._listen, self._wake_r):
                with contextlib.suppress(KeyError, ValueError):
                    self._sel.unregister(s)
                s.close()
            self._sel.close()

    def _accept(self) -> None:
        for _ in range(64):
            try:
                sock, _ = self._listen.accept()
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                return
            if len(self._conns) >= MAX_CLIENTS:
                sock.close()
                self.refused += 1
                continue
            sock.setblocking(False)
            conn = _Conn(sock)
            self._conns.add(conn)
            self._sel.register(sock, selectors.EVENT_READ, (conn, "client"))

    def _check_times(self) -> None:
        now = time.monotonic()
        for conn in list(self._conns):
            if conn.up is None and now > conn.deadline:
                self._drop(conn)  # a request head that never came
            elif conn.to_client and now - conn.idle_since > self.stall_s:
                self.dropped += 1
                self._drop(conn)  # took nothing for stall_s s

    def _event(self, conn: _Conn, side: str, mask: int) -> None:
        try:
            if side == "client":
                if mask & selectors.EVENT_READ:
                    data = conn.client.recv(_CHUNK)
                    if not data:
                        self._drop(conn)
                        return
                    if conn.up is None:
                        self._head(conn, data)
                    else:
                        conn.to_up += data
                        if len(conn.to_up) > self.max_pending:
                            self._drop(conn)
                            return
                if conn.up is not None and mask & selectors.EVENT_WRITE and conn.to_client:
                    n = conn.client.send(conn.to_client)
                    del conn.to_client[:n]
                    conn.idle_since = time.monotonic()
            else:
                assert conn.up is not None
                if mask & selectors.EVENT_READ:
                    data = conn.up.recv(_CHUNK)
                    if not data:
                        self._drop(conn)
                        return
                    if not conn.to_client:
                        conn.idle_since = time.monotonic()
                    conn.to_client += data
                    if len(conn.to_client) > self.max_pending:
                        self.dropped += 1
                        self._drop(conn)
                        return
                if mask & selectors.EVENT_WRITE and conn.to_up:
                    n = conn.up.send(conn.to_up)
                    del conn.to_up[:n]
            self._interest(conn)
        except (BlockingIOError, InterruptedError):
            self._interest(conn)
        except OSError:
            self._drop(conn)

    def _head(self, conn: _Conn, data: bytes) -> None:
        conn.head += data
        end = conn.head.find(b"\r\n\r\n")
        if end < 0:
            if len(conn.head) > MAX_HEAD:
                self._drop(conn)
            return
        head = bytes(conn.head[:end])
        ok, origin = origin_of(head)
        if not ok or not self.rule.allows(origin):
            self.refused += 1
            with contextlib.suppress(OSError):
                conn.client.send(forbidden(origin or ""))
            self._drop(conn)
            return
        up = socket.create_connection(self.upstream, timeout=1.0)
        up.setblocking(False)
        conn.up = up
        conn.to_up += conn.head
        conn.head = bytearray()
        self.accepted += 1
        self._sel.register(up, selectors.EVENT_READ, (conn, "up"))

    def _interest(self, conn: _Conn) -> None:
        if conn not in self._conns:
            return
        want_c = selectors.EVENT_READ | (selectors.EVENT_WRITE if conn.to_client else 0)
        self._sel.modify(conn.client, want_c, (conn, "client"))
        if conn.up is not None:
            want_u = selectors.EVENT_READ | (selectors.EVENT_WRITE if conn.to_up else 0)
            self._sel.modify(conn.up, want_u, (conn, "up"))

    def _drop(self, conn: _Conn) -> None:
        self._conns.discard(conn)
        for s in (conn.client, conn.up):
            if s is None:
                continue
            with contextlib.suppress(KeyError, ValueError):
                self._sel.unregister(s)
            with contextlib.suppress(OSError):
                s.shutdown(socket.SHUT_RDWR)
            s.close()

    # ------------------------------------------------------------------ closing
    def close(self, timeout: float = CLOSE_S) -> None:
        """Close every connection and the listener; waits at most ``timeout`` s."""
        if self._closing:
            return
        self._closing = True
        with contextlib.suppress(OSError):
            self._wake_w.send(b"x")
        self._thread.join(timeout)
        self._wake_w.close()


def allowed_origins(values: Iterable[str]) -> tuple[str, ...]:
    """``--live-allow-origin``'s values, checked (``ValueError`` with one line for a bad one)."""
    out = tuple(values)
    OriginRule("127.0.0.1", 1, out)
    return out
