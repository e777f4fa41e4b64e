"""Spatial skin: calibration to Table I, equilibrium, energy, agreement with the two-node twin.

Reference computations are independent of the builder where it matters: the heat balance
of each cell is written out again here from the physics (``_balance``), the lumped sums
are checked against ``physics.network.state_space``, the ZOH against
``physics.network.discretize`` (scipy's ``cont2discrete``), and the touch signal through
the project's observer.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import scipy.linalg

from thermoskin.estimation.observer import ThermalExchangeObserver
from thermoskin.params import Config, ConfigError, ObserverParams, SkinParams
from thermoskin.physics.convection import FlowResistance
from thermoskin.physics.network import discretize, state_space
from thermoskin.physics.spatial import (
    SpatialParams,
    contact_cells,
    spatial_state_space,
    spatial_steady_state,
)
from thermoskin.sim.skin import SimulatedSkin
from thermoskin.sim.spatial_skin import SpatialSkin

CFG = Config()
SKIN = CFG.skin
V_ON = 0.141
T_A, T_F, G_FINGER = 20.0, 34.0, 0.05


def _balance(skin: SkinParams, sp: SpatialParams, v: float, R_w: float, x: np.ndarray,
             u: np.ndarray, shares: dict[int, float], G_c: float) -> np.ndarray:
    """Net heat flow into every node (W), written out cell by cell from the physics."""
    N = sp.n_cells
    T_p, T_a, q_x, T_f = u
    Tw, Tg = x[:N], x[N:2 * N]
    Tf = x[2 * N:] if sp.has_foam else None
    dx = sp.length / N
    G_gl = sp.k_sheet * sp.width * sp.t_sheet / dx
    d_o = sp.d_i + 2 * sp.t_wall
    G_wl = (sp.k_pipe * math.pi / 4 * (d_o**2 - sp.d_i**2) + sp.k_water * math.pi / 4 * sp.d_i**2) / dx
    qw, qg = np.zeros(N), np.zeros(N)
    qf = np.zeros(N)
    for i in range(N):
        for j in (i - 1, i + 1):
            if 0 <= j < N:
                qw[i] += G_wl * (Tw[j] - Tw[i])
                qg[i] += G_gl * (Tg[j] - Tg[i])
        pipe_sheet = (Tw[i] - Tg[i]) / (N * skin.R_g)
        qw[i] -= pipe_sheet
        qg[i] += pipe_sheet - (Tg[i] - T_a) / (N * skin.R_ag)
        qg[i] += shares.get(i, 0.0) * (G_c * (T_f - Tg[i]) + q_x)
        if Tf is None:
            qw[i] -= (Tw[i] - T_a) / (N * skin.R_aw)
        else:
            s = sp.foam_split
            to_foam = (Tw[i] - Tf[i]) / (s * N * skin.R_aw)
            qw[i] -= to_foam
            qf[i] = to_foam - (Tf[i] - T_a) / ((1 - s) * N * skin.R_aw)
    W = 1 / R_w
    if v > 0:
        path = list(range(N - 1, -1, -1)) if sp.inlet == "far" else list(range(N))
        upstream = T_p
        for i in path:
            qw[i] += W * (upstream - Tw[i])
            upstream = Tw[i]
    else:
        qw[0] += W / 2 * (T_p - Tw[0])
        qw[N - 1] += W / 2 * (T_p - Tw[N - 1])
    return np.concatenate([qw, qg] + ([qf] if Tf is not None else []))


def _caps(skin: SkinParams, sp: SpatialParams) -> np.ndarray:
    N = sp.n_cells
    c = [np.full(N, skin.C_w / N), np.full(N, skin.C_g / N)]
    return np.concatenate(c + ([np.full(N, sp.C_foam / N)] if sp.has_foam else []))


SP_CASES = [SpatialParams(), SpatialParams(inlet="near", n_cells=12),
            SpatialParams(C_foam=0.1, foam_split=0.3, n_cells=10)]


# -- the builder against the cell balances --------------------------------------------------
@pytest.mark.parametrize("sp", SP_CASES)
@pytest.mark.parametrize("v", [0.0, V_ON])
def test_builder_matches_cell_balances(sp: SpatialParams, v: float) -> None:
    rng = np.random.default_rng(1)
    R_w = FlowResistance(SKIN)(v)
    shares = sp.shares(0.37)
    G_c = 0.07
    A, B = spatial_state_space(SKIN, sp, v, R_w, {i: G_c * s for i, s in shares.items()}, shares)
    for _ in range(3):
        x = 20 + 10 * rng.random(sp.n_states)
        u = np.array([30.0, 18.0, 0.3, 33.0])
        ref = _balance(SKIN, sp, v, R_w, x, u, shares, G_c) / _caps(SKIN, sp)
        np.testing.assert_allclose(A @ x + B @ u, ref, rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("sp", SP_CASES)
@pytest.mark.parametrize("v", [0.0, V_ON])
def test_equilibrium_solves_the_balances(sp: SpatialParams, v: float) -> None:
    R_w = FlowResistance(SKIN)(v)
    u = np.array([27.0, T_A, 0.0, T_F])
    shares = sp.shares(0.5)
    x = spatial_steady_state(SKIN, sp, v, R_w, u, {i: G_FINGER * s for i, s in shares.items()}, shares)
    q = _balance(SKIN, sp, v, R_w, x, u, shares, G_FINGER)
    assert np.max(np.abs(q)) < 1e-12
    skin = SpatialSkin(CFG, sp)
    skin.reset_equilibrium(27.0, v, T_A, G_FINGER, T_F, position=0.5)
    np.testing.assert_allclose(skin.x, x, rtol=0, atol=1e-12)
    for _ in range(50):
        skin.step(27.0, v, T_A, G_FINGER, T_F, position=0.5)
    np.testing.assert_allclose(skin.x, x, rtol=0, atol=1e-9)


def test_reset_puts_the_sheet_in_equilibrium_with_the_pipe() -> None:
    sp = SpatialParams()
    skin = SpatialSkin(CFG, sp)
    skin.reset(24.0, T_a=T_A, G_c=G_FINGER, T_f=T_F, position=1.0)
    q = _balance(SKIN, sp, 0.0, 1.0, skin.x, np.array([0.0, T_A, 0.0, T_F]), sp.shares(1.0), G_FINGER)
    N = sp.n_cells
    assert np.all(skin.x[:N] == 24.0)
    assert np.max(np.abs(q[N:])) < 1e-12
    # the touched end is warmer than the far end; T_g is the sheet under the touch
    assert skin.T_g_cells[-1] > skin.T_g_cells[0]
    assert skin.T_g > skin.T_g_mean
    assert skin.q_i == pytest.approx(G_FINGER * (T_F - skin.T_g))


# -- calibration: the lumped limit -------------------------------------------------------------
@pytest.mark.parametrize("sp", SP_CASES[:2])
@pytest.mark.parametrize("v", [0.0, V_ON])
@pytest.mark.parametrize("position", [0.0, 0.5, 1.0])
def test_lumped_sums_are_table_one(sp: SpatialParams, v: float, position: float) -> None:
    """Summed over the cells with a uniform state, the network is the two-node network."""
    N = sp.n_cells
    R_w = FlowResistance(SKIN)(v)
    shares = sp.shares(position)
    A, B = spatial_state_space(SKIN, sp, v, R_w, {i: G_FINGER * s for i, s in shares.items()}, shares)
    C = _caps(SKIN, sp)
    S = np.zeros((2, 2 * N))
    S[0, :N] = 1
    S[1, N:] = 1
    E = S.T  # uniform state from (T_w, T_g)
    A2, B2 = state_space(SKIN, R_w, G_FINGER)
    Cdiag = np.diag([SKIN.C_w, SKIN.C_g])
    np.testing.assert_allclose(S @ (C[:, None] * A) @ E, Cdiag @ A2, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(S @ (C[:, None] * B), Cdiag @ B2, rtol=1e-12, atol=1e-15)
    assert C[:N].sum() == pytest.approx(SKIN.C_w, rel=1e-12)
    assert C[N:].sum() == pytest.approx(SKIN.C_g, rel=1e-12)


def test_one_cell_is_the_two_node_network() -> None:
    sp = SpatialParams(n_cells=1, contact_length=0.0)
    for v in (0.0, V_ON):
        R_w = FlowResistance(SKIN)(v)
        A, B = spatial_state_space(SKIN, sp, v, R_w, {0: G_FINGER})
        A2, B2 = state_space(SKIN, R_w, G_FINGER)
        np.testing.assert_allclose(A, A2, rtol=1e-13)
        np.testing.assert_allclose(B, B2, rtol=1e-13)


def _run(skin: SimulatedSkin | SpatialSkin, v: float, position: float, n: int = 6000,
         k_on: int = 2000, T_p: float = 24.0) -> np.ndarray:
    skin.reset_equilibrium(T_p, v, T_A)
    out = np.empty(n)
    for k in range(n):
        G = G_FINGER if k >= k_on else 0.0
        if isinstance(skin, SpatialSkin):
            skin.step(T_p, v, T_A, G, T_F, position=position)
        else:
            skin.step(T_p, v, T_A, G, T_F)
        out[k] = skin.T_w
    return out


def _dq(T_w: np.ndarray, v: float, k_on: int = 2000, T_p: float = 24.0) -> float:
    """Mean change of the observer's ``dq_i_hat`` during contact from the second before it."""
    n = T_w.size
    obs = ThermalExchangeObserver(SKIN, ObserverParams(), CFG.sampling.t_s)
    out = obs.run(T_w, np.full(n, T_p), np.full(n, v), np.full(n, T_A))
    return float(out.dq_i_hat[k_on:].mean() - out.dq_i_hat[k_on - 1000:k_on].mean())


