"""The live server under abuse (issue 46): a viewer that subscribes and never reads never holds
a run, a replay or the server's close; SIGINT, SIGTERM and SIGHUP stop a live run or replay with
every output written; only the page's own origin, clients without ``Origin`` and the origins of
``--live-allow-origin`` are served (others: 403), on the WebSocket and on the page server.

The stalled client speaks the protocol only as far as it must (the handshake, the server's
first messages, one ``subscribe`` for every channel) and then never reads again, with a receive
buffer of 4 KiB, so that the kernel's buffers fill at once.
"""

from __future__ import annotations

import base64
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pytest

websocket = pytest.importorskip("websocket", reason="needs websocket-client (the [test] extra)")

from thermoskin.live import LiveServer  # noqa: E402
from thermoskin.live.gate import OriginRule, normal_origin  # noqa: E402
from thermoskin.logio import read_log  # noqa: E402
from thermoskin.runtime.closed_loop import COLUMNS  # noqa: E402
from thermoskin.runtime.record import LoopRecorder, iter_messages  # noqa: E402

pytestmark = pytest.mark.usefixtures("compiled_estimator")

ENV = {**os.environ, "PYTHONUNBUFFERED": "1"}
CMD = [sys.executable, "-c", "from thermoskin.cli import main; main()"]
SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]
#: A bound that only a hang passes: the design's bounds are a second or two (docs/reliability.md).
HANG_S = 60.0


def free_port_pair() -> int:
    for _ in range(50):
        with socket.socket() as a:
            a.bind(("127.0.0.1", 0))
            p = a.getsockname()[1]
            if p >= 65535:
                continue
            with socket.socket() as b:
                try:
                    b.bind(("127.0.0.1", p + 1))
                except OSError:
                    continue
        return p
    raise RuntimeError("no two consecutive free ports")


def stalled_client(port: int, timeout: float = HANG_S) -> websocket.WebSocket:
    """Connect, subscribe to every advertised channel, and from then on never read."""
    t_end = time.monotonic() + timeout
    while True:
        try:
            ws = websocket.create_connection(f"ws://127.0.0.1:{port}", subprotocols=SUBPROTOCOLS, timeout=10,
                                             sockopt=[(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)])
            break
        except (ConnectionError, OSError, websocket.WebSocketException):
            if time.monotonic() > t_end:
                raise
            time.sleep(0.05)
    json.loads(ws.recv())  # serverInfo
    channels: list[int] = []
    while not channels:
        m = json.loads(ws.recv())
        if m.get("op") == "advertise":
            channels = [c["id"] for c in m["channels"]]
    ws.send(json.dumps({"op": "subscribe",
                        "subscriptions": [{"id": i, "channelId": c} for i, c in enumerate(channels)]}))
    return ws


def _rows(k: int, n: int = 1000) -> dict[str, np.ndarray]:
    block = {c: np.zeros(n) for c in COLUMNS}
    block["t"] = (np.arange(n) + k * n) * 1e-3
    block["T_w"] = 24.0 + 0.01 * np.sin(block["t"])
    return block


def test_stalled_viewer_is_dropped_and_close_is_bounded() -> None:
    """A viewer that never reads: the publishing side never waits, the gate drops the viewer once
    it holds its limit for it, and the server's close ends at once (it waited for ever before)."""
    port = free_port_pair()
    live = LiveServer("127.0.0.1", port, rate=1000.0)
    ws = stalled_client(port)
    try:
        t_end = time.monotonic() + HANG_S
        k = 0
        while live.gate.dropped == 0:  # 7 topics at 1000 Hz: 4 MiB within a few blocks
            live.write_rows(_rows(k))
            k += 1
            assert time.monotonic() < t_end, "the stalled viewer was never dropped"
        assert live.gate.clients == 0
        t0 = time.monotonic()
        live.close()
        closed_s = time.monotonic() - t0
    finally:
        ws.sock.close()
    print(f"stalled viewer dropped after {k} blocks of 1000 rows; close took {closed_s:.3f} s")
    assert closed_s < 0.5 + 10.0  # linger 0.5 s, then at most 0.5 s by design; a hang was for ever


def test_close_is_bounded_with_a_stalled_viewer_still_connected() -> None:
    """Closed while a stalled viewer is still held (before the gate's limit): close drops it."""
    port = free_port_pair()
    live = LiveServer("127.0.0.1", port, rate=1000.0)
    ws = stalled_client(port)
    try:
        for k in range(3):
            live.write_rows(_rows(k))
        t0 = time.monotonic()
        live.close(linger=0)
        closed_s = time.monotonic() - t0
    finally:
        ws.sock.close()
    assert live.gate.clients == 0
    assert closed_s < 10.0, closed_s


