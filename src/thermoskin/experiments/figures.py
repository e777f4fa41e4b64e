"""The reproduced figures (Agg canvas, no pyplot state): Figs. 8 and 12-19 of the paper."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from thermoskin.experiments.scenarios import SETTLE_S

Result = Mapping[str, Any]
SHADE = {"color": "tab:purple", "alpha": 0.2, "lw": 0}
COLORS = ("tab:blue", "tab:orange", "tab:green")
DPI = 120


def _save(fig: Figure, path: Path) -> Path:
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=DPI)
    return path


def _shade_contacts(ax: Axes, res: Result, t0: float = 0.0, label: bool = True) -> None:
    for i, tc in enumerate(res["scenario"].touches):
        lab = "finger on (scripted)" if label and i == 0 else None
        ax.axvspan(tc.t_on - t0, tc.t_off - t0, **SHADE, label=lab)


def _smooth(y: np.ndarray, n: int = 50) -> np.ndarray:
    """Centred moving average over ``n`` points (0.5 s of the 100 Hz plot logs)."""
    k = np.ones(n) / n
    pad = np.concatenate([np.full(n // 2, y[0]), y, np.full(n - 1 - n // 2, y[-1])])
    return np.convolve(pad, k, mode="valid")


def _view(res: Result, t_from: float) -> tuple[np.ndarray, slice]:
    t = res["cols"]["t"]
    k = int(np.searchsorted(t, t_from))
    return t, slice(k, None)


def fig8(results: Sequence[Result], path: Path) -> Path:
    """Fig. 8: ``T_w`` tracking 24, 26, 28 °C from ambient; the tank ``T_p`` below."""
    fig = Figure(figsize=(9, 6.5), layout="constrained")
    ax, ax_p = fig.subplots(2, 1, sharex=True, height_ratios=(2, 1))
    for res, c in zip(results, COLORS, strict=False):
        cols, st = res["cols"], res["stats"]
        cmd = cols["T_w_cmd"][0]
        ax.plot(cols["t"], cols["T_w"], color=c, lw=0.8,
                label=f"$T_w$, command {cmd:g} °C (settles {st['settling_time_s']:.1f} s, "
                      f"error {st['steady_state_error_K']:.3f} K)")
        ax.axhline(cmd, color=c, ls="--", lw=1.0)
        ax_p.plot(cols["t"], cols["T_p"], color=c, lw=0.8, label=f"$T_p$ ({cmd:g} °C run)")
    ax.plot([], [], "k--", lw=1.0, label="$T_w^{cmd}$")
    ax.set_ylabel("temperature of water pipe $T_w$ (°C)")
    ax.set_title("Fig. 8 (reproduced): temperature control, commands 24, 26, 28 °C")
    ax.legend(loc="lower right", fontsize=8)
    ax.grid(alpha=0.3)
    # inset: the pump's chattering around the command
    ins = ax.inset_axes((0.42, 0.33, 0.3, 0.3))
    cols = results[0]["cols"]
    w = (cols["t"] >= 40.0) & (cols["t"] < 42.0)
    ins.plot(cols["t"][w], cols["T_w"][w], color=COLORS[0], lw=0.8)
    ins.axhline(cols["T_w_cmd"][0], color=COLORS[0], ls="--", lw=0.8)
    ins.set_title("chattering (pump on/off), 24 °C", fontsize=7)
    ins.tick_params(labelsize=6)
    ax_p.set_ylabel("Peltier/tank $T_p$ (°C)")
    ax_p.set_xlabel("time (s)")
    ax_p.legend(loc="lower right", fontsize=8, ncol=3)
    ax_p.grid(alpha=0.3)
    return _save(fig, path)


def fig_temperatures(res: Result, path: Path, number: int, n_fingers: int) -> Path:
    """Figs. 12-14: ``T_w`` and ``T_p`` during contacts every 3 s."""
    fig = Figure(figsize=(9, 4.5), layout="constrained")
    ax = fig.subplots()
    t, sl = _view(res, SETTLE_S - 5.0)
    cols = res["cols"]
    for key, c, name in (("T_w", "tab:blue", "$T_w$ (water pipe)"),
                         ("T_p", "tab:red", "$T_p$ (Peltier pump)")):
        ax.plot(t[sl], cols[key][sl], color=c, lw=0.5, alpha=0.35)
        ax.plot(t[sl], _smooth(cols[key])[sl], color=c, lw=1.6,
                label=f"{name}: 10 ms means (light), 0.5 s mean")
    ax.plot(t[sl], cols["T_w_cmd"][sl], "k--", lw=1.0, label="$T_w^{cmd}$")
    _shade_contacts(ax, res)
    ax.set_xlim(t[sl][0], t[-1])
    ax.set_xlabel("time (s)")
    ax.set_ylabel("temperature (°C)")
    word = {1: "one finger", 2: "two fingers", 3: "three fingers"}[n_fingers]
    ax.set_title(f"Fig. {number} (reproduced): temperature responses of {word} contact")
    ax.legend(loc="upper right", fontsize=8, ncol=2)
    ax.grid(alpha=0.3)
    return _save(fig, path)


def fig_heat_flow(res: Result, path: Path, number: int, n_fingers: int, q_max: float | None = None) -> Path:
    """Figs. 15-17: the paper's ``q_i_hat`` (top) and its change ``dq_i_hat`` (bottom)."""
    fig = Figure(figsize=(9, 6), layout="constrained")
    ax_q, ax_d = fig.subplots(2, 1, sharex=True)
    t, sl = _view(res, SETTLE_S - 5.0)
    cols, st = res["cols"], res["stats"]
    ax_q.plot(t[sl], cols["q_i_hat"][sl], color="tab:gray", lw=0.5, alpha=0.6,
              label=r"$\hat q_i$ (eq. 8 + $q_{ag}$ with $T_w$), 10 ms means")
    ax_q.plot(t[sl], _smooth(cols["q_i_hat"])[sl], color="k", lw=1.4, label="0.5 s mean")
    _shade_contacts(ax_q, res)
    ax_q.set_ylabel(r"estimated heat flow $\hat q_i$ (W)")
    ax_q.legend(loc="upper right", fontsize=8, ncol=3)
    ax_q.grid(alpha=0.3)
    base = st["baseline_dq_W"]
    ax_d.plot(t[sl], cols["dq_i_hat"][sl] - base, color="tab:blue", lw=0.8,
              label=r"$\Delta\hat q_i$: change from the no-touch baseline")
    ax_d.axhline(0.0, color="k", lw=0.6)
    _shade_contacts(ax_d, res, label=False)
    for on, off in res["events"]:
        ax_d.axvspan(on, off, ymin=0.93, ymax=1.0, color="tab:orange", alpha=0.8, lw=0)
    ax_d.axvspan(0, 0, color="tab:orange", label="detected contact")
    ax_d.set_ylabel(r"$\Delta\hat q_i$ (W)")
    ax_d.set_xlabel("time (s)")
    if q_max is not None:
        ax_d.set_ylim(-0.25 * q_max, 1.45 * q_max)
    ax_d.set_xlim(t[sl][0], t[-1])
    ax_d.legend(loc="upper left", bbox_to_anchor=(0.0, 0.92), fontsize=8, ncol=2)
    ax_d.text(0.99, 0.86, f"per contact (scripted windows): mean {1e3 * st['mean_dq_W']:.1f} mW, "
              f"peak {1e3 * st['peak_dq_W']:.1f} mW\ndetected {st['detected']}/{st['contacts']}, "
              f"false alarms {st['false_alarms']}", transform=ax_d.transAxes, ha="right", va="top",
              fontsize=8, bbox={"facecolor": "white", "alpha": 0.8, "lw": 0})
    ax_d.grid(alpha=0.3)
    word = {1: "one finger", 2: "two fingers", 3: "three fingers"}[n_fingers]
    ax_q.set_title(f"Fig. {number} (reproduced): estimated heat flow of {word} contact")
    return _save(fig, path)


