"""Streaming log I/O: :class:`LogReader` yields chunks of float64 columns, :class:`LogWriter` appends.

Memory stays bounded by the chunk size whatever the log's length. The format follows the
file extension (``.csv`` or ``.parquet``, see :mod:`thermoskin.logio.csvlog` and
:mod:`thermoskin.logio.parquetlog`).
"""

from __future__ import annotations

import contextlib
import os
import tempfile
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from thermoskin.logio.common import (
    CHUNK_ROWS,
    DEFAULT_REQUIRED,
    UNIFORM_RTOL,
    Array,
    LogError,
    allow_nan,
    as_column,
    check_names,
    check_time,
    first_bad_value,
    log_format,
    missing_columns,
)
from thermoskin.logio.csvlog import CsvSource, parse_block, write_all, write_rows
from thermoskin.logio.parquetlog import ROW_GROUP_ROWS, ParquetSink, ParquetSource, bad_value_message
from thermoskin.logio.units import Units

#: A CSV writer hands its buffered rows to the OS after this many seconds or rows.
FLUSH_S = 1.0
FLUSH_ROWS = 65_536


def _check_file(p: Path) -> None:
    if not p.exists():
        raise LogError(f"{p}: log file not found")
    if not p.is_file():
        raise LogError(f"{p}: not a regular file")


