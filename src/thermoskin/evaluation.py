"""Scoring detected contacts against scripted touches: hits, misses, false alarms, latency."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from thermoskin.detector import ContactEvent
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


def match_events(touches: Sequence[Touch], events: Sequence[ContactEvent],
                 late: float = 1.0) -> Match:
    """Pair each touch with the first event detected in ``[t_on, t_on + duration + late]``.

    Every other event (detected outside a touch's window, or a second event in the same
    window) is a false alarm.
    """
    used: set[int] = set()
    lat: list[float] = []
    missed: list[Touch] = []
    for tc in touches:
        hit = next((i for i, e in enumerate(events) if i not in used
                    and tc.t_on <= e.detected_at <= tc.t_on + tc.duration + late), None)
        if hit is None:
            missed.append(tc)
        else:
            used.add(hit)
            lat.append(events[hit].detected_at - tc.t_on)
    spurious = [e for i, e in enumerate(events) if i not in used]
    return Match(hits=len(lat), misses=len(missed), false_alarms=len(spurious),
                 latencies=np.asarray(lat), missed=missed, spurious=spurious)