def start(args: list[str], cwd: Path) -> subprocess.Popen[str]:
    return subprocess.Popen([*CMD, *args], cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=ENV)


def log_end(path: Path) -> float:
    try:
        return float(read_log(path, required=("t",), live=True)["t"][-1])
    except Exception:
        return 0.0


def test_run_with_a_stalled_viewer_ends_with_every_output(tmp_path: Path) -> None:
    """`run --live` with a viewer that subscribed and stalled: the run ends, exit 0, the whole log,
    the plot and a complete recording (before, the process never ended). As fast as it computes
    (--no-realtime: 30 s of loop in a few); the paced run is the signal test's below."""
    port = free_port_pair()
    p = start(["run", "--no-realtime", "--duration", "30", "--live", f"127.0.0.1:{port}", "--live-wait", "60",
               "--live-rate", "1000", "--log", "x.csv", "--record", "x.mcap"], tmp_path)
    ws = stalled_client(port)
    try:
        _out, err = p.communicate(timeout=600)
    finally:
        if p.poll() is None:
            p.kill()
        ws.sock.close()
    assert p.returncode == 0, err
    assert "Traceback" not in err
    t = read_log(tmp_path / "x.csv", required=("t",))["t"]
    assert len(t) == 30_000 and t[-1] == pytest.approx(29.999)
    assert (tmp_path / "x.png").stat().st_size > 10_000
    info: dict = {}
    n = sum(1 for _ in iter_messages(tmp_path / "x.mcap", ["/skin/sample"], info))
    assert info["complete"] and n == 30_000


@pytest.mark.parametrize(("sig", "code"), [(signal.SIGTERM, 143)])
def test_signal_stops_a_live_run_with_a_stalled_viewer(tmp_path: Path, sig: int, code: int) -> None:
    """SIGTERM to `run --live` (paced at wall-clock speed in the fixed-rate loop process, as a live
    run is by default) while a stalled viewer is connected: the run stops with 128 + the signal,
    its log, plot and a complete recording written (in about a second on a quiet machine)."""
    port = free_port_pair()
    p = start(["run", "--duration", "600", "--live", f"127.0.0.1:{port}", "--live-wait", "60",
               "--log", "x.csv", "--record", "x.mcap"], tmp_path)
    ws = stalled_client(port)
    try:
        t_end = time.monotonic() + HANG_S
        while log_end(tmp_path / "x.csv") < 2.0:
            assert p.poll() is None, p.communicate()
            assert time.monotonic() < t_end
            time.sleep(0.05)
        t0 = time.monotonic()
        p.send_signal(sig)
        _out, err = p.communicate(timeout=HANG_S)
        stop_s = time.monotonic() - t0
    finally:
        if p.poll() is None:
            p.kill()
        ws.sock.close()
    print(f"{signal.Signals(sig).name}: exit {p.returncode} {stop_s:.2f} s after the signal")
    assert p.returncode == code, err
    lines = err.strip().splitlines()
    assert lines[-1].startswith(f"thermoskin: stopped by {signal.Signals(sig).name} at t = "), err
    t = read_log(tmp_path / "x.csv", required=("t",))["t"]
    assert t[-1] >= 2.0
    assert (tmp_path / "x.png").stat().st_size > 10_000
    info: dict = {}
    last = [tt for _, tt, _ in iter_messages(tmp_path / "x.mcap", ["/skin/sample"], info)][-1]
    assert info["complete"] and last == t[-1]


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from thermoskin.params import Config

    path = tmp_path_factory.mktemp("rec") / "x.mcap"
    rec = LoopRecorder(path, Config())
    rec.event(0.0, "run-start", device="sim", scenario="test")
    for k in range(10):
        rec.write_rows(_rows(k))
    rec.event(9.999, "run-end", wall_s=1.0)
    rec.close()
    return path


