"""Logs in the shared schema: CSV (a header row) or Parquet, chosen by the file extension.

Columns are named as in ``docs/model.md``: ``t`` (s), ``T_w, T_p, T_a`` (°C), ``v`` (m/s),
``q_i_hat`` (W), ``contact`` (0/1), ... One row per sample, ``t`` strictly increasing and, by
default, uniformly sampled. Every value is a float64; a log written here and read back gives
the same float64 values bit for bit (CSV: shortest round-trip decimal form).

- :func:`read_log` / :func:`write_log`: a whole log in memory (small logs); ``write_log`` is
  atomic (temporary file, then rename).
- :class:`LogReader` / :class:`LogWriter`: streaming, in chunks; memory bounded whatever
  the log's length; :func:`write_blocks` writes a stream of chunks as one log, atomically. A
  CSV being written is readable up to its last flush; a Parquet file only once closed.

Bad input raises :class:`LogError` (a ``ValueError``) with a one-line message naming the
file, the line (CSV, 1-based, the header is line 1) or row (Parquet), the column and the
value. ``nan``, ``NaN``, ``NA`` and an empty field are read as NaN in the temperature and
velocity columns (a loose thermocouple gives NaN bursts; the observer handles those);
elsewhere, and in ``t`` always, every value must be a finite number.
"""

from __future__ import annotations

import contextlib
import math
import os
import warnings
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from thermoskin.logio.common import (
    CHUNK_ROWS,
    DEFAULT_REQUIRED,
    FLAG_COLUMNS,
    NAN_STRINGS,
    UNIFORM_RTOL,
    Array,
    LogError,
    as_column,
    check_names,
    check_time,
    log_format,
    nan_allowed,
    sample_time,
)
from thermoskin.logio.overlap import WriteBehind, prefetch
from thermoskin.logio.stream import LogReader, LogWriter
from thermoskin.logio.units import Units

__all__ = [
    "CHUNK_ROWS",
    "DEFAULT_REQUIRED",
    "FLAG_COLUMNS",
    "NAN_STRINGS",
    "UNIFORM_RTOL",
    "LogError",
    "LogReader",
    "LogWriter",
    "Units",
    "WriteBehind",
    "check_time",
    "has_rows",
    "log_format",
    "nan_allowed",
    "partial_last_line",
    "prefetch",
    "read_log",
    "sample_time",
    "write_blocks",
    "write_log",
]

#: Rows handed to the writer at a time by :func:`write_log` (bounds the formatting buffers).
_WRITE_SLICE = 262_144


def read_log(
    path: str | os.PathLike[str],
    required: Iterable[str] = DEFAULT_REQUIRED,
    nan_columns: Iterable[str] | None = None,
    *,
    uniform: bool = True,
    live: bool = False,
    one_patch: bool = False,
    keep: Iterable[str] | None = None,
    units: Units | None = None,
) -> dict[str, Array]:
    """Read a whole log into ``{column: float64 array}`` (in the file's column order).

    ``t`` is always required. ``nan_columns`` lists the columns where NaN (CSV: ``nan``,
    ``NaN``, ``NA``, empty) is accepted; by default the ``T_*`` and ``v`` columns.
    ``uniform=False`` accepts jitter in ``t`` (still strictly increasing); ``live=True``
    leaves out a CSV's last line if it has no line end yet (a log still being written, or
    whose writer was killed). ``one_patch=True`` refuses a skin's long-format log (a
    ``patch`` column: one row per sample and patch) with one line saying so. ``keep``: hold
    only these columns (every column is still read and checked, a chunk at a time; a command
    that needs three columns of a wide log then holds three, not all of them). ``units``:
    :class:`~thermoskin.logio.units.Units` (:class:`LogReader`). Raises :class:`LogError` on any
    user error. See :class:`LogReader` for long logs.
    """
    with LogReader(path, required, nan_columns, uniform=uniform, live=live,
                   one_patch=one_patch, units=units) as reader:
        if keep is None:
            chunks = list(reader)
            names = reader.names
        else:
            wanted = set(keep)
            names = [n for n in reader.names if n in wanted]
            # a column that is a view (of the chunk's parsed block) is copied: held, it would
            # hold the whole block
            chunks = [{n: c[n] if c[n].base is None else c[n].copy() for n in names} for c in reader]
    if len(chunks) == 1:
        return chunks[0]
    return {n: np.concatenate([c[n] for c in chunks]) for n in names}


def has_rows(path: str | os.PathLike[str]) -> bool:
    """Whether the log at ``path`` holds a sample that can be read back (a row after the header
    on disk; for Parquet, its footer's row count: one without a readable footer, its writer
    killed or its close failed, cannot be read). False where there is no file."""
    p = Path(path)
    if not p.is_file():
        return False
    if log_format(p) == "csv":
        with open(p, "rb") as fh:
            head = fh.read(1 << 20)
        nl = head.find(b"\n")
        return nl >= 0 and bool(head[nl + 1 :].strip())
    import pyarrow as pa
    import pyarrow.parquet as pq

    from thermoskin.atomic import arrow_target

    try:
        with arrow_target(p) as f:
            return pq.ParquetFile(f).metadata.num_rows > 0
    except (pa.ArrowInvalid, OSError):
        return False


