"""Contact events: what a detected contact is, and the events table (``--events EVENTS.csv``).

One row per contact with the columns of :data:`EVENT_COLUMNS` (s, s, s, s, +1/-1, W, W, J):
``onset`` (when the touch began, back-dated by the detector), ``detected`` (when the detector
decided), ``release``, ``duration``, ``sign`` (+1: heat into the skin, a warm body; -1: heat
out of it, a cold object), ``peak_dq`` and ``mean_dq`` (the estimated touch heat, signed)
and ``energy``; then what touched (:mod:`thermoskin.touch.characterise`, empty where not
identifiable): ``kind`` (``tap``/``hold``), ``toucher`` (``human``/``object``), ``material``
(the most likely material class), ``p_human``, the contact conductance ``G_hat`` and its
standard deviation ``G_sd`` (W/K), the toucher's surface temperature at the onset
``T_f_hat`` and ``T_f_sd`` (°C, K) and its effusivity ``effusivity_hat`` (W s^0.5/(m² K)).

The table is written as CSV (numbers in their shortest round-trip form, an empty field for
a value not identified) or Parquet (text columns as strings, null for not identified): whole
(:func:`write_events`, atomically) or, during a run, a row as each contact ends
(:class:`EventsStream`), so that a killed run keeps the contacts that had ended.
"""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from thermoskin.atomic import atomic_path

#: Columns of the detector's events: s, s, s, s, +1/-1, W, W, J.
DETECTION_COLUMNS = ("onset", "detected", "release", "duration", "sign", "peak_dq", "mean_dq", "energy")
#: Columns saying what touched: text, text, text, 1, W/K, W/K, °C, K, W s^0.5/(m² K).
CHARACTER_COLUMNS = ("kind", "toucher", "material", "p_human", "G_hat", "G_sd", "T_f_hat", "T_f_sd",
                     "effusivity_hat")
#: Columns of the events table (``--events``).
EVENT_COLUMNS = DETECTION_COLUMNS + CHARACTER_COLUMNS
#: The text columns among them (the others are numbers).
TEXT_COLUMNS = ("kind", "toucher", "material")

TAP_S = 1.0
"""A contact shorter than this is a tap, s (taps last 0.2-0.6 s, holds 1.5 s and more)."""

#: The compiled kernel's event record: these fields, in this order (``estimation.kernel``),
#: then what the estimator had learnt of the sensors when the contact ended (held through it):
#: the readings' variances of ``T_w``, ``T_p``, ``T_a`` (K²), the learnt offset of ``T_p``'s
#: readings against ``T_w``'s (K) and the pipe thermocouple's lag (s) (the re-dating's filter
#: takes them).
EV_ONSET, EV_DETECTED, EV_RELEASE, EV_DURATION, EV_SIGN, EV_PEAK, EV_MEAN, EV_ENERGY = range(8)
EV_RW, EV_RP, EV_RA, EV_BD, EV_LAG = range(8, 13)
NEV = 13


def one_patch_kind(duration: float) -> str:
    """``tap`` or ``hold`` by the contact's ``duration`` (s); ``""`` while not known (NaN)."""
    if not math.isfinite(duration):
        return ""
    return "tap" if duration < TAP_S else "hold"


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
    # what touched (:mod:`thermoskin.touch.characterise`): empty text and NaN where not identified
    kind: str = ""
    toucher: str = ""
    material: str = ""
    p_human: float = math.nan
    G_hat: float = math.nan
    G_sd: float = math.nan
    T_f_hat: float = math.nan
    T_f_sd: float = math.nan
    effusivity_hat: float = math.nan

    def as_dict(self) -> dict[str, float | str]:
        return asdict(self)

    def row(self) -> dict[str, float | str]:
        """The event as a row of :data:`EVENT_COLUMNS`."""
        return {"onset": self.onset, "detected": self.detected_at, "release": self.release,
                "duration": self.duration, "sign": self.sign, "peak_dq": self.peak_dq,
                "mean_dq": self.mean_dq, "energy": self.energy,
                **{k: getattr(self, k) for k in CHARACTER_COLUMNS}}

    @classmethod
    def from_kernel(cls, ev: NDArray[np.float64]) -> ContactEvent:
        """From the kernel's event record (the ``EV_*`` layout above)."""
        return cls(onset=float(ev[EV_ONSET]), detected_at=float(ev[EV_DETECTED]),
                   release=float(ev[EV_RELEASE]), duration=float(ev[EV_DURATION]),
                   sign=int(ev[EV_SIGN]), peak_dq=float(ev[EV_PEAK]),
                   mean_dq=float(ev[EV_MEAN]), energy=float(ev[EV_ENERGY]))


