"""Cost of the 1 kHz loop body and speed of the closed-loop simulation.

The loop body is ``SkinController.step``: pump logic, observer, detector, MPC (daqp, warm
started) and inner loop, timed per sample with ``perf_counter_ns`` while it controls the
simulated skin through touches (the plant's own step is not counted). Then the whole
closed-loop simulation (plant included) is timed for its real-time factor.
Prints one JSON object as its last line: p50_us, p99_us, max_us, realtime_factor.

    python benchmarks/loop_step.py [--seconds 60] [--json]
"""

from __future__ import annotations

import argparse
import gc
import json
import time

import numpy as np

from thermoskin.params import load_config
from thermoskin.runtime.closed_loop import run_closed_loop
from thermoskin.runtime.controller import SkinController
from thermoskin.sim.plant import SimulatedPlant
from thermoskin.sim.scenarios import SCENARIOS


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0, help="simulated seconds (>= 10)")
    ap.add_argument("--json", action="store_true", help="only the JSON line")
    a = ap.parse_args()
    cfg = load_config()
    sc = SCENARIOS["fingers"].shifted(10.0).with_duration(max(10.0, a.seconds))
    plant = SimulatedPlant(cfg, sc)
    ctrl = SkinController(cfg)
    ctrl.reset(sc.T_a)
    n, t_s = plant.n, cfg.sampling.t_s
    dt = np.empty(n, dtype=np.int64)
    clock = time.perf_counter_ns
    cmd = sc.T_w_cmd
    gc.disable()
    for k in range(n):
        T_w, T_p, T_a = plant.measure()
        t0 = clock()
        ctrl.step(k * t_s, T_w, T_p, T_a, cmd)
        dt[k] = clock() - t0
        plant.apply(ctrl.drive, ctrl.v)
    gc.enable()
    us = dt / 1e3
    res_loop = run_closed_loop(sc, cfg)
    res = {
        "steps": int(n),
        "p50_us": round(float(np.percentile(us, 50)), 1),
        "p99_us": round(float(np.percentile(us, 99)), 1),
        "max_us": round(float(us.max()), 1),
        "mean_us": round(float(us.mean()), 1),
        "mpc_fallbacks": int(ctrl.mpc.n_fallback),
        "realtime_factor": round(res_loop.realtime_factor, 1),
        "closed_loop_wall_s": round(res_loop.wall_s, 2),
        "simulated_s": sc.duration,
    }
    if not a.json:
        print(f"loop body over {n} steps: p50 {res['p50_us']} us, p99 {res['p99_us']} us, "
              f"max {res['max_us']} us; closed loop {res['realtime_factor']}x real time")
    print(json.dumps(res))


if __name__ == "__main__":
    main()
