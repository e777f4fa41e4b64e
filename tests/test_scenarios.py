"""Scenarios (as specified) and the simulation run on them."""

from __future__ import annotations

import math

import numpy as np
import pytest

from thermoskin.control.pump import PumpLogic
from thermoskin.params import Config
from thermoskin.physics.finger import PERSONS, Touch
from thermoskin.sim.run import simulate
from thermoskin.sim.scenarios import SCENARIOS, Scenario, random_scenario

CFG = Config()


def gaps(sc: Scenario) -> list[float]:
    return [b.t_on - a.t_off for a, b in zip(sc.touches, sc.touches[1:], strict=False)]


def check_touch_sequence(sc: Scenario) -> None:
    assert sc.touches[0].t_on >= 5.0
    for tc in sc.touches:
        assert 1.5 <= tc.duration <= 3.0
        assert tc.t_off <= sc.duration
    for g in gaps(sc):
        assert 5.0 <= g <= 9.0


def test_named_scenarios_exist():
    for name in ("fingers", "one-finger", "persons", "long-touch", "pump-on", "none", "realistic"):
        assert name in SCENARIOS
        assert SCENARIOS[name].name == name


def test_fingers_scenario():
    sc = SCENARIOS["fingers"]
    assert sc.pump == "logic" and sc.T_w_cmd == 24.0 and sc.T_a == 20.0
    assert 80.0 <= sc.duration <= 100.0
    assert sorted(tc.n_fingers for tc in sc.touches) == [1, 1, 1, 2, 2, 2, 3, 3, 3]
    assert {tc.person for tc in sc.touches} == {"man1"}
    check_touch_sequence(sc)


def test_other_named_scenarios():
    one = SCENARIOS["one-finger"]
    assert len(one.touches) >= 3 and all(tc.n_fingers == 1 for tc in one.touches)
    check_touch_sequence(one)
    persons = SCENARIOS["persons"]
    assert all(tc.n_fingers == 1 for tc in persons.touches)
    for who in ("man1", "woman1", "woman2"):
        assert sum(tc.person == who for tc in persons.touches) >= 2
    check_touch_sequence(persons)
    long = SCENARIOS["long-touch"]
    assert any(tc.duration == 30.0 for tc in long.touches)
    assert max(tc.t_off for tc in long.touches) < long.duration
    pump_on = SCENARIOS["pump-on"]
    assert pump_on.pump == "on" and len(pump_on.touches) > 0
    none = SCENARIOS["none"]
    assert none.touches == () and none.duration == 60.0


@pytest.mark.parametrize("seed", [0, 1, 5, 123, 98765])
def test_random_scenarios_follow_their_distributions(seed):
    sc = random_scenario(seed, 150.0)
    assert len(sc.touches) >= 8  # 150 s hold about 14 touches of 2.25 + 7 s
    check_touch_sequence(sc)
    assert sc.touches[0].t_on <= 7.0
    for tc in sc.touches:
        assert tc.n_fingers in (1, 2, 3)
        assert tc.person in PERSONS
        assert tc.T_body is not None and 32.0 <= tc.T_body <= 35.0
    assert 0.0 < sc.T_p_drift <= 0.05


def test_random_scenarios_are_seeded_and_varied():
    assert random_scenario(3, 100.0) == random_scenario(3, 100.0)
    assert random_scenario(3, 100.0).touches != random_scenario(4, 100.0).touches
    many = [tc for s in range(20) for tc in random_scenario(s, 120.0).touches]
    assert {tc.n_fingers for tc in many} == {1, 2, 3}
    assert {tc.person for tc in many} == set(PERSONS)
    d = np.array([tc.duration for tc in many])
    assert d.mean() == pytest.approx(2.25, abs=0.15)  # U(1.5, 3)


def test_realistic_is_a_random_scenario():
    sc = SCENARIOS["realistic"]
    check_touch_sequence(sc)
    assert len({tc.n_fingers for tc in sc.touches}) > 1


