"""Simulated skin: exact ZOH integration against independent solutions, equilibrium, energy, sensors."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import expm

from thermoskin.params import Config, SensorParams, SkinParams
from thermoskin.physics.convection import R_w
from thermoskin.physics.network import state_space
from thermoskin.sim.skin import Sensors, SimulatedSkin, zoh_2x2

CFG = Config()
SK = CFG.skin  # Table I: C_w 0.134, C_g 0.0124, R_g 10, R_aw 2100, R_ag 1


def rhs(skin: SkinParams, Rw: float, T_p: float, T_a: float, G_c: float, T_f: float, q_x: float):
    """The network of docs/model.md, written out again for the test."""
    def f(_t, x):
        T_w, T_g = x
        q_p = (T_p - T_w) / Rw
        q_aw = (T_w - T_a) / skin.R_aw
        q_ag = (T_g - T_a) / skin.R_ag
        q_i = q_x + G_c * (T_f - T_g)
        return [(q_p - q_aw - (T_w - T_g) / skin.R_g) / skin.C_w,
                ((T_w - T_g) / skin.R_g + q_i - q_ag) / skin.C_g]
    return f


@pytest.mark.parametrize(("Rw", "G_c"), [(0.19, 0.0), (57.0, 0.0), (0.19, 0.165), (57.0, 0.05), (3.0, 1e3)])
def test_zoh_matches_matrix_exponential(Rw, G_c):
    A, B = state_space(SK, Rw, G_c)
    t_s = 1e-3
    # Van Loan: expm([[A, B], [0, 0]] t) = [[Phi, Gamma], [0, I]]
    M = np.zeros((6, 6))
    M[:2, :2], M[:2, 2:] = A, B
    E = expm(M * t_s)
    Phi, Gamma = zoh_2x2(A, B, t_s)
    np.testing.assert_allclose(Phi, E[:2, :2], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(Gamma, E[:2, 2:], rtol=1e-10, atol=1e-15)


def test_zoh_long_step_does_not_overflow():
    A, B = state_space(SkinParams(C_g=1e-5), 0.19, 0.0)
    Phi, Gamma = zoh_2x2(A, B, 5.0)
    M = np.zeros((6, 6))
    M[:2, :2], M[:2, 2:] = A, B
    E = expm(M * 5.0)
    assert np.all(np.isfinite(Phi)) and np.all(np.isfinite(Gamma))
    np.testing.assert_allclose(Phi, E[:2, :2], atol=1e-12)
    np.testing.assert_allclose(Gamma, E[:2, 2:], atol=1e-9)


def inputs(k: int, t_s: float) -> tuple[float, float, float, float, float, float]:
    """(T_p, v, T_a, G_c, T_f, q_x) for sample k: pump switch, a ramped touch, a heat pulse."""
    t = k * t_s
    v = 0.141 if t < 0.25 else 0.0
    G_c = 0.11 * min(max((t - 0.1) / 0.03, 0.0), 1.0)  # press ramp from t = 0.1 s
    q_x = 0.2 if 0.3 <= t < 0.35 else 0.0
    T_p = 24.3 + 0.05 * math.sin(2 * math.pi * t / 0.2)
    return T_p, v, 20.0, G_c, 33.5, q_x


def test_trajectory_matches_solve_ivp_with_touch_and_pump_switch():
    t_s = CFG.sampling.t_s
    n = 400
    skin = SimulatedSkin(CFG)
    skin.reset(24.0, T_a=20.0)
    x = np.array([skin.T_w, skin.T_g])
    Rw = {0.141: R_w(0.141, SK), 0.0: R_w(0.0, SK)}
    sim = [x.copy()]
    ref = [x.copy()]
    for k in range(n):
        T_p, v, T_a, G_c, T_f, q_x = inputs(k, t_s)
        skin.step(T_p, v, T_a, G_c, T_f, q_x)
        sim.append([skin.T_w, skin.T_g])
        sol = solve_ivp(rhs(SK, Rw[v], T_p, T_a, G_c, T_f, q_x), (0.0, t_s), ref[-1],
                        method="DOP853", rtol=1e-9, atol=1e-12)
        ref.append(sol.y[:, -1])
    sim_a, ref_a = np.array(sim), np.array(ref)
    # the inputs did move the state
    assert np.ptp(ref_a[:, 0]) > 0.05 and np.ptp(ref_a[:, 1]) > 1.0
    np.testing.assert_allclose(sim_a, ref_a, rtol=0, atol=1e-8)
    assert skin.q_i == pytest.approx(0.11 * (33.5 - skin.T_g), rel=1e-12)
    assert skin.t == pytest.approx(n * t_s)


def test_no_touch_sheet_equilibrium_is_closed_form():
    skin = SimulatedSkin(CFG)
    skin.reset(24.0, T_a=20.0)
    # T_g = (T_w/R_g + T_a/R_ag) / (1/R_g + 1/R_ag) = (2.4 + 20) / 1.1
    assert skin.T_g == pytest.approx(22.4 / 1.1, rel=1e-14)
    assert skin.q_i == 0.0


def test_full_equilibrium_is_steady_and_matches_hand_solution():
    T_p, v, T_a, G_c, T_f = 24.3, 0.141, 20.0, 0.1, 34.0
    Rw = R_w(v, SK)
    # solve the two balance equations by hand (Cramer's rule)
    a11 = 1 / Rw + 1 / SK.R_aw + 1 / SK.R_g
    a12 = -1 / SK.R_g
    a22 = 1 / SK.R_g + 1 / SK.R_ag + G_c
    b1 = T_p / Rw + T_a / SK.R_aw
    b2 = T_a / SK.R_ag + G_c * T_f
    det = a11 * a22 - a12 * a12
    T_w = (b1 * a22 - a12 * b2) / det
    T_g = (a11 * b2 - a12 * b1) / det
    skin = SimulatedSkin(CFG)
    skin.reset_equilibrium(T_p, v, T_a, G_c, T_f)
    assert (skin.T_w, skin.T_g) == (pytest.approx(T_w, abs=1e-12), pytest.approx(T_g, abs=1e-12))
    for _ in range(2000):
        skin.step(T_p, v, T_a, G_c, T_f)
    assert (skin.T_w, skin.T_g) == (pytest.approx(T_w, abs=1e-10), pytest.approx(T_g, abs=1e-10))
    # a sample time change does not move the equilibrium either
    skin2 = SimulatedSkin(CFG.replace(sampling={"t_s": 0.01}))
    skin2.reset(24.0, T_a=T_a)
    for _ in range(3000):  # 30 s, many time constants
        skin2.step(T_p, v, T_a, G_c, T_f)
    assert skin2.T_w == pytest.approx(T_w, abs=1e-9)


def simpson(y: np.ndarray, h: float) -> float:
    assert (y.size - 1) % 2 == 0
    return h / 3 * (y[0] + y[-1] + 4 * y[1:-1:2].sum() + 2 * y[2:-1:2].sum())


def test_energy_balance():
    """C_w dT_w + C_g dT_g = ∫ (q_p - q_aw - q_ag + q_i) dt over a transient."""
    cfg = CFG.replace(sampling={"t_s": 1e-4})
    skin = SimulatedSkin(cfg)
    skin.reset(23.0, T_a=20.0)
    T_p, v, T_a, G_c, T_f = 25.0, 0.141, 20.0, 0.165, 34.0
    Rw = R_w(v, SK)
    n = 2000  # 0.2 s, even number of intervals for Simpson
    T_w = np.empty(n + 1)
    T_g = np.empty(n + 1)
    T_w[0], T_g[0] = skin.T_w, skin.T_g
    for k in range(n):
        skin.step(T_p, v, T_a, G_c, T_f)
        T_w[k + 1], T_g[k + 1] = skin.T_w, skin.T_g
    flows = (T_p - T_w) / Rw - (T_w - T_a) / SK.R_aw - (T_g - T_a) / SK.R_ag + G_c * (T_f - T_g)
    stored = SK.C_w * (T_w[-1] - T_w[0]) + SK.C_g * (T_g[-1] - T_g[0])
    assert abs(stored) > 0.05  # a real transient (J)
    assert simpson(flows, 1e-4) == pytest.approx(stored, rel=1e-7)


def test_coefficient_cache_and_bad_input():
    skin = SimulatedSkin(CFG)
    c1 = skin.coefficients(0.141, 0.05)
    assert skin.coefficients(0.141, 0.05) is c1
    with pytest.raises(ValueError):
        skin.coefficients(0.141, -0.1)


# -- sensors ---------------------------------------------------------------------------


def test_noise_std_matches_configuration():
    sensors = Sensors(SensorParams(noise_T=0.03, quantum_T=0.0, seed=3))
    x = sensors.measure("T_w", np.full(200_000, 24.0))
    # std of the sample std is sigma / sqrt(2 n) = 0.16 %: 1.5 % is about 9 of those
    assert np.std(x) == pytest.approx(0.03, rel=0.015)
    assert abs(np.mean(x) - 24.0) < 5 * 0.03 / math.sqrt(x.size)


def test_quantisation_step():
    q = 1 / 128
    sensors = Sensors(SensorParams(noise_T=0.0, quantum_T=q, seed=0))
    x = np.linspace(20.0, 21.0, 10_001)
    y = sensors.measure("T_p", x)
    np.testing.assert_allclose(y / q, np.round(y / q), atol=1e-9)  # multiples of q
    assert np.max(np.abs(y - x)) <= q / 2 + 1e-12
    assert np.unique(np.round(np.diff(np.unique(y)) / q)).tolist() == [1.0]  # nothing skipped
    assert sensors.quantise(20.0 + 0.4 * q) == pytest.approx(20.0)
    assert sensors.quantise(20.0 + 0.6 * q) == pytest.approx(20.0 + q)
    # with noise the readings stay on the grid
    noisy = Sensors(SensorParams(noise_T=0.02, quantum_T=q, seed=1)).measure("T_w", x)
    np.testing.assert_allclose(noisy / q, np.round(noisy / q), atol=1e-9)
    # quantum 0: no rounding at all
    raw = Sensors(SensorParams(noise_T=0.0, quantum_T=0.0)).measure("T_a", x)
    np.testing.assert_array_equal(raw, x)


def test_per_sample_and_array_readings_agree_and_are_seeded():
    p = SensorParams(noise_T=0.02, quantum_T=1 / 128, seed=11)
    x = 24.0 + 0.001 * np.arange(3000)
    a = Sensors(p)
    one = np.array([a.measure_one("T_w", float(v)) for v in x[:1500]])
    rest = a.measure("T_w", x[1500:])  # continues the same sequence after a partial block
    b = Sensors(p).measure("T_w", x)
    np.testing.assert_array_equal(np.concatenate([one, rest]), b)
    # channels are independent streams: T_w does not depend on T_p draws
    c = Sensors(p)
    c.measure("T_p", x)
    np.testing.assert_array_equal(c.measure("T_w", x), b)
    # another seed gives other readings
    d = Sensors(SensorParams(noise_T=0.02, quantum_T=1 / 128, seed=12)).measure("T_w", x)
    assert np.mean(d != b) > 0.5
    with pytest.raises(KeyError, match="unknown channel"):
        a.measure("T_x", x)
