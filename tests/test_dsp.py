"""Iir: Tustin discretisation, streamed vs array filtering, steady-state start."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import cont2discrete, lfilter

from thermoskin.estimation.dsp import Iir

T_S = 1e-3
# (num, den) of the kinds the observer uses: low-pass, lead/lag, derivative, third order
SYSTEMS = [
    ([1.0], [0.1, 1.0]),
    ([2.0, 1.0], [0.3, 1.0]),
    ([1.0], [0.0166, 1.47, 1.0]),
    ([0.0166, 0.146, 0.0], [0.0166, 1.47, 1.0]),
    ([3.0, 0.5], [0.02, 0.4, 2.0]),
    ([1.0, 2.0], [1e-3, 0.05, 0.6, 1.0]),
]


def _tustin_ref(num: list[float], den: list[float], t_s: float) -> tuple[np.ndarray, np.ndarray]:
    nd, dd, _ = cont2discrete((np.asarray(num), np.asarray(den)), t_s, method="bilinear")
    nd = np.atleast_1d(np.squeeze(nd))
    dd = np.atleast_1d(np.squeeze(dd))
    return nd / dd[0], dd / dd[0]


@pytest.mark.parametrize(("num", "den"), SYSTEMS)
def test_tustin_vs_cont2discrete(num: list[float], den: list[float]) -> None:
    f = Iir(np.array(num), np.array(den), T_S)
    b, a = _tustin_ref(num, den, T_S)
    assert f.order == len(den) - 1
    np.testing.assert_allclose(f.a, a, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(f.b[-len(b):], b, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(f.b[:-len(b)], 0.0)


@pytest.mark.parametrize(("num", "den"), SYSTEMS)
def test_step_run_and_lfilter_agree(num: list[float], den: list[float]) -> None:
    rng = np.random.default_rng(7)
    x = 20.0 + np.cumsum(rng.normal(0, 0.05, 3000)) + rng.normal(0, 0.02, 3000)
    x0 = 20.0
    f = Iir(np.array(num), np.array(den), T_S)
    y_run = f.run(x, x0)
    z_end = list(f.z)
    f.reset(x0)
    y_step = np.array([f.step(float(v)) for v in x])
    # rounding scale: the largest partial sum a sample feeds into the recursion
    # (a third-order direct form with its poles near z = 1 is ill-conditioned: 100x looser)
    scale = max(np.abs(x).max() * np.abs(f.b).sum(), np.abs(y_run).max(), 1.0)
    scale *= 100.0 if f.order >= 3 else 1.0
    np.testing.assert_allclose(y_step, y_run, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(f.z, z_end, rtol=0, atol=1e-12 * scale)
    # an independent reference: lfilter of cont2discrete's coefficients, started at rest at
    # the DC steady state, i.e. fed a long constant prefix
    b, a = _tustin_ref(num, den, T_S)
    pre = np.full(200_000, x0)
    y_ref = lfilter(b, a, np.concatenate([pre, x]))[len(pre):]
    np.testing.assert_allclose(y_run, y_ref, rtol=0, atol=1e-9 * scale)


@pytest.mark.parametrize(("num", "den"), SYSTEMS)
def test_run_then_step_continues(num: list[float], den: list[float]) -> None:
    """``run`` leaves the state at the end: a log split in two gives the same output."""
    rng = np.random.default_rng(3)
    x = rng.normal(0, 1, 1000)
    f = Iir(np.array(num), np.array(den), T_S)
    whole = f.run(x, 0.5)
    f.run(x[:600], 0.5)
    tail = np.array([f.step(float(v)) for v in x[600:]])
    np.testing.assert_allclose(tail, whole[600:], atol=1e-12 * max(np.abs(whole).max(), 1))


@pytest.mark.parametrize(("num", "den"), SYSTEMS)
def test_reset_gives_constant_dc_output(num: list[float], den: list[float]) -> None:
    f = Iir(np.array(num), np.array(den), T_S)
    dc = num[-1] / den[-1]
    assert f.dc == pytest.approx(dc, rel=1e-12)
    x0 = 23.7
    f.reset(x0)
    y = np.array([f.step(x0) for _ in range(2000)])
    scale = abs(x0) * max(np.abs(f.b).sum(), abs(dc)) * (100.0 if f.order >= 3 else 1.0)
    np.testing.assert_allclose(y, dc * x0, rtol=0, atol=1e-11 * scale)
    np.testing.assert_allclose(f.run(np.full(500, x0), x0), dc * x0, rtol=0, atol=1e-11 * scale)


@pytest.mark.parametrize(("t_s", "tau"), [(1e-3, 0.1), (1e-3, 1.34), (1e-2, 0.1)])
def test_first_order_step_response(t_s: float, tau: float) -> None:
    """Tustin's step response is 1 - exp(-t/tau) to first order in t_s/tau, and, taking
    the half-sample shift of the bilinear map (the step's first sample counts as the mean
    of 0 and 1), to second order."""
    f = Iir(np.array([1.0]), np.array([tau, 1.0]), t_s)
    f.reset(0.0)
    n = int(6 * tau / t_s)
    y = np.array([f.step(1.0) for _ in range(n)])
    t = np.arange(n) * t_s
    h = t_s / tau
    assert np.abs(y - (1 - np.exp(-t / tau))).max() <= 0.5 * h
    assert np.abs(y - (1 - np.exp(-(t + 0.5 * t_s) / tau))).max() <= 0.2 * h**2


def test_second_order_step_response() -> None:
    """Q(s) = 1/((tau1 s+1)(tau2 s+1)): step response by partial fractions."""
    tau1, tau2 = 1.34, 0.124
    f = Iir(np.array([1.0]), np.polymul([tau1, 1.0], [tau2, 1.0]), T_S)
    x = np.ones(8000)
    y = f.run(x, 0.0)
    t = (np.arange(len(x)) + 0.5) * T_S
    ref = 1 - (tau1 * np.exp(-t / tau1) - tau2 * np.exp(-t / tau2)) / (tau1 - tau2)
    assert np.abs(y - ref).max() < 1e-4


def test_ramp_through_differentiator() -> None:
    """(a s^2 + b s)/((tau1 s+1)(tau2 s+1)) turns a ramp of slope c into the constant b c."""
    a_, b_ = 0.0166, 0.1464
    f = Iir(np.array([a_, b_, 0.0]), np.polymul([1.34, 1.0], [0.124, 1.0]), T_S)
    c = 0.3
    t = np.arange(30_000) * T_S
    y = f.run(20.0 + c * t, 20.0)
    np.testing.assert_allclose(y[-2000:], b_ * c, rtol=1e-6)


def test_order_zero_and_improper() -> None:
    f = Iir(np.array([2.5]), np.array([1.0]), T_S)
    assert f.order == 0
    assert f.step(2.0) == pytest.approx(5.0)
    np.testing.assert_allclose(f.run(np.array([1.0, -2.0]), 0.0), [2.5, -5.0])
    with pytest.raises(ValueError):
        Iir(np.array([1.0, 0.0]), np.array([1.0]), T_S)


@pytest.mark.parametrize(("num", "den"), [([1.0], [0.0166, 0.1464, 0.0]), ([2.0, 1.0], [1.0, 3.0, 2.0]),
                                          ([1.0], [1.34, 1.0]), ([3.0, 0.0, 1.0], [1.0, 2.0, 2.0, 1.0])])
def test_bilinear_is_scipys(num: list[float], den: list[float]) -> None:
    """The hand-written Tustin map (no scipy.signal import at start-up) against scipy's."""
    from scipy.signal import bilinear as scipy_bilinear

    from thermoskin.estimation.dsp import bilinear

    b, a = bilinear(np.array(num), np.array(den), 1000.0)
    b_ref, a_ref = scipy_bilinear(num, den, 1000.0)
    np.testing.assert_allclose(b, b_ref, rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(a, a_ref, rtol=1e-12, atol=1e-15)