@pytest.mark.parametrize(("sig", "code"), [(signal.SIGINT, 130), (signal.SIGTERM, 143), (signal.SIGHUP, 129)])
def test_signal_stops_a_live_replay_with_a_stalled_viewer(recording: Path, tmp_path: Path, sig: int,
                                                         code: int) -> None:
    """`replay --live` (10 s at 0.1x: 100 s) with a stalled viewer: each of the three signals ends it
    with 128 + the signal and one line (before: it hung in the server's stop)."""
    port = free_port_pair()
    p = start(["replay", str(recording), "--live", f"127.0.0.1:{port}", "--live-wait", "60",
               "--speed", "0.1", "--live-rate", "1000"], tmp_path)
    ws = stalled_client(port)
    try:
        time.sleep(1.0)
        assert p.poll() is None, p.communicate()
        t0 = time.monotonic()
        p.send_signal(sig)
        out, err = p.communicate(timeout=HANG_S)
        stop_s = time.monotonic() - t0
    finally:
        if p.poll() is None:
            p.kill()
        ws.sock.close()
    print(f"replay, {signal.Signals(sig).name}: exit {p.returncode} {stop_s:.2f} s after the signal")
    assert p.returncode == code, err
    assert err.strip().splitlines()[-1] == (f"thermoskin: stopped by {signal.Signals(sig).name}: the replay "
                                            "into the live server ended"), err
    assert "played" in out


def test_signal_ends_the_wait_for_a_viewer(tmp_path: Path) -> None:
    """SIGTERM during `--live-wait 600` (no viewer): the wait ends, the run stops with 143."""
    port = free_port_pair()
    p = start(["run", "--duration", "5", "--live", f"127.0.0.1:{port}", "--live-wait", "600",
               "--log", "x.csv"], tmp_path)
    try:
        t_end = time.monotonic() + HANG_S
        while p.poll() is None and not _listening(port):
            assert time.monotonic() < t_end
            time.sleep(0.05)
        time.sleep(0.3)
        p.send_signal(signal.SIGTERM)
        _out, err = p.communicate(timeout=HANG_S)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 143, err
    assert "Traceback" not in err


def _listening(port: int) -> bool:
    with socket.socket() as s:
        s.settimeout(0.5)
        return s.connect_ex(("127.0.0.1", port)) == 0


# ----------------------------------------------------------------------------- Origin

def handshake(port: int, origin: str | None, path: str = "/") -> int:
    """The HTTP status of a WebSocket upgrade request with this ``Origin`` (None: no header)."""
    key = base64.b64encode(os.urandom(16)).decode()
    head = (f"GET {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
            f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n"
            f"Sec-WebSocket-Protocol: {', '.join(SUBPROTOCOLS)}\r\n")
    if origin is not None:
        head += f"Origin: {origin}\r\n"
    with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
        s.sendall((head + "\r\n").encode())
        got = b""
        while b"\r\n" not in got:
            piece = s.recv(4096)
            if not piece:
                break
            got += piece
    return int(got.split(b" ", 2)[1])


def page_status(port: int, origin: str | None) -> int:
    req = urllib.request.Request(f"http://127.0.0.1:{port + 1}/")
    if origin is not None:
        req.add_header("Origin", origin)
    try:
        with urllib.request.urlopen(req, timeout=10) as r:
            return r.status
    except urllib.error.HTTPError as e:
        return e.code


@pytest.fixture(scope="module")
def server() -> LiveServer:
    port = free_port_pair()
    live = LiveServer("127.0.0.1", port, allow_origins=("https://app.foxglove.dev",))
    yield live
    live.close(linger=0)


@pytest.mark.parametrize(("origin", "status"), [
    (None, 101),                                   # Foxglove desktop, Lichtblick, scripts
    ("http://127.0.0.1:{page}", 101),              # the live page
    ("http://localhost:{page}", 101),              # the live page, opened at localhost
    ("http://[::1]:{page}", 101),                  # ... at the IPv6 loopback
    ("http://127.0.0.1:{ws}", 101),                # what websocket-client sends by default
    ("https://app.foxglove.dev", 101),             # --live-allow-origin
    ("HTTPS://APP.FOXGLOVE.DEV:443", 101),         # the same origin, written otherwise
    ("https://evil.example", 403),                 # another site's page
    ("http://evil.example:{page}", 403),           # ... even on the page's port (DNS rebinding)
    ("http://127.0.0.1:9", 403),                   # another local service's page
    ("https://127.0.0.1:{page}", 403),             # not the page's scheme
    ("null", 403),                                 # a file or a sandboxed frame
    ("http://app.foxglove.dev", 403),              # the allowed host, another scheme
    ("garbage \x7f", 403),
])
def test_origin_on_the_websocket_and_the_page(server: LiveServer, origin: str | None, status: int) -> None:
    port = server.port
    o = None if origin is None else origin.format(page=port + 1, ws=port)
    assert handshake(port, o) == status
    assert page_status(port, o) == (200 if status == 101 else 403)


