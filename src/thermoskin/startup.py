"""The command line's start-up: Python's cyclic garbage collector paused while modules load.

A command imports numba, llvmlite, polars and this package and loads compiled code: some
160 000 objects that the collector tracks, and about 240 collections over them as they load
(55-72 ms of an ``observe`` of a short log: ``benchmarks/startup.py``), though nothing loaded
is garbage. So the program's entry
(:mod:`thermoskin.__main__`, the ``thermoskin`` command) pauses the collector, and the command
resumes it once it has started: what was made by then is frozen (``gc.freeze``: kept out of
every later collection, as it lives to the end anyway) and the collector runs as usual for
the command's work. A program that imports the package is not affected: only the entry pauses.

Reference counting frees everything that is not in a cycle as usual, paused or not.
"""

from __future__ import annotations

import gc

_paused = False


def pause() -> None:
    """Pause the cyclic collector for the start-up (the program's entry calls this first)."""
    global _paused
    if gc.isenabled():
        gc.disable()
        _paused = True


def resume() -> None:
    """End the start-up: freeze what exists (it is not garbage: loaded modules and code, the
    command's set-up), then collect as usual. Does nothing unless :func:`pause` paused it."""
    global _paused
    if _paused:
        _paused = False
        gc.freeze()
        gc.enable()


def paused() -> bool:
    """Whether the start-up's pause is on."""
    return _paused


def cancel() -> None:
    """Turn the collector back on without freezing (the program's entry, when a command ended
    before its start-up did: ``--help``, a usage error; for a caller that goes on after it)."""
    global _paused
    if _paused:
        _paused = False
        gc.enable()
