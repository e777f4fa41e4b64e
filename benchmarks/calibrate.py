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
- ``offsets``: the issue's bar. ``--runs`` logs of 300 s at 1 kHz, no touch, commands stepping
  (each its own schedule and noise), offsets of 0.3, -0.2, 0.5 K added to ``T_w, T_p, T_a``, the
  default fit from the preset (``C_w`` given): the wall time of each fit (median, max) and the
  offsets' errors against the injected ones (relative to ``T_w``'s); the same on a chattering
  300 s log; ``thermoskin.fit.check`` on the first log, timed.
- ``lags``: 120 s logs with a 0.2 s pipe sensor and a 1 s air sensor (door steps of 1 K every
  30 s), both fitted: their errors and whether their intervals hold the truth.

    python benchmarks/calibrate.py [--seeds 20] [--seconds 60] [--runs 5] [--only offsets,lags] [--json]
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

from thermoskin.fit.calibrate import DEFAULT_PARAMS, calibrate
from thermoskin.params import Config
from thermoskin.physics.finger import Touch
from thermoskin.sim.run import simulate
from thermoskin.sim.scenarios import SCENARIOS, Scenario, step_schedule

TRUE_SKIN = {"C_w": 0.2, "R_g": 8.0, "R_ag": 1.3, "R_w_flowing": 0.25, "R_w_stopped": 40.0}
BOARDS = {"noise_T": 0.02, "quantum_T": 1 / 128, "period_T_w": 0.0, "period_T_p": 0.0, "period_T_a": 0.0,
          "jitter": 0.0, "lag_T_w": 0.0, "lag_T_p": 0.0, "lag_T_a": 0.0, "offset_T_w": 0.0,
          "offset_T_p": 0.0, "offset_T_a": 0.0}
"""The boards in full (whatever the simulator's defaults): 20 mK in 1/128 K steps, every sample."""
OFFSETS = {"T_w": 0.3, "T_p": -0.2, "T_a": 0.5}
TRUE = {"C_g": 0.0124, "R_g": 8.0, "R_aw": 2100.0, "R_ag": 1.3, "R_w_flowing": 0.25, "R_w_stopped": 40.0}
IDENT = ("R_g", "R_w_flowing", "R_w_stopped")


def sim(sc: Scenario, seed: int, **sensor: float) -> dict[str, np.ndarray]:
    return simulate(sc, Config().replace(skin=TRUE_SKIN, sensor={**BOARDS, "seed": seed, **sensor}))


def offsets_bench(runs: int) -> dict:
    """The 300 s bar (module doc)."""
    from thermoskin.fit.check import check

    prior = Config().replace(skin={"C_w": 0.2})
    rel = {f"offset_{ch}": OFFSETS[ch] - OFFSETS["T_w"] for ch in ("T_p", "T_a")}
    walls, errs, inside, first = [], {p: [] for p in rel}, {p: 0 for p in rel}, None
    for r in range(runs):
        log = sim(Scenario("steps", "", 300.0, setpoints=step_schedule(300.0, seed=3000 + r)), 300 + r)
        for ch, b in OFFSETS.items():
            log[ch] = log[ch] + b
        first = first or log
        t0 = time.perf_counter()
        res = calibrate(log, prior)
        walls.append(time.perf_counter() - t0)
        for p, true in rel.items():
            errs[p].append(res.estimate[p] - true if p in res.names else math.nan)
            inside[p] += res.low[p] <= true <= res.high[p]
    log = sim(SCENARIOS["none"].with_duration(300.0), 399)
    for ch, b in OFFSETS.items():
        log[ch] = log[ch] + b
    t0 = time.perf_counter()
    res = calibrate(log, prior)
    chat_wall = time.perf_counter() - t0
    t0 = time.perf_counter()
    rep = check(first, prior)
    check_wall = time.perf_counter() - t0
    return {
        "log_s": 300.0, "rate_hz": 1000, "runs": runs,
        "wall_s_median": float(np.median(walls)), "wall_s_max": float(np.max(walls)), "wall_s": walls,
        "offset_error_K": {p: v for p, v in errs.items()},
        "offset_error_abs_max_K": {p: float(np.nanmax(np.abs(v))) for p, v in errs.items()},
        "inside_95": {p: inside[p] / runs for p in rel},
        "chattering": {"wall_s": chat_wall, "status": {p: res.status(p) for p in rel},
                       "offset_error_K": {p: (res.estimate[p] - true if p in res.names else None)
                                          for p, true in rel.items()}},
        "check": {"wall_s": check_wall, "advice": rep.advice,
                  "offset_error_K": {p: rep.found.get(p, math.nan) - true for p, true in rel.items()}},
    }


