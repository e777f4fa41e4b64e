"""Conditions of the detection test bench: seeded, within their stated ranges, and the physics
of an ambient step against the network's DC gain."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest

from thermoskin.params import Config
from thermoskin.physics.convection import R_w
from thermoskin.physics.finger import PERSONS, Touch
from thermoskin.sim.conditions import CONDITIONS, decimate, get_condition, simulate_condition
from thermoskin.sim.run import simulate
from thermoskin.sim.scenarios import Scenario

SEEDS = range(5)
NAMES = list(CONDITIONS)


def gaps(touches: tuple[Touch, ...]) -> np.ndarray:
    return np.array([b.t_on - a.t_off for a, b in itertools.pairwise(touches)])


def check_default_population(sc: Scenario) -> None:
    t = sc.touches
    assert len(t) >= 5
    assert 5.0 <= t[0].t_on <= 7.0 and t[-1].t_off <= sc.duration - 1.0
    for tc in t:
        assert tc.n_fingers in (1, 2, 3) and tc.person in PERSONS and tc.G is None
        assert tc.T_body is not None and 32.0 <= tc.T_body <= 35.0
        assert 1.5 <= tc.duration <= 3.0
    g = gaps(t)
    assert np.all((g >= 5.0) & (g <= 9.0))


def test_registry_has_every_condition() -> None:
    assert set(NAMES) == {"ambient-step", "ambient-ramp", "holds", "taps", "tap-burst", "weak", "palm",
                          "cold", "noisy", "boards-10hz", "log-100hz", "log-50hz", "setpoints",
                          "quiet-hour"}
    with pytest.raises(KeyError, match=r"unknown condition 'x'.*ambient-step"):
        get_condition("x", 0)


@pytest.mark.parametrize("name", NAMES)
def test_generators_are_seeded(name: str) -> None:
    a, b, c = CONDITIONS[name](3), CONDITIONS[name](3), CONDITIONS[name](4)
    assert a == b and a.name == name and a.seed == 3
    assert (a.scenario.touches, a.scenario.ambient, a.scenario.setpoints, a.scenario.T_p_drift) != (
        c.scenario.touches, c.scenario.ambient, c.scenario.setpoints, c.scenario.T_p_drift)
    assert a.overrides["sensor"]["seed"] == 3
    assert isinstance(a.config(), Config)  # the overrides are a valid configuration


@pytest.mark.parametrize("name", NAMES)
def test_same_seed_same_log(name: str) -> None:
    a = simulate_condition(name, 5, duration=2.0)
    b = simulate_condition(name, 5, duration=2.0)
    c = simulate_condition(name, 6, duration=2.0)
    assert a.keys() == b.keys()
    for k in a:
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)
    assert not np.array_equal(a["T_w"], c["T_w"])


@pytest.mark.parametrize("seed", SEEDS)
def test_default_population(seed: int) -> None:
    for name in ("noisy", "boards-10hz", "log-100hz", "log-50hz"):
        check_default_population(CONDITIONS[name](seed).scenario)
    assert CONDITIONS["noisy"](seed).config().sensor.noise_T == 0.05
    s = CONDITIONS["boards-10hz"](seed).config().sensor
    assert (s.period_T_w, s.period_T_p, s.period_T_a, s.jitter) == (0.1, 0.1, 0.1, 0.003)
    assert CONDITIONS["log-100hz"](seed).decimate == 10
    assert CONDITIONS["log-50hz"](seed).decimate == 20


@pytest.mark.parametrize("seed", SEEDS)
def test_ambient_step_ranges(seed: int) -> None:
    cond = CONDITIONS["ambient-step"](seed)
    sc = cond.scenario
    pts = np.array(sc.ambient)
    assert len(pts) % 2 == 0 and 3 <= len(pts) // 2 <= 4
    starts, ends = pts[0::2], pts[1::2]
    rise = ends[:, 0] - starts[:, 0]
    assert np.all((rise >= 0.3) & (rise <= 1.0))  # within 1 s
    np.testing.assert_allclose(np.abs(ends[:, 1] - starts[:, 1]), 1.0)
    np.testing.assert_allclose(starts[1:, 1], ends[:-1, 1])  # the air stays between doors
    spacing = np.diff(starts[:, 0])
    assert np.all((spacing >= 40.0) & (spacing <= 70.0))
    for tc in sc.touches:  # none during a door event or within 5 s after it
        for (t0, _), (t1, _) in zip(starts, ends, strict=True):
            assert tc.t_off <= t0 or tc.t_on >= t1 + 5.0
    assert all(1.5 <= tc.duration <= 3.0 for tc in sc.touches) and np.all(gaps(sc.touches) >= 5.0)
    assert cond.config().sensor.lag_T_a == 1.0


@pytest.mark.parametrize("seed", SEEDS)
def test_ambient_ramp_and_quiet_hour_ranges(seed: int) -> None:
    ramp = CONDITIONS["ambient-ramp"](seed)
    (t0, a0), (t1, a1), (t2, a2) = ramp.scenario.ambient
    assert a0 == a2 == 20.0 and 2.0 <= abs(a1 - a0) <= 3.0
    assert t1 - t0 == pytest.approx(600.0) and t2 - t1 == pytest.approx(600.0)
    check_default_population(ramp.scenario)
    assert ramp.config().sensor.lag_T_a == 1.0
    quiet = CONDITIONS["quiet-hour"](seed)
    sc = quiet.scenario
    assert sc.touches == () and sc.duration == 3600.0 and sc.pump == "logic"
    pts = np.array(sc.ambient)
    assert np.all(np.diff(pts[:, 0]) == 600.0) and np.all(np.abs(np.diff(pts[:, 1])) <= 1.0)
    assert np.ptp(sc.T_a_at(np.linspace(0, 3600, 100))) > 0.2  # it does drift
    assert quiet.config().sensor.lag_T_a == 1.0


@pytest.mark.parametrize("seed", SEEDS)
def test_touch_shapes(seed: int) -> None:
    holds = CONDITIONS["holds"](seed).scenario.touches
    assert holds and all(20.0 <= tc.duration <= 60.0 for tc in holds) and np.all(gaps(holds) >= 5.0)
    taps = CONDITIONS["taps"](seed).scenario.touches
    assert len(taps) >= 10 and all(0.2 <= tc.duration <= 0.5 for tc in taps)
    g = gaps(taps)
    assert np.all((g >= 3.0) & (g <= 8.0))
    burst = CONDITIONS["tap-burst"](seed).scenario.touches
    assert len(burst) >= 10 and len(burst) % 5 == 0
    for i in range(0, len(burst), 5):
        b = burst[i:i + 5]
        np.testing.assert_allclose(np.diff([tc.t_on for tc in b]), 1.0)  # onset to onset
        assert all(0.2 <= tc.duration <= 0.5 for tc in b)
        if i + 5 < len(burst):
            assert burst[i + 5].t_on - b[-1].t_off == pytest.approx(8.0)
    weak = CONDITIONS["weak"](seed).scenario.touches
    assert weak and all(tc.G == 0.02 and tc.n_fingers == 1 for tc in weak)
    palm = CONDITIONS["palm"](seed).scenario.touches
    assert palm and all(tc.G == 0.3 and tc.n_fingers == 0 for tc in palm)
    cold = CONDITIONS["cold"](seed).scenario.touches
    assert cold
    for tc in cold:
        assert 12.0 <= tc.T_body <= 18.0 and 0.05 <= tc.G <= 0.3 and 1.0 <= tc.duration <= 5.0  # type: ignore[operator]
        assert tc.n_fingers == 0
    assert np.all(gaps(cold) >= 5.0)


@pytest.mark.parametrize("seed", SEEDS)
def test_setpoints_ranges(seed: int) -> None:
    sc = CONDITIONS["setpoints"](seed).scenario
    sp = sc.setpoints
    assert sp[0] == (0.0, 24.0) and len(sp) == 4
    t, c = np.array(sp).T
    assert np.all((np.diff(t) >= 60.0) & (np.diff(t) <= 90.0))
    assert np.all((c >= 22.0) & (c <= 28.0)) and np.all(c * 2 == np.round(c * 2))
    assert np.all((np.abs(np.diff(c)) >= 1.0) & (np.abs(np.diff(c)) <= 4.0))
    for tc in sc.touches:
        for t0 in t[1:]:
            assert tc.t_off <= t0 or tc.t_on >= t0 + 10.0
    assert len(sc.touches) >= 10


def test_decimate_keeps_every_nth_row_and_the_pump_switches() -> None:
    log = {"t": np.arange(25) * 1e-3, "x": np.arange(25.0) ** 2}
    d = decimate(log, 10)
    np.testing.assert_array_equal(d["t"], [0.0, 0.01, 0.02])
    np.testing.assert_array_equal(d["x"], [0.0, 100.0, 400.0])
    for bad in (0, 2.5, True):
        with pytest.raises(ValueError, match="factor"):
            decimate(log, bad)  # type: ignore[arg-type]
    cond = CONDITIONS["log-100hz"](2)
    full = simulate(cond.scenario.with_duration(20.0), cond.config())
    slow = simulate_condition("log-100hz", 2, duration=20.0)
    np.testing.assert_allclose(np.diff(slow["t"]), 0.01)
    # the pump holds each state >= 50 ms (5 rows): no switch is lost at 100 Hz
    v = full["v"]
    sw = np.flatnonzero(np.diff(v)) + 1
    assert np.diff(sw).min() >= 50
    assert np.count_nonzero(np.diff(slow["v"])) == sw.size > 100


def dc_gains(Rw: float, sk) -> tuple[float, float]:  # type: ignore[no-untyped-def]
    """dT_w/dT_a and dT_g/dT_a in steady state, by Cramer's rule on the two balances::

        (g_w + g_aw + g_g) T_w - g_g T_g = g_w T_p + g_aw T_a
        -g_g T_w + (g_g + g_ag) T_g      = g_ag T_a
    """
    gw, gaw, gg, gag = 1 / Rw, 1 / sk.R_aw, 1 / sk.R_g, 1 / sk.R_ag
    a11, a12, a22 = gw + gaw + gg, -gg, gg + gag
    det = a11 * a22 - a12 * a12
    return (gaw * a22 - a12 * gag) / det, (a11 * gag - a12 * gaw) / det


@pytest.mark.parametrize("pump", ["on", "off"])
def test_ambient_step_reaches_the_networks_steady_state(pump: str) -> None:
    cond = CONDITIONS["ambient-step"](1)
    (t0, Ta0), (t1, Ta1) = cond.scenario.ambient[:2]
    sc = dataclasses.replace(cond.scenario, touches=(), pump=pump, T_p_drift=0.0, duration=t1 + 30.0)
    cfg = cond.config()
    r = simulate(sc, cfg)
    k0, k_end = int(t0 / 1e-3) - 1, len(r["t"]) - 1
    gw, gg = dc_gains(R_w(cfg.pump.v_on if pump == "on" else 0.0, cfg.skin), cfg.skin)
    assert 0.0 < gw < 1.0 and 0.0 < gg < 1.0
    dT = Ta1 - Ta0
    assert r["T_w_true"][k_end] - r["T_w_true"][k0] == pytest.approx(gw * dT, abs=1e-9)
    assert r["T_g"][k_end] - r["T_g"][k0] == pytest.approx(gg * dT, abs=1e-9)
    # the air sensor lags (1 s) the true air, then settles on it
    k_half = int((t1 + 0.5) / 1e-3)
    assert abs(r["T_a"][k_half] - r["T_a_true"][k_half]) > 0.3
    late = r["t"] > t1 + 20.0
    assert np.mean(r["T_a"][late]) == pytest.approx(Ta1, abs=0.01)
