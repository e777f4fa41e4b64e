"""Each patch's inlet water from the log: the cross-talk of shared water removed at its source.

The one-patch estimator takes ``T_p``, the water entering the pipe, as a measured input (on the
paper's skin the tank feeds the pipe directly). On a loop of several patches the water entering
patch ``q`` is not the tank's: it is what left patch ``q - 1`` (or the tank, for the first),
carried through the connecting pipe between them. A touch upstream warms that water; fed to the
downstream patch as its inlet, the warmer water explains the warmer outlet, and the touch is
not seen again downstream.

The pipe is a plug flow (``skin.Pipe``): the water at its far end at sample ``k`` left its near
end at the sample ``k'`` when the water pumped since was the pipe's length,

    x(k) = sum_{j<k} v_j t_s          (the loop's pump, ``v`` of row ``j`` held over [t_j, t_j+1))
    k'   = the last sample with x(k') <= x(k) - L

and it cooled towards the air meanwhile (``Pipe.attenuation``)::

    T_in(k) = T_a(k) + (T_src(k') - T_a(k)) exp(-(t_k - t_k') / tau_loss)

``T_src`` is the upstream patch's outlet thermocouple (the one nearest its outlet) or, for the
first patch, the tank ``T_p``. While the pump stands, ``k'`` stands too: no new water arrives,
so the inlet gets no fresh reading (the estimator predicts it). A reading of ``T_src`` that was
fresh at ``k'`` is fresh at ``k`` the first time ``k'`` reaches it (bit 2 of ``fresh``). With
no connecting pipe (the paper's single patch) the inlet is the tank itself, unchanged. Before
the log's first ``L`` of water has passed, the inlet is the source's first reading.

**Between an outlet's readings.** A thermocouple board slower than the loop reads an upstream
outlet every few samples; the water that passed it in between was not read. Where the water
between two readings is at most :data:`INTERP_M` long and the later reading had come by ``k``
(it has: the water took the connecting pipe's length to arrive), ``T_src(k')`` is the linear
interpolation of the two, and fresh: the inlet then follows the water's fronts (a pump pulse
brings warmer water) instead of a staircase the downstream patch took for touches. Longer gaps
are held as before (across 1.4 mm of water, 100 Hz boards, the interpolated fronts made more
false alarms, not fewer: docs/skin.md); the tank's own readings are never interpolated (its
noise, turned into ramps, gave the loops' first patches false alarms). With a reading every
sample nothing changes.

**Chunk by chunk.** Every quantity above is causal: ``x(k)`` sums the past, ``k' <= k``. A live
run feeds the rows block by block (:class:`InletStream`), keeping of the past only what is still
to come out of the pipes (the samples from the oldest ``k'`` on); the whole log
(:func:`inlet_inputs`) is the same stream fed in one block, so both give the same values to the
bit (``x(k)`` is summed in the same order).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from thermoskin.skin.layout import Skin, tc_fresh_bit

Array = NDArray[np.float64]
Ints = NDArray[np.int64]

FRESH_T_P = 2  # the tank's fresh bit
INTERP_M = 1e-3
"""Longest water (m) between two readings of an upstream outlet that the inlet interpolates
across (module doc): 200 Hz boards at full flow leave 0.7 mm, 100 Hz boards 1.4 mm."""


def source_thermocouple(skin: Skin, i: int) -> int:
    """Index (0: ``T_w``, 1: ``T_w2``, ...) of patch ``i``'s thermocouple nearest its outlet."""
    tcs = skin.patches[i].thermocouples
    return max(range(len(tcs)), key=lambda j: tcs[j])


def displacement(v: Array, t_s: float) -> Array:
    """``x(k)``, m: the water pumped before sample ``k`` (``v`` held over each interval)."""
    v = np.nan_to_num(np.asarray(v, dtype=float), nan=0.0)
    x = np.empty(len(v))
    x[0] = 0.0
    np.cumsum(v[:-1] * t_s, out=x[1:])
    return x


