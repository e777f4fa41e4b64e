"""A `thermoskin` command as a process of its own: its wall time and peak resident memory; CPU-bound
processes to load the machine beside it."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

CMD = [sys.executable, "-c", "from thermoskin.__main__ import main; main()"]


@contextmanager
def cpu_hogs(n: int) -> Iterator[None]:
    """``n`` CPU-bound processes (``python -c 'while True: pass'``) for the time of the block,
    killed and reaped at its end, however it ends."""
    hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]
    try:
        yield
    finally:
        for p in hogs:
            p.kill()
            p.wait()


def check_package_dir(option: str, folder: str | None) -> None:
    """End the script if ``folder`` (given as ``option``: another checkout's ``src``) holds no
    thermoskin package: the comparison would otherwise run this code against itself."""
    if folder and not (Path(folder) / "thermoskin" / "__init__.py").is_file():
        raise SystemExit(f"{option} {folder}: no thermoskin package there (the folder holding it: a `src`)")


def run(args: list[str], env: dict[str, str] | None = None) -> tuple[float, float]:
    """Wall time (s) and peak resident memory (MiB, from the kernel: ``wait4``) of
    ``thermoskin ARGS``; a failure ends the script with the command's last words."""
    t0 = time.perf_counter()
    p = subprocess.Popen([*CMD, *args], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                         env=None if env is None else {**os.environ, **env})
    _, status, usage = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    p.returncode = os.waitstatus_to_exitcode(status)
    err = p.stderr.read().decode() if p.stderr else ""
    if p.returncode:
        raise SystemExit(f"thermoskin {' '.join(args)} failed ({p.returncode}): {err.strip()[-300:]}")
    return wall, usage.ru_maxrss / 1024.0


def rss_trace(args: list[str], every: float = 15.0, env: dict[str, str] | None = None
              ) -> list[dict[str, float]]:
    """``thermoskin ARGS`` run to its end, the resident memory (MiB, ``/proc``) of it and of each
    of its child processes read every ``every`` s: ``[{"t_s", "main_mib", "children_mib"}]``
    (``children_mib``: the largest child, e.g. the fixed-rate loop process)."""

    def rss(pid: int) -> float:
        try:
            with open(f"/proc/{pid}/status") as fh:
                for line in fh:
                    if line.startswith("VmRSS:"):
                        return int(line.split()[1]) / 1024.0
        except OSError:
            pass
        return 0.0

    def children(pid: int) -> list[int]:
        try:
            with open(f"/proc/{pid}/task/{pid}/children") as fh:
                return [int(x) for x in fh.read().split()]
        except OSError:
            return []

    p = subprocess.Popen([*CMD, *args], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                         env=None if env is None else {**os.environ, **env})
    t0 = time.perf_counter()
    out = []
    while p.poll() is None:
        time.sleep(every)
        if p.poll() is not None:
            break
        kids = [rss(c) for c in children(p.pid)]
        out.append({"t_s": round(time.perf_counter() - t0, 1), "main_mib": round(rss(p.pid), 1),
                    "children_mib": round(max(kids), 1) if kids else 0.0})
    return out
