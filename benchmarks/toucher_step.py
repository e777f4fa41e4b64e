"""Per-sample cost of a toucher (physics/contact.py): ``step(T_g, G)`` and ``begin``/``end``.

For every preset, a touch is stepped at 1 kHz (contact for half the samples, released for
the other half, the sheet temperature varying): batches of ``--batch`` steps are timed
with ``perf_counter_ns`` (the timer's own cost spread over the batch), ``--repeats``
batches per kind; the per-step median and p99 over the batches are reported, and the
same for the ``begin(G)`` + ``end(T_g)`` pair the coupled simulator uses. Prints one JSON
object as its last line (the machine is shared: read medians, not maxima).

    python benchmarks/toucher_step.py [--batch 2000] [--repeats 200] [--json]
"""

from __future__ import annotations

import argparse
import gc
import json
import time

import numpy as np

from thermoskin.physics.contact import HUMANS, OBJECTS, toucher


def time_kind(kind: str, batch: int, repeats: int) -> dict[str, float]:
    t = toucher(kind)
    G = t.truth["G_true"]
    T_g = [24.0 + 0.001 * (k % 100) for k in range(batch)]
    Gs = [G if k < batch // 2 else 0.0 for k in range(batch)]
    step, begin, end = t.step, t.begin, t.end
    clock = time.perf_counter_ns
    per_step = np.empty(repeats)
    per_pair = np.empty(repeats)
    gc.disable()
    try:
        for r in range(repeats):
            t0 = clock()
            for k in range(batch):
                step(T_g[k], Gs[k])
            per_step[r] = (clock() - t0) / batch
            t0 = clock()
            for k in range(batch):
                begin(Gs[k])
                end(T_g[k])
            per_pair[r] = (clock() - t0) / batch
    finally:
        gc.enable()
    # an empty loop of the same shape, to subtract the loop's own cost
    t0 = clock()
    for k in range(batch):
        _ = (T_g[k], Gs[k])
    loop_ns = (clock() - t0) / batch
    return {
        "nodes": len(t.C),
        "step_p50_us": round(float(np.percentile(per_step, 50)) / 1e3, 3),
        "step_p99_us": round(float(np.percentile(per_step, 99)) / 1e3, 3),
        "begin_end_p50_us": round(float(np.percentile(per_pair, 50)) / 1e3, 3),
        "begin_end_p99_us": round(float(np.percentile(per_pair, 99)) / 1e3, 3),
        "loop_overhead_us": round(loop_ns / 1e3, 3),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", type=int, default=2000, help="steps per timed batch")
    ap.add_argument("--repeats", type=int, default=200, help="batches per kind")
    ap.add_argument("--json", action="store_true", help="only the JSON line")
    a = ap.parse_args()
    res = {kind: time_kind(kind, a.batch, a.repeats) for kind in [*HUMANS, *OBJECTS]}
    if not a.json:
        for kind, r in res.items():
            print(f"{kind:16s} {r['nodes']:2d} nodes: step p50 {r['step_p50_us']:.2f} us "
                  f"(p99 {r['step_p99_us']:.2f}), begin+end p50 {r['begin_end_p50_us']:.2f} us")
    print(json.dumps({"per_kind": res, "batch": a.batch, "repeats": a.repeats,
                      "note": "medians over batches on a shared two-core machine"}))


if __name__ == "__main__":
    main()
