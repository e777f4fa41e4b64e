"""Detection when the sensors and the skin are not what the configuration says.

Every condition simulates a skin whose thermocouple boards (and, for some, the skin itself)
differ from the configuration given to the estimator, which is the default one (the paper's
skin, ideal 1 kHz boards of 0.02 K noise) unless the condition says the lab knows better (its
boards' period). The estimator learns what it can (offsets, lag, noise, converter step,
dispersion: ``docs/model.md``, Sensors that calibrate themselves); nothing is hand-tuned per
condition. Per condition, over ``--seeds`` logs of ``--duration`` s with touches (1-3 fingers
of the three persons, ``sim.conditions``) and ``--quiet-min`` minutes without touch:

- touches, detected, missed; false alarms and their rate per hour of all the logs;
- onset latency median and p90;
- the one-finger SNR the estimator learnt (its median over the logs), whether ``observe``
  prints its below-the-noise line (SNR < 5);
- where an offset or a lag is set: the learnt offset of the T_p readings against the T_w
  readings and the pipe thermocouple's lag, their errors (median, largest);
- the bar of issue 43: SNR >= 5: every touch, no false alarm, median latency <= 0.3 s (0.4 s
  with 10 Hz boards); SNR < 5: the line, and at most one false alarm an hour.

``--config F``: the configuration given to the estimator is the default one with the TOML file
``F`` over it (a lab's, or a change of a default tried on the grid before it is made).
``--told-noise``: each log's configuration also says its boards' true noise per channel (what
learning the noise should come to; ``docs/sensors.md``, a slow board's pipe noise).

Seeds from ``--seed0`` (7000): never used in tuning (the tuning seeds were 100-111 for the lab's
boards, 9000-9002 for the issue's cases, 0-5 in closed loop).

    python benchmarks/mismatch.py [--seeds 3] [--duration 240] [--quiet-min 20] [--only a,b]
                                  [--config F] [--told-noise] [--json]
    python benchmarks/mismatch.py --markdown RESULT.json    # the table of docs/sensors.md
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from thermoskin.analysis.evaluation import match_events
from thermoskin.estimation.estimator import TouchEstimator
from thermoskin.estimation.freshness import infer_fresh
from thermoskin.estimation.learnt import SNR_MIN, learnt
from thermoskin.params import Config, SensorParams, load_config
from thermoskin.sim.boards import lab_boards
from thermoskin.sim.conditions import ambient_ramp, ambient_step, finger_train, mis_sized_skin
from thermoskin.sim.run import simulate
from thermoskin.sim.scenarios import Scenario

SEED0 = 7000
BOARDS_10HZ = {"period_T_w": 0.1, "period_T_p": 0.1, "period_T_a": 0.1, "jitter": 0.003}
LAB = "lab"  # the boards drawn per seed as a lab buys them (sim.boards)


@dataclasses.dataclass(frozen=True)
class Mismatch:
    """One condition: the true boards (changes to the configured ``[sensor]``, or ``LAB``
    with changes), the true skin (changes to ``[skin]``), what the lab configures (its boards'
    period), and the scenario maker (``None``: touches of 1-3 fingers on a steady air)."""

    name: str
    boards: dict[str, Any] = dataclasses.field(default_factory=dict)
    lab: bool = False
    skin: dict[str, float] = dataclasses.field(default_factory=dict)
    configured: dict[str, Any] = dataclasses.field(default_factory=dict)
    scenario: Callable[[int, float], Scenario] | None = None
    slow_boards: bool = False


def _skin(f: float) -> dict[str, float]:
    """Table I's network values scaled (``sim.conditions.mis_sized_skin``)."""
    return mis_sized_skin(load_config().skin, f)


def _door(seed: int, duration: float) -> Scenario:
    """Doors: the air steps by 1 K within 1 s, 3-4 times (``sim.conditions.ambient_step``)."""
    return ambient_step(seed, duration).scenario


def _ramp(seed: int, duration: float) -> Scenario:
    return ambient_ramp(seed, max(duration, 1200.0)).scenario.with_duration(duration)