def lags_bench(seeds: int) -> dict:
    """The sensors' lags (module doc)."""
    prior = Config().replace(skin={"C_w": 0.2})
    true = {"lag_T_w": 0.2, "lag_T_a": 1.0}
    amb = tuple((t, 20.0 + (1.0 if (t0 // 30) % 2 else 0.0)) for t0 in np.arange(0.0, 120.0, 30.0)
                for t in (t0, t0 + 0.01))[1:]
    errs, inside, walls = {p: [] for p in true}, {p: 0 for p in true}, []
    for s in range(seeds):
        sc = Scenario("doors", "", 120.0, setpoints=step_schedule(120.0, seed=4000 + s), ambient=amb)
        log = sim(sc, 400 + s, **true)
        for ch, b in OFFSETS.items():
            log[ch] = log[ch] + b
        t0 = time.perf_counter()
        res = calibrate(log, prior, (*DEFAULT_PARAMS, *true))
        walls.append(time.perf_counter() - t0)
        for p, v in true.items():
            errs[p].append(res.estimate[p] / v - 1.0)
            inside[p] += res.low[p] - 1e-3 <= v <= res.high[p] + 1e-3
    return {"log_s": 120.0, "seeds": seeds, "true_s": true,
            "rel_error_median_abs": {p: float(np.median(np.abs(v))) for p, v in errs.items()},
            "rel_error_max_abs": {p: float(np.max(np.abs(v))) for p, v in errs.items()},
            "inside_95_within_a_sample": {p: inside[p] / seeds for p in true},
            "wall_s_median": float(np.median(walls))}


def summary(res, wall: float) -> dict:
    return {
        "fitted": {p: {"estimate": res.estimate[p], "low": res.low[p], "high": res.high[p],
                       "true": TRUE.get(p, 0.0),
                       "rel_error": res.estimate[p] / TRUE[p] - 1.0 if p in TRUE else None,
                       "depends_on": res.dependence.get(p, {})} for p in res.names},
        "held": {p: {"value": res.estimate[p], "true": TRUE.get(p, 0.0), "why": why}
                 for p, why in res.held.items()},
        "rms_mK": res.rms * 1e3, "sigma_mK": res.sigma * 1e3, "colour": res.colour, "model_runs": res.nfev,
        "wall_s": wall,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--runs", type=int, default=5, help="300 s logs for the offsets' bar and its time")
    ap.add_argument("--only", default="coverage,default,touch,chattering,offsets,lags",
                    help="comma-separated sections")
    ap.add_argument("--json", action="store_true", help="only the JSON line")
    a = ap.parse_args()
    only = set(a.only.split(","))
    out: dict = {}
    if "offsets" in only:
        out["offsets"] = offsets_bench(a.runs)
    if "lags" in only:
        out["lags"] = lags_bench(max(2, a.seeds // 4))
    prior_sheet = Config().replace(skin={"C_w": 0.2, "R_ag": 1.3})
    prior = Config().replace(skin={"C_w": 0.2})

    if "coverage" in only:
        coverage(a, prior_sheet, out)
    if "default" in only:
        out["default"] = {}
        for name in ("calibration", "none"):
            log = sim(SCENARIOS[name].with_duration(120.0), 0)
            t0 = time.perf_counter()
            res = calibrate(log, prior)
            out["default"][name] = summary(res, time.perf_counter() - t0)
    if "touch" in only:
        touch(prior_sheet, out)
    if "chattering" in only:
        chattering(a, prior_sheet, out)

    out["machine"] = "shared two-core machine: wall times are noisy"
    print(json.dumps(out))


def coverage(a: argparse.Namespace, prior_sheet: Config, out: dict) -> None:
    """Interval coverage over seeds (module doc)."""
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
    out["coverage"] = {
        "log_s": a.seconds, "seeds": a.seeds,
        "inside_95": {p: inside[p] / a.seeds for p in IDENT},
        "inside_95_all": sum(inside.values()) / (len(IDENT) * a.seeds),
        "z_mean": {p: float(np.mean(z[p])) for p in IDENT},
        "z_sd": {p: float(np.std(z[p], ddof=1)) for p in IDENT},
        "rel_error_median_abs": {p: float(np.median(np.abs(err[p]))) for p in IDENT},
        "rel_error_max_abs": {p: float(np.max(np.abs(err[p]))) for p in IDENT},
        "wall_s_median": float(np.median(walls)), "wall_s_max": float(np.max(walls)),
    }


def touch(prior_sheet: Config, out: dict) -> None:
    """A touch log, fitted without its contact rows (module doc)."""
    touches = tuple(Touch(t_on=t, duration=2.5, n_fingers=2, person="woman1")
                    for t in np.arange(6.0, 90.0, 10.0))
    sc = Scenario("touch", "", 90.0, setpoints=step_schedule(90.0, seed=77), touches=touches)
    log = sim(sc, 3)
    log["contact"] = log["contact_true"].astype(float)
    t0 = time.perf_counter()
    res = calibrate(log, prior_sheet, IDENT)
    out["touch"] = summary(res, time.perf_counter() - t0) | {"stretches": res.n_stretches,
                                                             "usable_s": res.n_samples * 1e-3}


def chattering(a: argparse.Namespace, prior_sheet: Config, out: dict) -> None:
    """Chattering logs, sample by sample against 10 ms blocks (module doc)."""
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


if __name__ == "__main__":
    main()
