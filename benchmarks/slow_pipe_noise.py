"""A slow board's pipe noise learnt from the readings, against the board's own.

No-touch logs read through 10 Hz boards whose pipe noise is not the configured 0.02 K: the
emulator's default boards (``[sensor] seed`` 0, the pipe's 0.049 K, no jitter) and the mismatch
grid's ``10 Hz boards as a lab buys them`` (seeds from ``--seed``, 3 ms of jitter). Each log is
estimated three times with the default configuration: as it is (the pipe's noise learnt at the
same point of the pump's cycle, ``docs/model.md``), told each board's true pipe noise
(``[sensor] noise_T_w``, what learning it should come to), and with the noise held at the
configured 0.02 K (``[estimator] phase_tol = 0``, as before it was learnt). Per log: the
board's noise, the one learnt, the evidence's dispersion and the false alarms (every event: no
touch) each way; and the robust sd of the pipe readings' second differences over ``sqrt(6)``
(what they would give for the noise: the pump's kinks).

    python benchmarks/slow_pipe_noise.py [--seed 8600] [--seeds 6] [--duration 120] [--json]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys

import numpy as np

sys.path.insert(0, __file__.rsplit("/", 1)[0])
import mismatch

from thermoskin.estimation.estimator import TouchEstimator
from thermoskin.estimation.freshness import infer_fresh
from thermoskin.params import Config, SensorParams, load_config
from thermoskin.sim.boards import lab_boards
from thermoskin.sim.run import simulate
from thermoskin.sim.scenarios import SCENARIOS

PERIODS = {"period_T_w": 0.1, "period_T_p": 0.1, "period_T_a": 0.1}


def estimate(cfg: Config, log: dict) -> dict[str, float]:
    """The default estimator over ``log``: the pipe noise learnt, the dispersion, the events."""
    fresh, _ = infer_fresh(log)
    est = TouchEstimator(cfg)
    res = est.run(log["t"], log["T_w"], log["T_p"], log["v"], log["T_a"], T_w_cmd=log["T_w_cmd"],
                  fresh=fresh)
    lt = est.learnt()
    return {"noise_T_w": lt.noise["T_w"], "rho": lt.rho, "false_alarms": len(res.events)}


def one(name: str, cfg: Config, boards: SensorParams, duration: float) -> dict[str, object]:
    log = simulate(SCENARIOS["none"].with_duration(duration), cfg, boards=boards)
    true = math.hypot(boards.noise("T_w"), boards.quantum_T / math.sqrt(12.0))
    learnt = estimate(cfg, log)
    told = estimate(cfg.replace(sensor={"noise_T_w": boards.noise("T_w")}), log)
    held = estimate(cfg.replace(estimator={"phase_tol": 0.0}), log)
    fresh, _ = infer_fresh(log)
    d2 = np.diff(log["T_w"][(fresh & 1) != 0], 2)
    return {"boards": name, "noise_T_w_true": true, "noise_T_w_learnt": learnt["noise_T_w"],
            "ratio": learnt["noise_T_w"] / true, "rho": learnt["rho"],
            "false_alarms": learnt["false_alarms"], "rho_told": told["rho"],
            "false_alarms_told": told["false_alarms"], "rho_held": held["rho"],
            "false_alarms_held": held["false_alarms"],
            "second_difference_sd": float(np.median(np.abs(d2)) / 0.6745 / math.sqrt(6.0))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=8600, help="first seed of the grid's 10 Hz boards")
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--duration", type=float, default=120.0, help="s per log")
    ap.add_argument("--json", action="store_true", help="only the JSON line on stdout")
    a = ap.parse_args()
    base = load_config()
    cfg = base.replace(sensor=PERIODS)
    runs = [("emulator's default (seed 0)", cfg, lab_boards(dataclasses.replace(base.sensor, **PERIODS)))]
    m = next(g for g in mismatch.GRID if g.name == "10 Hz boards as a lab buys them")
    gcfg = base.replace(sensor=m.configured)
    runs += [(f"grid 10 Hz lab, seed {s}", gcfg, mismatch._boards(m, gcfg, s))
             for s in range(a.seed, a.seed + a.seeds)]
    rows = []
    for name, c, b in runs:
        r = one(name, c, b, a.duration)
        rows.append(r)
        if not a.json:
            print(f"{name:30s} true {r['noise_T_w_true']:.4f} K learnt {r['noise_T_w_learnt']:.4f} K "
                  f"({r['ratio']:.2f}), dispersion {r['rho']:.2f}, false alarms {r['false_alarms']} "
                  f"(told the noise: {r['rho_told']:.2f}, {r['false_alarms_told']}; held at the "
                  f"prior: {r['rho_held']:.2f}, {r['false_alarms_held']}; second differences "
                  f"{r['second_difference_sd']:.3f} K)",
                  file=sys.stderr, flush=True)
    print(json.dumps({"seed": a.seed, "seeds": a.seeds, "duration_s": a.duration, "logs": rows}))


if __name__ == "__main__":
    main()
