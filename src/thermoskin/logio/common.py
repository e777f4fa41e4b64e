"""What every log format shares: the error type, the column rules, the value and time checks.

No heavy import here (``LogError`` is imported by the CLI at start-up).
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]

DEFAULT_REQUIRED: tuple[str, ...] = ("t", "T_w", "T_p", "v", "T_a")
#: Columns written as integers (in CSV) when their values are integers.
FLAG_COLUMNS: frozenset[str] = frozenset(
    {"contact", "gap", "contact_true", "n_fingers", "fresh", "sign", "patch", "toucher_true",
     "material_true"}
)
#: Strings read as NaN in the columns that allow NaN (CSV).
NAN_STRINGS: frozenset[str] = frozenset({"nan", "NaN", "NA", ""})
#: Relative tolerance of the sample interval (uniform sampling check).
UNIFORM_RTOL = 0.01
#: Rows per chunk of the streaming reader (about; CSV chunks follow the line length).
CHUNK_ROWS = 262_144
#: Log formats by file extension.
FORMATS: dict[str, str] = {".csv": "csv", ".parquet": "parquet"}
#: Most columns a log may have (a log of this project has a few dozen; an export of a recording,
#: every topic's fields: about 60). More is refused before the names are read.
MAX_COLUMNS = 4096
#: Longest CSV header line, bytes (4096 names of 256 characters).
MAX_HEADER_BYTES = 1 << 20
#: Bytes a CSV field may take on a row: a float64 in its shortest form takes 24 at most, with
#: its comma 25; five times that for blanks, quotes and other writers' forms.
FIELD_BYTES = 128
#: Shortest line-length limit, bytes.
MIN_LINE_BYTES = 1 << 16


def max_line_bytes(n_columns: int) -> int:
    """The longest data line a CSV log of ``n_columns`` columns may have (bytes): five times what
    its numbers take written in full, at least :data:`MIN_LINE_BYTES`. A longer line is refused
    before it is split into fields, so memory before that error stays within a small multiple
    of a row's size (a 40 MB row took 7 GB before its error, and a minute)."""
    return max(MIN_LINE_BYTES, FIELD_BYTES * n_columns)


class LogError(ValueError):
    """A user error in a log (one-line message: file, line or row, column, value)."""


def log_format(path: str | os.PathLike[str]) -> str:
    """``"csv"`` or ``"parquet"`` from the file extension; :class:`LogError` otherwise."""
    p = Path(path)
    fmt = FORMATS.get(p.suffix.lower())
    if fmt is None:
        what = f"extension {p.suffix!r}" if p.suffix else "no extension"
        hint = (" (an MCAP recording: `thermoskin export` makes a log of it, `thermoskin replay` "
                "estimates from it)") if p.suffix.lower() == ".mcap" else ""
        raise LogError(f"{p}: unknown log format ({what}); the file name must end in .csv or .parquet"
                       + hint)
    return fmt


def nan_allowed(name: str) -> bool:
    """Default rule: NaN is allowed in temperature (``T_*``) and velocity (``v``, ``v_*``) columns."""
    return name.startswith("T_") or name == "v" or name.startswith("v_")


def allow_nan(names: list[str], nan_columns: object = None) -> list[bool]:
    """Per column, whether NaN is allowed: ``nan_columns`` if given (the names, or a rule taking a
    name), else :func:`nan_allowed`; never ``t``."""
    if callable(nan_columns):
        return [(n != "t") and bool(nan_columns(n)) for n in names]
    nan_set = set(nan_columns) if nan_columns is not None else None  # type: ignore[call-overload]
    return [(n != "t") and (n in nan_set if nan_set is not None else nan_allowed(n)) for n in names]


def check_names(names: list[str], where: str) -> None:
    """Column names a CSV header can hold: non-empty, no comma, quote or line break, no outer blanks."""
    if not names:
        raise ValueError(f"{where}: no columns to write")
    for n in names:
        if not isinstance(n, str) or not n or any(c in n for c in ',"\r\n') or n != n.strip():
            raise ValueError(f"{where}: invalid column name {n!r}")
    if len(set(names)) != len(names):
        raise ValueError(f"{where}: duplicate column names in {names}")


def missing_columns(path: Path, names: list[str], required: object, where: str) -> None:
    """Raise :class:`LogError` if a required column (``t`` always) is missing."""
    req = list(dict.fromkeys(["t", *required]))  # type: ignore[misc]
    have = set(names)
    missing = [n for n in req if n not in have]
    if missing:
        raise LogError(
            f"{path}: {where}missing required column(s) {listing(missing)}; "
            f"columns found: {listing(names)}"
        )


def short(value: object, limit: int = 40) -> str:
    """Repr of a value, shortened so that the message stays one line."""
    if isinstance(value, str | bytes) and len(value) > 4 * limit:
        value = value[: 4 * limit]  # a huge field: only its start is ever shown
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 4] + "...'"


def listing(names: list[str], limit: int = 12) -> str:
    """``names`` joined by commas, at most ``limit`` of them (each shortened) and how many more."""
    shown = [n if len(n) <= 40 else n[:36] + "..." for n in names[:limit]]
    more = f" and {len(names) - limit} more" if len(names) > limit else ""
    return ", ".join(shown) + more