def test_with_duration_and_T_p_profile():
    sc = SCENARIOS["fingers"].with_duration(20.0)
    assert sc.duration == 20.0 and all(tc.t_on < 20.0 for tc in sc.touches)
    assert len(sc.touches) < len(SCENARIOS["fingers"].touches)
    assert sc.T_p(3.0) == pytest.approx(24.3)
    drift = Scenario("d", "", 10.0, T_p_offset=0.3, T_p_drift=0.02, T_p_period=40.0)
    assert drift.T_p(10.0) == pytest.approx(24.32)
    tp = drift.T_p(np.linspace(0, 80, 801))
    assert tp.min() == pytest.approx(24.28) and tp.max() == pytest.approx(24.32)
    with pytest.raises(ValueError, match="pump"):
        Scenario("x", "", 10.0, pump="sometimes")


# -- simulate --------------------------------------------------------------------------


def test_simulate_columns_and_truth():
    sc = SCENARIOS["fingers"].with_duration(12.0)
    calls: list[float] = []
    r = simulate(sc, CFG, progress=calls.append)
    n = 12_000
    for col in ("t", "T_w", "T_p", "v", "T_a", "T_w_cmd", "T_w_true", "T_g", "q_i", "contact_true",
                "n_fingers"):
        assert r[col].shape == (n,), col
    np.testing.assert_allclose(r["t"], np.arange(n) * 1e-3)
    assert 90 <= len(calls) <= 102 and calls[-1] == 1.0 and np.all(np.diff(calls) > 0)
    # contact truth from the touch list
    t = r["t"]
    inside = np.zeros(n, bool)
    nf = np.zeros(n, int)
    for tc in sc.touches:
        m = (t > tc.t_on) & (t < tc.t_off)
        inside |= m
        nf[m] += tc.n_fingers
    np.testing.assert_array_equal(r["contact_true"], inside.astype(int))
    np.testing.assert_array_equal(r["n_fingers"], nf)
    # q_i: zero without contact, a finger's conductance times the gradient on the plateau
    assert np.all(r["q_i"][~inside] == 0.0)
    tc = sc.touches[0]
    k = round((tc.t_on + 1.0) / 1e-3)
    p = PERSONS[tc.person]
    assert r["q_i"][k] == pytest.approx(tc.n_fingers * p.G_finger * (p.T_body - r["T_g"][k]), rel=1e-12)
    assert r["q_i"][k] > 0.3
    assert np.all(r["T_w_cmd"] == 24.0)


def test_simulate_pump_logic_runs_on_measured_temperature():
    r = simulate("none", CFG, duration=10.0)
    v, Tw, Tw_true = r["v"], r["T_w"], r["T_w_true"]
    assert set(np.unique(v)) == {0.0, CFG.pump.v_on}
    stops = np.flatnonzero((v[1:] == 0) & (v[:-1] > 0)) + 1
    starts = np.flatnonzero((v[1:] > 0) & (v[:-1] == 0)) + 1
    assert len(stops) > 20
    assert np.all(Tw[stops] > 24.0) and np.all(Tw[starts] < 24.0)
    # the wiring: a pump logic fed the measured column reproduces v, fed the truth it does not
    # (with Table I's small C_w the pipe overshoots within the 50 ms dwell, so the two differ
    # in the timing of some switches, not in whether they happen)
    def replay(T_w: np.ndarray) -> np.ndarray:
        pump = PumpLogic(CFG.pump, CFG.sampling.t_s)
        return np.array([pump.step(float(x), 24.0) for x in T_w])
    np.testing.assert_array_equal(replay(Tw), v)
    assert not np.array_equal(replay(Tw_true), v)
    # the loop holds the command within its chattering (Fig. 8): a sawtooth of a few tenths
    # of a kelvin set by the dwell, the pump running part of the time
    assert np.all(np.abs(Tw_true - 24.0) < 0.25)
    assert 0.2 < np.mean(v > 0) < 0.8
    # measured = truth + noise of the configured size, on the thermocouple grid
    err = Tw - Tw_true
    assert np.std(err) == pytest.approx(CFG.sensor.noise_T, rel=0.05)
    q = CFG.sensor.quantum_T
    np.testing.assert_allclose(Tw / q, np.round(Tw / q), atol=1e-6)
    assert np.std(r["T_p"] - 24.3) == pytest.approx(CFG.sensor.noise_T, rel=0.05)
    assert np.std(r["T_a"] - 20.0) == pytest.approx(CFG.sensor.noise_T, rel=0.05)


