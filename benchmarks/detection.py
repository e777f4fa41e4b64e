"""Detection figures: hits, misses, false alarms and onset latency over unseen scenarios.

Runs randomised touch scenarios (seeds not used in tuning) on several skin parameter sets,
plus long no-touch runs for the false-alarm rate, through the vectorised pipeline.
Prints one JSON object as its last line.

    python benchmarks/detection.py [--seeds 10] [--quiet-s 600] [--json]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from thermoskin.evaluation import match_events
from thermoskin.params import Config, load_config
from thermoskin.pipeline import observe
from thermoskin.sim.run import simulate
from thermoskin.sim.scenarios import SCENARIOS, random_scenario

PARAM_SETS: dict[str, dict[str, dict[str, float]]] = {
    "paper": {},
    "slow-pipe": {"skin": {"C_w": 0.25, "R_g": 8.0, "C_g": 0.02, "R_ag": 1.5}},
    "fast-sheet": {"skin": {"C_w": 0.09, "R_g": 14.0, "C_g": 0.008, "R_ag": 0.7}},
}


def run(seeds: int, quiet_s: float, seed0: int = 1000) -> dict[str, object]:
    base = load_config()
    out: dict[str, object] = {}
    all_lat: list[float] = []
    totals = {"touches": 0, "hits": 0, "misses": 0, "false_alarms": 0, "quiet_s": 0.0}
    for name, over in PARAM_SETS.items():
        cfg: Config = base.replace(**over) if over else base
        lat: list[float] = []
        hits = misses = fas = touches = 0
        for k in range(seeds):
            seed = seed0 + k
            cfg_k = cfg.replace(sensor={"seed": seed})
            sc = random_scenario(seed, 120.0)
            log = simulate(sc, cfg_k)
            res = observe(log, cfg_k)
            m = match_events(sc.touches, res.events)
            touches += len(sc.touches)
            hits += m.hits
            misses += m.misses
            fas += m.false_alarms
            lat.extend(m.latencies.tolist())
        quiet = SCENARIOS["none"].with_duration(quiet_s)
        cfg_q = cfg.replace(sensor={"seed": seed0 + 999})
        resq = observe(simulate(quiet, cfg_q), cfg_q)
        fas_quiet = len(resq.events)
        lat_a = np.asarray(lat)
        out[name] = {
            "touches": touches, "hits": hits, "misses": misses, "false_alarms": fas,
            "quiet_s": quiet_s, "false_alarms_quiet": fas_quiet,
            "latency_median_s": float(np.median(lat_a)) if len(lat_a) else None,
            "latency_p90_s": float(np.percentile(lat_a, 90)) if len(lat_a) else None,
            "latency_max_s": float(lat_a.max()) if len(lat_a) else None,
        }
        all_lat.extend(lat)
        totals["touches"] += touches
        totals["hits"] += hits
        totals["misses"] += misses
        totals["false_alarms"] += fas + fas_quiet
        totals["quiet_s"] += quiet_s
    la = np.asarray(all_lat)
    totals["latency_median_s"] = float(np.median(la)) if len(la) else None
    totals["latency_p90_s"] = float(np.percentile(la, 90)) if len(la) else None
    out["total"] = totals
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10, help="random scenarios per parameter set")
    ap.add_argument("--quiet-s", type=float, default=600.0, help="no-touch seconds per set")
    ap.add_argument("--json", action="store_true", help="only the JSON line")
    a = ap.parse_args()
    t0 = time.perf_counter()
    res = run(a.seeds, a.quiet_s)
    res["wall_s"] = round(time.perf_counter() - t0, 1)
    if not a.json:
        for k, v in res.items():
            print(k, v)
    print(json.dumps(res))


if __name__ == "__main__":
    main()
