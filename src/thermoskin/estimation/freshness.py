"""Which samples of a log carry a new reading, per thermocouple channel.

A thermocouple board converts every 100 ms or so and the loop (or the logger) repeats its
last reading in between; a repeated reading is no new information. A log written by
``thermoskin run`` says which samples were fresh (its ``fresh`` column: bit 1 ``T_w``, 2
``T_p``, 4 ``T_a``). For any other log the channel's update rate is read from the data: a
channel whose value changes on at least half of its first 64 samples updates every sample
(decided there, so that a log read whole or in chunks of any size gets the same bits; a fresh
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

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from thermoskin.logio import LogError
from thermoskin.params import Config, SamplingParams

CHANNELS = ("T_w", "T_p", "T_a")
BITS = {"T_w": 1, "T_p": 2, "T_a": 4}
#: A one-patch log's channels and their bits.
CHANNEL_BITS: tuple[tuple[str, int], ...] = tuple(BITS.items())
ALL_FRESH = 7
#: A channel whose readings change on at least this fraction of samples updates every sample.
EVERY_SAMPLE = 0.5


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


def column_with_changes(cols: Mapping[str, NDArray[np.float64]], fresh: NDArray[Any],
                        channels: Sequence[tuple[str, int]] = CHANNEL_BITS,
                        last: dict[str, Any] | None = None) -> NDArray[np.int64]:
    """A log's ``fresh`` bits with each channel's bit set too where its value changed (module
    doc). ``cols`` one patch's columns ``(samples,)`` or a skin's ``(samples, patches)``;
    ``last``: each channel's previous sample (updated; None: none before)."""
    out = np.nan_to_num(np.asarray(fresh, dtype=float), nan=0.0).astype(np.int64)
    for col, bit in channels:
        if col not in cols or not len(cols[col]):
            continue
        x = np.asarray(cols[col], dtype=float)
        out |= np.where(value_changed(x, np.nan if last is None else last.get(col, np.nan)), bit, 0)
        if last is not None:
            last[col] = x[-1].copy()
    return out


class FreshInference:
    """The ``fresh`` bits of a log, chunk by chunk, the same however it is cut: the log's own
    column with the changes of its values (:func:`column_with_changes`), or, where it has none,
    read from the values per channel (and per patch, for a skin's ``(samples, patches)``
    columns): a channel that changes on at least :data:`EVERY_SAMPLE` of its first
    :attr:`DECIDE_ROWS` rows updates every sample, any other is fresh where its value changed
    (module doc). Its first rows, before that is known, are read by their changes alone.

    ``periods``: each channel's update period in samples, the median interval between the
    bits of the first chunk that has rows (of a one-patch log; 1 = every sample; read from
    that chunk alone, as the command line shows it, so a short first chunk reads it roughly)."""

    DECIDE_ROWS = 64

    def __init__(self, channels: Sequence[tuple[str, int]] = CHANNEL_BITS) -> None:
        self.channels = list(channels)
        self._rows = 0
        self._last: dict[str, Any] = {}
        self._every: dict[str, NDArray[np.bool_]] = {}
        self._n_changed: dict[str, NDArray[np.float64]] = {}
        self.periods: dict[str, float] = {}

    def feed(self, chunk: Mapping[str, NDArray[np.float64]]) -> NDArray[np.int64]:
        """The next chunk's bits (the shape of its ``T_w``)."""
        if "fresh" in chunk:
            out = column_with_changes(chunk, chunk["fresh"], self.channels, self._last)
        else:
            out = self._infer(chunk)
        if not self.periods and out.ndim == 1 and len(out):
            n = len(out)
            for col, bit in self.channels:
                idx = np.flatnonzero(out & bit)
                self.periods[col] = float(np.median(np.diff(idx))) if len(idx) > 2 else float(n)
        self._rows += len(out)
        return out

    def _infer(self, chunk: Mapping[str, NDArray[np.float64]]) -> NDArray[np.int64]:
        shape = np.shape(chunk["T_w"])
        m, k0, D = shape[0], self._rows, self.DECIDE_ROWS
        out = np.zeros(shape, dtype=np.int64)
        for c, bit in self.channels:
            if c not in chunk:
                continue
            x = np.asarray(chunk[c], dtype=float)
            changed = value_changed(x, self._last.get(c, np.nan))
            if k0 < D:  # the deciding rows (the first row, new by definition, not counted)
                a = max(1 - k0, 0)
                n = self._n_changed.setdefault(c, np.zeros(shape[1:]))
                n += changed[a:D - k0].sum(axis=0)
                if k0 + m >= D:
                    self._every[c] = n / (D - 1) >= EVERY_SAMPLE
            if c in self._every and k0 + m > D:
                changed[max(D - k0, 0):] |= self._every[c]  # per patch: broadcast over rows
            out |= np.where(changed, bit, 0)
            if m:
                self._last[c] = x[-1].copy()
        return out


def infer_fresh(log: Mapping[str, NDArray[np.float64]]) -> tuple[NDArray[np.int64], dict[str, float]]:
    """The ``fresh`` bitmask per sample of a whole log (:class:`FreshInference`) and each
    channel's update period in samples (1 = every sample)."""
    inf = FreshInference()
    return inf.feed(log), inf.periods


# A log's sampling interval, as the estimator takes it


def sample_interval(t: NDArray[np.float64]) -> float:
    """The log's sampling interval: the median step of ``t`` (s)."""
    t = np.asarray(t, dtype=float)
    if len(t) < 2:
        raise ValueError("a log needs at least 2 samples to have a sampling interval")
    return float(np.median(np.diff(t)))


def check_interval(t_s: float, where: str = "the log") -> None:
    """Refuse a sampling interval outside ``sampling.t_s``'s range (one-line :class:`LogError`)."""
    import dataclasses

    meta = {f.name: f.metadata for f in dataclasses.fields(SamplingParams)}["t_s"]
    if not meta["lo"] <= t_s <= meta["hi"]:
        raise LogError(f"{where} is sampled every {t_s:.3g} s; the estimator works at "
                       f"{meta['lo']:g} to {meta['hi']:g} s per sample")


def loop_t_s(t_s: float, cfg: Config) -> float:
    """A log's sampling interval as the estimator takes it: the configured ``sampling.t_s``
    where the log's is that within 0.1 % (the median of the differences of its times carries
    their rounding; the live loop used the configured value), else the log's own."""
    cfg_t_s = cfg.sampling.t_s
    return cfg_t_s if abs(t_s - cfg_t_s) <= 1e-3 * cfg_t_s else float(t_s)
