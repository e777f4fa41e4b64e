"""Benchmark: streaming log I/O (thermoskin.logio) against polars alone, CSV and Parquet.

On a generated log (default 1 h at 1 kHz: 3.6 M rows of t,T_w,T_p,v,T_a,T_w_cmd; the
temperatures in 1/64 K steps, as the thermocouple converters give them), each run reads the
log and writes it again with two more float columns (``q_i_hat = (T_w - T_p)/0.19``,
``dq_i_hat = q_i_hat - 3.6``, full-precision values):

- ``peer``: polars alone, the whole log in memory (``read_csv``/``read_parquet``,
  ``with_columns``, ``write_csv``/``write_parquet``);
- ``ours``: ``LogReader`` -> ``LogWriter``, chunk by chunk, every check on (values, t
  strictly increasing, uniform sampling).

Each run is a fresh process: wall time of the read + write (imports excluded) and peak RSS
(``VmHWM``; ``base`` is the peak after the imports). Medians (and min, max) over
``--runs`` runs. Targets: ours within 2x of the peer's time for CSV, 3x for Parquet; our
peak RSS <= 1 GiB whatever the log's length (try ``--hours 4``).

    python benchmarks/log_io.py --json [--hours 1] [--runs 3] [--dir DIR]
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

COLUMNS = ("t", "T_w", "T_p", "v", "T_a", "T_w_cmd")
RATE_HZ = 1000
TARGET_RATIO = {"csv": 2.0, "parquet": 3.0}
TARGET_PEAK_MIB = 1024.0


def generate(folder: Path, hours: float, seed: int = 0) -> dict[str, Path]:
    """Write the test log as ``log.csv`` and ``log.parquet`` (polars / pyarrow, in slices)."""
    import polars as pl
    import pyarrow as pa
    import pyarrow.parquet as pq

    n = round(hours * 3600 * RATE_HZ)
    rng = np.random.default_rng(seed)
    paths = {"csv": folder / "log.csv", "parquet": folder / "log.parquet"}
    schema = pa.schema([(c, pa.float64()) for c in COLUMNS])
    step = 1_000_000
    with open(paths["csv"], "wb") as fh, pq.ParquetWriter(paths["parquet"], schema) as pw:
        for i0 in range(0, n, step):
            i = np.arange(i0, min(n, i0 + step))
            m = i.size

            def quant(x: np.ndarray) -> np.ndarray:
                return np.round(x * 64) / 64

            cols = {
                "t": i / RATE_HZ,
                "T_w": quant(24 + rng.normal(0, 0.05, m)),
                "T_p": quant(20 + rng.normal(0, 0.1, m)),
                "v": np.where((i // 60_000) % 2 == 0, 0.141, 0.0),
                "T_a": quant(20 + rng.normal(0, 0.02, m)),
                "T_w_cmd": np.full(m, 24.0),
            }
            pl.DataFrame(cols).write_csv(fh, include_header=i0 == 0)
            pw.write_table(pa.table(cols, schema=schema))
    return paths


# --------------------------------------------------------------------------- one run


def _peer(fmt: str, src: Path, dst: Path) -> None:
    import polars as pl

    df = pl.read_csv(src) if fmt == "csv" else pl.read_parquet(src)
    q = (pl.col("T_w") - pl.col("T_p")) / 0.19
    df = df.with_columns(q.alias("q_i_hat"), (q - 3.6).alias("dq_i_hat"))
    if fmt == "csv":
        df.write_csv(dst)
    else:
        df.write_parquet(dst)


def _ours(fmt: str, src: Path, dst: Path) -> None:
    from thermoskin.logio import LogReader, LogWriter

    with LogReader(src, required=COLUMNS) as r, LogWriter(dst, [*r.names, "q_i_hat", "dq_i_hat"]) as w:
        for c in r:
            q = (c["T_w"] - c["T_p"]) / 0.19
            c["q_i_hat"] = q
            c["dq_i_hat"] = q - 3.6
            w.write(c)


def worker(impl: str, fmt: str, src: Path, dst: Path) -> dict[str, float]:
    """One read + write in this process; time and memory as a dict."""
    for mod in ("polars", "pyarrow.csv", "pyarrow.parquet", "thermoskin.logio"):
        importlib.import_module(mod)  # both sides pay the same imports before the clock starts

    base = _hwm_mib()
    t0 = time.perf_counter()
    (_peer if impl == "peer" else _ours)(fmt, src, dst)
    dt = time.perf_counter() - t0
    return {"s": dt, "peak_mib": _hwm_mib(), "base_mib": base}


def _hwm_mib() -> float:
    """Peak RSS of this process (MiB): ``VmHWM``, which, unlike ``ru_maxrss``, does not inherit the
    parent's peak across ``fork`` + ``exec``."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _run(impl: str, fmt: str, src: Path, dst: Path) -> dict[str, float]:
    out = subprocess.run(
        [sys.executable, __file__, "--worker", impl, fmt, str(src), str(dst)],
        check=True, capture_output=True, text=True,
    )
    return json.loads(out.stdout)


