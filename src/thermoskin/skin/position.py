"""Where along its pipe a patch was touched: a likelihood over a grid of positions.

The patch's spatial model (``physics.spatial``: cells along the pipe, the sheet over them, the
water advected from the inlet to the outlet while the pump runs) is linear for a given pump
sequence. Over a window around a contact, with the log's own inputs (the patch's inlet water
``T_in``, the air ``T_a`` and the pump ``v``, sample by sample), each thermocouple ``j`` reads

    y_j(t) = y0_j(t) + c_j + a h_j(t; s) + noise

``y0`` the model's response to the inputs alone (run from the steady state of its inputs
``BURN_S`` before the window, so its own start-up is over), ``c_j`` an offset
per thermocouple (the model's error; fitted on the samples before the onset), ``h_j(t; s)``
the response to the estimator's heat ``dq_i_hat(t)`` (its time course: a touch's heat falls as
the sheet under it warms) put into the sheet at position ``s`` (the contact's footprint on the
cells, ``contact_cells``) from the onset on, ``a`` its scale (fitted). For every
``s`` on the grid, ``a`` is the least-squares fit and ``RSS(s)`` the residual; the likelihood is
``exp(-(RSS(s) - RSS_min) / (2 sigma^2))`` with ``sigma^2 = RSS_min / (m - 2)`` (the noise as the
best fit leaves it, so a model error widens the answer rather than hiding in it); its mean
and standard deviation over the grid (a uniform prior) are the position and its uncertainty.

**What the thermocouples can tell.** With the pump running, the water carries all of a touch's
heat past an outlet thermocouple wherever the touch is: one thermocouple at the outlet sees
*how much* heat, barely *where* (the transit through the patch is short against the readings'
noise). A second thermocouple upstream of the outlet (at the middle, or the inlet) sees only
the heat that entered upstream of it: the ratio of the two rises places the touch. With the
pump stopped, the heat spreads by conduction only and the thermocouples' rises fall with the
distance (the paper's Fig. 19), but the strength of the touch and its distance trade off
against each other for one thermocouple. The answer is left empty (NaN) where the likelihood
is not narrower than the grid itself (its sd above :data:`IDENTIFIABLE` of the uniform
prior's), as it is for one thermocouple with the pump running, and when the pump did not run
during the contact (no flow to separate the thermocouples' shares).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from thermoskin.physics.convection import FlowResistance
from thermoskin.physics.expm import expm
from thermoskin.physics.spatial import contact_cells, spatial_state_space, spatial_steady_state
from thermoskin.skin.layout import Patch, Skin

Array = NDArray[np.float64]

GRID = 25
"""Candidate places along the footprint's travel."""
IDENTIFIABLE = 0.6
"""A position is reported when its sd is below this share of the uniform prior's sd."""
PRE_S = 1.5
"""Seconds of the window before the onset (the offsets are fitted on them)."""
MAX_S = 4.0
"""Seconds of the contact used at most."""
BURN_S = 1.0
"""Seconds the model runs before the window, from the steady state of its first inputs: the
model's own start-up (the water's crossing, the sheet settling: +0.7 K at the start of a window
that began with the pump stopped, gone after 0.25 s) is not fitted as the offset."""


@dataclass(frozen=True)
class Position:
    """Position (m from the inlet) and its standard deviation (m); NaN where not identifiable;
    ``sd_fit`` the likelihood's own sd (also where it was not narrow enough to report)."""

    mean: float
    sd: float
    sd_fit: float
    heat: float


NAN_POSITION = Position(math.nan, math.nan, math.nan, math.nan)


def window(k_on: int, k_off: int, n: int, t_s: float) -> tuple[int, int, int]:
    """The samples :meth:`PatchLocator.locate` reads for a contact from sample ``k_on`` to
    ``k_off`` of a log of ``n``: the model's start-up from ``kb``, the fitted window ``k0`` to
    ``k1`` (:data:`BURN_S`, :data:`PRE_S` before the onset, at most :data:`MAX_S` of the contact).
    Only ``[kb, k1)`` is read, so a log streamed by (``observe --skin``) keeps just those samples."""
    k0 = max(0, k_on - round(PRE_S / t_s))
    k1 = min(n, k_off, k_on + round(MAX_S / t_s))
    return max(0, k0 - round(BURN_S / t_s)), k0, k1


