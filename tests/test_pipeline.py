"""End to end on the simulated skin: the observer + detector meet the detection target.

Target (issue 2, item 5): on realistic scenarios (1-3 fingers, 0.05 W/K-class contact to a
body at 32-35 °C, 0.02 K thermocouple noise, pump switching around the set-point, touches
1.5-3 s long and 5-9 s apart), every touch detected, no false alarm, median onset latency
at most 0.3 s. The seeds here were never used while tuning the detector.
"""

from __future__ import annotations

import numpy as np
import pytest

from thermoskin.analysis.evaluation import match_events
from thermoskin.analysis.observe import Observation, observe
from thermoskin.estimation.estimator import TouchEstimator
from thermoskin.params import load_config
from thermoskin.sim.run import simulate
from thermoskin.sim.scenarios import SCENARIOS, random_scenario

CFG = load_config()


@pytest.mark.parametrize("seed", [7001, 7002, 7003])
def test_detection_target_on_unseen_scenarios(seed: int) -> None:
    sc = random_scenario(seed, 120.0)
    cfg = CFG.replace(sensor={"seed": seed})
    log = simulate(sc, cfg)
    assert np.ptp(log["v"]) > 0 and np.sum(np.diff(log["v"]) != 0) > 100  # pump switching
    res = observe(log, cfg)
    m = match_events(sc.touches, res.events)
    assert m.misses == 0, m.missed
    assert m.false_alarms == 0, m.spurious
    assert np.median(m.latencies) <= 0.3


def test_no_false_alarm_without_touch() -> None:
    sc = SCENARIOS["none"].with_duration(300.0)
    cfg = CFG.replace(sensor={"seed": 7100})
    res = observe(simulate(sc, cfg), cfg)
    assert res.events == []
    assert not res.columns["contact"].any()


def test_heat_flow_grows_with_fingers() -> None:
    sc = SCENARIOS["fingers"]
    res = observe(simulate(sc, CFG), CFG)
    assert len(res.events) == 9
    peaks = np.array([e.peak_dq for e in res.events]).reshape(3, 3).mean(axis=1)
    assert peaks[0] < peaks[1] < peaks[2]


def stream(log: dict[str, np.ndarray], cfg) -> Observation:  # type: ignore[no-untyped-def]
    """The live path: ``TouchEstimator.step`` per sample, as the loop body calls it."""
    est = TouchEstimator(cfg)
    n = len(log["t"])
    cols = {k: np.zeros(n) for k in ("q_i_hat", "dq_i_hat", "contact", "gap")}
    rows = zip(*(log[k].tolist() for k in ("t", "T_w", "T_p", "v", "T_a", "T_w_cmd")), strict=True)
    for i, (t, T_w, T_p, v, T_a, cmd) in enumerate(rows):
        cols["contact"][i] = est.step(t, T_w, T_p, v, T_a, cmd)
        cols["q_i_hat"][i], cols["dq_i_hat"][i], cols["gap"][i] = est.q_i_hat, est.dq_i_hat, est.gap
    est.finish(float(log["t"][-1]))
    return Observation(columns=cols, events=est.events)


