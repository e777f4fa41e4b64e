"""Issue 12's done-when check on a skin: every touch on its patch, no event elsewhere, latency, position.

For each seed (the sensors' noise), ``examples/forearm.toml`` under scenario ``multi`` is run in
closed loop (``run_skin``), the truth columns are removed, and every patch is estimated
(``observe_skin``). Against the truth (``contact_true`` per patch): a touch is found when an
event on its patch overlaps it (latency: detection minus the true onset); an event overlapping
no touch of its patch (0.5 s of slack after the release) is a false alarm (on a touched patch)
or an event on an untouched patch (a patch the scenario never touches: none in ``multi``, where
every patch is touched at some time); ``false_near_touch`` counts the false alarms that came
while some patch of the skin was touched or within ``NEAR_S`` s after. Position: for patches
with two thermocouples, the error of the reported position against the contact's mean true
position, RMS as a share of the pipe length, and how many touches had a position at all.
The machine may be shared.

``--rate HZ``: thermocouple boards converting that many times a second (every channel, 3 %
jitter; default: fresh every sample); ``--S-w``: the estimator's pipe-node noise (K²/s, kept
where above a skin patch's own), as a config would set it; ``--no-fresh``: the log without its
``fresh`` column (a lab's own logger), its readings found from the values; ``--flow-noise``:
``skin_observe.FLOW_NOISE`` (0: none; it was fitted on ``forearm.toml``, and
``benchmarks/skins/upper_arm.toml``, a skin it was not fitted on, checks it).

    python benchmarks/skin_detection.py [--skin F.toml] [--seeds 0,1,2] [--duration S] [--rate HZ]
        [--S-w X] [--no-fresh] [--flow-noise X] [--json]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import tempfile
from pathlib import Path

import numpy as np

from thermoskin.runtime.skin_loop import run_skin
from thermoskin.sim.skin_scenarios import skin_scenario
from thermoskin.skin import observe as skin_observe
from thermoskin.skin.layout import load_skin
from thermoskin.skin.log import read_skin_log
from thermoskin.skin.observe import observe_skin

ROOT = Path(__file__).resolve().parent.parent
NEAR_S = 3.0
"""A false alarm this soon after (or during) a touch anywhere on the skin counts as near a touch."""


def score(log, obs, skin) -> dict[str, object]:
    """Touches found, latencies, false alarms and position errors of one run (module doc)."""
    t = log.t
    lat, missed, false, pos_err, pos_none = [], [], [], [], 0
    any_touch = log.cols["contact_true"].any(axis=1)
    w = round(NEAR_S / log.t_s)
    for i, p in enumerate(skin.patches):
        c = log.cols["contact_true"][:, i].astype(int)
        d = np.diff(np.concatenate([[0], c, [0]]))
        on, off = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
        evs = [e for e in obs.events if e.patch == i]
        for a, b in zip(on, off, strict=True):
            hit = [e for e in evs if e.event.onset < t[b - 1] and e.event.release > t[a]]
            if not hit:
                missed.append((p.name, float(t[a])))
                continue
            e = hit[0]
            lat.append(e.event.detected_at - t[a])
            if len(p.thermocouples) >= 2:
                true = float(np.nanmean(log.cols["position_true"][a:b, i]))
                if np.isfinite(e.position.mean):
                    pos_err.append((e.position.mean - true) / p.length)
                else:
                    pos_none += 1
        for e in evs:
            if not any(e.event.onset < t[b - 1] + 0.5 and e.event.release > t[a] for a, b in zip(on, off,
                                                                                           strict=True)):
                k = int(np.searchsorted(t, e.event.onset))
                near = any_touch[max(k - w, 0):k + 1].any()  # another patch touched then (or just before)
                false.append((p.name, round(e.event.onset, 2), bool(len(on)), bool(near)))
    return {"touches": len(lat) + len(missed), "found": len(lat), "missed": missed,
            "false_on_touched": sum(1 for f in false if f[2]),
            "events_on_untouched": sum(1 for f in false if not f[2]),
            "false_near_touch": sum(1 for f in false if f[3]), "false": false[:20],
            "latencies": lat, "pos_err": pos_err, "pos_none": pos_none}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--skin", default=str(ROOT / "examples" / "forearm.toml"))
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--duration", type=float, default=None)
    ap.add_argument("--rate", type=float, default=None, help="boards' rate, Hz (default: every sample)")
    ap.add_argument("--S-w", dest="S_w", type=float, default=None, help="estimator.S_w, K^2/s")
    ap.add_argument("--no-fresh", action="store_true", help="drop the log's fresh column")
    ap.add_argument("--flow-noise", type=float, default=None,
                    help=f"skin_observe.FLOW_NOISE (default {skin_observe.FLOW_NOISE:g}; 0: none)")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    if a.flow_noise is not None:
        skin_observe.FLOW_NOISE = a.flow_noise  # read by patch_config at each call
    base = load_skin(a.skin)
    if a.rate:
        p = 1.0 / a.rate
        base = load_skin(a.skin, base.cfg.replace(sensor={"period_T_w": p, "period_T_p": p, "period_T_a": p,
                                                          "jitter": 0.03 * p}))
    runs, lat, err = [], [], []
    for seed in [int(s) for s in a.seeds.split(",")]:
        cfg = dataclasses.replace(base.cfg, sensor=dataclasses.replace(base.cfg.sensor, seed=seed))
        skin = load_skin(a.skin, cfg)
        seen = skin if a.S_w is None else load_skin(a.skin, cfg.replace(estimator={"S_w": a.S_w}))
        sc = skin_scenario("multi", skin, a.duration)
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "log.parquet"
            run_skin(skin, sc, path)
            log = read_skin_log(path, skin)
        truth = {k: log.cols.pop(k) for k in ("q_i", "contact_true", "position_true")}
        if a.no_fresh:
            log.cols.pop("fresh")
        log.names = [k for k in log.names if k in log.cols]
        obs = observe_skin(log, seen)
        log.cols.update(truth)
        s = score(log, obs, skin)
        lat += s["latencies"]
        err += s["pos_err"]
        runs.append({"seed": seed, **{k: v for k, v in s.items() if k not in ("latencies", "pos_err")},
                     "latency_median_s": float(np.median(s["latencies"])) if s["latencies"] else None})
        if not a.json:
            print(json.dumps(runs[-1]))
    out = {"skin": Path(a.skin).name, "scenario": "multi", "rate_hz": a.rate, "S_w": a.S_w,
           "fresh": not a.no_fresh, "flow_noise": skin_observe.FLOW_NOISE,
           "seeds": len(runs),
           "touches": sum(r["touches"] for r in runs), "found": sum(r["found"] for r in runs),
           "false_on_touched": sum(r["false_on_touched"] for r in runs),
           "events_on_untouched": sum(r["events_on_untouched"] for r in runs),
           "false_near_touch": sum(r["false_near_touch"] for r in runs),
           "latency_median_s": float(np.median(lat)) if lat else None,
           "latency_p90_s": float(np.quantile(lat, 0.9)) if lat else None,
           "position_rms_share_of_length": float(np.sqrt(np.mean(np.square(err)))) if err else None,
           "positions_reported": len(err), "positions_empty": sum(r["pos_none"] for r in runs),
           "runs": runs}
    print(json.dumps(out))


if __name__ == "__main__":
    main()