class PatchLocator:
    """The spatial model of one patch of a skin, discretised for the pump running and stopped."""

    def __init__(self, skin: Skin, i: int, t_s: float, grid: int = GRID) -> None:
        p: Patch = skin.patches[i]
        lp = skin.loops[p.loop]
        self.patch = p
        self.t_s = t_s
        self.flow = FlowResistance(lp.cfg.skin)
        self.ends = (p.index == lp.patches[0], p.index == lp.patches[-1])
        sp = p.spatial
        N, f = sp.n_cells, sp.footprint
        par = np.linspace(0.0, 1.0, grid)
        self.positions = p.length * (1.0 - (0.5 * f + par * (1.0 - f))) if f < 1.0 else \
            np.full(grid, 0.5 * p.length)
        self.shares = [contact_cells(float(x), N, f) for x in par]
        self.tc_cells = p.tc_cells
        self._mats: dict[float, tuple[Array, Array, Array]] = {}

    def _matrices(self, v: float) -> tuple[Array, Array, Array]:
        """``(Phi, Gamma_u, Gamma_q)`` at pump velocity ``v``: ``Gamma_u`` for ``[T_in, T_a]``,
        ``Gamma_q`` one column per grid position (1 W on its cells)."""
        got = self._mats.get(v)
        if got is not None:
            return got
        p = self.patch
        A, B = spatial_state_space(p.skin, p.spatial, v, self.flow(v), still_ends=self.ends)
        n = A.shape[0]
        N = p.spatial.n_cells
        Bq = np.zeros((n, len(self.shares)))
        cap_g = p.skin.C_g / N
        for c, sh in enumerate(self.shares):
            for cell, w in sh.items():
                Bq[N + cell, c] = w / cap_g
        m = 2 + Bq.shape[1]
        aug = np.zeros((n + m, n + m))
        aug[:n, :n] = A
        aug[:n, n:n + 2] = B[:, :2]
        aug[:n, n + 2:] = Bq
        E = expm(aug * self.t_s)
        got = (E[:n, :n], E[:n, n:n + 2], E[:n, n + 2:])
        self._mats[v] = got
        return got

    def locate(self, k_on: int, k_off: int, T_in: Array, T_a: Array, v: Array, Y: list[Array],
               fresh: list[NDArray[np.bool_]] | None = None, dq: Array | None = None) -> Position:
        """The position of a contact from sample ``k_on`` to ``k_off`` (module doc), from the
        patch's inlet ``T_in``, air ``T_a``, pump ``v``, thermocouple readings ``Y[j]`` and the
        estimated heat ``dq`` (all over the whole log; ``fresh[j]`` marks the readings to use,
        default all; ``dq`` None: a step of 1 W)."""
        kb, k0, k1 = window(k_on, k_off, len(v), self.t_s)
        if k1 - k_on < 2 or k_on - k0 < 2:
            return NAN_POSITION
        vv = np.nan_to_num(v[k0:k1])
        if not np.any(vv[k_on - k0:] > 0.0):
            return NAN_POSITION  # the pump did not run during the contact
        vb = np.nan_to_num(v[kb:k0])
        mats = {float(x): self._matrices(float(x)) for x in np.unique(np.concatenate((vb, vv)))}
        p = self.patch
        v_start = float(vb[0]) if len(vb) else float(vv[0])
        x = spatial_steady_state(p.skin, p.spatial, v_start, self.flow(v_start),
                                 np.array([T_in[kb], T_a[kb], 0.0, 0.0]))
        for k in range(kb, k0):  # the model's own start-up, before the window
            F, Gu, _ = mats[float(vb[k - kb])]
            x = F @ x + Gu @ np.array([T_in[k], T_a[k]])
        G = len(self.shares)
        H = np.zeros((x.size, G))
        m = k1 - k0
        cells = list(self.tc_cells)
        y0 = np.empty((m, len(cells)))
        h = np.empty((m, len(cells), G))
        for r in range(m):
            k = k0 + r
            y0[r] = x[cells]
            h[r] = H[cells]
            F, Gu, Gq = mats[float(vv[r])]
            x = F @ x + Gu @ np.array([T_in[k], T_a[k]])
            H = F @ H + Gq * (1.0 if dq is None else float(dq[k])) if k >= k_on else F @ H
        pre = slice(0, k_on - k0)
        rs, hs = [], []
        for j in range(len(cells)):
            y = Y[j][k0:k1]
            use = np.isfinite(y)
            if fresh is not None:
                use &= fresh[j][k0:k1]
            e = y - y0[:, j]
            if not use[pre].any():
                continue
            c = float(np.mean(e[pre][use[pre]]))
            post = use.copy()
            post[pre] = False
            if not post.any():
                continue
            rs.append(e[post] - c)
            hs.append(h[post, j, :])
        if not rs:
            return NAN_POSITION
        r_all = np.concatenate(rs)
        h_all = np.concatenate(hs)
        hh = np.einsum("mg,mg->g", h_all, h_all)
        hr = h_all.T @ r_all
        ok = hh > 0.0
        a = np.where(ok, hr / np.where(ok, hh, 1.0), 0.0)
        rss = float(r_all @ r_all) - np.where(ok, hr * a, 0.0)
        dof = max(1, len(r_all) - 2)
        s2 = max(float(rss.min()) / dof, 1e-12)
        ll = -(rss - rss.min()) / (2.0 * s2)
        w = np.exp(ll - ll.max())
        w /= w.sum()
        mean = float(w @ self.positions)
        sd = float(math.sqrt(max(w @ (self.positions - mean) ** 2, 0.0)))
        heat = float(w @ a)
        prior = float(np.std(self.positions))
        if prior > 0 and sd > IDENTIFIABLE * prior:
            return Position(math.nan, math.nan, sd, heat)
        return Position(mean, sd, sd, heat)