def test_streaming_equals_vectorised() -> None:
    sc = SCENARIOS["one-finger"].with_duration(25.0)
    log = simulate(sc, CFG)
    log["T_w"][8000:8040] = np.nan  # a loose thermocouple
    a = observe(log, CFG)
    b = stream(log, CFG)
    np.testing.assert_allclose(b.columns["q_i_hat"], a.columns["q_i_hat"], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(b.columns["dq_i_hat"], a.columns["dq_i_hat"])  # one kernel
    np.testing.assert_array_equal(b.columns["contact"], a.columns["contact"])
    np.testing.assert_array_equal(b.columns["gap"], a.columns["gap"])
    assert len(a.events) == len(b.events) >= 2
    for ea, eb in zip(a.events, b.events, strict=True):
        assert ea == eb


def test_switch_rows_counts_changes_of_v() -> None:
    from thermoskin.analysis.observe import switch_rows

    v = np.array([0.0, 0.0, 0.14, 0.14, np.nan, 0.0, 0.14])
    assert switch_rows(v) == 3  # rows 2, 5 (against 0.14 before the NaN) and 6
    assert switch_rows(v, v_before=0.14) == 4  # the previous chunk ended running
    assert switch_rows(np.array([0.0, np.nan, 0.14])) == 1  # a switch across a NaN counts
    assert switch_rows(np.zeros(0)) == 0 and switch_rows(np.full(3, np.nan)) == 0
    # chunk by chunk, carrying the last known velocity, as the whole
    from thermoskin.analysis.observe import last_known

    w = np.array([0.0, 0.14, np.nan, np.nan, 0.0, np.nan, 0.14, 0.14])
    total, before = 0, np.nan
    for a, b in ((0, 2), (2, 4), (4, 5), (5, 8)):
        total += switch_rows(w[a:b], before)
        before = last_known(w[a:b], before)
    assert total == switch_rows(w) == 3


def test_a_log_coarser_than_the_loop_with_a_switching_pump_is_warned_about(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """A 1 kHz run logged at 50 Hz: the pump (held >= 50 ms) switches within about a third of
    the rows, counted independently from the 1 kHz log's switches; the same log at the loop's
    rate, or without a switch, gets no warning, and the streamed path says the same."""
    from thermoskin.analysis.observe import coarse_log_warnings, observe_file
    from thermoskin.logio import LogWriter
    from thermoskin.sim.conditions import decimate

    full = simulate(SCENARIOS["one-finger"].with_duration(20.0), CFG)
    slow = decimate(full, 20)
    # every 1 kHz switch shows in the 50 Hz log in the row after it (dwell 50 ms > 20 ms)
    k = np.flatnonzero(np.diff(full["v"])) + 1
    rows = np.unique((k + 19) // 20)
    expect = int(np.sum(rows < len(slow["t"])))  # a switch after the last row is not in the log
    assert expect == np.count_nonzero(np.diff(slow["v"])) > 0.2 * len(slow["t"])
    warn: list[str] = []
    observe(slow, CFG, warnings=warn)
    assert len(warn) == 1 and "sampled at 50 Hz, coarser than the loop (1000 Hz)" in warn[0]
    assert f"within {100 * expect / len(slow['t']):.0f} % of its rows" in warn[0]
    quiet: list[str] = []
    observe(full, CFG, warnings=quiet)
    assert quiet == []
    assert coarse_log_warnings(0.02, CFG, 1000, 49) == []  # under 5 % of rows: nothing said
    path = tmp_path / "slow.csv"
    with LogWriter(path, list(slow)) as w:
        w.write(slow)
    res = observe_file(path, tmp_path / "out.csv", CFG, characterise=False)
    assert res.warnings == warn


def test_a_stuck_pipe_thermocouple_is_warned_about(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """A T_w that never moves (a stuck or disconnected thermocouple) gets a warning naming it,
    in memory and streamed; the same log as read by 10 Hz boards (held 100 ms) gets none."""
    from thermoskin.analysis.observe import observe_file, stuck_warnings
    from thermoskin.logio import write_log

    log = simulate(SCENARIOS["one-finger"].with_duration(12.0), CFG)
    log = {k: log[k] for k in ("t", "T_w", "T_p", "v", "T_a")}
    boards = dict(log)
    for k in ("T_w", "T_p", "T_a"):  # each reading held for 100 samples
        boards[k] = np.repeat(log[k][::100], 100)[: len(log["t"])]
    warn: list[str] = []
    observe(boards, CFG, warnings=warn)
    assert not any("stuck" in w for w in warn), warn
    stuck = dict(log, T_w=np.full(len(log["t"]), 24.03125))
    observe(stuck, CFG, warnings=warn)
    assert [w for w in warn if "stuck" in w] == [
        "T_w changes only every 12 s (thermocouple boards update at 5 Hz or faster): a stuck or "
        "disconnected thermocouple, or one too coarse or without noise to show its updates? the "
        "estimates and contacts rest on it"]
    write_log(tmp_path / "stuck.csv", stuck)
    res = observe_file(tmp_path / "stuck.csv", tmp_path / "out.csv", CFG)
    assert sum("T_w changes only every 12 s" in w for w in res.warnings) == 1
    assert stuck_warnings({"T_w": 9999.0, "T_p": 10001.0}, 1e-3) == stuck_warnings({"T_p": 10001.0}, 1e-3)
    assert len(stuck_warnings({"T_p": 10001.0}, 1e-3)) == 1
