"""Cost of the 1 kHz loop body and speed of the closed-loop simulation.

The loop body is ``SkinController.step``: pump logic, observer, detector, MPC and inner
loop, timed per sample with ``perf_counter_ns`` while it controls the simulated skin
through touches from ambient (the plant's own step is not counted). In the same run and on
the same measurements, stepped in lockstep (alternating which goes first):

* ``body_fast``: the controller as shipped (MPC fast path), which drives the plant;
* ``body_qp``: the same controller with ``mpc.fast = False`` (daqp every sample);
  both also from 10 s on (``*_after_10s``), once the warm-up from ambient, where the
  command sits at ``T_p_max`` and daqp runs, is over;
* ``parts``: a third controller whose blocks are called one by one exactly as
  ``SkinController.step`` does, each timed: the share of the MPC and of the estimator
  (observer + detector) in the body.

Then the whole closed-loop simulation (``run_closed_loop``: plant, supervisor and
recording included) is timed for its real-time factor, alternately with the shipped
controller and with the QP every sample, ``--repeats`` times each (medians reported).
Prints one JSON object as its last line.

    python benchmarks/loop_step.py [--seconds 60] [--repeats 3] [--json]
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import gc
import json
import time
from collections.abc import Iterator

import numpy as np

from thermoskin.control.mpc import Mpc
from thermoskin.params import load_config
from thermoskin.runtime import controller as controller_module
from thermoskin.runtime.closed_loop import run_closed_loop
from thermoskin.runtime.controller import SkinController
from thermoskin.sim.plant import SimulatedPlant
from thermoskin.sim.scenarios import SCENARIOS


def pct(ns: np.ndarray) -> dict[str, float]:
    us = ns / 1e3
    return {"p50_us": round(float(np.percentile(us, 50)), 2),
            "p99_us": round(float(np.percentile(us, 99)), 2),
            "max_us": round(float(us.max()), 1),
            "mean_us": round(float(us.mean()), 2)}


@contextlib.contextmanager
def qp_every_sample() -> Iterator[None]:
    """Controllers built inside get ``Mpc(..., fast=False)`` (benchmark only)."""
    controller_module.Mpc = functools.partial(Mpc, fast=False)
    try:
        yield
    finally:
        controller_module.Mpc = Mpc


def loop_body(seconds: float) -> dict[str, object]:
    cfg = load_config()
    sc = SCENARIOS["fingers"].shifted(10.0).with_duration(max(10.0, seconds))
    plant = SimulatedPlant(cfg, sc)
    ctrl = SkinController(cfg)
    ctrl_qp = SkinController(cfg)
    ctrl_qp.mpc.fast = False
    parts = SkinController(cfg)
    for c in (ctrl, ctrl_qp, parts):
        c.reset(sc.T_a)
    pump, est, mpc, inner = parts.pump, parts.estimator, parts.mpc, parts.inner
    n, t_s = plant.n, cfg.sampling.t_s
    dt = np.empty(n, dtype=np.int64)
    dt_qp = np.empty(n, dtype=np.int64)
    dt_parts = np.empty((n, 4), dtype=np.int64)
    clock = time.perf_counter_ns
    cmd = sc.T_w_cmd
    dev_fast_qp = 0.0
    parts_identical = True
    step, step_qp = ctrl.step, ctrl_qp.step
    gc.collect()
    gc.disable()
    for k in range(n):
        T_w, T_p, T_a = plant.measure()
        t = k * t_s
        if k & 1:
            t0 = clock()
            step(t, T_w, T_p, T_a, cmd)
            t1 = clock()
            step_qp(t, T_w, T_p, T_a, cmd)
            t2 = clock()
            dt[k], dt_qp[k] = t1 - t0, t2 - t1
        else:
            t0 = clock()
            step_qp(t, T_w, T_p, T_a, cmd)
            t1 = clock()
            step(t, T_w, T_p, T_a, cmd)
            t2 = clock()
            dt_qp[k], dt[k] = t1 - t0, t2 - t1
        # SkinController.step, block by block
        t0 = clock()
        v = pump.step(T_w, cmd)
        t1 = clock()
        T_p_cmd = mpc.step(T_w, T_a, cmd, v > 0.0)
        t2 = clock()
        drive = inner.step(T_p, T_p_cmd, T_a)
        t3 = clock()
        contact = est.step(t, T_w, T_p, v, T_a, cmd, 7, drive)
        t4 = clock()
        row = dt_parts[k]
        row[0], row[1], row[2], row[3] = t1 - t0, t4 - t3, t2 - t1, t3 - t2
        parts_identical &= (drive == ctrl.drive and contact == ctrl.contact and v == ctrl.v)
        dev_fast_qp = max(dev_fast_qp, abs(ctrl.T_p_cmd - ctrl_qp.T_p_cmd))
        plant.apply(ctrl.drive, ctrl.v)
    gc.enable()
    overhead = min(c1 - c0 for c0, c1 in ((clock(), clock()) for _ in range(1000)))
    body_sum = float(dt_parts.sum())
    names = ("pump", "estimator", "mpc", "inner")
    return {
        "steps": int(n),
        "simulated_s": sc.duration,
        "body_fast": pct(dt),
        "body_qp": pct(dt_qp),
        "body_fast_after_10s": pct(dt[int(10.0 / t_s):]),    # warmed up, touches from 15 s
        "body_qp_after_10s": pct(dt_qp[int(10.0 / t_s):]),
        "parts": {name: {**pct(dt_parts[:, i]),
                         "share_of_time": round(float(dt_parts[:, i].sum()) / body_sum, 3)}
                  for i, name in enumerate(names)},
        "mpc_share_of_body_p50": round(float(np.percentile(dt_parts[:, 2], 50))
                                       / float(np.percentile(dt_parts.sum(axis=1), 50)), 3),
        "mpc_qp_fraction": round(ctrl.mpc.n_solves / max(1, ctrl.mpc.n_solves + ctrl.mpc.n_fast), 4),
        "mpc_fallbacks": int(ctrl.mpc.n_fallback + ctrl_qp.mpc.n_fallback),
        "fast_vs_qp_max_abs_diff_T_p_cmd_K": dev_fast_qp,
        "parts_reproduce_body": bool(parts_identical),
        "clock_overhead_ns": int(overhead),
    }


def realtime(seconds: float, repeats: int) -> dict[str, object]:
    cfg = load_config()
    sc = SCENARIOS["fingers"].shifted(10.0).with_duration(max(10.0, seconds))
    rtf: dict[str, list[float]] = {"fast": [], "qp": []}
    for _ in range(repeats):
        rtf["fast"].append(run_closed_loop(sc, cfg).realtime_factor)
        with qp_every_sample():
            rtf["qp"].append(run_closed_loop(sc, cfg).realtime_factor)
    return {f"realtime_factor_{k}": round(float(np.median(v)), 1) for k, v in rtf.items()} | {
        f"realtime_factor_{k}_all": [round(x, 1) for x in v] for k, v in rtf.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0, help="simulated seconds (>= 10)")
    ap.add_argument("--repeats", type=int, default=3, help="closed-loop runs of each kind")
    ap.add_argument("--json", action="store_true", help="only the JSON line")
    a = ap.parse_args()
    res = loop_body(a.seconds) | realtime(a.seconds, max(1, a.repeats))
    if not a.json:
        b, q, p = res["body_fast"], res["body_qp"], res["parts"]
        print(f"loop body over {res['steps']} steps: p50 {b['p50_us']} us, p99 {b['p99_us']} us "
              f"(daqp every sample: p50 {q['p50_us']}, p99 {q['p99_us']}); MPC p50 "
              f"{p['mpc']['p50_us']} us, {100 * p['mpc']['share_of_time']:.0f} % of the body's "
              f"time; closed loop {res['realtime_factor_fast']}x real time "
              f"(daqp every sample: {res['realtime_factor_qp']}x)")
    print(json.dumps(res))


if __name__ == "__main__":
    main()
