"""Benchmark: ``thermoskin export RUN.mcap --ros2`` on a 60 s recording.

The recording is that of ``thermoskin run --duration 60 --scenario one-finger --record``
(the simulated skin: /skin/sample, /control, /skin/estimate, /sim/truth at 1 kHz, the
events and /params; a hardware recording has /loop/timing in place of /sim/truth, as many
messages). Timed in this process, imports done before the clock starts, medians (min, max)
over ``--runs`` runs:

- ``ros2``: :func:`thermoskin.runtime.ros2.export_ros2` (struct-compiled CDR);
- ``ros2_library_encoder``: the same reading and conversion, every message encoded and
  written by ``mcap-ros2-support``'s ``Writer`` (its generic CDR encoder), for comparison;
- ``parquet``: the table export (``thermoskin export -o RUN.parquet``), for scale.

    python benchmarks/ros2_export.py --json [--runs 5] [--recording RUN.mcap]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any


def record(folder: Path, seconds: float) -> Path:
    path = folder / "run.mcap"
    subprocess.run([sys.executable, "-c", "from thermoskin.cli import main; main()", "run",
                    "--duration", str(seconds), "--scenario", "one-finger", "--record", str(path),
                    "--log", str(folder / "run.csv"), "--plot", str(folder / "run.png")],
                   check=True, capture_output=True)
    return path


def export_with_library_encoder(src: Path, out: Path) -> None:
    """As ``export_ros2``, but each message a dict encoded by ``mcap_ros2.writer.Writer``."""
    from mcap_ros2.writer import Writer

    from thermoskin.runtime.record import scan_messages
    from thermoskin.runtime.ros2 import ROS_TYPES, STRING, schema_text

    sc = scan_messages(src, publish_time=True)
    schemas: dict[str, Any] = {}
    with open(out, "wb") as fh:
        w = Writer(fh)
        for batch in sc.batches():
            objs = json.loads(b"[" + b",".join([m[3] for m in batch]) + b"]")
            for (topic, seq, ns, payload, pub), obj in zip(batch, objs, strict=True):
                rt = ROS_TYPES.get(topic, STRING)
                if rt is STRING:
                    msg: dict[str, Any] = {"data": payload.decode()}
                else:
                    msg = {"header": {"stamp": {"sec": ns // 10**9, "nanosec": ns % 10**9}, "frame_id": ""}}
                    msg.update(zip((f[1] for f in rt.fields), rt.values(obj, ns), strict=True))
                schema = schemas.get(rt.name)
                if schema is None:
                    schema = schemas[rt.name] = w.register_msgdef(rt.name, schema_text(rt.name))
                w.write_message(topic, schema, msg, log_time=ns, publish_time=pub, sequence=seq)
        w.finish()


def bench(src: Path, folder: Path, runs: int) -> dict[str, Any]:
    from thermoskin.runtime.record import check, export
    from thermoskin.runtime.ros2 import export_ros2

    rep = check(src)
    seconds = rep.t_end - rep.t_start
    jobs = {
        "ros2": lambda: export_ros2(src, folder / "ros2.mcap"),
        "ros2_library_encoder": lambda: export_with_library_encoder(src, folder / "lib.mcap"),
        "parquet": lambda: export(src, folder / "run.parquet"),
    }
    out: dict[str, Any] = {
        "recording": {"seconds": round(seconds, 3), "messages": rep.messages,
                      "mib": round(src.stat().st_size / 2**20, 2)},
        "runs": runs, "machine": f"{os.cpu_count()} cores, shared",
    }
    for name, job in jobs.items():
        times = []
        for _ in range(runs):
            t0 = time.perf_counter()
            job()
            times.append(time.perf_counter() - t0)
        med = statistics.median(times)
        out[name] = {"median_s": round(med, 3), "min_s": round(min(times), 3), "max_s": round(max(times), 3),
                     "us_per_message": round(med / rep.messages * 1e6, 2),
                     "x_real_time": round(seconds / med, 1)}
    out["ros2"]["output_mib"] = round((folder / "ros2.mcap").stat().st_size / 2**20, 2)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print JSON (the default; kept for symmetry)")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--seconds", type=float, default=60.0, help="length of the recording to make")
    ap.add_argument("--recording", type=Path, default=None, help="use this recording instead")
    args = ap.parse_args()
    import mcap_ros2.writer  # noqa: F401  (imports before the clock)

    import thermoskin.runtime.ros2  # noqa: F401

    with tempfile.TemporaryDirectory() as d:
        folder = Path(d)
        src = args.recording or record(folder, args.seconds)
        print(json.dumps(bench(src, folder, args.runs), indent=2))


if __name__ == "__main__":
    main()
