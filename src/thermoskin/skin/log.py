"""The long-format log of a skin of many patches: read, checked, and laid out as (sample, patch).

``thermoskin simulate --skin`` and ``run --skin`` write one row per sample and patch,
``t,patch,T_w,T_p,v,T_a[,T_w2,...]`` (``runtime/skin_loop.py``), patches in the description's
order within each sample. :func:`read_skin_log` reads such a log (CSV or Parquet) whole and
returns its columns as arrays of shape ``(n, P)`` (sample ``k``, patch ``i``);
:class:`SkinLogReader` reads it block by block, memory bounded whatever its length. Every user
error (a missing column, a non-numeric value, a row out of place, a patch index the skin does
not have, a non-uniform ``t``) is a :class:`~thermoskin.logio.LogError` of one line naming the
file, the line or row and the column.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from thermoskin.atomic import atomic_path
from thermoskin.logio import LogError
from thermoskin.logio.units import Units
from thermoskin.skin.layout import Skin

Array = NDArray[np.float64]

REQUIRED = ("t", "patch", "T_w", "T_p", "v", "T_a")
"""Columns a skin log must have."""
TRUTH = ("q_i", "contact_true", "position_true")
"""The simulator's truth columns (kept, never used by the estimator)."""
CHUNK_SAMPLES = 16_384
"""Samples per block of :class:`SkinLogReader` (times the patches: rows), at most."""
ROWS_PER_BLOCK = 1 << 20
"""Rows (samples times patches) a block of a skin's log holds at most, so that memory follows
neither the log's length nor the skin's size: with 10 000 patches a block of 16 384 samples was
1.6e8 rows, about 26 GB of columns (:func:`block_samples`)."""


