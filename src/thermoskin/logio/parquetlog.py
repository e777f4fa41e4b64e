"""Parquet logs (pyarrow): one float64 column per signal, in row groups.

A Parquet file is readable only once its writer has closed it (the footer, written last,
holds the schema and the row groups' places): a run killed while writing leaves a file that
:class:`ParquetSource` refuses with a one-line :class:`LogError`. Write CSV when the log must
be readable while it grows or after a crash. Errors in a Parquet log name the data row
(1-based), there being no text lines.

Columns are written as float64 (flags too: exact for integers up to 2**53, and Parquet's
dictionary and run-length encodings store them compactly), but for :data:`INTEGER_COLUMNS`
(a skin's ``patch``: an index, int64 in the file's schema); reading accepts any integer,
float or boolean column, and reads a null as NaN where NaN is allowed.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from thermoskin.logio.common import MAX_COLUMNS, Array, LogError, arrow_float64, listing, short, writable

#: Rows per row group (8 columns: 16 MiB before compression).
ROW_GROUP_ROWS = 262_144
#: Encoding, chosen per column on a sample of the first row group (:func:`few_values`): a
#: dictionary for the columns of few values (flags, set-points, a thermocouple's 1/64 K steps),
#: given up after 64 KiB of dictionary (8192 distinct values, then plain values); the others
#: (time, estimates) byte-stream-split, where a dictionary tried first would cost its encoding
#: and then fall back to plain values (the 1 h benchmark's observe output: written in 0.52 s
#: instead of 0.62 s, 51 MiB instead of 63); zstd over all.
DICTIONARY_PAGE_BYTES = 1 << 16
COMPRESSION = "zstd"
#: The sample of a column's first row group that :func:`few_values` counts, and how many
#: distinct values in it still make a dictionary worth trying.
SAMPLE_ROWS = 4096
FEW_VALUES = 1024


def few_values(col: np.ndarray) -> bool:
    """Whether ``col`` (a column's first row group) has few distinct values, counted in
    :data:`SAMPLE_ROWS` rows spread over it (NaN one value)."""
    sample = col[::max(1, len(col) // SAMPLE_ROWS)]
    return len(np.unique(sample)) <= FEW_VALUES


def _arrow_errors() -> tuple[type[BaseException], ...]:
    import pyarrow as pa

    return (pa.ArrowException, OSError)


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


class ParquetSource:
    """An open Parquet log: schema checked on opening, then :meth:`batches` of float64 columns."""

    def __init__(self, path: Path) -> None:
        import pyarrow.parquet as pq

        from thermoskin.atomic import arrow_name

        self.path = path
        name = arrow_name(path)
        self._fh = None if name is not None else open(path, "rb")  # noqa: SIM115 (closed by close())
        try:
            # pre_buffer (pyarrow's default) keeps every row group read so far: memory would
            # grow with the log's length
            self._file = pq.ParquetFile(name if name is not None else self._fh, pre_buffer=False,
                                        buffer_size=1 << 20)
            schema = self._file.schema_arrow
        except _arrow_errors() as exc:
            if self._fh is not None:
                self._fh.close()
            raise LogError(
                f"{path}: not a readable Parquet file ({_first_line(exc)}); "
                "a Parquet log is readable only once its writer has closed it"
            ) from exc
        self.names: list[str] = list(schema.names)
        self.n_rows: int | None = self._file.metadata.num_rows
        try:
            self._check_schema(schema)
        except LogError:
            self.close()
            raise

    def _check_schema(self, schema: Any) -> None:
        import pyarrow as pa

        path = self.path
        if not self.names:
            raise LogError(f"{path}: empty file (no columns)")
        if len(self.names) > MAX_COLUMNS:
            raise LogError(f"{path}: {len(self.names)} columns, more than a log may have ({MAX_COLUMNS})")
        dups = [n for n, c in Counter(self.names).items() if c > 1]
        if dups:
            raise LogError(f"{path}: duplicate column name(s): {listing(dups)}")
        for field in schema:
            ty = field.type
            if not (pa.types.is_integer(ty) or pa.types.is_floating(ty) or pa.types.is_boolean(ty)):
                raise LogError(f"{path}: column {short(field.name)} has type {short(str(ty), 60)[1:-1]}, "
                               "expected numbers")

    def close(self) -> None:
        self._file.close()
        if self._fh is not None:
            self._fh.close()

    def batches(self, chunk_rows: int) -> Iterator[tuple[list[Array], list[np.ndarray | None]]]:
        """Float64 columns (nulls as NaN) per batch, with each column's null mask (None if no null)."""
        import pyarrow as pa

        try:
            for batch in self._file.iter_batches(batch_size=chunk_rows, use_threads=True):
                cols: list[Array] = []
                nulls: list[np.ndarray | None] = []
                for col in batch.columns:
                    got = arrow_float64(col)
                    if got is None:  # another type: Arrow's own cast (slow to import)
                        import pyarrow.compute as pc

                        f = pc.cast(col, pa.float64())
                        nulls.append(col.is_null().to_numpy(zero_copy_only=False) if col.null_count
                                     else None)
                        cols.append(writable(f.to_numpy(zero_copy_only=False)))
                    else:
                        cols.append(got[0])
                        nulls.append(got[1])
                yield cols, nulls
        except _arrow_errors() as exc:
            raise LogError(f"{self.path}: cannot read the Parquet data ({_first_line(exc)})") from exc


def bad_value_message(path: Path, row: int, name: str, value: float, is_null: bool) -> str:
    """One-line message for a bad value at 0-based data ``row`` of a Parquet log."""
    if is_null:
        what = "null value"
    elif np.isnan(value):
        what = "NaN value"
    else:
        what = f"infinite value {short(float(value))}"
    hint = " (t must be a finite number on every row)" if name == "t" else (
        "" if what.startswith("infinite") else " (NaN is allowed only in temperature and velocity columns)"
    )
    return f"{path}: row {row + 1}, column {name!r}: {what}{hint}"


#: Columns written as int64: a skin's long-format log's patch index.
INTEGER_COLUMNS = frozenset({"patch"})


def _arrow_type(name: str) -> Any:
    import pyarrow as pa

    return pa.int64() if name in INTEGER_COLUMNS else pa.float64()


def _as_stored(name: str, a: Any) -> np.ndarray:
    """A chunk of column ``name`` as its stored dtype (an integer column's values checked whole)."""
    if name not in INTEGER_COLUMNS:
        return np.asarray(a, dtype=np.float64)
    x = np.asarray(a)
    if x.dtype.kind in "iub":
        return x.astype(np.int64, copy=False)
    out = x.astype(np.int64)
    if not np.array_equal(out, x):
        raise ValueError(f"column {name!r} holds a value that is not a whole number")
    return out


class ParquetSink:
    """Appends chunks to a Parquet file, one row group per ``row_group_rows`` rows."""

    def __init__(self, path: Path, names: list[str], row_group_rows: int = ROW_GROUP_ROWS) -> None:
        import pyarrow as pa

        self.path = path
        self.names = names
        self.row_group_rows = row_group_rows
        self._schema = pa.schema([(n, _arrow_type(n)) for n in names])
        self._writer: Any = None  # opened with the first row group, its encodings chosen on it
        self._fh: Any = None
        self._buf: list[list[np.ndarray]] = []
        self._rows = 0

    def _open(self, first: list[np.ndarray] | None) -> Any:
        import pyarrow.parquet as pq

        from thermoskin.atomic import arrow_name

        few = [n for n, c in zip(self.names, first, strict=True) if few_values(c)] if first else self.names
        name = arrow_name(self.path)
        if name is None:  # a name pyarrow cannot take (module doc of thermoskin.atomic)
            self._fh = open(self.path, "wb")  # noqa: SIM115 (closed by close())
        return pq.ParquetWriter(
            name if name is not None else self._fh, self._schema, compression=COMPRESSION, use_dictionary=few,
            use_byte_stream_split=[n for n in self.names if n not in few],
            dictionary_pagesize_limit=DICTIONARY_PAGE_BYTES,
        )

    def write(self, cols: list[np.ndarray]) -> None:
        self._buf.append([_as_stored(n, a) for n, a in zip(self.names, cols, strict=True)])
        self._rows += len(cols[0])
        if self._rows >= self.row_group_rows:
            self.flush()

    def flush(self) -> None:
        """Write the buffered rows as one row group (not readable before :meth:`close`)."""
        import pyarrow as pa

        if not self._rows:
            return
        cols = [np.concatenate([c[j] for c in self._buf]) for j in range(len(self.names))]
        self._buf, self._rows = [], 0
        # zero-copy views of the buffers (``pa.array`` would import pandas to check for it)
        n = len(cols[0])
        arrays = [pa.Array.from_buffers(_arrow_type(name), n, [None, pa.py_buffer(np.ascontiguousarray(c))])
                  for name, c in zip(self.names, cols, strict=True)]
        table = pa.Table.from_arrays(arrays, schema=self._schema)
        if self._writer is None:
            self._writer = self._open(cols)
        self._writer.write_table(table, row_group_size=len(cols[0]))

    def close(self) -> None:
        self.flush()
        if self._writer is None:  # no row: the schema alone
            self._writer = self._open(None)
        try:
            self._writer.close()
        finally:
            if self._fh is not None:
                self._fh.close()
