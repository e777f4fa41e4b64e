"""The results of a sweep on disk: a directory of Parquet parts as chunks finish, merged at the end.

``RESULTS.parquet`` is written last, whole (a temporary file renamed over it). While the
sweep runs, each finished chunk is one part, ``RESULTS.parquet.parts/part-<hash>.parquet``,
also written to a temporary name and renamed: a kill leaves whole parts only. A rerun
reads the point hashes already in ``RESULTS.parquet`` and in the parts and skips them;
the merge sorts the rows by point index and removes the parts.
"""

from __future__ import annotations

import hashlib
import shutil
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from thermoskin.atomic import arrow_target, atomic_path


def parts_dir(out: Path) -> Path:
    """Where the parts of ``out`` go."""
    return out.with_name(out.name + ".parts")


def check_columns(out: Path, columns: Sequence[str]) -> None:
    """Refuse (one-line ``SweepError``) an ``out`` or parts holding other columns than this
    sweep's (another sweep, other metrics): resuming into them would mix or lose rows."""
    from thermoskin.sweep.spec import SweepError

    d = parts_dir(out)
    files = ([out] if out.is_file() else []) + (sorted(d.glob("part-*.parquet")) if d.is_dir() else [])
    for f in files:
        try:
            with arrow_target(f) as src:
                names = pq.read_schema(src).names
        except (pa.ArrowInvalid, OSError):
            raise SweepError(f"-o {out}: {f} exists and is not a Parquet file; choose another "
                             "output or remove it") from None
        if list(names) != list(columns):
            raise SweepError(f"-o {out}: {f} holds other columns than this sweep's (another sweep "
                             "or other metrics); choose another output or remove it")


def done_hashes(out: Path) -> set[str]:
    """The points already written (in ``out`` or its parts)."""
    done: set[str] = set()
    files = [out] if out.is_file() else []
    d = parts_dir(out)
    if d.is_dir():
        files += sorted(d.glob("part-*.parquet"))
    for f in files:
        try:
            with arrow_target(f) as src:
                done.update(pq.read_table(src, columns=["hash"]).column("hash").to_pylist())
        except (pa.ArrowInvalid, OSError, KeyError):
            continue  # not a result file of ours: it is rewritten at the merge
    return done


def check_points(out: Path, done: set[str], points: set[str]) -> None:
    """Refuse (one-line ``SweepError``) an ``out`` or parts holding points (``done``, from
    :func:`done_hashes`) that are not this sweep's (another sweep with the same columns, or
    this one edited): the merge keeps only this sweep's points, so theirs would be lost."""
    from thermoskin.sweep.spec import SweepError

    other = done - points
    if other:
        raise SweepError(f"-o {out}: holds {len(other)} point(s) that are not in this sweep (another "
                         "sweep's, or this one's before an edit), which its merge would drop; choose "
                         "another output or move that one away")


def _table(rows: Sequence[dict[str, Any]], columns: Sequence[str]) -> pa.Table:
    return pa.table({c: [r.get(c) for r in rows] for c in columns})


def _write_atomic(table: pa.Table, path: Path) -> None:
    with atomic_path(path) as tmp, arrow_target(tmp, "wb") as f:
        pq.write_table(table, f)


def write_part(out: Path, rows: Sequence[dict[str, Any]], columns: Sequence[str]) -> Path:
    """One finished chunk as a part (named by its points' hashes)."""
    d = parts_dir(out)
    d.mkdir(parents=True, exist_ok=True)
    name = hashlib.sha256("".join(r["hash"] for r in rows).encode()).hexdigest()[:16]
    path = d / f"part-{name}.parquet"
    _write_atomic(_table(rows, columns), path)
    return path


def merge(out: Path, columns: Sequence[str], keep: set[str]) -> int:
    """``out`` from itself and its parts: the rows of the points in ``keep``, by point index,
    each once; the parts removed. Returns the row count."""
    tables = []
    d = parts_dir(out)
    files = ([out] if out.is_file() else []) + (sorted(d.glob("part-*.parquet")) if d.is_dir() else [])
    for f in files:
        try:
            with arrow_target(f) as src:
                t = pq.read_table(src)
        except (pa.ArrowInvalid, OSError):
            continue
        if list(t.column_names) == list(columns):
            tables.append(t)
    if tables:
        t = pa.concat_tables(tables, promote_options="permissive")
        rows = {}
        for r in t.to_pylist():
            if r["hash"] in keep:
                rows.setdefault(r["hash"], r)
        ordered = sorted(rows.values(), key=lambda r: r["point"])
    else:
        ordered = []
    _write_atomic(_table(ordered, columns), out)
    if d.is_dir():
        shutil.rmtree(d, ignore_errors=True)
    return len(ordered)