def first_bad_value(cols: list[Array], allow: list[bool]) -> tuple[int, int] | None:
    """``(row, column)`` of the first NaN where not allowed or infinite value, in reading order; or None."""
    first: tuple[int, int] | None = None
    for j, (a, ok_nan) in enumerate(zip(cols, allow, strict=True)):
        bad = np.isinf(a) if ok_nan else ~np.isfinite(a)
        if bad.any():
            k = int(np.argmax(bad))
            if first is None or k < first[0]:
                first = (k, j)
    return first


def as_column(a: np.ndarray) -> np.ndarray:
    """A column as written: booleans kept, integers as int64, anything else as float64 (native order)."""
    if a.dtype.kind == "b":
        return a
    return a.astype(np.int64 if a.dtype.kind in "iu" else np.float64, copy=False)


#: Arrow's numeric types read straight from their buffers (no pandas import, no copy but one).
_NUMERIC = {"double": np.float64, "float": np.float32, "int64": np.int64, "int32": np.int32,
            "int16": np.int16, "int8": np.int8, "uint64": np.uint64, "uint32": np.uint32,
            "uint16": np.uint16, "uint8": np.uint8}


def arrow_float64(col: Any) -> tuple[Array, np.ndarray | None] | None:
    """An Arrow numeric column as float64 (nulls as NaN) and its null mask (None if none),
    read from its buffers; None for a type it does not know (the caller converts those).

    pyarrow's own ``to_numpy`` and ``cast`` import pandas (0.2 s), which a start-up-sensitive
    command cannot afford.
    """
    import pyarrow as pa

    arr = col.combine_chunks() if isinstance(col, pa.ChunkedArray) else col
    dtype = _NUMERIC.get(str(arr.type))
    if dtype is None:
        return None
    n, off = len(arr), arr.offset
    bufs = arr.buffers()
    if n == 0:
        return np.zeros(0), None
    vals = np.frombuffer(bufs[1], dtype=dtype, count=n, offset=off * np.dtype(dtype).itemsize)
    out = np.array(vals, dtype=np.float64)
    nulls = None
    if arr.null_count:
        bits = np.unpackbits(np.frombuffer(bufs[0], dtype=np.uint8), bitorder="little")
        nulls = ~bits[off:off + n].astype(bool)
        out[nulls] = np.nan
    return out, nulls


def writable(a: Array) -> Array:
    """``a``, or a copy of it if read-only (Arrow's zero-copy views are)."""
    return a if a.flags.writeable and a.flags.c_contiguous else np.array(a, dtype=np.float64)


def sample_time(t: ArrayLike) -> float:
    """Median sample interval of the time vector ``t`` (s)."""
    tt = np.asarray(t, dtype=np.float64).ravel()
    if tt.size < 2:
        raise ValueError(f"sample_time needs at least 2 samples, got {tt.size}")
    return float(np.median(np.diff(tt)))


def check_time(
    t: ArrayLike,
    *,
    t_prev: float | None = None,
    t_s: float | None = None,
    uniform: bool = True,
    rtol: float = UNIFORM_RTOL,
) -> tuple[int, str] | None:
    """First fault of the time vector ``t``, as ``(k, reason)``, or None.

    ``t`` must increase strictly; with ``uniform``, every interval must be within ``rtol`` of
    ``t_s`` (default: the median of the positive intervals). The fault met first in time
    is reported. ``t_prev`` is the sample
    before ``t[0]`` (the previous chunk's last), so a chunked log is checked across its
    boundaries. ``k`` indexes ``t``: the interval ending at ``t[k]`` is at fault.
    """
    tt = np.asarray(t, dtype=np.float64).ravel()
    full = tt if t_prev is None else np.concatenate(([t_prev], tt))
    off = 0 if t_prev is None else 1
    dt = np.diff(full)
    nonpos = ~(dt > 0)
    i_np = int(np.argmax(nonpos)) if nonpos.any() else dt.size
    i_nu = dt.size
    if uniform and dt.size:
        pos = dt[dt > 0]
        ts = t_s if t_s is not None else float(np.median(pos)) if pos.size else 1.0
        off_rate = np.abs(dt[:i_np] - ts) > rtol * ts  # the first fault in time order is reported
        if off_rate.any():
            i_nu = int(np.argmax(off_rate))
    if i_nu < i_np:
        t0, t1 = float(full[i_nu]), float(full[i_nu + 1])
        return i_nu + 1 - off, (
            f"non-uniform sampling: interval {dt[i_nu]:.6g} s (t = {t0!r} -> {t1!r}), "
            f"expected {ts:.6g} s ± {100 * rtol:g} % (read with uniform=False to accept jitter)"
        )
    if i_np < dt.size:
        t0, t1 = float(full[i_np]), float(full[i_np + 1])
        return i_np + 1 - off, f"time not strictly increasing (t = {t1!r} after {t0!r})"
    return None


def parse_value(raw: str, allow_nan: bool) -> float | str:
    """Parse one CSV field; a ``str`` return is the reason it is invalid."""
    s = raw.strip()
    if allow_nan and s in NAN_STRINGS:
        return math.nan
    if not s:
        return "empty value"
    if "_" in s:  # float() takes 1_000, the fast parser does not
        return "non-numeric value"
    try:
        x = float(s)
    except ValueError:
        return "non-numeric value"
    if math.isnan(x):
        return "NaN value" if not allow_nan else x
    if math.isinf(x):
        return "infinite value"
    return x


def is_number(s: str) -> bool:
    """Whether ``s`` reads as a float."""
    try:
        float(s)
    except ValueError:
        return False
    return True
