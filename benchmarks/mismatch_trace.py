"""One log of a `mismatch.py` condition, traced: its touches against the detector's events, and
the estimator's state every ``--every`` s over ``--start``..``--end``.

Where `mismatch.py` counts false alarms and missed touches, this says why: the estimate about
its baseline (``dq``, W) against the true touch heat (``q_true``), the contact's smoothed and
largest level and the release CUSUM (``run``; it ends the contact above ``h_off``), the
dispersion the detector takes and its three trackers (short windows, long windows, the pump's
phases: ``docs/model.md``), whether the dispersion's windows are taken (``disp``: the slow
states learnt, no contact), and the slow states (the T_p offset against T_w, the pipe bead's lag
and its sd), the air (its reading, its filter's estimate, and whether the detector holds after a
sudden change of it: ``air_held``) and the sheet (the simulator's ``T_g`` against the estimate).
The same log as `mismatch.py` makes for that condition and seed (the touch log of
``--duration`` s), estimated the same way.

    python benchmarks/mismatch_trace.py "T_w lag 0.3" 8100 [--start 5.8] [--end 10.3]
                                        [--every 0.1] [--config F] [--json]
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

sys.path.insert(0, __file__.rsplit("/", 1)[0])
import mismatch as M  # noqa: N812

from thermoskin.analysis.evaluation import match_events
from thermoskin.estimation import kernel as K  # noqa: N812
from thermoskin.estimation.estimator import TouchEstimator
from thermoskin.estimation.freshness import infer_fresh


def trace(name: str, seed: int, start: float, end: float, every: float, duration: float,
          config: str | None) -> dict[str, object]:
    """The touches, events and state rows of condition ``name`` (a substring) on ``seed``."""
    found = [m for m in M.GRID if name in m.name]
    if not found:
        raise SystemExit(f"mismatch_trace.py: no condition matches {name!r}")
    m = found[0]
    sc = (m.scenario or M._finger_scenario)(seed, duration)
    cfg, boards, log = M.make_log(m, sc, seed, config)
    fresh, _ = infer_fresh(log)
    est = TouchEstimator(cfg)
    st, pr = est.st, est.pr
    n = len(log["t"])
    t_s = float(log["t"][1] - log["t"][0])
    step = max(1, round(every / t_s))
    rows = []
    last = min(n, round(end / t_s) + 1)
    for i in range(0, n, step):
        sl = slice(i, min(i + step, n))
        out, _ = est.feed(log["t"][sl], log["T_w"][sl], log["T_p"][sl], log["v"][sl], log["T_a"][sl],
                          T_w_cmd=log["T_w_cmd"][sl], fresh=fresh[sl])
        t = float(log["t"][sl][-1])
        if i >= last:
            continue
        if t >= start:
            sd = pr[K.PR_S0] * st[K.KAPPA] * st[K.SQ]
            rows.append({"t": round(t, 3), "pump": float(log["v"][sl][-1]),
                         "q_true": float(log["q_i"][sl][-1]),
                         "contact": int(out["contact"][-1]), "dq": float(out["dq_i_hat"][-1]),
                         "level": float(st[K.LEVEL]), "level_max": float(st[K.LVLMAX]), "sd": float(sd),
                         "run": float(st[K.RUN]), "rho": float(st[K.RHO]), "rho_short": float(st[K.RHOS]),
                         "rho_long": float(st[K.RHOL]), "rho_phases": float(st[K.RHOP]),
                         "disp": bool(K._slow_learnt(st, pr)), "offset_p": float(st[K.BD]),
                         "lag": float(st[K.LAGT]), "lag_sd": float(np.sqrt(max(st[K.PTT], 0.0))),
                         "T_a": float(log["T_a"][sl][-1]), "T_a_hat": float(st[K.XA]),
                         "T_g": float(log["T_g"][sl][-1]), "T_g_hat": float(st[K.X + 1]),
                         "air_held": bool(t - st[K.TAMB] < pr[K.PR_TAMBH])})
    est.finish(float(log["t"][-1]))
    match = match_events(sc.touches, est.events)
    events = [{"onset": round(e.onset, 3), "release": round(e.release, 3), "sign": e.sign,
               "peak_dq": round(e.peak_dq, 3)} for e in est.events]
    touches = [{"on": round(tc.t_on, 3), "off": round(tc.t_off, 3), "fingers": tc.n_fingers,
                "events": [j for j, e in enumerate(events)
                           if e["onset"] <= tc.t_off + 0.5 and e["release"] >= tc.t_on - 0.1]}
               for tc in sc.touches]
    return {"condition": m.name, "seed": seed, "true_lag_T_w": boards.lag_T_w, "hits": match.hits,
            "touches": touches, "events": events,
            "false_alarms_at_s": [round(float(e.detected_at), 3) for e in match.spurious], "rows": rows}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("condition", help="a substring of a condition's name (mismatch.py)")
    ap.add_argument("seed", type=int)
    ap.add_argument("--start", type=float, default=0.0, help="first traced time, s")
    ap.add_argument("--end", type=float, default=20.0, help="last traced time, s")
    ap.add_argument("--every", type=float, default=0.1, help="s between traced rows")
    ap.add_argument("--duration", type=float, default=240.0, help="the touch log's length, s")
    ap.add_argument("--config", default=None, metavar="F", help="as mismatch.py --config")
    ap.add_argument("--json", action="store_true", help="one JSON object instead of the tables")
    a = ap.parse_args()
    res = trace(a.condition, a.seed, a.start, a.end, a.every, a.duration, a.config)
    if a.json:
        print(json.dumps(res))
        return
    ev = res["events"]
    print(f"{res['condition']}, seed {res['seed']}: {res['hits']} of {len(res['touches'])} touches "
          f"found; false alarms at {res['false_alarms_at_s']} s")
    for tc in res["touches"]:
        got = ", ".join(f"{ev[j]['onset']:.2f}-{ev[j]['release']:.2f} ({ev[j]['sign']:+d})"
                        for j in tc["events"])
        print(f"  touch {tc['on']:7.2f}-{tc['off']:7.2f} s, {tc['fingers']} finger(s): {got or 'missed'}")
    cols = ("t", "pump", "q_true", "contact", "dq", "level", "level_max", "sd", "run", "rho", "rho_short",
            "rho_long", "rho_phases", "disp", "offset_p", "lag", "lag_sd", "T_a", "T_a_hat", "T_g", "T_g_hat",
            "air_held")
    print(" ".join(f"{c:>9s}" for c in cols))
    for r in res["rows"]:
        print(" ".join(f"{r[c]:9.3f}" if isinstance(r[c], float) else f"{r[c]!s:>9s}" for c in cols))
    sys.stdout.flush()


if __name__ == "__main__":
    main()
