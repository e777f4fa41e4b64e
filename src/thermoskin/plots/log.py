"""Plots of a run: temperatures and estimated heat flow, with detected and true contacts.

Drawn with matplotlib's object API on an Agg canvas (``matplotlib.figure.Figure``): no
display, no pyplot global state, safe to call from scripts, tests and threads.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from thermoskin.atomic import atomic_path
from thermoskin.paths import shown

Array = NDArray[np.float64]

#: At most about this many points are drawn per line (min/max decimation above it).
MAX_POINTS = 20_000

_TEMPS = (
    ("T_w", "T_w (pipe)", "tab:blue", "-"),
    ("T_p", "T_p (Peltier/tank)", "tab:red", "-"),
    ("T_g", "true T_g (sheet)", "tab:green", "-"),
    ("T_w_cmd", "T_w command", "black", "--"),
    ("T_a", "T_a (air)", "tab:gray", ":"),
)
_DETECTED = {"color": "tab:orange", "alpha": 0.18, "lw": 0}
_TRUE = {"color": "tab:purple", "alpha": 0.7, "lw": 0}


def decimate(t: ArrayLike, y: ArrayLike, max_points: int = MAX_POINTS) -> tuple[Array, Array]:
    """Min/max decimation to at most about ``max_points`` points (NaN gaps are kept)."""
    tt = np.asarray(t, dtype=np.float64)
    yy = np.asarray(y, dtype=np.float64)
    n = yy.size
    if n <= max_points:
        return tt, yy
    b = math.ceil(n / max(max_points // 2, 1))  # samples per bucket, two points per bucket
    nb = math.ceil(n / b)
    pad = nb * b - n
    lo = np.concatenate([np.where(np.isnan(yy), np.inf, yy), np.full(pad, np.inf)]).reshape(nb, b)
    hi = np.concatenate([np.where(np.isnan(yy), -np.inf, yy), np.full(pad, -np.inf)]).reshape(nb, b)
    base = np.arange(nb) * b
    i_min = np.minimum(base + np.argmin(lo, axis=1), n - 1)
    i_max = np.minimum(base + np.argmax(hi, axis=1), n - 1)
    idx = np.sort(np.stack([i_min, i_max], axis=1), axis=1).ravel()
    return tt[idx], yy[idx]


def _runs(flag: ArrayLike) -> list[tuple[int, int]]:
    """Index ranges ``[start, stop)`` where ``flag > 0.5``."""
    f = np.nan_to_num(np.asarray(flag, dtype=np.float64)) > 0.5
    d = np.diff(np.concatenate([[0], f.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(), strict=True))


def _event_span(ev: Any, t_end: float) -> tuple[float, float] | None:
    """``(onset, release)`` of an event object (or mapping); open release -> end of the run."""

    def get(name: str) -> Any:
        return ev.get(name) if isinstance(ev, Mapping) else getattr(ev, name, None)

    onset, release = get("onset"), get("release")
    if onset is None or not np.isfinite(onset):
        return None
    if release is None or not np.isfinite(release):
        release = t_end
    return float(onset), float(release)


def _moving_mean(t: Array, y: Array, window: float) -> Array:
    """Trailing mean over ``window`` seconds (NaN samples left out)."""
    if t.size < 2:
        return y.copy()
    n = max(1, round(window / float(np.median(np.diff(t)))))
    ok = np.isfinite(y)
    c = np.concatenate([[0.0], np.cumsum(np.where(ok, y, 0.0))])
    k = np.concatenate([[0], np.cumsum(ok)])
    idx = np.arange(1, y.size + 1)
    lo = np.maximum(idx - n, 0)
    cnt = k[idx] - k[lo]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(cnt > 0, (c[idx] - c[lo]) / np.maximum(cnt, 1), np.nan)


def plot_run(
    columns: Mapping[str, ArrayLike],
    events: Sequence[Any],
    path: str | os.PathLike[str],
    title: str = "",
    max_points: int = MAX_POINTS,
) -> Path:
    """Write a plot of a run (PNG; PDF or SVG by ``path``'s extension): temperatures, heat
    flow, and (if present) truth and control.

    Panels: ``T_w`` and, if present, ``T_p``, ``T_g`` (true), ``T_w_cmd``, ``T_a`` (°C);
    ``q_i_hat`` (W, raw and a 0.1 s mean) with, on a twin axis, its change from the
    no-touch baseline ``dq_i_hat``; the simulator's true ``q_i`` if present; ``T_p_cmd``,
    the Peltier drive and the pump if present. The trailing means are computed here, or
    taken from ``q_i_hat_mean`` and ``v_mean`` if given (a long run's digest,
    :class:`thermoskin.plots.digest.PlotDigest`). Detected
    contacts (``events``: objects or mappings with ``onset``/``release`` in s) are shaded
    in both panels; true contacts (``contact_true``) are a thin band at the top of each
    panel. Returns the path.
    """
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    if "t" not in columns:
        raise ValueError("plot_run: the columns need a time column 't'")
    t = np.asarray(columns["t"], dtype=np.float64)
    cols = {k: np.asarray(v, dtype=np.float64) for k, v in columns.items()}
    for k, v in cols.items():
        if v.shape != t.shape:
            raise ValueError(f"plot_run: column {k!r} has shape {v.shape}, 't' has {t.shape}")
    t_end = float(t[-1]) if t.size else 0.0

    has_truth = "q_i" in cols
    has_ctrl = "T_p_cmd" in cols or "drive" in cols
    heights = [3, 3] + ([1.4] if has_truth else []) + ([1.6] if has_ctrl else [])
    fig = Figure(figsize=(11, 3.2 + 1.6 * len(heights)), dpi=110, layout="constrained")
    axes = list(fig.subplots(len(heights), 1, sharex=True, height_ratios=heights))
    ax_t, ax_q = axes[0], axes[1]
    ax_i = axes[2] if has_truth else None
    ax_c = axes[-1] if has_ctrl else None

    def line(
        ax: Any, name: str, label: str, color: str, style: str = "-", lw: float = 1.0, alpha: float = 1.0,
        y: Array | None = None,
    ) -> Any:
        tx, yx = decimate(t, cols[name] if y is None else y, max_points)
        return ax.plot(tx, yx, style, color=color, lw=lw, alpha=alpha, label=label)[0]

    # top: temperatures
    handles_t = [line(ax_t, k, lab, c, s) for k, lab, c, s in _TEMPS if k in cols]
    ax_t.set_ylabel("temperature (°C)")
    if not handles_t:
        ax_t.text(0.5, 0.5, "no temperature columns", ha="center", va="center", transform=ax_t.transAxes)

    # heat flow: the paper's estimate (raw and a 0.1 s mean) and its change from no touch
    handles_q = []
    if "q_i_hat" in cols:
        handles_q.append(line(ax_q, "q_i_hat", "q_i_hat (eq. 8, left)", "tab:blue", lw=0.6, alpha=0.35))
        mean = cols["q_i_hat_mean"] if "q_i_hat_mean" in cols else _moving_mean(t, cols["q_i_hat"], 0.1)
        handles_q.append(line(ax_q, "q_i_hat", "q_i_hat, 0.1 s mean", "tab:blue", lw=1.0, y=mean))
    ax_q.set_ylabel("q_i_hat (W)")
    if "dq_i_hat" in cols:
        ax_r = ax_q.twinx() if "q_i_hat" in cols else ax_q
        handles_q.append(line(ax_r, "dq_i_hat", "dq_i_hat (change from no-touch, right)", "tab:red",
                              lw=1.0))
        ax_r.set_ylabel("dq_i_hat (W)")
    if not handles_q:
        ax_q.text(0.5, 0.5, "no heat-flow columns", ha="center", va="center", transform=ax_q.transAxes)
    handles_i: list[Any] = []
    if ax_i is not None:
        handles_i.append(line(ax_i, "q_i", "true q_i (simulator)", "black", lw=1.2))
        ax_i.set_ylabel("true q_i (W)")
    handles_c: list[Any] = []
    if ax_c is not None:
        if "T_p_cmd" in cols:
            handles_c.append(line(ax_c, "T_p_cmd", "T_p_cmd (MPC, left)", "tab:purple", lw=1.0))
            ax_c.set_ylabel("T_p_cmd (°C)")
        if "drive" in cols:
            ax_d = ax_c.twinx()
            handles_c.append(line(ax_d, "drive", "Peltier drive (right)", "tab:green", lw=0.8, alpha=0.8))
            if "v" in cols:
                v = cols["v"]
                vmax = float(np.nanmax(v)) if np.any(v > 0) else 1.0
                duty = cols["v_mean"] / vmax if "v_mean" in cols else _moving_mean(t, v / vmax, 1.0)
                handles_c.append(line(ax_d, "v", "pump duty, 1 s mean (right)", "tab:gray", lw=1.0, y=duty))
            ax_d.set_ylabel("drive, pump")
    panels = [(ax_t, handles_t), (ax_q, handles_q)]
    if ax_i is not None:
        panels.append((ax_i, handles_i))
    if ax_c is not None:
        panels.append((ax_c, handles_c))

    # contacts
    spans = [s for s in (_event_span(ev, t_end) for ev in events) if s is not None]
    true_runs = _runs(cols["contact_true"]) if "contact_true" in cols else []
    for ax, _ in panels:
        for a, b in spans:
            ax.axvspan(a, b, **_DETECTED)
        for i0, i1 in true_runs:
            ax.axvspan(t[i0], t[min(i1, t.size - 1)], ymin=0.965, ymax=1.0, **_TRUE)
    extra = []
    if spans:
        extra.append(Patch(label=f"detected contact ({len(spans)})", **_DETECTED))
    if "contact_true" in cols:
        extra.append(Patch(label=f"true contact ({len(true_runs)})", **_TRUE))

    for i, (ax, hs0) in enumerate(panels):
        hs = hs0 + (extra if i < 2 else [])
        if hs:  # one row above the panel: never hides data
            ax.legend(
                handles=hs,
                loc="lower left",
                bbox_to_anchor=(0.0, 1.0),
                ncols=min(len(hs), 4),
                fontsize=8,
                frameon=False,
                borderaxespad=0.2,
            )
    for ax, _ in panels:
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("time (s)")
    if t.size:
        axes[-1].set_xlim(float(t[0]), t_end)
    fig.suptitle(shown(title or "thermoskin run"))

    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(out) as tmp:  # whole or not at all
        fig.savefig(tmp, format=out.suffix[1:].lower() if out.suffix.lower() in FORMATS else "png")
    return out


#: File formats :func:`plot_run` writes, by extension (anything else is written as PNG).
FORMATS = (".png", ".pdf", ".svg")


def contact_spans(t: ArrayLike, contact: ArrayLike) -> list[dict[str, float]]:
    """``{"onset", "release"}`` (s) of each run of ``contact > 0.5`` (a log's ``contact``
    column: from the detection to the release); a run still open at the end has no release."""
    tt = np.asarray(t, dtype=np.float64)
    out = []
    for i0, i1 in _runs(contact):
        out.append({"onset": float(tt[i0]), "release": float(tt[i1]) if i1 < tt.size else math.nan})
    return out


def plot_log(columns: Mapping[str, ArrayLike], path: str | os.PathLike[str], title: str = "") -> Path:
    """:func:`plot_run` of a log's own columns, contacts from its ``contact`` column (as
    ``thermoskin run`` draws its plot at the end, and ``thermoskin plot LOG`` afterwards)."""
    spans = contact_spans(columns["t"], columns["contact"]) if "contact" in columns else []
    return plot_run(columns, spans, path, title=title)
