"""`thermoskin device-emulator`, `run --device serial://`, `--record`, `export`, `replay` as
processes, end to end over a real pseudo-terminal."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from thermoskin.logio import read_log
from thermoskin.runtime.closed_loop import COLUMNS
from thermoskin.runtime.record import iter_messages, read_mcap

pytestmark = [pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs pseudo-terminals"),
              pytest.mark.usefixtures("compiled_estimator")]

ENV = {**os.environ, "PYTHONUNBUFFERED": "1"}
CMD = [sys.executable, "-c", "from thermoskin.cli import main; main()"]
MEASURED = [k for k in COLUMNS if k not in ("q_i", "T_g", "T_w_true", "T_p_true", "contact_true",
                                             "n_fingers")]


def thermoskin(*args: str, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*CMD, *args], capture_output=True, text=True, timeout=timeout, env=ENV)


@pytest.fixture
def emulator(tmp_path: Path) -> Iterator[Callable[..., Path]]:
    procs: list[subprocess.Popen[str]] = []

    def start(*faults: str) -> Path:
        link = tmp_path / f"skin{len(procs)}"
        args = [*CMD, "device-emulator", "--link", str(link)]
        for f in faults:
            args += ["--fault", f]
        p = subprocess.Popen(args, stderr=subprocess.PIPE, text=True, env=ENV)
        procs.append(p)
        t_end = time.monotonic() + 20
        while not link.is_symlink():
            assert p.poll() is None, p.stderr.read() if p.stderr else ""
            assert time.monotonic() < t_end, "the emulator did not create its link"
            time.sleep(0.05)
        return link

    yield start
    for p in procs:
        p.send_signal(signal.SIGTERM)
        try:
            p.wait(10)
        except subprocess.TimeoutExpired:
            p.kill()


def tolerant_config(tmp_path: Path) -> str:
    """A link timeout (0.5 s) that no scheduling stall of a loaded CI machine reaches."""
    p = tmp_path / "tolerant.toml"
    p.write_text("[safety]\nlink_timeout_s = 0.5\n")
    return str(p)


def test_serial_run_record_replay_export(emulator: Callable[..., Path], tmp_path: Path) -> None:
    link = emulator()
    log, rec = tmp_path / "x.csv", tmp_path / "x.mcap"
    r = thermoskin("run", "--device", f"serial://{link}", "--duration", "3", "--log", str(log),
                   "--plot", str(tmp_path / "x.png"), "--record", str(rec),
                   "--config", tolerant_config(tmp_path))
    assert r.returncode == 0, r.stderr
    assert "lateness p50" in r.stdout and "overruns" in r.stdout
    d = read_log(log)
    assert list(d) == MEASURED and len(d["t"]) == 3000
    assert all(np.isfinite(v).all() for v in d.values())
    # the recording: JSON-schema channels, parameters, every sample
    info: dict = {}
    data = read_mcap(rec, info=info)
    assert info["complete"]
    assert len(data["/skin/sample"]) == 3000 and len(data["/skin/estimate"]) == 3000
    assert data["/params"][0]["config"]["safety"]["T_touch_max"] == 40.0
    kinds = [e["kind"] for e in data["/events"]]
    assert kinds[0] == "run-start" and kinds[-1] == "run-end"
    # replay reproduces the live estimates exactly
    out = tmp_path / "replay.csv"
    r = thermoskin("replay", str(rec), "-o", str(out))
    assert r.returncode == 0, r.stdout + r.stderr
    assert "identical" in r.stdout
    rp = read_log(out)
    np.testing.assert_array_equal(rp["q_i_hat"], d["q_i_hat"])
    np.testing.assert_array_equal(rp["contact"], d["contact"])
    # export
    for ext in ("parquet", "csv"):
        r = thermoskin("export", str(rec), "-o", str(tmp_path / f"x.{ext}"))
        assert r.returncode == 0, r.stderr
    import pyarrow.parquet as pq

    tab = pq.read_table(tmp_path / "x.parquet")
    assert tab.num_rows == 3000 and {"T_w", "q_i_hat", "v_cmd", "late"} <= set(tab.column_names)


def test_fault_exits_3_in_safe_state(emulator: Callable[..., Path], tmp_path: Path) -> None:
    link = emulator("overtemp@1.0")
    log = tmp_path / "f.csv"
    r = thermoskin("run", "--device", f"serial://{link}", "--duration", "5", "--log", str(log),
                   "--plot", str(tmp_path / "f.png"), "--record", str(tmp_path / "f.mcap"),
                   "--config", tolerant_config(tmp_path))
    assert r.returncode == 3, r.stdout + r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.startswith("thermoskin: fault:")]
    assert len(lines) == 1 and "overtemp at t = 1.000 s" in lines[0] and "drive 0, pump off" in lines[0]
    d = read_log(log)  # what was recorded is kept
    assert 999 <= len(d["t"]) <= 1001 and d["drive"][-1] == 0 and d["v"][-1] == 0
    ev = [e for e in read_mcap(tmp_path / "f.mcap", ["/events"])["/events"] if e["kind"] == "fault"]
    assert ev and ev[0]["detail"]["name"] == "overtemp"


def test_no_device_is_a_one_line_error(tmp_path: Path) -> None:
    r = thermoskin("run", "--device", f"serial://{tmp_path / 'nothing'}", "--duration", "1",
                   "--log", str(tmp_path / "n.csv"))
    assert r.returncode == 2 and r.stderr.startswith("thermoskin: error: cannot open")
    assert len(r.stderr.strip().splitlines()) == 1  # at once, cold cache or not: no compile first


def test_bad_arguments(tmp_path: Path) -> None:
    r = thermoskin("run", "--device", "usb0", "--duration", "1")
    assert r.returncode == 2 and "sim or serial://PATH" in r.stderr
    r = thermoskin("run", "--duration", "1", "--record", str(tmp_path / "x.bag"))
    assert r.returncode == 2 and ".mcap" in r.stderr
    r = thermoskin("replay", str(tmp_path / "none.mcap"), "-o", str(tmp_path / "o.csv"))
    assert r.returncode == 2 and "does not exist" in r.stderr
    r = thermoskin("device-emulator", "--link", str(tmp_path / "l"), "--fault", "melt@1")
    assert r.returncode == 2 and "KIND@SECONDS" in r.stderr


def test_killed_recording_loses_at_most_a_second(tmp_path: Path) -> None:
    rec = tmp_path / "k.mcap"
    p = subprocess.Popen([*CMD, "run", "--realtime", "--scenario", "none", "--duration", "60",
                          "--log", str(tmp_path / "k.csv"), "--record", str(rec)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV)
    assert p.stdout is not None
    assert p.stdout.readline().startswith("thermoskin run")  # the loop starts right after this
    # once it is recording (its start-up is the loaded machine's business, not under test), the
    # device time it has recorded so far; the loop, paced at wall-clock speed, goes on 2 s
    deadline = time.monotonic() + 120.0
    while time.monotonic() < deadline and (not rec.exists() or rec.stat().st_size < 20_000):
        assert p.poll() is None
        time.sleep(0.05)
    t_seen = max(ti for _, ti, _ in iter_messages(rec, ["/skin/sample"], {}))
    time.sleep(2.0)
    p.kill()
    p.wait(10)
    info: dict = {}
    t = [ti for _, ti, _ in iter_messages(rec, ["/skin/sample"], info)]
    assert info["truncated"] or not info["complete"]
    assert t_seen + 2.0 - 1.0 - 0.1 <= t[-1]  # at most the last second lost
    assert np.allclose(np.diff(t), 1e-3)  # contiguous: nothing lost in between
    # its export ends at the last whole sample, so every command reads it (a sample whose
    # estimate was never written would be a NaN estimate, which logs refuse)
    out = tmp_path / "k_export.csv"
    r = thermoskin("export", str(rec), "-o", str(out))
    assert r.returncode == 0 and "cut off" in r.stderr, r.stderr
    cols = read_log(out)
    assert np.isfinite(cols["q_i_hat"]).all() and t[-1] - 0.01 <= cols["t"][-1] <= t[-1]


def test_interrupted_recording_is_finished(tmp_path: Path) -> None:
    """SIGINT, SIGTERM and SIGHUP to real `thermoskin run --record` processes (in process
    and the fixed-rate loop) all stop the run the same clean way: the safe-state line, exit
    128 + the signal number, the log and the plot written, the recording finished (summary,
    footer) and read to its end by the `mcap` library."""
    from mcap.reader import make_reader
    from mcap.records import Footer
    from mcap.stream_reader import StreamReader

    # each signal once, each loop at least once (five processes, all five pairs of them, were
    # 20 s of the suite's CPU)
    cases = [("sim", signal.SIGINT, []), ("rt-term", signal.SIGTERM, ["--realtime"]),
             ("rt-hup", signal.SIGHUP, ["--realtime"])]
    procs = []
    for name, _, extra in cases:
        # the in-process runs go at about 100x real time: a long run, still going when signalled
        duration = "60" if extra else "1800"
        p = subprocess.Popen([*CMD, "run", *extra, "--scenario", "none", "--duration", duration,
                              "--log", str(tmp_path / f"{name}.csv"), "--plot", str(tmp_path / f"{name}.png"),
                              "--record", str(tmp_path / f"{name}.mcap")],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV)
        procs.append(p)
    for p in procs:
        assert p.stdout is not None
        assert p.stdout.readline().startswith("thermoskin run")  # recording starts right after
    # signal each run once its loop is recording (a loaded machine may take a while to start)
    for p, (name, sig, _) in zip(procs, cases, strict=True):
        path = tmp_path / f"{name}.mcap"
        deadline = time.monotonic() + 120.0  # three runs compiling a cold kernel cache at once
        while time.monotonic() < deadline and (not path.exists() or path.stat().st_size < 20_000):
            assert p.poll() is None, name
            time.sleep(0.05)
        assert path.exists() and path.stat().st_size >= 20_000, f"{name}: not recording after 120 s"
        time.sleep(0.3)
        p.send_signal(sig)
    for p, (name, sig, _) in zip(procs, cases, strict=True):
        _, err = p.communicate(timeout=30)
        assert p.returncode == 128 + sig, (name, err)
        lines = err.strip().splitlines()
        assert len(lines) == 1 and "safe state" in lines[0], (name, err)
        assert lines[0].endswith("log, plot and recording written"), lines[0]  # what was given
        if sig != signal.SIGINT:
            assert f"stopped by {signal.Signals(sig).name}" in lines[0]
        log = read_log(tmp_path / f"{name}.csv")
        assert len(log["t"]) > 100 and (tmp_path / f"{name}.png").stat().st_size > 10_000
        path = tmp_path / f"{name}.mcap"
        with open(path, "rb") as fh:
            assert isinstance(list(StreamReader(fh, validate_crcs=True).records)[-1], Footer)
        with open(path, "rb") as fh:
            reader = make_reader(fh)
            summary = reader.get_summary()
            assert summary is not None and summary.statistics is not None
            assert sum(1 for _ in reader.iter_messages()) == summary.statistics.message_count
        info: dict = {}
        t = [ti for _, ti, _ in iter_messages(path, ["/skin/sample"], info)]
        assert info["complete"] and len(t) > 100, name
        assert np.allclose(np.diff(t), 1e-3)
        np.testing.assert_array_equal(t, log["t"])  # the log and the recording hold the same rows


def _score(truth: Path, events_csv: Path, t_end: float) -> Any:
    """The truth file's touches against a run's --events (those cut by ``t_end`` not scored):
    the match and the touches."""
    import csv

    from thermoskin.analysis.evaluation import match_events, touches_from_truth
    from thermoskin.estimation.events import ContactEvent

    tr = read_log(truth, required=("t", "contact_true", "q_i", "n_fingers", "T_g"))
    touches = touches_from_truth(tr["t"], tr["contact_true"], tr["n_fingers"])
    with open(events_csv) as fh:
        events = [ContactEvent(float(x["onset"]), float(x["detected"]), float(x["release"]),
                               float(x["duration"]), int(x["sign"]), float(x["peak_dq"]),
                               float(x["mean_dq"]), float(x["energy"])) for x in csv.DictReader(fh)]
    return match_events(touches, events, t_end=t_end), touches


def _start(args: list[str], link: Path) -> subprocess.Popen[str]:
    p = subprocess.Popen([*CMD, *args], stderr=subprocess.PIPE, text=True, env=ENV)
    t_end = time.monotonic() + 30
    while not link.is_symlink():
        assert p.poll() is None and time.monotonic() < t_end, p.stderr.read() if p.stderr else ""
        time.sleep(0.05)
    return p


def _stop(p: subprocess.Popen[str]) -> str:
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=20)
    assert p.returncode == 0, err
    return err


def test_serial_run_against_the_firmware_and_a_second_session(tmp_path: Path) -> None:
    """`device-emulator --firmware`: the reference firmware's own code on models of its
    hardware. A 20 s run detects every touch with no false alarm, scored against the truth;
    `observe` of its log gives the live estimates again; a second run on the same device is a
    fresh session (its log and the truth file from t = 0), and a third `run` while the second
    is on is refused in one line; the second, stopped by SIGINT, keeps every sample. The boards
    as configured (`--ideal-sensors`): this is the firmware's path, not what the estimator
    learns of a lab's boards (a touch 5 s in, before it has learnt them)."""
    link, truth = tmp_path / "skin", tmp_path / "truth.csv"
    emu = _start(["device-emulator", "--firmware", "--link", str(link), "--scenario", "mixed", "--truth",
                  str(truth), "--watchdog", "0.5", "--ideal-sensors"], link)
    try:
        r = thermoskin("run", "--device", f"serial://{link}", "--duration", "20", "--config",
                       tolerant_config(tmp_path), "--log", str(tmp_path / "run.csv"), "--events",
                       str(tmp_path / "ev.csv"), "--record", str(tmp_path / "run.mcap"), timeout=120)
        assert r.returncode == 0, r.stderr
        assert "0 corrupted" in r.stdout
        m, _ = _score(truth, tmp_path / "ev.csv", 20.0)
        assert m.false_alarms == 0, m.spurious
        assert m.hits == 3 and not m.missed and np.median(m.latencies) <= 0.6
        log = read_log(tmp_path / "run.csv")
        assert log["t"][0] == 0.0 and len(log["t"]) == 20_000
        o = thermoskin("observe", str(tmp_path / "run.csv"), "-o", str(tmp_path / "obs.csv"))
        assert o.returncode == 0 and "max |q_i_hat difference| 0 W, 0 contact mismatches" in o.stdout
        rp = thermoskin("replay", str(tmp_path / "run.mcap"), "-o", str(tmp_path / "replay.csv"))
        assert rp.returncode == 0 and "identical" in rp.stdout, rp.stdout + rp.stderr
        # a second session on the same device, and a third host while it is on
        second = subprocess.Popen([*CMD, "run", "--device", f"serial://{link}", "--duration", "60",
                                   "--config", tolerant_config(tmp_path), "--log", str(tmp_path / "run2.csv"),
                                   "--plot", str(tmp_path / "run2.png")],
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV)
        deadline = time.monotonic() + 60
        while not (tmp_path / "run2.csv").exists() or (tmp_path / "run2.csv").stat().st_size < 2000:
            assert second.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
        third = thermoskin("run", "--device", f"serial://{link}", "--duration", "2", "--log",
                           str(tmp_path / "run3.csv"))
        # the second stopped as a user stops it once the third has been refused (a 6 s session
        # ended, once, before the third's process had started on a loaded machine)
        assert second.poll() is None
        second.send_signal(signal.SIGINT)
        _, err2 = second.communicate(timeout=60)
        assert second.returncode == 130, err2
    finally:
        err = _stop(emu)
    assert third.returncode == 2 and len(third.stderr.strip().splitlines()) == 1
    assert "in use by another program" in third.stderr
    log2 = read_log(tmp_path / "run2.csv")  # every sample of its session up to the stop
    assert log2["t"][0] == 0.0 and len(log2["t"]) >= 1_000
    np.testing.assert_array_equal(np.round(log2["t"] * 1000), np.arange(len(log2["t"])))
    tr2 = read_log(truth, required=("t", "contact_true"))
    assert tr2["t"][0] == 0.0 and len(tr2["t"]) >= len(log2["t"])  # the truth file started again
    assert "in 2 sessions" in err and "0 frames dropped" in err


