"""Many thermocouple boards read together, every sample, in one compiled loop.

A skin of many patches has a board per thermocouple and per loop a tank and an air board;
stepping :class:`~thermoskin.sim.sensors.Board` objects one by one costs about 0.4 µs each
per sample. :class:`BoardBank` holds the same boards as arrays and reads them all at once
(``numba``): each board's readings are exactly its :meth:`Board.read`'s (lag, conversions
with jitter, noise, quantum, hold; the same noise and jitter streams, drawn in the same
order: a block of :data:`~thermoskin.sim.sensors.BLOCK` normals at a time, one uniform per
conversion instant), which the tests check.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from thermoskin._jit import njit
from thermoskin.sim.sensors import BLOCK, Board

Array = NDArray[np.float64]
JITTER_CHUNK = 64
"""Jitter draws taken from a board's stream at a time (its stream's order is kept)."""


@njit(cache=True)
def _read(x, noise, pos, y, a, b, lagged, noise_T, quantum, period, t_s, jit, jpos, jlen, jidx, nxt, k,
          value, fresh, offset):  # pragma: no cover - compiled
    """One sample of every board (``Board.read``, term for term); returns False if a board ran
    out of jitter draws before scheduling its next conversion (then nothing was changed)."""
    nb = x.shape[0]
    for i in range(nb):  # jitter draws needed this sample must be there first
        if k >= nxt[i] and period[i] > 0.0 and jpos[i] + 8 > jlen[i]:
            return False
    for i in range(nb):
        xi = x[i]
        if lagged[i]:
            yi = y[i]
            if yi != yi:
                yi = xi
            y[i] = a[i] * yi + b[i] * xi
        else:
            yi = xi
        if k < nxt[i]:
            fresh[i] = False
            continue
        if period[i] > 0.0:
            j = jidx[i]
            while True:
                j += 1
                u = jit[i, jpos[i]]
                jpos[i] += 1
                kn = math.floor((j * period[i] + u) / t_s + 0.5)
                if kn > k:
                    break
            jidx[i] = j
            nxt[i] = kn
        r = yi + offset[i] + noise_T[i] * noise[i, pos]
        q = quantum[i]
        if q > 0.0:
            r = q * math.floor(r / q + 0.5)
        value[i] = r
        fresh[i] = True
    return True


class BoardBank:
    """The boards ``boards`` (each from its own seeds), read together: :meth:`read` per sample."""

    def __init__(self, boards: list[Board]) -> None:
        self.boards = boards
        nb = len(boards)
        t_s = {b.t_s for b in boards if math.isfinite(b.t_s)}
        self.t_s = t_s.pop() if t_s else 1.0
        self.a = np.array([b._a for b in boards])
        self.b = np.array([b._b for b in boards])
        self.lagged = np.array([b._lagged for b in boards])
        self.noise_T = np.array([b.noise_T for b in boards])
        self.offset = np.array([b.offset for b in boards])
        self.quantum = np.array([b.quantum_T for b in boards])
        self.period = np.array([b.period for b in boards])
        self.J = np.array([b.jitter for b in boards])
        self.value = np.full(nb, math.nan)
        self.fresh = np.zeros(nb, dtype=np.bool_)
        self.reset()

    def reset(self) -> None:
        """Every board back to sample 0 (its noise and jitter streams from their seeds)."""
        nb = len(self.boards)
        self._noise_rng = [np.random.default_rng(b._noise_seed) for b in self.boards]
        self._jitter_rng = [np.random.default_rng(b._jitter_seed) for b in self.boards]
        self.noise = np.zeros((nb, BLOCK))
        self.y = np.full(nb, math.nan)
        self.nxt = np.zeros(nb, dtype=np.int64)
        self.jidx = np.zeros(nb, dtype=np.int64)
        self.jit = np.zeros((nb, 0))
        self.jpos = np.zeros(nb, dtype=np.int64)
        self.jlen = np.zeros(nb, dtype=np.int64)
        self.value[:] = math.nan
        self.fresh[:] = False
        self.k = 0
        self._refill_jitter()

    def _refill_jitter(self) -> None:
        """Keep each periodic board's unused draws and add :data:`JITTER_CHUNK` more."""
        nb = len(self.boards)
        keep = [self.jit[i, self.jpos[i]:self.jlen[i]] for i in range(nb)]
        new = []
        for i in range(nb):
            J = self.J[i]
            if self.period[i] > 0.0:
                rng = self._jitter_rng[i]
                more = rng.uniform(-J, J, size=JITTER_CHUNK) if J > 0.0 else np.zeros(JITTER_CHUNK)
            else:
                more = np.zeros(0)
            new.append(np.concatenate([keep[i], more]))
        width = max(len(r) for r in new)
        self.jit = np.zeros((nb, max(width, 1)))
        for i, r in enumerate(new):
            self.jit[i, :len(r)] = r
            self.jlen[i] = len(r)
        self.jpos[:] = 0

    def read(self, x: Array) -> None:
        """One sample: the readings of the true temperatures ``x`` (one per board) into
        ``value``, ``fresh`` which converted."""
        k = self.k
        pos = k % BLOCK
        if pos == 0:
            for i, rng in enumerate(self._noise_rng):
                self.noise[i] = rng.standard_normal(BLOCK)
        while not _read(x, self.noise, pos, self.y, self.a, self.b, self.lagged, self.noise_T, self.quantum,
                        self.period, self.t_s, self.jit, self.jpos, self.jlen, self.jidx, self.nxt, k,
                        self.value, self.fresh, self.offset):
            self._refill_jitter()
        self.k = k + 1
