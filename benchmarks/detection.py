"""Detection figures: the detector's operating curve and every test-bench condition.

Two parts, each on seeds never used in tuning (9000 and up), printing one JSON object as
the last line:

``--curve``: latency against false-alarm rate (the detector's operating curve) for ideal
thermocouples fresh at 1 kHz and for 10 Hz boards (3 ms jitter), with 0.02 K of noise: for
each onset threshold ``h_on``, false alarms per hour on no-touch logs and the onset latency
(median, p90) of one-finger touches and of the default 1-3 finger population, with misses.

``--conditions``: every condition of ``sim.conditions`` (ambient steps and ramps seen late by
a lagging air sensor, holds, taps, bursts of taps, weak and palm touches, cold objects,
noise, 10 Hz boards, 100 Hz logs, set-point changes, an hour with no touch): touches,
hits, misses, false alarms, latency, and the errors of each event's onset, release and
duration against the touch.

    python benchmarks/detection.py --curve [--quiet-h 4] [--seeds 20] [--json]
    python benchmarks/detection.py --conditions [--seeds 3] [--seed0 9000] [--only a,b] [--json]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from typing import Any

import numpy as np

from thermoskin.analysis.evaluation import match_events
from thermoskin.analysis.observe import observe
from thermoskin.params import Config, load_config
from thermoskin.physics.finger import PERSONS, Touch
from thermoskin.sim.conditions import CONDITIONS, decimate, finger_touch, get_condition, touch_train
from thermoskin.sim.run import simulate
from thermoskin.sim.scenarios import SCENARIOS, Scenario

SEED0 = 9000
BOARDS_10HZ = {"period_T_w": 0.1, "period_T_p": 0.1, "period_T_a": 0.1, "jitter": 0.003}


def one_finger(rng: np.random.Generator, t_on: float, duration: float) -> Touch:
    names = sorted(PERSONS)
    return Touch(t_on=t_on, duration=duration, n_fingers=1, person=names[int(rng.integers(3))],
                 T_body=float(rng.uniform(32.0, 35.0)))


def touch_log(seed: int, cfg: Config, population: str, duration: float = 120.0
              ) -> tuple[Scenario, dict[str, np.ndarray]]:
    rng = np.random.default_rng(seed)
    make = one_finger if population == "one" else finger_touch
    touches = touch_train(rng, duration, make=make)
    sc = dataclasses.replace(SCENARIOS["none"], name=f"{population}-{seed}", duration=duration,
                             touches=touches, T_p_drift=float(rng.uniform(0.01, 0.04)),
                             T_p_period=float(rng.uniform(30.0, 90.0)))
    return sc, simulate(sc, cfg.replace(sensor={"seed": seed}))


def latency_stats(lat: list[float]) -> dict[str, float | None]:
    a = np.asarray(lat)
    return {"median_s": float(np.median(a)) if len(a) else None,
            "p90_s": float(np.percentile(a, 90)) if len(a) else None}


def curve(quiet_h: float, seeds: int, h_values: list[float]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for name, sensor in (("1kHz", {}), ("10Hz-boards", BOARDS_10HZ)):
        base = load_config().replace(sensor=sensor) if sensor else load_config()
        quiet = simulate(SCENARIOS["none"].with_duration(3600.0 * quiet_h),
                         base.replace(sensor={"seed": SEED0 + 999}))
        logs = {pop: [touch_log(SEED0 + 100 * (pop == "mixed") + k, base, pop) for k in range(seeds)]
                for pop in ("one", "mixed")}
        rows = []
        for h in h_values:
            cfg = base.replace(detector={"h_on": h})
            row: dict[str, Any] = {"h_on": h,
                                   "false_alarms_per_h": len(observe(quiet, cfg).events) / quiet_h}
            for pop, items in logs.items():
                lat: list[float] = []
                miss = fa = n = 0
                for sc, log in items:
                    m = match_events(sc.touches, observe(log, cfg).events)
                    lat += m.latencies.tolist()
                    miss += m.misses
                    fa += m.false_alarms
                    n += len(sc.touches)
                row[pop] = {"touches": n, "misses": miss, "false_alarms": fa, **latency_stats(lat)}
            rows.append(row)
            print(name, json.dumps(row), file=sys.stderr, flush=True)
        out[name] = {"quiet_h": quiet_h, "points": rows}
    return out


def score_condition(name: str, seed: int, cfg: Config) -> dict[str, Any]:
    cond = get_condition(name, seed)
    log = simulate(cond.scenario, cond.config(cfg))
    if cond.decimate > 1:
        log = decimate(log, cond.decimate)
    res = observe(log, cond.config(cfg))
    m = match_events(cond.scenario.touches, res.events)
    matched = [(tc, e) for tc, e in _pairs(cond.scenario.touches, res.events, m)]
    on = [e.onset - tc.t_on for tc, e in matched]
    rel = [e.release - tc.t_off for tc, e in matched]
    dur = [e.duration - tc.duration for tc, e in matched]
    return {"condition": name, "seed": seed, "touches": len(cond.scenario.touches), "hits": m.hits,
            "misses": m.misses, "false_alarms": m.false_alarms, "latencies": m.latencies.tolist(),
            "onset_err": on, "release_err": rel, "duration_err": dur,
            "signs_right": sum(1 for tc, e in matched if (e.sign > 0) == _warm(tc)),
            "duration_s": cond.scenario.duration}


def _warm(tc: Touch) -> bool:
    T = tc.T_body if tc.T_body is not None else PERSONS[tc.person].T_body
    return T > 25.0


def _pairs(touches: tuple[Touch, ...], events: list[Any], m: Any) -> list[tuple[Touch, Any]]:
    """Each detected touch with the event :func:`match_events` gave it (same rule)."""
    used: set[int] = set()
    out = []
    for tc in touches:
        hit = next((i for i, e in enumerate(events) if i not in used
                    and tc.t_on <= e.detected_at <= tc.t_on + tc.duration + 1.0), None)
        if hit is not None:
            used.add(hit)
            out.append((tc, events[hit]))
    return out


def conditions(seeds: int, seed0: int = SEED0, only: list[str] | None = None) -> dict[str, Any]:
    base = load_config()
    out: dict[str, Any] = {}
    for name in only or CONDITIONS:
        rows = [score_condition(name, seed0 + k, base) for k in range(seeds)]
        lat = [x for r in rows for x in r["latencies"]]
        errs = {k: [abs(x) for r in rows for x in r[k]] for k in ("onset_err", "release_err", "duration_err")}
        out[name] = {
            "touches": sum(r["touches"] for r in rows), "hits": sum(r["hits"] for r in rows),
            "misses": sum(r["misses"] for r in rows), "false_alarms": sum(r["false_alarms"] for r in rows),
            "hours": sum(r["duration_s"] for r in rows) / 3600.0,
            "signs_right": sum(r["signs_right"] for r in rows), **latency_stats(lat),
            **{f"{k}_max_s": (max(v) if v else None) for k, v in errs.items()},
            **{f"{k}_within_0.3s": (float(np.mean(np.asarray(v) <= 0.3)) if v else None)
               for k, v in errs.items()},
        }
        print(name, json.dumps(out[name]), file=sys.stderr, flush=True)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--curve", action="store_true", help="the operating curve (1 kHz and 10 Hz boards)")
    ap.add_argument("--conditions", action="store_true", help="every test-bench condition")
    ap.add_argument("--quiet-h", type=float, default=4.0, help="no-touch hours per curve")
    ap.add_argument("--seeds", type=int, default=None, help="logs per population / condition")
    ap.add_argument("--h", default="3,4,5,6,7", help="h_on values of the curve")
    ap.add_argument("--seed0", type=int, default=SEED0,
                    help="first seed of --conditions (default 9000, held out: tune on others)")
    ap.add_argument("--only", default=None, help="comma-separated conditions (default: all)")
    ap.add_argument("--json", action="store_true", help="only the JSON line on stdout")
    a = ap.parse_args()
    if not (a.curve or a.conditions):
        a.curve = a.conditions = True
    t0 = time.perf_counter()
    res: dict[str, Any] = {}
    if a.curve:
        res["curve"] = curve(a.quiet_h, a.seeds or 20, [float(x) for x in a.h.split(",")])
    if a.conditions:
        res["conditions"] = conditions(a.seeds or 3, a.seed0, a.only.split(",") if a.only else None)
    res["wall_s"] = round(time.perf_counter() - t0, 1)
    print(json.dumps(res))


if __name__ == "__main__":
    main()
