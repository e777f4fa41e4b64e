"""Stop requests by signal: SIGINT, SIGTERM and SIGHUP all end a run the same clean way.

A service manager stops a run with SIGTERM, a closed terminal sends SIGHUP, Ctrl-C sends
SIGINT. While a :class:`StopRequest` is installed, the first of these only sets a flag
(``is_set()``), which the loops poll (the in-process loop every sample, the fixed-rate
loop's parent every drain, ~20 ms): the device is put in its safe state, the rows so
far are written, the log, the plot and the recording are finished, and the command
exits with ``128 + signal number`` (130 SIGINT, 143 SIGTERM, 129 SIGHUP). Nothing is
raised asynchronously, so no write is torn. A second signal raises
``KeyboardInterrupt`` (the impatient user's way out; the recording is still closed by
its ``finally``).

Two of the log libraries interrupt their own calls on SIGINT, below Python's handler:
polars installs a handler of its own when it is imported (chained to the one there
before) and raises ``KeyboardInterrupt`` from any call under way, and pyarrow cancels a
long read (``ArrowCancelled``). Either would end a run through an exception instead of this
flag, without the safe-state report, whenever the signal came during a log write (seen
about once in twenty runs under load). So :meth:`StopRequest.install` imports polars first,
so that the handler it then installs replaces polars' (Python's ``signal.signal`` sets the
process's action), and turns pyarrow's interruption off until the last :meth:`StopRequest.restore`.
polars' handler is not put back: after a run a long polars call is interrupted only when it
returns, as any other Python call.
"""

from __future__ import annotations

import signal
import threading
from types import FrameType
from typing import Any

SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


class StopRequest:
    """A stop flag set by SIGINT, SIGTERM or SIGHUP (or by :meth:`set`)."""

    def __init__(self) -> None:
        self.signum = 0
        """The signal that asked for the stop (0: none, or :meth:`set` called)."""
        self._set = False
        self._previous: dict[int, Any] = {}

    def is_set(self) -> bool:
        return self._set

    def set(self, signum: int = 0) -> None:
        if not self._set:
            self.signum = signum
        self._set = True

    @property
    def exit_code(self) -> int:
        """``128 + signal number`` (130 for SIGINT, 143 SIGTERM, 129 SIGHUP); 130 if none."""
        return 128 + (self.signum or signal.SIGINT)

    @property
    def name(self) -> str:
        return signal.Signals(self.signum).name if self.signum else "stop"

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        if self._set:
            raise KeyboardInterrupt
        self.set(signum)

    def install(self) -> StopRequest:
        """Take SIGINT, SIGTERM and SIGHUP (main thread only; elsewhere a no-op), from the
        log libraries too (module doc)."""
        if threading.current_thread() is threading.main_thread():
            _quiet_libraries(True)
            for sig in SIGNALS:
                self._previous[sig] = signal.signal(sig, self._handle)
        return self

    def restore(self) -> None:
        """Put the previous handlers back."""
        if self._previous:
            _quiet_libraries(False)
        for sig, prev in self._previous.items():
            signal.signal(sig, prev if prev is not None else signal.SIG_DFL)
        self._previous.clear()

    def __enter__(self) -> StopRequest:
        return self.install()

    def __exit__(self, *exc: object) -> None:
        self.restore()


_installed = 0
"""Stop requests installed now (nested ones: pyarrow's interruption back on after the last)."""


def _quiet_libraries(quiet: bool) -> None:
    """Keep polars and pyarrow from interrupting their own calls on SIGINT (module doc):
    polars imported before the handlers are set (its own is set on import), pyarrow's
    interruption off from the first install to the last restore."""
    import polars  # noqa: F401  (its SIGINT handler, set on import, is then replaced by ours)
    import pyarrow

    global _installed
    _installed += 1 if quiet else -1
    if _installed == (1 if quiet else 0):
        pyarrow.enable_signal_handlers(not quiet)