def test_a_run_started_any_time_after_the_emulator_is_ready(tmp_path: Path) -> None:
    """At once, and after the emulator idled a while: the first sample is there, no link
    fault; the lateness is never negative."""
    link = tmp_path / "skin"
    emu = _start(["device-emulator", "--link", str(link)], link)
    try:
        for i, wait in enumerate((0.0, 3.0)):
            time.sleep(wait)
            r = thermoskin("run", "--device", f"serial://{link}", "--duration", "2", "--config",
                           tolerant_config(tmp_path), "--log", str(tmp_path / f"r{i}.csv"))
            assert r.returncode == 0, r.stderr
            assert read_log(tmp_path / f"r{i}.csv")["t"][0] == 0.0
            late = [float(x) for x in re.findall(r"lateness p50 (-?\d+) µs, p99 (-?\d+) µs, max (-?\d+)",
                                                 r.stdout)[0]]
            assert min(late) >= 0, r.stdout
    finally:
        _stop(emu)


def test_serial_run_on_a_loaded_host_detects_with_10hz_boards(tmp_path: Path) -> None:
    """The hardware path end to end, on a loaded host: the emulator's 10 Hz boards, the host
    over the pty, two CPU-bound processes beside them on the two cores. Every touch above the
    readings' noise is detected and there is no false alarm, scored against the emulator's
    --truth; where frames came late the run says so. Judged by the device's clock and by
    counts (no duration is asserted). `observe` of the run's log gives the live run again,
    events and estimates bit for bit.

    The processes run at nice 19: the emulator and the loop (real-time priority) meet them as
    they would any others, while the suite's other workers, whose tests start processes at
    normal priority, are not starved meanwhile (`benchmarks/serial_load.py --load 2` runs them
    at nice 0, 75 s). The boards as configured (`--ideal-sensors`): a touch 5 s in comes before
    the estimator has learnt a lab's boards (those are the mismatch benchmark's). One session
    for all of this: each real-time session is its length in CPU of the suite's two cores."""
    import csv

    link, truth = tmp_path / "skin", tmp_path / "truth.csv"
    hogs = [subprocess.Popen([sys.executable, "-c", "import os; os.nice(19)\nwhile True: pass"])
            for _ in range(2)]
    try:
        emu = _start(["device-emulator", "--link", str(link), "--scenario", "mixed", "--truth", str(truth),
                      "--ideal-sensors"], link)
        try:
            r = thermoskin("run", "--device", f"serial://{link}", "--duration", "20", "--config",
                           tolerant_config(tmp_path), "--log", str(tmp_path / "run.csv"), "--events",
                           str(tmp_path / "ev.csv"), timeout=180)
        finally:
            emu_err = _stop(emu)
    finally:
        for h in hogs:
            h.kill()
            h.wait()
    assert r.returncode == 0, r.stderr
    assert "thermocouples every 100 ms" in emu_err  # the emulator's default boards
    assert (tmp_path / "run.png").exists()  # the plot beside the log
    m, touches = _score(truth, tmp_path / "ev.csv", 20.0)
    seen = (m.latencies, m.missed, m.not_scored)
    assert [tc.n_fingers for tc in touches] == [2, 3, 1], seen  # at 5, 11 and 17 s
    assert m.false_alarms == 0, m.spurious
    # issue 43's bar with 10 Hz boards (every touch, median latency <= 0.4 s) is for readings
    # whose one-finger SNR is at least 5; these boards' is about 3, and the run says so in its
    # line ("found late or missed"). The touches whose own SNR (fingers x that) is 5 or more, of
    # two and three fingers, are detected within 0.5 s each; the fingertip's is not asserted (found
    # at 0.6-1.1 s in most sessions, not by the session's end in one loaded suite of seven on
    # 2026-12-07). Both strong touches come before the dispersion has windows of its own (11 s
    # in with these boards): with its prior 2 the first sat at the threshold on its third reading
    # (0.3-0.6 s); with the prior 1 (the model's own) it is found there with margin
    # (docs/sensors.md)
    pat = r"one-finger SNR of (\d+\.\d+) with these readings: below 5"
    snr = float(re.findall(pat, r.stdout + r.stderr)[0])
    lat = m.latency_by_touch()
    strong = [i for i, tc in enumerate(touches) if tc.n_fingers * snr >= 5]
    assert strong == [0, 1] and all(lat[i] is not None and lat[i] <= 0.5 for i in strong), (snr, seen)
    fell_behind = "fell behind" in r.stderr
    link_line = next(ln for ln in r.stdout.splitlines() if ln.startswith("link"))
    pat = r"(\d+) frames late from the device, (\d+) samples handled"
    counts = [int(x) for x in re.findall(pat, link_line)[0]]
    assert fell_behind == (counts[1] > 0 or " 0 lost" not in link_line)
    with open(tmp_path / "ev.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == ["onset", "detected", "release", "duration", "sign", "peak_dq", "mean_dq",
                             "energy", "kind", "toucher", "material", "p_human", "G_hat", "G_sd",
                             "T_f_hat", "T_f_sd", "effusivity_hat"]
    # offline equals live: the same estimator on the same samples
    o = thermoskin("observe", str(tmp_path / "run.csv"), "-o", str(tmp_path / "obs.csv"), "--events",
                   str(tmp_path / "ev2.csv"))
    assert o.returncode == 0, o.stderr
    assert "max |q_i_hat difference| 0 W, 0 contact mismatches" in o.stdout
    assert (tmp_path / "ev2.csv").read_text() == (tmp_path / "ev.csv").read_text()
    live, off = read_log(tmp_path / "run.csv"), read_log(tmp_path / "obs.csv")
    np.testing.assert_array_equal(off["dq_i_hat"], live["dq_i_hat"])


