"""Implausible samples are bad samples: a reading outside its physical range is no reading.

One bad value (a thermocouple board's garbage word, a corrupted log field: ``T_w = 1e30``,
``v = 1e308``) fed to a filter stays in its state for good: it poisons every estimate after
it, or overflows. So before any filter sees them, the measured columns are checked
against the ``[plausible]`` ranges of the configuration (:class:`~thermoskin.params.PlausibleParams`;
by default -50 to 150 °C for ``T_w, T_p, T_a``, 0 to 10 m/s for ``v``, -1 to 1 for the
drive) and a value outside (or not finite) becomes NaN: the estimator holds its outputs
over it and flags the row ``gap``, exactly as for a NaN reading; the supervisor counts it
as a NaN reading (``max_nan_s``). ``T_w_cmd`` outside the ``T_w`` range holds the last
plausible command; an implausible ``drive`` is an unknown drive.

The check is done in one place on each path: :func:`admit` (three plain floats, the loop
body's input, :mod:`thermoskin.runtime.realtime` and :mod:`~thermoskin.runtime.closed_loop`)
and :func:`clean_log` (whole columns, :func:`thermoskin.analysis.observe.observe`, and ``replay``).
A log written by a run therefore gives the live run's estimates again offline: the same
values are dropped on both paths. The log keeps what the device sent.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from thermoskin.params import Config, PlausibleParams

Array = NDArray[np.float64]

#: Columns checked, and the ``[plausible]`` range each is checked against.
RANGES = {"T_w": "T_w", "T_p": "T_p", "T_a": "T_a", "v": "v", "drive": "drive", "T_w_cmd": "T_w"}
UNITS = {"T_w": "degC", "T_p": "degC", "T_a": "degC", "v": "m/s", "drive": "", "T_w_cmd": "degC"}


def limits(p: PlausibleParams) -> tuple[float, float, float, float, float, float]:
    """``(T_w_min, T_w_max, T_p_min, T_p_max, T_a_min, T_a_max)``: the loop's three readings."""
    return p.T_w_min, p.T_w_max, p.T_p_min, p.T_p_max, p.T_a_min, p.T_a_max


def admit(lim: tuple[float, float, float, float, float, float], T_w: float, T_p: float,
          T_a: float) -> tuple[float, float, float]:
    """The three readings with each outside its range (or NaN, or infinite) as NaN."""
    nan = math.nan
    return (T_w if lim[0] <= T_w <= lim[1] else nan,
            T_p if lim[2] <= T_p <= lim[3] else nan,
            T_a if lim[4] <= T_a <= lim[5] else nan)


def admit_arrays(lim: tuple[float, float, float, float, float, float], T_w: Array, T_p: Array,
                 T_a: Array) -> tuple[Array, Array, Array]:
    """:func:`admit` over whole columns (a recording's readings, as the loop admitted them)."""
    out = []
    with np.errstate(invalid="ignore"):
        for j, x in enumerate((T_w, T_p, T_a)):
            x = np.asarray(x, dtype=float)
            out.append(np.where((x >= lim[2 * j]) & (x <= lim[2 * j + 1]), x, np.nan))
    return out[0], out[1], out[2]


@dataclass
class Cleaned:
    """:func:`clean_log`'s result: the columns to estimate from and what was dropped."""

    columns: dict[str, Array]
    rejected: Array
    """Rows where any checked input was implausible (finite or not, but not a NaN already)."""
    counts: dict[str, int] = field(default_factory=dict)
    """Implausible values per column (NaN readings not counted)."""
    first: dict[str, float] = field(default_factory=dict)
    """``t`` of the first implausible value per column."""
    no_valid: list[str] = field(default_factory=list)
    """Measured columns (``T_w, T_p, T_a, v``) with no plausible value at all."""

    def warnings(self, cfg: Config) -> list[str]:
        """One line per column with implausible values, and per column with none valid."""
        p = cfg.plausible
        out = []
        for col, n in self.counts.items():
            r = RANGES[col]
            lo, hi = getattr(p, f"{r}_min"), getattr(p, f"{r}_max")
            what = ("held at the last plausible command" if col == "T_w_cmd" else
                    "taken as an unknown drive" if col == "drive" else "treated as missing (held over, gap)")
            out.append(f"{n} value(s) of {col} outside the plausible range [{lo:g}, {hi:g}] "
                       f"{UNITS[col]} (first at t = {self.first[col]:.3f} s) {what}")
        for col in self.no_valid:
            out.append(f"column {col} has no valid sample (all NaN or implausible): every row is a "
                       "gap; no estimate and no contact can come from this log")
        return out


def clean_log(log: Mapping[str, Array], cfg: Config) -> Cleaned:
    """The log's estimator inputs with implausible values dropped (see the module doc)."""
    p = cfg.plausible
    t = np.asarray(log["t"], dtype=float)
    out = dict(log)
    rejected = np.zeros(len(t), dtype=bool)
    counts: dict[str, int] = {}
    first: dict[str, float] = {}
    no_valid = []
    for col, r in RANGES.items():
        if col not in log:
            continue
        x = np.asarray(log[col], dtype=float)
        lo, hi = getattr(p, f"{r}_min"), getattr(p, f"{r}_max")
        with np.errstate(invalid="ignore"):
            ok = (x >= lo) & (x <= hi)
        bad = ~ok & ~np.isnan(x)
        if bad.any():
            counts[col] = int(bad.sum())
            first[col] = float(t[np.argmax(bad)])
            x = _hold(x, ok) if col == "T_w_cmd" else np.where(ok, x, np.nan)
            rejected |= bad
            out[col] = x
        if col in ("T_w", "T_p", "T_a", "v") and len(x) and not ok.any():
            no_valid.append(col)
    return Cleaned(columns=out, rejected=rejected, counts=counts, first=first, no_valid=no_valid)


def _hold(x: Array, ok: NDArray[np.bool_]) -> Array:
    """``x`` with each value where not ``ok`` replaced by the last ``ok`` one (NaN kept, and
    before the first ``ok`` value the first one)."""
    nan_in = np.isnan(x)
    good = ok | nan_in
    if not good.any():
        return np.full_like(x, np.nan)
    idx = np.where(good, np.arange(len(x)), 0)
    np.maximum.accumulate(idx, out=idx)
    first_good = int(np.argmax(good))
    idx[:first_good] = first_good
    return x[idx]