@pytest.mark.parametrize("v", [0.0, V_ON])
def test_infinitely_conducting_skin_is_the_two_node_twin(v: float) -> None:
    """With lateral conduction far above every other conductance the cells move together."""
    sp = SpatialParams(n_cells=6, k_sheet=1e7, k_pipe=1e7)
    a = _run(SpatialSkin(CFG, sp), v, 0.0, n=3000, k_on=1000)
    b = _run(SimulatedSkin(CFG), v, 0.0, n=3000, k_on=1000)
    rise = np.max(np.abs(b - b[999]))
    assert np.max(np.abs(a - b)) < 2e-3 * rise


def test_touch_at_thermocouple_matches_two_node_twin_with_flow() -> None:
    """Pump running, touch at the thermocouple: T_w (after 0.1 s) and the observer's dq within 5 %.

    Not exact: the touch warms a third of the sheet, and the heat reaches the pipe cells
    under it only; with the water flowing towards the thermocouple the outlet collects it
    (``W (T_p - T_w_0)`` is the whole exchange), so what remains is the sheet's local
    warming (a larger ``T_g`` under the finger, a smaller ``q_i``) and the pipe profile.
    """
    a = _run(SpatialSkin(CFG), V_ON, 0.0)
    b = _run(SimulatedSkin(CFG), V_ON, 0.0)
    rise_a, rise_b = a[-1] - a[1999], b[-1] - b[1999]
    assert rise_a == pytest.approx(rise_b, rel=0.05)
    # the touch's response (change from the no-touch value) once the 30 ms press ramp
    # and the local warming of the touched cells are over (0.1 s); before that the
    # spatial T_w rises up to three times as fast (a third of the pipe takes the heat)
    da, db = a - a[1999], b - b[1999]
    assert np.max(np.abs(da[2100:] - db[2100:])) < 0.05 * rise_b
    assert np.max(np.abs(da[2000:2100] - db[2000:2100])) < 0.4 * rise_b
    # before the touch the profiles differ a little: the outlet is not the mean pipe
    assert abs(a[1999] - b[1999]) < 2e-3
    assert _dq(a, V_ON) == pytest.approx(_dq(b, V_ON), rel=0.05)


