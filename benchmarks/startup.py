"""Start-up: `thermoskin --help` and `thermoskin observe` on a 2-second log against
`python -c "import numpy"`, each a process of its own, alternating in one run.

The 2 s log (the simulated skin, 1 kHz) is written first; each command then runs ``--runs``
times in turn with its peer, so that load on a shared machine falls on all of them alike.
The package's bytecode is compiled first, as ``pip install`` does for numpy's (an editable
install leaves it to the first import, which ``PYTHONDONTWRITEBYTECODE``, set on some
machines, forbids: each run would then compile the package's sources again, about 0.07 s).
Each command runs also as the command line entered as a module (``*_unpaused``: Python's
collector never paused, :mod:`thermoskin.startup`), and one ``observe`` of each kind counts its
collections and the time they took (``gc.callbacks``). Prints one JSON line: per command the
median and p99 wall time (s), the ratio of medians to the peer's, and for the program's the
median of its run-by-run ratio to the unpaused one; the collections.

``--peer DIR``: also ``--help`` and ``observe`` with the package under ``DIR`` (another
checkout's ``src``, e.g. the code before a change), in the same turns; each of the two gets
``ratio_to_peer``, the median of its run-by-run ratio to the peer's.

    python benchmarks/startup.py [--runs 15] [--peer DIR] [--json]
"""

from __future__ import annotations

import argparse
import compileall
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _proc import check_package_dir

CLI = [sys.executable, "-c", "from thermoskin.__main__ import main; main()"]  # the `thermoskin` program
#: the same command line entered as a module: the collector never paused (thermoskin.startup)
UNPAUSED = [sys.executable, "-c", "from thermoskin.cli import main; main()"]

#: counts the collections of a command (up to its exit handlers) and the time they took
COUNTED = """
import gc, json, sys, time
n, spent, t0, done = [0], [0.0], [0.0], []
def cb(phase, info):
    if done: return
    if phase == "start": t0[0] = time.perf_counter()
    else: n[0] += 1; spent[0] += time.perf_counter() - t0[0]
gc.callbacks.append(cb)
entry = sys.argv.pop(1)
try:
    if entry == "program":
        from thermoskin.__main__ import main
    else:
        from thermoskin.cli import main
    main()
finally:
    done.append(1)
    print(json.dumps({"collections": n[0], "ms": round(spent[0] * 1e3, 1)}), file=sys.stderr)
"""


def wall(cmd: list[str], env: dict[str, str] | None = None) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                   env=None if env is None else {**os.environ, **env})
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=15, help="runs of each command")
    ap.add_argument("--peer", default=None,
                    help="also the package under this folder (PYTHONPATH), in the same turns")
    ap.add_argument("--json", action="store_true", help="only the JSON line")
    a = ap.parse_args()
    check_package_dir("--peer", a.peer)
    import thermoskin

    compileall.compile_dir(Path(thermoskin.__file__).parent, quiet=1)
    if a.peer:
        compileall.compile_dir(Path(a.peer) / "thermoskin", quiet=1)
    peer_env = {"PYTHONPATH": str(Path(a.peer).resolve())} if a.peer else None
    with tempfile.TemporaryDirectory() as d:
        log, out = Path(d) / "two.csv", Path(d) / "out.csv"
        subprocess.run([*CLI, "simulate", "--duration", "2", "-o", str(log)], check=True,
                       stdout=subprocess.DEVNULL)
        cmds = {"numpy": [sys.executable, "-c", "import numpy"],
                "help": [*CLI, "--help"],
                "observe_2s": [*CLI, "observe", str(log), "-o", str(out)],
                "help_unpaused": [*UNPAUSED, "--help"],
                "observe_2s_unpaused": [*UNPAUSED, "observe", str(log), "-o", str(out)]}
        envs: dict[str, dict[str, str] | None] = dict.fromkeys(cmds)
        if peer_env:
            for k in ("help", "observe_2s"):
                cmds[f"{k}_peer"] = cmds[k]
                envs[f"{k}_peer"] = peer_env
        for k, c in cmds.items():  # caches (numba's, the file system's) warm, as a user's second call
            wall(c, envs[k])
        times: dict[str, list[float]] = {k: [] for k in cmds}
        for _ in range(a.runs):
            for k, c in cmds.items():
                times[k].append(wall(c, envs[k]))
        counted = {}
        for entry in ("program", "module"):
            r = subprocess.run([sys.executable, "-c", COUNTED, entry, "observe", str(log), "-o", str(out)],
                               capture_output=True, text=True, check=True)
            counted[entry] = json.loads(r.stderr.strip().splitlines()[-1])
    peer = float(np.median(times["numpy"]))
    res = {k: {"median_s": round(float(np.median(v)), 3), "p99_s": round(float(np.percentile(v, 99)), 3),
               "ratio_to_numpy": round(float(np.median(v)) / peer, 2)} for k, v in times.items()}
    for k in ("help", "observe_2s"):  # paired with the same command unpaused, run by run
        res[k]["ratio_to_unpaused"] = round(float(np.median(np.array(times[k]) / times[f"{k}_unpaused"])), 2)
        if peer_env:
            res[k]["ratio_to_peer"] = round(float(np.median(np.array(times[k]) / times[f"{k}_peer"])), 3)
    res["collections_observe_2s"] = {"paused": counted["program"], "unpaused": counted["module"]}
    res["runs"] = a.runs
    res["peer"] = a.peer
    if not a.json:
        for k, v in res.items():
            print(k, v)
    print(json.dumps(res))


if __name__ == "__main__":
    main()
