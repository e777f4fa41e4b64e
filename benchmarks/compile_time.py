"""The estimator's compile on an empty cache: what a first run waits for, against another checkout.

A fresh install (or an edit of the compiled code) compiles the estimation kernel on its first
use, and keeps it in numba's cache for the next runs. This times that first use, each in a
process of its own with an empty ``NUMBA_CACHE_DIR``: ``warm_up`` (one patch's sample step,
the whole-log loop and the re-dating fit: what ``thermoskin run`` and ``observe`` compile), and
with ``--parallel`` also the first tick of 200 patches on every core (``step_many_parallel``,
what ``run --skin`` of many patches and ``benchmarks/patches.py`` compile).

``--peer DIR``: the same with another checkout's package (``DIR``, a ``src`` holding
``thermoskin``), alternating with this one run by run, so that the host's load falls on both
alike. Prints one JSON line: per case the median and every run's seconds, and with a peer the
median of the run-by-run ratios.

    python benchmarks/compile_time.py [--runs 3] [--parallel] [--peer DIR] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np
from _proc import check_package_dir

#: the child: the seconds of ``warm_up`` and (argument "1") of the first parallel tick
CHILD = """
import sys, time
import numpy as np
from thermoskin.params import load_config
from thermoskin.estimation.estimator import warm_up
cfg = load_config()
t0 = time.perf_counter()
warm_up(cfg)
out = [time.perf_counter() - t0]
if sys.argv[1] == "1":
    from thermoskin.estimation.patches import PatchEstimators
    n = 200
    pe = PatchEstimators(cfg, n=n, parallel=True)
    x = np.full(n, 24.0)
    t0 = time.perf_counter()
    pe.tick(0.0, x, x, x, np.full(n, np.nan), pe.index(np.zeros(n)), np.full(n, np.nan),
            np.full(n, 7, dtype=np.int64))
    out.append(time.perf_counter() - t0)
print(" ".join(f"{s:.2f}" for s in out))
"""


def first_use(parallel: bool, src: str | None) -> list[float]:
    """Seconds of the child's cases on an empty cache, with ``src`` first on the path if given."""
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        if src:
            env["PYTHONPATH"] = os.pathsep.join(filter(None, [src, env.get("PYTHONPATH")]))
        r = subprocess.run([sys.executable, "-c", CHILD, "1" if parallel else "0"],
                           capture_output=True, text=True, env=env)
    if r.returncode:
        raise SystemExit(f"the child failed ({r.returncode}): {r.stderr.strip()[-400:]}")
    return [float(x) for x in r.stdout.split()]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3, help="first uses timed (each its own process)")
    ap.add_argument("--parallel", action="store_true", help="also the first tick on every core")
    ap.add_argument("--peer", default=None, metavar="DIR", help="another checkout's src, alternating")
    ap.add_argument("--json", action="store_true", help="only the JSON line")
    a = ap.parse_args()
    check_package_dir("--peer", a.peer)
    if a.runs < 1:
        raise SystemExit(f"--runs {a.runs}: at least 1")
    names = ["warm_up_s"] + (["parallel_tick_s"] if a.parallel else [])
    runs: dict[str, list[list[float]]] = {"this": [], "peer": []}
    for i in range(a.runs):
        order = ("this", "peer") if i % 2 == 0 else ("peer", "this")
        for who in order:
            if who == "peer" and not a.peer:
                continue
            runs[who].append(first_use(a.parallel, a.peer if who == "peer" else None))
            if not a.json:
                print(who, runs[who][-1], file=sys.stderr)
    out: dict[str, object] = {"runs": a.runs}
    for k, name in enumerate(names):
        mine = [r[k] for r in runs["this"]]
        case: dict[str, object] = {"median": round(float(np.median(mine)), 1), "all": mine}
        if a.peer:
            theirs = [r[k] for r in runs["peer"]]
            case["peer_median"] = round(float(np.median(theirs)), 1)
            case["peer_all"] = theirs
            case["ratio"] = round(float(np.median(np.divide(mine, theirs))), 3)
        out[name] = case
    print(json.dumps(out))


if __name__ == "__main__":
    main()