def test_touch_at_thermocouple_pump_stopped_is_stronger_than_two_node() -> None:
    """Pump stopped: the heat stays near the touch, so the thermocouple under it sees more.

    The two-node model spreads the same heat over the whole pipe. With the default
    skin the spatial ``T_w`` rise after 4 s is 1.54 times the lumped one (0.82 K against
    0.53 K), the observer's mean ``dq_i_hat`` 1.64 times (0.068 W against 0.041 W).
    """
    a = _run(SpatialSkin(CFG), 0.0, 0.0)
    b = _run(SimulatedSkin(CFG), 0.0, 0.0)
    ratio = (a[-1] - a[1999]) / (b[-1] - b[1999])
    assert 1.1 < ratio < 2.0
    assert 1.1 < _dq(a, 0.0) / _dq(b, 0.0) < 2.0


# -- position -----------------------------------------------------------------------------------
def test_signal_falls_with_distance_pump_stopped() -> None:
    """Fig. 19: near > middle > far, on T_w and on the observer's dq_i_hat."""
    rises, dqs = [], []
    for x in (0.0, 0.5, 1.0):
        T_w = _run(SpatialSkin(CFG), 0.0, x)
        rises.append(T_w[-1] - T_w[1999])
        dqs.append(_dq(T_w, 0.0))
    assert rises[0] > rises[1] > rises[2] > 0
    assert dqs[0] > 2 * dqs[1] > 0
    assert dqs[1] > 2 * dqs[2] > 0


