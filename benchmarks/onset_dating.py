"""Would dating an onset by the step's exact signature date touches better? A tried alternative.

The detector dates an onset by the generalised likelihood ratio over the change time within
the firing CUSUM's window, weighing each reading by its sensitivity to a lasting change of
``q_i`` (``g = P[i, q] / P[q, q]``; ``docs/model.md``, Detection). The textbook weighting is
the step's signature at each delay (Willsky and Jones 1976): a unit step of ``q_i`` after a
candidate reading, carried through the filter (``mu <- Phi (I - K H) mu``), which starts at
zero and grows. This runs the plain-Python reference detector (``estimation/reference.py``)
both ways on the same logs: stock, and with its ``_glr_time`` replaced by the exact
signature over every pipe reading of the last ``--window`` s (the filter's gains recorded
per reading); detection and release are untouched. Prints, per way, the touches whose
duration is within 0.3 s, the mean and median onset error, and one JSON line.

    python benchmarks/onset_dating.py [--only boards-10hz,log-100hz] [--seeds 18] [--seed0 100]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections import deque
from typing import Any

import numpy as np

from thermoskin.estimation.freshness import infer_fresh, loop_t_s, sample_interval
from thermoskin.estimation.model import I_Q
from thermoskin.estimation.reference import ReferenceEstimator, _Cusum
from thermoskin.params import Config, load_config
from thermoskin.sim.conditions import decimate, get_condition
from thermoskin.sim.run import simulate


class SignatureDating(ReferenceEstimator):
    """The reference detector with its onsets dated by the step's exact signature."""

    window_s = 4.0

    def __post_init__(self) -> None:
        super().__post_init__()
        self.hist: deque[tuple[float, list[Any], np.ndarray | None]] = deque(
            maxlen=max(10, int(self.window_s / self.t_s)))
        self._t = 0.0

    def step(self, t: float, *args: Any, **kw: Any) -> int:
        self.updates, self._t = [], t  # this sample's scalar updates, recorded by the filter
        code = super().step(t, *args, **kw)
        self.hist.append((t, self.updates, self.tables.Phi[self.iv_prev]))
        return code

    def _glr_time(self, c: _Cusum, sg: float) -> float:
        rows = [h for h in self.hist if h[0] > c.t_zero] + [(self._t, self.updates or [], None)]
        idx = [-1] + [j for j, r in enumerate(rows[:-1]) if r[1]]  # after c.t_zero or a reading
        times = [c.t_zero] + [rows[j][0] for j in idx[1:]]
        n = len(idx)
        start = {j: m for m, j in enumerate(idx) if j >= 0}
        mu = np.zeros((5, n))
        mu[I_Q, 0] = 1.0
        a, b = np.zeros(n), np.zeros(n)
        for j, (_, ups, Phi) in enumerate(rows):
            for i, e, Se, K, evidence in ups:
                rho = mu[i].copy()
                if evidence:
                    a += rho * e / Se
                    b += rho * rho / Se
                mu -= np.outer(K, rho)
            if j in start:  # this candidate's step acts after this row's readings
                m = start[j]
                mu[:, m] = 0.0
                mu[I_Q, m] = 1.0
            if Phi is not None:
                mu = Phi @ mu
        llr = np.where((sg * a > 0) & (b > 0), a * a / np.where(b > 0, b, 1.0), 0.0)
        best_t, best = c.t_zero, llr[0]
        for m in range(1, n):  # of equals, the first (as the detector's own scan)
            if llr[m] > best * (1.0 + 1e-12):
                best_t, best = times[m], llr[m]
        return best_t


def errors(name: str, seed: int, base: Config, signature: bool) -> list[list[float] | None]:
    """Per touch of the condition's log, the detector's onset, release and duration errors (s)."""
    cond = get_condition(name, seed)
    cfg = cond.config(base)
    log = simulate(cond.scenario, cfg)
    if cond.decimate > 1:
        log = decimate(log, cond.decimate)
    fresh = infer_fresh(log)[0]
    t = log["t"]
    est = (SignatureDating if signature else ReferenceEstimator)(cfg, loop_t_s(sample_interval(t), cfg))
    cmd, drv = log.get("T_w_cmd"), log.get("drive")
    for k in range(len(t)):
        est.step(float(t[k]), float(log["T_w"][k]), float(log["T_p"][k]), float(log["v"][k]),
                 float(log["T_a"][k]), float(cmd[k]) if cmd is not None else math.nan, int(fresh[k]),
                 float(drv[k]) if drv is not None else math.nan)
    used: set[int] = set()
    out: list[list[float] | None] = []
    for tc in cond.scenario.touches:
        hit = next((i for i, e in enumerate(est.events) if i not in used
                    and tc.t_on <= e.detected_at <= tc.t_on + tc.duration + 1.0), None)
        if hit is None:
            out.append(None)
            continue
        used.add(hit)
        e = est.events[hit]
        out.append([e.onset - tc.t_on, e.release - tc.t_off, e.duration - tc.duration])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="boards-10hz,log-100hz", help="comma-separated conditions")
    ap.add_argument("--seeds", type=int, default=18, help="logs per condition")
    ap.add_argument("--seed0", type=int, default=100, help="first seed (100: the tuning seeds)")
    ap.add_argument("--window", type=float, default=4.0, help="readings kept for the signature, s")
    a = ap.parse_args()
    SignatureDating.window_s = a.window
    t0 = time.perf_counter()
    base = load_config()
    res: dict[str, Any] = {}
    for name in a.only.split(","):
        for way in ("stock", "signature"):
            rows = [r for s in range(a.seed0, a.seed0 + a.seeds)
                    for r in errors(name, s, base, way == "signature")]
            e = np.array([r for r in rows if r is not None])
            res[f"{name}/{way}"] = {
                "touches": len(rows), "detected": len(e),
                "duration_within_0.3s": int(np.sum(np.abs(e[:, 2]) <= 0.3)),
                "onset_err_mean_s": round(float(e[:, 0].mean()), 3),
                "onset_err_median_s": round(float(np.median(e[:, 0])), 3),
                "release_err_mean_s": round(float(e[:, 1].mean()), 3)}
            print(name, way, json.dumps(res[f"{name}/{way}"]), file=sys.stderr, flush=True)
    res["wall_s"] = round(time.perf_counter() - t0, 1)
    print(json.dumps(res))


if __name__ == "__main__":
    main()
