"""Contact detector on synthetic residuals whose truth is known by construction."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import lfilter

from thermoskin.detector import ContactDetector
from thermoskin.params import DetectorParams

T_S = 1e-3


def coloured_noise(n: int, sigma: float, tau: float, seed: int) -> np.ndarray:
    """Gaussian noise through a first-order low-pass (time constant ``tau``), std ``sigma``."""
    rng = np.random.default_rng(seed)
    a = np.exp(-T_S / tau)
    x = lfilter([1 - a], [1, -a], rng.normal(0, 1, n))
    return sigma * x / np.sqrt((1 - a) / (1 + a))


def steps(n: int, touches: list[tuple[float, float, float]], tau: float = 0.03) -> np.ndarray:
    """Sum of steps (t_on, t_off, height) smoothed by a first-order lag."""
    t = np.arange(n) * T_S
    x = np.zeros(n)
    for a, b, h in touches:
        x[(t >= a) & (t < b)] += h
    al = np.exp(-T_S / tau)
    return lfilter([1 - al], [1, -al], x)


TOUCHES = [(5.0, 7.0, 0.06), (12.0, 14.5, 0.12), (20.0, 21.6, 0.06), (28.0, 31.0, 0.18)]


def test_detects_steps_in_noise_with_short_latency() -> None:
    n = 40_000
    r = 0.3 + steps(n, TOUCHES) + coloured_noise(n, 0.008, 0.03, seed=1)
    t = np.arange(n) * T_S
    det = ContactDetector(DetectorParams(), T_S)
    contact = det.run(t, r, r - 0.3)
    assert len(det.events) == len(TOUCHES)
    for e, (a, b, h) in zip(det.events, TOUCHES, strict=True):
        assert a <= e.detected_at < a + 0.3
        assert abs(e.onset - a) < 0.1
        assert abs(e.release - b) < 0.15
        assert h - 0.01 < e.peak_r < h + 5 * 0.008  # the peak of a noisy plateau
    # contact flag raised from detection to release
    e0 = det.events[0]
    assert contact[int(e0.detected_at / T_S) + 1] == 1
    assert contact[int(e0.onset / T_S) - 5] == 0


def test_no_false_alarm_in_ten_minutes_of_noise() -> None:
    n = 600_000
    r = coloured_noise(n, 0.01, 0.05, seed=2) + 0.002 * np.sin(np.arange(n) * T_S / 30)
    det = ContactDetector(DetectorParams(), T_S)
    det.run(np.arange(n) * T_S, r, r)
    assert det.events == []


def test_sigma_learnt_from_noise() -> None:
    n = 5000
    r = np.random.default_rng(3).normal(0.5, 0.01, n)
    det = ContactDetector(DetectorParams(t_warmup=2.0), T_S)
    det.run(np.arange(n) * T_S, r, r)
    assert det.sigma == pytest.approx(0.01, rel=0.1)
    assert det.b == pytest.approx(0.5, abs=0.002)


def test_fixed_sigma_from_config() -> None:
    n = 20_000
    r = steps(n, [(6.0, 8.0, 0.05)]) + np.random.default_rng(4).normal(0, 0.004, n)
    det = ContactDetector(DetectorParams(sigma=0.05), T_S)  # threshold 5.5 * 0.05: nothing
    det.run(np.arange(n) * T_S, r, r)
    assert det.sigma == 0.05 and det.events == []


def test_long_touch_is_not_swallowed() -> None:
    n = 80_000
    r = steps(n, [(10.0, 70.0, 0.05)]) + coloured_noise(n, 0.006, 0.03, seed=5)
    det = ContactDetector(DetectorParams(), T_S)
    contact = det.run(np.arange(n) * T_S, r, r)
    assert len(det.events) == 1
    assert det.events[0].duration == pytest.approx(60.0, abs=0.3)
    assert contact[int(10.5 / T_S):int(69.5 / T_S)].all()


def test_no_retrigger_on_slow_decay_after_release() -> None:
    """A release followed by a slowly decaying overshoot must give one event, not two."""
    n = 20_000
    t = np.arange(n) * T_S
    r = steps(n, [(5.0, 7.0, 0.1)])
    tail = (t >= 7.0) * 0.03 * np.exp(-(t - 7.0) / 1.3) * (t < 12.0)
    r = r + np.where(t > 7.2, tail, 0) + coloured_noise(n, 0.005, 0.03, seed=6)
    det = ContactDetector(DetectorParams(), T_S)
    det.run(t, r, r)
    assert len(det.events) == 1


def test_event_metrics_match_hand_computation_on_dq() -> None:
    """peak, mean and energy are taken on dq minus its baseline over [detection, release]."""
    n = 12_000
    t = np.arange(n) * T_S
    r = steps(n, [(4.0, 6.0, 0.2)], tau=0.001)
    dq = 1.0 + np.where((t >= 4.0) & (t < 6.0), 0.05 * (t - 4.0), 0.0)  # ramp 0 -> 0.1 W
    det = ContactDetector(DetectorParams(sigma=0.01, t_warmup=1.0), T_S)
    det.run(t, r, dq)
    (e,) = det.events
    win = (t >= e.detected_at) & (t < e.release + T_S / 2)
    d = dq[win] - 1.0
    assert e.peak_dq == pytest.approx(d.max(), abs=2e-4)
    assert e.mean_dq == pytest.approx(d.mean(), abs=2e-3)
    assert e.energy == pytest.approx(e.mean_dq * e.duration, rel=1e-12)


def test_gaps_hold_the_state() -> None:
    n = 20_000
    t = np.arange(n) * T_S
    r = steps(n, [(5.0, 8.0, 0.08)]) + coloured_noise(n, 0.005, 0.03, seed=7)
    gap = np.zeros(n, dtype=bool)
    gap[6000:6300] = True
    r_bad = r.copy()
    r_bad[gap] = np.nan
    det = ContactDetector(DetectorParams(), T_S)
    c = det.run(t, r_bad, r_bad, gap)
    assert len(det.events) == 1
    assert c[6000:6300].all()  # held through the gap


def test_step_and_run_agree() -> None:
    n = 30_000
    t = np.arange(n) * T_S
    r = steps(n, TOUCHES[:3]) + coloured_noise(n, 0.008, 0.03, seed=8)
    a = ContactDetector(DetectorParams(), T_S)
    ca = a.run(t, r, r)
    b = ContactDetector(DetectorParams(), T_S)
    cb = np.array([b.step(float(tk), float(rk), float(rk)) for tk, rk in zip(t, r, strict=True)])
    b.finish(float(t[-1]))
    np.testing.assert_array_equal(ca, cb)
    assert a.events == b.events
