"""Draw docs/img/architecture.png: the package's layers (pyproject.toml's import-linter
contract, top to bottom), each package a box listing its modules, each arrow a package that
imports another (grimp's import graph, lazy imports included).

    python docs/architecture.py            # needs the test extra (import-linter brings grimp)
"""

from __future__ import annotations

import collections
import tomllib
from pathlib import Path

import grimp
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.patches import FancyBboxPatch

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "img" / "architecture.png"
BASICS = "params, paths, atomic, startup, _jit, _numba_cache, _blas"
NOTE = {"cli": "one module per command group", "estimation": "eq. 8, filter, detector, kernel, events",
        "touch": "what touched", "skin": "many patches", "fit": "calibrate, identify",
        "analysis": "offline pipeline, scoring", "runtime": "loop, safety, recording",
        "live": "Foxglove WebSocket, page", "sim": "the simulated skin and boards",
        "devices": "serial, emulator", "physics": "eqs. 1-7, Peltier, touchers",
        "logio": "CSV / Parquet, streamed", "control": "MPC, inner loop, pump", "sweep": "design sweeps",
        "plots": "figures", "experiments": "the paper's Sec. VI"}


def layers() -> list[list[str]]:
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]["contracts"]
    spec = next(c for c in cfg if c["type"] == "layers")["layers"]
    return [[m.strip().removeprefix("thermoskin.") for m in layer.split("|")] for layer in spec]


def main() -> None:
    g = grimp.build_graph("thermoskin")
    rows = [r for r in layers() if not r[0].startswith("__main__")]
    basics = {m.strip() for m in BASICS.split(",")}
    rows = [r for r in rows if not set(r) <= basics] + [["(root)"]]
    modules: dict[str, list[str]] = collections.defaultdict(list)
    for m in sorted(g.modules):
        parts = m.split(".")
        if len(parts) == 2 and parts[1] in basics | {"__main__"}:
            continue
        if len(parts) >= 3:
            modules[parts[1]].append(parts[2])
    edges: set[tuple[str, str]] = set()
    for m in g.modules:
        a = m.split(".")[1] if "." in m else "(root)"
        for n in g.find_modules_directly_imported_by(m):
            b = n.split(".")[1] if "." in n else "(root)"
            a2, b2 = ("(root)" if x in basics else x for x in (a, b))
            if a2 != b2 and a2 in modules and b2 in modules:
                edges.add((a2, b2))
    width, row_h, gap = 16.0, 1.05, 0.35
    fig, ax = plt.subplots(figsize=(width, len(rows) * (row_h + gap) * 0.78 + 0.6))
    ax.set_xlim(0, width)
    ax.set_ylim(-0.2, len(rows) * (row_h + gap) + 0.2)
    ax.axis("off")
    box: dict[str, tuple[float, float, float, float]] = {}
    for i, row in enumerate(rows):
        y = (len(rows) - 1 - i) * (row_h + gap) + 0.1
        w = (width - 0.4 - 0.25 * (len(row) - 1)) / len(row)
        for j, name in enumerate(row):
            x = 0.2 + j * (w + 0.25)
            box[name] = (x, y, w, row_h)
            fc = "#eef3fb" if name != "(root)" else "#f4f4f4"
            ax.add_patch(FancyBboxPatch((x, y), w, row_h, boxstyle="round,pad=0.02,rounding_size=0.08",
                                        fc=fc, ec="#4a6fa5", lw=1.2))
            title = name if name != "(root)" else "the root: shared basics"
            ax.text(x + 0.12, y + row_h - 0.12, title, fontsize=11, fontweight="bold", va="top")
            if name in NOTE:
                ax.text(x + w - 0.1, y + row_h - 0.14, NOTE[name], fontsize=7.5, va="top", ha="right",
                        color="#555555", style="italic")
            mods = modules.get(name, []) if name != "(root)" else sorted(basics)
            mods = [m for m in mods if m not in ("__init__", "__main__")]
            per_line = max(1, int(w / 0.95))
            lines = [", ".join(mods[k:k + per_line]) for k in range(0, len(mods), per_line)]
            ax.text(x + 0.12, y + row_h - 0.42, "\n".join(lines), fontsize=7.2, va="top", family="monospace",
                    linespacing=1.25)
    for name, (x, y, _w, _h) in box.items():  # what each package uses, below its modules
        uses = [b for row in rows for b in row if (name, b) in edges]
        if uses:
            ax.text(x + 0.12, y + 0.1, "uses " + ", ".join(uses), fontsize=7.5, va="bottom", color="#a03c36")
    ax.text(width - 0.2, len(rows) * (row_h + gap) + 0.05,
            f"thermoskin: {len(rows)} layers, top to bottom, each package with its modules and the packages "
            f"it uses (all below it: import-linter, tests/test_architecture.py)",
            fontsize=8.5, ha="right", va="bottom", color="#333333")
    fig.tight_layout()
    OUT.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(OUT, dpi=110)
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