def delayed(x: Array, length: float) -> Ints:
    """``k'`` per sample (module doc): the sample whose water reaches ``length`` m further now
    (-1 before any has)."""
    if length <= 0.0:
        return np.arange(len(x), dtype=np.int64)
    return (np.searchsorted(x, x - length * (1.0 - 1e-12), side="right") - 1).astype(np.int64)


def inlet_inputs(skin: Skin, t_s: float, T_w: list[Array], T_p: Array, v: Array, T_a: Array,
                 fresh: Ints | None) -> tuple[Array, Ints]:
    """Each patch's inlet water and the fresh bits that go with it, ``(T_in, fresh_in)`` of shape
    ``(n, P)`` (module doc). ``T_w[j]`` is thermocouple ``j``'s ``(n, P)`` array; ``T_p, v, T_a``
    and ``fresh`` (None: every reading fresh) are ``(n, P)``."""
    return InletStream(skin, t_s).push(T_w, T_p, v, T_a, fresh)


def _through(length: float, tau_loss: float, st: _PipeState, xh: Array, x_new: Array, base: int, kg: Ints,
             k0: int, sh: Array, bh: Ints, T_a: Array, t_s: float, interp: bool
             ) -> tuple[Array, NDArray[np.bool_]]:
    """One pipe of ``length`` over a block (module doc): the water out of it and its fresh flags;
    ``st`` keeps the last ``k'`` and the source's reading at or before it. ``interp``: the source
    is an outlet, interpolated between its readings (module doc)."""
    if length <= 0.0:
        kp = kg.copy()
    else:
        kp = (np.searchsorted(xh, x_new - length * (1.0 - 1e-12), side="right") - 1).astype(np.int64)
        kp = np.where(kp < 0, -1, kp + base)
    before = kp < 0
    kk = np.where(before, 0, kp)
    age = (kg - kk) * t_s
    keep = 0.0 if tau_loss <= 0.0 else 1.0 / tau_loss
    j = kk - base
    src, known = sh[j], bh[j] != 0
    read = np.flatnonzero(bh != 0)
    if interp and len(read):
        src, known = _between_readings(sh, xh, read, j, kg - base, src, known)
    val = T_a + (src - T_a) * np.exp(-age * keep)
    val[before] = st.src0
    new = np.empty(len(kg), dtype=bool)
    new[0] = k0 == 0 or kk[0] != st.kk_last
    new[1:] = kk[1:] != kk[:-1]
    f = known & new & ~before
    if k0 == 0:
        f[0] = True
    st.kk_last = int(kk[-1])
    r = np.searchsorted(read, st.kk_last - base, side="right") - 1  # the history still needed
    st.kk_keep = int(read[r]) + base if r >= 0 else st.kk_last
    return val, f


def _between_readings(sh: Array, xh: Array, read: Ints, j: Ints, now: Ints, src: Array,
                      known: NDArray[np.bool_]) -> tuple[Array, NDArray[np.bool_]]:
    """``src`` and ``known`` (the source at history rows ``j``, a reading there) with the rows
    between two readings interpolated where the later one had come by row ``now`` and the water
    between them is at most :data:`INTERP_M` (module doc)."""
    r = np.searchsorted(read, j, side="right") - 1  # the reading at or before j
    p = read[np.maximum(r, 0)]
    n = read[np.minimum(r + 1, len(read) - 1)]
    a, b = sh[p], sh[n]
    ok = ((r >= 0) & (r + 1 < len(read)) & (n <= now) & (xh[n] - xh[p] <= INTERP_M)
          & np.isfinite(a) & np.isfinite(b))
    if not ok.any():
        return src, known
    src = src.copy()
    w = (j[ok] - p[ok]) / (n[ok] - p[ok])
    src[ok] = a[ok] + w * (b[ok] - a[ok])
    return src, known | ok


class _PipeState:
    """One pipe's stream: its source's first reading, the last ``k'`` and the source's reading at
    or before it (global indices: the history is kept from there)."""

    __slots__ = ("kk_keep", "kk_last", "src0")

    def __init__(self) -> None:
        self.src0 = 0.0
        self.kk_last = -1
        self.kk_keep = -1


