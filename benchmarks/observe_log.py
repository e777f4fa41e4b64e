"""`thermoskin observe` on long logs: time and peak memory against polars alone, CSV and Parquet.

A 1 h, 1 kHz log (3.6 M rows: t,T_w,T_p,v,T_a,T_w_cmd from the simulated skin) is written as
CSV and as Parquet; longer logs repeat it (time shifted). Each command runs as a process of
its own, several times, alternating with its peer; wall time and peak resident memory (the
process's own, from ``wait4``) are reported as medians. The peer is polars alone reading the
file and writing the same columns plus two (what ``observe`` adds, less the estimation).
The package's bytecode is compiled first, as ``pip install`` does for polars' (see
``startup.py``). Prints one JSON line.

    python benchmarks/observe_log.py [--hours 1] [--runs 3] [--memory-hours 4,8] [--events] [--json]
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

PEER = """
import sys, polars as pl
src, dst = sys.argv[1], sys.argv[2]
df = pl.read_parquet(src) if src.endswith('.parquet') else pl.read_csv(src)
df = df.with_columns((pl.col('T_w') * 1.0).alias('q_i_hat'), (pl.col('T_p') * 1.0).alias('dq_i_hat'))
df.write_parquet(dst) if dst.endswith('.parquet') else df.write_csv(dst, float_precision=None)
"""


def make_log(path: Path, hours: float, base: dict[str, np.ndarray]) -> None:
    from thermoskin.logio import LogWriter

    n1 = len(base["t"])
    dt = float(base["t"][1] - base["t"][0])
    reps = int(np.ceil(hours * 3600.0 / (n1 * dt)))
    with LogWriter(path, list(base)) as w:
        for r in range(reps):
            chunk = dict(base)
            chunk["t"] = base["t"] + r * n1 * dt
            w.write(chunk)


def timed(cmd: list[str]) -> tuple[float, float]:
    """Wall seconds and peak resident MiB of one process."""
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, ru = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    if status != 0:
        raise RuntimeError(f"{cmd} failed: {p.stderr.read().decode() if p.stderr else ''}")
    return wall, ru.ru_maxrss / 1024.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=1.0)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--memory-hours", default="4,8", help="longer logs: observe's peak memory only")
    ap.add_argument("--events", action="store_true",
                    help="also observe with --events (what touched: its 50 ms bins and each contact)")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    import thermoskin
    from thermoskin.params import load_config
    from thermoskin.sim.run import simulate
    from thermoskin.sim.scenarios import random_scenario

    compileall.compile_dir(Path(thermoskin.__file__).parent, quiet=1)
    cfg = load_config()
    sim = simulate(random_scenario(31, 600.0), cfg)
    base = {k: sim[k] for k in ("t", "T_w", "T_p", "v", "T_a", "T_w_cmd")}
    tool = [sys.executable, "-c", "from thermoskin.__main__ import main; main()"]  # the `thermoskin` program
    res: dict[str, object] = {"hours": a.hours, "runs": a.runs}
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        for fmt in ("csv", "parquet"):
            src = d / f"log.{fmt}"
            make_log(src, a.hours, base)
            ours, peer, evs = [], [], []
            for _ in range(a.runs):
                ours.append(timed([*tool, "observe", str(src), "-o", str(d / f"o.{fmt}")]))
                peer.append(timed([sys.executable, "-c", PEER, str(src), str(d / f"p.{fmt}")]))
                if a.events:
                    evs.append(timed([*tool, "observe", str(src), "-o", str(d / f"o.{fmt}"),
                                      "--events", str(d / "ev.csv")])[0])
            ow, om = np.median([x[0] for x in ours]), np.median([x[1] for x in ours])
            pw, pm = np.median([x[0] for x in peer]), np.median([x[1] for x in peer])
            res[fmt] = {"observe_s": round(float(ow), 2), "polars_s": round(float(pw), 2),
                        "ratio": round(float(ow / pw), 2), "observe_peak_mib": round(float(om)),
                        "polars_peak_mib": round(float(pm)), "file_mib": round(src.stat().st_size / 2**20)}
            if evs:
                res[fmt]["observe_events_s"] = round(float(np.median(evs)), 2)
            print(fmt, res[fmt], file=sys.stderr, flush=True)
            src.unlink()
        for h in (float(x) for x in a.memory_hours.split(",") if x):
            src = d / "long.parquet"
            make_log(src, h, base)
            wall, mib = timed([*tool, "observe", str(src), "-o", str(d / "o.parquet")])
            res[f"{h:g}h_parquet"] = {"observe_s": round(wall, 1), "observe_peak_mib": round(mib)}
            print(h, res[f"{h:g}h_parquet"], file=sys.stderr, flush=True)
            src.unlink()
    print(json.dumps(res))


if __name__ == "__main__":
    main()
