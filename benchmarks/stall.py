"""Benchmark: the longest stalls of the loop process and of the device emulator on a busy machine.

Each run starts ``thermoskin device-emulator`` and ``thermoskin run --device serial://LINK
--duration S --record RUN.mcap`` while ``--load`` processes (``yes > /dev/null``) keep every
core busy, with the link timeout raised to 0.5 s so that a stall shows as lateness instead
of ending the run. Two conditions:

- ``rt``: as shipped, both processes ask for ``SCHED_FIFO`` (the loop 50, the emulator 40);
- ``normal``: the same with ``CAP_SYS_NICE`` withheld (``setpriv``), so both run at normal
  priority next to the load, as on a machine that does not allow real-time scheduling.

Figures per run (ms): the loop process's own longest stall (``lag``: from a sample being
there to its processing), the lateness of the samples on the host (device jitter, the
emulator's stalls, transport and host), the longest silence the host saw between two
samples (what the link timeout, 50 ms by default, is compared with), and the emulator's own
longest stall (its report at the stop: the latest sample against its deadline). Medians and
maxima over ``--runs`` runs.

    python benchmarks/stall.py --json [--runs 3] [--seconds 20] [--load 2]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

CMD = [sys.executable, "-c", "from thermoskin.cli import main; main()"]
EMU_RE = re.compile(r"max \(longest stall\) (\d+) µs; (\d+) samples sent late.*?(\d+) lost.*priority (.+)$",
                    re.M)


def one_run(folder: Path, seconds: float, rt: bool) -> dict[str, Any]:
    from thermoskin.runtime.record import iter_messages

    pre = [] if rt else ["setpriv", "--inh-caps=-sys_nice", "--bounding-set=-sys_nice"]
    link, rec = folder / "skin", folder / "run.mcap"
    cfg = folder / "tolerant.toml"
    cfg.write_text("[safety]\nlink_timeout_s = 0.5\n")
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    emu = subprocess.Popen([*pre, *CMD, "device-emulator", "--link", str(link)], stderr=subprocess.PIPE,
                           text=True, env=env)
    try:
        t_end = time.monotonic() + 30
        while not link.is_symlink():
            if emu.poll() is not None or time.monotonic() > t_end:
                raise RuntimeError(f"the emulator did not start: {emu.stderr.read() if emu.stderr else ''}")
            time.sleep(0.05)
        host = subprocess.run([*pre, *CMD, "run", "--device", f"serial://{link}", "--duration", str(seconds),
                               "--config", str(cfg), "--record", str(rec), "--log", str(folder / "run.csv")],
                              capture_output=True, text=True, env=env, timeout=seconds + 120)
    finally:
        emu.send_signal(signal.SIGTERM)
        _, emu_err = emu.communicate(timeout=30)
    t, late, lag = [], [], []
    for _, _, m in iter_messages(rec, ["/loop/timing"]):
        t.append(m["t"])
        late.append(m["late"])
        lag.append(m["lag"])
    t_a, late_a = np.asarray(t), np.asarray(late)
    silence = float(np.max(np.diff(t_a + late_a))) if len(t_a) > 1 else float("nan")
    m = EMU_RE.search(emu_err)
    prio = re.search(r"priority (SCHED_FIFO \d+|normal[^\n;]*)", host.stdout)
    return {"exit_code": host.returncode, "rows": len(t),
            "loop_priority": prio.group(1) if prio else "?",
            "loop_stall_ms": float(np.nanmax(lag)) * 1e3 if lag else float("nan"),
            "lateness_p99_ms": float(np.percentile(late_a, 99)) * 1e3 if len(late_a) else float("nan"),
            "lateness_max_ms": float(np.max(late_a)) * 1e3 if len(late_a) else float("nan"),
            "host_silence_max_ms": silence * 1e3,
            "emulator_stall_ms": int(m.group(1)) / 1e3 if m else float("nan"),
            "emulator_late_samples": int(m.group(2)) if m else -1,
            "emulator_lost_samples": int(m.group(3)) if m else -1,
            "emulator_priority": m.group(4).strip() if m else "?"}


def summarise(runs: list[dict[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {"runs": runs}
    for k in ("loop_stall_ms", "lateness_p99_ms", "lateness_max_ms", "host_silence_max_ms",
              "emulator_stall_ms"):
        x = [r[k] for r in runs if r[k] == r[k]]
        if x:
            out[k] = {"median": round(statistics.median(x), 3), "max": round(max(x), 3)}
    out["link_faults_at_50ms"] = sum(1 for r in runs if r["host_silence_max_ms"] > 50.0)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print JSON (the only output format)")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--load", type=int, default=os.cpu_count() or 2,
                    help="busy processes (yes > /dev/null) during the runs (default: one per core)")
    ap.add_argument("--conditions", default="rt,normal", help="rt, normal or both")
    a = ap.parse_args()
    if "normal" in a.conditions and shutil.which("setpriv") is None:
        sys.exit("stall.py: the 'normal' condition needs setpriv (util-linux)")
    load = [subprocess.Popen(["yes"], stdout=subprocess.DEVNULL) for _ in range(a.load)]
    result: dict[str, Any] = {"cores": os.cpu_count(), "load_processes": a.load, "seconds": a.seconds,
                              "note": "shared development machine: other jobs may run too"}
    try:
        for cond in a.conditions.split(","):
            runs = []
            for _ in range(a.runs):
                with tempfile.TemporaryDirectory() as d:
                    runs.append(one_run(Path(d), a.seconds, cond == "rt"))
            result[cond] = summarise(runs)
    finally:
        for p in load:
            p.kill()
            p.wait()
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
