"""The current figures: run the benchmark scripts, keep each one's JSON with its date and machine
in docs/benchmarks.json, and write the table of docs/performance.md from what is kept.

Each row is one script with its arguments; its record holds the script's own JSON line, the
date (UTC) it ran, the commit, and the machine (CPU, cores, memory, load average before the
run). A row is measured again only when asked (``--only``), so a long benchmark measured once
stays with its date until it is run again; ``--render`` writes the table from the kept records
alone.

    python benchmarks/table.py                       # every row (about half an hour here)
    python benchmarks/table.py --only loop,patches   # some rows
    python benchmarks/table.py --render              # the table from what is kept
    python benchmarks/table.py --list                # the rows and their scripts
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
STORE = ROOT / "docs" / "benchmarks.json"
DOC = ROOT / "docs" / "performance.md"
START, END = "<!-- table:start (benchmarks/table.py writes this) -->", "<!-- table:end -->"

J = dict[str, Any]


@dataclass(frozen=True)
class Row:
    key: str
    what: str
    args: tuple[str, ...]
    figure: Callable[[J], str]
    target: str = "–"
    met: Callable[[J], bool | None] = lambda j: None


def _pct(d: J, unit: str = "µs") -> str:
    return f"p50 {d['p50_us']:g} {unit}, p99 {d['p99_us']:g} {unit}"


def _first(j: J, *keys: str) -> Any:
    for k in keys:
        if k in j:
            return j[k]
    raise KeyError(keys)


ROWS: tuple[Row, ...] = (
    Row(
        "loop",
        "the loop body (pump, MPC, inner loop, estimator), one sample; the closed loop with its plant",
        ("loop_step.py", "--seconds", "30", "--repeats", "3", "--json"),
        lambda j: (
            f"{_pct(j['body_fast'])}; after the first 10 s p99 {j['body_fast_after_10s']['p99_us']:g} µs; "
            f"closed loop {j['realtime_factor_fast']:g}× real time"
        ),
        "p99 ≤ 30 µs; ≥ 60× real time",
        lambda j: j["body_fast"]["p99_us"] <= 30 and j["realtime_factor_fast"] >= 60,
    ),
    Row(
        "estimator",
        "the estimator, one sample from Python (the loop body's call); over arrays",
        ("estimator_step.py", "--json"),
        lambda j: f"{_pct(j)}; over arrays {j['array_us_per_sample']:g} µs a sample",
    ),
    Row(
        "mpc",
        "the MPC (H = 100): the unconstrained optimum with a bounds check; the warm-started daqp QP",
        ("mpc_solve.py", "--json"),
        lambda j: (
            f"fast path p50 {j['fast']['p50_us']:g} µs (the QP on {100 * j['fast']['qp_fraction']:.1f} % "
            f"of samples); daqp every sample p50 {j['qp']['p50_us']:g} µs"
            if "fast" in j
            else json.dumps(j)[:200]
        ),
    ),
    Row(
        "patches",
        "1000 patches, one sample of each (one compiled loop on both cores): a skin's, which learn "
        "nothing of their boards; patches that learn theirs (the one-patch default)",
        ("patches.py", "--n", "1000", "--skin-detector", "--json"),
        lambda j: (
            f"a skin's {_pct(j['skin_detector'])} a tick; learning {_pct(j)}; equal to the plain-Python "
            f"reference to {max(j['max_abs_diff_W'], j['skin_detector']['max_abs_diff_W']):.1e} W"
        ),
        "p99 ≤ 100 µs (a skin's)",
        lambda j: j["skin_detector"]["p99_us"] <= 100,
    ),
    Row(
        "patches10k",
        "10 000 patches, one sample of each",
        ("patches.py", "--n", "10000", "--ticks", "1000", "--json"),
        lambda j: (
            f"p50 {j['p50_us'] / 1e3:.2f} ms ({j['ns_per_patch_p50']:g} ns a patch), "
            f"p99 {j['p99_us'] / 1e3:.2f} ms"
        ),
    ),
    Row(
        "host",
        "this host's stalls: a bare loop on each core, no estimator",
        ("host_jitter.py", "--seconds", "5", "--json"),
        lambda j: (
            f"{j['stalls_over_20us_per_s_merged']:g} stalls a second over 20 µs "
            f"({100 * j['ticks_hit_over_20us']:.1f} % of 60 µs ticks hit)"
        ),
    ),
    Row(
        "parts",
        "plain-Python blocks a call: the Peltier tank, the spatial skin, a SAMPLE frame both ends",
        ("parts_step.py", "--json"),
        lambda j: "; ".join(f"{k.replace('_', ' ')} {_pct(v)}" for k, v in j.items() if isinstance(v, dict)),
        "5, 50, 200 µs",
        lambda j: all(v["met"] for v in j.values() if isinstance(v, dict)),
    ),
    Row(
        "observe",
        "`thermoskin observe` of a 1 h, 1 kHz log (3.6 M rows) against polars alone reading it and "
        "writing the same columns plus two",
        ("observe_log.py", "--runs", "3", "--memory-hours", "", "--json"),
        lambda j: "; ".join(
            f"{fmt.upper()} {j[fmt]['ratio']:g}× ({j[fmt]['observe_s']:g} s against "
            f"{j[fmt]['polars_s']:g} s), peak {j[fmt]['observe_peak_mib']} MiB"
            for fmt in ("csv", "parquet")
            if fmt in j
        ),
        "CSV ≤ 2×, Parquet ≤ 3×, ≤ 1 GiB",
        lambda j: j["csv"]["ratio"] <= 2 and j["parquet"]["ratio"] <= 3,
    ),
    Row(
        "startup",
        'start-up of the `thermoskin` program against `python -c "import numpy"`',
        ("startup.py", "--runs", "11", "--json"),
        lambda j: (
            f"`--help` {j['help']['ratio_to_numpy']:g}×, `observe` of a 2 s log "
            f"{j['observe_2s']['ratio_to_numpy']:g}×"
        ),
        "`--help` ≤ 3×, `observe` ≤ 6×",
        lambda j: j["help"]["ratio_to_numpy"] <= 3 and j["observe_2s"]["ratio_to_numpy"] <= 6,
    ),
    Row(
        "compile",
        "the estimator's compile on an empty cache (a fresh install's first `run` or `observe`)",
        ("compile_time.py", "--runs", "1", "--json"),
        lambda j: f"{j['warm_up_s']['median']:g} s",
    ),
    Row(
        "calibrate",
        "`calibrate` of a 300 s, 1 kHz no-touch log whose thermocouples carry offsets (0.3, -0.2, 0.5 K)",
        ("calibrate.py", "--only", "offsets", "--runs", "3", "--json"),
        lambda j: (
            f"median {j['offsets']['wall_s_median']:.2g} s (max {j['offsets']['wall_s_max']:.2g} s); "
            "offsets within "
            f"{1e3 * max(v for v in j['offsets']['offset_error_abs_max_K'].values() if v == v):.1f} mK"
        ),
        "≤ 15 s; offsets within 20 mK",
        lambda j: j["offsets"]["wall_s_max"] <= 15
        and max(v for v in j["offsets"]["offset_error_abs_max_K"].values() if v == v) <= 0.02,
    ),
    Row(
        "firmware",
        "the reference firmware's frame loop, one sample, on MicroPython's Unix port (x86-64)",
        ("firmware_loop.py", "--runs", "5", "--json"),
        lambda j: (
            "p50 {:.1f} µs, p99 {:.1f} µs a sample (median of the runs); a 46-byte CRC {:.1f} µs".format(
                *(
                    sorted(r[k] for r in j["micropython_unix"])[len(j["micropython_unix"]) // 2]
                    for k in ("sample_p50_us", "sample_p99_us", "crc16_46_bytes_us")
                )
            )
            if isinstance(j.get("micropython_unix"), list)
            else str(j.get("micropython_unix"))
        ),
    ),
    Row(
        "suite",
        "the test suite from a clean state (the README's command; empty numba and pytest caches), "
        "on two cores",
        ("suite_time.py", "--runs", "2", "--json"),
        lambda j: (
            f"median {j['median_wall_s']:g} s ("
            + ", ".join(f"{r['wall_s']:g} s" for r in j["runs"])
            + f"), {j['runs'][-1]['passed']} passed" + ("" if j["all_passed"] else ", **a run failed**")
        ),
        target="≤ 300 s",
        met=lambda j: j["all_passed"] and j["median_wall_s"] <= 300.0,
    ),
    Row(
        "sweep",
        "`thermoskin sweep examples/sweep.toml` (1000 designs of 60 s in closed loop)",
        ("sweep.py", "--runs", "3", "--json"),
        lambda j: (
            f"median {j['median_s']:g} s (max {j['max_s']:g} s), "
            f"{j['point_samples_per_s'] / 1e6:.1f} M point-samples a second"
        ),
    ),
)


def machine() -> J:
    """What ran it: CPU, cores, memory, the load average just before."""
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "memory_gib": round(mem, 1),
        "load_1min": round(os.getloadavg()[0], 2),
    }


def commit() -> str:
    r = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True)
    return r.stdout.strip() or "unknown"


def measure(row: Row) -> J:
    cmd = [sys.executable, str(ROOT / "benchmarks" / row.args[0]), *row.args[1:]]
    print(f"{row.key}: {' '.join(row.args)}", file=sys.stderr, flush=True)
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": ""}
    when = dt.datetime.now(dt.UTC)
    mach = machine()
    p = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, env=env)
    if p.returncode != 0:
        raise SystemExit(
            f"{row.key}: {row.args[0]} failed (exit {p.returncode}): "
            f"{' '.join(p.stderr.strip().splitlines()[-3:])}"
        )
    try:
        out = json.loads(p.stdout.strip().splitlines()[-1])
    except json.JSONDecodeError:  # a script printing indented JSON
        out = json.loads(p.stdout)
    return {
        "script": f"benchmarks/{' '.join(row.args)}",
        "date": when.strftime("%Y-%m-%d %H:%M UTC"),
        "commit": commit(),
        "machine": mach,
        "seconds": round((dt.datetime.now(dt.UTC) - when).total_seconds()),
        "json": out,
    }


def render(store: J) -> str:
    lines = ["| what | measured | target | script | when, where |", "|---|---|---|---|---|"]
    for row in ROWS:
        rec = store.get(row.key)
        if rec is None:
            continue
        j = rec["json"]
        try:
            fig = row.figure(j)
        except (KeyError, TypeError):
            fig = "(the script's JSON changed: run it again)"
        met = row.met(j) if row.target != "–" else None
        target = row.target + ("" if met is None else (": met" if met else ": **not met**"))
        m = rec["machine"]
        lines.append(
            f"| {row.what} | {fig} | {target} | `{rec['script']}` | {rec['date']}, {rec['commit']}; "
            f"{m['cores']} cores ({m['cpu']}), load {m['load_1min']:g} |"
        )
    return "\n".join(lines)


def write_doc(table: str) -> None:
    text = DOC.read_text(encoding="utf-8")
    if START not in text:
        raise SystemExit(f"{DOC}: no {START} marker")
    head, rest = text.split(START, 1)
    _, tail = rest.split(END, 1)
    DOC.write_text(head + START + "\n" + table + "\n" + END + tail, encoding="utf-8")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", default=None, help="comma-separated rows to measure (see --list)")
    ap.add_argument("--render", action="store_true", help="write the table from the kept records only")
    ap.add_argument("--list", action="store_true")
    a = ap.parse_args()
    if a.list:
        for row in ROWS:
            print(f"{row.key:>11}  benchmarks/{' '.join(row.args)}")
        return
    store: J = json.loads(STORE.read_text()) if STORE.exists() else {}
    if not a.render:
        keys = (
            [r.key for r in ROWS] if a.only is None else [k.strip() for k in a.only.split(",") if k.strip()]
        )
        unknown = set(keys) - {r.key for r in ROWS}
        if unknown:
            raise SystemExit(f"--only: unknown row(s) {', '.join(sorted(unknown))} (see --list)")
        for row in ROWS:
            if row.key in keys:
                store[row.key] = measure(row)
                STORE.write_text(json.dumps(store, indent=1, ensure_ascii=False) + "\n")
    write_doc(render(store))
    print(json.dumps({k: store[k]["date"] for k in store}))


if __name__ == "__main__":
    main()
