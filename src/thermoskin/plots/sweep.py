"""Pictures of a sweep's results: metric against parameters (``thermoskin sweep-plot``).

- two keys taking a few values each (a grid): one heat map per metric, the mean over seeds
  in each cell;
- one key: the metric against it (each seed a dot, the mean a line);
- otherwise: parallel coordinates, one panel per metric: an axis per key (scaled to its
  range) and the metric last, each point a line coloured by the metric.

A metric with no value in any point (a latency where no touch was detected, an SNR of a
sweep with no touch) gets a panel that says so and why, and :func:`plot_results` returns
that line for the command line to print.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from thermoskin.paths import shown
from thermoskin.sweep.engine import EXTRA, METRICS
from thermoskin.sweep.spec import SweepError

LABELS = {"detection_rate": "detection rate", "false_alarms_per_h": "false alarms / h",
          "latency_median_s": "latency median, s", "latency_p90_s": "latency p90, s",
          "snr_one_finger": "SNR, one finger", "tracking_rms_K": "tracking RMS, K",
          "energy_J": "Peltier energy, J"}


def read_results(path: Path) -> dict[str, np.ndarray]:
    """The columns of ``RESULTS.parquet`` (one-line ``SweepError`` if it is not one)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    if not Path(path).is_file():
        raise SweepError(f"results file {path} does not exist")
    from thermoskin.atomic import arrow_target

    try:
        with arrow_target(path) as src:
            t = pq.read_table(src)
    except (pa.ArrowInvalid, OSError) as e:
        raise SweepError(f"{path} is not a Parquet file: {' '.join(str(e).split())}") from None
    if "hash" not in t.column_names or "point" not in t.column_names:
        raise SweepError(f"{path} is not a sweep's results (no point and hash columns)")
    return {c: np.asarray(t.column(c).to_pylist(), dtype=object) for c in t.column_names}


#: Why a metric can have no value in a point (it is NaN there).
WHY_EMPTY = {"detection_rate": "no touch in the scenario",
             "latency_median_s": "no touch detected", "latency_p90_s": "no touch detected",
             "snr_one_finger": "no touch in the scenario to measure it on",
             "false_alarms_per_h": "no time observed", "tracking_rms_K": "no time observed",
             "energy_J": "no time observed"}


