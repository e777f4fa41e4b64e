"""Speed of the whole skin in closed loop (issue 12 item 7): examples/forearm.toml, scenario
``multi`` (touches, a grasp, a stroke: new transition matrices while contacts ramp and move)
and ``none`` (no touch), one controller per water loop, the long-format log built (not written).

Per run: the real-time factor (simulated over wall-clock seconds of the loop) and the time of
each sample (plant, controllers, recording; the samples where a new transition matrix is
computed included). Medians over repeats; p50/p99/max over every sample of every repeat. The
machine may be shared (its load average is printed): maxima are scheduling stalls.

    python benchmarks/skin_sim.py [--skin examples/forearm.toml] [--repeats 3] [--duration S]

Prints one JSON object as its last line.
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import statistics
from pathlib import Path

import numpy as np

from thermoskin.runtime.skin_loop import run_skin
from thermoskin.sim.skin_scenarios import skin_scenario
from thermoskin.skin.layout import load_skin

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--skin", default=str(ROOT / "examples" / "forearm.toml"))
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--duration", type=float, default=None, help="seconds (default: the scenario's)")
    args = ap.parse_args()
    skin = load_skin(args.skin)
    warm = skin_scenario("none", skin, 2.0)
    run_skin(skin, warm)  # compile (or load) the kernels once
    out: dict[str, object] = {"skin": Path(args.skin).name, "patches": len(skin.patches),
                              "loops": len(skin.loops), "thermocouples": sum(len(p.thermocouples)
                                                                              for p in skin.patches)}
    for name in ("multi", "none"):
        default = None if name == "multi" else 60.0
        sc = skin_scenario(name, skin, args.duration if args.duration else default)
        factors, steps = [], []
        for _ in range(args.repeats):
            n = round(sc.duration / skin.cfg.sampling.t_s) + 1
            st = np.zeros(n, dtype=np.int64)
            gc.collect()
            res = run_skin(skin, sc, step_times=st)
            factors.append(res.realtime_factor)
            steps.append(st[:res.n] / 1e3)
            tracking = res.tracking
        us = np.concatenate(steps)
        out[name] = {"duration_s": sc.duration, "contacts": len(sc.contacts),
                     "realtime_factor_median": round(statistics.median(factors), 1),
                     "realtime_factor_runs": [round(f, 1) for f in factors],
                     "step_us_p50": round(float(np.percentile(us, 50)), 1),
                     "step_us_p99": round(float(np.percentile(us, 99)), 1),
                     "step_us_max": round(float(us.max()), 1),
                     "tracking_K": [round(x, 3) for x in tracking]}
        print(f"{name}: {out[name]}")
    out["load_average"] = [round(x, 2) for x in os.getloadavg()]
    out["cpus"] = os.cpu_count()
    print(json.dumps(out))


if __name__ == "__main__":
    main()
