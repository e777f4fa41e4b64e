"""Inner PI loop on the Peltier drive: against a hand-written discrete PI, anti-windup, clipping."""

from __future__ import annotations

import math

import pytest

from thermoskin.control.inner import InnerLoop
from thermoskin.params import ControlParams

CTL = ControlParams()  # Kp = 0.1 /K, Ki = 0.03 /(K s), drive in [-1, 1]


class Plant:
    """First-order tank: tau dT_p/dt = -(T_p - T_a) + K drive, exact ZOH step."""

    def __init__(self, t_s: float, tau: float = 20.0, K: float = 15.0, T_a: float = 20.0) -> None:
        self.phi = math.exp(-t_s / tau)
        self.K, self.T_a, self.T_p = K, T_a, T_a

    def step(self, drive: float) -> float:
        target = self.T_a + self.K * drive
        self.T_p = target + (self.T_p - target) * self.phi
        return self.T_p


def test_step_response_matches_hand_written_pi() -> None:
    t_s = 1e-2
    pi = InnerLoop(CTL, t_s)
    plant_a, plant_b = Plant(t_s), Plant(t_s)
    integ = 0.0
    cmd = 22.0                       # small step: no saturation (Kp e = 0.2)
    for _ in range(6000):
        d = pi.step(plant_a.T_p, cmd, 20.0)
        e = cmd - plant_b.T_p
        integ += 0.03 * t_s * e      # backward Euler
        d_ref = 0.1 * e + integ
        assert abs(d - d_ref) < 1e-12
        assert not pi.saturated
        plant_a.step(d)
        plant_b.step(d_ref)
    assert abs(plant_a.T_p - cmd) < 0.02    # integral action: no offset


def run(pi: InnerLoop, plant: Plant, cmd: float, n: int) -> list[float]:
    out = []
    for _ in range(n):
        d = pi.step(plant.T_p, cmd, plant.T_a)
        assert pi.drive_min <= d <= pi.drive_max
        plant.step(d)
        out.append(plant.T_p)
    return out


def recovery_time(pi: InnerLoop, t_s: float) -> float:
    """Saturate for 300 s on an unreachable command, then return to a reachable one."""
    plant = Plant(t_s)
    run(pi, plant, 50.0, int(300 / t_s))          # max reachable is T_a + K = 35
    back = 25.0
    for k in range(int(600 / t_s)):
        d = pi.step(plant.T_p, back, plant.T_a)
        plant.step(d)
        if d < pi.drive_max and plant.T_p < back + 1.0:
            return k * t_s
    return math.inf


def test_anti_windup_bounds_recovery() -> None:
    t_s = 1e-2
    pi = InnerLoop(CTL, t_s)
    t_rec = recovery_time(pi, t_s)
    assert pi.integral <= CTL.drive_max - CTL.drive_min
    # the plant needs about tau ln(15/11) ~ 6 s to fall from 35 to 26 at full cooling at most
    assert t_rec < 20.0

    class NoAntiWindup(InnerLoop):
        __slots__ = ()

        def step(self, T_p: float, T_p_cmd: float, T_a: float = 20.0) -> float:
            e = T_p_cmd - T_p
            self.integral += self._ki_ts * e
            self.drive = min(max(self.Kp * e + self.integral, self.drive_min), self.drive_max)
            return self.drive

    wound = recovery_time(NoAntiWindup(CTL, t_s), t_s)
    assert wound > 5 * t_rec                         # the check would catch a missing clamp


def test_integrator_frozen_while_saturated() -> None:
    t_s = 1e-3
    pi = InnerLoop(CTL, t_s)
    pi.reset(0.0)
    d = pi.step(0.0, 100.0)        # Kp e = 10: saturated at once
    assert d == CTL.drive_max and pi.saturated
    i0 = pi.integral
    for _ in range(1000):
        pi.step(0.0, 100.0)
    assert pi.integral == i0
    d = pi.step(0.0, -100.0)       # saturated the other way: still frozen
    assert d == CTL.drive_min and pi.integral == i0
    d = pi.step(0.0, -5.0)         # back inside the range: integration resumes
    assert d == pytest.approx(-0.5 - 0.03e-3 * 5.0) and pi.integral < i0


def test_clipping_to_custom_drive_range() -> None:
    ctl = ControlParams(drive_min=-0.4, drive_max=0.7)
    pi = InnerLoop(ctl, 1e-3)
    for cmd in (100.0, -100.0, 20.0, 60.0):
        for _ in range(200):
            d = pi.step(20.0, cmd)
            assert -0.4 <= d <= 0.7
    assert pi.step(20.0, 100.0) == 0.7
    assert pi.step(20.0, -100.0) == -0.4


def test_reset_and_feedforward() -> None:
    pi = InnerLoop(CTL, 1e-3)
    pi.reset(0.3)
    assert pi.step(25.0, 25.0) == pytest.approx(0.3)
    assert InnerLoop(CTL, 1e-3).reset(5.0) is None
    ff_gain = InnerLoop(CTL, 1e-3, feedforward=0.05)
    assert ff_gain.step(30.0, 30.0, 20.0) == pytest.approx(0.5)     # 0.05 * (30 - 20)
    calls = []

    def ff(T_p_cmd: float, T_a: float) -> float:
        calls.append((T_p_cmd, T_a))
        return -0.2

    ff_fn = InnerLoop(CTL, 1e-3, feedforward=ff)
    assert ff_fn.step(10.0, 10.0, 20.0) == pytest.approx(-0.2)
    assert calls == [(10.0, 20.0)]
    # with an exact feed-forward of the plant's static map, the integrator stays near 0
    t_s = 1e-2
    plant = Plant(t_s)
    exact = InnerLoop(CTL, t_s, feedforward=lambda c, a: (c - a) / plant.K)
    run(exact, plant, 28.0, 20000)
    assert abs(plant.T_p - 28.0) < 1e-3
    assert abs(exact.integral) < 1e-3


def test_nan_reading_holds_drive() -> None:
    pi = InnerLoop(CTL, 1e-3)
    d = pi.step(20.0, 22.0)
    i0 = pi.integral
    assert pi.step(float("nan"), 22.0) == d
    assert pi.integral == i0


def test_bad_arguments() -> None:
    with pytest.raises(ValueError):
        InnerLoop(CTL, 0.0)