def test_simulate_starts_in_equilibrium():
    # pump always on, no touch in the first 5 s: the truth must not move
    r = simulate("pump-on", CFG, duration=4.0)
    assert np.ptp(r["T_w_true"]) < 1e-9 and np.ptp(r["T_g"]) < 1e-9
    # the same with the pump off
    sc = Scenario("off", "", 3.0, pump="off")
    r = simulate(sc, CFG)
    assert np.all(r["v"] == 0.0)
    assert np.ptp(r["T_w_true"]) < 1e-9
    # pump logic: starts at the command with the sheet's no-touch equilibrium
    r = simulate("fingers", CFG, duration=1.0)
    assert r["T_w_true"][0] == 24.0
    assert r["T_g"][0] == pytest.approx((24.0 / 10.0 + 20.0 / 1.0) / (1 / 10.0 + 1 / 1.0), rel=1e-14)


def test_simulate_is_deterministic_and_seeded():
    a = simulate("realistic", CFG, duration=8.0)
    b = simulate("realistic", CFG, duration=8.0)
    for col in a:
        np.testing.assert_array_equal(a[col], b[col])
    c = simulate("realistic", CFG.replace(sensor={"seed": 99}), duration=8.0)
    assert not np.array_equal(a["T_w"], c["T_w"])


def test_more_fingers_more_heat_flow():
    sc = Scenario("f", "", 30.0, touches=(Touch(5.0, 2.0, 1), Touch(12.0, 2.0, 2), Touch(19.0, 2.0, 3)))
    r = simulate(sc, CFG)
    peaks = [r["q_i"][(r["t"] > tc.t_on) & (r["t"] < tc.t_off)].max() for tc in sc.touches]
    assert peaks[0] < peaks[1] < peaks[2]
    # the sheet warms under the finger
    assert r["T_g"][int(6.9 / 1e-3)] > r["T_g"][int(4.9 / 1e-3)] + 0.3


# -- ambient, set-point schedules, sensors in the log ------------------------------------


def test_ambient_profile_is_piecewise_linear():
    sc = Scenario("a", "", 100.0, T_a=99.0, ambient=((10.0, 20.0), (11.0, 21.0), (70.0, 18.5)))
    assert sc.T_a == 20.0  # the profile's value at t = 0
    t = np.array([0.0, 10.0, 10.25, 11.0, 40.5, 70.0, 95.0])
    np.testing.assert_allclose(sc.T_a_at(t), [20.0, 20.0, 20.25, 21.0, 21.0 - 2.5 * 29.5 / 59.0, 18.5, 18.5],
                               rtol=0, atol=1e-12)
    assert sc.T_a_at(10.5) == pytest.approx(20.5)
    sh = sc.shifted(5.0)
    assert sh.T_a_at(15.5) == pytest.approx(20.5) and sh.duration == 105.0
    assert Scenario("c", "", 10.0, T_a=22.0).T_a_at(3.0) == 22.0
    with pytest.raises(ValueError, match="the times of ambient must increase"):
        Scenario("x", "", 10.0, ambient=((1.0, 20.0), (1.0, 21.0)))
    with pytest.raises(ValueError, match="finite"):
        Scenario("x", "", 10.0, ambient=((1.0, float("nan")),))


def rate_limited(target: np.ndarray, start: float, step: float) -> np.ndarray:
    """A discrete rate limiter, written out again: move at most ``step`` toward the target per sample."""
    out = np.empty_like(target)
    p = start
    for k, c in enumerate(target):
        out[k] = p
        p += min(max(c - p, -step), step)
    return out


def test_prescribed_T_p_follows_the_setpoints_rate_limited():
    sc = Scenario("s", "", 90.0, setpoints=((0.0, 24.0), (30.0, 26.0), (60.0, 23.0)), T_p_offset=0.3,
                  T_p_rate=0.3)
    t = np.arange(90_000) * 1e-3
    tp = sc.T_p(t)
    target = sc.T_w_cmd_profile(t) + 0.3
    np.testing.assert_allclose(tp, rate_limited(target, 24.3, 0.3e-3), rtol=0, atol=1e-9)
    assert np.max(np.abs(np.diff(tp))) <= 0.3e-3 + 1e-12
    # 2 K up at 0.3 K/s takes 6.67 s; 3 K down takes 10 s
    assert sc.T_p(30.0 + 2.0 / 0.3 - 0.01) < 26.3 and sc.T_p(30.0 + 2.0 / 0.3 + 0.01) == pytest.approx(26.3)
    assert sc.T_p(70.0 - 0.01) > 23.3 and sc.T_p(70.01) == pytest.approx(23.3)
    np.testing.assert_array_equal(sc.T_w_cmd_profile(np.array([0.0, 29.999, 30.0, 75.0])),
                                  [24.0, 24.0, 26.0, 23.0])
    # no schedule: the constant offset of before
    assert Scenario("c", "", 10.0).T_p(5.0) == pytest.approx(24.3)


