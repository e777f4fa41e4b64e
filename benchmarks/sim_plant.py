"""Cost of the simulated plant: the open-loop simulate(), one plant step with ideal and with
10 Hz lagged boards, the emulator's DeviceCore step, and the pump switches a 100 Hz log keeps.

Medians over repeats (the machine may be shared: maxima are scheduling stalls). Prints one
JSON object as its last line.

    python benchmarks/sim_plant.py [--seconds 60] [--repeats 5] [--json]
"""

from __future__ import annotations

import argparse
import gc
import json
import statistics
import time

import numpy as np

from thermoskin.devices import protocol as proto
from thermoskin.devices.emulator import DeviceCore
from thermoskin.params import load_config
from thermoskin.sim.conditions import CONDITIONS, decimate
from thermoskin.sim.plant import SimulatedPlant
from thermoskin.sim.run import simulate
from thermoskin.sim.scenarios import SCENARIOS

BOARDS = {"period_T_w": 0.1, "period_T_p": 0.1, "period_T_a": 0.1, "jitter": 0.003, "lag_T_a": 1.0}


def per_sample_us(fn, n: int, repeats: int) -> float:  # type: ignore[no-untyped-def]
    """Median over ``repeats`` of the mean time of ``fn()`` (which runs ``n`` samples), µs/sample."""
    out = []
    for _ in range(repeats):
        gc.collect()
        t0 = time.perf_counter()
        fn()
        out.append((time.perf_counter() - t0) / n * 1e6)
    return statistics.median(out)


def plant_steps(cfg, n: int) -> None:  # type: ignore[no-untyped-def]
    plant = SimulatedPlant(cfg, SCENARIOS["fingers"])
    measure, apply = plant.measure, plant.apply
    for _ in range(n):
        measure()
        apply(0.1, 0.141)


def core_steps(cfg, n: int) -> None:  # type: ignore[no-untyped-def]
    core = DeviceCore(cfg, SCENARIOS["fingers"], command_timeout=1e9)
    core.on_message(proto.Hello(0))
    core.on_message(proto.Command(1, 0.1, 0.141))
    step = core.step
    for _ in range(n):
        step()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0, help="simulated seconds (1 kHz)")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--json", action="store_true", help="only the JSON line")
    a = ap.parse_args()
    cfg = load_config()
    boards = cfg.replace(sensor=BOARDS)
    sc = SCENARIOS["fingers"].with_duration(a.seconds)
    n = round(a.seconds / cfg.sampling.t_s)
    m = min(n, 20_000)
    res: dict[str, float] = {
        "simulate_ideal_us_per_sample": per_sample_us(lambda: simulate(sc, cfg), n, a.repeats),
        "simulate_10hz_boards_us_per_sample": per_sample_us(lambda: simulate(sc, boards), n, a.repeats),
        "plant_step_ideal_us": per_sample_us(lambda: plant_steps(cfg, m), m, a.repeats),
        "plant_step_10hz_boards_us": per_sample_us(lambda: plant_steps(boards, m), m, a.repeats),
        "device_core_step_us": per_sample_us(lambda: core_steps(cfg, m), m, a.repeats),
    }
    log = simulate(CONDITIONS["log-100hz"](0).scenario.with_duration(a.seconds), cfg)
    v = log["v"]
    sw = np.flatnonzero(np.diff(v)) + 1
    rows = v[: v.size // 10 * 10].reshape(-1, 10)
    res.update({
        "pump_switches_per_s": sw.size / a.seconds,
        "pump_min_interval_ms": float(np.diff(sw).min()) if sw.size > 1 else float("nan"),
        "switches_kept_at_100hz": int(np.count_nonzero(np.diff(decimate(log, 10)["v"]))),
        "switches_at_1khz": int(sw.size),
        "rows_100hz_with_a_switch_inside": float(np.mean(np.any(rows != rows[:, :1], axis=1))),
    })
    res = {k: round(x, 3) if isinstance(x, float) else x for k, x in res.items()}
    if not a.json:
        for k, x in res.items():
            print(f"{k}: {x}")
    print(json.dumps(res))


if __name__ == "__main__":
    main()
