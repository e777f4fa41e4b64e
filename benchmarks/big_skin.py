"""A skin of many patches, written as a skin description (TOML), for the scale measurements of
docs/skin.md ("Limits"): ``N`` patches of the paper's size (30 x 10 mm) on a grid of one link,
their pipes along x, in water loops of ``--per-loop`` patches in series (20 mm of pipe between
two, 0.2 m to and from each tank); every patch one thermocouple at its outlet.

    python benchmarks/big_skin.py --patches 1000 -o /tmp/skin1000.toml
    python benchmarks/big_skin.py --patches 10000 -o /tmp/skin10000.toml --measure 2

With ``--measure S``: then `thermoskin simulate --skin` (S s), `observe --skin` of that log and
`run --skin` (S s) as processes of their own, each one's wall time and peak resident memory
(MiB, from the kernel), or its one-line refusal; prints one JSON object.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CMD = [sys.executable, "-c", "from thermoskin.__main__ import main; main()"]


def skin_toml(n: int, per_loop: int = 10) -> str:
    cols = math.ceil(math.sqrt(n * 2))  # about as wide (0.04 m a column) as high (0.02 m a row)
    rows = math.ceil(n / cols)
    length, circumference = 0.04 * cols + 0.02, 0.02 * rows + 0.02
    names = [f"p{k}" for k in range(n)]
    out = [f'name = "grid{n}"', "", "[links.body]", f"length = {length:.3f}",
           f"circumference = {circumference:.3f}", "origin = [0.0, 0.0]", ""]
    for j in range(0, n, per_loop):
        members = names[j:j + per_loop]
        pipes = [0.2] + [0.02] * (len(members) - 1) + [0.2]
        out += [f"[loops.l{j // per_loop}]", f"patches = [{', '.join(repr(m) for m in members)}]",
                f"pipes = [{', '.join(str(p) for p in pipes)}]", "tank = [-0.05, 0.0]", ""]
    for k, name in enumerate(names):
        c, r = k % cols, k // cols
        centre = f"[{0.03 + 0.04 * c:.3f}, {0.02 + 0.02 * r:.3f}]"
        out += [f"[patches.{name}]", 'link = "body"', f"centre = {centre}", ""]
    return "\n".join(out).replace("'", '"')


def measure(args: list[str]) -> dict[str, object]:
    with tempfile.TemporaryFile("w+") as errf:  # a file: a pipe would fill with the contacts' lines
        t0 = time.perf_counter()
        p = subprocess.Popen([*CMD, *args], stdout=subprocess.DEVNULL, stderr=errf, text=True)
        _, status, usage = os.wait4(p.pid, 0)
        wall = time.perf_counter() - t0
        errf.seek(0)
        err = errf.read().strip()
    return {"exit": os.waitstatus_to_exitcode(status), "wall_s": round(wall, 1),
            "peak_mib": round(usage.ru_maxrss / 1024.0),
            "last_line": err.splitlines()[-1][:300] if err else ""}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--patches", type=int, required=True)
    ap.add_argument("--per-loop", type=int, default=10)
    ap.add_argument("-o", "--output", required=True)
    ap.add_argument("--measure", type=float, default=None, metavar="S")
    a = ap.parse_args()
    Path(a.output).write_text(skin_toml(a.patches, a.per_loop), encoding="utf-8")
    if a.measure is None:
        return
    with tempfile.TemporaryDirectory() as d:
        log = str(Path(d) / "skin.parquet")
        out = {"patches": a.patches, "seconds": a.measure,
               "simulate": measure(["simulate", "--skin", a.output, "--scenario", "multi", "--duration",
                                    str(a.measure), "-o", log]),
               "observe": measure(["observe", log, "--skin", a.output, "-o", str(Path(d) / "o.parquet"),
                                   "--events", str(Path(d) / "e.csv")]),
               "run": measure(["run", "--skin", a.output, "--duration", str(a.measure), "--log",
                               str(Path(d) / "r.parquet")])}
    print(json.dumps(out))


if __name__ == "__main__":
    main()
