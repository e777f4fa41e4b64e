"""The live view: Foxglove WebSocket protocol v1 from a real `thermoskin run --live`, the page in
headless Chromium, `replay --live`, and the parts (address, decimation, row messages, layout).

The protocol client below is written from the protocol's specification (text ``serverInfo``,
``advertise``; ``subscribe``; binary message data ``0x01, subscription id u32 LE, log time
u64 LE, payload``), not from the server's code. foxglove-sdk names the v1 subprotocol
``foxglove.sdk.v1`` (``foxglove.websocket.v1`` before); the client offers both.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

websocket = pytest.importorskip("websocket", reason="needs websocket-client (the [test] extra)")

from thermoskin.live import Decimator, LiveError, LiveServer, RowMessages, parse_address  # noqa: E402
from thermoskin.params import Config  # noqa: E402
from thermoskin.runtime.record import TOPIC_SCHEMAS, LoopRecorder, read_mcap  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.usefixtures("compiled_estimator")  # its runs time out as runs

ENV = {**os.environ, "PYTHONUNBUFFERED": "1"}
CMD = [sys.executable, "-c", "from thermoskin.cli import main; main()"]
SUBPROTOCOLS = ["foxglove.websocket.v1", "foxglove.sdk.v1"]
CHROMIUM = "/usr/bin/chromium"
CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def free_port_pair() -> int:
    """A port ``p`` with ``p`` and ``p + 1`` free on 127.0.0.1 (at the time of asking)."""
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


# ----------------------------------------------------------------------------- a protocol client

class FoxgloveClient:
    """Connects, subscribes to every advertised channel, collects ``(wall, topic, log_time, msg)``."""

    def __init__(self, port: int, timeout: float = 60.0, expect: int = 1) -> None:
        """``expect``: the channels to wait for before subscribing (a server may advertise them
        in several messages, as its run creates them)."""
        t_end = time.monotonic() + timeout
        while True:
            try:
                self.ws = websocket.create_connection(f"ws://127.0.0.1:{port}", subprotocols=SUBPROTOCOLS,
                                                      timeout=5)
                break
            except (ConnectionError, OSError, websocket.WebSocketException):
                if time.monotonic() > t_end:
                    raise
                time.sleep(0.05)
        self.subprotocol = self.ws.getsubprotocol()
        self.server_info = json.loads(self.ws.recv())
        self.channels: dict[int, dict[str, Any]] = {}
        while len(self.channels) < expect:
            m = json.loads(self.ws.recv())
            if m.get("op") == "advertise":
                self.channels.update({c["id"]: c for c in m["channels"]})
        subs = [{"id": 100 + i, "channelId": cid} for i, cid in enumerate(self.channels)]
        self.topic_of = {s["id"]: self.channels[s["channelId"]]["topic"] for s in subs}
        self.json_of = {s["id"]: self.channels[s["channelId"]]["encoding"] == "json" for s in subs}
        self.ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
        self.received: list[tuple[float, str, int, dict[str, Any]]] = []
        self.closed = threading.Event()
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        self.ws.settimeout(None)
        try:
            while True:
                frame = self.ws.recv()
                if isinstance(frame, str) or not frame:
                    continue
                op, sub, log_time = struct.unpack_from("<BIQ", frame)
                if op == 1:
                    payload = frame[13:]  # JSON, or kept as bytes (a protobuf scene)
                    self.received.append((time.monotonic(), self.topic_of[sub], log_time,
                                          json.loads(payload) if self.json_of[sub] else bytes(payload)))
        except Exception:
            pass
        finally:
            self.closed.set()

    def of(self, topic: str) -> list[dict[str, Any]]:
        return [m for _, tp, _, m in self.received if tp == topic]

    def close(self) -> None:
        self.ws.close()


class Lines:
    """A process's output read line by line in a thread, each line with its arrival time."""

    def __init__(self, stream: Any) -> None:
        self.lines: list[tuple[float, str]] = []
        threading.Thread(target=self._read, args=(stream,), daemon=True).start()

    def _read(self, stream: Any) -> None:
        for line in stream:
            self.lines.append((time.monotonic(), line.rstrip("\n")))

    def text(self) -> str:
        return "\n".join(s for _, s in self.lines)


