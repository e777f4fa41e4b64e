"""Where along its pipe a patch was touched (``skin_position``), on readings of a known touch."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg

from thermoskin.physics.convection import FlowResistance
from thermoskin.physics.spatial import contact_cells, spatial_state_space, spatial_steady_state
from thermoskin.skin.layout import load_skin
from thermoskin.skin.position import PatchLocator

ROOT = Path(__file__).resolve().parent.parent
T_S = 1e-3


def _readings(skin, i: int, par: float, k_on: int, n: int, q: float, seed: int, cells: int | None = None,
              offsets: tuple[float, ...] = ()):
    """The thermocouples of patch ``i`` (its spatial model through ``physics.spatial``'s own heat
    input ``q_x``, spread on the contact's cells), the pump chattering 50 ms off / 50 ms on,
    ``q`` W into the sheet at ``par`` of the footprint's travel from sample ``k_on``; noise 20 mK.
    ``cells``: the readings' model with this many cells (a second discretisation of the pipe, not
    the locator's own); ``offsets``: each thermocouple's constant error (K, a board's)."""
    p, lp = skin.patches[i], skin.loops[skin.patches[i].loop]
    sp, v_on = p.spatial, lp.cfg.pump.v_on
    if cells is not None:
        sp = dataclasses.replace(sp, n_cells=cells)
    # each thermocouple's cell on this grid (cell 0 at the outlet; s from the inlet)
    tc_cells = [min(max(math.floor((1.0 - s / p.length) * sp.n_cells), 0), sp.n_cells - 1)
                for s in p.thermocouples]
    flow = FlowResistance(lp.cfg.skin)
    ends = (p.index == lp.patches[0], p.index == lp.patches[-1])
    w = contact_cells(par, sp.n_cells, sp.footprint)
    E = {}
    for v in (0.0, v_on):
        A, B = spatial_state_space(p.skin, sp, v, flow(v), q_weights=w, still_ends=ends)
        m = A.shape[0]
        M = np.zeros((m + 4, m + 4))
        M[:m, :m], M[:m, m:] = A, B
        X = scipy.linalg.expm(M * T_S)
        E[v] = (X[:m, :m], X[:m, m:])
    v = np.where((np.arange(n) // 50) % 2 == 1, v_on, 0.0)
    T_in = 24.6 + 0.05 * np.sin(np.arange(n) / 300.0)
    x = spatial_steady_state(p.skin, sp, v_on, flow(v_on), np.array([T_in[0], 20.0, 0.0, 0.0]))
    for k in range(3000):  # into the chatter's periodic state before the log begins
        F, G = E[float(v[k % 100])]
        x = F @ x + G @ np.array([T_in[0], 20.0, 0.0, 0.0])
    Y = np.empty((n, len(tc_cells)))
    for k in range(n):
        Y[k] = x[tc_cells]
        F, G = E[float(v[k])]
        x = F @ x + G @ np.array([T_in[k], 20.0, q if k >= k_on else 0.0, 0.0])
    Y += np.random.default_rng(seed).normal(0.0, 0.02, Y.shape)
    for j, c in enumerate(offsets):
        Y[:, j] += c
    s_true = p.length * (1.0 - (0.5 * sp.footprint + par * (1.0 - sp.footprint)))
    return T_in, v, [Y[:, j] for j in range(Y.shape[1])], s_true


@pytest.mark.parametrize("par", [0.2, 0.8])
def test_a_touch_near_either_end_is_placed_where_it_was(par: float) -> None:
    """Two thermocouples (outlet and inlet), the pump chattering, the window opening while the
    pump stands: the position is within 10 % of the pipe of the truth (the model's own start-up,
    0.7 K from a still-water steady state, once took the place of the offset and put a touch
    near the outlet at the inlet)."""
    skin = load_skin(ROOT / "examples" / "forearm.toml")
    i = skin.patch("ventral1").index
    p = skin.patches[i]
    n, k_on, k_off = 5000, 2000, 4200  # the window opens at k_on - 1.5 s = 500: the pump off
    T_in, v, Y, s_true = _readings(skin, i, par, k_on, n, q=1.5, seed=3)
    assert v[k_on - 1500] == 0.0
    pos = PatchLocator(skin, i, T_S).locate(k_on, k_off, T_in, np.full(n, 20.0), v, Y, None,
                                            np.where(np.arange(n) >= k_on, 1.5, 0.0))
    assert np.isfinite(pos.mean), "a position is reported"
    assert abs(pos.mean - s_true) < 0.1 * p.length
    assert pos.heat == pytest.approx(1.0, abs=0.2)  # dq is the heat itself: scale 1


@pytest.mark.parametrize("par", [0.2, 0.8])
def test_board_offsets_and_another_discretisation(par: float) -> None:
    """The readings from a model of the pipe with twice the cells (not the locator's own), each
    thermocouple off by a board's constant error (+0.4 K at the outlet, -0.3 K at the inlet, ten
    times the touch's rise): the touch is still placed within 15 % of the pipe of the truth, its
    scale near 1 (the offsets are fitted before the onset; without that fit the +0.7 K between
    the two thermocouples would read as a touch at the inlet)."""
    skin = load_skin(ROOT / "examples" / "forearm.toml")
    i = skin.patch("ventral1").index
    p = skin.patches[i]
    n, k_on, k_off = 5000, 2000, 4200
    T_in, v, Y, s_true = _readings(skin, i, par, k_on, n, q=1.5, seed=5, cells=2 * p.spatial.n_cells,
                                   offsets=(0.4, -0.3))
    pos = PatchLocator(skin, i, T_S).locate(k_on, k_off, T_in, np.full(n, 20.0), v, Y, None,
                                            np.where(np.arange(n) >= k_on, 1.5, 0.0))
    assert np.isfinite(pos.mean)
    assert abs(pos.mean - s_true) < 0.15 * p.length, (pos.mean, s_true)
    assert pos.heat == pytest.approx(1.0, abs=0.3)
