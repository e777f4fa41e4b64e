"""CSV logs: a header row, then one row per sample; read by blocks with polars (Arrow where it
refuses a block), written with polars.

Reading: the file is cut into blocks of whole lines (about ``chunk_rows`` rows each) and each
block is parsed by polars' CSV parser into float64 columns, or, where polars refuses the block
or finds a row short of fields, by Arrow's (strict: a row with too many or too few fields
fails; it also takes numbers with blanks around them, which polars does not). Polars comes
first because the writer needs it anyway: a CSV command then never imports pyarrow (0.1 s of
its start-up). A block that fails, or holds a NaN where none is allowed or an infinite value,
is parsed again in pieces of 2000 lines and, where a piece fails, line by line, to name the
file line, the column and the value at fault. Line numbers are file lines (the header is
line 1): every line of a block that passes is one row.

Writing: floats in their shortest round-trip form (polars' formatter), so reading the file
back gives the same float64 bit for bit; integer arrays, and flag columns whose values are
integers, as integers; NaN as ``NaN``. Each flush is one ``write`` of whole lines to the OS,
so another process reading the file sees whole rows up to the last flush, except when the
writer is killed inside that ``write``: then the last line may be cut, which
``LogReader(..., live=True)`` ignores.
"""

from __future__ import annotations

import csv
import os
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from thermoskin.logio.common import (
    FLAG_COLUMNS,
    MAX_COLUMNS,
    MAX_HEADER_BYTES,
    NAN_STRINGS,
    Array,
    LogError,
    arrow_float64,
    first_bad_value,
    is_number,
    listing,
    max_line_bytes,
    parse_value,
    short,
    writable,
)

#: Lines per piece when a failing block is parsed again to locate its error.
PIECE_LINES = 2000
_BOM = b"\xef\xbb\xbf"
_BLANK = b" \t\r\n"


# --------------------------------------------------------------------------- reading


def _utf8_error(path: Path, lineno: int, raw: bytes, exc: UnicodeDecodeError) -> LogError:
    bad = raw[exc.start : exc.start + 4]
    return LogError(
        f"{path}: line {lineno}: not valid UTF-8 text ({bad!r} at byte {exc.start + 1} of the line); "
        "save the log as UTF-8 CSV"
    )


def parse_header(path: Path, raw: bytes) -> list[str]:
    """Column names from the header line (bytes, BOM and line end included), with its checks."""
    if len(raw) > MAX_HEADER_BYTES:
        raise LogError(f"{path}: line 1: the header is longer than {MAX_HEADER_BYTES} bytes (at most "
                       f"{MAX_COLUMNS} columns): not a log")
    n_cols = raw.count(b",") + 1
    if n_cols > MAX_COLUMNS and b'"' not in raw:
        raise LogError(f"{path}: line 1: {n_cols} columns, more than a log may have ({MAX_COLUMNS})")
    try:
        line = raw.removeprefix(_BOM).decode("utf-8").rstrip("\r\n")
    except UnicodeDecodeError as exc:
        raise _utf8_error(path, 1, raw, exc) from exc
    try:
        names = [n.strip() for n in next(csv.reader([line]))]
    except (csv.Error, StopIteration) as exc:
        raise LogError(f"{path}: line 1: cannot parse the header row: {short(line)}") from exc
    if len(names) > MAX_COLUMNS:
        raise LogError(f"{path}: line 1: {len(names)} columns, more than a log may have ({MAX_COLUMNS})")
    if all(is_number(n) for n in names):
        raise LogError(f"{path}: line 1: no header row (first line looks like data: {short(line)})")
    for k, n in enumerate(names, start=1):
        if not n:
            raise LogError(f"{path}: line 1: column {k} has an empty name (header {short(line)})")
    dups = [n for n, c in Counter(names).items() if c > 1]
    if dups:
        raise LogError(f"{path}: line 1: duplicate column name(s): {listing(dups)}")
    return names


def _only_blanks(fh: BinaryIO) -> bool:
    """Whether the rest of the file is blank (whitespace only)."""
    while piece := fh.read(1 << 20):
        if piece.strip(_BLANK):
            return False
    return True


