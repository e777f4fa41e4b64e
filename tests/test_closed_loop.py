"""The whole skin in closed loop on the simulated plant (issue 3's acceptance checks)."""

from __future__ import annotations

import numpy as np
import pytest

from thermoskin.analysis.evaluation import match_events, tracking_errors
from thermoskin.params import load_config
from thermoskin.runtime.closed_loop import COLUMNS, run_closed_loop
from thermoskin.sim.scenarios import SCENARIOS, Scenario, random_scenario

CFG = load_config()


@pytest.fixture(scope="module")
def steps_run():  # type: ignore[no-untyped-def]
    sc = Scenario("steps", "24 -> 26 -> 28 degC, 60 s each", duration=180.0,
                  setpoints=((0.0, 24.0), (60.0, 26.0), (120.0, 28.0)))
    return run_closed_loop(sc, CFG)


def test_setpoint_steps_tracked(steps_run) -> None:  # type: ignore[no-untyped-def]
    c = steps_run.columns
    for t0, cmd in ((0.0, 24.0), (60.0, 26.0), (120.0, 28.0)):
        w = (c["t"] >= t0 + 40.0) & (c["t"] < t0 + 60.0)  # the last 20 s of the step
        assert np.mean(np.abs(c["T_w_true"][w] - cmd)) <= 0.1
        assert np.mean(np.abs(c["T_w"][w] - cmd)) <= 0.1
    segs = tracking_errors(c, window=20.0)
    assert [s.T_w_cmd for s in segs] == [24.0, 26.0, 28.0]
    assert all(s.mean_abs_error <= 0.1 for s in segs)


def test_T_p_cmd_within_bounds_and_columns(steps_run) -> None:  # type: ignore[no-untyped-def]
    c = steps_run.columns
    assert list(c) == list(COLUMNS)
    assert c["T_p_cmd"].min() >= CFG.control.T_p_min
    assert c["T_p_cmd"].max() <= CFG.control.T_p_max
    assert c["T_p_cmd"].max() == CFG.control.T_p_max  # the heating from ambient saturates it
    assert np.all(np.abs(c["drive"]) <= 1.0)
    assert set(np.unique(c["v"])) == {0.0, CFG.pump.v_on}  # the pump switches
    for k in COLUMNS:
        assert np.isfinite(c[k]).all(), k


def test_no_false_alarm_while_heating_and_stepping(steps_run) -> None:  # type: ignore[no-untyped-def]
    assert steps_run.events == []


@pytest.mark.parametrize("sc", [SCENARIOS["fingers"].shifted(10.0),
                                random_scenario(7301, 90.0).shifted(10.0)],
                         ids=["fingers", "random-7301"])
def test_touches_detected_while_controlled(sc: Scenario) -> None:
    res = run_closed_loop(sc, CFG.replace(sensor={"seed": 31}))
    m = match_events(sc.touches, res.events)
    assert m.misses == 0 and m.false_alarms == 0
    assert np.median(m.latencies) <= 0.3
    c = res.columns
    after = c["t"] > 10.0
    assert np.mean(np.abs(c["T_w_true"][after] - sc.T_w_cmd)) <= 0.1
