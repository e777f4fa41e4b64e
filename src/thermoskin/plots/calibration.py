"""The picture of a calibration (``thermoskin calibrate``'s PNG): the measured and fitted
``T_w``, a two-second close-up with the pump's state, and the residuals."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from thermoskin.atomic import atomic_path
from thermoskin.paths import shown
from thermoskin.plots.log import decimate

if TYPE_CHECKING:
    from thermoskin.fit.calibrate import Calibration


def plot_fit(cal: Calibration, path: str | Path, title: str = "") -> Path:
    """PNG: measured and fitted ``T_w``, a two-second close-up, and the residuals."""
    from matplotlib.figure import Figure

    b = cal.blocks
    t = b.t_mid
    what = " (block means)" if b.m > 1 else ""
    fig = Figure(figsize=(11, 8), dpi=110, layout="constrained")
    ax_t, ax_z, ax_r = fig.subplots(3, 1, height_ratios=[3, 2.2, 2])
    # stretches as separate lines (no line across a gap)
    breaks = np.flatnonzero(b.start)[1:]
    for k, (seg_t, seg_m, seg_f) in enumerate(zip(np.split(t, breaks), np.split(b.Tw, breaks),
                                                  np.split(cal.fitted, breaks), strict=True)):
        ax_t.plot(*decimate(seg_t, seg_m), color="tab:blue", lw=0.6, alpha=0.6,
                  label=f"measured T_w{what}" if k == 0 else None)
        ax_t.plot(*decimate(seg_t, seg_f), color="tab:orange", lw=0.9,
                  label="network, fitted" if k == 0 else None)
    gaps = [(t[i - 1], t[i]) for i in breaks]
    for a, c in gaps:
        for ax in (ax_t, ax_r):
            ax.axvspan(a, c, color="tab:gray", alpha=0.15, lw=0)
    ax_t.set_ylabel("T_w (°C)")
    ax_t.legend(loc="lower left", bbox_to_anchor=(0.0, 1.0), ncols=3, fontsize=8, frameon=False)
    # close-up: two seconds in the middle of the longest stretch
    counts = np.bincount(b.stretch)
    sel = np.flatnonzero(b.stretch == int(np.argmax(counts)))
    mid = t[sel[sel.size // 2]]
    z = sel[(t[sel] >= mid - 1.0) & (t[sel] <= mid + 1.0)]
    ax_z.plot(t[z], b.Tw[z], ".", ms=3, color="tab:blue", label=f"measured{what}")
    ax_z.plot(t[z], cal.fitted[z], "-", lw=1.0, color="tab:orange", label="fitted")
    on = b.v_modes[b.mode[z]] > 0
    ax_z2 = ax_z.twinx()
    ax_z2.step(t[z], on.astype(float), where="mid", color="tab:gray", lw=0.8, alpha=0.7, label="pump on")
    ax_z2.set_ylim(-0.1, 4.0)
    ax_z2.set_yticks([])
    ax_z.set_ylabel("T_w (°C), close-up")
    handles = ax_z.get_legend_handles_labels()[0] + ax_z2.get_legend_handles_labels()[0]
    ax_z.legend(handles=handles, loc="lower left", bbox_to_anchor=(0.0, 1.0), ncols=3, fontsize=8,
                frameon=False)
    r = cal.residuals * 1e3
    hs = ax_r.plot(*decimate(t, r), color="tab:blue", lw=0.4, alpha=0.5, label=f"residual{what} (left)")
    n1 = max(1, round(1.0 / cal.t_fit))
    if r.size > n1:  # the slow part, where a model error would show, on its own scale
        ax_m = ax_r.twinx()
        hs += ax_m.plot(t[n1 - 1:], np.convolve(r, np.ones(n1) / n1, mode="valid"), color="black",
                        lw=1.0, label="1 s mean (right)")
        ax_m.set_ylabel("1 s mean (mK)")
    ax_r.axhline(0.0, color="black", lw=0.5)
    ax_r.set_ylabel("measured − fitted (mK)")
    ax_r.set_xlabel("time (s)")
    ax_r.legend(handles=hs, loc="lower left", bbox_to_anchor=(0.0, 1.0), ncols=2, fontsize=8,
                frameon=False)
    for ax in (ax_t, ax_z, ax_r):
        ax.grid(True, alpha=0.3)
    ax_r.set_xlim(ax_t.get_xlim())
    fig.suptitle(shown(title or f"thermoskin calibrate: residual rms {cal.rms * 1e3:.2f} mK"))
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(out) as tmp:
        fig.savefig(tmp, format="png")
    return out