GRID: tuple[Mismatch, ...] = (
    Mismatch("ideal boards (as configured)"),
    Mismatch("boards as a lab buys them", lab=True),
    Mismatch("noise x0.5 (0.01 K)", {"noise_T": 0.01}),
    Mismatch("noise x2.5 (0.05 K)", {"noise_T": 0.05}),
    Mismatch("noise x5 (0.1 K)", {"noise_T": 0.1}),
    Mismatch("quantum 1/16 K", {"quantum_T": 1 / 16}),
    Mismatch("quantum 1/4 K", {"quantum_T": 0.25}),
    Mismatch("offset 0.1 K on T_w", {"offset_T_w": 0.1}),
    Mismatch("offsets 0.3, -0.2, 0.5 K", {"offset_T_w": 0.3, "offset_T_p": -0.2, "offset_T_a": 0.5}),
    Mismatch("offset 0.5 K on T_p", {"offset_T_p": 0.5}),
    Mismatch("T_w lag 0.1 s", {"lag_T_w": 0.1}),
    Mismatch("T_w lag 0.3 s", {"lag_T_w": 0.3}),
    Mismatch("T_a lag 1 s, doors", {"lag_T_a": 1.0}, scenario=_door),
    Mismatch("T_a lag 3 s, doors", {"lag_T_a": 3.0}, scenario=_door),
    Mismatch("T_a lag 3 s, ramps", {"lag_T_a": 3.0}, scenario=_ramp),
    Mismatch("skin +30 %", skin=_skin(0.3)),
    Mismatch("skin -30 %", skin=_skin(-0.3)),
    Mismatch("10 Hz boards (as configured)", BOARDS_10HZ, configured=BOARDS_10HZ, slow_boards=True),
    Mismatch("10 Hz boards as a lab buys them", BOARDS_10HZ, lab=True, configured=BOARDS_10HZ,
             slow_boards=True),
    Mismatch("10 Hz, 1/4 K (MAX31855)", {**BOARDS_10HZ, "quantum_T": 0.25}, configured=BOARDS_10HZ,
             slow_boards=True),
)


def _finger_scenario(seed: int, duration: float) -> Scenario:
    return finger_train(seed, duration)


def _quiet(seed: int, duration: float) -> Scenario:
    return dataclasses.replace(_finger_scenario(seed, duration), touches=())


def _boards(m: Mismatch, cfg: Config, seed: int) -> SensorParams:
    s = dataclasses.replace(cfg.sensor, seed=seed)
    if m.lab:
        s = lab_boards(s)
    return dataclasses.replace(s, **m.boards)


CONFIG: str | None = None
"""``--config``: a TOML file over the default configuration (None: the default)."""
TOLD_NOISE = False
"""``--told-noise``: the estimator is told each log's boards' noise."""


def make_log(m: Mismatch, sc: Scenario, seed: int, config: str | None = None
             ) -> tuple[Config, SensorParams, dict[str, np.ndarray]]:
    """Condition ``m``'s log of ``sc``: the configuration given to the estimator (the default
    one, or ``config`` over it, with the boards the lab is said to know), the true boards, and the
    log simulated with them and the true skin."""
    base = load_config(config)
    cfg = base.replace(sensor=m.configured) if m.configured else base
    true = cfg.replace(skin=m.skin) if m.skin else cfg
    boards = _boards(m, cfg, seed)
    return cfg, boards, simulate(sc, true, boards=boards)


def one_log(m: Mismatch, sc: Scenario, seed: int) -> dict[str, Any]:
    """One log of condition ``m``: simulated with the true boards and skin, estimated with the
    configuration; its events against the touches and what the estimator learnt."""
    cfg, boards, log = make_log(m, sc, seed, CONFIG)
    if TOLD_NOISE:
        cfg = cfg.replace(sensor={f"noise_{ch}": boards.noise(ch) for ch in ("T_w", "T_p", "T_a")})
    fresh, _ = infer_fresh(log)
    est = TouchEstimator(cfg)
    res = est.run(log["t"], log["T_w"], log["T_p"], log["v"], log["T_a"], T_w_cmd=log["T_w_cmd"],
                  fresh=fresh)
    lt = learnt(est.st, cfg)
    match = match_events(sc.touches, res.events)
    return {"touches": len(sc.touches), "hits": match.hits, "misses": match.misses,
            "false_alarms": match.false_alarms, "latencies": [float(x) for x in match.latencies],
            "false_alarms_at_s": [round(float(e.detected_at), 2) for e in match.spurious],
            "hours": sc.duration / 3600.0, "snr": lt.snr,
            "offset_err": lt.offset_p - (boards.offset_T_p - boards.offset_T_w),
            "lag": lt.lag_w, "lag_err": lt.lag_w - boards.lag_T_w}


