"""The run's log, written while the loop runs (``thermoskin run --log``).

Blocks of rows (the loop's ``on_block`` / the fixed-rate loop's drained rows) go straight
to a :class:`~thermoskin.logio.LogWriter`: a CSV log is handed to the operating system
at least every :data:`FLUSH_S` seconds, so a killed run (SIGKILL, a power cut of the
host process) leaves a log holding every row up to about a second before the end, which
``read_log(..., live=True)`` reads (its last line may be cut). A Parquet log is complete
only once the run ends (Parquet has its index at the end).

The flag columns (:data:`~thermoskin.logio.FLAG_COLUMNS`) are written as integers, NaN
as 0, as the whole-log writer did.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from thermoskin.logio import FLAG_COLUMNS, LogWriter

#: Seconds (wall clock) between hand-overs of the CSV rows to the OS: well inside the
#: one second a killed run may lose, with the fixed-rate loop's 20 ms drain on top.
FLUSH_S = 0.5


class RunLog:
    """Append the loop's blocks (columns) to the log at ``path``, keeping ``names`` in order."""

    def __init__(self, path: str | os.PathLike[str], names: Sequence[str]) -> None:
        self.path = Path(path)
        self.names = list(names)
        self._flags = {n for n in self.names if n in FLAG_COLUMNS}
        self.writer = LogWriter(self.path, self.names, flush_s=FLUSH_S)
        self.rows = 0

    def write(self, block: Mapping[str, Any]) -> None:
        """Append a block (every name of the log as a column; other columns ignored)."""
        cols = {}
        for n in self.names:
            x = np.asarray(block[n])
            if n in self._flags:
                x = np.nan_to_num(x.astype(np.float64, copy=False)).astype(np.int8)
            cols[n] = x
        self.writer.write(cols)
        self.rows += len(cols[self.names[0]])

    def close(self) -> Path:
        """Hand the last rows over and close; the log's path."""
        return self.writer.close()
