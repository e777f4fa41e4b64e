"""MPC cost per sample (eqs. 9-11, H = 100) on a realistic closed-loop trajectory.

The plant is the pipe of eq. 10 with the sheet path (pipe and sheet nodes of Fig. 3),
fed by a tank whose temperature ``T_p`` follows ``T_p_cmd`` with a first-order lag
(``tau_p``, the inner loop and the tank), the on/off pump of Sec. V (the MPC keeps
solving while it is stopped), thermocouple noise, and ``T_w_cmd`` stepping 24 -> 26 ->
28 -> 24 °C as in Fig. 8, from ambient.

Measured in the same run, on the same states (``perf_counter_ns`` around each call):

* ``fast``: ``Mpc.step`` with the fast path (the unconstrained optimum when it is
  feasible, daqp otherwise); it drives the plant;
* ``qp``: ``Mpc.step(fast=False)``, the persistent warm-started daqp solve every sample,
  stepped in lockstep on the same measurements (the two alternate which goes first);
* ``oneshot``: ``daqp.solve`` without a persistent workspace, and ``lsq_linear``:
  ``scipy.optimize.lsq_linear`` (bvls) on the same QP as box-constrained least squares,
  on every ``--every``-th state (only the solver call is timed).

Reports p50/p99 of each, the ratios to the warm-started solve, the fraction of samples
that called daqp, and the largest difference between the two controllers' commands.
Prints one JSON object as its last line.

OpenBLAS runs on one thread unless ``OPENBLAS_NUM_THREADS`` says otherwise (daqp and the
loop are single-threaded; on a loaded two-core machine a multi-threaded BLAS under
``lsq_linear`` spends most of its time contending for the cores, 5-6 times the
one-thread figure). The JSON says which.

    python benchmarks/mpc_solve.py [--n 20000] [--every 10] [--cost rate] [--json]
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")     # before numpy loads OpenBLAS

import daqp
import numpy as np
from scipy.optimize import lsq_linear

from thermoskin.control.mpc import Mpc
from thermoskin.control.pump import PumpLogic
from thermoskin.params import ControlParams, PumpParams, SkinParams
from thermoskin.physics.convection import R_w


def pct(x: np.ndarray) -> dict[str, float]:
    """p50, p99 and max of times in µs."""
    return {"p50_us": round(float(np.percentile(x, 50)), 2),
            "p99_us": round(float(np.percentile(x, 99)), 2),
            "max_us": round(float(x.max()), 1), "n": len(x)}


def run(n: int, cost: str, every: int = 10, seed: int = 0, tau_p: float = 0.05
        ) -> dict[str, object]:
    skin = SkinParams()
    t_s = 1.0e-3
    ctl = ControlParams(cost=cost)
    fast = Mpc(skin, ctl, t_s)
    full = Mpc(skin, ctl, t_s, fast=False)
    pump = PumpLogic(PumpParams(), t_s)
    rng = np.random.default_rng(seed)
    R_on, R_off = R_w(0.141, skin), R_w(0.0, skin)
    T_a = 20.0
    T_w = T_g = T_p = T_a
    fast.reset(T_a)
    full.reset(T_a)
    k_p = t_s / tau_p
    t_fast = np.empty(n, dtype=np.int64)
    t_full = np.empty(n, dtype=np.int64)
    qp = np.zeros(n, dtype=bool)
    iters = np.empty(n, dtype=np.int64)
    err = np.empty(n)
    states: list[tuple[float, float, float, float]] = []
    dev_cmd = 0.0
    cmds = (24.0, 26.0, 28.0, 24.0)
    clock = time.perf_counter_ns
    gc.collect()
    gc.disable()
    for k in range(n):
        T_w_cmd = cmds[min(4 * k // n, 3)]
        T_w_meas = T_w + rng.normal(0.0, 0.02)
        v = pump.step(T_w_meas, T_w_cmd)
        on = v > 0
        if k % every == 0:
            states.append((T_w_meas, T_a, T_w_cmd, full.T_p_prev))
        n0 = fast.n_solves
        if k & 1:
            t0 = clock()
            T_p_cmd = fast.step(T_w_meas, T_a, T_w_cmd, on)
            t1 = clock()
            T_p_full = full.step(T_w_meas, T_a, T_w_cmd, on)
            t2 = clock()
            t_fast[k], t_full[k] = t1 - t0, t2 - t1
        else:
            t0 = clock()
            T_p_full = full.step(T_w_meas, T_a, T_w_cmd, on)
            t1 = clock()
            T_p_cmd = fast.step(T_w_meas, T_a, T_w_cmd, on)
            t2 = clock()
            t_full[k], t_fast[k] = t1 - t0, t2 - t1
        qp[k] = fast.n_solves > n0
        iters[k] = full.iterations
        dev_cmd = max(dev_cmd, abs(T_p_cmd - T_p_full))
        err[k] = T_w - T_w_cmd
        # plant
        T_p += k_p * (T_p_cmd - T_p)
        q_p = (T_p - T_w) / (R_on if on else R_off)
        q_wg = (T_w - T_g) / skin.R_g
        dT_w = (q_p - (T_w - T_a) / skin.R_aw - q_wg) / skin.C_w
        dT_g = (q_wg - (T_g - T_a) / skin.R_ag) / skin.C_g
        T_w, T_g = T_w + t_s * dT_w, T_g + t_s * dT_g
    gc.enable()
    us_fast, us_full = t_fast / 1e3, t_full / 1e3

    # generic solvers on the same QPs, from the same run
    L = np.linalg.cholesky(full.P)       # 0.5 u'Pu + q'u = 0.5 ||L'u + L^-1 q||^2 + const
    lsq_t, one_t, dev = [], [], 0.0
    A0 = np.zeros((0, full.H))
    gc.disable()
    for st in states:
        q = full.q(*st)
        b = -np.linalg.solve(L, q)
        t0 = clock()
        res = lsq_linear(L.T, b, bounds=(ctl.T_p_min, ctl.T_p_max), method="bvls")
        t1 = clock()
        x, _, _, _ = daqp.solve(full.P, q, A0, full._ub, full._lb)
        t2 = clock()
        lsq_t.append(t1 - t0)
        one_t.append(t2 - t1)
        dev = max(dev, float(np.abs(res.x - x).max()))
    gc.enable()
    us_lsq, us_one = np.array(lsq_t) / 1e3, np.array(one_t) / 1e3
    ref50 = float(np.percentile(us_full, 50))
    ref99 = float(np.percentile(us_full, 99))

    def ratios(x: np.ndarray) -> dict[str, float]:
        return {"p50_over_qp_p50": round(float(np.percentile(x, 50)) / ref50, 2),
                "p99_over_qp_p99": round(float(np.percentile(x, 99)) / ref99, 2)}

    return {
        "calls": n, "H": full.H, "cost": cost,
        "openblas_threads": os.environ.get("OPENBLAS_NUM_THREADS"),
        "fast": {**pct(us_fast), **ratios(us_fast),
                 "fast_path_samples": pct(us_fast[~qp]) if (~qp).any() else None,
                 "qp_samples": pct(us_fast[qp]) if qp.any() else None,
                 "qp_fraction": round(float(qp.mean()), 4),
                 "qp_fraction_after_first_second": round(float(qp[1000:].mean()), 4)},
        "qp": {**pct(us_full),
               "on_the_fast_runs_qp_samples": pct(us_full[qp]) if qp.any() else None,
               "mean_iterations": round(float(iters.mean()), 3),
               "max_iterations": int(iters.max()), "fallbacks": full.n_fallback},
        "oneshot_daqp": {**pct(us_one), **ratios(us_one)},
        "lsq_linear_bvls": {**pct(us_lsq), **ratios(us_lsq)},
        "fast_vs_qp_max_abs_diff_K": dev_cmd,
        "lsq_vs_daqp_max_abs_diff_K": dev,
        "last_segment_mean_T_w_error_K": round(float(err[-n // 8:].mean()), 4),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=20000, help="MPC samples (>= 10000 for the figures)")
    ap.add_argument("--every", type=int, default=10, help="time the generic solvers every Nth state")
    ap.add_argument("--cost", default="rate", choices=("rate", "deviation", "absolute"))
    ap.add_argument("--json", action="store_true", help="only the JSON line")
    a = ap.parse_args()
    res = run(a.n, a.cost, a.every)
    if not a.json:
        for k, v in res.items():
            print(f"{k:>30}: {v}")
    print(json.dumps(res))


if __name__ == "__main__":
    main()
