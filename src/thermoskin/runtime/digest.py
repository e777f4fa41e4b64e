"""What ``thermoskin run`` reports at its end, gathered block by block as it writes its log.

The loop hands every block of rows to the log, the recording and a :class:`RunDigest`,
which keeps, in memory that does not grow with the run's length:

- the plot's columns (:class:`~thermoskin.plots.digest.PlotDigest`: every row of a short
  run, an exact min/max envelope of a long one);
- each command's tracking (:class:`~thermoskin.analysis.evaluation.TrackingStream`);
- what touched (:class:`~thermoskin.touch.characterise.Characteriser`): each contact is
  characterised as soon as its samples are in (the characteriser holds only the last few
  minutes of its binned signals, so a contact of the first minutes of an hour's run could
  not be characterised at the end);
- the rows and the last ``t``.

A live run's digest gives what the same computations on its whole log give: the tracking
and the characterisation exactly, the plot exactly up to :data:`~thermoskin.plots.digest.ROWS` rows.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from thermoskin.analysis.evaluation import Tracking, TrackingStream
from thermoskin.estimation.events import ContactEvent
from thermoskin.params import Config
from thermoskin.plots.digest import PlotDigest
from thermoskin.touch.characterise import BIN_S, Characteriser, window_end

#: Columns the characteriser reads.
CHARACTER_INPUTS = ("t", "dq_i_hat", "T_w", "T_a")


class RunDigest:
    """A run's report, fed with each block of its log (module doc)."""

    def __init__(self, cfg: Config, *, characterise: bool = True) -> None:
        self.plot = PlotDigest(cfg.sampling.t_s)
        self.tracking = TrackingStream()
        self._ch = Characteriser(cfg) if characterise else None
        self._pending: list[ContactEvent] = []
        self._done: dict[tuple[float, float], ContactEvent] = {}
        self._fed = False  # the characteriser had its columns
        self.rows = 0
        self.t_last = math.nan

    def feed(self, block: Mapping[str, Any]) -> None:
        """The next rows of the log (columns of equal length)."""
        t = np.asarray(block["t"], dtype=np.float64)
        if not len(t):
            return
        self.plot.feed(block)
        if "T_w_cmd" in block:
            self.tracking.feed(t, block["T_w"], block["T_w_cmd"], block.get("T_p_cmd"))
        if self._ch is not None and all(k in block for k in CHARACTER_INPUTS):
            self._ch.feed(t, block["dq_i_hat"], block["T_w"], block["T_a"])
            self._fed = True
        self.rows += len(t)
        self.t_last = float(t[-1])
        self._annotate_ready()

    def event(self, e: ContactEvent) -> None:
        """A contact that ended: characterised once the samples it needs are in."""
        self._pending.append(e)
        self._annotate_ready()

    def _annotate_ready(self) -> None:
        if self._ch is None or not self._fed or not self._pending:
            return
        keep = []
        for e in self._pending:
            if self.t_last >= window_end(e) + BIN_S:  # every bin the contact's window reads is closed
                self._done[(e.onset, e.detected_at)] = self._ch.annotate(e)
            else:
                keep.append(e)
        self._pending = keep

    def events(self, events: Sequence[ContactEvent]) -> list[ContactEvent]:
        """The run's contacts, characterised (those still open at the end with the samples
        there are); as given without a characteriser or its columns."""
        if self._ch is None or not self._fed or not events:
            return list(events)
        self._ch.finish()
        out = []
        for e in events:
            done = self._done.get((e.onset, e.detected_at))
            out.append(done if done is not None else self._ch.annotate(e))
        return out

    def columns(self) -> dict[str, np.ndarray]:
        """The plot's columns (:meth:`PlotDigest.columns`)."""
        return self.plot.columns()

    def tracking_errors(self) -> list[Tracking]:
        """Each command's tracking (:func:`thermoskin.analysis.evaluation.tracking_errors`)."""
        return self.tracking.finish()
