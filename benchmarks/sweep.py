"""Time ``thermoskin sweep`` on a sweep file (default ``examples/sweep.toml``, 1000 points of 60 s).

Each run starts from an empty results file (a fresh temporary folder); the compiled kernel is
warmed first on a 1-point sweep so compilation is not timed. Prints JSON: the wall time of
each run, their median, points and point-samples per second. ``--dask local`` (or an
address) runs the chunks on a Dask cluster instead (cluster start-up included).

    python benchmarks/sweep.py --json [--runs 3] [--sweep FILE] [--dask local]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from thermoskin.sweep.engine import run_chunk  # noqa: E402
from thermoskin.sweep.run import run_sweep  # noqa: E402
from thermoskin.sweep.spec import load_sweep  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sweep", type=Path, default=ROOT / "examples" / "sweep.toml")
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--dask", default=None)
    ap.add_argument("--json", action="store_true", help="JSON only (the default output anyway)")
    a = ap.parse_args()
    sw = load_sweep(a.sweep)
    p = sw.points[0]
    run_chunk([(p.cfg, p.seed)], sw.scenario)  # compile / load the cached kernel
    walls = []
    for _ in range(a.runs):
        with tempfile.TemporaryDirectory() as d:
            t0 = time.perf_counter()
            res = run_sweep(sw, Path(d) / "r.parquet", dask=a.dask)
            walls.append(time.perf_counter() - t0)
            assert res.rows == len(sw.points)
    n = len(sw.points)
    samples = sum(round(sw.scenario.duration / q.cfg.sampling.t_s) for q in sw.points)
    med = statistics.median(walls)
    print(json.dumps({"sweep": str(a.sweep), "points": n, "duration_s": sw.scenario.duration,
                      "loop": sw.scenario.loop, "dask": a.dask, "runs": len(walls),
                      "wall_s": [round(w, 2) for w in walls], "median_s": round(med, 2),
                      "max_s": round(max(walls), 2), "points_per_s": round(n / med, 2),
                      "point_samples_per_s": round(samples / med), "note": "shared two-core machine"}))


if __name__ == "__main__":
    main()
