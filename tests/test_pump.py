"""Pump logic (Sec. V): on below the command, off above; hysteresis band; minimum dwell."""

from __future__ import annotations

import numpy as np
import pytest

from thermoskin.control.pump import PumpLogic
from thermoskin.params import PumpParams

CMD = 24.0


def run(pump: PumpLogic, T_w: np.ndarray) -> np.ndarray:
    return np.array([pump.step(float(x), CMD) for x in T_w])


def test_plain_rule_without_dwell():
    pump = PumpLogic(PumpParams(v_on=0.2, hysteresis=0.0), 1e-3, min_dwell=0.0)
    assert pump.step(23.9, CMD) == 0.2
    assert pump.step(24.1, CMD) == 0.0
    assert pump.step(24.0, CMD) == 0.0  # equality keeps the state
    assert pump.step(23.99, CMD) == 0.2
    assert pump.step(24.0, CMD) == 0.2
    assert pump.step(24.0001, CMD) == 0.0


def test_plain_rule_matches_sign_of_error_on_random_input():
    rng = np.random.default_rng(1)
    T_w = CMD + 0.05 * rng.standard_normal(2000)
    v = run(PumpLogic(PumpParams(still_readings=1), 1e-3, min_dwell=0.0), T_w)
    np.testing.assert_array_equal(v[T_w < CMD], 0.141)
    np.testing.assert_array_equal(v[T_w > CMD], 0.0)


def test_still_for_two_readings_of_a_slow_board():
    """A 10 Hz board (a new T_w every 100 samples): once stopped, the pump waits for the second
    new reading before it runs again, whatever the first one says."""
    pump = PumpLogic(PumpParams(still_readings=2), 1e-3, min_dwell=0.05)
    readings = [23.9, 24.2, 23.8, 23.7, 24.1, 24.05, 23.95, 23.9]
    #  pump after each reading (hand-worked): run, stop, (still: 1st new reading) stop, run,
    #  stop, stop (above anyway), run (2nd reading since the stop), run
    exp = [0.141, 0.0, 0.0, 0.141, 0.0, 0.0, 0.141, 0.141]
    got = []
    for r in readings:
        v = [pump.step(r, CMD, fresh=(j == 0)) for j in range(100)]
        assert len(set(v)) == 1  # the state changes only at a new reading
        got.append(v[0])
    assert got == exp


def test_still_readings_change_nothing_at_the_loop_rate():
    """Every sample fresh (1 kHz): two readings are 2 ms, inside the 50 ms dwell; the default
    pump switches exactly as the paper's rule with that dwell."""
    rng = np.random.default_rng(4)
    T_w = CMD + 0.05 * rng.standard_normal(3000)
    a = run(PumpLogic(PumpParams(), 1e-3), T_w)
    b = run(PumpLogic(PumpParams(still_readings=1), 1e-3), T_w)
    assert PumpParams().still_readings == 2
    np.testing.assert_array_equal(a, b)
    assert 10 < np.count_nonzero(np.diff(a)) < 3000 / 50


def test_hysteresis_band():
    pump = PumpLogic(PumpParams(v_on=0.141, hysteresis=0.2), 1e-3, min_dwell=0.0)
    # running: keeps running up to cmd + 0.1
    seq = [23.5, 24.0, 24.05, 24.099, 24.101, 24.05, 24.0, 23.95, 23.901, 23.899, 23.95, 24.05]
    exp = [0.141, 0.141, 0.141, 0.141, 0.0, 0.0, 0.0, 0.0, 0.0, 0.141, 0.141, 0.141]
    assert [pump.step(x, CMD) for x in seq] == exp


def test_reset_state_and_v_property():
    pump = PumpLogic(PumpParams(), 1e-3, min_dwell=0.05)
    pump.reset(on=False)
    assert pump.v == 0.0 and not pump.on
    assert pump.step(24.0, CMD) == 0.0
    # after reset the dwell counts as satisfied: an immediate switch is allowed
    pump.reset(on=False)
    assert pump.step(23.0, CMD) == pytest.approx(0.141)
    assert pump.on and pump.v == pytest.approx(0.141)


def test_dwell_holds_a_state_for_min_dwell():
    t_s, dwell = 1e-3, 0.05
    pump = PumpLogic(PumpParams(), t_s, min_dwell=dwell)
    # above the command at once: stops at sample 0; then wants to run on every sample
    v = run(pump, np.array([25.0] + [23.0] * 100))
    assert v[0] == 0.0
    first_on = int(np.argmax(v > 0))
    assert first_on == 50  # 50 samples = 0.05 s held off
    assert np.all(v[first_on:] > 0)


def run_lengths(v: np.ndarray) -> list[int]:
    edges = np.flatnonzero(np.diff(v) != 0) + 1
    bounds = np.concatenate([[0], edges, [v.size]])
    return list(np.diff(bounds))


@pytest.mark.parametrize(("h", "dwell"), [(0.0, 0.05), (0.04, 0.02), (0.0, 0.0101)])
def test_dwell_and_band_properties_on_noisy_input(h, dwell):
    t_s = 1e-3
    n_dwell = int(np.ceil(dwell / t_s - 1e-9))
    rng = np.random.default_rng(7)
    T_w = CMD + 0.03 * rng.standard_normal(5000) + 0.05 * np.sin(np.arange(5000) * 0.01)
    pump = PumpLogic(PumpParams(hysteresis=h), t_s, min_dwell=dwell)
    v = run(pump, T_w)
    on = v > 0
    lengths = run_lengths(v)
    assert len(lengths) > 10  # it does switch
    assert min(lengths[1:-1]) >= n_dwell  # every complete run lasts min_dwell at least
    # a switch only where the band says so
    k = np.flatnonzero(np.diff(on.astype(int)) != 0) + 1
    off_at = k[~on[k]]
    on_at = k[on[k]]
    assert np.all(T_w[off_at] > CMD + h / 2)
    assert np.all(T_w[on_at] < CMD - h / 2)
    # and no switch is missed once the dwell has passed
    held = 1
    for i in range(1, v.size):
        if on[i] == on[i - 1]:
            if held >= n_dwell:
                want_switch = T_w[i] > CMD + h / 2 if on[i - 1] else T_w[i] < CMD - h / 2
                assert not want_switch, f"missed switch at sample {i}"
            held += 1
        else:
            held = 1


def test_validation():
    with pytest.raises(ValueError):
        PumpLogic(PumpParams(), 0.0)
    with pytest.raises(ValueError):
        PumpLogic(PumpParams(), 1e-3, min_dwell=-1.0)
