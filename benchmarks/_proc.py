"""A `thermoskin` command as a process of its own: its wall time and peak resident memory."""

from __future__ import annotations

import os
import subprocess
import sys
import time

CMD = [sys.executable, "-c", "from thermoskin.__main__ import main; main()"]


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
