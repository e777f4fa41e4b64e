"""The lumped pipe node's missing transport: how much later a patch's outlet answers its inlet.

The estimator's network (eq. 10's pipe node, ``C_w dT_w/dt = (T_p - T_w)/R_w + ...``) answers a
step of its inlet at once, as ``1 - exp(-t/tau)`` (``tau = C_w / (1/R_w + 1/R_g + 1/R_aw)``,
about 26 ms on the paper's patch). The pipe of a patch is many cells the water crosses in
turn (``physics.spatial``: upwind advection through ``N`` cells, ``C_w R_w`` in all): its
outlet thermocouple sees an inlet step only once the water has crossed, a rise close to a
delayed step. Fed water whose temperature steps every few tens of ms (the upstream patch's
outlet, swinging with the pump's chatter), the lumped node leads the reading at every step,
and the detector takes the misfit for touches.

The inlet the lumped model is given is therefore the water that entered the patch's pipe
``d`` earlier, ``d`` the delay that best aligns the two step responses at the patch's ``T_w``
thermocouple, pump running, in least squares::

    d = argmin_d  int_0^{T} (y_spatial(t) - y_lumped(t - d))^2 dt,   y_lumped = 0 for t < d

(``T`` = 10 ``tau``, both from rest, the sheet included), expressed as the water pumped in
that time, ``lag = d v_on`` (m): with the pump stopped no water moves and the lagged inlet
waits, as the water does. On the forearm's patches ``d`` is 0.29 ``tau`` (7.4 ms, 1.0 mm).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import scipy.linalg

from thermoskin.params import SkinParams
from thermoskin.physics.convection import R_w as flow_R_w
from thermoskin.physics.spatial import SpatialParams, spatial_state_space
from thermoskin.skin import Skin

N_STEPS = 2000
"""Points of the step responses over ``T`` (the delay's resolution: ``T / N_STEPS``)."""


def step_responses(net: SkinParams, spatial_skin: SkinParams, sp: SpatialParams, R_w: float,
                   tc_cell: int, T: float, n: int = N_STEPS) -> tuple[np.ndarray, np.ndarray]:
    """The responses to a unit step of the inlet at ``t_j = j T / n``: the spatial patch's cell
    ``tc_cell`` (``spatial_skin``, ``sp``; pipe ends meeting still water) and the lumped pipe
    node (``net``'s ``C_w, C_g, R_g, R_aw, R_ag``), both with the water at ``R_w``."""
    A, B = spatial_state_space(spatial_skin, sp, 1.0, R_w, still_ends=(False, False))
    Cw, Cg, Rg, Raw, Rag = net.C_w, net.C_g, net.R_g, net.R_aw, net.R_ag
    A2 = np.array([[-(1 / R_w + 1 / Raw + 1 / Rg) / Cw, 1 / (Rg * Cw)],
                   [1 / (Rg * Cg), -(1 / Rg + 1 / Rag) / Cg]])
    b2 = np.array([1 / (R_w * Cw), 0.0])
    h = T / n
    out = []
    for a, b, c in ((A, B[:, 0], tc_cell), (A2, b2, 0)):
        m = a.shape[0]
        M = np.zeros((m + 1, m + 1))  # the step input as a state: z = [x; 1]
        M[:m, :m] = a
        M[:m, m] = b
        E = scipy.linalg.expm(M * h)
        z = np.zeros(m + 1)
        z[m] = 1.0
        y = np.empty(n)
        for k in range(n):
            y[k] = z[c]
            z = E @ z
        out.append(y)
    return out[0], out[1]


def best_delay(y_s: np.ndarray, y_l: np.ndarray) -> int:
    """The shift ``k`` (samples) minimising ``sum (y_s[j] - y_l[j - k])^2`` (``y_l`` 0 before 0)."""
    n = len(y_s)
    errs = [float(np.sum((y_s[k:] - y_l[:n - k]) ** 2) + np.sum(y_s[:k] ** 2)) for k in range(n // 2)]
    return int(np.argmin(errs))


@lru_cache(maxsize=64)
def _lag(net: SkinParams, spatial_skin: SkinParams, sp: SpatialParams, R_w: float, v: float,
         tc_cell: int) -> float:
    tau = net.C_w / (1 / R_w + 1 / net.R_g + 1 / net.R_aw)
    T = 10.0 * tau
    y_s, y_l = step_responses(net, spatial_skin, sp, R_w, tc_cell, T)
    return best_delay(y_s, y_l) * T / N_STEPS * v


def lumped_lag(skin: Skin, i: int, net: SkinParams) -> float:
    """Patch ``i``'s lag (m of water, module doc): its estimator's network ``net`` against its
    spatial model, the loop's pump running."""
    p = skin.patches[i]
    lc = skin.loops[p.loop].cfg
    v = lc.pump.v_on
    return _lag(net, p.skin, p.spatial, float(flow_R_w(v, lc.skin)), float(v), p.tc_cells[0])
