"""The test suite's time from a clean clone, as CI runs it: against another checkout, and under load.

Each run is the README's test command (``python -m pytest``, the project's settings: three
workers) on an empty numba cache and an empty pytest cache, as on a fresh clone: its wall time,
the CPU (user and system) of the suite's processes, and its result line. The virtual environment
is this one (installing it is not the suite's time); the package is the checkout's own ``src``,
put first on ``PYTHONPATH``.

``--peer DIR``: the same for another checkout (``DIR``, its root), alternating with this one run
by run (this, peer, peer, this, ...), so that the host's speed, which moves from hour to hour
by a quarter, falls on both alike; the median of the run-by-run ratios is printed.
``--load N``: N CPU-bound processes beside every run (the issue's "two CPU-bound processes").
Prints one JSON line with every run (a failed one with pytest's FAILED lines and its "E" lines,
the assertion and its values) and the medians.

    python benchmarks/suite_time.py [--runs 2] [--peer DIR] [--load 2] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from _proc import check_package_dir, cpu_hogs

ROOT = Path(__file__).resolve().parents[1]


def _commit(root: Path) -> str:
    r = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"], capture_output=True,
                       text=True)
    dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                           capture_output=True, text=True).stdout.strip()
    return r.stdout.strip() + ("+changes" if dirty else "")


def _clean(root: Path) -> None:
    """What a fresh clone has not: numba's cache of the package, pytest's cache."""
    pyc = root / "src" / "thermoskin" / "__pycache__"
    for d in pyc.glob("numba-*") if pyc.is_dir() else ():
        shutil.rmtree(d, ignore_errors=True)
    shutil.rmtree(root / ".pytest_cache", ignore_errors=True)


def one_run(root: Path, load: int) -> dict[str, object]:
    """The suite of the checkout at ``root``, once."""
    _clean(root)
    env = dict(os.environ, PYTHONPATH=str(root / "src"))
    env.pop("NUMBA_CACHE_DIR", None)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    load_avg = os.getloadavg()[0]
    t0 = time.perf_counter()
    with cpu_hogs(load):
        r = subprocess.run([sys.executable, "-m", "pytest"], cwd=root,
                           env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    last = (r.stdout.strip().splitlines() or [""])[-1]
    counts = {k: int(n) for n, k in re.findall(r"(\d+) (passed|failed|error|errors|skipped)", last)}
    return {"checkout": str(root), "commit": _commit(root), "wall_s": round(wall, 1),
            "user_s": round(after.ru_utime - before.ru_utime, 1),
            "sys_s": round(after.ru_stime - before.ru_stime, 1), "returncode": r.returncode,
            "passed": counts.get("passed", 0), "failed": counts.get("failed", 0) + counts.get("error", 0)
            + counts.get("errors", 0), "load_avg_before": round(load_avg, 2), "result": last[-200:],
            "failures": [ln[:300] for ln in r.stdout.splitlines() if ln.startswith(("FAILED", "ERROR"))],
            # what a failure said: pytest's "E" lines (its assertion and values), the first 60
            "errors": [ln[:300] for ln in r.stdout.splitlines() if ln.startswith("E ")][:60]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=2, help="runs of each checkout (default 2)")
    ap.add_argument("--peer", type=Path, default=None,
                    help="another checkout's root, alternated with this one")
    ap.add_argument("--load", type=int, default=0, help="CPU-bound processes beside each run (default 0)")
    ap.add_argument("--json", action="store_true", help="(the output is always one JSON line)")
    a = ap.parse_args()
    if a.peer is not None:
        check_package_dir("--peer", str(a.peer / "src"))
    order: list[Path] = []
    for i in range(a.runs):
        pair = [ROOT] if a.peer is None else ([ROOT, a.peer] if i % 2 == 0 else [a.peer, ROOT])
        order += pair
    runs = []
    for k, root in enumerate(order):
        print(f"suite_time: run {k + 1}/{len(order)}: {root}", file=sys.stderr, flush=True)
        runs.append(one_run(root, a.load))
        print(f"  {runs[-1]['wall_s']} s, {runs[-1]['result']}", file=sys.stderr, flush=True)
        for line in [*runs[-1]["failures"], *runs[-1]["errors"]]:  # type: ignore[misc]
            print(f"  {line}", file=sys.stderr, flush=True)
    out: dict[str, object] = {"runs": runs, "load": a.load, "cores": os.cpu_count()}
    mine = [r["wall_s"] for r in runs if r["checkout"] == str(ROOT)]
    out["median_wall_s"] = float(np.median(mine))
    out["all_passed"] = all(r["returncode"] == 0 for r in runs)
    if a.peer is not None:
        peer = [r["wall_s"] for r in runs if r["checkout"] == str(a.peer)]
        out["peer_median_wall_s"] = float(np.median(peer))
        out["ratio_median"] = round(float(np.median(np.array(mine) / np.array(peer))), 3)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