def block_samples(P: int, samples: int = CHUNK_SAMPLES) -> int:
    """Samples of a block of a ``P``-patch skin: ``samples``, fewer where that would be more than
    :data:`ROWS_PER_BLOCK` rows (one at least)."""
    return max(1, min(int(samples), ROWS_PER_BLOCK // max(1, P)))
RTOL = 1e-3
"""A skin log's sample intervals are within this share of the first block's median."""


@dataclass
class SkinLog:
    """A long-format log as ``(n, P)`` arrays: ``cols[name][k, i]`` is sample ``k`` of patch ``i``;
    ``t`` (n,) the sample times, ``t_s`` the interval, ``names`` the file's columns in order."""

    path: Path
    t: Array
    t_s: float
    cols: dict[str, Array]
    names: list[str]

    @property
    def n(self) -> int:
        return len(self.t)

    def has(self, name: str) -> bool:
        return name in self.cols


def _nan_ok(name: str) -> bool:
    """NaN is a value anywhere but in a row's time, patch and flags (a held-over reading, no
    contact's position yet)."""
    return name not in ("patch", "fresh", "contact_true")


class SkinLogReader:
    """A skin's long-format log read in blocks of whole samples, checked as it goes: iterating
    gives ``(t, cols)``, ``t`` the block's sample times ``(m,)`` and ``cols[name]`` its ``(m, P)``
    columns (sample ``k``, patch ``i``). Memory holds one block whatever the log's length.

    The patches' order within each sample, then the checks of :class:`~thermoskin.logio.LogReader`
    (every value a number, NaN only where :func:`_nan_ok`, nothing infinite, no empty line, each
    sample's rows of one ``t``, ``t`` uniform within :data:`RTOL`, the last sample whole); a
    fault is a :class:`LogError` of one line naming the file, the CSV line or Parquet row and
    the column, when its block is reached. Attributes: ``names`` (the file's columns), ``t_s``
    (the first block's interval, once read), ``n`` (samples read so far)."""

    def __init__(self, path: str | os.PathLike[str], skin: Skin, chunk_samples: int = CHUNK_SAMPLES,
                 units: Units | None = None) -> None:
        """``units``: the log's units (:class:`~thermoskin.logio.units.Units`; None: as they are)."""
        from thermoskin.logio import LogReader

        self.path, self.skin, self.P = Path(path), skin, len(skin.patches)
        self._r = LogReader(path, ("t",), _nan_ok, chunk_rows=block_samples(self.P, chunk_samples) * self.P,
                            rows_per_sample=self.P, check=self._patches, rtol=RTOL, units=units)
        self.names: list[str] = list(self._r.names)
        missing = [c for c in REQUIRED if c not in self.names]
        if missing:
            self._r.close()
            hint = ("; it looks like one patch's log: observe reads it without --skin"
                    if "patch" in missing and "T_w" in self.names else "")
            raise LogError(f"{self.path}: column(s) {', '.join(missing)} missing (a skin log has "
                           f"{', '.join(REQUIRED)}, one row per sample and patch){hint}")
        self._ip = self.names.index("patch")

    @property
    def t_s(self) -> float:
        assert self._r.t_s is not None, "read a block first"
        return self._r.t_s

    @property
    def n(self) -> int:
        return self._r.rows // self.P

    def _patches(self, cols: list[Array], row0: int) -> None:
        """The patches in order in every sample of a chunk (``row0``: the log's row of its first)."""
        patch = cols[self._ip]
        P = self.P
        wrong = np.flatnonzero(patch != np.tile(np.arange(P, dtype=float), len(patch) // P))
        if wrong.size:
            j = int(wrong[0])
            raise LogError(f"{self.path}: {self._r.place(row0 + j)}, column 'patch': {patch[j]:g} where "
                           f"patch {j % P} was due: the skin {self.skin.name!r} has {P} patches (0 to "
                           f"{P - 1}), every sample one row each, in order")

    def __iter__(self) -> Iterator[tuple[Array, dict[str, Array]]]:
        P = self.P
        with self._r:
            for cols in self._r:
                m = len(cols["t"]) // P
                yield cols["t"][::P].copy(), {k: v.reshape(m, P) for k, v in cols.items()}


def read_skin_log(path: str | os.PathLike[str], skin: Skin) -> SkinLog:
    """The long-format log at ``path`` for ``skin`` (module doc), read whole (its blocks from
    :class:`SkinLogReader` joined); :class:`LogError` on bad input."""
    r = SkinLogReader(path, skin)
    ts, blocks = [], []
    for t, cols in r:
        ts.append(t)
        blocks.append(cols)
    cols = {k: np.concatenate([b[k] for b in blocks]) for k in r.names}
    return SkinLog(r.path, np.concatenate(ts), r.t_s, cols, r.names)


def long_columns(log: SkinLog, extra: dict[str, Array], drop: tuple[str, ...] = ()) -> dict[str, Array]:
    """The log's columns (less ``drop``) and ``extra`` (each ``(n, P)``) back in long format."""
    return long_block(log.cols, log.names, extra, drop)


def long_block(cols: dict[str, Array], names: list[str], extra: dict[str, Array],
               drop: tuple[str, ...] = ()) -> dict[str, Array]:
    """A block's ``(m, P)`` columns ``names`` (less ``drop``) and ``extra`` in long format."""
    out = {k: cols[k].ravel() for k in names if k not in drop and k not in extra}
    for c in ("patch", "fresh", "contact_true"):
        if c in out:
            out[c] = out[c].astype(np.int64)
    out.update({k: v.ravel() for k, v in extra.items()})
    return out


def write_table(path: str | os.PathLike[str], columns: dict[str, NDArray[np.generic]]) -> Path:
    """A small table with text columns (events, groups) as CSV, written atomically; floats in their
    shortest round-trip form, NaN as an empty field."""
    import csv

    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    names = list(columns)
    n = len(next(iter(columns.values()))) if columns else 0

    def cell(x: object) -> str:
        if isinstance(x, float | np.floating):
            return "" if math.isnan(x) else repr(float(x))
        return str(x)

    with atomic_path(p) as tmp, open(tmp, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(names)
        for r in range(n):
            w.writerow([cell(columns[c][r]) for c in names])
    return p
