"""Per-call cost of the small blocks of the 1 kHz path that are plain Python: the Peltier
tank's step, the spatial skin's step (the emulator's plant), and a SAMPLE frame encoded and
decoded (the serial link, each end). These were timed tests; timing belongs here.

Each figure is the median and p99 over ``--repeats`` batches of ``--n`` calls (µs a call); the
maxima are the shared host's stalls. Prints one JSON object as its last line.

    python benchmarks/parts_step.py [--n 20000] [--repeats 30] [--json]
"""

from __future__ import annotations

import argparse
import gc
import json
import statistics
import time
from collections.abc import Callable

import numpy as np

from thermoskin.devices import protocol as proto
from thermoskin.devices.protocol import Decoder, SampleMsg, encode
from thermoskin.params import Config, PeltierParams
from thermoskin.physics.peltier import PeltierTank
from thermoskin.sim.spatial_skin import SpatialSkin

TARGETS_US = {"peltier_tank_step": 5.0, "spatial_skin_step": 50.0, "sample_frame_encode_decode": 200.0}
"""What each must stay under, µs a call (a fifth of the 1 ms sample for the frame)."""


def batches(call: Callable[[], object], n: int, repeats: int) -> list[float]:
    """µs a call in each of ``repeats`` batches of ``n`` calls."""
    out = []
    for _ in range(repeats):
        gc.collect()
        t0 = time.perf_counter()
        for _ in range(n):
            call()
        out.append((time.perf_counter() - t0) / n * 1e6)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=20_000)
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--json", action="store_true", help="the JSON line only")
    a = ap.parse_args()
    tank = PeltierTank(PeltierParams(), 1e-3)
    tank.reset(24.0)
    skin = SpatialSkin(Config())
    skin.reset_equilibrium(24.0, 0.141, 20.0)
    m = SampleMsg(123, t_us=123_000, T_w=24.25, T_p=24.5, T_a=20.0, fresh=proto.CH_W, status=proto.ST_SAFE,
                  counters=(123, 2, 65535), v=0.140625, drive=-0.5, cmd_seq=122)
    frame = encode(m)
    dec = Decoder(check_seq=False)

    def frame_both() -> None:
        encode(m)
        dec.feed(frame)

    calls = {"peltier_tank_step": lambda: tank.step(0.1, 20.0, 0.0),
             "spatial_skin_step": lambda: skin.step(24.0, 0.141, 20.0, 0.05, 34.0, position=0.5),
             "sample_frame_encode_decode": frame_both}
    res = {}
    for name, call in calls.items():
        call()  # the first call's imports and caches out of the figure
        t = batches(call, a.n if name != "spatial_skin_step" else a.n // 4, a.repeats)
        p99 = float(np.percentile(t, 99))
        res[name] = {"p50_us": round(statistics.median(t), 3), "p99_us": round(p99, 3),
                     "max_us": round(max(t), 3), "target_us": TARGETS_US[name],
                     "met": p99 < TARGETS_US[name]}
        if not a.json:
            print(f"{name}: p50 {res[name]['p50_us']} µs, p99 {res[name]['p99_us']} µs "
                  f"(target {TARGETS_US[name]} µs)")
    print(json.dumps({"n": a.n, "repeats": a.repeats, **res}))


if __name__ == "__main__":
    main()
