"""Key numbers of the reproduced experiments: set-point tracking and heat flow per contact.

Heat flow per contact (``dq``: the change of the estimated heat flow from its no-touch
baseline). The observer's ``dq_i_hat`` is already the estimate minus what eq. 8 gives with
no touch for the measured temperatures; its *no-touch baseline* is taken here as its mean
over the last :data:`BASELINE_S` s before the first contact (near zero). Each contact is
characterised on its scripted window (the truth: onset ``t_on``, release ``t_off``):

- ``mean_dq``: mean of ``dq_i_hat - baseline`` over ``[t_on, t_off)``;
- ``peak_dq``: max of ``dq_i_hat - baseline`` over ``[t_on, t_on + PERIOD_S)`` (the estimate
  lags the touch, so its peak comes at or just after the release);
- ``rise``: that peak minus the value at the onset (what the contact adds to what the
  previous ones left: with a contact every 3 s the estimate does not return to its
  baseline in between).

The detector's own events (``ContactEvent.mean_dq``/``peak_dq``, on ``dq_i_hat`` minus the
detector's baseline, over the *detected* span) are kept alongside.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from thermoskin.analysis.evaluation import match_events
from thermoskin.estimation.events import ContactEvent
from thermoskin.experiments.scenarios import PERIOD_S
from thermoskin.physics.finger import Touch

Array = NDArray[np.float64]

BASELINE_S = 3.0
"""Length of the no-touch window before the first contact, s."""
SETTLE_BAND_K = 0.1
"""Settling band around the command, K."""
SMOOTH_S = 1.0
"""Moving-average window of ``T_w`` for the settling time, s (averages out the pump's chatter)."""
STEADY_S = 20.0
"""The last seconds of a set-point run over which the steady-state error is taken."""
ALIGN = (-0.5, PERIOD_S)
"""Window of the contact-aligned mean response, s from the onset."""


@dataclass
class ContactStats:
    """Heat flow per contact (W) from the scripted windows, and the detector's view."""

    baseline: float
    q_i_hat_baseline: float
    mean_dq: list[float]
    peak_dq: list[float]
    rise: list[float]
    q_i_true: list[float]
    detected: int
    false_alarms: int
    event_mean_dq: list[float] = field(default_factory=list)
    event_peak_dq: list[float] = field(default_factory=list)

    def summary(self) -> dict[str, Any]:
        """Means over the contacts (the summary.json entry)."""

        def m(x: Sequence[float]) -> float | None:
            return float(np.mean(x)) if len(x) else None

        def sem(x: Sequence[float]) -> float | None:
            return float(np.std(x, ddof=1) / np.sqrt(len(x))) if len(x) > 1 else None

        return {
            "mean_dq_W": m(self.mean_dq), "peak_dq_W": m(self.peak_dq),
            "mean_dq_sem_W": sem(self.mean_dq), "peak_dq_sem_W": sem(self.peak_dq),
            "rise_dq_W": m(self.rise), "true_q_i_W": m(self.q_i_true),
            "baseline_dq_W": self.baseline, "baseline_q_i_hat_W": self.q_i_hat_baseline,
            "contacts": len(self.mean_dq), "detected": self.detected, "false_alarms": self.false_alarms,
            "detector_mean_dq_W": m(self.event_mean_dq), "detector_peak_dq_W": m(self.event_peak_dq),
        }

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def _window(t: Array, a: float, b: float) -> slice:
    return slice(int(np.searchsorted(t, a)), int(np.searchsorted(t, b)))


def contact_stats(cols: Mapping[str, Array], touches: Sequence[Touch],
                  events: Sequence[ContactEvent] = ()) -> ContactStats:
    """:class:`ContactStats` of a run with scripted ``touches`` (see the module docstring)."""
    t, dq = np.asarray(cols["t"]), np.asarray(cols["dq_i_hat"])
    if not touches:
        raise ValueError("contact_stats needs at least one touch")
    first = touches[0].t_on
    pre = _window(t, first - BASELINE_S, first)
    base = float(np.nanmean(dq[pre]))
    q_base = float(np.nanmean(np.asarray(cols["q_i_hat"])[pre]))
    q_true = np.asarray(cols["q_i"]) if "q_i" in cols else None
    means, peaks, rises, qs = [], [], [], []
    for tc in touches:
        w = _window(t, tc.t_on, tc.t_off)
        after = _window(t, tc.t_on, tc.t_on + PERIOD_S)
        seg = dq[after] - base
        means.append(float(np.nanmean(dq[w]) - base))
        peaks.append(float(np.nanmax(seg)))
        rises.append(float(np.nanmax(seg) - seg[0]))
        if q_true is not None:
            qs.append(float(np.mean(q_true[w])))
    m = match_events(touches, events)
    matched = [e for e in events if e not in m.spurious]
    return ContactStats(baseline=base, q_i_hat_baseline=q_base, mean_dq=means, peak_dq=peaks, rise=rises,
                        q_i_true=qs, detected=m.hits, false_alarms=m.false_alarms,
                        event_mean_dq=[e.mean_dq for e in matched],
                        event_peak_dq=[e.peak_dq for e in matched])


def aligned_response(cols: Mapping[str, Array], touches: Sequence[Touch], key: str = "dq_i_hat",
                     window: tuple[float, float] = ALIGN, step: float = 0.01,
                     baseline: float = 0.0) -> tuple[Array, Array, Array]:
    """Contact-aligned response: ``(tau, mean, std)`` of ``cols[key] - baseline`` at ``t_on + tau``."""
    t, y = np.asarray(cols["t"]), np.asarray(cols[key]) - baseline
    tau = np.arange(window[0], window[1], step)
    rows = [np.interp(tc.t_on + tau, t, y) for tc in touches if tc.t_on + window[0] >= t[0]]
    a = np.asarray(rows)
    return tau, a.mean(axis=0), a.std(axis=0)


def setpoint_stats(cols: Mapping[str, Array], t_s: float) -> dict[str, float]:
    """Steady-state error and settling time of ``T_w`` (measured) to its (constant) command.

    ``steady_state_error_K``: ``|mean(T_w - T_w_cmd)|`` over the last :data:`STEADY_S` s;
    ``mean_abs_error_K`` over the same window; ``settling_time_s``: the first time after
    which the :data:`SMOOTH_S` s moving average of ``T_w`` stays within
    :data:`SETTLE_BAND_K` of the command (NaN if it never does).
    """
    t, T_w, cmd = (np.asarray(cols[k]) for k in ("t", "T_w", "T_w_cmd"))
    last = t >= t[-1] - STEADY_S
    e = T_w[last] - cmd[last]
    n = max(1, round(SMOOTH_S / t_s))
    avg = np.convolve(T_w, np.ones(n) / n, mode="valid")  # avg[j] = mean(T_w[j:j+n]), ends at j+n-1
    t_avg = t[n - 1:]
    outside = np.flatnonzero(np.abs(avg - cmd[n - 1:]) > SETTLE_BAND_K)
    if outside.size == 0:
        settle = float(t_avg[0])
    elif outside[-1] + 1 < t_avg.size:
        settle = float(t_avg[outside[-1] + 1])
    else:
        settle = float("nan")
    T_p_cmd = np.asarray(cols["T_p_cmd"]) if "T_p_cmd" in cols else np.full(1, np.nan)
    v = np.asarray(cols["v"])
    return {"steady_state_error_K": float(abs(np.mean(e))), "mean_abs_error_K": float(np.mean(np.abs(e))),
            "settling_time_s": settle, "T_w_std_K": float(np.std(e)),
            "pump_on_fraction": float(np.mean(v[last] > 0)),
            "T_p_cmd_max_degC": float(np.nanmax(T_p_cmd))}