def _aligned(ax: Axes, runs: Sequence[tuple[str, Result]], title: str) -> None:
    for (label, res), c in zip(runs, COLORS, strict=False):
        tau, mean, std = res["aligned"]
        st = res["stats"]
        ax.plot(tau, mean, color=c, lw=1.4,
                label=f"{label}: mean {1e3 * st['mean_dq_W']:.1f}, peak {1e3 * st['peak_dq_W']:.1f} mW")
        ax.fill_between(tau, mean - std, mean + std, color=c, alpha=0.15, lw=0)
    tc = runs[0][1]["scenario"].touches[0]
    ax.axvspan(0.0, tc.duration, **SHADE, label="finger on")
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_xlabel("time from contact onset (s)")
    ax.set_ylabel(r"$\Delta\hat q_i$ (W)")
    ax.set_title(title, fontsize=10)
    ax.legend(loc="upper right", fontsize=7)
    ax.grid(alpha=0.3)


def fig18(runs: Sequence[tuple[str, Result]], path: Path) -> Path:
    """Fig. 18: three persons, one finger: time traces and the contact-aligned mean."""
    fig = Figure(figsize=(11, 4.8), layout="constrained")
    ax_t, ax_a = fig.subplots(1, 2, width_ratios=(1.6, 1))
    for (label, res), c in zip(runs, COLORS, strict=False):
        t, sl = _view(res, SETTLE_S - 2.0)
        cols = res["cols"]
        end = int(np.searchsorted(t, SETTLE_S + 21.0))
        dq = cols["dq_i_hat"] - res["stats"]["baseline_dq_W"]
        ax_t.plot(t[sl.start:end], dq[sl.start:end], color=c, lw=0.8, label=label)
    for tc in runs[0][1]["scenario"].touches:
        if tc.t_on < SETTLE_S + 21.0:
            ax_t.axvspan(tc.t_on, tc.t_off, **SHADE)
    ax_t.axhline(0.0, color="k", lw=0.6)
    ax_t.set_xlabel("time (s)")
    ax_t.set_ylabel(r"estimated heat flow change $\Delta\hat q_i$ (W)")
    ax_t.set_title("one finger, a contact every 3 s (first 7 contacts)", fontsize=10)
    ax_t.legend(loc="upper left", fontsize=8)
    ax_t.grid(alpha=0.3)
    _aligned(ax_a, runs, "mean over 15 contacts (±1 s.d.)")
    fig.suptitle("Fig. 18 (reproduced): estimated heat flow of three persons")
    return _save(fig, path)


