"""Scoring detected contacts against scripted touches: hits, misses, false alarms, latency."""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from thermoskin.events import ContactEvent
from thermoskin.physics.finger import Touch


@dataclass
class Match:
    """Result of :func:`match_events`. Latency is ``detected_at - t_on`` (s)."""

    hits: int
    misses: int
    false_alarms: int
    latencies: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    missed: list[Touch] = field(default_factory=list)
    spurious: list[ContactEvent] = field(default_factory=list)
    not_scored: int = 0
    """Touches left out because the run ended (``t_end``) before they could be told."""
    pairs: list[int | None] = field(default_factory=list)
    """Per touch (in order), the index of its event in ``events``; None if it has none."""


def match_events(touches: Sequence[Touch], events: Sequence[ContactEvent],
                 late: float = 1.0, t_end: float = math.inf) -> Match:
    """Pair each touch with the first event detected in ``[t_on, t_on + duration + late]``.

    Every other event (detected outside a touch's window, or a second event in the same
    window) is a false alarm. A run that ended at ``t_end`` (stopped early) scores only
    what it could see: a touch scripted from ``t_end`` on, or one whose window was cut
    by ``t_end`` with no detection in it yet, is neither a hit nor a miss (``not_scored``).
    """
    used: set[int] = set()
    lat: list[float] = []
    missed: list[Touch] = []
    pairs: list[int | None] = []
    not_scored = 0
    for tc in touches:
        if tc.t_on >= t_end:
            not_scored += 1
            pairs.append(None)
            continue
        hit = next((i for i, e in enumerate(events) if i not in used
                    and tc.t_on <= e.detected_at <= tc.t_on + tc.duration + late), None)
        pairs.append(hit)
        if hit is None and tc.t_on + tc.duration + late > t_end:
            not_scored += 1
        elif hit is None:
            missed.append(tc)
        else:
            used.add(hit)
            lat.append(events[hit].detected_at - tc.t_on)
    spurious = [e for i, e in enumerate(events) if i not in used]
    return Match(hits=len(lat), misses=len(missed), false_alarms=len(spurious),
                 latencies=np.asarray(lat), missed=missed, spurious=spurious, not_scored=not_scored,
                 pairs=pairs)


def touches_from_truth(t: NDArray[np.float64], contact_true: NDArray[np.float64],
                       n_fingers: NDArray[np.float64] | None = None) -> list[Touch]:
    """The touches of a truth log (``contact_true`` 0/1 per sample, e.g. the emulator's
    ``--truth`` file): one :class:`Touch` per run of ones, from its first to its last sample."""
    t = np.asarray(t, dtype=float)
    c = np.asarray(contact_true, dtype=float) > 0.5
    if not len(t):
        return []
    edges = np.flatnonzero(np.diff(np.concatenate([[False], c, [False]]).astype(np.int8)))
    out = []
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        n = int(np.max(n_fingers[a:b])) if n_fingers is not None else 1
        t_end = t[b - 1] + (t[1] - t[0] if len(t) > 1 else 0.0)
        out.append(Touch(t_on=float(t[a]), duration=float(t_end - t[a]), n_fingers=n,
                         G=None if n > 0 else 0.05))
    return out


@dataclass
class Tracking:
    """Tracking of one command over ``[t0, t1)`` (s): errors of ``T_w`` (measured), K."""

    T_w_cmd: float
    t0: float
    t1: float
    mean_abs_error: float
    mean_error: float
    T_p_cmd_min: float
    T_p_cmd_max: float


def tracking_errors(log: dict[str, NDArray[np.float64]], window: float = 60.0) -> list[Tracking]:
    """Per command segment of ``log["T_w_cmd"]``: errors over its last ``window`` s (or half)."""
    t, cmd, T_w = log["t"], log["T_w_cmd"], log["T_w"]
    edges = np.flatnonzero(np.diff(cmd) != 0) + 1
    bounds = [0, *edges.tolist(), len(t)]
    out = []
    for a, b in itertools.pairwise(bounds):
        t_end = t[b - 1]
        t_start = max(t[a] + 0.5 * (t_end - t[a]), t_end - window)
        w = slice(int(np.searchsorted(t, t_start)), b)
        e = T_w[w] - cmd[w]
        e = e[np.isfinite(e)]
        T_pc = log["T_p_cmd"][a:b] if "T_p_cmd" in log else np.full(1, np.nan)
        out.append(Tracking(T_w_cmd=float(cmd[a]), t0=float(t_start), t1=float(t_end),
                            mean_abs_error=float(np.mean(np.abs(e))), mean_error=float(np.mean(e)),
                            T_p_cmd_min=float(np.min(T_pc)), T_p_cmd_max=float(np.max(T_pc))))
    return out
