"""MPC solve time per call (eqs. 9-11, H = 100) on a realistic closed-loop trajectory.

The plant is the pipe of eq. 10 with the sheet path (pipe and sheet nodes of Fig. 3),
fed by a tank whose temperature ``T_p`` follows ``T_p_cmd`` with a first-order lag
(``tau_p``, the inner loop and the tank), the on/off pump of Sec. V (the MPC keeps
solving while it is stopped), thermocouple noise, and ``T_w_cmd`` stepping 24 -> 26 ->
28 -> 24 °C as in Fig. 8. Each ``Mpc.step`` is timed with ``perf_counter_ns``; a generic
call (``scipy.optimize.lsq_linear`` on the same QP as box-constrained least squares, and
a one-shot ``daqp.solve`` without a persistent workspace) is timed on states from the
same run. Prints one JSON object as its last line.

    python benchmarks/mpc_solve.py [--n 20000] [--cost rate] [--json]
"""

from __future__ import annotations

import argparse
import json
import time

import daqp
import numpy as np
from scipy.optimize import lsq_linear

from thermoskin.control.mpc import Mpc
from thermoskin.control.pump import PumpLogic
from thermoskin.params import ControlParams, PumpParams, SkinParams
from thermoskin.physics.convection import R_w


def run(n: int, cost: str, seed: int = 0, tau_p: float = 0.05) -> dict[str, object]:
    skin = SkinParams()
    t_s = 1.0e-3
    ctl = ControlParams(cost=cost)
    mpc = Mpc(skin, ctl, t_s)
    pump = PumpLogic(PumpParams(), t_s)
    rng = np.random.default_rng(seed)
    R_on, R_off = R_w(0.141, skin), R_w(0.0, skin)
    T_a = 20.0
    T_w = T_g = T_p = T_a
    mpc.reset(T_a)
    k_p = t_s / tau_p
    times = np.empty(n, dtype=np.int64)
    iters = np.empty(n, dtype=np.int64)
    err = np.empty(n)
    states: list[tuple[float, float, float, float]] = []
    cmds = (24.0, 26.0, 28.0, 24.0)
    for k in range(n):
        T_w_cmd = cmds[min(4 * k // n, 3)]
        T_w_meas = T_w + rng.normal(0.0, 0.02)
        v = pump.step(T_w_meas, T_w_cmd)
        if k % max(1, n // 50) == 0:
            states.append((T_w_meas, T_a, T_w_cmd, mpc.T_p_prev))
        t0 = time.perf_counter_ns()
        T_p_cmd = mpc.step(T_w_meas, T_a, T_w_cmd, pump_on=v > 0)
        times[k] = time.perf_counter_ns() - t0
        iters[k] = mpc.iterations
        err[k] = T_w - T_w_cmd
        # plant
        T_p += k_p * (T_p_cmd - T_p)
        q_p = (T_p - T_w) / (R_on if v > 0 else R_off)
        q_wg = (T_w - T_g) / skin.R_g
        dT_w = (q_p - (T_w - T_a) / skin.R_aw - q_wg) / skin.C_w
        dT_g = (q_wg - (T_g - T_a) / skin.R_ag) / skin.C_g
        T_w, T_g = T_w + t_s * dT_w, T_g + t_s * dT_g
    us = times / 1e3

    # generic solvers on the same QPs, from the same run
    L = np.linalg.cholesky(mpc.P)          # 0.5 u'Pu + q'u = 0.5 ||L'u + L^-1 q||^2 + const
    lsq_t, one_t, dev = [], [], 0.0
    A0 = np.zeros((0, mpc.H))
    for st in states:
        q = mpc.q(*st)
        b = -np.linalg.solve(L, q)
        t0 = time.perf_counter_ns()
        res = lsq_linear(L.T, b, bounds=(ctl.T_p_min, ctl.T_p_max), method="bvls")
        lsq_t.append(time.perf_counter_ns() - t0)
        t0 = time.perf_counter_ns()
        x, _, _, _ = daqp.solve(mpc.P, q, A0, mpc._ub, mpc._lb)
        one_t.append(time.perf_counter_ns() - t0)
        dev = max(dev, float(np.abs(res.x - x).max()))
    p50 = float(np.percentile(us, 50))
    lsq_med = float(np.median(lsq_t)) / 1e3
    one_med = float(np.median(one_t)) / 1e3
    return {
        "calls": n, "H": mpc.H, "cost": cost,
        "p50_us": round(p50, 2),
        "p99_us": round(float(np.percentile(us, 99)), 2),
        "max_us": round(float(us.max()), 2),
        "mean_us": round(float(us.mean()), 2),
        "mean_iterations": round(float(iters.mean()), 3),
        "max_iterations": int(iters.max()),
        "fallbacks": mpc.n_fallback,
        "last_segment_mean_T_w_error_K": round(float(err[-n // 8:].mean()), 4),
        "lsq_linear_median_us": round(lsq_med, 1),
        "lsq_linear_over_p50": round(lsq_med / p50, 1),
        "daqp_solve_oneshot_median_us": round(one_med, 1),
        "daqp_solve_oneshot_over_p50": round(one_med / p50, 2),
        "generic_max_abs_diff": dev,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=20000, help="MPC calls (>= 10000 for the figures)")
    ap.add_argument("--cost", default="rate", choices=("rate", "deviation", "absolute"))
    ap.add_argument("--json", action="store_true", help="only the JSON line")
    a = ap.parse_args()
    res = run(a.n, a.cost)
    if not a.json:
        for k, v in res.items():
            print(f"{k:>30}: {v}")
    print(json.dumps(res))


if __name__ == "__main__":
    main()