class CsvSource:
    """An open CSV log: header checked on opening, then :meth:`blocks` of whole lines."""

    def __init__(self, path: Path, live: bool) -> None:
        self.path = path
        self.live = live
        self._fh: BinaryIO = open(path, "rb")  # noqa: SIM115 (closed by close())
        try:
            header = self._fh.readline(MAX_HEADER_BYTES + 1)  # a line without end is not read whole
            if not header.strip(_BLANK) and _only_blanks(self._fh):
                raise LogError(f"{path}: empty file")
            if live and not header.endswith(b"\n") and len(header) <= MAX_HEADER_BYTES:
                raise LogError(f"{path}: no complete header line yet (live log still being started?)")
            self.names = parse_header(path, header)
        except BaseException:
            self._fh.close()
            raise
        self.n_rows: int | None = None
        #: The longest data line accepted (:func:`~thermoskin.logio.common.max_line_bytes`).
        self.max_line = max_line_bytes(len(self.names))
        self._line = 2  # the file line of the next block's first line

    def close(self) -> None:
        self._fh.close()

    def blocks(self, chunk_rows: int) -> Iterator[memoryview]:
        """Blocks of whole data lines, about ``chunk_rows`` lines each; trailing blank lines dropped.

        In ``live`` mode a last line without its line end (a write in progress) is left out.
        """
        size = max(1 << 16, chunk_rows * 48)  # bytes; then from the line length of each block
        rest = b""
        while True:
            piece = self._fh.read(size)
            buf = rest + piece if rest else piece
            if not piece:  # end of file
                stop = buf.rfind(b"\n") + 1 if self.live else len(buf)
                end = _content_end(buf, stop)
                if end:
                    yield memoryview(buf)[:end]
                return
            cut = buf.rfind(b"\n") + 1
            if cut == 0:  # a line longer than the block: read on, up to the longest a row may be
                if len(buf) > self.max_line:
                    raise self.too_long(self._line, len(buf))
                rest = buf
                continue
            # blank lines at the end are held back (if the file ends there, they are harmless)
            end = _content_end(buf, cut)
            end = buf.find(b"\n", end) + 1 if end else 0
            rest = buf[end:]
            if not end:
                continue
            if len(buf) - end > self.max_line:  # what is held back: blank lines, or a line too long
                raise self.too_long(self._line + buf.count(b"\n", 0, end), len(buf) - end)
            self._line += buf.count(b"\n", 0, end)
            yield memoryview(buf)[:end]
            sample = min(end, 1 << 20)  # the line length at the block's end sizes the next one
            lines = buf.count(b"\n", end - sample, end)
            size = max(1 << 16, int(chunk_rows * sample / max(lines, 1)))


    def too_long(self, line: int, n: int) -> LogError:
        """The error of a line of at least ``n`` bytes from file line ``line`` on."""
        return LogError(f"{self.path}: line {line}: a line of {n} bytes or more, longer than a row of "
                        f"{len(self.names)} numbers can be ({self.max_line} bytes at most): not a log row")


def _content_end(buf: bytes, stop: int) -> int:
    """Index just after the last non-blank byte of ``buf[:stop]`` (0 if all blank)."""
    tail = buf[max(0, stop - 4096) : stop].rstrip(_BLANK)
    if tail or stop <= 4096:
        return max(0, stop - 4096) + len(tail)
    return len(buf[:stop].rstrip(_BLANK))


def _fast_parse(block: bytes | memoryview, names: list[str]) -> list[Array] | None:
    """Float64 columns of a block (empty and ``NA`` fields as NaN); None if neither polars nor
    Arrow can parse it. Polars accepts a subset of what Arrow does, to the same values (the
    tests hold them to each other), but it fills a row short of fields with nulls, which a
    null in the last column alone reveals: such a block goes to Arrow, which fails on it."""
    cols = _polars_parse(block, names)
    return cols if cols is not None else _arrow_parse(block, names)


def _polars_parse(block: bytes | memoryview, names: list[str]) -> list[Array] | None:
    """:func:`_fast_parse` by polars; None if it refuses the block or the last column holds
    a null (an empty last field, or a row short of fields)."""
    import polars as pl

    try:
        df = pl.read_csv(bytes(block) if isinstance(block, memoryview) else block, has_header=False,
                         new_columns=names, schema=dict.fromkeys(names, pl.Float64),
                         null_values=["", "NA"], truncate_ragged_lines=False, raise_if_empty=False)
    except (pl.exceptions.PolarsError, ValueError):
        return None
    if df.height and df[names[-1]].null_count():
        return None
    return [writable(df[c].to_numpy()) for c in names]


