"""The host's own stalls: how often a busy thread loses the CPU, for how long, and on which cores at once.

A tick of many patches (``benchmarks/patches.py``) ends when the last core finishes its share,
so a stall of any core lands in that tick whole. This measures the stalls with no estimator at
all: one process per core (each pinned to its core) spins reading the clock for ``--seconds``
and records every gap between two readings longer than 5 µs (the loop's own step is about
0.1 µs), with its start and end on the machine's monotonic clock. It prints one JSON line: per
core, the gaps per second over 10, 20, 40 and 80 µs and their p50/p99/max; the share of one
core's stalls over 20 µs that overlap a stall of another core (1: the whole machine stops, as a
virtual machine does when its host takes it off the CPU; 0: each core alone); and, for ticks of
``--tick-us``, the share of ticks a stall over 20 and over 40 µs would hit: ``1 - exp(-rate *
tick)`` with ``rate`` that of the stalls of all cores merged where they overlap. If that share
is above 1 %, such stalls reach a tick's p99, whatever the tick computes.

Beside the stalls it gives each core's interrupts a second over the same window, from
``/proc/interrupts`` (``LOC``: the guest kernel's own timer tick, ``CONFIG_HZ`` a second on a
busy core), to set the stalls' rate against.

It also asks whether the cores are cores: a compiled loop of independent multiply-adds (it
keeps a core's arithmetic units busy, as the estimation kernel does) is timed on each core
alone and then on every core at once (threads pinned, started together). ``shared_slowdown``
is the ratio of the two times (medians of ``--reps``): about 1 where each virtual CPU has a
physical core of its own, 1.5-2 where they are hyperthreads of one core (SMT), which then
share its units and a tick of many patches gains far less than the core count from both.

    python benchmarks/host_jitter.py [--seconds 3] [--tick-us 65] [--reps 5] [--json]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import threading
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from numba import njit

LIMITS_US = (10, 20, 40, 80)


def spin(args: tuple[int, float]) -> list[tuple[int, int]]:
    """On core ``args[0]`` for ``args[1]`` s: (start, end) in ns of each gap over 5 µs between
    consecutive clock readings of a busy loop."""
    core, seconds = args
    os.sched_setaffinity(0, {core})
    pc = time.perf_counter_ns  # CLOCK_MONOTONIC: one clock for every process
    gaps: list[tuple[int, int]] = []
    end = pc() + int(seconds * 1e9)
    last = pc()
    while last < end:
        now = pc()
        if now - last > 5000:
            gaps.append((last, now))
        last = now
    return gaps


@njit(nogil=True, fastmath=True)
def _multiply_adds(n: int, a: np.ndarray) -> float:
    """``n`` passes of eight independent multiply-add chains over ``a``: bound by the core's
    arithmetic throughput, not by memory (``a`` stays in L1) nor by one chain's latency."""
    s0 = s1 = s2 = s3 = s4 = s5 = s6 = s7 = 0.0
    for _ in range(n):
        for i in range(0, a.shape[0], 8):
            s0 += a[i] * 1.0001
            s1 += a[i + 1] * 1.0001
            s2 += a[i + 2] * 1.0001
            s3 += a[i + 3] * 1.0001
            s4 += a[i + 4] * 1.0001
            s5 += a[i + 5] * 1.0001
            s6 += a[i + 6] * 1.0001
            s7 += a[i + 7] * 1.0001
    return s0 + s1 + s2 + s3 + s4 + s5 + s6 + s7


def shared_core(cpus: list[int], reps: int, passes: int = 50_000) -> dict[str, float]:
    """Seconds of :func:`_multiply_adds` on one core alone and on every core at once (median
    over ``reps``; at once: the slowest thread), and their ratio."""
    a = np.random.default_rng(0).random(2048)
    _multiply_adds(1, a)  # compile

    def timed(core: int, go: threading.Barrier | None, out: list[float]) -> None:
        os.sched_setaffinity(0, {core})  # this thread alone (Linux)
        if go is not None:
            go.wait()
        t0 = time.perf_counter()
        _multiply_adds(passes, a)
        out.append(time.perf_counter() - t0)

    alone: list[float] = []
    together: list[float] = []
    for _ in range(reps):
        for c in cpus:
            th = threading.Thread(target=timed, args=(c, None, alone))
            th.start()
            th.join()
        got: list[float] = []
        go = threading.Barrier(len(cpus))
        ths = [threading.Thread(target=timed, args=(c, go, got)) for c in cpus]
        for th in ths:
            th.start()
        for th in ths:
            th.join()
        together.append(max(got))
    t1, t2 = float(np.median(alone)), float(np.median(together))
    return {"alone_s": round(t1, 4), "together_s": round(t2, 4), "shared_slowdown": round(t2 / t1, 2)}