class InletStream:
    """:func:`inlet_inputs` block by block (module doc): :meth:`push` the next rows, get their inlets."""

    def __init__(self, skin: Skin, t_s: float) -> None:
        self.skin, self.t_s = skin, float(t_s)
        self.k = 0  # samples pushed so far
        L = len(skin.loops)
        self._x_last = [0.0] * L   # x of the last sample pushed
        self._a_last = [0.0] * L   # its v t_s: the next sample's increment
        self._base = [0] * L       # global index of each loop's history's first sample
        self._x: list[Array] = [np.zeros(0)] * L
        self._src: list[list[Array]] = [[np.zeros(0)] * len(lp.patches) for lp in skin.loops]
        self._sbit: list[list[Ints]] = [[np.zeros(0, dtype=np.int64)] * len(lp.patches) for lp in skin.loops]
        self._pipe = [[_PipeState() for _ in lp.patches] for lp in skin.loops]

    def push(self, T_w: list[Array], T_p: Array, v: Array, T_a: Array,
             fresh: Ints | None) -> tuple[Array, Ints]:
        """The next ``m`` rows (arrays ``(m, P)`` as :func:`inlet_inputs`): their ``(T_in, fresh_in)``."""
        m, P = T_p.shape
        t_s = self.t_s
        k0 = self.k
        T_in = T_p.copy()
        fr = np.full((m, P), 7, dtype=np.int64) if fresh is None else fresh.astype(np.int64).copy()
        if m == 0:
            return T_in, fr
        kg = np.arange(k0, k0 + m, dtype=np.int64)
        for li, lp in enumerate(self.skin.loops):
            a = np.nan_to_num(np.asarray(v[:, lp.patches[0]], dtype=float), nan=0.0) * t_s
            if k0 == 0:
                x_new = np.empty(m)
                x_new[0] = 0.0
                np.cumsum(a[:-1], out=x_new[1:])
            else:  # x(k) = x(k-1) + v(k-1) t_s, summed in the whole log's order
                x_new = np.cumsum(np.concatenate(([self._x_last[li], self._a_last[li]], a[:-1])))[1:]
            self._x_last[li], self._a_last[li] = float(x_new[-1]), float(a[-1])
            base = self._base[li]
            xh = np.concatenate((self._x[li], x_new))
            keep_from = k0 + m - 1  # the oldest sample a pipe still needs
            for q, i in enumerate(lp.patches):
                pipe = lp.pipes[q]
                if q == 0:
                    src, sbit = T_p[:, i], fr[:, i] & FRESH_T_P
                else:
                    u = lp.patches[q - 1]
                    j = source_thermocouple(self.skin, u)
                    src = T_w[j][:, u]
                    sbit = fr[:, u] & tc_fresh_bit(j)
                sh = np.concatenate((self._src[li][q], np.asarray(src, dtype=float)))
                bh = np.concatenate((self._sbit[li][q], sbit.astype(np.int64)))
                self._src[li][q], self._sbit[li][q] = sh, bh
                st = self._pipe[li][q]
                if k0 == 0:
                    st.src0 = float(src[0])
                if pipe.length <= 0.0 and q == 0:
                    continue  # fed straight from the tank: the tank is the inlet
                val, f = _through(pipe.length, pipe.tau_loss, st, xh, x_new, base, kg, k0, sh, bh, T_a[:, i],
                                  t_s, q > 0)
                keep_from = min(keep_from, st.kk_keep)
                T_in[:, i] = val
                fr[:, i] = (fr[:, i] & ~FRESH_T_P) | np.where(f, FRESH_T_P, 0)
            cut = max(keep_from - base, 0)
            self._base[li] = base + cut
            self._x[li] = xh[cut:]
            for q in range(len(lp.patches)):
                self._src[li][q] = self._src[li][q][cut:]
                self._sbit[li][q] = self._sbit[li][q][cut:]
        self.k = k0 + m
        return T_in, fr
