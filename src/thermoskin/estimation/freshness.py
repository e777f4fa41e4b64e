"""Which samples of a log carry a new reading, per thermocouple channel.

A thermocouple board converts every 100 ms or so and the loop (or the logger) repeats its
last reading in between; a repeated reading is no new information. A log written by
``thermoskin run`` says which samples were fresh (its ``fresh`` column: bit 1 ``T_w``, 2
``T_p``, 4 ``T_a``). For any other log the channel's update rate is read from the data: a
channel whose value changes on at least half the samples updates every sample (a fresh
reading equal to the last one is then common, about one in ten with 0.02 K of noise and
1/128 K steps); otherwise a sample is fresh where the value changed. A fresh reading that
happens to equal the previous one is then taken as stale: the estimator just predicts one
interval longer, with no bias.

A ``fresh`` column is trusted where it sets a bit; where it does not but the value changed,
the sample is fresh too: a held reading never changes, and a log kept at every n-th row of
the loop's (a slower logger, a downsampled file) has lost the bits of the readings that came
between its rows, while their values show. On a log as the loop wrote it this adds nothing
(its values change only where its bits are set), so ``observe`` still equals the live run.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

CHANNELS = ("T_w", "T_p", "T_a")
BITS = {"T_w": 1, "T_p": 2, "T_a": 4}
ALL_FRESH = 7
#: A channel whose readings change on at least this fraction of samples updates every sample.
EVERY_SAMPLE = 0.5


def updates_every_sample(x: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Per column of ``x`` (samples along the first axis): does that channel update every
    sample, its value changing on at least :data:`EVERY_SAMPLE` of the samples after the first
    (module doc)? A channel of fewer than two samples does."""
    x = np.asarray(x, dtype=float)
    if len(x) < 2:
        return np.ones(x.shape[1:], dtype=bool)
    return np.asarray(np.mean(value_changed(x[1:], x[0]), axis=0) >= EVERY_SAMPLE)


def channel_fresh(x: NDArray[np.float64]) -> tuple[NDArray[np.bool_], float]:
    """Fresh samples of one channel and its median update period in samples."""
    x = np.asarray(x, dtype=float)
    n = len(x)
    if n == 0:
        return np.zeros(0, dtype=bool), 1.0
    changed = value_changed(x)
    changed[0] = True
    if updates_every_sample(x):
        return np.ones(n, dtype=bool), 1.0
    idx = np.flatnonzero(changed)
    period = float(np.median(np.diff(idx))) if len(idx) > 2 else float(n)
    return changed, period


def value_changed(x: NDArray[np.float64], before: Any = np.nan) -> NDArray[np.bool_]:
    """Samples (along the first axis) whose value differs from the one before: ``before`` is
    the sample before the first (a number, or a row for ``(samples, patches)``; NaN: none);
    NaN after NaN is no change."""
    x = np.asarray(x, dtype=float)
    if not len(x):
        return np.zeros(x.shape, dtype=bool)
    first = np.broadcast_to(np.asarray(before, dtype=float), x.shape[1:])[None]
    prev = np.concatenate([first, x[:-1]])
    return (x != prev) & ~(np.isnan(x) & np.isnan(prev))


def _column_and_changes(log: Mapping[str, NDArray[np.float64]], last: Mapping[str, float]
                        ) -> NDArray[np.int64]:
    """The log's ``fresh`` column, with each channel's bit set where its value changed too."""
    f = np.nan_to_num(np.asarray(log["fresh"], dtype=float), nan=0.0).astype(np.int64)
    for ch in CHANNELS:
        if ch in log:
            f |= np.where(value_changed(log[ch], last.get(ch, np.nan)), BITS[ch], 0)
    return f


def infer_fresh(log: Mapping[str, NDArray[np.float64]]) -> tuple[NDArray[np.int64], dict[str, float]]:
    """The ``fresh`` bitmask per sample (the log's own column if it has one, with a bit set too
    where the value changed) and each channel's update period in samples (1 = every sample)."""
    n = len(log["t"])
    if "fresh" in log:
        f = _column_and_changes(log, {})
        periods = {}
        for ch in CHANNELS:
            idx = np.flatnonzero(f & BITS[ch])
            periods[ch] = float(np.median(np.diff(idx))) if len(idx) > 2 else float(n)
        return f, periods
    out = np.zeros(n, dtype=np.int64)
    periods = {}
    for ch in CHANNELS:
        fr, per = channel_fresh(log[ch])
        out |= np.where(fr, BITS[ch], 0)
        periods[ch] = per
    return out, periods


class FreshInference:
    """:func:`infer_fresh` chunk by chunk, for a log read in pieces (the same flags: each
    channel's rate is decided on the first chunk; a change is taken against the previous
    chunk's last value)."""

    def __init__(self) -> None:
        self._every: dict[str, bool] | None = None
        self._last: dict[str, float] = {}
        self.periods: dict[str, float] = {}

    def feed(self, chunk: Mapping[str, NDArray[np.float64]]) -> NDArray[np.int64]:
        n = len(chunk["t"])
        if "fresh" in chunk:
            f = _column_and_changes(chunk, self._last)
            for ch in CHANNELS:
                if n and ch in chunk:
                    self._last[ch] = float(chunk[ch][-1])
            if not self.periods:
                for ch in CHANNELS:
                    idx = np.flatnonzero(f & BITS[ch])
                    self.periods[ch] = float(np.median(np.diff(idx))) if len(idx) > 2 else float(n)
            return f
        if self._every is None:
            self._every = {}
            for ch in CHANNELS:
                fr, per = channel_fresh(chunk[ch])
                self._every[ch] = bool(fr.all())
                self.periods[ch] = per
        out = np.zeros(n, dtype=np.int64)
        for ch in CHANNELS:
            x = np.asarray(chunk[ch], dtype=float)
            every = self._every[ch]
            changed = np.ones(n, dtype=bool) if every else value_changed(x, self._last.get(ch, np.nan))
            out |= np.where(changed, BITS[ch], 0)
            if n:
                self._last[ch] = float(x[-1])
        return out
