"""A run's plot, fed block by block in bounded memory (``thermoskin run`` and ``plot`` of a log).

:func:`thermoskin.plots.log.plot_run` draws at most about ``MAX_POINTS`` points a line
(min/max decimation), so a long run needs only an envelope of its columns.
:class:`PlotDigest` holds every row of :data:`PLOT_COLUMNS` while there are at most
``rows`` of them (the plot is then the whole log's, exactly). Beyond, it holds *ranges*:
contiguous samples, each kept as two rows, the range's minimum and maximum of every column
in their time order, at the range's first and last ``t``. When the rows pass ``rows`` again,
neighbouring ranges are merged (the minimum of two minima, ...), and new samples are taken
in ranges twice as long. The envelope of every column is kept exactly (every sample is in
one range), whatever the run's length.

The plot's trailing means (``q_i_hat`` over 0.1 s, the pump ``v`` over 1 s) are computed
at the full rate as the samples come, NaNs left out, and kept as ranges too
(``q_i_hat_mean``, ``v_mean``) once the digest holds ranges.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]

#: The columns :func:`thermoskin.plots.log.plot_run` draws.
PLOT_COLUMNS = ("t", "T_w", "T_p", "T_g", "T_w_cmd", "T_a", "q_i_hat", "dq_i_hat", "q_i", "T_p_cmd",
                "drive", "v", "contact", "contact_true")
#: Trailing means the plot draws: ``(column, window s)``.
MEANS = (("q_i_hat", 0.1), ("v", 1.0))
ROWS = 200_000
"""Rows a digest holds at most (about 25 MB): runs up to 200 s at 1 kHz are kept whole."""


class TrailingMean:
    """Mean of the last ``n`` samples (fewer at the start), NaNs left out (NaN if all are),
    fed chunk by chunk: the ``n - 1`` samples before a chunk are carried over."""

    def __init__(self, n: int) -> None:
        self.n = max(1, int(n))
        self._y = np.zeros(0)
        self._ok = np.zeros(0, dtype=np.int64)

    def __call__(self, y: ArrayLike) -> Array:
        y = np.asarray(y, dtype=np.float64)
        ok = np.isfinite(y)
        Y = np.concatenate((self._y, np.where(ok, y, 0.0)))
        K = np.concatenate((self._ok, ok.astype(np.int64)))
        c = np.concatenate(([0.0], np.cumsum(Y)))
        k = np.concatenate(([0], np.cumsum(K)))
        m = len(self._y)
        idx = np.arange(m + 1, m + len(y) + 1)
        lo = np.maximum(idx - self.n, 0)
        cnt = k[idx] - k[lo]
        keep = self.n - 1
        start = max(0, len(Y) - keep)  # the last keep samples (all of them while fewer)
        self._y, self._ok = (Y[start:], K[start:]) if keep else (Y[:0], K[:0])
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(cnt > 0, (c[idx] - c[lo]) / np.maximum(cnt, 1), np.nan)


def _ranges(t: Array, cols: dict[str, Array], w: int) -> tuple[Array, dict[str, Array]]:
    """Rows ``(m w,)`` as ``m`` ranges of ``w`` -> two rows a range: its first and last ``t``;
    each column's minimum and maximum in their time order (NaNs left out; NaN if all are)."""
    m = len(t) // w
    T = t[:m * w].reshape(m, w)
    tt = np.stack((T[:, 0], T[:, -1]), axis=1).ravel()
    out = {}
    for k, x in cols.items():
        X = x[:m * w].reshape(m, w)
        nan = np.isnan(X)
        i_lo = np.argmin(np.where(nan, np.inf, X), axis=1)
        i_hi = np.argmax(np.where(nan, -np.inf, X), axis=1)
        idx = np.sort(np.stack((i_lo, i_hi), axis=1), axis=1)
        out[k] = np.take_along_axis(X, idx, axis=1).ravel()
    return tt, out


class PlotDigest:
    """The columns of a run's plot, fed block by block (module doc). ``t_s`` (s) sets the
    trailing means' lengths; ``rows`` the most rows held (default :data:`ROWS`)."""

    def __init__(self, t_s: float, rows: int | None = None) -> None:
        self.limit = max(4, int(ROWS if rows is None else rows))
        self.span = 1
        """Samples a new range takes (1: every row is kept)."""
        self.names: list[str] | None = None
        self._means = {k: TrailingMean(round(w / t_s)) for k, w in MEANS}
        self._rows: dict[str, list[Array]] = {}
        self._n = 0  # rows held
        self._held: dict[str, Array] = {}  # the samples of the range being filled

    def feed(self, block: Mapping[str, ArrayLike]) -> None:
        """The next rows (``t`` increasing); columns the plot does not draw are ignored."""
        if self.names is None:
            self.names = [k for k in PLOT_COLUMNS if k in block]
            self.names += [f"{k}_mean" for k, _ in MEANS if k in block]
            self._rows = {k: [] for k in self.names}
        cols = {k: np.asarray(block[k], dtype=np.float64) for k in PLOT_COLUMNS if k in block}
        if not len(cols["t"]):
            return
        for k, _ in MEANS:
            if k in cols:
                cols[f"{k}_mean"] = self._means[k](cols[k])
        if self.span == 1:
            self._append(cols)
        else:
            if self._held:
                cols = {k: np.concatenate((self._held[k], x)) for k, x in cols.items()}
            m = len(cols["t"]) // self.span * self.span
            if m:
                t, v = _ranges(cols["t"], {k: x for k, x in cols.items() if k != "t"}, self.span)
                self._append({"t": t, **v})
            self._held = {k: x[m:] for k, x in cols.items()}
        while self._n > self.limit:
            self._halve()

    def _append(self, cols: dict[str, Array]) -> None:
        for k, x in cols.items():
            self._rows[k].append(x)
        self._n += len(cols["t"])

    def _joined(self) -> dict[str, Array]:
        return {k: np.concatenate(x) if x else np.zeros(0) for k, x in self._rows.items()}

    def _halve(self) -> None:
        """Merge neighbouring ranges (rows kept whole become ranges of two samples first)."""
        cols = self._joined()
        t = cols.pop("t")
        if self.span == 1:  # each pair of samples is a range already: its minimum and maximum
            if len(t) % 2:  # in time order; an odd last sample starts the next range
                self._held = {"t": t[-1:], **{k: x[-1:] for k, x in cols.items()}}
                t, cols = t[:-1], {k: x[:-1] for k, x in cols.items()}
            self.span = 2
        p = len(t) // 4  # pairs of ranges; an odd last range stays as it is
        tt, merged = _ranges(t[:4 * p], {k: x[:4 * p] for k, x in cols.items()}, 4)
        self._rows = {"t": [tt, t[4 * p:]], **{k: [merged[k], cols[k][4 * p:]] for k in cols}}
        self._n = len(tt) + len(t) - 4 * p
        self.span *= 2

    def columns(self) -> dict[str, Array]:
        """The plot's columns: every row fed (without the means, which the plot computes), or
        the ranges' rows with the means (module doc)."""
        if self.names is None:
            return {}
        cols = self._joined()
        if self.span == 1:
            return {k: x for k, x in cols.items() if not k.endswith("_mean")}
        held = self._held
        if held and len(held["t"]):
            t, v = _ranges(held["t"], {k: x for k, x in held.items() if k != "t"}, len(held["t"]))
            cols = {k: np.concatenate((x, t if k == "t" else v[k])) for k, x in cols.items()}
        return cols

    @property
    def rows(self) -> int:
        """Rows held now."""
        return self._n + (len(self._held["t"]) if self._held else 0)