class LogReader:
    """Read a log in chunks: iterating gives ``{column: float64 array}`` of about ``chunk_rows`` rows.

    The header (or Parquet schema) and the required columns (``t`` always) are checked on
    opening; every chunk is checked before it is given: values (NaN only in ``nan_columns``,
    by default the ``T_*`` and ``v`` columns; nothing infinite; in CSV every field a number,
    every row as many fields as the header), ``t`` strictly increasing across chunks and,
    with ``uniform``, every interval within ``UNIFORM_RTOL`` of the first chunk's median
    interval (:attr:`t_s`). A fault raises :class:`LogError` (one line: file, CSV line or
    Parquet row, column, value) when its chunk is reached. A log needs 2 rows at least.

    ``live=True`` reads a CSV that may still be being written (or whose writer was killed):
    a last line without its line end is left out instead of read as a cut row.
    ``one_patch=True``: a skin's long-format log (a ``patch`` column) is refused at once, in
    one line saying what it is (the single patch's commands read logs this way).
    ``rows_per_sample=P``: a skin's long format, each sample ``P`` rows (one per patch) of one
    ``t``: chunks hold whole samples, ``t`` is checked sample by sample, a row whose ``t`` is
    not its sample's and a last sample cut short are faults, and a log needs 2 samples.
    ``check(cols, row)``: the caller's own check of each chunk (``row``: the log's row of its
    first), run before the time's (a skin's patches out of order would otherwise show as a
    sample whose rows have different times). ``rtol``: the uniform sampling's tolerance.
    ``units``: the units of ``t`` and the ``T_*`` columns (:class:`~thermoskin.logio.units.Units`):
    each chunk is given in seconds and °C, and where a unit is not said, a first chunk that
    looks like another is refused with one line naming it; None: read as they are, unchecked.

    Attributes: ``names`` (column order of the file), ``n_rows`` (Parquet: from the footer;
    CSV: None until read to the end), ``rows`` (rows given so far), ``t_s`` (the first
    chunk's median interval, once it is read), ``format``. A reader is iterated once.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        required: Iterable[str] = DEFAULT_REQUIRED,
        nan_columns: Iterable[str] | None = None,
        *,
        uniform: bool = True,
        chunk_rows: int = CHUNK_ROWS,
        live: bool = False,
        one_patch: bool = False,
        rows_per_sample: int = 1,
        check: Callable[[list[Array], int], None] | None = None,
        rtol: float = UNIFORM_RTOL,
        units: Units | None = None,
    ) -> None:
        self.path = p = Path(path)
        self.format = log_format(p)
        if chunk_rows < 1:
            raise ValueError(f"LogReader: chunk_rows must be >= 1, got {chunk_rows}")
        if rows_per_sample < 1:
            raise ValueError(f"LogReader: rows_per_sample must be >= 1, got {rows_per_sample}")
        self.rows_per_sample = rows_per_sample
        self._check, self.rtol = check, rtol
        self.units = units
        _check_file(p)
        self.chunk_rows = chunk_rows
        self.uniform = uniform
        self.rows = 0
        self.t_s: float | None = None
        self._t_prev: float | None = None
        self._started = False
        self._src: CsvSource | ParquetSource
        try:
            self._src = CsvSource(p, live) if self.format == "csv" else ParquetSource(p)
        except OSError as exc:
            raise LogError(f"{p}: cannot read: {exc.strerror or exc}") from exc
        self.names: list[str] = self._src.names
        self.n_rows: int | None = self._src.n_rows
        try:
            missing_columns(p, self.names, required, "line 1: " if self.format == "csv" else "")
            if one_patch and "patch" in self.names:
                raise LogError(f"{p}: a skin's log (its 'patch' column: one row per sample and "
                               "patch), not one patch's: observe reads it with --skin LAYOUT.toml")
        except LogError:
            self.close()
            raise
        self._allow = allow_nan(self.names, nan_columns)
        self._it = self.names.index("t")

    # ------------------------------------------------------------------ iteration

    def __iter__(self) -> Iterator[dict[str, Array]]:
        if self._started:
            raise RuntimeError(f"LogReader({self.path}) can be iterated once; open a new one")
        self._started = True
        R = self.rows_per_sample
        pending: list[Array] | None = None  # a first chunk of one sample waits for the next
        for cols in self._chunks():
            if pending is not None:
                cols = [np.concatenate((a, b)) for a, b in zip(pending, cols, strict=True)]
                pending = None
            if self.rows < 2 * R:
                pending = cols
                continue
            yield dict(zip(self.names, cols, strict=True))
        if self.rows == 0:
            where = " (only the header on line 1)" if self.format == "csv" else ""
            raise LogError(f"{self.path}: no data rows{where}")
        if self.rows == R:
            where = " (line 2)" if self.format == "csv" and R == 1 else ""
            what = "data row" if R == 1 else f"sample ({R} rows)"
            raise LogError(f"{self.path}: only 1 {what}{where}; a log needs at least 2 samples")
        if self.n_rows is None:
            self.n_rows = self.rows

    def _where(self, k: int) -> str:
        """Place of the chunk's row ``k``: CSV file line or Parquet row (1-based)."""
        return self.place(self.rows + k)

    def place(self, row: int) -> str:
        """Place of the log's data row ``row`` (0-based): its CSV file line or Parquet row (1-based)."""
        return f"line {row + 2}" if self.format == "csv" else f"row {row + 1}"

    def _chunks(self) -> Iterator[list[Array]]:
        carry: list[Array] | None = None  # rows of a sample the chunk cut (rows_per_sample > 1)
        try:
            for cols in self._checked():
                if self.units is not None:
                    if self.rows == 0 and carry is None:
                        self.units.check(self.path, self.names, cols, self.rows_per_sample)
                    cols = self.units.convert(self.names, cols)
                if self.rows_per_sample > 1:
                    if carry is not None:
                        cols = [np.concatenate((a, b)) for a, b in zip(carry, cols, strict=True)]
                    whole = len(cols[0]) - len(cols[0]) % self.rows_per_sample
                    carry = [a[whole:] for a in cols]
                    cols = [a[:whole] for a in cols]
                if self._check is not None:
                    self._check(cols, self.rows)
                yield self._timed(cols)
        except OSError as exc:
            raise LogError(f"{self.path}: cannot read: {exc.strerror or exc}") from exc
        if carry is not None and len(carry[0]):
            R, r = self.rows_per_sample, len(carry[0])
            raise LogError(f"{self.path}: the last sample ({self._where(0)} on) has {r} of its {R} rows "
                           "(one per patch): the log is cut")

    def _checked(self) -> Iterator[list[Array]]:
        """The source's chunks, their values checked (the rows before them: ``self.rows`` plus
        a cut sample's rows carried, which only a skin's log has and which were checked)."""
        if isinstance(self._src, CsvSource):
            line = 2
            for block in self._src.blocks(self.chunk_rows):
                cols = parse_block(self.path, block, self.names, self._allow, line)
                line += len(cols[0])
                yield cols
        else:
            row = 0
            for cols, nulls in self._src.batches(self.chunk_rows):
                bad = first_bad_value(cols, self._allow)
                if bad is not None:
                    k, j = bad
                    null = nulls[j] is not None and bool(nulls[j][k])  # type: ignore[index]
                    raise LogError(bad_value_message(self.path, row + k, self.names[j], cols[j][k], null))
                row += len(cols[0])
                yield cols

    def _timed(self, cols: list[Array]) -> list[Array]:
        """Check the chunk's ``t`` against the previous chunk's; count its rows."""
        t = cols[self._it]
        R = self.rows_per_sample
        if R > 1:
            ts = t.reshape(-1, R)
            off = np.flatnonzero((ts != ts[:, :1]).any(axis=1))
            if off.size:
                k = int(off[0])
                j = int(np.flatnonzero(ts[k] != ts[k, 0])[0])
                got, own = float(ts[k, j]), float(ts[k, 0])
                raise LogError(f"{self.path}: {self._where(k * R + j)}, column 't': {got!r} where its "
                               f"sample's rows (one per patch) have t = {own!r}")
            t = ts[:, 0]
        fault = check_time(t, t_prev=self._t_prev, t_s=self.t_s, uniform=self.uniform, rtol=self.rtol)
        if fault is not None:
            k, reason = fault
            if reason.startswith("time not"):  # "(t = a after b)" -> "(t = a after b on line n)"
                reason = f"{reason[:-1]} on {self._where((k - 1) * R)})"
            raise LogError(f"{self.path}: {self._where(k * R)}, column 't': {reason}")
        if self.t_s is None and t.size + (self._t_prev is not None) >= 2:
            full = t if self._t_prev is None else np.concatenate(([self._t_prev], t))
            self.t_s = float(np.median(np.diff(full)))
        if t.size:
            self._t_prev = float(t[-1])
        self.rows += t.size * R
        return cols

    # ------------------------------------------------------------------ closing

    def close(self) -> None:
        self._src.close()

    def __enter__(self) -> LogReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class LogWriter:
    """Write a log chunk by chunk: ``write({column: array})`` appends rows, :meth:`close` ends it.

    CSV: the header is written on opening; rows are formatted (shortest round-trip floats,
    integers as integers) and handed to the OS in one ``write`` at least every ``flush_s``
    seconds (checked at each :meth:`write`) or ``flush_rows`` rows, so another process, or a
    reader after a crash (SIGKILL included), sees every row up to the last flush.
    ``flush_s=0`` hands every chunk over at once. Parquet: one row group per
    ``row_group_rows`` rows; the file is readable only once closed.

    ``atomic=True`` writes to a temporary file in the same folder, renamed to ``path`` by
    :meth:`close` (and removed if the ``with`` block raises): the log appears whole or not
    at all. Without it, the rows written so far are kept if the ``with`` block raises.
    ``fsync=True`` also syncs the file to disk on :meth:`close`.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        names: Iterable[str],
        *,
        atomic: bool = False,
        fsync: bool = False,
        flush_s: float = FLUSH_S,
        flush_rows: int = FLUSH_ROWS,
        row_group_rows: int = ROW_GROUP_ROWS,
    ) -> None:
        self.path = p = Path(path)
        self.format = log_format(p)
        self.names = list(names)
        check_names(self.names, "LogWriter")
        self.atomic, self.fsync = atomic, fsync
        self.flush_s, self.flush_rows = flush_s, flush_rows
        self.rows = 0
        self.closed = False
        p.parent.mkdir(parents=True, exist_ok=True)
        if atomic:
            fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=f".tmp{p.suffix}", dir=p.parent)
            self._target = Path(tmp)
        else:
            fd = os.open(p, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o666)
            self._target = p
        self._fd: int | None = fd
        self._buf: list[list[np.ndarray]] = []
        self._buffered = 0
        self._last_flush = time.monotonic()
        self._sink: ParquetSink | None = None
        try:
            if self.format == "csv":
                write_all(fd, (",".join(self.names) + "\n").encode())
            else:
                os.close(fd)
                self._fd = None
                self._sink = ParquetSink(self._target, self.names, row_group_rows)
        except BaseException:
            self._discard()
            raise

    def write(self, chunk: Mapping[str, ArrayLike]) -> None:
        """Append the rows of ``chunk`` (every column of the log, 1-D arrays of one length)."""
        if self.closed:
            raise ValueError(f"LogWriter({self.path}): write after close")
        if set(chunk) != set(self.names):
            missing = [n for n in self.names if n not in chunk]
            extra = [n for n in chunk if n not in self.names]
            raise ValueError(f"LogWriter.write: columns missing {missing}, unexpected {extra}")
        cols = []
        for n in self.names:
            a = np.asarray(chunk[n])
            a = as_column(a)
            if a.ndim != 1:
                raise ValueError(f"LogWriter.write: column {n!r} is not 1-D (shape {a.shape})")
            cols.append(a)
        if len({a.size for a in cols}) != 1:
            sizes = ", ".join(f"{n}={a.size}" for n, a in zip(self.names, cols, strict=True))
            raise ValueError(f"LogWriter.write: columns of different lengths: {sizes}")
        n_rows = cols[0].size
        if n_rows == 0:
            return
        self.rows += n_rows
        if self._sink is not None:
            with self._storage():
                self._sink.write(cols)
            return
        self._buf.append(cols)
        self._buffered += n_rows
        if self._buffered >= self.flush_rows or time.monotonic() - self._last_flush >= self.flush_s:
            self.flush()

    def flush(self) -> None:
        """Hand the buffered rows to the OS (CSV) or write them as a row group (Parquet)."""
        with self._storage():
            if self._sink is not None:
                self._sink.flush()
                return
            self._last_flush = time.monotonic()
            if not self._buffered or self._fd is None:
                return
            buf, self._buf, self._buffered = self._buf, [], 0
            cols = buf[0] if len(buf) == 1 else [np.concatenate(c) for c in zip(*buf, strict=True)]
            write_rows(self._fd, self.names, cols)

    @contextlib.contextmanager
    def _storage(self) -> Iterator[None]:
        """The file system's refusal (a full disk, a quota, a device gone) as one line naming the
        log (:class:`LogError`): what was flushed before stays."""
        try:
            yield
        except OSError as e:
            raise LogError(f"cannot write {self.path}: {e.strerror or e}") from None

    def close(self) -> Path:
        """Flush, close and (``atomic``) rename into place; returns the log's path."""
        if self.closed:
            return self.path
        try:
            with self._storage():
                if self._sink is not None:
                    self._sink.close()
                else:
                    self.flush()
                if self.fsync or self.atomic:
                    _fsync(self._target if self._fd is None else self._fd)
        except BaseException:
            self._discard()
            raise
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
        self.closed = True
        if self.atomic:
            mode = self.path.stat().st_mode & 0o777 if self.path.exists() else 0o644
            try:
                os.chmod(self._target, mode)
                os.replace(self._target, self.path)
            except BaseException:
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(self._target)
                raise
        return self.path

    def _discard(self) -> None:
        """Close without finishing; remove the temporary file of an atomic writer."""
        self.closed = True
        if self._sink is not None:
            with contextlib.suppress(Exception):
                self._sink.close()
        if self._fd is not None:
            with contextlib.suppress(OSError):
                os.close(self._fd)
            self._fd = None
        if self.atomic:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(self._target)

    def __enter__(self) -> LogWriter:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        if exc_type is not None and self.atomic:
            self._discard()
        else:
            self.close()


def _fsync(target: Any) -> None:
    if isinstance(target, int):
        os.fsync(target)
        return
    fd = os.open(target, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
