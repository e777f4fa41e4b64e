"""The two-node network (Fig. 3): state space, equilibrium, transfer functions, ZOH."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.signal import ss2tf

from thermoskin.params import SkinParams
from thermoskin.physics.network import (
    D_poly,
    Q_den,
    discretize,
    state_space,
    steady_state,
    tf_pump_path,
    tf_Q,
    tf_touch_path,
    tf_touch_path_eq6,
)

SKINS = [
    SkinParams(),
    SkinParams(C_w=0.4, C_g=0.0062, R_g=25.0, R_aw=800.0, R_ag=3.0),
    SkinParams(C_w=0.067, C_g=0.037, R_g=5.0, R_aw=5000.0, R_ag=0.5),
]
RW = [0.19, 57.0, 2.0]


def rhs_by_hand(x: np.ndarray, u: np.ndarray, s: SkinParams, Rw: float, Gc: float) -> np.ndarray:
    """The ODE of docs/model.md written out term by term."""
    Tw, Tg = x
    Tp, Ta, qx, Tf = u
    q_p = (Tp - Tw) / Rw
    q_aw = (Tw - Ta) / s.R_aw
    q_ag = (Tg - Ta) / s.R_ag
    q_g = (Tw - Tg) / s.R_g
    q_i = qx + Gc * (Tf - Tg)
    return np.array([(q_p - q_aw - q_g) / s.C_w, (q_g + q_i - q_ag) / s.C_g])


@pytest.mark.parametrize("skin", SKINS)
@pytest.mark.parametrize("Rw", RW)
@pytest.mark.parametrize("Gc", [0.0, 0.05])
def test_state_space_matches_ode(skin: SkinParams, Rw: float, Gc: float) -> None:
    rng = np.random.default_rng(1)
    A, B = state_space(skin, Rw, Gc)
    assert A.shape == (2, 2) and B.shape == (2, 4)
    for _ in range(5):
        x = rng.uniform(15, 35, 2)
        u = np.array([rng.uniform(7, 37), rng.uniform(15, 30), rng.normal(0, 0.5), 34.0])
        ref = rhs_by_hand(x, u, skin, Rw, Gc)
        np.testing.assert_allclose(A @ x + B @ u, ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())


def steady_by_hand(s: SkinParams, Rw: float, u: np.ndarray, Gc: float) -> tuple[float, float]:
    """Nodal analysis: eliminate T_g from the sheet node, solve the pipe node."""
    Tp, Ta, qx, Tf = u
    Yg = 1 / s.R_g + Gc + 1 / s.R_ag
    Sg = qx + Gc * Tf + Ta / s.R_ag
    Yw = 1 / Rw + 1 / s.R_aw + 1 / s.R_g
    Tw = (Tp / Rw + Ta / s.R_aw + Sg / (s.R_g * Yg)) / (Yw - 1 / (s.R_g**2 * Yg))
    Tg = (Tw / s.R_g + Sg) / Yg
    return Tw, Tg


@pytest.mark.parametrize("skin", SKINS)
@pytest.mark.parametrize("Rw", RW)
@pytest.mark.parametrize("Gc", [0.0, 0.05])
def test_steady_state_closed_form(skin: SkinParams, Rw: float, Gc: float) -> None:
    u = np.array([26.0, 20.0, 0.3, 34.0])
    x = steady_state(skin, Rw, u, Gc)
    np.testing.assert_allclose(x, steady_by_hand(skin, Rw, u, Gc), rtol=1e-12)
    # energy balance: what the water brings and the touch adds leaves to the air
    Tw, Tg = x
    q_p = (26.0 - Tw) / Rw
    q_i = 0.3 + Gc * (34.0 - Tg)
    assert q_p + q_i == pytest.approx((Tw - 20.0) / skin.R_aw + (Tg - 20.0) / skin.R_ag, rel=1e-10)


def test_steady_state_physical_limits() -> None:
    s = SkinParams()
    # everything at ambient, no touch: all at ambient
    np.testing.assert_allclose(steady_state(s, 0.19, [20.0, 20.0, 0.0, 34.0]), [20.0, 20.0])
    # a very strong contact pins the sheet to the finger
    Tg = steady_state(s, 0.19, [20.0, 20.0, 0.0, 34.0], G_c=1e6)[1]
    assert Tg == pytest.approx(34.0, abs=1e-4)
    # a tiny R_w pins the pipe to the pump
    Tw = steady_state(s, 1e-9, [26.0, 20.0, 0.0, 34.0])[0]
    assert Tw == pytest.approx(26.0, abs=1e-6)
    # pipe -> sheet -> air is a divider R_g : R_ag (R_aw, R_w small/large aside)
    Tg = steady_state(s, 1e-9, [26.0, 20.0, 0.0, 34.0])[1]
    assert Tg == pytest.approx(20.0 + 6.0 * s.R_ag / (s.R_g + s.R_ag), rel=1e-6)


def _normalise(num: np.ndarray, den: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    def trim(c: np.ndarray) -> np.ndarray:
        c = np.atleast_1d(np.asarray(c, float))
        keep = np.flatnonzero(np.abs(c) > 1e-12 * np.abs(c).max())
        return c[keep[0]:]

    num, den = trim(num), trim(den)
    return num / den[0], den / den[0]


def _open_network(s: SkinParams) -> tuple[np.ndarray, np.ndarray]:
    """The network with q_p - q_aw (into the T_w node) and q_i - q_ag (into T_g) as inputs."""
    A = np.array([[-1 / (s.R_g * s.C_w), 1 / (s.R_g * s.C_w)],
                  [1 / (s.R_g * s.C_g), -1 / (s.R_g * s.C_g)]])
    B = np.array([[1 / s.C_w, 0.0], [0.0, 1 / s.C_g]])
    return A, B


@pytest.mark.parametrize("skin", SKINS)
def test_pump_path_eq5_vs_ss2tf(skin: SkinParams) -> None:
    A, B = _open_network(skin)
    num, den = ss2tf(A, B, np.array([[1.0, 0.0]]), np.zeros((1, 2)), input=0)
    ref = _normalise(num[0], den)
    got = _normalise(*tf_pump_path(skin))
    np.testing.assert_allclose(got[1], ref[1], rtol=1e-9, atol=1e-9 * np.abs(ref[1]).max())
    np.testing.assert_allclose(got[0], ref[0], rtol=1e-9)


@pytest.mark.parametrize("skin", SKINS)
def test_touch_path_vs_ss2tf(skin: SkinParams) -> None:
    A, B = _open_network(skin)
    num, den = ss2tf(A, B, np.array([[1.0, 0.0]]), np.zeros((1, 2)), input=1)
    ref = _normalise(num[0], den)
    got = _normalise(*tf_touch_path(skin))
    np.testing.assert_allclose(got[1], ref[1], rtol=1e-9, atol=1e-9 * np.abs(ref[1]).max())
    np.testing.assert_allclose(got[0], ref[0], rtol=1e-9)


def test_D_and_Q_polynomials_by_hand() -> None:
    s = SkinParams()
    Cw, Cg, Rg = 0.134, 0.0124, 10.0
    np.testing.assert_allclose(D_poly(s), [Rg * Cw * Cg, Cw + Cg, 0.0], rtol=1e-12)
    expanded = [Rg**2 * Cw * Cg, Rg * (Cw + Cg), 1.0]
    np.testing.assert_allclose(Q_den(s), expanded, rtol=1e-12)
    num, den = tf_Q(s)
    assert np.polyval(num, 0) / np.polyval(den, 0) == pytest.approx(1.0)  # unit DC gain
    np.testing.assert_allclose(sorted(np.roots(den).real), sorted([-1 / (Rg * Cw), -1 / (Rg * Cg)]),
                               rtol=1e-9)
    num6, den6 = tf_touch_path_eq6(s)
    np.testing.assert_allclose(num6, expanded, rtol=1e-12)
    np.testing.assert_allclose(den6, D_poly(s), rtol=1e-12)
    # R_g C_w ~ 1.3 s (docs/model.md)
    assert Rg * Cw == pytest.approx(1.34)


@pytest.mark.parametrize("skin", SKINS)
def test_eq8_inverts_network_to_Q(skin: SkinParams) -> None:
    """Eq. 8 applied to T_w of the network gives Q (q_i - q_ag) and nothing of q_p - q_aw.

    Checked on the frequency response of the state space (not on the polynomials)."""
    A, B = _open_network(skin)
    D = lambda s: np.polyval(D_poly(skin), s)  # noqa: E731
    Qd = lambda s: np.polyval(Q_den(skin), s)  # noqa: E731
    for w in np.logspace(-3, 3, 13):
        s = 1j * w
        G = np.linalg.solve(s * np.eye(2) - A, B)[0]  # T_w per input
        pump = (D(s) * G[0] - (skin.R_g * skin.C_g * s + 1)) / Qd(s)
        touch = D(s) * G[1] / Qd(s)
        assert abs(pump) < 1e-9
        assert touch == pytest.approx(1 / Qd(s), rel=1e-9)


def test_dc_and_limits() -> None:
    """The paths integrate (pole at 0); high frequency rolls off as 1/(C_w s) and 1/s^2."""
    s = SkinParams()
    num, den = tf_pump_path(s)
    w = 1e-6
    g = np.polyval(num, 1j * w) / np.polyval(den, 1j * w)
    assert abs(g) * w == pytest.approx(1 / (s.C_w + s.C_g), rel=1e-4)  # total capacitance
    w = 1e6
    g = np.polyval(num, 1j * w) / np.polyval(den, 1j * w)
    assert abs(g) * w == pytest.approx(1 / s.C_w, rel=1e-4)
    num, den = tf_touch_path(s)
    g = np.polyval(num, 1j * w) / np.polyval(den, 1j * w)
    assert abs(g) * w**2 == pytest.approx(1 / (s.R_g * s.C_w * s.C_g), rel=1e-4)


@pytest.mark.parametrize("skin", SKINS)
@pytest.mark.parametrize("t_s", [1e-3, 0.05])
def test_discretize_vs_expm(skin: SkinParams, t_s: float) -> None:
    A, B = state_space(skin, 0.19, 0.05)
    Phi, Gamma = discretize(A, B, t_s)
    M = np.zeros((6, 6))
    M[:2, :2] = A
    M[:2, 2:] = B
    E = expm(M * t_s)
    np.testing.assert_allclose(Phi, E[:2, :2], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(Gamma, E[:2, 2:], rtol=1e-9, atol=1e-14)


def test_discretize_keeps_equilibrium() -> None:
    s = SkinParams()
    u = np.array([26.0, 20.0, 0.2, 34.0])
    A, B = state_space(s, 0.19, 0.05)
    Phi, Gamma = discretize(A, B, 1e-3)
    x = steady_state(s, 0.19, u, 0.05)
    np.testing.assert_allclose(Phi @ x + Gamma @ u, x, rtol=1e-12)
