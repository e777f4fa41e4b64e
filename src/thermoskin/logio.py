"""Reading and writing logs in the shared schema (CSV with a header row).

Columns are named as in ``MODEL.md``: ``t`` (s), ``T_w, T_p, T_a`` (°C), ``v`` (m/s),
``q_i_hat`` (W), ``contact`` (0/1), ... One row per sample, uniform sampling.

:func:`read_log` checks the file and raises :class:`LogError` with a one-line message that
names the file, the line (1-based, the header is line 1), the column and the offending
value. ``nan``, ``NaN``, ``NA`` and an empty field are read as NaN in the temperature and
velocity columns (a loose thermocouple gives NaN bursts; the observer handles those);
elsewhere, and in ``t`` always, every value must be a finite number.

Speed: the data are parsed with ``np.loadtxt`` (C parser), a second time with empty and
``NA`` fields mapped to ``nan`` if the first try fails; only when both fail does a slow
row-by-row scan run, to locate the error.

:func:`write_log` writes atomically (temporary file in the same folder, then rename).
"""

from __future__ import annotations

import contextlib
import csv
import math
import os
import re
import tempfile
from collections import Counter
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]

DEFAULT_REQUIRED: tuple[str, ...] = ("t", "T_w", "T_p", "v", "T_a")
#: Columns written as integers by :func:`write_log` (when their values are integers).
FLAG_COLUMNS: frozenset[str] = frozenset({"contact", "gap", "contact_true", "n_fingers"})
#: Strings read as NaN in the columns that allow NaN.
NAN_STRINGS: frozenset[str] = frozenset({"nan", "NaN", "NA", ""})
#: Relative tolerance of the sample interval (uniform sampling check).
UNIFORM_RTOL = 0.01


class LogError(ValueError):
    """A user error in an input log (one-line message: file, line, column, value)."""


def nan_allowed(name: str) -> bool:
    """Default rule: NaN is allowed in temperature (``T_*``) and velocity (``v``, ``v_*``) columns."""
    return name.startswith("T_") or name == "v" or name.startswith("v_")


def sample_time(t: ArrayLike) -> float:
    """Median sample interval of the time vector ``t`` (s)."""
    tt = np.asarray(t, dtype=np.float64).ravel()
    if tt.size < 2:
        raise ValueError(f"sample_time needs at least 2 samples, got {tt.size}")
    return float(np.median(np.diff(tt)))


# --------------------------------------------------------------------------- reading


def _short(value: str, limit: int = 40) -> str:
    """Repr of a value, shortened so that the message stays one line."""
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 4] + "...'"


def _parse_value(raw: str, allow_nan: bool) -> float | str:
    """Parse one field; a ``str`` return is the reason it is invalid."""
    s = raw.strip()
    if allow_nan and s in NAN_STRINGS:
        return math.nan
    if not s:
        return "empty value"
    try:
        x = float(s)
    except ValueError:
        return "non-numeric value"
    if math.isnan(x):
        return "NaN value" if not allow_nan else x
    if math.isinf(x):
        return "infinite value"
    return x


def _read_text(path: Path) -> str:
    """The file's text (UTF-8, optional BOM), with the file-level checks."""
    if not path.exists():
        raise LogError(f"{path}: log file not found")
    if not path.is_file():
        raise LogError(f"{path}: not a regular file")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise LogError(f"{path}: cannot read: {exc.strerror or exc}") from exc
    if not data.strip():
        raise LogError(f"{path}: empty file")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        bad = data[exc.start : exc.start + 4]
        raise LogError(
            f"{path}: line {line}: not valid UTF-8 text (byte {exc.start}: {bad!r}); "
            "save the log as UTF-8 CSV"
        ) from exc


def _parse_header(path: Path, line: str) -> list[str]:
    """Column names from the header line, with the header checks."""
    try:
        names = [n.strip() for n in next(csv.reader([line]))]
    except (csv.Error, StopIteration) as exc:
        raise LogError(f"{path}: line 1: cannot parse the header row: {_short(line)}") from exc
    if all(_is_number(n) for n in names):
        raise LogError(f"{path}: line 1: no header row (first line looks like data: {_short(line)})")
    for k, n in enumerate(names, start=1):
        if not n:
            raise LogError(f"{path}: line 1: column {k} has an empty name (header {_short(line)})")
    dups = [n for n, c in Counter(names).items() if c > 1]
    if dups:
        raise LogError(f"{path}: line 1: duplicate column name(s): {', '.join(dups)}")
    return names


