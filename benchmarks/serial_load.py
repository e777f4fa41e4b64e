"""Benchmark: serial runs against the emulator (or the host-tested firmware), scored against the
truth, on a quiet host and with CPU-bound processes beside them.

Each run starts ``thermoskin device-emulator --link LINK --truth TRUTH.csv`` (``--firmware``:
the firmware's own code behind the pty), waits ``--delay`` s after its link appears, then runs
``thermoskin run --device serial://LINK --duration S --events EV.csv`` (the default
configuration: link timeout 50 ms), ``--sessions`` times in a row on the same emulator (each a
fresh session). ``--load N`` processes (``python -c 'while True: pass'``) run beside them for
the whole benchmark. Each run's events are scored against the emulator's truth file
(``analysis.evaluation``: every touch that ended 1 s before the run's end, a hit when a
contact is detected from its onset to 1 s after its release; every other contact a false
alarm). Figures per run: exit code, touches, hits, misses, false alarms, latency median and
max and per touch (its onset, fingers, latency or ``None``), the log's first ``t`` (0 for a
fresh session), the loop's lateness p50/p99/max and overruns and frames late as the run
reports them, and the emulator's own stop line.

    python benchmarks/serial_load.py --json [--runs 2] [--seconds 75] [--load 2] [--firmware]
        [--delay 4] [--sessions 2] [--scenario fingers] [--ideal-sensors]

The emulator's boards are its default, a lab's at 10 Hz (``sim/boards.py``); ``--ideal-sensors``
gives the boards exactly as ``[sensor]`` says (the emulator's default before issue 43).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from _proc import cpu_hogs

CMD = [sys.executable, "-c", "from thermoskin.cli import main; main()"]
LOOP_RE = re.compile(r"lateness p50 (-?[\d.]+) µs, p99 (-?[\d.]+) µs, max (-?[\d.]+) µs")


def score(truth: Path, events: Path, t_end: float) -> dict[str, Any]:
    """The truth file's touches against the events; those the run's end (``t_end``) cut are not
    scored (``match_events``)."""
    import csv

    from thermoskin.analysis.evaluation import match_events, touches_from_truth
    from thermoskin.estimation.events import ContactEvent
    from thermoskin.logio import read_log

    tr = read_log(truth, required=("t", "contact_true", "n_fingers"))
    touches = touches_from_truth(tr["t"], tr["contact_true"], tr["n_fingers"])
    rows = list(csv.DictReader(events.open())) if events.exists() else []
    ev = [ContactEvent(float(x["onset"]), float(x["detected"]), float(x["release"]), float(x["duration"]),
                       int(x["sign"]), float(x["peak_dq"]), float(x["mean_dq"]), float(x["energy"]))
          for x in rows]
    m = match_events(touches, ev, t_end=t_end)
    lat = list(m.latencies)
    return {"touches": len(touches) - m.not_scored, "hits": m.hits, "missed": m.misses,
            "false_alarms": m.false_alarms,
            "latency_median_s": round(float(np.median(lat)), 3) if lat else None,
            "latency_max_s": round(float(np.max(lat)), 3) if lat else None,
            "latency_by_touch": [{"t_on_s": round(tc.t_on, 3), "n_fingers": tc.n_fingers,
                                  "latency_s": None if x is None else round(x, 3)}
                                 for tc, x in zip(touches, m.latency_by_touch(), strict=True)
                                 if tc.t_on < t_end]}


def one_session(folder: Path, link: Path, truth: Path, i: int, seconds: float, pre: list[str],
                extra: list[str]) -> dict[str, Any]:
    log, ev = folder / f"run{i}.csv", folder / f"ev{i}.csv"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    host = subprocess.run([*pre, *CMD, "run", "--device", f"serial://{link}", "--duration", str(seconds),
                           "--log", str(log), "--events", str(ev), *extra],
                          capture_output=True, text=True, env=env, timeout=seconds + 180)
    out: dict[str, Any] = {"exit_code": host.returncode}
    if host.returncode not in (0, 3):
        out["stderr"] = host.stderr.strip()[-400:]
    if host.returncode == 3:
        out["fault"] = host.stderr.strip()[-300:]
    m = LOOP_RE.search(host.stdout)
    if m:
        out.update(lateness_p50_us=float(m.group(1)), lateness_p99_us=float(m.group(2)),
                   lateness_max_us=float(m.group(3)))
    for key, pat in (("overruns", r"(\d+) overruns"), ("frames_late", r"(\d+) frames? late")):
        mm = re.search(pat, host.stdout)
        if mm:
            out[key] = int(mm.group(1))
    out["loop_line"] = next((ln for ln in host.stdout.splitlines() if ln.startswith("loop")), "")
    out["link_line"] = next((ln for ln in host.stdout.splitlines() if ln.startswith("link")), "")
    if log.exists() and log.stat().st_size > 0:
        from thermoskin.logio import read_log

        d = read_log(log, required=("t",), uniform=False)
        t = d["t"]
        out["t_first"] = float(t[0]) if len(t) else None
        out["rows"] = len(t)
        steps = np.diff(t)
        out["gaps"] = int(np.count_nonzero(steps > 1.5e-3))  # samples missing in the log
        out["longest_gap_s"] = round(float(steps.max()), 4) if len(steps) else None
        # the host's truth file: rows up to the end the emulator wrote (flushed every 0.5 s)
        time.sleep(1.2)
        out.update(score(truth, ev, float(t[-1]) if len(t) else 0.0))
    return out


def one_run(folder: Path, seconds: float, delay: float, sessions: int, firmware: bool,
            scenario: str, normal: bool, config: str | None, ideal: bool = False) -> dict[str, Any]:
    link, truth = folder / "skin", folder / "truth.csv"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    pre = ["setpriv", "--inh-caps=-sys_nice", "--bounding-set=-sys_nice"] if normal else []
    extra = ["--config", config] if config else []
    emu = subprocess.Popen([*pre, *CMD, "device-emulator", "--link", str(link), "--truth", str(truth),
                            "--scenario", scenario, *(["--firmware"] if firmware else []),
                            *(["--ideal-sensors"] if ideal else [])],
                           stderr=subprocess.PIPE, text=True, env=env)
    runs = []
    try:
        t_end = time.monotonic() + 60
        while not link.is_symlink():
            if emu.poll() is not None or time.monotonic() > t_end:
                raise RuntimeError(f"the emulator did not start: {emu.stderr.read() if emu.stderr else ''}")
            time.sleep(0.05)
        time.sleep(delay)
        for i in range(sessions):
            runs.append(one_session(folder, link, truth, i, seconds, pre, extra))
    finally:
        emu.send_signal(signal.SIGTERM)
        _, emu_err = emu.communicate(timeout=30)
    return {"sessions": runs, "emulator": [ln for ln in emu_err.splitlines() if "stopped" in ln]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print JSON (the only output format)")
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--seconds", type=float, default=75.0)
    ap.add_argument("--load", type=int, default=0, help="CPU-bound processes beside the runs")
    ap.add_argument("--delay", type=float, default=4.0, help="s between the emulator's link and the run")
    ap.add_argument("--sessions", type=int, default=1, help="runs in a row on one emulator")
    ap.add_argument("--firmware", action="store_true", help="the firmware's code behind the pty")
    ap.add_argument("--scenario", default="fingers")
    ap.add_argument("--ideal-sensors", action="store_true",
                    help="the emulator's boards exactly as [sensor] says (default: a lab's, 10 Hz)")
    ap.add_argument("--normal-priority", action="store_true",
                    help="withhold CAP_SYS_NICE (setpriv): both processes at normal priority, as on a "
                         "machine without real-time scheduling")
    ap.add_argument("--config", default=None, help="a config for the runs (e.g. a longer link timeout)")
    ap.add_argument("--keep", default=None, help="keep each run's files under this folder")
    a = ap.parse_args()
    result: dict[str, Any] = {"cores": os.cpu_count(), "load_processes": a.load, "seconds": a.seconds,
                              "device": "firmware" if a.firmware else "emulator",
                              "scenario": a.scenario, "ideal_sensors": a.ideal_sensors, "delay_s": a.delay,
                              "priority": ("normal" if a.normal_priority else
                                           "as shipped (SCHED_FIFO where allowed)"),
                              "config": a.config,
                              "note": "shared development machine: other jobs may run too"}
    with cpu_hogs(a.load):
        runs = []
        for j in range(a.runs):
            with tempfile.TemporaryDirectory() as d:
                folder = Path(a.keep) / f"run{j}" if a.keep else Path(d)
                folder.mkdir(parents=True, exist_ok=True)
                runs.append(one_run(folder, a.seconds, a.delay, a.sessions, a.firmware, a.scenario,
                                    a.normal_priority, a.config, a.ideal_sensors))
        result["runs"] = runs
        ses = [s for r in runs for s in r["sessions"]]
        result["total"] = {k: sum(s.get(k, 0) or 0 for s in ses)
                           for k in ("touches", "hits", "missed", "false_alarms")}
        result["total"]["faults"] = sum(1 for s in ses if s["exit_code"] != 0)
        lat = [s["latency_median_s"] for s in ses if s.get("latency_median_s") is not None]
        if lat:
            result["total"]["latency_median_s"] = statistics.median(lat)
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