def _arrow_parse(block: bytes | memoryview, names: list[str]) -> list[Array] | None:
    """Float64 columns of a block (empty and ``NA`` fields as NaN); None if Arrow cannot parse it."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    try:
        tab = pacsv.read_csv(
            pa.BufferReader(block),
            read_options=pacsv.ReadOptions(column_names=names, block_size=1 << 22),
            parse_options=pacsv.ParseOptions(ignore_empty_lines=False),
            convert_options=pacsv.ConvertOptions(
                column_types=dict.fromkeys(names, pa.float64()),
                null_values=["", "NA"],
                strings_can_be_null=False,
            ),
        )
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
        return None
    out = []
    for c in tab.columns:
        got = arrow_float64(c)
        out.append(got[0] if got is not None else writable(c.to_numpy()))
    return out


def _scan_lines(
    path: Path, lines: list[bytes], names: list[str], allow: list[bool], first_line: int
) -> Array:
    """Slow line-by-line parse (rows x columns); raises :class:`LogError` at the first bad line."""
    ncol = len(names)
    longest = max_line_bytes(ncol)
    out = np.empty((len(lines), ncol), dtype=np.float64)
    for i, raw in enumerate(lines):
        lineno = first_line + i
        if len(raw) > longest:  # not split into its fields (millions of them): refused as it is
            raise LogError(f"{path}: line {lineno}: a line of {len(raw)} bytes, longer than a row of {ncol} "
                           f"numbers can be ({longest} bytes at most): not a log row")
        try:
            line = raw.decode("utf-8").rstrip("\r")
        except UnicodeDecodeError as exc:
            raise _utf8_error(path, lineno, raw, exc) from exc
        try:
            fields = line.split(",") if '"' not in line else next(csv.reader([line]), [])
        except csv.Error as exc:
            raise LogError(f"{path}: line {lineno}: cannot parse the row ({exc}): {short(line)}") from exc
        if len(fields) != ncol:
            what = "empty line" if not line.strip() else f"{len(fields)} fields"
            raise LogError(
                f"{path}: line {lineno}: {what}, expected {ncol} fields (as in the header): {short(line)}"
            )
        for j, field in enumerate(fields):
            x = parse_value(field, allow[j])
            if isinstance(x, str):
                nanlike = field.strip() in NAN_STRINGS or x == "NaN value"
                hint = " (NaN is allowed only in temperature and velocity columns)" if nanlike else ""
                if names[j] == "t":
                    hint = " (t must be a finite number on every row)"
                raise LogError(f"{path}: line {lineno}, column {names[j]!r}: {x} {short(field)}{hint}")
            out[i, j] = x
    return out


def _checked_piece(
    path: Path, lines: list[bytes], names: list[str], allow: list[bool], first_line: int
) -> list[Array]:
    """Parse a list of lines, fast if it can, and check the values; raises at the first bad line."""
    cols = None if any(not ln.strip(_BLANK) for ln in lines) else _fast_parse(b"\n".join(lines), names)
    if cols is None or len(cols[0]) != len(lines):
        arr = _scan_lines(path, lines, names, allow, first_line)
        return [np.ascontiguousarray(arr[:, j]) for j in range(len(names))]
    bad = first_bad_value(cols, allow)
    if bad is not None:
        k = bad[0]
        _scan_lines(path, lines[k : k + 1], names, allow, first_line + k)  # raises with the message
        raise LogError(f"{path}: line {first_line + k}: invalid value")  # not reached
    return cols


def parse_block(
    path: Path, block: bytes | memoryview, names: list[str], allow: list[bool], first_line: int
) -> list[Array]:
    """Float64 columns of a block of lines starting at file line ``first_line``, values checked.

    NaN only where ``allow``, nothing infinite; else :class:`LogError` naming line, column, value.
    """
    cols = _fast_parse(block, names)
    if cols is not None and first_bad_value(cols, allow) is None:
        return cols
    lines = bytes(block).split(b"\n")
    if lines and not lines[-1].strip(_BLANK):
        lines.pop()
    parts = [
        _checked_piece(path, lines[i : i + PIECE_LINES], names, allow, first_line + i)
        for i in range(0, len(lines), PIECE_LINES)
    ]
    return [np.concatenate([p[j] for p in parts]) for j in range(len(names))]


# --------------------------------------------------------------------------- writing


def _integral(a: np.ndarray) -> np.ndarray | None:
    """``a`` as int64 if every value is an integer (no NaN), else None."""
    with np.errstate(invalid="ignore"):
        ai = a.astype(np.int64)
    return ai if np.array_equal(ai, a) else None


def write_rows(fd: int, names: list[str], cols: list[np.ndarray]) -> None:
    """Append CSV lines (no header) of the columns to ``fd``: shortest round-trip floats,
    integers as integers. polars formats straight into the file (no copy of the text)."""
    import polars as pl

    data: dict[str, Any] = {}
    for n, a in zip(names, cols, strict=True):
        out = a
        if a.dtype.kind == "f" and n in FLAG_COLUMNS:
            ai = _integral(a)
            out = a if ai is None else ai
        elif a.dtype.kind == "b":
            out = a.astype(np.int8)
        data[n] = out
    with os.fdopen(fd, "wb", buffering=0, closefd=False) as fh:
        pl.DataFrame(data).write_csv(fh, include_header=False, line_terminator="\n")


def write_all(fd: int, data: bytes) -> None:
    """``os.write`` until every byte is handed to the OS."""
    view = memoryview(data)
    while view:
        n = os.write(fd, view)
        view = view[n:]