def test_two_origin_headers_are_refused(server: LiveServer) -> None:
    port = server.port
    head = (f"GET / HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
            f"Sec-WebSocket-Key: {base64.b64encode(os.urandom(16)).decode()}\r\nSec-WebSocket-Version: 13\r\n"
            f"Origin: http://127.0.0.1:{port + 1}\r\nOrigin: https://evil.example\r\n\r\n")
    with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
        s.sendall(head.encode())
        assert s.recv(4096).startswith(b"HTTP/1.1 403")


def test_a_client_that_sends_no_request_is_let_go(server: LiveServer) -> None:
    """A connection that never sends its request head is closed by the gate (5 s), not held."""
    with socket.create_connection(("127.0.0.1", server.port), timeout=HANG_S) as s:
        t0 = time.monotonic()
        assert s.recv(1) == b""
    assert time.monotonic() - t0 < HANG_S


def test_many_clients_and_garbage_do_not_stop_the_server(server: LiveServer) -> None:
    """50 clients at once, half of them sending binary garbage: the server still serves a viewer."""
    socks = []
    for k in range(50):
        s = socket.create_connection(("127.0.0.1", server.port), timeout=10)
        if k % 2:
            s.sendall(os.urandom(20_000) + b"\r\n\r\n")
        socks.append(s)
    try:
        assert handshake(server.port, None) == 101
    finally:
        for s in socks:
            s.close()


def test_origin_rule_independently() -> None:
    """The rule's pieces against origins written out by hand (RFC 6454: scheme, host, port;
    default ports left out; hosts in lower case)."""
    assert normal_origin("HTTP://LocalHost:80") == "http://localhost"
    assert normal_origin("https://a.b:8443/") == "https://a.b:8443"
    assert normal_origin("http://[::1]:8766") == "http://[::1]:8766"
    for bad in ("null", "", "ftp://x", "http://", "http://a/b", "http://a?x=1", "http://a:99999"):
        assert normal_origin(bad) is None, bad
    wide = OriginRule("0.0.0.0", 8766)
    assert wide.allows("http://192.168.1.20:8766") and not wide.allows("http://lab.example:8766")
    named = OriginRule("skin-pc.lab", 8766)
    assert named.allows("http://skin-pc.lab:8766") and not named.allows("http://127.0.0.1:8766")
    assert OriginRule("127.0.0.1", 8766, ("*",)).allows("https://anything.example")
    with pytest.raises(ValueError, match="not an origin"):
        OriginRule("127.0.0.1", 8766, ("app.foxglove.dev",))


def test_allow_origin_option_is_checked_first(tmp_path: Path) -> None:
    from click.testing import CliRunner

    from thermoskin.cli import main

    r = CliRunner().invoke(main, ["run", "--duration", "1", "--log", str(tmp_path / "x.csv"), "--live",
                                  "--live-allow-origin", "app.foxglove.dev"])
    assert r.exit_code == 2
    assert r.stderr.strip().splitlines() == [
        "thermoskin: error: --live-allow-origin 'app.foxglove.dev': not an origin (scheme://host[:port], "
        "e.g. https://app.foxglove.dev), nor *"]
    assert list(tmp_path.iterdir()) == []


def test_a_reading_viewer_still_gets_everything_through_the_gate() -> None:
    """The gate relays whole: a viewer that reads receives every message published for it."""
    port = free_port_pair()
    live = LiveServer("127.0.0.1", port, rate=100.0)
    ws = websocket.create_connection(f"ws://127.0.0.1:{port}", subprotocols=SUBPROTOCOLS, timeout=10)
    json.loads(ws.recv())
    ch: dict[str, int] = {}
    while "/skin/sample" not in ch:  # (the channels may come in several advertisements)
        m = json.loads(ws.recv())
        if m.get("op") == "advertise":
            ch.update({c["topic"]: c["id"] for c in m["channels"]})
    ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 7, "channelId": ch["/skin/sample"]}]}))
    got: list[float] = []
    done = threading.Event()

    def read() -> None:
        try:
            while len(got) < 300:
                frame = ws.recv()
                if isinstance(frame, bytes) and frame[:1] == b"\x01":
                    got.append(json.loads(frame[13:])["t"])
        finally:
            done.set()

    threading.Thread(target=read, daemon=True).start()
    t_end = time.monotonic() + HANG_S
    while not live._first_sub.is_set():
        assert time.monotonic() < t_end
        time.sleep(0.01)
    time.sleep(0.2)
    for k in range(3):
        live.write_rows(_rows(k))
    assert done.wait(HANG_S)
    live.close(linger=0)
    ws.close()
    assert got == pytest.approx([k * 0.01 for k in range(300)])