def test_simulate_honours_the_setpoint_schedule():
    sc = Scenario("s", "", 60.0, setpoints=((0.0, 24.0), (20.0, 26.0), (40.0, 23.0)))
    r = simulate(sc, CFG)
    np.testing.assert_array_equal(r["T_w_cmd"], sc.T_w_cmd_profile(r["t"]))
    for t0, cmd in ((0.0, 24.0), (20.0, 26.0), (40.0, 23.0)):
        w = (r["t"] >= t0 + 15.0) & (r["t"] < t0 + 20.0)
        assert np.mean(np.abs(r["T_w_true"][w] - cmd)) < 0.15
    # the pump logic ran against the command of each sample
    pump = PumpLogic(CFG.pump, CFG.sampling.t_s)
    v = np.array([pump.step(float(m), float(c)) for m, c in zip(r["T_w"], r["T_w_cmd"], strict=True)])
    np.testing.assert_array_equal(v, r["v"])


def test_simulate_logs_fresh_and_the_true_ambient_seen_through_the_air_sensor_lag():
    tau, r_K = 1.0, 1.0  # lag (s); ambient ramp 1 K/s from 5 to 6 s
    cfg = CFG.replace(sensor={"noise_T": 0.0, "quantum_T": 0.0, "lag_T_a": tau, "period_T_w": 0.1})
    sc = Scenario("amb", "", 12.0, ambient=((5.0, 20.0), (6.0, 21.0)))
    r = simulate(sc, cfg)
    t = r["t"]
    np.testing.assert_allclose(r["T_a_true"], sc.T_a_at(t), rtol=0, atol=1e-12)
    # first-order lag of a ramp: x - r tau (1 - e^{-(t - t0)/tau}) during it, then relaxing
    # (to half a sample of the ramp: the element integrates the air held over each sample)
    ramp = (t >= 5.0) & (t <= 6.0)
    expected = r["T_a_true"][ramp] - r_K * tau * (1 - np.exp(-(t[ramp] - 5.0) / tau))
    np.testing.assert_allclose(r["T_a"][ramp], expected, rtol=0, atol=r_K * 1e-3)
    after = t > 6.0
    lag_end = r_K * tau * (1 - math.exp(-1.0 / tau))
    expected = 21.0 - lag_end * np.exp(-(t[after] - 6.0) / tau)
    np.testing.assert_allclose(r["T_a"][after], expected, rtol=0, atol=r_K * 1e-3)
    # fresh: T_w every 100th sample, T_p and T_a every sample
    k = np.arange(len(t))
    np.testing.assert_array_equal(r["fresh"], np.where(k % 100 == 0, 7, 6))
    assert np.all(r["T_w"] == r["T_w"][k - k % 100])


@pytest.mark.parametrize("name", ["fingers", "touchers"])
def test_simulation_in_blocks_is_the_same_samples(name: str) -> None:
    """:func:`simulate_blocks` (``thermoskin simulate`` writes each block as it comes): blocks of 997
    samples, cut anywhere (mid-touch, mid-board-interval), join to the same log, column for column
    and type for type, as one block the length of the run (the plant, pump and boards keep their
    state from block to block); and each block holds only its own samples."""
    from thermoskin.sim.run import simulate_blocks

    whole = next(simulate_blocks(name, CFG, 21.0, block=10**9))
    blocks = list(simulate_blocks(name, CFG, 21.0, block=997))
    assert len(blocks) == math.ceil(21000 / 997) and all(len(b["t"]) <= 997 for b in blocks)
    assert list(blocks[0]) == list(whole)
    for k, a in whole.items():
        joined = np.concatenate([b[k] for b in blocks])
        assert joined.dtype == np.asarray(a).dtype and np.array_equal(joined, a, equal_nan=True), k
    assert whole["contact_true"].any()  # touches fall in the run
