"""How well can a touch's onset, release and duration be dated from the readings? A second opinion.

For each touch of a test-bench condition (``sim.conditions``), a maximum-likelihood pulse
fit that knows what the detector has to guess: that there is exactly one touch within 1 s
of the true one and that its heat is a rectangular pulse. It runs the estimator's own
Kalman filter with detection off (so the filter never jumps) and takes the generalised
likelihood ratio of a pulse of free height from ``t_on`` to ``t_off``
(Willsky and Jones 1976; Basseville and Nikiforov 1993, sec. 2.4),

    LLR(t_on, t_off) = a^2 / (2 b),   a = sum_k rho_k e_k / S_k,   b = sum_k rho_k^2 / S_k,

``e_k, S_k`` the innovations and their variances, ``rho_k`` what a unit pulse would have
left in them (a unit step of ``q_i`` at ``t_on`` carried through the filter,
``mu <- Phi (I - K H) mu``, minus the same at ``t_off``), over a 10 ms grid of both times
within 1 s of the truth, with the pulse's sign the touch's. The filter's state error where
the evidence starts (1 s before the earliest candidate) is a nuisance of free value, its
signatures (a unit error of each state, carried the same way) projected out of the
innovations and of the pulse's (Willsky and Jones's unknown initial state): with detection
off the filter keeps its no-touch ``q_i`` noise, and at 100 Hz it takes some 10 s to forget
the touch before (at 1 kHz about 1 s), which a single pulse cannot explain. It is not a
proof of a floor (the filter's model is not the simulated skin's), but it is the textbook
estimator of a change time on the same filter, given more than the detector is: where it
too misses 0.3 s, we know no estimator that dates that touch within 0.3 s. ``--noiseless``
checks the fit itself: the same conditions with thermocouples free of noise and
quantisation.

    python benchmarks/dating_bound.py [--only boards-10hz,log-100hz,weak] [--seeds 6]
                                      [--seed0 9000] [--noiseless] [--around truth|detector]
                                      [--reach 1.0] [--json]

``--around detector`` centres the fit's window on the detector's own onset and release: what
re-dating each event when it ends (the events are written at the release) by this fit, on a
detection-free filter beside the detector's, would give.

Prints per condition, for the detector (``pipeline.observe``) and for the pulse fit, the
share of touches whose onset, release and duration are within 0.3 s, the largest and
median errors, and how many touches miss 0.3 s in duration by each and by both; one JSON
line on stdout.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from typing import Any

import numpy as np

from thermoskin.analysis.observe import observe
from thermoskin.estimation.freshness import infer_fresh, loop_t_s, sample_interval
from thermoskin.estimation.model import I_Q
from thermoskin.estimation.reference import ReferenceEstimator
from thermoskin.params import Config, load_config
from thermoskin.sim.conditions import decimate, get_condition
from thermoskin.sim.run import simulate

GRID_S = 0.01     # candidate spacing
REACH_S = 1.0     # candidates within this of the true onset and release
TAIL_S = 1.5      # readings used after the true release
HISTORY_S = 20.0  # the filter runs this long before the touch (or from the log's start)
NUISANCE_S = 1.0  # evidence used before the earliest candidate, to pin the state error there


def _record(log: dict[str, np.ndarray], cfg: Config, k0: int, k1: int
            ) -> tuple[list[list[tuple[int, float, float, np.ndarray, bool]]], list[np.ndarray]]:
    """Run the filter over rows ``k0..k1`` (no detection); per row its updates and its Phi."""
    t = log["t"]
    t_s = loop_t_s(sample_interval(t), cfg)
    # the reference filter with detection off (it never jumps and keeps its no-touch noise),
    # recording each scalar update: state read, innovation, its variance times the learnt
    # scale squared, gain, whether it is evidence (weighed as the detector weighs it)
    est = ReferenceEstimator(cfg, t_s, detect=False)
    fresh = log["_fresh"]
    cmd = log.get("T_w_cmd")
    rows, phis = [], []
    for k in range(k0, k1):
        est.updates = []
        est.step(float(t[k]), float(log["T_w"][k]), float(log["T_p"][k]), float(log["v"][k]),
                 float(log["T_a"][k]), float(cmd[k]) if cmd is not None else math.nan,
                 int(fresh[k]))
        rows.append(est.updates)
        phis.append(est.tables.Phi[est.iv_prev])
    # the pump-switch correction of a coarse log (reference._switch_correction) moves T_w by a
    # deterministic share of T_p - T_w, which the signatures leave out, as the detector's own do
    return rows, phis


def pulse_fit(log: dict[str, np.ndarray], cfg: Config, t_on: float, t_off: float,
              sign: float, reach: float = REACH_S) -> tuple[float, float, float]:
    """The GLR onset and release of a pulse of free height and sign ``sign``, near the true
    ``t_on, t_off``, with the filter's state error ``NUISANCE_S`` before the earliest
    candidate free (profiled out); and its height (W, as the filter's model sees it)."""
    t = log["t"]
    k0 = int(np.searchsorted(t, max(t[0], t_on - HISTORY_S)))
    k1 = int(np.searchsorted(t, t_off + TAIL_S))
    rows, phis = _record(log, cfg, k0, k1)
    tt = t[k0:k1]
    cand_on = np.arange(t_on - reach, t_on + reach + 1e-9, GRID_S)
    cand_off = np.arange(t_off - reach, t_off + reach + 1e-9, GRID_S)
    cands = np.concatenate([cand_on, cand_off])
    start = np.searchsorted(tt, cands)  # the step acts from the first row at or after it
    n = len(cands)
    # columns n..n+4: a unit error of each state at the row the evidence starts (nuisance)
    mu = np.zeros((5, n + 5))
    j_first = int(np.searchsorted(tt, tt[int(start.min())] - NUISANCE_S))
    mu[:, n:] = np.eye(5)
    cols: list[np.ndarray] = []
    z: list[float] = []
    for j in range(j_first, len(tt)):
        new = start == j
        if new.any():
            mu[:, :n][:, new] = 0.0
            mu[I_Q, :n][new] = 1.0
        for i, e, Se, K, evidence in rows[j]:
            rho = mu[i].copy()
            if evidence:
                sS = math.sqrt(Se)
                cols.append(rho / sS)
                z.append(e / sS)
            mu -= np.outer(K, rho)
        mu = phis[j] @ mu
    R = np.array(cols).T  # candidates (then the nuisance) x readings
    zz = np.array(z)
    U, sv, _ = np.linalg.svd(R[n:].T, full_matrices=False)  # the nuisance's span, orthonormal
    U = U[:, sv > 1e-9 * sv[0]]
    R = R[:n] - (R[:n] @ U) @ U.T
    zz = zz - U @ (U.T @ zz)
    a = R @ zz
    G = R @ R.T
    no, nf = len(cand_on), len(cand_off)
    ia = np.arange(no)[:, None]
    ib = no + np.arange(nf)[None, :]
    num = a[ia] - a[ib]
    den = G[ia, ia] + G[ib, ib] - 2.0 * G[ia, ib]
    # a pulse starts and ends at different rows, and is not lost in the rounding of den
    ok = (num * sign > 0) & (start[ia] < start[ib]) & (den > 1e-12 * (G[ia, ia] + G[ib, ib]))
    llr = np.where(ok, num * num / np.where(ok, den, 1.0), -np.inf)
    i_on, i_off = np.unravel_index(int(np.argmax(llr)), llr.shape)
    return float(cand_on[i_on]), float(cand_off[i_off]), float(num[i_on, i_off] / den[i_on, i_off])


def score(name: str, seed: int, base: Config, around: str = "truth",
          reach: float = REACH_S) -> list[dict[str, Any]]:
    """Per touch, the detector's and the fit's errors (onset, release, duration). ``around``:
    the fit's window is centred on the true times (``truth``) or on the detector's own
    (``detector``: what re-dating each event at its release by this fit would give; touches
    the detector missed get no fit then)."""
    cond = get_condition(name, seed)
    cfg = cond.config(base)
    log = simulate(cond.scenario, cfg)
    if cond.decimate > 1:
        log = decimate(log, cond.decimate)
    events = observe(log, cfg).events
    log["_fresh"] = infer_fresh(log)[0]
    out = []
    used: set[int] = set()
    t = log["t"]
    for tc in cond.scenario.touches:
        hit = next((i for i, e in enumerate(events) if i not in used
                    and tc.t_on <= e.detected_at <= tc.t_on + tc.duration + 1.0), None)
        sel = (t >= tc.t_on) & (t < tc.t_off)
        A = float(np.mean(log["q_i"][sel])) if sel.any() else 0.0
        row: dict[str, Any] = {"seed": seed, "t_on": tc.t_on, "duration": tc.duration, "q_i_mean_W": A}
        e = events[hit] if hit is not None else None
        if e is not None:
            used.add(hit)  # type: ignore[arg-type]
            row["detector"] = [e.onset - tc.t_on, e.release - tc.t_off, e.duration - tc.duration]
        if around == "truth" or e is not None:
            on, off, sg = ((tc.t_on, tc.t_off, 1.0 if A >= 0 else -1.0) if around == "truth"
                           else (e.onset, e.release, float(e.sign)))  # type: ignore[union-attr]
            o_on, o_off, A_fit = pulse_fit(log, cfg, on, off, sg, reach)
            row["fit_height_W"] = A_fit
            row["fit"] = [o_on - tc.t_on, o_off - tc.t_off, (o_off - o_on) - tc.duration]
        out.append(row)
    return out


def summary(rows: list[dict[str, Any]], who: str) -> dict[str, Any]:
    errs = np.abs(np.array([r[who] for r in rows if who in r]))
    if not len(errs):
        return {"n": 0}
    return {"n": len(errs),
            **{f"{k}_within_0.3s": float(np.mean(errs[:, j] <= 0.3))
               for j, k in enumerate(("onset", "release", "duration"))},
            **{f"{k}_err_max_s": float(errs[:, j].max())
               for j, k in enumerate(("onset", "release", "duration"))},
            **{f"{k}_err_median_s": float(np.median(errs[:, j]))
               for j, k in enumerate(("onset", "release", "duration"))}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="boards-10hz,log-100hz,weak", help="comma-separated conditions")
    ap.add_argument("--seeds", type=int, default=6, help="logs per condition")
    ap.add_argument("--seed0", type=int, default=9000, help="first seed (9000: held out)")
    ap.add_argument("--noiseless", action="store_true",
                    help="thermocouples without noise or quantisation (a check of the fit itself)")
    ap.add_argument("--around", choices=("truth", "detector"), default="truth",
                    help="centre the fit's window on the true times, or on the detector's own")
    ap.add_argument("--reach", type=float, default=REACH_S, help="the window's half width, s")
    ap.add_argument("--json", action="store_true", help="only the JSON line on stdout")
    a = ap.parse_args()
    t0 = time.perf_counter()
    base = load_config()
    if a.noiseless:
        base = base.replace(sensor={"noise_T": 0.0, "quantum_T": 0.0})
    res: dict[str, Any] = {}
    for name in a.only.split(","):
        rows = [r for k in range(a.seeds) for r in score(name, a.seed0 + k, base, a.around, a.reach)]
        over = [("detector" in r and abs(r["detector"][2]) > 0.3, "fit" in r and abs(r["fit"][2]) > 0.3)
                for r in rows]
        res[name] = {"detector": summary(rows, "detector"), "fit": summary(rows, "fit"),
                     "detector_over_0.3s": sum(1 for d, _ in over if d),
                     "fit_over_0.3s": sum(1 for _, f in over if f),
                     "both_over_0.3s": sum(1 for d, f in over if d and f)}
        print(name, json.dumps(res[name]), file=sys.stderr, flush=True)
        if not a.json:
            for r in rows:
                if any(k in r and abs(r[k][2]) > 0.3 for k in ("fit", "detector")):
                    print("  ", json.dumps(r), file=sys.stderr)
    res["wall_s"] = round(time.perf_counter() - t0, 1)
    print(json.dumps(res))


if __name__ == "__main__":
    main()