def fig19(closed: Sequence[tuple[str, Result]], stopped: Sequence[tuple[str, Result]],
          network: Result | None, path: Path) -> Path:
    """Fig. 19: positions near/middle/far: closed loop (pump chattering) and pump stopped in contact."""
    fig = Figure(figsize=(13, 4.8), layout="constrained")
    ax_c, ax_s, ax_b = fig.subplots(1, 3, width_ratios=(1, 1, 0.8))
    _aligned(ax_c, closed, "(a) closed loop as Figs. 12-18 (pump switching)")
    if network is not None:
        tau, mean, _ = network["aligned"]
        ax_c.plot(tau, mean, "k:", lw=1.2, label="two-node skin (reference)")
        ax_c.legend(loc="upper right", fontsize=7)
    _aligned(ax_s, stopped, "(b) pump stopped while the finger is on")
    top = max(r["stats"]["peak_dq_W"] for _, r in stopped)
    ax_s.set_ylim(-0.15 * top, 1.25 * top)
    ax_s.annotate("pump restarts: the model's\nlumped pipe is off for ~0.1 s\n(clipped)",
                  xy=(1.52, -0.12 * top), xytext=(1.9, -0.1 * top), fontsize=7,
                  arrowprops={"arrowstyle": "->", "lw": 0.6})
    labels = [lab for lab, _ in closed]
    x = np.arange(len(labels))
    for j, (runs, name, c) in enumerate(((closed, "closed loop", "tab:gray"),
                                         (stopped, "pump stopped in contact", "tab:red"))):
        mean = [r["stats"]["mean_dq_W"] for _, r in runs]
        err = [r["stats"]["mean_dq_sem_W"] or 0.0 for _, r in runs]
        ax_b.bar(x + (j - 0.5) * 0.38, mean, 0.38, yerr=err, color=c, alpha=0.8, label=name, capsize=3)
    ax_b.set_xticks(x, [f"{lab}\n(case {i + 1})" for i, lab in enumerate(labels)])
    ax_b.set_ylabel(r"mean $\Delta\hat q_i$ during contact (W)")
    ax_b.set_title("(c) per-contact mean (±s.e.)", fontsize=10)
    ax_b.legend(fontsize=7)
    ax_b.grid(alpha=0.3, axis="y")
    fig.suptitle("Fig. 19 (reproduced): estimated heat flow comparing finger positions "
                 "(near = at the thermocouple, far = 30 mm away)")
    return _save(fig, path)