def partial_last_line(path: str | os.PathLike[str]) -> bool:
    """Whether a CSV log ends in a line without its line end (not blank): the line a writer
    was killed inside, which ``read_log(..., live=True)`` leaves out. Always False for Parquet
    (and for a path that is not a readable file: its reader says why)."""
    p = Path(path)
    if not p.is_file() or log_format(p) != "csv":
        return False
    with open(p, "rb") as fh:
        size = fh.seek(0, os.SEEK_END)
        fh.seek(max(0, size - 65536))
        tail = fh.read()
    nl = tail.rfind(b"\n")
    if nl < 0:  # no line end in the last 64 KiB: cut if anything came before it
        return size > len(tail) and bool(tail.strip(b" \t\r"))
    return bool(tail[nl + 1 :].strip(b" \t\r"))


def write_log(
    path: str | os.PathLike[str],
    columns: Mapping[str, ArrayLike],
    float_format: str | None = None,
) -> Path:
    """Write ``columns`` as a log (CSV or Parquet by the extension), atomically; return the path.

    Floats keep full precision (CSV: shortest round-trip form); integer arrays and flag
    columns (:data:`FLAG_COLUMNS`) holding integers are written as integers. The parent
    folder is created if needed; the log is written to a temporary file in the same folder
    and renamed, so a crash never leaves half a log. ``float_format`` is obsolete (ignored,
    with a ``DeprecationWarning``): values are never rounded any more.
    """
    if float_format is not None:
        warnings.warn("write_log: float_format is ignored; logs keep full precision",
                      DeprecationWarning, stacklevel=2)
    names = list(columns)
    check_names(names, "write_log")
    log_format(path)
    arrays = {}
    for n in names:
        a = np.asarray(columns[n])
        a = as_column(a)
        if a.ndim != 1:
            raise ValueError(f"write_log: column {n!r} is not 1-D (shape {a.shape})")
        arrays[n] = a
    if len({a.size for a in arrays.values()}) != 1:
        sizes = ", ".join(f"{n}={a.size}" for n, a in arrays.items())
        raise ValueError(f"write_log: columns of different lengths: {sizes}")
    n_rows = arrays[names[0]].size
    with LogWriter(path, names, atomic=True, flush_rows=_WRITE_SLICE) as w:
        for i in range(0, n_rows, _WRITE_SLICE):
            w.write({n: a[i : i + _WRITE_SLICE] for n, a in arrays.items()})
    return Path(path)


def write_blocks(path: str | os.PathLike[str], blocks: Iterable[Mapping[str, ArrayLike]], *,
                 by_rows: bool = False) -> int:
    """Write the column chunks ``blocks`` one after the other as one log (CSV or Parquet by the
    extension), atomically: whole, or nothing if the blocks raise; the columns are the first
    block's. Memory holds one block (the blocks may be made as they are asked for). Returns the
    rows written (0: no block, nothing written). ``by_rows``: hand the rows over in the slices
    of 262 144 rows :func:`write_log` writes (not also every second), whatever the blocks'
    lengths, so that the bytes are those of the whole table written at once (a flag column's
    integers or floats are chosen per hand-over)."""
    rows = 0
    kw: dict[str, Any] = {"flush_rows": _WRITE_SLICE, "flush_s": math.inf} if by_rows else {}
    if by_rows:
        blocks = _sliced(blocks, _WRITE_SLICE)
    with contextlib.ExitStack() as stack:
        writer: LogWriter | None = None
        for block in blocks:
            if writer is None:
                writer = stack.enter_context(LogWriter(path, list(block), atomic=True, **kw))
            writer.write(block)
            rows += len(next(iter(block.values())))
    return rows


def _sliced(blocks: Iterable[Mapping[str, ArrayLike]], size: int) -> Iterator[dict[str, np.ndarray]]:
    """The rows of ``blocks`` again, in blocks of exactly ``size`` rows (the last shorter; blocks
    of no rows: the first of them, for the log's columns)."""
    held: list[dict[str, np.ndarray]] = []
    n_held = 0
    first: dict[str, np.ndarray] | None = None
    for block in blocks:
        b = {k: np.asarray(v) for k, v in block.items()}
        if first is None:
            first = b
        n = len(next(iter(b.values()), ()))
        i = 0
        while n - i >= size - n_held:
            take = size - n_held
            held.append({k: v[i : i + take] for k, v in b.items()})
            yield _joined_rows(held)
            held, n_held, i = [], 0, i + take
        if i < n:
            held.append({k: v[i:] for k, v in b.items()})
            n_held += n - i
    if held:
        yield _joined_rows(held)
    elif first is not None and not len(next(iter(first.values()), ())):
        yield first  # no rows at all: the header alone, as the blocks as they came


def _joined_rows(parts: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    return parts[0] if len(parts) == 1 else {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