def test_advection_direction_matters_with_flow() -> None:
    """Touch at the far end, pump running: upstream of the thermocouple (inlet far) the water
    carries the heat to it; downstream (inlet near) it is carried away."""
    far = _run(SpatialSkin(CFG, SpatialParams(inlet="far")), V_ON, 1.0)
    near = _run(SpatialSkin(CFG, SpatialParams(inlet="near")), V_ON, 1.0)
    rise_far, rise_near = far[-1] - far[1999], near[-1] - near[1999]
    assert rise_far > 20 * rise_near > 0
    # with the inlet far, the outlet sees every touch about alike
    mid = _run(SpatialSkin(CFG, SpatialParams(inlet="far")), V_ON, 0.5)
    assert mid[-1] - mid[1999] == pytest.approx(rise_far, rel=0.05)
    # pump stopped: the flow direction does not matter
    a = _run(SpatialSkin(CFG, SpatialParams(inlet="far")), 0.0, 1.0, n=500, k_on=100)
    b = _run(SpatialSkin(CFG, SpatialParams(inlet="near")), 0.0, 1.0, n=500, k_on=100)
    np.testing.assert_array_equal(a, b)


def test_contact_cells() -> None:
    assert contact_cells(0.0, 15) == {0: 1.0}
    assert contact_cells(1.0, 15) == {14: 1.0}
    s = contact_cells(0.5, 10)
    assert s == pytest.approx({4: 0.5, 5: 0.5})
    sp = SpatialParams()  # 10 mm of 30 mm on 15 cells: five cells
    assert sp.shares(0.0) == pytest.approx({i: 0.2 for i in range(5)})
    assert sp.shares(1.0) == pytest.approx({i: 0.2 for i in range(10, 15)})
    for x in np.linspace(0, 1, 37):
        sh = sp.shares(float(x))
        assert sum(sh.values()) == pytest.approx(1.0)
        # the footprint's centre moves linearly from 5 mm to 25 mm
        centre = sum((i + 0.5) / sp.n_cells * w for i, w in sh.items())
        assert centre == pytest.approx(1 / 6 + x * 2 / 3, abs=1e-9)
    with pytest.raises(ValueError):
        contact_cells(1.2, 10)
    with pytest.raises(ConfigError):
        SpatialParams(contact_length=0.05)
    with pytest.raises(ConfigError):
        SpatialParams(inlet="left")


