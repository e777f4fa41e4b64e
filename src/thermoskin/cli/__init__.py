"""Command line: ``thermoskin observe | simulate | run | plot | calibrate | export | replay | ...``.

One module per group of commands (:mod:`.observe`, :mod:`.simulate`, :mod:`.run`,
:mod:`.device`, :mod:`.recording`, :mod:`.fit`, :mod:`.sweep`, :mod:`.reproduce`, :mod:`.check`), each a thin
layer over the Python API, registered on the group of :mod:`.app`; :mod:`.common` holds what
they share. User errors (a bad log, a bad config, an unknown scenario) print one line,
``thermoskin: error: ...``, and exit with code 2; never a traceback.
"""

from __future__ import annotations

# isort: off
import thermoskin._blas  # noqa: F401  (one BLAS thread: before numpy is loaded)
# isort: on
from thermoskin.cli import check, device, fit, observe, recording, reproduce, run, simulate, sweep  # noqa: F401  (registers the commands)
from thermoskin.cli.app import freeze_at_exit, main

__all__ = ["freeze_at_exit", "main"]
