"""The lumped pipe node's misfit on a patch fed through a pipe, taken out of its reading.

The estimator's network (Fig. 3, eqs. 3-7: one pipe node ``T_w``, one sheet node ``T_g``)
answers its inlet water at once, within ``R_w C_w`` (about 26 ms). A patch's pipe is many
cells the water crosses in turn (``physics.spatial``), and the water a patch of a loop is fed
steps every 50 ms (the upstream patch's outlet swings with the pump's on/off chatter, 0.1-0.4 K
peak to peak at the forearm's downstream inlets). The one node leads the reading after every
step and lags it after the next; the size of that misfit follows the size of the inlet's swing
(on the forearm's dorsal4: innovations of 20 mK rms, the thermocouple's noise, while the pump
runs steadily; 30-50 mK rms while it chatters with a large swing), and the detector takes it
for touches.

Both models are linear, and the misfit is theirs, not the touch's: driven by the same inputs
(the patch's inlet water ``T_in``, the air ``T_a``, the pump ``v``, sample by sample, held over
each sample) and no touch, the spatial model's ``T_w`` thermocouple cell ``y_s`` and the
lumped pipe node ``y_l`` differ by::

    c(k) = y_s(k) - y_l(k)

and the reading the lumped estimator is given is ``T_w(k) - c(k)``, with ``T_in`` itself as its
inlet: what the lumped model would have read with the same inlet, plus the touch's own
response. ``c`` is computed exactly per sample (both systems discretised together by one
matrix exponential per pump velocity, zero-order hold), from the steady state of the first
sample's inputs, block by block with its state kept (:class:`TransportCorrection`), so a live
run and the whole log give the same values. A patch fed straight from its tank (no pipe) is
not corrected: its inlet is the tank, which does not step with the chatter, and its
estimator's pump-cycle correction covers the same misfit (``skin_observe``).

On the simulated skin the spatial model is the plant's own, so ``c`` is exact there up to the
inlet's measurement noise; on a real skin it is as good as the spatial model (its cells, its
sheet's conduction, its flow resistance).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from thermoskin._jit import njit
from thermoskin.params import SkinParams
from thermoskin.physics.convection import FlowResistance
from thermoskin.physics.network import discretize, state_space
from thermoskin.physics.spatial import spatial_state_space
from thermoskin.skin.layout import Skin

Array = NDArray[np.float64]


@njit(cache=True, fastmath=True)
def _run(F, G, iv, cell, x, T_in, T_a, out):  # pragma: no cover - compiled
    """``out[k] = x[cell] - x[-2]`` (spatial thermocouple cell minus lumped pipe node), then
    ``x = F[iv[k]] x + G[iv[k]] [T_in[k], T_a[k]]``, for every sample of the block."""
    n = x.shape[0]
    xn = np.empty(n)
    for k in range(iv.shape[0]):
        out[k] = x[cell] - x[n - 2]
        j = iv[k]
        a, b = T_in[k], T_a[k]
        for r in range(n):
            s = G[j, r, 0] * a + G[j, r, 1] * b
            for c in range(n):
                s += F[j, r, c] * x[c]
            xn[r] = s
        for r in range(n):
            x[r] = xn[r]


def joint_system(skin: Skin, i: int, net: SkinParams, v: float) -> tuple[Array, Array, int]:
    """``(A, B, cell)``: patch ``i``'s spatial model (its loop's flow at ``v``, the loop's still
    ends) and the lumped network ``net`` side by side, ``x = [spatial; T_w, T_g]``, input
    ``[T_in, T_a]``; ``cell`` the spatial state read by the ``T_w`` thermocouple."""
    p = skin.patches[i]
    lp = skin.loops[p.loop]
    R_w = FlowResistance(lp.cfg.skin)(v)
    ends = (p.index == lp.patches[0], p.index == lp.patches[-1])
    As, Bs = spatial_state_space(p.skin, p.spatial, v, R_w, still_ends=ends)
    Al, Bl = state_space(net, R_w)
    n = As.shape[0]
    A = np.zeros((n + 2, n + 2))
    A[:n, :n] = As
    A[n:, n:] = Al
    B = np.zeros((n + 2, 2))
    B[:n] = Bs[:, :2]
    B[n:] = Bl[:, :2]
    return A, B, p.tc_cells[0]


class TransportCorrection:
    """``c(k)`` of the module doc for the patches ``patches`` of ``skin`` (``nets[i]`` the lumped
    network of patch ``i``'s estimator), block by block: :meth:`push` the next rows, get ``c``
    ``(m, P)``, zero for the patches not corrected."""

    def __init__(self, skin: Skin, t_s: float, nets: Sequence[SkinParams], patches: Sequence[int]) -> None:
        self.skin, self.t_s = skin, float(t_s)
        self.nets = list(nets)
        self.patches = [int(i) for i in patches]
        self._x: dict[int, Array] = {}
        self._last: dict[int, tuple[float, float, float]] = {}  # last finite T_in, T_a, v
        self._mats: dict[int, dict[float, tuple[Array, Array, Array, Array]]] = {i: {} for i in self.patches}
        self._cell: dict[int, int] = {}

    def _discrete(self, i: int, v: float) -> tuple[Array, Array, Array, Array]:
        """Patch ``i``'s joint system at ``v``: ``(Phi, Gamma)`` (zero-order hold) and ``(A, B)``."""
        got = self._mats[i].get(v)
        if got is None:
            A, B, self._cell[i] = joint_system(self.skin, i, self.nets[i], v)
            got = (*discretize(A, B, self.t_s), A, B)
            self._mats[i][v] = got
        return got

    def push(self, T_in: Array, T_a: Array, v: Array) -> Array:
        """The correction over the next ``m`` rows (``(m, P)`` inputs; NaN inputs hold the last
        finite ones)."""
        m, P = T_in.shape
        out = np.zeros((m, P))
        if m == 0:
            return out
        for i in self.patches:
            cols = []
            last = self._last.get(i)
            for col, c in enumerate((T_in[:, i], T_a[:, i], v[:, i])):
                x = np.asarray(c, dtype=float)
                ok = np.isfinite(x)
                if not ok.all():
                    idx = np.where(ok, np.arange(m), -1)
                    np.maximum.accumulate(idx, out=idx)
                    fill = last[col] if last is not None else (x[ok][0] if ok.any() else 0.0)
                    x = np.where(idx >= 0, x[np.maximum(idx, 0)], fill)
                cols.append(x)
            ti, ta, vv = cols
            self._last[i] = (float(ti[-1]), float(ta[-1]), float(vv[-1]))
            vals, iv = np.unique(vv, return_inverse=True)
            mats = [self._discrete(i, float(x)) for x in vals]
            F = np.stack([m_[0] for m_ in mats])
            G = np.stack([m_[1] for m_ in mats])
            x = self._x.get(i)
            if x is None:  # the steady state of the first sample's inputs
                _, _, A, B = self._discrete(i, float(vv[0]))
                x = np.linalg.solve(A, -B @ np.array([ti[0], ta[0]]))
                self._x[i] = x
            col = np.empty(m)
            _run(F, G, iv.astype(np.int64), self._cell[i], x, ti, ta, col)
            out[:, i] = col
        return out
