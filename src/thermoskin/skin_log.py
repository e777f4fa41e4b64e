"""The long-format log of a skin of many patches: read, checked, and laid out as (sample, patch).

``thermoskin simulate --skin`` and ``run --skin`` write one row per sample and patch,
``t,patch,T_w,T_p,v,T_a[,T_w2,...]`` (``runtime/skin_loop.py``), patches in the description's
order within each sample. :func:`read_skin_log` reads such a log (CSV or Parquet) whole and
returns its columns as arrays of shape ``(n, P)`` (sample ``k``, patch ``i``). Every user error
(a missing column, a non-numeric value, a row out of place, a patch index the skin does not
have, a non-uniform ``t``) is a :class:`~thermoskin.logio.LogError` of one line naming the file,
the row and the column.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from thermoskin.atomic import atomic_path
from thermoskin.logio import LogError, log_format
from thermoskin.skin import Skin

Array = NDArray[np.float64]

REQUIRED = ("t", "patch", "T_w", "T_p", "v", "T_a")
"""Columns a skin log must have."""
TRUTH = ("q_i", "contact_true", "position_true")
"""The simulator's truth columns (kept, never used by the estimator)."""


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


def _table(path: Path) -> dict[str, NDArray[np.generic]]:
    fmt = log_format(path)
    if not path.exists():
        raise LogError(f"{path} does not exist")
    if path.is_dir():
        raise LogError(f"{path} is a directory, not a log")
    try:
        if fmt == "parquet":
            import pyarrow.parquet as pq

            tab = pq.read_table(path)
        else:
            import pyarrow.csv as pc

            tab = pc.read_csv(path)
    except Exception as e:
        msg = " ".join(str(e).split())
        raise LogError(f"{path}: cannot be read as a {fmt.upper()} log: {msg[:160]}") from None
    out: dict[str, NDArray[np.generic]] = {}
    import pyarrow as pa

    for name in tab.column_names:
        col = tab[name]
        if pa.types.is_null(col.type):  # every value NaN (Arrow reads "NaN" as null): no contact yet
            out[name] = np.full(len(col), np.nan)
            continue
        try:
            a = col.to_numpy(zero_copy_only=False)
        except Exception:
            a = np.asarray(col.to_pylist(), dtype=object)
        out[name] = a
    return out


def read_skin_log(path: str | os.PathLike[str], skin: Skin) -> SkinLog:
    """The long-format log at ``path`` for ``skin`` (module doc); :class:`LogError` on bad input."""
    p = Path(path)
    raw = _table(p)
    P = len(skin.patches)
    for c in REQUIRED:
        if c not in raw:
            raise LogError(f"{p}: column {c!r} is missing (a skin log has {', '.join(REQUIRED)}, "
                           "one row per sample and patch)")
    m = len(raw["t"])
    if m == 0:
        raise LogError(f"{p}: the log has no rows")
    cols: dict[str, Array] = {}
    for name, a in raw.items():
        if a.dtype.kind not in "fiub":
            bad = next((j for j, x in enumerate(a) if not _is_number(x)), 0)
            raise LogError(f"{p}: row {bad + 1}, column {name!r}: {a[bad]!r} is not a number")
        cols[name] = np.asarray(a, dtype=float)
    patch = cols["patch"]
    expect = np.tile(np.arange(P, dtype=float), m // P + 1)[:m]
    wrong = np.flatnonzero(patch != expect)
    if wrong.size:
        j = int(wrong[0])
        raise LogError(f"{p}: row {j + 1}, column 'patch': {patch[j]:g} where patch {int(expect[j])} "
                       f"was due: the skin {skin.name!r} has {P} patches (0 to {P - 1}), every sample "
                       "one row each, in order")
    if m % P:
        raise LogError(f"{p}: {m} rows is not a whole number of samples of {P} patches (the last is cut)")
    n = m // P
    if n < 2:
        raise LogError(f"{p}: a log needs at least 2 samples")
    t2 = cols["t"].reshape(n, P)
    if not np.all(np.isfinite(t2)):
        j = int(np.flatnonzero(~np.isfinite(cols["t"]))[0])
        raise LogError(f"{p}: row {j + 1}, column 't': {cols['t'][j]} is not a finite time")
    same = np.flatnonzero((t2 != t2[:, :1]).any(axis=1))
    if same.size:
        raise LogError(f"{p}: row {same[0] * P + 1}: the patches of one sample have different times t")
    t = t2[:, 0].copy()
    dt = np.diff(t)
    t_s = float(np.median(dt))
    if not (t_s > 0) or np.any(np.abs(dt - t_s) > 1e-3 * t_s + 1e-9):
        j = int(np.flatnonzero(~(np.abs(dt - t_s) <= 1e-3 * t_s + 1e-9))[0]) + 1
        raise LogError(f"{p}: row {j * P + 1}, column 't': {t[j]:.6g} s breaks the uniform sampling "
                       f"(every {t_s:.6g} s)")
    for c in ("t", "patch", "fresh", "contact_true"):
        if c in cols and np.any(~np.isfinite(cols[c])):
            j = int(np.flatnonzero(~np.isfinite(cols[c]))[0])
            raise LogError(f"{p}: row {j + 1}, column {c!r}: NaN value")
    shaped = {k: v.reshape(n, P) for k, v in cols.items()}
    return SkinLog(p, t, t_s, shaped, list(raw))


def _is_number(x: object) -> bool:
    if x is None:
        return True  # a null: NaN
    if isinstance(x, int | float) and not isinstance(x, bool):
        return True
    try:
        float(str(x))
    except ValueError:
        return False
    return True


def long_columns(log: SkinLog, extra: dict[str, Array], drop: tuple[str, ...] = ()) -> dict[str, Array]:
    """The log's columns (less ``drop``) and ``extra`` (each ``(n, P)``) back in long format."""
    out = {k: log.cols[k].ravel() for k in log.names if k not in drop and k not in extra}
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
