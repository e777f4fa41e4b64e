"""Recovery, interval coverage and time of ``thermoskin.fit.calibrate`` on simulated logs.

The skin is not the preset (C_w 0.2, R_g 8, R_ag 1.3, R_w_flowing 0.25, R_w_stopped 40);
the fit starts from the preset with the true ``C_w`` (the heat scale, which no log fixes).

- ``coverage``: per seed a no-touch log with commands stepping every 5 s (its own
  schedule and sensor noise), ``R_g, R_w_flowing, R_w_stopped`` fitted with the sheet's
  ``R_ag`` given; the share of 95 % intervals holding the truth, ``z = (ln p - ln p_true)/sd``
  (mean, sd: 0 and 1 if the intervals are right), relative errors, wall time.
- ``default``: the default parameters on the named ``calibration`` scenario (120 s) and on
  ``none`` (120 s, pump chattering): what is fitted, what held, errors, time.
- ``touch``: 90 s with a touch every 10 s, fitted without the contact rows.
- ``chattering``: ``none`` logs (the pump switching on the measured ``T_w`` every 50 ms),
  ``R_g, R_w_flowing`` fitted with the rest given, every sample against 10 ms block means.

    python benchmarks/calibrate.py [--seeds 20] [--seconds 60] [--json]
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

from thermoskin.fit.calibrate import calibrate
from thermoskin.params import Config
from thermoskin.physics.finger import Touch
from thermoskin.sim.run import simulate
from thermoskin.sim.scenarios import SCENARIOS, Scenario, step_schedule

TRUE_SKIN = {"C_w": 0.2, "R_g": 8.0, "R_ag": 1.3, "R_w_flowing": 0.25, "R_w_stopped": 40.0}
TRUE = {"C_g": 0.0124, "R_g": 8.0, "R_aw": 2100.0, "R_ag": 1.3, "R_w_flowing": 0.25, "R_w_stopped": 40.0}
IDENT = ("R_g", "R_w_flowing", "R_w_stopped")


def sim(sc: Scenario, seed: int) -> dict[str, np.ndarray]:
    return simulate(sc, Config().replace(skin=TRUE_SKIN, sensor={"seed": seed}))


def summary(res, wall: float) -> dict:
    return {
        "fitted": {p: {"estimate": res.estimate[p], "low": res.low[p], "high": res.high[p],
                       "true": TRUE[p], "rel_error": res.estimate[p] / TRUE[p] - 1.0,
                       "depends_on": res.dependence.get(p, {})} for p in res.names},
        "held": {p: {"value": res.estimate[p], "true": TRUE[p], "why": why} for p, why in res.held.items()},
        "rms_mK": res.rms * 1e3, "sigma_mK": res.sigma * 1e3, "colour": res.colour, "model_runs": res.nfev,
        "wall_s": wall,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--json", action="store_true", help="only the JSON line")
    a = ap.parse_args()
    prior_sheet = Config().replace(skin={"C_w": 0.2, "R_ag": 1.3})
    prior = Config().replace(skin={"C_w": 0.2})

    z: dict[str, list[float]] = {p: [] for p in IDENT}
    err: dict[str, list[float]] = {p: [] for p in IDENT}
    inside = dict.fromkeys(IDENT, 0)
    walls = []
    for seed in range(a.seeds):
        schedule = step_schedule(a.seconds, seed=1000 + seed)
        log = sim(Scenario("steps", "", a.seconds, setpoints=schedule), seed)
        t0 = time.perf_counter()
        res = calibrate(log, prior_sheet, IDENT)
        walls.append(time.perf_counter() - t0)
        for p in IDENT:
            lo, hi = res.interval(p)
            inside[p] += lo <= TRUE[p] <= hi
            z[p].append((math.log(res.estimate[p]) - math.log(TRUE[p])) / res.sd_log[p])
            err[p].append(res.estimate[p] / TRUE[p] - 1.0)
        if not a.json:
            fits = ", ".join(f"{p} {res.estimate[p]:.4g} (z {z[p][-1]:+.2f})" for p in IDENT)
            print(f"seed {seed}: {fits}; {walls[-1]:.2f} s")
    out: dict = {"coverage": {
        "log_s": a.seconds, "seeds": a.seeds,
        "inside_95": {p: inside[p] / a.seeds for p in IDENT},
        "inside_95_all": sum(inside.values()) / (len(IDENT) * a.seeds),
        "z_mean": {p: float(np.mean(z[p])) for p in IDENT},
        "z_sd": {p: float(np.std(z[p], ddof=1)) for p in IDENT},
        "rel_error_median_abs": {p: float(np.median(np.abs(err[p]))) for p in IDENT},
        "rel_error_max_abs": {p: float(np.max(np.abs(err[p]))) for p in IDENT},
        "wall_s_median": float(np.median(walls)), "wall_s_max": float(np.max(walls)),
    }}

    out["default"] = {}
    for name in ("calibration", "none"):
        log = sim(SCENARIOS[name].with_duration(120.0), 0)
        t0 = time.perf_counter()
        res = calibrate(log, prior)
        out["default"][name] = summary(res, time.perf_counter() - t0)

    touches = tuple(Touch(t_on=t, duration=2.5, n_fingers=2, person="woman1")
                    for t in np.arange(6.0, 90.0, 10.0))
    sc = Scenario("touch", "", 90.0, setpoints=step_schedule(90.0, seed=77), touches=touches)
    log = sim(sc, 3)
    log["contact"] = log["contact_true"].astype(float)
    t0 = time.perf_counter()
    res = calibrate(log, prior_sheet, IDENT)
    out["touch"] = summary(res, time.perf_counter() - t0) | {"stretches": res.n_stretches,
                                                             "usable_s": res.n_samples * 1e-3}
    out["chattering"] = {}
    prior_rest = prior_sheet.replace(skin={"R_w_stopped": 40.0})
    for t_fit in (0.0, 0.01):
        zc: dict[str, list[float]] = {"R_g": [], "R_w_flowing": []}
        for seed in range(max(2, a.seeds // 2)):
            log = sim(SCENARIOS["none"].with_duration(a.seconds), seed)
            res = calibrate(log, prior_rest, tuple(zc), t_fit=t_fit)
            for p in zc:
                zc[p].append((math.log(res.estimate[p]) - math.log(TRUE[p])) / res.sd_log[p])
        out["chattering"][f"t_fit={t_fit:g}"] = {
            p: {"z_mean": float(np.mean(v)), "z_sd": float(np.std(v, ddof=1)),
                "inside_95": float(np.mean(np.abs(v) < 1.96))} for p, v in zc.items()}
    out["machine"] = "shared two-core machine: wall times are noisy"
    print(json.dumps(out))


if __name__ == "__main__":
    main()
