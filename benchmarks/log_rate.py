"""Detection against the rate a log was written at, and why a coarse log loses touches.

The default touch population (1-3 fingers, ``sim.conditions``), simulated with the loop at
1 kHz and logged at 1000, 500, 200, 100 and 50 Hz (every n-th row kept), then three
references at 50 readings a second that each keep one thing the 50 Hz log lost:

- ``loop-50hz``: the loop itself runs at 50 Hz (the pump switches at the samples);
- ``boards-50hz``: the loop at 1 kHz with 50 Hz thermocouple boards (the estimator knows
  each pump switch to the millisecond, the readings are as sparse as in the 50 Hz log);
- ``loop-50hz-vsw``: the 50 Hz loop estimated as if it were a coarse log, the pump-switch
  timing uncertainty (``kernel.PR_VSW``) added at every switch although there is none;

and ``log-50hz-novsw``, the 50 Hz log estimated without that uncertainty. Then the same
touches on 10 Hz boards (3 ms jitter, ``boards-10hz``) logged at 1000, 100 and 50 Hz, the
log's ``fresh`` column kept (``boards-log-*``) or dropped (``boards-log-*-nofresh``: the
readings are then found where the values change).

Touches, misses, false alarms and latency (median, p90), per population (one fingertip, and
1-3 fingers), on seeds never used in tuning (9000 and up). One JSON object, last line::

    python benchmarks/log_rate.py [--seeds 6] [--json]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from typing import Any

import numpy as np

from thermoskin.analysis.evaluation import match_events
from thermoskin.estimation import kernel as K  # noqa: N812
from thermoskin.estimation.estimator import TouchEstimator
from thermoskin.estimation.freshness import infer_fresh
from thermoskin.params import load_config
from thermoskin.sim.conditions import decimate, get_condition
from thermoskin.sim.run import simulate

SEED0 = 9000
FACTORS = {"log-1000hz": 1, "log-500hz": 2, "log-200hz": 5, "log-100hz": 10, "log-50hz": 20}
BOARD_FACTORS = {"boards-log-1000hz": 1, "boards-log-100hz": 10, "boards-log-50hz": 20}
BOARDS_50HZ = {"period_T_w": 0.02, "period_T_p": 0.02, "period_T_a": 0.02, "jitter": 0.003}


def score(case: str, seed: int) -> dict[str, Any]:
    cond = get_condition("log-100hz", seed)  # the default population (its own decimation unused)
    cfg = cond.config(load_config())
    vsw = None
    if case in FACTORS:
        log = decimate(simulate(cond.scenario, cfg), FACTORS[case])
    elif case.startswith("boards-log-"):
        cond = get_condition("boards-10hz", seed)
        cfg = cond.config(load_config())
        log = decimate(simulate(cond.scenario, cfg), BOARD_FACTORS[case.removesuffix("-nofresh")])
        if case.endswith("-nofresh"):
            del log["fresh"]
    elif case == "log-50hz-novsw":
        log = decimate(simulate(cond.scenario, cfg), 20)
        vsw = 0.0
    elif case == "boards-50hz":
        cfg = cfg.replace(sensor=BOARDS_50HZ)
        log = simulate(cond.scenario, cfg)
    else:  # loop-50hz, loop-50hz-vsw
        cfg = cfg.replace(sampling={"t_s": 0.02})
        log = simulate(cond.scenario, cfg)
        vsw = 0.29 if case.endswith("vsw") else None
    t = log["t"]
    t_s = float(np.median(np.diff(t)))
    est = TouchEstimator(cfg, t_s=cfg.sampling.t_s if abs(t_s - cfg.sampling.t_s) <= 1e-6 else t_s)
    if vsw is not None:
        est.pr[K.PR_VSW] = vsw
    res = est.run(t, log["T_w"], log["T_p"], log["v"], log["T_a"], T_w_cmd=log["T_w_cmd"],
                  fresh=infer_fresh(log)[0])  # as observe finds them
    m = match_events(cond.scenario.touches, res.events)
    one = [tc.n_fingers == 1 for tc in cond.scenario.touches]
    hit = [p is not None for p in m.pairs]
    lat_all = {i: res.events[p].detected_at - tc.t_on
               for i, (tc, p) in enumerate(zip(cond.scenario.touches, m.pairs, strict=True)) if p is not None}
    return {"touches": len(one), "one_finger": sum(one), "misses": m.misses,
            "one_finger_misses": sum(1 for o, h in zip(one, hit, strict=True) if o and not h),
            "false_alarms": m.false_alarms, "latencies": list(lat_all.values()),
            "one_finger_latencies": [x for i, x in lat_all.items() if one[i]],
            "switch_rows": float(np.mean(np.diff(log["v"]) != 0))}


def summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    def stats(x: list[float]) -> dict[str, float | None]:
        return {"median_s": float(np.median(x)) if x else None,
                "p90_s": float(np.percentile(x, 90)) if x else None}

    lat = [x for r in rows for x in r["latencies"]]
    one = [x for r in rows for x in r["one_finger_latencies"]]
    return {"touches": sum(r["touches"] for r in rows), "misses": sum(r["misses"] for r in rows),
            "false_alarms": sum(r["false_alarms"] for r in rows),
            "one_finger": sum(r["one_finger"] for r in rows),
            "one_finger_misses": sum(r["one_finger_misses"] for r in rows),
            "rows_with_a_switch": float(np.mean([r["switch_rows"] for r in rows])),
            "all": stats(lat), "one_finger_lat": stats(one)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=6, help="120 s logs per case (default 6)")
    ap.add_argument("--json", action="store_true", help="only the JSON line on stdout")
    a = ap.parse_args()
    t0 = time.perf_counter()
    out: dict[str, Any] = {}
    for case in (*FACTORS, "log-50hz-novsw", "loop-50hz", "boards-50hz", "loop-50hz-vsw", *BOARD_FACTORS,
                 *(f"{b}-nofresh" for b in list(BOARD_FACTORS)[1:])):
        out[case] = summary([score(case, SEED0 + k) for k in range(a.seeds)])
        print(case, json.dumps(out[case]), file=sys.stderr, flush=True)
    out["wall_s"] = round(time.perf_counter() - t0, 1)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
