"""Scoring detected contacts against scripted touches: hits, misses, false alarms, latency."""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from thermoskin.estimation.events import ContactEvent
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

    def latency_by_touch(self) -> list[float | None]:
        """Per touch (in order), its latency (s); None where it has no event."""
        hits = iter(self.latencies.tolist())
        return [None if j is None else next(hits) for j in self.pairs]


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
    """Per command segment of ``log["T_w_cmd"]``: errors over its last ``window`` s (or half).
    The whole log at once: :class:`TrackingStream` fed one chunk."""
    ts = TrackingStream(window)
    ts.feed(log["t"], log["T_w"], log["T_w_cmd"], log.get("T_p_cmd"))
    return ts.finish()


class TrackingStream:
    """:func:`tracking_errors` fed chunk by chunk (a run as it goes), in bounded memory.

    A segment is a run of equal ``T_w_cmd``; it ends where the command changes (between
    chunks too) or at :meth:`finish`. Its errors ``T_w - T_w_cmd`` (finite ones) are
    averaged over ``[max(t_a + (t_end - t_a)/2, t_end - window), t_end]``, ``t_a`` and
    ``t_end`` its first and last sample; ``T_p_cmd``'s range (NaN without it) is over the
    whole segment. Only the last ``window`` s of the current segment are held, so any
    chunking gives the same numbers as the whole log.
    """

    def __init__(self, window: float = 60.0) -> None:
        self.window = float(window)
        self.out: list[Tracking] = []
        self._held: list[tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]] = []
        self._cmd = math.nan  # the segment's command
        self._t_a = math.nan  # its first sample's time
        self._pc = (math.nan, math.nan)  # T_p_cmd's min and max over it
        self._open = False

    def feed(self, t: NDArray[np.float64], T_w: NDArray[np.float64], T_w_cmd: NDArray[np.float64],
             T_p_cmd: NDArray[np.float64] | None = None) -> None:
        """The next samples (``t`` increasing)."""
        t, T_w, cmd = (np.asarray(x, dtype=np.float64) for x in (t, T_w, T_w_cmd))
        if not len(t):
            return
        pc = np.full(len(t), np.nan) if T_p_cmd is None else np.asarray(T_p_cmd, dtype=np.float64)
        cuts = (np.flatnonzero(np.diff(cmd) != 0) + 1).tolist()
        new_first = self._open and bool(cmd[0] != self._cmd)  # NaN != NaN: a change, as np.diff
        for a, b in itertools.pairwise([0, *cuts, len(t)]):
            if a > 0 or new_first or not self._open:
                self._close()
                self._open = True
                self._cmd, self._t_a = float(cmd[a]), float(t[a])
                self._pc = (float(np.min(pc[a:b])), float(np.max(pc[a:b])))
            else:
                self._pc = (float(np.minimum(self._pc[0], np.min(pc[a:b]))),
                            float(np.maximum(self._pc[1], np.max(pc[a:b]))))
            self._held.append((t[a:b], T_w[a:b], cmd[a:b]))
        self._trim(float(t[-1]) - self.window)

    def _trim(self, cutoff: float) -> None:
        """Drop the held samples before ``cutoff`` (s): no segment's window reaches them."""
        held = self._held
        while held and held[0][0][-1] < cutoff:
            held.pop(0)
        if held:
            i = int(np.searchsorted(held[0][0], cutoff))
            if i:
                held[0] = tuple(x[i:] for x in held[0])  # type: ignore[assignment]

    def _close(self) -> None:
        if not self._open:
            return
        t, T_w, cmd = (np.concatenate([h[i] for h in self._held]) for i in range(3))
        self._held = []
        self._open = False
        t_end = float(t[-1])
        t_start = max(self._t_a + 0.5 * (t_end - self._t_a), t_end - self.window)
        w = slice(int(np.searchsorted(t, t_start)), len(t))
        e = T_w[w] - cmd[w]
        e = e[np.isfinite(e)]
        self.out.append(Tracking(T_w_cmd=self._cmd, t0=float(t_start), t1=t_end,
                                 mean_abs_error=float(np.mean(np.abs(e))), mean_error=float(np.mean(e)),
                                 T_p_cmd_min=self._pc[0], T_p_cmd_max=self._pc[1]))

    def finish(self) -> list[Tracking]:
        """Close the last segment; every segment's :class:`Tracking`, in order."""
        self._close()
        return self.out
