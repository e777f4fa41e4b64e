"""Cost of `run --skin`'s live estimation: the closed loop of a skin (default examples/forearm.toml,
scenario multi) with every block of 1000 samples estimated as it is written (SkinEstimator), and
the per-patch messages of the live view (100 Hz) and of the recording (every sample) built from it.

Prints one JSON object: per block (1 s of loop), the estimation's median / p99 / max in ms and per
patch-sample in µs, the messages' build time, and the loop's real-time factor with and without.

    python benchmarks/skin_live.py [--skin examples/forearm.toml] [--duration 30]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from thermoskin.live.skin_topics import SkinMessages
from thermoskin.runtime.skin_loop import run_skin
from thermoskin.sim.skin_scenarios import skin_scenario
from thermoskin.skin.layout import load_skin
from thermoskin.skin.observe import SkinEstimator

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--skin", default=str(ROOT / "examples" / "forearm.toml"))
    ap.add_argument("--duration", type=float, default=30.0)
    a = ap.parse_args()
    skin = load_skin(a.skin)
    P = len(skin.patches)
    sc = skin_scenario("multi", skin, a.duration)
    SkinEstimator(skin, skin.cfg.sampling.t_s)  # compile (or load) the kernel first
    bare = run_skin(skin, sc)
    est = SkinEstimator(skin, skin.cfg.sampling.t_s)
    live, rec = SkinMessages(skin, 100.0), SkinMessages(skin)
    t_est: list[float] = []
    t_live: list[float] = []
    t_rec: list[float] = []

    def on_block(cols: dict) -> None:
        m = len(cols["t"]) // P
        c = {k: np.asarray(v).reshape(m, P) for k, v in cols.items() if k not in ("t", "patch")}
        t = np.asarray(cols["t"])[::P]
        t0 = time.perf_counter()
        b = est.block(t, c)
        t1 = time.perf_counter()
        for _ in live.messages(t, c, b):
            pass
        t2 = time.perf_counter()
        for _ in rec.messages(t, c, b):
            pass
        t3 = time.perf_counter()
        t_est.append((t1 - t0) * 1e3)
        t_live.append((t2 - t1) * 1e3)
        t_rec.append((t3 - t2) * 1e3)

    with_est = run_skin(skin, sc, on_block=on_block)
    e = np.array(t_est)
    out = {
        "skin": skin.name, "patches": P, "blocks": len(e), "block_samples": 1000,
        "estimate_ms_p50": float(np.median(e)), "estimate_ms_p99": float(np.percentile(e, 99)),
        "estimate_ms_max": float(e.max()),
        "estimate_us_per_patch_sample_p50": float(np.median(e) * 1e3 / (1000 * P)),
        "live_messages_ms_p50": float(np.median(t_live)), "record_messages_ms_p50": float(np.median(t_rec)),
        "realtime_factor_loop_only": bare.realtime_factor,
        "realtime_factor_with_estimation_and_messages": with_est.realtime_factor,
        "note": "shared two-core machine; message times are building them, not sending or writing",
    }
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