def test_device_hello_answers_with_outputs_off(tmp_path: Path) -> None:
    """`device-hello`: the device's HELLO_ACK and its channels, no COMMAND sent (the device's
    outputs stay off); an open thermocouple is exit 3; no device is exit 2 in one line."""
    link, bad = tmp_path / "skin", tmp_path / "bad"
    emu = _start(["device-emulator", "--link", str(link), "--scenario", "none"], link)
    emu2 = _start(["device-emulator", "--firmware", "--link", str(bad), "--scenario", "none", "--fault",
                   "tc-open@0.5"], bad)
    try:
        r = thermoskin("device-hello", "--device", f"serial://{link}", "--seconds", "1.5")
        r2 = thermoskin("device-hello", "--device", f"serial://{bad}", "--seconds", "1")
    finally:
        _stop(emu)
        _stop(emu2)
    assert r.returncode == 0, r.stderr
    assert "id 0x7E570001" in r.stdout and "every 1000 µs; 0 frames corrupted" in r.stdout
    assert len(re.findall(r"T_[wpa]: 1[56] conversions \(10\.0/s\)", r.stdout)) == 3, r.stdout
    assert "no command yet: outputs off" in r.stdout
    assert r2.returncode == 3 and "T_w: open thermocouple" in r2.stdout and "tc-open" in r2.stdout
    r3 = thermoskin("device-hello", "--device", f"serial://{tmp_path / 'none'}")
    assert r3.returncode == 2 and len(r3.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize("fault,name", [("tc-open@1.5", "tc-open"), ("overtemp@1.5", "overtemp"),
                                        ("serial-drop@1.5", "link")])
def test_firmware_faults_reach_the_safe_state_and_the_host_says_so(tmp_path: Path, fault: str,
                                                                   name: str) -> None:
    """Against the firmware: the fault trips the host (exit 3, one line naming it), and the
    firmware was in its own safe state within the fault's delay (the emulator's stop line: its
    first sample in the safe state, device time): at the conversion that showed the fault for
    tc-open and overtemp (at most 98 ms after its onset, plus a sample), its watchdog for a cut
    cable (0.2 s here: the shipped 50 ms is the firmware's own tests', tests/test_firmware.py)."""
    link = tmp_path / "skin"
    # a stall of this loaded machine is no fault under test: a tolerant link timeout, and the
    # firmware's watchdog at 0.5 s; where it is what is under test (the cut cable), at 0.2 s: the
    # host stalled past 50 ms at 0.78 s in one suite of 2026-12-08, and the firmware's safe state
    # came before the cable was cut (a device fault, not the link's)
    wd_s = 0.2 if name == "link" else 0.5
    wd = ["--watchdog", str(wd_s)]
    emu = _start(["device-emulator", "--firmware", "--link", str(link), "--scenario", "none", "--fault",
                  fault, *wd], link)
    try:
        r = thermoskin("run", "--device", f"serial://{link}", "--duration", "4", "--log",
                       str(tmp_path / "f.csv"), "--plot", str(tmp_path / "f.png"), "--config",
                       tolerant_config(tmp_path))
    finally:
        err = _stop(emu)
    assert r.returncode == 3, r.stdout + r.stderr
    line = [ln for ln in r.stderr.splitlines() if ln.startswith("thermoskin: fault:")]
    assert len(line) == 1 and f"fault: {name} at t = " in line[0]
    pat = r"safe state from t = ([\d.]+) s \(fault at t = ([\d.]+) s"
    t_safe, t_fault = (float(x) for x in re.findall(pat, err)[0])
    assert t_fault == 1.5
    # the watchdog trips on its own clock strictly past wd_s after the last COMMAND's arrival, at
    # the next tick; the stop line is in device time (sample counts), which late ticks on a loaded
    # machine put behind the firmware's clock by at most the samples it then sent late (each owed
    # sample goes out with its own time): that many samples of slack, and 5 at least (CI saw 52 ms;
    # a quiet suite 62 ms with 23 samples sent late)
    late = int(re.findall(r"(\d+) samples sent late", err)[0])
    limit = wd_s + 1e-3 * max(5, late + 1) if name == "link" else 0.098 + 0.002
    assert 0.0 <= round(t_safe - t_fault, 6) <= limit, err
