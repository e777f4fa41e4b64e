"""`thermoskin simulate`, `run` and `plot` of growing length: their peak memory and time.

For each ``--seconds``: ``thermoskin simulate`` of the scenario (Parquet, kept in ``--dir``),
``thermoskin plot`` of that log, and ``thermoskin run`` of the scenario on the simulated skin
(``--events`` too: what touched), each a process of its own, its peak resident memory read from
the kernel (``wait4``). ``--realtime S,..``: also ``run --realtime`` (the fixed-rate loop
process, at wall-clock speed) of each length. Prints one JSON line: per length and command,
the wall time (median of ``--runs``) and the peak memory (MiB, the largest of the runs).
``--record S,..``: also ``run --record`` of each length, then ``replay`` of that recording
(to CSV) and ``export`` of it (to Parquet). ``--skin-record S,..``: ``run --skin --record``
of the forearm (``examples/forearm.toml``), then ``export`` of it (to Parquet). All stream
their logs (the plant's profiles a window at a time, the run's report gathered block by
block, a recording read a block at a time), so the peaks should not follow the length.
``--trace S``: one ``run --realtime`` of ``S`` s, the resident memory of the command and of
its loop process read every 15 s. ``--src DIR``: run the code under ``DIR`` (another
checkout's ``src``) instead, the peer of a before/after comparison. ``--peer DIR``: the same,
in the same run: every command is run once untimed with each code, then ``--runs`` times with
this code and with the code under ``DIR``, alternating (which goes first alternates too), and
each gets ``"peer"`` (its wall time and peak memory) and ``"ratio"`` (the median of the pairs'
time ratios, this / peer).

    python benchmarks/run_memory.py [--seconds 300,1200,3600] [--runs 1] [--realtime 60,240]
        [--record 300,1200] [--skin-record 30,120] [--trace 600] [--src DIR] [--peer DIR] [--json]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
from pathlib import Path

from _proc import check_package_dir, rss_trace, run


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", default="300,1200,3600", help="lengths, s (comma-separated)")
    ap.add_argument("--scenario", default="realistic", help="scenario (its touches, then quiet)")
    ap.add_argument("--runs", type=int, default=1, help="runs per command and length")
    ap.add_argument("--realtime", default="", help="lengths of `run --realtime`, s (none by default)")
    ap.add_argument("--record", default="", help="lengths of `run --record`, then replay and export, s")
    ap.add_argument("--skin-record", default="", help="lengths of `run --skin --record` (the forearm), "
                    "then export, s")
    ap.add_argument("--trace", type=float, default=0.0,
                    help="also one `run --realtime` of this many seconds, its memory read every 15 s")
    ap.add_argument("--dir", default=None, help="folder for the logs (default: a temporary one)")
    ap.add_argument("--src", default=None, help="run the package under this folder (PYTHONPATH)")
    ap.add_argument("--peer", default=None,
                    help="also the package under this folder, each command alternating with it")
    ap.add_argument("--json", action="store_true", help="only the JSON line")
    a = ap.parse_args()
    check_package_dir("--src", a.src)
    check_package_dir("--peer", a.peer)
    folder = Path(a.dir) if a.dir else Path(tempfile.mkdtemp(prefix="run_memory_"))
    folder.mkdir(parents=True, exist_ok=True)
    env = {"PYTHONPATH": a.src} if a.src else None
    peer_env = {"PYTHONPATH": a.peer} if a.peer else None

    def measure(args: list[str]) -> dict[str, object]:
        walls: list[float] = []
        peaks: list[float] = []
        peer_walls: list[float] = []
        peer_peaks: list[float] = []
        if a.peer:  # each side once first, untimed: compiled caches and page cache warm alike
            run(args, env)
            run(args, peer_env)
        for i in range(a.runs):
            order = [(env, walls, peaks)]
            if a.peer:
                order.append((peer_env, peer_walls, peer_peaks))
                if i % 2:
                    order.reverse()
            for e, ws, ms in order:
                w, m = run(args, e)
                ws.append(w)
                ms.append(m)
        res: dict[str, object] = {"wall_s": round(statistics.median(walls), 2),
                                  "peak_mib": round(max(peaks), 1)}
        if a.peer:
            res["peer"] = {"wall_s": round(statistics.median(peer_walls), 2),
                           "peak_mib": round(max(peer_peaks), 1)}
            pairs = zip(walls, peer_walls, strict=True)
            res["ratio"] = round(statistics.median([x / y for x, y in pairs]), 3)
        return res

    out: dict[str, object] = {"scenario": a.scenario, "runs": a.runs, "src": a.src or "installed",
                              "peer": a.peer,
                              "lengths": [], "realtime": [], "recordings": [],
                              "skin_recordings": [], "trace": []}
    for s in (float(x) for x in a.seconds.split(",") if x):
        if not a.json:
            print(f"{s:g} s ...", file=sys.stderr)
        log = folder / f"sim_{s:g}s.parquet"
        row: dict[str, object] = {"seconds": s}
        row["simulate"] = measure(["simulate", "--scenario", a.scenario, "--duration", f"{s:g}",
                                   "-o", str(log)])
        row["plot"] = measure(["plot", str(log), "-o", str(folder / "plot.png")])
        row["run"] = measure(["run", "--scenario", a.scenario, "--duration", f"{s:g}",
                              "--log", str(folder / "run.parquet"), "--events", str(folder / "run_ev.csv")])
        out["lengths"].append(row)  # type: ignore[attr-defined]
    for s in (float(x) for x in a.realtime.split(",") if x):
        if not a.json:
            print(f"run --realtime {s:g} s ...", file=sys.stderr)
        out["realtime"].append({"seconds": s, **measure(  # type: ignore[attr-defined]
            ["run", "--realtime", "--scenario", a.scenario, "--duration", f"{s:g}",
             "--log", str(folder / "rt.parquet")])})
    for s in (float(x) for x in a.record.split(",") if x):
        if not a.json:
            print(f"run --record {s:g} s, replay, export ...", file=sys.stderr)
        mcap = folder / f"rec_{s:g}s.mcap"
        row = {"seconds": s, "run_record": measure(
            ["run", "--scenario", a.scenario, "--duration", f"{s:g}", "--log", str(folder / "rec.parquet"),
             "--record", str(mcap)])}
        row["mcap_mib"] = round(mcap.stat().st_size / 2**20, 1)
        row["replay"] = measure(["replay", str(mcap), "-o", str(folder / "replay.csv")])
        row["export"] = measure(["export", str(mcap), "-o", str(folder / "export.parquet")])
        out["recordings"].append(row)  # type: ignore[attr-defined]
    skin = Path(__file__).resolve().parent.parent / "examples" / "forearm.toml"
    for s in (float(x) for x in a.skin_record.split(",") if x):
        if not a.json:
            print(f"run --skin --record {s:g} s, export ...", file=sys.stderr)
        mcap = folder / f"skin_{s:g}s.mcap"
        if not mcap.exists():
            run(["run", "--skin", str(skin), "--duration", f"{s:g}", "--log", str(folder / "skin.parquet"),
                 "--record", str(mcap)], env)
        row = {"seconds": s, "mcap_mib": round(mcap.stat().st_size / 2**20, 1),
               "export": measure(["export", str(mcap), "-o", str(folder / "skin_export.parquet")])}
        out["skin_recordings"].append(row)  # type: ignore[attr-defined]
    if a.trace:
        if not a.json:
            print(f"run --realtime {a.trace:g} s, traced ...", file=sys.stderr)
        out["trace"] = rss_trace(["run", "--realtime", "--scenario", a.scenario, "--duration", f"{a.trace:g}",
                                  "--log", str(folder / "trace.parquet")], env=env)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