# -- energy and discretisation -----------------------------------------------------------------
@pytest.mark.parametrize("sp", SP_CASES)
@pytest.mark.parametrize("v", [0.0, V_ON])
def test_energy_conservation(sp: SpatialParams, v: float) -> None:
    """Stored heat change = integral of the boundary flows, written out independently.

    Boundary flows: water ``W (T_p - T_outlet)`` (still water: both ends), air at pipe
    (or foam) and sheet, touch and ``q_x``. Their time integral over each sample is
    carried exactly as an extra state of the ZOH system.
    """
    R_w = FlowResistance(SKIN)(v)
    N, n = sp.n_cells, sp.n_states
    shares = sp.shares(0.8)
    skin = SpatialSkin(CFG, sp)
    skin.reset(26.0, 22.0, T_a=T_A)
    A, B = skin.matrices(v, G_FINGER, 0.8)
    # boundary flow f = cx . x + cu . u, from the physics
    cx, cu = np.zeros(n), np.zeros(4)
    W = 1 / R_w
    if v > 0:
        out = 0 if sp.inlet == "far" else N - 1
        cu[0] += W
        cx[out] -= W
    else:
        cu[0] += W
        cx[0] -= W / 2
        cx[N - 1] -= W / 2
    air = slice(2 * N, 3 * N) if sp.has_foam else slice(0, N)
    g_air = 1 / (N * SKIN.R_aw) / ((1 - sp.foam_split) if sp.has_foam else 1)
    cx[air] -= g_air
    cu[1] += N * g_air
    cx[N:2 * N] -= 1 / (N * SKIN.R_ag)
    cu[1] += 1 / SKIN.R_ag
    for i, s in shares.items():
        cx[N + i] -= G_FINGER * s
    cu[3] += G_FINGER
    cu[2] += 1.0
    big = np.zeros((n + 5, n + 5))
    big[:n, :n] = A
    big[:n, n + 1:] = B
    big[n, :n] = cx
    big[n, n + 1:] = cu
    M = scipy.linalg.expm(big * skin.t_s)
    z = np.concatenate([skin.x, [0.0], np.zeros(4)])
    E0 = skin.energy()
    rng = np.random.default_rng(3)
    for _ in range(400):
        u = np.array([24 + 8 * rng.random(), T_A, 0.2 * rng.random(), T_F])
        skin.step(float(u[0]), v, T_A, G_FINGER, T_F, q_x=float(u[2]), position=0.8)
        z[n + 1:] = u
        z = M @ z
    np.testing.assert_allclose(skin.x, z[:n], rtol=0, atol=1e-9)
    assert skin.energy() - E0 == pytest.approx(z[n], rel=1e-9, abs=1e-12)
    assert abs(z[n]) > 1e-3  # something happened


def test_zoh_matches_cont2discrete() -> None:
    skin = SpatialSkin(CFG)
    A, B = skin.matrices(V_ON, G_FINGER, 0.3)
    Phi, Gamma = discretize(A, B, skin.t_s)
    M = skin.transition(V_ON, G_FINGER, 0.3)
    np.testing.assert_allclose(M[:, :skin.n], Phi, rtol=1e-10, atol=1e-13)
    np.testing.assert_allclose(M[:, skin.n:], Gamma, rtol=1e-10, atol=1e-13)


def test_same_interface_as_simulated_skin() -> None:
    a, b = SpatialSkin(CFG), SimulatedSkin(CFG)
    for s in (a, b):
        s.reset(24.0, T_a=T_A)
        s.reset_equilibrium(24.0, V_ON, T_A, G_c=0.0, T_f=0.0)
        s.step(24.0, V_ON, T_A, G_FINGER, T_F, 0.0)
        assert math.isfinite(s.T_w) and math.isfinite(s.T_g) and math.isfinite(s.q_i)
        assert s.t == pytest.approx(CFG.sampling.t_s)
    assert dataclasses.is_dataclass(SpatialParams())