def interrupts() -> dict[str, list[int]] | None:
    """``/proc/interrupts``: each interrupt's count per CPU (None where the file is not there)."""
    try:
        with open("/proc/interrupts") as f:
            lines = f.read().splitlines()
    except OSError:
        return None
    ncpu = len(lines[0].split())
    out: dict[str, list[int]] = {}
    for line in lines[1:]:
        name, _, rest = line.partition(":")
        cols = rest.split()[:ncpu]
        if len(cols) == ncpu and all(c.isdigit() for c in cols):
            out[name.strip()] = [int(c) for c in cols]
    return out


def interrupt_rates(before: dict[str, list[int]] | None, after: dict[str, list[int]] | None,
                    cpus: list[int], seconds: float) -> list[dict[str, float]] | None:
    """Per core of ``cpus``: each interrupt's rate per second between two :func:`interrupts`
    readings (those that came at all), the local timer's (``LOC``) first."""
    if before is None or after is None:
        return None
    rows = []
    for c in cpus:
        row = {}
        for name, counts in after.items():
            if name in before and c < len(counts):
                d = counts[c] - before[name][c]
                if d > 0:
                    row[name] = round(d / seconds, 1)
        rows.append(dict(sorted(row.items(), key=lambda kv: (kv[0] != "LOC", -kv[1]))))
    return rows


def merged(spans: list[np.ndarray]) -> int:
    """Number of stalls once the cores' overlapping ones are merged into one."""
    s = np.concatenate(spans) if spans else np.empty((0, 2))
    if not len(s):
        return 0
    s = s[np.argsort(s[:, 0])]
    n, end = 1, s[0, 1]
    for a, b in s[1:]:
        if a > end:
            n += 1
        end = max(end, b)
    return n


def overlap_share(spans: list[np.ndarray]) -> float | None:
    """Share of the stalls of each core that overlap some stall of another core."""
    hit = total = 0
    for i, x in enumerate(spans):
        others = [y for j, y in enumerate(spans) if j != i and len(y)]
        if not others:
            continue
        y = np.concatenate(others)
        for a, b in x:
            total += 1
            hit += bool(((y[:, 0] < b) & (y[:, 1] > a)).any())
    return round(hit / total, 3) if total else None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=3.0, help="spin this long on each core")
    ap.add_argument("--tick-us", type=float, default=65.0, help="a tick, µs (1000 patches: about 65)")
    ap.add_argument("--reps", type=int, default=5, help="repetitions of the shared-core test")
    ap.add_argument("--json", action="store_true", help="only the JSON line")
    a = ap.parse_args()
    cpus = sorted(os.sched_getaffinity(0))
    with ProcessPoolExecutor(len(cpus)) as ex:
        ex.submit(int, 0).result()  # the workers up before the interrupts are counted
        irq0 = interrupts()
        per_core = [np.array(g, dtype=np.int64).reshape(-1, 2)
                    for g in ex.map(spin, [(c, a.seconds) for c in cpus])]
        irq1 = interrupts()
    out: dict[str, object] = {"cores": len(cpus), "seconds": a.seconds, "tick_us": a.tick_us}
    cores_out = []
    for gaps in per_core:
        g = (gaps[:, 1] - gaps[:, 0]) * 1e-3
        row: dict[str, float | None] = {f"over_{lim}us_per_s": round(float((g > lim).sum()) / a.seconds, 1)
                                        for lim in LIMITS_US}
        row["p50_us"] = round(float(np.median(g)), 1) if g.size else None
        row["p99_us"] = round(float(np.percentile(g, 99)), 1) if g.size else None
        row["max_us"] = round(float(g.max()), 1) if g.size else None
        cores_out.append(row)
    out["per_core"] = cores_out
    # what the guest's kernel took the cores for meanwhile: its timer tick (LOC, CONFIG_HZ a
    # second on a busy core) and the cross-CPU calls (CAL, RES, TLB) each leave the virtual
    # machine, which on a shared host can cost tens of µs
    out["interrupts_per_s"] = interrupt_rates(irq0, irq1, cpus, a.seconds)
    long20 = [x[(x[:, 1] - x[:, 0]) > 20_000] for x in per_core]
    out["overlap_share_over_20us"] = overlap_share(long20)
    tick = a.tick_us * 1e-6
    for lim in (20, 40):
        spans = [x[(x[:, 1] - x[:, 0]) > lim * 1000] for x in per_core]
        rate = merged(spans) / a.seconds  # any core's stall holds the tick; simultaneous ones once
        out[f"stalls_over_{lim}us_per_s_merged"] = round(rate, 1)
        out[f"ticks_hit_over_{lim}us"] = round(1.0 - math.exp(-rate * tick), 4)
    if len(cpus) > 1:
        out["multiply_adds"] = shared_core(cpus, a.reps)
    if not a.json:
        print(json.dumps(out, indent=1))
    print(json.dumps(out))


if __name__ == "__main__":
    main()
