"""Contact events: what a detected contact is, and the events table (``--events EVENTS.csv``).

One row per contact with the columns of :data:`EVENT_COLUMNS` (s, s, s, s, +1/-1, W, W, J):
``onset`` (when the touch began, back-dated by the detector), ``detected`` (when the detector
decided), ``release``, ``duration``, ``sign`` (+1: heat into the skin, a warm body; -1: heat
out of it, a cold object), ``peak_dq`` and ``mean_dq`` (the estimated touch heat, signed)
and ``energy``.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

#: Columns of the events table (``--events``): s, s, s, s, +1/-1, W, W, J.
EVENT_COLUMNS = ("onset", "detected", "release", "duration", "sign", "peak_dq", "mean_dq", "energy")
#: The compiled kernel's event record: these fields, in this order (``estimation.kernel``).
EV_ONSET, EV_DETECTED, EV_RELEASE, EV_DURATION, EV_SIGN, EV_PEAK, EV_MEAN, EV_ENERGY = range(8)
NEV = 8


@dataclass(frozen=True)
class ContactEvent:
    """One detected contact. Times in s; heat flows (signed: negative when heat leaves the
    skin, a cold object) in W; energy in J; ``sign`` +1 (heat in) or -1 (heat out)."""

    onset: float
    detected_at: float
    release: float
    duration: float
    sign: int
    peak_dq: float
    mean_dq: float
    energy: float

    def as_dict(self) -> dict[str, float]:
        return asdict(self)

    def row(self) -> dict[str, float]:
        """The event as a row of :data:`EVENT_COLUMNS`."""
        return {"onset": self.onset, "detected": self.detected_at, "release": self.release,
                "duration": self.duration, "sign": self.sign, "peak_dq": self.peak_dq,
                "mean_dq": self.mean_dq, "energy": self.energy}

    @classmethod
    def from_kernel(cls, ev: NDArray[np.float64]) -> ContactEvent:
        """From the kernel's event record (the ``EV_*`` layout above)."""
        return cls(onset=float(ev[EV_ONSET]), detected_at=float(ev[EV_DETECTED]),
                   release=float(ev[EV_RELEASE]), duration=float(ev[EV_DURATION]),
                   sign=int(ev[EV_SIGN]), peak_dq=float(ev[EV_PEAK]),
                   mean_dq=float(ev[EV_MEAN]), energy=float(ev[EV_ENERGY]))


def events_columns(events: Sequence[ContactEvent]) -> dict[str, NDArray[np.float64]]:
    """The events as columns of :data:`EVENT_COLUMNS` (empty columns for no event)."""
    rows = [e.row() for e in events]
    return {k: np.array([r[k] for r in rows], dtype=float) for k in EVENT_COLUMNS}


def write_events(path: str | os.PathLike[str], events: Sequence[ContactEvent]) -> Path:
    """Write the events table (CSV or Parquet by the extension), one row per contact."""
    from thermoskin.logio import write_log

    return write_log(path, events_columns(events))
