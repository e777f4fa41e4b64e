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
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from thermoskin.skin import Skin, tc_fresh_bit

Array = NDArray[np.float64]
Ints = NDArray[np.int64]

FRESH_T_P = 2  # the tank's fresh bit


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
    n, P = T_p.shape
    T_in = T_p.copy()
    fr = np.full((n, P), 7, dtype=np.int64) if fresh is None else fresh.astype(np.int64).copy()
    for lp in skin.loops:
        x = displacement(v[:, lp.patches[0]], t_s)
        for q, i in enumerate(lp.patches):
            pipe = lp.pipes[q]
            if q == 0:
                src, sbit = T_p[:, i], fr[:, i] & FRESH_T_P
            else:
                u = lp.patches[q - 1]
                j = source_thermocouple(skin, u)
                src = T_w[j][:, u]
                sbit = fr[:, u] & tc_fresh_bit(j)
            if pipe.length <= 0.0 and q == 0:
                continue  # fed straight from the tank: the tank is the inlet
            kp = delayed(x, pipe.length)
            before = kp < 0
            kk = np.where(before, 0, kp)
            age = (np.arange(n) - kk) * t_s
            keep = 0.0 if pipe.tau_loss <= 0.0 else 1.0 / pipe.tau_loss
            val = T_a[:, i] + (src[kk] - T_a[:, i]) * np.exp(-age * keep)
            val[before] = src[0]
            new = np.ones(n, dtype=bool)
            new[1:] = kk[1:] != kk[:-1]
            f = (sbit[kk] != 0) & new & ~before
            f[0] = True
            T_in[:, i] = val
            fr[:, i] = (fr[:, i] & ~FRESH_T_P) | np.where(f, FRESH_T_P, 0)
    return T_in, fr
