"""The live server: the recording's topics over the Foxglove WebSocket protocol, and a page.

:class:`LiveServer` runs in the parent process (the command line), never in the 1 kHz
loop process. It advertises one channel per topic of the recording, with the same JSON
schemas (:data:`~thermoskin.runtime.record.TOPIC_SCHEMAS`), so one Foxglove layout serves
live runs and recordings. Messages carry ``log_time = t`` in ns of the loop clock, as in
the recording. Signals are decimated to ``rate`` Hz (:mod:`thermoskin.live.messages`);
events are sent at once; ``/params`` (and a skin's ``/skin/scene``) is sent again to every new
subscriber (latched). A skin's run serves its own topics (``topics``,
:mod:`thermoskin.live.skin_topics`), the scene as protobuf (``foxglove.SceneUpdate``).

The WebSocket is served by ``foxglove-sdk`` (its subprotocol is ``foxglove.sdk.v1``, the
Foxglove WebSocket protocol v1 under its current name) behind :class:`~thermoskin.live.gate.Gate`,
which checks each connection's ``Origin`` and drops a client that stops reading, so that a
stalled viewer never holds a run (:mod:`thermoskin.live.gate`). The page (``page.html``, one
file, no external resource) is served over HTTP on ``port + 1`` under the same ``Origin`` rule;
it speaks the same protocol to the WebSocket. :meth:`LiveServer.close` is bounded (at most
:data:`CLOSE_S` s after its ``linger``).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import socket
import threading
import time
from collections.abc import Callable, Mapping
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from typing import Any

import foxglove

from thermoskin.live.address import LiveError, url_host
from thermoskin.live.gate import Gate, OriginRule, forbidden, private_loopback
from thermoskin.live.messages import RowMessages, clean
from thermoskin.runtime.record import TOPIC_SCHEMAS

#: Outgoing messages buffered per client before the oldest is dropped (the SDK's default
#: is 1024: 2 s of an as-fast-as-possible run at 100 Hz on five topics).
BACKLOG = 1 << 16
#: Seconds after a subscription before the latched ``/params`` is sent again (the SDK may
#: call back before the client's subscription is in place).
LATCH_DELAY_S = 0.05
#: Seconds :meth:`LiveServer.close` may take to stop the servers (after its ``linger``).
CLOSE_S = 0.5
#: Seconds a page request may take to arrive before its connection is closed.
PAGE_TIMEOUT_S = 5.0


def _quiet_sdk() -> None:
    """foxglove-sdk's log lines (a viewer that went away: "Error receiving from client ...") are
    not the user's business and would break a command's one-line messages: kept off stderr
    unless logging was set up (then they go where it says)."""
    log = logging.getLogger("foxglove")
    if not log.handlers and not logging.getLogger().handlers:
        log.addHandler(logging.NullHandler())
        log.propagate = False


_quiet_sdk()


def page_html() -> bytes:
    """The live page (``thermoskin/live/page.html``)."""
    return resources.files("thermoskin.live").joinpath("page.html").read_bytes()


class _Listener:
    """foxglove-sdk server callbacks (called on the SDK's threads)."""

    def __init__(self, owner: LiveServer) -> None:
        self.owner = owner

    def on_subscribe(self, client: Any, channel: Any) -> None:
        self.owner._subscribed(channel.topic)

    def on_unsubscribe(self, client: Any, channel: Any) -> None:
        return None


class _PageHandler(BaseHTTPRequestHandler):
    server_version = "thermoskin-live"
    timeout = PAGE_TIMEOUT_S  # a client that sends nothing does not hold a thread for ever

    def do_GET(self) -> None:
        self._send(head=False)

    def do_HEAD(self) -> None:
        self._send(head=True)

    def _send(self, head: bool) -> None:
        origins = self.headers.get_all("Origin") or []
        rule: OriginRule = self.server.rule  # type: ignore[attr-defined]
        if len(origins) > 1 or not rule.allows(origins[0] if origins else None):
            self.connection.sendall(forbidden(", ".join(origins)))
            self.close_connection = True
            return
        path = self.path.split("?", 1)[0]
        if path not in ("/", "/index.html"):
            self.send_error(404, "only / is served here")
            return
        body: bytes = self.server.page  # type: ignore[attr-defined]
        self.send_response(200)
        self.send_header("Content-Type", "text/html; charset=utf-8")
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        if not head:
            self.wfile.write(body)

    def log_message(self, format: str, *args: Any) -> None:  # quiet
        return None


class _PageServer(ThreadingHTTPServer):
    daemon_threads = True

    def __init__(self, host: str, port: int, page: bytes, rule: OriginRule) -> None:
        self.address_family = socket.AF_INET6 if ":" in host else socket.AF_INET
        self.page = page
        self.rule = rule
        super().__init__((host, port), _PageHandler)


#: Topics whose last message is sent again to a new subscriber.
LATCHED = ("/params", "/skin/scene")


def _channel(topic: str, schema: Any, context: foxglove.Context) -> foxglove.Channel:
    """A JSON channel for a JSON schema (a dict), a protobuf one for a ``foxglove.Schema``, and
    for ``(message encoding, foxglove.Schema)`` that channel (a recording's, replayed)."""
    if isinstance(schema, tuple):
        encoding, fs = schema
        return foxglove.Channel(topic, schema=fs, message_encoding=encoding, context=context)
    if isinstance(schema, dict):
        fs = foxglove.Schema(name=schema.get("title", topic.strip("/").replace("/", ".")),
                             encoding="jsonschema", data=json.dumps(schema).encode())
        return foxglove.Channel(topic, schema=fs, message_encoding="json", context=context)
    return foxglove.Channel(topic, schema=schema, message_encoding=schema.encoding, context=context)


def _config_object(config: Any) -> Any:
    if dataclasses.is_dataclass(config) and not isinstance(config, type):
        return dataclasses.asdict(config)
    return config


class LiveServer:
    """Foxglove WebSocket on ``host:port`` and the live page on ``host:port+1``.

    ``config`` (a :class:`~thermoskin.params.Config` or a mapping) is sent on ``/params``
    (``params``: more fields of that message, e.g. a skin's layout);
    ``rate`` (Hz of the loop clock) is what :meth:`write_rows` decimates signals to;
    ``topics`` (topic: schema, a JSON schema or a ``foxglove.Schema``) replaces the recording's
    topics (a skin's run, :func:`~thermoskin.live.skin_topics.skin_topics`);
    ``allow_origins``: origins served besides the page's own and clients with no ``Origin``
    (``--live-allow-origin``, :class:`~thermoskin.live.gate.OriginRule`); ``stop``: a signal's stop
    request (``is_set``): once true, :meth:`close` does not linger.
    Raises :class:`~thermoskin.live.address.LiveError` if a port cannot be bound.
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 8765, *, config: Any = None,
                 rate: float = 100.0, page: bool = True, name: str = "thermoskin",
                 topics: Mapping[str, Any] | None = None, params: Mapping[str, Any] | None = None,
                 allow_origins: tuple[str, ...] = (), stop: Callable[[], bool] | None = None) -> None:
        self.host, self.port = host, port
        self._stop = stop
        try:
            self.rule = OriginRule(host, port + 1, tuple(allow_origins))
        except ValueError as e:
            raise LiveError(str(e)) from None
        self.rows = RowMessages(rate)
        self.published = 0
        self._lock = threading.Lock()
        self._latched: dict[str, tuple[bytes, int]] = {}
        self._first_sub = threading.Event()
        self._timers: list[threading.Timer] = []
        self._closed = False
        self._http: _PageServer | None = None
        self.context = foxglove.Context()
        where = f"--live {url_host(host)}:{port}"
        inner = private_loopback()  # the SDK's server, reached only through the gate
        try:
            self._ws = foxglove.start_server(name=name, host=inner, port=0, context=self.context,
                                             server_listener=_Listener(self),
                                             message_backlog_size=BACKLOG,
                                             session_id=str(time.time_ns()))
        except RuntimeError as e:
            raise LiveError(f"{where}: cannot serve the WebSocket there ({_reason(e)})") from None
        try:
            self.gate = Gate(host, port, (inner, self._ws.port), self.rule)
        except OSError as e:
            _stop_bounded(self._ws.stop, CLOSE_S)
            raise LiveError(f"{where}: cannot serve the WebSocket there ({e.strerror or e})") from None
        self.topics = dict(TOPIC_SCHEMAS if topics is None else topics)
        self.channels = {topic: _channel(topic, schema, self.context)
                         for topic, schema in self.topics.items()}
        if page:
            try:
                self._http = _PageServer(host, port + 1, page_html(), self.rule)
            except OSError as e:
                self.gate.close()
                _stop_bounded(self._ws.stop, CLOSE_S)
                raise LiveError(f"{where}: cannot serve the page on port {port + 1} "
                                f"({e.strerror or e})") from None
            threading.Thread(target=self._http.serve_forever, kwargs={"poll_interval": 0.1},
                             name="thermoskin-live-page", daemon=True).start()
        if config is not None:
            self.publish("/params", 0.0, {"config": _config_object(config), **(params or {})})

    # ------------------------------------------------------------------ addresses
    @property
    def ws_url(self) -> str:
        return f"ws://{url_host(self.host)}:{self.port}"

    @property
    def page_url(self) -> str | None:
        return f"http://{url_host(self.host)}:{self.port + 1}/" if self._http is not None else None

    # ------------------------------------------------------------------ publishing
    def publish(self, topic: str, t: float, data: Mapping[str, Any] | bytes) -> None:
        """Send one message to the subscribers: a mapping as JSON (``t`` s of the loop clock is added
        to it), bytes as they are (an encoded protobuf message)."""
        ch = self.channels.get(topic)
        if ch is None:
            raise KeyError(f"live: no channel {topic!r} (this run's topics: {', '.join(self.topics)})")
        latched = topic in LATCHED
        if not (latched or ch.has_sinks()):
            return
        if isinstance(data, bytes):
            payload = data
        else:
            obj = {"t": t}
            for k, v in data.items():
                if k != "t":
                    obj[k] = clean(v)
            payload = json.dumps(obj, separators=(",", ":"), allow_nan=False).encode()
        ns = max(0, round(t * 1e9))
        if latched:
            with self._lock:
                self._latched[topic] = (payload, ns)
        ch.base.log(payload, ns)
        self.published += 1

    def write_rows(self, block: Mapping[str, Any]) -> None:
        """One block of the loop's rows (columns of equal length), decimated; contact changes at once."""
        channels = self.channels
        live = {topic for topic, ch in channels.items() if ch.has_sinks()}
        dumps = json.dumps
        for topic, t, msg in self.rows.messages(block):  # already JSON-clean (no NaN)
            if topic in live:
                ns = max(0, round(t * 1e9))
                channels[topic].base.log(dumps({"t": t, **msg}, separators=(",", ":")).encode(), ns)
                self.published += 1

    def event(self, t: float, kind: str, **detail: Any) -> None:
        """An event on ``/events`` (the recorder's form: ``kind`` and ``detail``)."""
        self.publish("/events", t, {"kind": kind, "detail": detail})

    # ------------------------------------------------------------------ clients
    def _subscribed(self, topic: str) -> None:
        self._first_sub.set()
        if topic in LATCHED and not self._closed:
            timer = threading.Timer(LATCH_DELAY_S, self._resend, (topic,))
            timer.daemon = True
            self._timers.append(timer)
            timer.start()

    def _resend(self, topic: str) -> None:
        with self._lock:
            latched = self._latched.get(topic)
        if latched is not None and not self._closed:
            self.channels[topic].base.log(*latched)

    def wait_for_client(self, timeout: float, stop: Callable[[], bool] | None = None) -> bool:
        """Wait up to ``timeout`` s for a first subscription (and a little more for the rest of
        the client's subscriptions); true if one came. ``stop``: looked at every 50 ms, ends the
        wait when true (a signal's stop request)."""
        t_end = time.monotonic() + timeout
        while (left := t_end - time.monotonic()) > 0:
            if self._first_sub.wait(min(left, 0.05)):
                time.sleep(0.25)
                return True
            if stop is not None and stop():
                return False
        return self._first_sub.is_set()

    def close(self, linger: float = 0.5) -> None:
        """Let the last messages go out (``linger`` s), then stop both servers, in at most
        :data:`CLOSE_S` s more whatever the clients do: the gate drops every connection (so the
        SDK waits for none), and the SDK's and the page server's stops are waited for that long."""
        if self._closed:
            return
        if linger > 0 and not (self._stop is not None and self._stop()):
            time.sleep(linger)
        self._closed = True
        t_end = time.monotonic() + CLOSE_S
        for timer in self._timers:
            timer.cancel()
        self.gate.close(timeout=CLOSE_S / 2)
        _stop_bounded(self._ws.stop, max(0.0, t_end - time.monotonic()))
        if self._http is not None:
            http = self._http
            _stop_bounded(http.shutdown, max(0.0, t_end - time.monotonic()))
            http.server_close()

    def __enter__(self) -> LiveServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close(linger=0)


def _stop_bounded(stop: Any, timeout: float) -> bool:
    """Call ``stop`` in a thread of its own and wait at most ``timeout`` s for it; whether it ended
    (one that did not carries on in its daemon thread and does not hold the process's exit)."""
    th = threading.Thread(target=stop, name="thermoskin-live-stop", daemon=True)
    th.start()
    th.join(timeout)
    return not th.is_alive()


def _reason(e: Exception) -> str:
    msg = " ".join(str(e).split())
    return msg.removeprefix("FoxgloveError: ")


class Fanout:
    """Hands the loop's rows and events to several sinks (a recorder, a live server)."""

    def __init__(self, *sinks: Any) -> None:
        self.sinks = [s for s in sinks if s is not None]

    def write_rows(self, block: Mapping[str, Any]) -> None:
        for s in self.sinks:
            s.write_rows(block)

    def event(self, t: float, kind: str, **detail: Any) -> None:
        for s in self.sinks:
            s.event(t, kind, **detail)

    def close(self) -> None:
        """Close every sink, even if one fails (the first error is raised after)."""
        error: BaseException | None = None
        for s in self.sinks:
            try:
                s.close()
            except BaseException as e:
                error = error or e
        if error is not None:
            raise error