def _is_number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def _scan_rows(
    path: Path, lines: list[str], names: list[str], allow: list[bool], first_line: int = 2
) -> Array:
    """Slow row-by-row parse; raises LogError at the first bad row or value.

    ``first_line`` is the file line number of ``lines[0]`` (the header is line 1).
    """
    ncol = len(names)
    out = np.empty((len(lines), ncol), dtype=np.float64)
    for i, line in enumerate(lines):
        lineno = i + first_line
        try:
            fields = line.split(",") if '"' not in line else next(csv.reader([line]), [])
        except csv.Error as exc:
            raise LogError(f"{path}: line {lineno}: cannot parse the row ({exc}): {_short(line)}") from exc
        if len(fields) != ncol:
            what = "empty line" if not line.strip() else f"{len(fields)} fields"
            raise LogError(
                f"{path}: line {lineno}: {what}, expected {ncol} fields (as in the header): {_short(line)}"
            )
        for j, raw in enumerate(fields):
            x = _parse_value(raw, allow[j])
            if isinstance(x, str):
                nanlike = raw.strip() in NAN_STRINGS or x == "NaN value"
                hint = " (NaN is allowed only in temperature and velocity columns)" if nanlike else ""
                if names[j] == "t":
                    hint = " (t must be a finite number on every row)"
                raise LogError(f"{path}: line {lineno}, column {names[j]!r}: {x} {_short(raw)}{hint}")
            out[i, j] = x
    return out


def _loadtxt(lines: list[str], ncol: int) -> Array | None:
    try:
        arr = np.loadtxt(lines, delimiter=",", comments=None, dtype=np.float64, ndmin=2)
    except ValueError:
        return None
    return arr if arr.shape == (len(lines), ncol) else None


#: An empty or ``NA`` field (between commas / line ends), for the NaN-normalising pass.
_NA_FIELD = re.compile(r"(?m)(?<![^,\n])[ \t]*(?:NA)?[ \t]*(?![^,\n])")


def _fast_parse(lines: list[str], ncol: int) -> Array | None:
    """C-speed parse with ``np.loadtxt``; None if it fails or the shape is unexpected.

    A second try maps empty and ``NA`` fields to ``nan``; whether NaN is allowed in their
    column is checked afterwards (:func:`_check_finite`).
    """
    if any(not ln.strip() for ln in lines):  # loadtxt would skip blank lines silently
        return None
    arr = _loadtxt(lines, ncol)
    if arr is None:
        fixed = _NA_FIELD.sub("nan", "\n".join(lines)).split("\n")
        if len(fixed) == len(lines):
            arr = _loadtxt(fixed, ncol)
    return arr


def _check_finite(path: Path, arr: Array, lines: list[str], names: list[str], allow: list[bool]) -> None:
    """After the fast parse: NaN only where allowed, no inf anywhere."""
    for j, name in enumerate(names):
        col = arr[:, j]
        bad = ~np.isfinite(col)
        if allow[j]:
            bad &= ~np.isnan(col)
        if bad.any():
            i = int(np.argmax(bad))
            _scan_rows(path, lines[i : i + 1], names, allow, first_line=i + 2)  # raises the message
            raise LogError(
                f"{path}: line {i + 2}, column {name!r}: invalid value {float(col[i])!r}"
            )  # fallback


def _check_time(path: Path, t: Array) -> None:
    """``t`` strictly increasing and uniform within ``UNIFORM_RTOL`` of the median interval."""
    dt = np.diff(t)
    nonpos = dt <= 0
    if nonpos.any():
        k = int(np.argmax(nonpos))
        raise LogError(
            f"{path}: line {k + 3}, column 't': time not strictly increasing "
            f"(t = {float(t[k + 1])!r} after {float(t[k])!r} on line {k + 2})"
        )
    ts = float(np.median(dt))
    off = np.abs(dt - ts) > UNIFORM_RTOL * ts
    if off.any():
        k = int(np.argmax(off))
        raise LogError(
            f"{path}: line {k + 3}, column 't': non-uniform sampling: interval {dt[k]:.6g} s "
            f"(t = {float(t[k])!r} -> {float(t[k + 1])!r}), expected {ts:.6g} s ± {100 * UNIFORM_RTOL:g} %"
        )