def plot_results(path: Path, out: Path, metrics: list[str] | None = None, dpi: int = 110) -> list[str]:
    """Draw ``path``'s metrics against its keys into ``out`` (module doc); one line for each
    metric with no value in any point (its panel says the same)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cols = read_results(path)
    keys = [c for c in cols if c not in ("point", "hash", "seed", *METRICS, *EXTRA)]
    have = [m for m in METRICS if m in cols]
    if metrics:
        for m in metrics:
            if m not in have:
                raise SweepError(f"--metric {m}: not in {path} (it has {', '.join(have)})")
        have = list(metrics)
    if not keys:
        raise SweepError(f"{path}: no swept key to plot against")
    if not len(cols["point"]):
        raise SweepError(f"{path}: no rows")
    num = {k: _numeric(cols[k]) for k in keys}
    Y = {m: np.asarray(cols[m], dtype=float) for m in have}
    n = len(have)
    ncol = 2 if n == 4 else min(n, 3)
    nrow = -(-n // ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.6 * ncol, 3.6 * nrow), squeeze=False)
    grid2 = len(keys) == 2 and all(len(np.unique(num[k])) <= 12 for k in keys)
    empty: list[str] = []
    for i, m in enumerate(have):
        ax = axes[i // ncol][i % ncol]
        y = Y[m]
        if not np.isfinite(y).any():
            why = (f"{LABELS.get(m, m)}: no value in any of the {len(y)} points "
                   f"({WHY_EMPTY.get(m, 'not measured')})")
            empty.append(why)
            ax.text(0.5, 0.5, why.replace(": ", ":\n", 1).replace(" (", "\n("), ha="center", va="center",
                    fontsize=9, transform=ax.transAxes, wrap=True)
            ax.set_title(LABELS.get(m, m), fontsize=9)
            ax.set_xticks([])
            ax.set_yticks([])
        elif grid2:
            _heat(fig, ax, num[keys[0]], num[keys[1]], y, keys, LABELS.get(m, m))
        elif len(keys) == 1:
            x = num[keys[0]]
            ax.plot(x, y, ".", alpha=0.4)
            ux = np.unique(x)
            means = [np.nanmean(y[x == u]) if np.any(np.isfinite(y[x == u])) else np.nan for u in ux]
            ax.plot(ux, means, "-")
            ax.set_xlabel(keys[0])
            ax.set_ylabel(LABELS.get(m, m))
        else:
            _parallel(fig, ax, [num[k] for k in keys], keys, y, LABELS.get(m, m))
    for j in range(n, nrow * ncol):
        axes[j // ncol][j % ncol].axis("off")
    fig.suptitle(shown(f"{Path(path).name}: {len(cols['point'])} points"))
    fig.tight_layout()
    fig.savefig(out, dpi=dpi)
    plt.close(fig)
    return empty


def _numeric(x: np.ndarray) -> np.ndarray:
    try:
        return np.asarray(x, dtype=float)
    except (TypeError, ValueError):  # words (e.g. control.cost): their order of appearance
        names = list(dict.fromkeys(x.tolist()))
        return np.asarray([names.index(v) for v in x], dtype=float)


def _heat(fig, ax, x, y, z, keys, label) -> None:  # type: ignore[no-untyped-def]
    ux, uy = np.unique(x), np.unique(y)
    Z = np.full((len(uy), len(ux)), np.nan)
    for a, xv in enumerate(ux):
        for b, yv in enumerate(uy):
            sel = (x == xv) & (y == yv) & np.isfinite(z)
            if sel.any():
                Z[b, a] = z[sel].mean()
    im = ax.imshow(Z, origin="lower", aspect="auto", cmap="viridis")
    ax.set_xticks(range(len(ux)), [f"{v:.3g}" for v in ux], fontsize=7)
    ax.set_yticks(range(len(uy)), [f"{v:.3g}" for v in uy], fontsize=7)
    ax.set_xlabel(keys[0])
    ax.set_ylabel(keys[1])
    ax.set_title(label, fontsize=9)
    fig.colorbar(im, ax=ax)


def _parallel(fig, ax, xs, keys, z, label) -> None:  # type: ignore[no-untyped-def]
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection

    cols = [*xs, z]
    names = [*keys, label]
    scaled = []
    for c in cols:
        fin = np.any(np.isfinite(c))
        lo, hi = (np.nanmin(c), np.nanmax(c)) if fin else (0.0, 1.0)
        scaled.append((c - lo) / (hi - lo) if hi > lo else np.full(len(c), 0.5))
    S = np.column_stack(scaled)
    ok = np.all(np.isfinite(S), axis=1)
    order = np.argsort(z[ok], kind="stable")  # the highest values drawn last, on top
    segs = [np.column_stack([np.arange(S.shape[1]), s]) for s in S[ok][order]]
    zz = z[ok][order]
    lc = LineCollection(segs, array=zz, cmap="viridis", linewidths=0.6, alpha=0.5)
    ax.add_collection(lc)
    ax.set_xlim(-0.1, S.shape[1] - 0.9)
    ax.set_ylim(-0.05, 1.05)
    ax.set_xticks(range(len(names)), names, rotation=30, ha="right", fontsize=7)
    ax.set_yticks([])
    for j, c in enumerate(cols):
        if np.any(np.isfinite(c)):
            ax.text(j, -0.04, f"{np.nanmin(c):.3g}", ha="center", va="top", fontsize=6)
            ax.text(j, 1.04, f"{np.nanmax(c):.3g}", ha="center", va="bottom", fontsize=6)
    ax.set_title(label, fontsize=9)
    fig.colorbar(lc, ax=ax)
    plt.setp(ax.spines.values(), visible=False)