def condition(m: Mismatch, seeds: list[int], duration: float, quiet_min: float) -> dict[str, Any]:
    """Condition ``m`` over ``seeds`` (each a log with touches and one without)."""
    logs = []
    for s in seeds:
        make = m.scenario or _finger_scenario
        logs.append(one_log(m, make(s, duration), s))
        if quiet_min > 0:
            logs.append(one_log(m, _quiet(s + 500, 60.0 * quiet_min), s + 500))
    lat = [x for r in logs for x in r["latencies"]]
    touches = sum(r["touches"] for r in logs)
    hits = sum(r["hits"] for r in logs)
    fa = sum(r["false_alarms"] for r in logs)
    hours = sum(r["hours"] for r in logs)
    snr = float(np.median([r["snr"] for r in logs if math.isfinite(r["snr"])] or [math.nan]))
    med = float(np.median(lat)) if lat else math.nan
    lat_max = 0.4 if m.slow_boards else 0.3
    # the bar: a fingertip above the noise, every touch, no false alarm, a quick median; below
    # it, at most one false alarm an hour
    bar = (hits == touches and fa == 0 and med <= lat_max) if snr >= SNR_MIN else fa / hours <= 1.0
    off = np.array([r["offset_err"] for r in logs])
    lag = np.array([r["lag"] for r in logs])
    lag_err = np.array([r["lag_err"] for r in logs])
    return {"condition": m.name, "touches": touches, "detected": hits, "missed": touches - hits,
            "false_alarms": fa, "false_alarms_per_h": fa / hours, "hours": hours,
            # when in its log each came (s; a log's start is where its estimator learns)
            "false_alarms_at_s": sorted(x for r in logs for x in r["false_alarms_at_s"]),
            "latency_median_s": med, "latency_p90_s": float(np.percentile(lat, 90)) if lat else math.nan,
            "snr_one_finger": snr, "snr_line": bool(snr < SNR_MIN),
            "offset_err_median_K": float(np.median(np.abs(off))),
            "offset_err_max_K": float(np.abs(off).max()),
            "lag_learnt_median_s": float(np.median(lag)), "lag_err_max_s": float(np.abs(lag_err).max()),
            "bar_met": bool(bar)}


def markdown(res: dict[str, Any]) -> str:
    """The table of a ``--json`` result (``docs/sensors.md``)."""
    out = [f"Seeds {res['seeds'][0]}-{res['seeds'][-1]} (touch logs of {res['duration_s']:g} s) and "
           f"{res['seeds'][0] + 500}-{res['seeds'][-1] + 500} (no touch, {res['quiet_min']:g} min each).",
           "",
           "| condition | detected | false alarms (per hour) | latency median / p90 s | one-finger SNR "
           "| offset error max mK | lag learnt ms | bar |",
           "|---|---|---|---|---|---|---|---|"]
    for r in res["conditions"]:
        out.append(f"| {r['condition']} | {r['detected']}/{r['touches']} | {r['false_alarms']} "
                   f"({r['false_alarms_per_h']:.1f}) | {r['latency_median_s']:.2f} / "
                   f"{r['latency_p90_s']:.2f} "
                   f"| {r['snr_one_finger']:.1f}{' (line)' if r['snr_line'] else ''} "
                   f"| {r['offset_err_max_K'] * 1e3:.0f} | {r['lag_learnt_median_s'] * 1e3:.0f} "
                   f"| {'met' if r['bar_met'] else '**not met**'} |")
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3, help="logs with touches per condition")
    ap.add_argument("--seed0", type=int, default=SEED0, help="first seed (never used in tuning)")
    ap.add_argument("--duration", type=float, default=240.0, help="s per log with touches")
    ap.add_argument("--quiet-min", type=float, default=20.0, help="minutes of no touch per seed")
    ap.add_argument("--only", default=None, help="comma-separated substrings of condition names")
    ap.add_argument("--config", default=None, metavar="F",
                    help="a TOML file over the default configuration given to the estimator")
    ap.add_argument("--told-noise", action="store_true",
                    help="tell the estimator each log's boards' true noise per channel")
    ap.add_argument("--json", action="store_true", help="only the JSON line on stdout")
    ap.add_argument("--markdown", default=None, metavar="RESULT.json",
                    help="print the markdown table of a --json result and exit")
    a = ap.parse_args()
    if a.markdown:
        with open(a.markdown) as f:
            print(markdown(json.loads(f.read().splitlines()[-1])))
        return
    global CONFIG, TOLD_NOISE
    CONFIG = a.config
    TOLD_NOISE = a.told_noise
    if CONFIG is not None:
        try:
            load_config(CONFIG)
        except (OSError, ValueError) as e:
            raise SystemExit(f"mismatch.py: --config {CONFIG}: {e}") from None
    seeds = list(range(a.seed0, a.seed0 + a.seeds))
    grid = [m for m in GRID if a.only is None or any(s in m.name for s in a.only.split(","))]
    rows = []
    t0 = time.perf_counter()
    for m in grid:
        r = condition(m, seeds, a.duration, a.quiet_min)
        rows.append(r)
        if not a.json:
            print(f"{r['condition']:34s} {r['detected']:4d}/{r['touches']:<4d} FA {r['false_alarms']:3d} "
                  f"({r['false_alarms_per_h']:.2f}/h) latency {r['latency_median_s']:.2f}/"
                  f"{r['latency_p90_s']:.2f} s SNR {r['snr_one_finger']:.1f} "
                  f"offset err {r['offset_err_max_K'] * 1e3:.1f} mK "
                  f"lag {r['lag_learnt_median_s'] * 1e3:.0f} ms "
                  f"bar {'met' if r['bar_met'] else 'NOT met'}", file=sys.stderr, flush=True)
    print(json.dumps({"seeds": seeds, "duration_s": a.duration, "quiet_min": a.quiet_min, "config": a.config,
                      "wall_s": time.perf_counter() - t0, "conditions": rows}))


if __name__ == "__main__":
    main()
