"""Per-sample cost of the 1 kHz estimation path: TouchEstimator.step (eq. 8, the Kalman filter
and the detector: one call of the compiled kernel from Python, as the loop body makes it).

Times each sample with perf_counter_ns over a simulated log (pump switching, touches), and
the same kernel over the whole log (``TouchEstimator.run``, the loop inside compiled code)
for the ratio: the difference is the cost of calling into the kernel once a sample. Prints
one JSON object as its last line: p50_us, p99_us, max_us per sample, and the array speed.

    python benchmarks/estimator_step.py [--seconds 60] [--config F] [--json]

``--config F``: a TOML file over the default configuration (a change of a default measured
against the default, e.g. ``[estimator] switch_bins = 0``).
"""

from __future__ import annotations

import argparse
import gc
import json
import time

import numpy as np

from thermoskin.estimation.estimator import TouchEstimator
from thermoskin.params import load_config
from thermoskin.sim.run import simulate
from thermoskin.sim.scenarios import SCENARIOS


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0, help="simulated seconds (1 kHz)")
    ap.add_argument("--config", default=None, metavar="F",
                    help="a TOML file over the default configuration")
    ap.add_argument("--json", action="store_true", help="only the JSON line")
    a = ap.parse_args()
    try:
        cfg = load_config(a.config)
    except (OSError, ValueError) as e:
        raise SystemExit(f"estimator_step.py: --config {a.config}: {e}") from None
    log = simulate(SCENARIOS["fingers"].with_duration(a.seconds), cfg)
    t, T_w, T_p, v, T_a = (log[k].tolist() for k in ("t", "T_w", "T_p", "v", "T_a"))
    n = len(t)
    est = TouchEstimator(cfg)
    step = est.step
    dt = np.empty(n, dtype=np.int64)
    clock = time.perf_counter_ns
    gc.disable()
    for k in range(n):
        t0 = clock()
        step(t[k], T_w[k], T_p[k], v[k], T_a[k])
        dt[k] = clock() - t0
    gc.enable()
    us = dt[cfg.observer.n_init:] / 1e3
    est.run(log["t"][:100], log["T_w"][:100], log["T_p"][:100], log["v"][:100], log["T_a"][:100])
    runs = []
    for _ in range(5):
        t0 = time.perf_counter()
        est.run(log["t"], log["T_w"], log["T_p"], log["v"], log["T_a"])
        runs.append(time.perf_counter() - t0)
    batch_s = float(np.median(runs))
    res = {
        "samples": n,
        "p50_us": round(float(np.percentile(us, 50)), 2),
        "p99_us": round(float(np.percentile(us, 99)), 2),
        "max_us": round(float(us.max()), 1),
        "mean_us": round(float(us.mean()), 2),
        "array_us_per_sample": round(batch_s / n * 1e6, 3),
        "step_over_array": round(float(us.mean()) / (batch_s / n * 1e6), 1),
    }
    if not a.json:
        print(f"TouchEstimator step over {n} samples: p50 {res['p50_us']} us, "
              f"p99 {res['p99_us']} us, max {res['max_us']} us; over arrays "
              f"{res['array_us_per_sample']} us/sample")
    print(json.dumps(res))


if __name__ == "__main__":
    main()
