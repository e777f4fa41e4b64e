"""`thermoskin observe --skin` on skin logs of growing length: its peak memory and time.

Simulates the forearm (`examples/forearm.toml`, 9 patches, scenario `multi`) for each
``--seconds`` (``thermoskin simulate --skin``, Parquet, kept in ``--dir``), then times
``thermoskin observe --skin`` on each log as a process of its own and reads its peak resident
memory from the kernel (``wait4``). Prints one JSON line: per length, the log's rows, the
command's wall time (median of ``--runs``) and its peak memory (MiB, the largest of the runs).
The observation streams its log (``skin_observe.observe_skin_file``), so the peak should not
follow the length. ``--run``: also ``thermoskin run --skin`` of each length (one run each), which
reads its log back the same way at its end.

    python benchmarks/observe_skin.py [--seconds 120,480] [--runs 3] [--format parquet] [--json]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
from pathlib import Path

from _proc import run

ROOT = Path(__file__).resolve().parent.parent
SKIN = ROOT / "examples" / "forearm.toml"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", default="120,480", help="log lengths, s (comma-separated)")
    ap.add_argument("--runs", type=int, default=3, help="runs of observe per length")
    ap.add_argument("--format", choices=("parquet", "csv"), default="parquet", help="the logs' format")
    ap.add_argument("--dir", default=None, help="folder for the logs (default: a temporary one)")
    ap.add_argument("--run", action="store_true",
                    help="also `thermoskin run --skin` of each length (one run: its loop, its log, "
                         "and the log read back at the end for positions)")
    ap.add_argument("--json", action="store_true", help="only the JSON line")
    a = ap.parse_args()
    folder = Path(a.dir) if a.dir else Path(tempfile.mkdtemp(prefix="observe_skin_"))
    folder.mkdir(parents=True, exist_ok=True)
    from thermoskin.skin.layout import load_skin

    skin = load_skin(SKIN)
    out: dict[str, object] = {"skin": SKIN.name, "format": a.format, "runs": a.runs, "lengths": []}
    for s in (float(x) for x in a.seconds.split(",")):
        log = folder / f"forearm_{s:g}s.{a.format}"
        if not log.exists():
            if not a.json:
                print(f"simulating {s:g} s ...", file=sys.stderr)
            run(["simulate", "--skin", str(SKIN), "--scenario", "multi", "--duration", f"{s:g}",
                 "-o", str(log)])
        walls, peaks = [], []
        for _ in range(a.runs):
            w, m = run(["observe", "--skin", str(SKIN), str(log), "-o", str(folder / f"out.{a.format}")])
            walls.append(w)
            peaks.append(m)
        row = {"seconds": s, "rows": round(s / skin.cfg.sampling.t_s) * len(skin.patches),
               "wall_s": round(statistics.median(walls), 2),
               "peak_mib": round(max(peaks), 1)}
        if a.run:
            w, m = run(["run", "--skin", str(SKIN), "--scenario", "multi", "--duration", f"{s:g}",
                        "--log", str(folder / f"run.{a.format}")])
            row.update({"run_wall_s": round(w, 2), "run_peak_mib": round(m, 1)})
        out["lengths"].append(row)  # type: ignore[attr-defined]
        if not a.json:
            print(row, file=sys.stderr)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
