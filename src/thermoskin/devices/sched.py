"""Real-time scheduling where the operating system allows it (as labs run 1 kHz loops).

``SCHED_FIFO`` puts a process (on Linux: the calling thread) ahead of every normal process
on its core: a compiler or a browser on the same machine then cannot delay it, only the
kernel and higher real-time priorities can. It needs ``CAP_SYS_NICE`` (root) or an
``RLIMIT_RTPRIO`` allowance (``ulimit -r``, ``/etc/security/limits.conf``); without it the
process runs at normal priority, and says so. The loop process and the device emulator
both sleep between samples, so they take only the CPU time they need.
"""

from __future__ import annotations

import os


def set_fifo(priority: int) -> str:
    """Ask for ``SCHED_FIFO`` at ``priority`` (0: do not ask); what was granted, as text."""
    if priority <= 0 or not hasattr(os, "sched_setscheduler"):
        return "normal"
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
        return f"SCHED_FIFO {priority}"
    except (PermissionError, OSError):
        return "normal (no permission for SCHED_FIFO)"