def read_log(
    path: str | os.PathLike[str],
    required: Iterable[str] = DEFAULT_REQUIRED,
    nan_columns: Iterable[str] | None = None,
) -> dict[str, Array]:
    """Read a CSV log into ``{column: float64 array}`` (in the file's column order).

    ``t`` is always required (the time checks need it). ``nan_columns`` lists the columns
    where ``nan``/``NaN``/``NA``/empty are read as NaN; by default the temperature
    (``T_*``) and velocity (``v``) columns. Raises :class:`LogError` on any user error.
    """
    p = Path(path)
    text = _read_text(p)
    lines = text.splitlines()
    while lines and not lines[-1].strip():  # trailing blank lines are harmless
        lines.pop()
    if not lines:
        raise LogError(f"{p}: empty file")
    names = _parse_header(p, lines[0])
    body = lines[1:]

    req = list(dict.fromkeys(["t", *required]))
    missing = [n for n in req if n not in names]
    if missing:
        raise LogError(
            f"{p}: line 1: missing required column(s) {', '.join(missing)}; columns found: {', '.join(names)}"
        )
    if not body:
        raise LogError(f"{p}: no data rows (only the header on line 1)")

    nan_set = set(nan_columns) if nan_columns is not None else None
    allow = [(n != "t") and (n in nan_set if nan_set is not None else nan_allowed(n)) for n in names]
    arr = _fast_parse(body, len(names))
    if arr is None:  # locate the error: fast parse by chunks, slow scan of the failing chunk
        chunk = 2000
        parts = []
        for i in range(0, len(body), chunk):
            lines = body[i : i + chunk]
            part = _fast_parse(lines, len(names))
            parts.append(part if part is not None else _scan_rows(p, lines, names, allow, first_line=i + 2))
        arr = np.concatenate(parts, axis=0)
    _check_finite(p, arr, body, names, allow)

    if arr.shape[0] < 2:
        raise LogError(f"{p}: only {arr.shape[0]} data row (line 2); a log needs at least 2 samples")
    _check_time(p, arr[:, names.index("t")])
    return {n: np.ascontiguousarray(arr[:, j]) for j, n in enumerate(names)}


# --------------------------------------------------------------------------- writing


def _time_format(t: Array) -> str:
    """Fixed-point format with enough decimals to keep ``t`` uniform (>= 6 decimals)."""
    if t.size >= 2:
        dt = np.diff(t)
        dt = dt[np.isfinite(dt) & (dt > 0)]
        if dt.size:
            decimals = max(6, math.ceil(-math.log10(float(np.median(dt)))) + 4)
            return f"%.{min(decimals, 15)}f"
    return "%.6f"


def _is_integer_valued(x: Array) -> bool:
    return bool(np.all(np.isfinite(x)) and np.all(x == np.round(x)))


def write_log(
    path: str | os.PathLike[str],
    columns: Mapping[str, ArrayLike],
    float_format: str = "%.6g",
) -> Path:
    """Write ``columns`` as a CSV log (header + one row per sample); return the path.

    Flag columns (``contact``, ``gap``, ``contact_true``, ``n_fingers``) are written as
    integers, ``t`` in fixed point with enough decimals to stay uniform, the rest with
    ``float_format``. The parent folder is created if needed; the file is written to a
    temporary file in the same folder and renamed, so a crash never leaves half a log.
    """
    p = Path(path)
    if not columns:
        raise ValueError("write_log: no columns to write")
    names = list(columns)
    for n in names:
        if not n or any(c in n for c in ',"\r\n') or n != n.strip():
            raise ValueError(f"write_log: invalid column name {n!r}")
    arrays = [np.asarray(columns[n], dtype=np.float64) for n in names]
    for n, a in zip(names, arrays, strict=True):
        if a.ndim != 1:
            raise ValueError(f"write_log: column {n!r} is not 1-D (shape {a.shape})")
    lengths = {a.size for a in arrays}
    if len(lengths) != 1:
        sizes = ", ".join(f"{n}={a.size}" for n, a in zip(names, arrays, strict=True))
        raise ValueError(f"write_log: columns of different lengths: {sizes}")
    try:
        float_format % 1.0  # fail early on a bad format
    except (TypeError, ValueError) as exc:
        raise ValueError(f"write_log: bad float_format {float_format!r}: {exc}") from exc

    fmts = []
    for n, a in zip(names, arrays, strict=True):
        if n == "t":
            fmts.append(_time_format(a))
        elif n in FLAG_COLUMNS and _is_integer_valued(a):
            fmts.append("%d")
        else:
            fmts.append(float_format)
    row_fmt = ",".join(fmts) + "\n"
    data = np.column_stack(arrays).tolist() if arrays[0].size else []

    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as fh:
            fh.write(",".join(names) + "\n")
            chunk = 20_000
            for i in range(0, len(data), chunk):
                fh.write("".join([row_fmt % tuple(r) for r in data[i : i + chunk]]))
            fh.flush()
            os.fsync(fh.fileno())
        mode = p.stat().st_mode & 0o777 if p.exists() else 0o644
        os.chmod(tmp, mode)
        os.replace(tmp, p)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    return p
