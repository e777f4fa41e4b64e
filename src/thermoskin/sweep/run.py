"""Running a sweep: chunks of points of one structure, here or on a Dask cluster, written as they finish.

Points are grouped by structure (``engine.structure``: samples and MPC horizon) and cut into
chunks of ``sweep.chunk`` points, in point order; each chunk is one batched simulation
(:func:`thermoskin.sweep.engine.run_chunk`), and one task on a cluster. A chunk's rows do
not depend on the chunk they were run in (rows are independent and every row's inputs come
from its own seed), so a Dask run, a resumed run and a straight run give the same rows.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from thermoskin.sweep import store
from thermoskin.sweep.engine import ScenarioSpec, run_chunk, structure
from thermoskin.sweep.spec import Point, Sweep


@dataclass
class SweepRun:
    """What a run did: points in the sweep, already done before, run now, rows written."""

    total: int
    skipped: int
    ran: int
    rows: int
    wall_s: float


def chunks(points: Sequence[Point], spec: ScenarioSpec, size: int) -> list[list[Point]]:
    """Points cut into chunks of ``size`` of one structure each, in point order."""
    groups: dict[Any, list[Point]] = {}
    for p in points:
        groups.setdefault(structure(p.cfg, spec), []).append(p)
    out = []
    for g in groups.values():
        out += [g[i:i + size] for i in range(0, len(g), size)]
    return out


def run_task(points: Sequence[Point], spec: ScenarioSpec, keys: Sequence[str]) -> list[dict[str, Any]]:
    """One chunk: its result rows (the task a Dask worker runs)."""
    metrics = run_chunk([(p.cfg, p.seed) for p in points], spec)
    rows = []
    for p, m in zip(points, metrics, strict=True):
        row: dict[str, Any] = {"point": p.index, "hash": p.hash, "seed": p.seed}
        row.update({k: p.values.get(k) for k in keys})
        row.update(m)
        rows.append(row)
    return rows


def _local(todo: list[list[Point]], spec: ScenarioSpec, keys: list[str]) -> Iterator[list[dict[str, Any]]]:
    for c in todo:
        yield run_task(c, spec, keys)


def _dask(todo: list[list[Point]], spec: ScenarioSpec, keys: list[str],
          address: str) -> Iterator[list[dict[str, Any]]]:
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError:
        from thermoskin.params import ConfigError

        raise ConfigError("--dask needs dask.distributed: pip install 'thermoskin[dask]'") from None
    # one worker process per core, each running its chunk's rows on one thread (numba's
    # threads on top of two processes would only contend for the two cores)
    cluster = LocalCluster(n_workers=os.cpu_count() or 1, threads_per_worker=1, processes=True,
                           dashboard_address=None, env={"NUMBA_NUM_THREADS": "1"}
                           ) if address == "local" else None
    try:
        try:
            client = Client(cluster if cluster is not None else address, timeout="20s")
        except (OSError, TimeoutError, ValueError, TypeError) as e:
            from thermoskin.params import ConfigError

            raise ConfigError(f"--dask {address}: cannot reach the scheduler: "
                              f"{' '.join(str(e).split()) or type(e).__name__}") from None
        with client:
            futures = [client.submit(run_task, c, spec, keys, pure=False) for c in todo]
            for fut in as_completed(futures):
                yield fut.result()
    finally:
        if cluster is not None:
            cluster.close()


def run_sweep(sw: Sweep, out: Path, *, dask: str | None = None,
              progress: Callable[[int, int], None] | None = None) -> SweepRun:
    """Run every point of ``sw`` not yet in ``out`` (or its parts), write them as they finish,
    merge; ``progress(done, total)`` after each chunk."""
    import time

    t0 = time.perf_counter()
    cols = sw.columns()
    store.check_columns(out, cols)
    done = store.done_hashes(out)
    store.check_points(out, done, {p.hash for p in sw.points})
    todo_pts = [p for p in sw.points if p.hash not in done]
    total = len(sw.points)
    skipped = total - len(todo_pts)
    todo = chunks(todo_pts, sw.scenario, sw.chunk)
    n_done = skipped
    if progress is not None:
        progress(n_done, total)
    it = _dask(todo, sw.scenario, sw.keys, dask) if dask else _local(todo, sw.scenario, sw.keys)
    for rows in it:
        for r in rows:
            r.update({k: (float(v) if isinstance(v, float) else v) for k, v in r.items()})
        store.write_part(out, rows, cols)
        n_done += len(rows)
        if progress is not None:
            progress(n_done, total)
    rows = store.merge(out, cols, {p.hash for p in sw.points})
    return SweepRun(total=total, skipped=skipped, ran=len(todo_pts), rows=rows,
                    wall_s=time.perf_counter() - t0)
