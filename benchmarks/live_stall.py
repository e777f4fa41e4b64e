"""A live run (or replay) with a viewer that subscribes and never reads: does it end, how soon
after its loop, and how soon after a signal? Prints JSON.

    python benchmarks/live_stall.py --duration 100 --realtime          # the issue's 100 s case
    python benchmarks/live_stall.py --duration 200 --signal TERM --after 20 --runs 5

Each run: `thermoskin run --duration D --live PORT --live-wait 60 --log ... --record ...` (with
``--realtime``: paced at wall-clock speed in the fixed-rate loop process), a stalled client
(``tests/test_live_abuse.py``'s) subscribed to every channel; with ``--signal``, the signal is
sent once the log reaches ``--after`` s of loop time. Reported per run: exit code, wall time,
seconds from the signal to the exit (``stop_s``), from the log's last row being written to the
exit (``tail_s``: what the run does after its loop: closing, plot, summary), the log's rows; and
the median and maximum of ``stop_s`` and ``tail_s`` over the runs.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_live_abuse import free_port_pair, log_end, stalled_client

from thermoskin.logio import read_log

CMD = [sys.executable, "-c", "from thermoskin.cli import main; main()"]


def one(args: argparse.Namespace, folder: Path) -> dict[str, float]:
    port = free_port_pair()
    log = folder / "x.csv"
    cmd = [*CMD, "run", "--duration", str(args.duration), "--live", f"127.0.0.1:{port}", "--live-wait", "60",
           "--log", str(log), "--record", str(folder / "x.mcap"),
           "--realtime" if args.realtime else "--no-realtime"]
    t0 = time.monotonic()
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                         env={**os.environ, "PYTHONUNBUFFERED": "1"})
    ws = stalled_client(port)
    t_sig = last_write = float("nan")
    size = -1
    try:
        while p.poll() is None:
            if args.signal and t_sig != t_sig and log_end(log) >= args.after:
                t_sig = time.monotonic()
                p.send_signal(getattr(signal, f"SIG{args.signal}"))
            s = log.stat().st_size if log.exists() else -1
            if s != size:
                size, last_write = s, time.monotonic()
            time.sleep(0.02)
        t_end = time.monotonic()
    finally:
        if p.poll() is None:
            p.kill()
        ws.sock.close()
    err = p.stderr.read() if p.stderr else ""
    rows = len(read_log(log, required=("t",))["t"]) if log.exists() else 0
    return {"exit": p.returncode, "wall_s": t_end - t0, "stop_s": t_end - t_sig, "tail_s": t_end - last_write,
            "rows": rows, "last_line": err.strip().splitlines()[-1] if err.strip() else ""}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--duration", type=float, default=100.0)
    ap.add_argument("--realtime", action="store_true")
    ap.add_argument("--signal", choices=("INT", "TERM", "HUP"), default=None)
    ap.add_argument("--after", type=float, default=10.0, help="send the signal at this loop time, s")
    ap.add_argument("--runs", type=int, default=1)
    args = ap.parse_args()
    runs = []
    for _ in range(args.runs):
        with tempfile.TemporaryDirectory() as d:
            runs.append(one(args, Path(d)))
    out: dict[str, object] = {"duration_s": args.duration, "realtime": args.realtime, "signal": args.signal,
                              "runs": runs}
    for k in ("stop_s", "tail_s"):
        vals = [r[k] for r in runs if r[k] == r[k]]
        if vals:
            out[f"{k}_median"] = statistics.median(vals)
            out[f"{k}_max"] = max(vals)
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
