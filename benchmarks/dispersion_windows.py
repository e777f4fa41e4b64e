"""The onset evidence's dispersion over short and long windows, per mismatch condition.

For each condition of ``benchmarks/mismatch.py`` (its boards and skin, no touch), one log of
``--duration`` s estimated with the default configuration; the evidence ``z² = (sum g e/S)² /
sum g²/S`` over consecutive windows of 0.4, 2 and 8 s, and over each phase of the pump's cycle
(from one switch to the next), taken from ``--start`` s on where no contact was seen, as its
median over chi2(1)'s (1 where the innovations are white); and the kernel's trackers at the
end (``rho``; ``rho_phases``, the phases'). This is what ``docs/model.md`` (Long windows,
Phase windows) quotes: a tank held on one coarse step gives far more over 8 s than over 0.4 s,
a misfit locked to the pump's cycle (a lighter sheet, a lag being learnt) far more over the
phases. Also the events of each log (all false: no touch) with the long windows and without
(``detector.rho_window_long = 0``). ``--touches``: the condition's touch log instead (the
mismatch grid's), the windows over its stretches without contact, and the short windows' and
the phases' trackers' 10th and 90th percentiles over it, read each second from ``--start``
(where touches come every few seconds the pump-cycle correction seldom learns).

    python benchmarks/dispersion_windows.py [--seed 8650] [--seeds 1] [--duration 240]
                                            [--start 20] [--touches] [--only a,b] [--json]
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json
import sys

import numpy as np

sys.path.insert(0, __file__.rsplit("/", 1)[0])
import mismatch

from thermoskin.estimation import kernel as K  # noqa: N812
from thermoskin.estimation.estimator import TouchEstimator
from thermoskin.estimation.freshness import infer_fresh
from thermoskin.params import load_config

WINDOWS = (0.4, 2.0, 8.0)


def _median_z2(ge: np.ndarray, gg: np.ndarray, idle: np.ndarray, idx: np.ndarray) -> float:
    """The median of ``z²`` over chi2(1)'s over the windows between ``idx``, idle all through."""
    z = [ge[a:b].sum() ** 2 / gg[a:b].sum() for a, b in itertools.pairwise(idx)
         if idle[a:b].all() and gg[a:b].sum() > 0]
    return float(np.median(z) / 0.4549) if z else float("nan")


def condition(m: mismatch.Mismatch, seed: int, duration: float,
              start: float = 20.0, touches: bool = False) -> dict[str, float]:
    make = m.scenario or mismatch._finger_scenario
    sc = make(seed, duration) if touches else dataclasses.replace(make(seed, duration), touches=())
    base = load_config()
    cfg = base.replace(sensor=m.configured) if m.configured else base
    true = cfg.replace(skin=m.skin) if m.skin else cfg
    log = mismatch.simulate(sc, true, boards=mismatch._boards(m, cfg, seed))
    fresh, _ = infer_fresh(log)
    est = TouchEstimator(cfg)
    st = est.st
    n = len(log["t"])
    ge, gg, idle = np.zeros(n), np.zeros(n), np.zeros(n, bool)
    rho_s, rho_p = [], []  # the trackers, each second from `start`
    for k in range(n):
        est.step(log["t"][k], log["T_w"][k], log["T_p"][k], log["v"][k], log["T_a"][k],
                 log["T_w_cmd"][k], int(fresh[k]))
        ge[k], gg[k], idle[k] = st[K.SGE], st[K.SGG], st[K.MODE] == K.IDLE
        if k % 1000 == 0 and log["t"][k] >= start:
            rho_s.append(st[K.RHOS])
            rho_p.append(st[K.RHOP])
    t = log["t"]
    out = {}
    for w in WINDOWS:
        idx = np.searchsorted(t, np.arange(start, t[-1], w))
        out[f"z2_median_over_chi2_{w:g}s"] = _median_z2(ge, gg, idle, idx)
    switches = np.flatnonzero(np.diff(log["v"]) != 0) + 1  # each phase from its switch's sample
    out["z2_median_over_chi2_phases"] = _median_z2(ge, gg, idle, switches[t[switches] >= start])
    out["rho"] = float(st[K.RHO])
    out["rho_phases"] = float(st[K.RHOP])
    for name, r in (("rho_short", rho_s), ("rho_phases", rho_p)):
        out[f"{name}_p10"], out[f"{name}_p90"] = (float(x) for x in np.percentile(r, [10, 90]))
    out["events"] = len(est.events)
    off = TouchEstimator(cfg.replace(detector={"rho_window_long": 0.0}))
    out["events_without_long_windows"] = len(off.run(log["t"], log["T_w"], log["T_p"], log["v"],
                                                     log["T_a"], T_w_cmd=log["T_w_cmd"],
                                                     fresh=fresh).events)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=8650, help="first seed")
    ap.add_argument("--seeds", type=int, default=1, help="logs per condition")
    ap.add_argument("--duration", type=float, default=240.0)
    ap.add_argument("--start", type=float, default=20.0, help="s of each log left out first")
    ap.add_argument("--touches", action="store_true", help="the touch logs (the trackers' spread)")
    ap.add_argument("--only", default=None, help="comma-separated substrings of condition names")
    ap.add_argument("--json", action="store_true", help="only the JSON line on stdout")
    a = ap.parse_args()
    rows = []
    for m in mismatch.GRID:
        if a.only and not any(s in m.name for s in a.only.split(",")):
            continue
        for seed in range(a.seed, a.seed + a.seeds):
            r = {"condition": m.name, "seed": seed, **condition(m, seed, a.duration, a.start, a.touches)}
            rows.append(r)
            if not a.json:
                print(f"{m.name:34s} {seed} " + " ".join(
                    f"{w:g} s {r[f'z2_median_over_chi2_{w:g}s']:6.2f}" for w in WINDOWS)
                    + f" phases {r['z2_median_over_chi2_phases']:6.2f}"
                    + f" events {r['events']} (without long windows {r['events_without_long_windows']})",
                    file=sys.stderr, flush=True)
    print(json.dumps({"seed": a.seed, "seeds": a.seeds, "duration_s": a.duration, "start_s": a.start,
                      "touches": a.touches,
                      "conditions": rows}))


if __name__ == "__main__":
    main()