def _stats(xs: list[float]) -> dict[str, float]:
    return {"median": statistics.median(xs), "min": min(xs), "max": max(xs)}


def bench(folder: Path, hours: float, runs: int) -> dict[str, object]:
    paths = generate(folder, hours)
    rows = round(hours * 3600 * RATE_HZ)
    result: dict[str, object] = {
        "log": {"hours": hours, "rows": rows, "columns": list(COLUMNS),
                "csv_mib": paths["csv"].stat().st_size / 2**20,
                "parquet_mib": paths["parquet"].stat().st_size / 2**20},
        "runs": runs, "cpus": os.cpu_count(),
    }
    for fmt, src in paths.items():
        res: dict[str, list[dict[str, float]]] = {"peer": [], "ours": []}
        for _ in range(runs):  # interleaved, so that a busy spell hits both
            for impl in res:
                res[impl].append(_run(impl, fmt, src, folder / f"out_{impl}.{fmt}"))
        entry: dict[str, object] = {}
        for impl, rs in res.items():
            entry[impl] = {"s": _stats([r["s"] for r in rs]), "peak_mib": _stats([r["peak_mib"] for r in rs]),
                           "base_mib": statistics.median(r["base_mib"] for r in rs),
                           "rows_per_s": rows / statistics.median(r["s"] for r in rs),
                           "out_mib": (folder / f"out_{impl}.{fmt}").stat().st_size / 2**20}
        med = {impl: statistics.median(r["s"] for r in rs) for impl, rs in res.items()}
        ratio = med["ours"] / med["peer"]
        peak = max(r["peak_mib"] for r in res["ours"])
        entry["time_ratio"] = ratio
        entry["time_ratio_target"] = TARGET_RATIO[fmt]
        entry["ours_peak_mib_max"] = peak
        entry["ok"] = bool(ratio <= TARGET_RATIO[fmt] and peak <= TARGET_PEAK_MIB)
        result[fmt] = entry
    return result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print JSON only")
    ap.add_argument("--hours", type=float, default=1.0, help="log length at 1 kHz (default 1)")
    ap.add_argument("--runs", type=int, default=3, help="runs per case (default 3)")
    ap.add_argument("--dir", type=Path, default=None, help="work folder (default: a temporary one)")
    ap.add_argument("--worker", nargs=4, metavar=("IMPL", "FMT", "SRC", "DST"), help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.worker:
        impl, fmt, src, dst = a.worker
        print(json.dumps(worker(impl, fmt, Path(src), Path(dst))))
        return
    if a.dir is not None:
        a.dir.mkdir(parents=True, exist_ok=True)
        result = bench(a.dir, a.hours, a.runs)
    else:
        with tempfile.TemporaryDirectory(prefix="log_io_bench_") as d:
            result = bench(Path(d), a.hours, a.runs)
    if a.json:
        print(json.dumps(result, indent=2))
        return
    for fmt in ("csv", "parquet"):
        e = result[fmt]
        assert isinstance(e, dict)
        print(f"{fmt:8s} peer {e['peer']['s']['median']:.2f} s {e['peer']['peak_mib']['median']:.0f} MiB | "
              f"ours {e['ours']['s']['median']:.2f} s {e['ours']['peak_mib']['median']:.0f} MiB | "
              f"ratio {e['time_ratio']:.2f} (target {e['time_ratio_target']:g}) "
              + ("ok" if e["ok"] else "MISSED"))


if __name__ == "__main__":
    main()
