"""The transport correction (``skin_transport``): the spatial patch minus the lumped node, no touch."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from thermoskin.physics.convection import FlowResistance
from thermoskin.physics.network import state_space, steady_state
from thermoskin.physics.spatial import spatial_state_space, spatial_steady_state
from thermoskin.skin.layout import load_skin
from thermoskin.skin.observe import patch_config
from thermoskin.skin.transport import TransportCorrection

ROOT = Path(__file__).resolve().parent.parent
T_S = 1e-3


def _inputs(m: int, P: int, v_on: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An inlet swinging with a 50 ms on/off pump (the chatter), the air still."""
    k = np.arange(m)
    on = (k // 50) % 2 == 0
    T_in = np.where(on, 24.4, 24.1)[:, None] + 0.01 * np.sin(k / 7.0)[:, None] + np.zeros((1, P))
    v = np.where(on, v_on, 0.0)[:, None] + np.zeros((1, P))
    return T_in, np.full((m, P), 20.0), v


def test_correction_is_the_two_models_integrated_apart() -> None:
    """c(k) = spatial T_w cell - lumped node, each integrated on its own (an ODE solver over every
    sample with the inputs held), from their own steady states."""
    skin = load_skin(ROOT / "examples" / "forearm.toml")
    i = 1  # dorsal2: a patch in the middle of its loop
    p, lp = skin.patches[i], skin.loops[skin.patches[i].loop]
    net = patch_config(skin, i).skin
    P, m = len(skin.patches), 240
    v_on = lp.cfg.pump.v_on
    T_in, T_a, v = _inputs(m, P, v_on)
    tc = TransportCorrection(skin, T_S, [patch_config(skin, j).skin for j in range(P)], [i])
    c = tc.push(T_in, T_a, v)
    assert not c[:, [j for j in range(P) if j != i]].any()  # only the patch asked for

    flow = FlowResistance(lp.cfg.skin)
    ends = (False, False)
    xs = spatial_steady_state(p.skin, p.spatial, v_on, flow(v_on), np.array([T_in[0, i], 20.0, 0.0, 0.0]))
    xl = steady_state(net, flow(v_on), np.array([T_in[0, i], 20.0, 0.0, 0.0]))
    ref = np.empty(m)
    for k in range(m):
        ref[k] = xs[p.tc_cells[0]] - xl[0]
        vk = float(v[k, i])
        As, Bs = spatial_state_space(p.skin, p.spatial, vk, flow(vk), still_ends=ends)
        Al, Bl = state_space(net, flow(vk))
        u = np.array([T_in[k, i], 20.0, 0.0, 0.0])
        for A, B, name in ((As, Bs, "s"), (Al, Bl, "l")):
            x0 = xs if name == "s" else xl
            sol = solve_ivp(lambda _t, x, A=A, b=B @ u: A @ x + b, (0.0, T_S), x0, method="Radau",
                            rtol=1e-10, atol=1e-12)
            if name == "s":
                xs = sol.y[:, -1]
            else:
                xl = sol.y[:, -1]
    np.testing.assert_allclose(c[:, i], ref, atol=2e-6)
    assert np.ptp(ref) > 0.02  # the chatter shows: the correction is not a constant


def test_blocks_give_the_whole_log_and_nan_holds_the_last_input() -> None:
    """Pushed in uneven blocks the correction is the whole log's to the bit; a NaN input is the
    last finite one."""
    skin = load_skin(ROOT / "examples" / "forearm.toml")
    P, m = len(skin.patches), 500
    nets = [patch_config(skin, j).skin for j in range(P)]
    T_in, T_a, v = _inputs(m, P, 0.141)
    whole = TransportCorrection(skin, T_S, nets, range(P)).push(T_in, T_a, v)
    tc = TransportCorrection(skin, T_S, nets, range(P))
    cuts = [0, 1, 77, 300, m]
    parts = [tc.push(T_in[a:b], T_a[a:b], v[a:b]) for a, b in itertools.pairwise(cuts)]
    np.testing.assert_array_equal(np.vstack(parts), whole)
    holes = T_in.copy()
    holes[[120, 121, 300], :] = np.nan
    held = T_in.copy()
    held[[120, 121], :] = T_in[119]
    held[300] = T_in[299]
    got = TransportCorrection(skin, T_S, nets, range(P)).push(holes, T_a, v)
    np.testing.assert_array_equal(got, TransportCorrection(skin, T_S, nets, range(P)).push(held, T_a, v))


def test_steady_inputs_give_the_steady_difference() -> None:
    """Constant inputs, pump running: c is the difference of the two steady states throughout."""
    skin = load_skin(ROOT / "examples" / "forearm.toml")
    i = 8  # the palm: a larger patch, last of its loop
    p, lp = skin.patches[i], skin.loops[skin.patches[i].loop]
    net = patch_config(skin, i).skin
    P, m, v_on = len(skin.patches), 200, lp.cfg.pump.v_on
    tc = TransportCorrection(skin, T_S, [patch_config(skin, j).skin for j in range(P)], [i])
    c = tc.push(np.full((m, P), 25.0), np.full((m, P), 20.0), np.full((m, P), v_on))
    R_w = FlowResistance(lp.cfg.skin)(v_on)
    u = np.array([25.0, 20.0, 0.0, 0.0])
    y_s = spatial_steady_state(p.skin, p.spatial, v_on, R_w, u)[p.tc_cells[0]]
    expect = y_s - steady_state(net, R_w, u)[0]
    assert c[:, i] == pytest.approx(np.full(m, expect), abs=1e-9)
