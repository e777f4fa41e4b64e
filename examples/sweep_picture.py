"""Make docs/img/sweep.png: run examples/sweep.toml (resuming into sweep.parquet) and plot it.

    python examples/sweep_picture.py [--results sweep.parquet]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from thermoskin.plots.sweep import plot_results  # noqa: E402
from thermoskin.sweep.run import run_sweep  # noqa: E402
from thermoskin.sweep.spec import load_sweep  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--results", type=Path, default=Path("sweep.parquet"))
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "img" / "sweep.png")
    a = ap.parse_args()
    res = run_sweep(load_sweep(ROOT / "examples" / "sweep.toml"), a.results)
    print(f"{res.rows} points ({res.ran} run now in {res.wall_s:.1f} s)")
    plot_results(a.results, a.out, ["latency_median_s", "snr_one_finger", "tracking_rms_K", "energy_J"],
                 dpi=72)
    print(f"written {a.out}")


if __name__ == "__main__":
    main()