def start_run(tmp_path: Path, port: int, *extra: str) -> tuple[subprocess.Popen[str], Lines, Lines]:
    p = subprocess.Popen([*CMD, "run", "--scenario", "one-finger", "--duration", "18",
                          "--log", str(tmp_path / "run.csv"), "--plot", str(tmp_path / "run.png"),
                          "--live", f"127.0.0.1:{port}", "--live-wait", "60", "--no-realtime", *extra],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV)
    return p, Lines(p.stdout), Lines(p.stderr)


def test_a_live_run_goes_at_wall_clock_pace_unless_asked_otherwise(tmp_path: Path) -> None:
    """`run --live` on the simulated skin is paced at wall-clock speed (the fixed-rate loop, which
    reports its lateness), so that a viewer sees it as it goes; `--no-realtime` runs it flat out
    in this process; a run without --live is not paced. Read from what the run says it does, not
    from how long it took."""
    from thermoskin.logio import read_log
    from thermoskin.params import load_config
    from thermoskin.sim.boards import lab_boards

    port = free_port_pair()
    log = ["--duration", "0.5", "--log", str(tmp_path / "r.csv")]
    boards = lab_boards(load_config().sensor)  # the default boards: a lab's, seed 0
    for extra, paced in (([], True), (["--no-realtime"], False)):
        p = subprocess.run([*CMD, "run", *log, "--live", f"127.0.0.1:{port}", *extra], env=ENV,
                           capture_output=True, text=True, timeout=120)
        assert p.returncode == 0, p.stdout + p.stderr
        assert ("at wall-clock speed" in p.stdout) == paced, p.stdout
        assert ("loop: 500 steps" in p.stdout) == paced, p.stdout  # the fixed-rate loop's report
        # paced or not, the simulated skin is read through the same boards as a lab buys them
        assert "boards as a lab buys them" in p.stdout, p.stdout
        # (their offset, and their bead's first-order lag behind the warming water: -tau dT/dt)
        d = read_log(tmp_path / "r.csv", required=("t", "T_w", "T_w_true"))
        lagged = boards.offset_T_w - boards.lag_T_w * np.gradient(d["T_w_true"], d["t"])
        assert abs(float((d["T_w"] - d["T_w_true"] - lagged)[100:].mean())) < 0.01
    p = subprocess.run([*CMD, "run", *log], env=ENV, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0 and "wall-clock" not in p.stdout, p.stdout + p.stderr
    forearm = str(Path(__file__).parents[1] / "examples" / "forearm.toml")
    for extra, paced in (([], True), (["--no-realtime"], False)):  # a skin of many patches too
        p = subprocess.run([*CMD, "run", "--skin", forearm, *log, "--live", f"127.0.0.1:{port}", *extra],
                           env=ENV, capture_output=True, text=True, timeout=120, cwd=tmp_path)
        assert p.returncode == 0, p.stdout + p.stderr
        assert ("at wall-clock speed" in p.stdout) == paced, p.stdout


def finish(p: subprocess.Popen[str], out: Lines, err: Lines, timeout: float = 120) -> None:
    try:
        assert p.wait(timeout) == 0, out.text() + err.text()
    finally:
        if p.poll() is None:
            p.kill()
    time.sleep(0.1)  # the reader threads take the last lines


# ----------------------------------------------------------------------------- the parts

def test_parse_address() -> None:
    assert parse_address("8765") == ("127.0.0.1", 8765)
    assert parse_address(":9000") == ("127.0.0.1", 9000)
    assert parse_address("0.0.0.0:9000") == ("0.0.0.0", 9000)
    assert parse_address("localhost:1") == ("localhost", 1)
    assert parse_address("[::1]:65534") == ("::1", 65534)
    for bad, why in (("", "give"), ("abc", "not a number"), ("host:", "not a number"),
                     ("host:80x", "not a number"), ("0", "out of range"), ("65535", "out of range"),
                     ("::1:8765", "IPv6"), ("[::1]8765", "IPv6"), ("a b:8765", "space"),
                     ("-5", "not a number")):
        with pytest.raises(LiveError, match=why) as e:
            parse_address(bad)
        assert "\n" not in str(e.value) and "--live" in str(e.value)


def test_decimator_keeps_the_first_sample_of_each_bin_across_blocks() -> None:
    rng = np.random.default_rng(3)
    k = np.arange(5003)
    t = k * 1e-3  # the loop's clock, as the loop computes it
    for rate, every in ((100.0, 10), (50.0, 20), (1000.0, 1), (250.0, 4)):
        dec = Decimator(rate)
        kept: list[int] = []
        i = 0
        while i < len(t):
            n = int(rng.integers(1, 700))
            kept += (dec.select(t[i:i + n]) + i).tolist()
            i += n
        assert kept == k[k % every == 0].tolist(), rate  # integer arithmetic: k ms in bins of `every`
        one = Decimator(rate)
        assert [int(j) for j in k if one.keep(float(t[j]))] == kept
    with pytest.raises(ValueError):
        Decimator(0.0)


def _loop_block(n: int, k0: int = 0, fault_at: int | None = None) -> dict[str, np.ndarray]:
    """A block of loop rows with distinct values per column (no simulation needed)."""
    k = np.arange(k0, k0 + n, dtype=float)
    t = k * 1e-3
    cols = {"t": t, "T_w": 20 + k * 1e-4, "T_p": 25 + k * 1e-4, "v": np.where(k % 2000 < 1000, 0.05, 0.0),
            "T_a": np.full(n, 20.0), "T_w_cmd": np.full(n, 24.0), "T_p_cmd": 30 + k * 1e-5,
            "drive": np.sin(k / 50), "q_i_hat": k * 1e-5, "dq_i_hat": k * 2e-5,
            "contact": ((k >= 1234) & (k < 2345)).astype(float), "gap": np.zeros(n), "fresh": np.full(n, 7.0),
            "q_i": k * 3e-5, "T_g": 21 + k * 1e-4, "T_w_true": 20 + k * 1e-4, "T_p_true": 25 + k * 1e-4,
            "contact_true": ((k >= 1200) & (k < 2300)).astype(np.int8), "n_fingers": np.ones(n, np.int8),
            "fault": np.zeros(n)}
    cols["T_w"][5] = math.nan  # a NaN reading is sent as null
    if fault_at is not None:
        cols["fault"][fault_at] = 3
    return cols


def test_row_messages_equal_the_recorders_messages(tmp_path: Path) -> None:
    """Each live message is the recorded message (LoopRecorder) at that t, every contact change
    an event, every 10th row of the loop kept at 100 Hz; the tripping row has no estimate."""
    blocks = [_loop_block(700, 0), _loop_block(1000, 700), _loop_block(1291, 1700, fault_at=1290)]
    rec = LoopRecorder(tmp_path / "x.mcap", Config())
    live = RowMessages(100.0)
    sent: list[tuple[str, float, dict[str, Any]]] = []
    for b in blocks:
        rec.write_rows(b)
        sent += list(live.messages(b))
    rec.close()
    recorded = read_mcap(tmp_path / "x.mcap")
    by_t = {topic: {round(m["t"] * 1e6): m for m in msgs} for topic, msgs in recorded.items()}
    signals = [(tp, t, m) for tp, t, m in sent if tp != "/events"]
    assert {tp for tp, _, _ in signals} == {"/skin/sample", "/control", "/skin/estimate", "/sim/truth"}
    for topic, t, msg in signals:
        assert round(t * 1000) % 10 == 0
        ref = by_t[topic][round(t * 1e6)]
        for field, value in msg.items():
            r = ref[field]
            assert (value is None and math.isnan(r)) or value == r, (topic, t, field)
        assert set(msg) <= set(TOPIC_SCHEMAS[topic]["properties"])
    for topic in ("/skin/sample", "/control", "/sim/truth"):  # rows k = 0..2990, every 10th
        assert len([1 for tp, _, _ in signals if tp == topic]) == 300
    est_t = [t for tp, t, _ in signals if tp == "/skin/estimate"]
    assert len(est_t) == 299 and 2.99 not in est_t  # the fault tripped on the last row, k = 2990
    assert round(2.99 * 1e6) not in by_t["/skin/estimate"]
    events = [(round(t, 6), m["kind"]) for tp, t, m in sent if tp == "/events"]
    rec_events = [(round(m["t"], 6), m["kind"]) for m in recorded["/events"]]
    assert events == rec_events == [(1.234, "contact-on"), (2.345, "contact-off")]


def test_layout_names_only_recorded_topics_and_fields() -> None:
    layout = json.loads((ROOT / "docs" / "foxglove-layout.json").read_text())
    paths = []
    for cfg in layout["configById"].values():
        paths += [p["value"] for p in cfg.get("paths", [])]
        if "topicPath" in cfg:
            paths.append(cfg["topicPath"])
    for path in paths:
        m = re.fullmatch(r"(/[a-z/]+)(?:\.(\w+))?", path)
        assert m, path
        topic, field = m.groups()
        assert topic in TOPIC_SCHEMAS, path
        assert field is None or field in TOPIC_SCHEMAS[topic]["properties"], path
    needed = {"/skin/sample.T_w", "/skin/sample.T_p", "/control.T_w_cmd", "/control.T_p_cmd",
              "/skin/estimate.q_i_hat", "/skin/estimate.dq_i_hat", "/skin/estimate.contact", "/events"}
    assert needed <= set(paths)

    def panels(node: Any) -> set[str]:
        return {node} if isinstance(node, str) else panels(node["first"]) | panels(node["second"])

    assert panels(layout["layout"]) == set(layout["configById"])


SERVE = """
import sys
from thermoskin.live import LiveServer
from thermoskin.params import Config
live = LiveServer("127.0.0.1", int(sys.argv[1]), config=Config())
print("ready", flush=True)
sys.stdin.read()
live.close(linger=0)
"""


def test_server_latches_params_and_serves_a_self_contained_page() -> None:
    """A LiveServer in a process of its own (its SDK callbacks would leave foreign-thread entries
    in this process's `threading`, which would make later tests start their loop processes
    by spawn rather than fork)."""
    port = free_port_pair()
    server = subprocess.Popen([sys.executable, "-c", SERVE, str(port)], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True, env=ENV)
    try:
        assert server.stdout is not None and server.stdout.readline().strip() == "ready"
        cfg = Config()
        clients = []
        for _ in range(2):  # two clients, one after the other: both get the parameters
            c = FoxgloveClient(port, timeout=10)
            clients.append(c)
            t_end = time.monotonic() + 5
            while not c.of("/params") and time.monotonic() < t_end:
                time.sleep(0.02)
            assert c.of("/params"), "no /params for a client that came after it was published"
        got = clients[1].of("/params")[0]
        assert got["config"]["skin"]["R_g"] == cfg.skin.R_g
        assert got["config"]["sampling"]["t_s"] == cfg.sampling.t_s
        assert clients[1].subprotocol in SUBPROTOCOLS
        adv = {c["topic"]: c for c in clients[1].channels.values()}
        assert set(adv) == set(TOPIC_SCHEMAS)
        for topic, ch in adv.items():
            assert ch["encoding"] == "json" and ch["schemaEncoding"] == "jsonschema"
            assert json.loads(ch["schema"]) == TOPIC_SCHEMAS[topic]
        for c in clients:
            c.close()
        with urllib.request.urlopen(f"http://127.0.0.1:{port + 1}/", timeout=5) as r:
            assert r.headers["Content-Type"].startswith("text/html")
            html = r.read().decode()
        assert "<canvas" in html and "foxglove.sdk.v1" in html
        # self-contained: no external script, style, image or font, no http(s) address
        assert not re.search(r"\b(src|href)\s*=", html) and "http://" not in html and "https://" not in html
        with pytest.raises(urllib.error.HTTPError):
            urllib.request.urlopen(f"http://127.0.0.1:{port + 1}/other", timeout=5)
        # a port in use is a one-line error (no callback runs: nothing is left in `threading`)
        with pytest.raises(LiveError, match="in use") as e:
            LiveServer("127.0.0.1", port)
        assert "\n" not in str(e.value)
    finally:
        server.communicate("", timeout=10)
    assert server.returncode == 0


# ----------------------------------------------------------------------------- end to end

def test_run_live_foxglove_client(tmp_path: Path) -> None:
    """A short in-process run: topics and schemas as recorded, 100 Hz signals, the contact
    event at the printed detection time and within a second of it being printed."""
    port = free_port_pair()
    p, out, err = start_run(tmp_path, port)
    # every channel before subscribing: the server may advertise them in several messages (on a
    # loaded host the first held only /skin/sample, and the others went unsubscribed)
    client = FoxgloveClient(port, expect=len(TOPIC_SCHEMAS))
    finish(p, out, err)
    client.closed.wait(5)
    client.close()
    assert client.subprotocol in SUBPROTOCOLS
    assert {c["topic"] for c in client.channels.values()} == set(TOPIC_SCHEMAS)
    assert f"ws://127.0.0.1:{port}" in out.text() and f"http://127.0.0.1:{port + 1}/" in out.text()
    # signals: 100 Hz of the loop clock, finite after the first seconds, log_time = t
    samples = client.of("/skin/sample")
    t = np.array([m["t"] for m in samples])
    assert len(t) >= 1700 and np.allclose(np.diff(t), 0.01)
    T_w = np.array([m["T_w"] for m in samples], dtype=float)
    assert np.isfinite(T_w).all() and T_w.max() - T_w.min() > 1  # it warms from ambient
    for _, topic, log_time, m in client.received:
        assert log_time == max(0, round(m["t"] * 1e9)), topic
    est = client.of("/skin/estimate")
    assert {"q_i_hat", "dq_i_hat", "contact"} <= set(est[0])
    assert client.of("/params") and client.of("/params")[0]["config"]["sampling"]["t_s"] == 1e-3
    # the contact: the printed detection ("t = 15.161 s  contact detected") and the event
    printed = [(w, float(m.group(1))) for w, line in err.lines + out.lines
               if (m := re.search(r"t =\s*([\d.]+) s\s+contact detected", line))]
    assert len(printed) == 1, out.text() + err.text()
    w_print, t_detect = printed[0]
    on = [(w, m) for w, tp, _, m in client.received if tp == "/events" and m["kind"] == "contact-on"]
    assert len(on) == 1
    w_event, ev = on[0]
    assert ev["t"] == pytest.approx(t_detect, abs=1e-9)
    # live, not at the end: the event came while the run went on (before it printed its summary);
    # how soon after the printed line is the host's speed, printed, not asserted
    w_summary = next(w for w, line in out.lines if line.startswith("summary:"))
    assert w_event < w_summary, (w_event, w_summary)
    print(f"live: the contact event {(w_event - w_print) * 1e3:+.0f} ms from the printed detection; "
          f"{len(client.received)} messages received")
    # the estimate says the same at that sample
    first_on = next(m for m in est if m["contact"] == 1)
    assert first_on["t"] == pytest.approx(t_detect, abs=0.01)


def replay_to_client(rec_path: Path, speed: float) -> tuple[FoxgloveClient, Lines]:
    """`replay REC --live` at ``speed`` with a Foxglove client subscribed from the start; the
    client (closed, holding what it received) and the command's output, once it has ended."""
    port = free_port_pair()
    p = subprocess.Popen([*CMD, "replay", str(rec_path), "--live", str(port), "--speed", str(speed),
                          "--live-wait", "60"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True, env=ENV)
    out, err = Lines(p.stdout), Lines(p.stderr)
    # every channel of the recording's topics before subscribing (as above)
    client = FoxgloveClient(port, expect=sum(1 for msgs in read_mcap(rec_path).values() if msgs))
    finish(p, out, err, timeout=60)
    client.closed.wait(5)
    client.close()
    return client, out


def test_replay_live_delivers_the_recorded_messages(tmp_path: Path) -> None:
    """A recording of 3 s played at 4x: every event and the parameters, the 100 Hz signals
    equal to the recorded messages at those times, in about 0.75 s."""
    rec_path = tmp_path / "x.mcap"
    rec = LoopRecorder(rec_path, Config())
    rec.event(0.0, "run-start", device="sim", scenario="test")
    for b in (_loop_block(1000, 0), _loop_block(1000, 1000), _loop_block(1000, 2000)):
        rec.write_rows(b)
    rec.event(2.999, "run-end", wall_s=1.0)
    rec.close()
    recorded = read_mcap(rec_path)
    client, out = replay_to_client(rec_path, 4.0)
    got = {topic: client.of(topic) for topic in TOPIC_SCHEMAS}
    assert got["/events"] == json.loads(json.dumps([_nulls(m) for m in recorded["/events"]]))
    assert got["/params"][0]["config"] == json.loads(json.dumps(_nulls(recorded["/params"][0]["config"])))
    for topic in ("/skin/sample", "/control", "/skin/estimate", "/sim/truth"):
        rec_msgs = recorded[topic]
        want = [_nulls(m) for m in rec_msgs if round(m["t"] * 1000) % 10 == 0]
        assert got[topic] == want, topic
    # paced at 4x: a quarter of a second of wall time a second of recording, judged by the
    # median over pairs of samples 1.5 s of recording apart (a loaded host delays a message
    # now and then, the first among them, which shortened the first-to-last span to 0.596 s
    # once; unpaced the slope is about 0, at 1x it is 1)
    wt = [(w, m["t"]) for w, tp, _, m in client.received if tp == "/skin/sample"]
    half = len(wt) // 2
    slope = float(np.median([(wt[i + half][0] - wt[i][0]) / (wt[i + half][1] - wt[i][1])
                             for i in range(len(wt) - half)]))
    assert 0.15 < slope < 0.6, slope
    assert "played" in out.text()


def _nulls(m: dict[str, Any]) -> dict[str, Any]:
    return {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in m.items()}


def test_live_errors_are_one_line(tmp_path: Path) -> None:
    from click.testing import CliRunner

    from thermoskin.cli import main

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        busy = s.getsockname()[1]
        log = ["--log", str(tmp_path / "x.csv"), "--plot", str(tmp_path / "x.png"), "--duration", "1"]
        for args, why in ((["run", "--live", "nope", *log], "not a number"),
                          (["run", "--live", "70000", *log], "out of range"),
                          (["run", "--live", f"127.0.0.1:{busy}", *log], "in use"),
                          (["run", "--live", "--live-rate", "0", *log], "--live-rate"),
                          (["replay", "x.mcap"], "give -o"),
                          (["replay", "x.mcap", "-o", "y.csv", "--speed", "2"], "--live"),
                          (["replay", "x.mcap", "--live", "9000"], "does not exist")):
            r = CliRunner().invoke(main, args)
            assert r.exit_code == 2, (args, r.stdout, r.stderr)
            lines = r.stderr.strip().splitlines()
            assert len(lines) == 1 and why in lines[0] and "Traceback" not in r.stderr, (args, r.stderr)
    assert not (tmp_path / "x.csv").exists()


# ----------------------------------------------------------------------------- the page in Chromium

class Browser:
    """Headless Chromium driven over the Chrome DevTools protocol (a websocket)."""

    def __init__(self, width: int = 1400, height: int = 900) -> None:
        self.profile = tempfile.mkdtemp(prefix="thermoskin-chromium-")
        self.proc = subprocess.Popen([CHROMIUM, *CHROMIUM_FLAGS, f"--user-data-dir={self.profile}",
                                      "--remote-debugging-port=0", f"--window-size={width},{height}",
                                      "--hide-scrollbars", "about:blank"],
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        active = Path(self.profile) / "DevToolsActivePort"
        t_end = time.monotonic() + 30
        while not (active.is_file() and active.read_text().count("\n") >= 1):
            assert self.proc.poll() is None, "chromium exited at start"
            assert time.monotonic() < t_end, "chromium did not open its DevTools port"
            time.sleep(0.05)
        port = int(active.read_text().split()[0])
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=10) as r:
            page = next(t for t in json.load(r) if t["type"] == "page")
        self.ws = websocket.create_connection(page["webSocketDebuggerUrl"], suppress_origin=True, timeout=30)
        self._id = 0

    def call(self, method: str, **params: Any) -> dict[str, Any]:
        self._id += 1
        self.ws.send(json.dumps({"id": self._id, "method": method, "params": params}))
        while True:
            m = json.loads(self.ws.recv())
            if m.get("id") == self._id:
                if "error" in m:
                    raise RuntimeError(f"{method}: {m['error']}")
                return m.get("result", {})

    def eval(self, expr: str) -> Any:
        r = self.call("Runtime.evaluate", expression=expr, returnByValue=True)
        if "exceptionDetails" in r:
            raise RuntimeError(f"{expr}: {r['exceptionDetails']}")
        return r["result"].get("value")

    def screenshot(self, path: Path) -> None:
        import base64

        path.write_bytes(base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"]))

    def close(self) -> None:
        try:
            self.ws.close()
        finally:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
            shutil.rmtree(self.profile, ignore_errors=True)


@pytest.fixture
def browser() -> Iterator[Browser]:
    if not Path(CHROMIUM).exists():
        pytest.skip(f"{CHROMIUM} is absent: the page test needs Debian's chromium (apt-get install chromium)")
    b = Browser()
    yield b
    b.close()


STATE = """(() => { const S = window.thermoskin; if (!S) return null;
  return {connected: S.connected, messages: S.messages,
  contacts: S.contacts, tNow: S.tNow, T_w: S.last.T_w, counts: S.counts,
  events: [...document.querySelectorAll('#events li')].map(li => li.textContent)}; })()"""


def test_page_in_headless_chromium(browser: Browser, tmp_path: Path) -> None:
    """The page connects, its values change as the run goes, the scripted touch shows as a
    contact (indicator count, events list, the plotted truth); screenshot in tmp_path."""
    port = free_port_pair()
    p, out, err = start_run(tmp_path, port)
    browser.call("Page.enable")
    page = f"http://127.0.0.1:{port + 1}/"
    t_end = time.monotonic() + 60
    while True:  # the page server comes up with the run
        try:
            urllib.request.urlopen(page, timeout=2).close()
            break
        except OSError:
            assert time.monotonic() < t_end and p.poll() is None, out.text() + err.text()
            time.sleep(0.1)
    browser.call("Page.navigate", url=page)
    seen: list[dict[str, Any]] = []
    # THERMOSKIN_SCREENSHOT=docs/img/live.png makes the README's picture: taken live, 1 s
    # into the scripted touch (15 to 17 s)
    shot = Path(os.environ.get("THERMOSKIN_SCREENSHOT", tmp_path / "live.png"))
    shot.unlink(missing_ok=True)
    while p.poll() is None and time.monotonic() < t_end:
        s = browser.eval(STATE)
        if s is not None:
            seen.append(s)
            if not shot.exists() and (s.get("tNow") or 0.0) >= 16.0:
                browser.screenshot(shot)
        time.sleep(0.05)
    finish(p, out, err)
    time.sleep(0.3)
    final = browser.eval(STATE)
    if not shot.exists():
        browser.screenshot(shot)
    assert shot.stat().st_size > 10_000
    # live values changed while the run went on
    live = [s for s in seen if s["connected"] and s["messages"] > 0]
    assert len({s["messages"] for s in live}) >= 2, seen[-3:]
    assert len({s.get("T_w") for s in live if s.get("T_w") is not None}) >= 2
    assert final["counts"].get("/skin/sample", 0) >= 1700
    # the scripted touch: detected (counter and list) and plotted from the simulator's truth
    assert final["contacts"] == 1
    on = [float(e.split()[0]) for e in final["events"] if "contact-on" in e]
    assert len(on) == 1 and 15.0 <= on[0] <= 15.5, final["events"]  # the touch begins at 15.0 s
    truth = browser.eval("(() => { const s = window.thermoskin.series.contact_true;"
                         " return s ? s.v.filter(v => v === 1).length : -1; })()")
    assert truth > 100  # 2 s of touch at 100 Hz
    text = browser.eval("document.getElementById('contact-info').textContent")
    assert text.startswith("1 contact")