def events_columns(events: Sequence[ContactEvent]) -> dict[str, NDArray[Any]]:
    """The events as columns of :data:`EVENT_COLUMNS` (float arrays; the text columns as
    arrays of ``str``); empty columns for no event."""
    rows = [e.row() for e in events]
    return {k: np.array([r[k] for r in rows], dtype=str if k in TEXT_COLUMNS else float)
            for k in EVENT_COLUMNS}


def _csv_field(name: str, v: Any) -> str:
    """A CSV field: text as it is, a number in its shortest round-trip form (NaN empty)."""
    if name in TEXT_COLUMNS or isinstance(v, str):
        return str(v)
    x = float(v)
    if not math.isfinite(x):
        return ""
    return str(int(x)) if name == "sign" else repr(x)


class EventsStream:
    """An events table (CSV) written as the contacts end, a row each, flushed at once: a run
    killed at any moment (SIGKILL, a power cut after the flush) keeps every contact that had
    ended. Their ``kind`` is known then; what touched is said at the end of the run, when
    :func:`write_events` replaces this file with the whole table. ``columns``: the table's
    (default :data:`EVENT_COLUMNS`; a skin's has its patch and position too); ``fill_kind``: a
    ``kind`` left empty is the one patch's ``tap`` or ``hold`` (a skin's kind comes from several
    patches' contacts: at the end). A context manager."""

    def __init__(self, path: str | os.PathLike[str], columns: Sequence[str] = EVENT_COLUMNS,
                 fill_kind: bool = True) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.columns = tuple(columns)
        self._kind = one_patch_kind if fill_kind and "kind" in self.columns else None
        self._fh = open(self.path, "w", newline="", encoding="utf-8")  # noqa: SIM115 (closed by close())
        self._w = csv.writer(self._fh, lineterminator="\n")
        self._w.writerow(self.columns)
        self._fh.flush()
        self.rows = 0

    def add(self, e: ContactEvent) -> None:
        """One contact that has ended."""
        self.add_row(e.row())

    def add_row(self, row: dict[str, Any]) -> None:
        """One contact's row (columns missing from it are left empty)."""
        if self._kind is not None and not row.get("kind"):
            row = {**row, "kind": self._kind(float(row.get("duration", math.nan)))}
        self._w.writerow([_csv_field(k, row.get(k, "")) for k in self.columns])
        self._fh.flush()
        self.rows += 1

    def close(self) -> None:
        self._fh.close()

    def __enter__(self) -> EventsStream:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def write_events(path: str | os.PathLike[str], events: Sequence[ContactEvent]) -> Path:
    """Write the events table (CSV or Parquet by the extension), one row per contact,
    atomically (a temporary file in the same folder, renamed)."""
    from thermoskin.logio.common import log_format

    p = Path(path)
    fmt = log_format(p)
    p.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(p) as tmp:  # whole or not at all
        if fmt == "csv":
            with open(tmp, "w", newline="", encoding="utf-8") as fh:
                w = csv.writer(fh, lineterminator="\n")
                w.writerow(EVENT_COLUMNS)
                for e in events:
                    r = e.row()
                    w.writerow([_csv_field(k, r[k]) for k in EVENT_COLUMNS])
        else:
            import pyarrow as pa
            import pyarrow.parquet as pq

            cols = events_columns(events)
            arrays = [pa.array([x or None for x in cols[k].tolist()], type=pa.string()) if k in TEXT_COLUMNS
                      else pa.array(cols[k], type=pa.float64(), mask=~np.isfinite(cols[k]))
                      for k in EVENT_COLUMNS]
            from thermoskin.atomic import arrow_target

            with arrow_target(tmp, "wb") as f:
                pq.write_table(pa.Table.from_arrays(arrays, names=list(EVENT_COLUMNS)), f)
    return p
