"""The host's own stalls: how often a busy thread loses the CPU, and for how long.

A tick of many patches (``benchmarks/patches.py``) ends when the last core finishes its share,
so a stall of either core lands in that tick whole. This measures the stalls with no
estimator at all: one process per core spins reading the clock for ``--seconds`` and records
every gap between two readings longer than 5 µs (the loop's own step is about 0.1 µs). It
prints one JSON line: per core, the gaps per second over 10, 20, 40 and 80 µs and their
p50/p99/max; and, for ticks of ``--tick-us`` on all cores at once, the share of ticks that a
stall over 20 and over 40 µs would hit (``1 - exp(-cores * rate * tick)``, stalls taken as
independent). If that share is above 1 %, such stalls reach a tick's p99.

    python benchmarks/host_jitter.py [--seconds 3] [--tick-us 65] [--json]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

LIMITS_US = (10, 20, 40, 80)


def spin(seconds: float) -> list[int]:
    """Gaps (ns) over 5 µs between consecutive clock readings of a busy loop."""
    pc = time.perf_counter_ns
    gaps: list[int] = []
    end = pc() + int(seconds * 1e9)
    last = pc()
    while last < end:
        now = pc()
        if now - last > 5000:
            gaps.append(now - last)
        last = now
    return gaps


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=3.0, help="spin this long on each core")
    ap.add_argument("--tick-us", type=float, default=65.0, help="a tick, µs (1000 patches: about 65)")
    ap.add_argument("--json", action="store_true", help="only the JSON line")
    a = ap.parse_args()
    cores = len(os.sched_getaffinity(0))
    with ProcessPoolExecutor(cores) as ex:
        per_core = list(ex.map(spin, [a.seconds] * cores))
    out: dict[str, object] = {"cores": cores, "seconds": a.seconds, "tick_us": a.tick_us}
    rates = {lim: [] for lim in LIMITS_US}
    cores_out = []
    for gaps in per_core:
        g = np.array(gaps, dtype=float) * 1e-3
        row: dict[str, float | None] = {f"over_{lim}us_per_s": round(float((g > lim).sum()) / a.seconds, 1)
                                        for lim in LIMITS_US}
        for lim in LIMITS_US:
            rates[lim].append(float((g > lim).sum()) / a.seconds)
        row["p50_us"] = round(float(np.median(g)), 1) if g.size else None
        row["p99_us"] = round(float(np.percentile(g, 99)), 1) if g.size else None
        row["max_us"] = round(float(g.max()), 1) if g.size else None
        cores_out.append(row)
    out["per_core"] = cores_out
    tick = a.tick_us * 1e-6
    for lim in (20, 40):
        total = sum(rates[lim])  # any core's stall holds the tick
        out[f"ticks_hit_over_{lim}us"] = round(1.0 - math.exp(-total * tick), 4)
    if not a.json:
        print(json.dumps(out, indent=1))
    print(json.dumps(out))


if __name__ == "__main__":
    main()
