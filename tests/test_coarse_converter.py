"""A converter coarser than configured: 10 Hz boards with a 1/4 K step (MAX31855-like) read
with a configuration that says 1/128 K (the pipe reading's variance is at least its learnt
step's, ``q²/12``; docs/sensors.md).

At 10 Hz the pipe reading's variance is not learnt from its innovations (they hold the model's
prediction over the interval too), so it stayed at its configured prior, 0.02 K: a reading
one 1/4 K step off the prediction read as ten standard deviations, and the detector found a
contact of -3 W lasting 50 ms in it (the mismatch grid's MAX31855 row: 56 false alarms in
1.2 h). A quantisation error uniform over a step ``q`` has the variance ``q²/12`` (the
physical floor: no reading of such a board is better known), which the filter now takes.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from thermoskin.analysis.evaluation import match_events
from thermoskin.estimation import kernel as K  # noqa: N812
from thermoskin.estimation.estimator import TouchEstimator
from thermoskin.estimation.freshness import infer_fresh
from thermoskin.estimation.learnt import SNR_MIN, learnt, notices
from thermoskin.params import load_config
from thermoskin.sim.run import simulate
from thermoskin.sim.scenarios import SCENARIOS, Scenario

QUANTUM = 0.25


def _ten_hz():  # type: ignore[no-untyped-def]
    """The configuration of 10 Hz boards (a 1/128 K step, as a MAX31856's), as the lab gives it."""
    return load_config().replace(sensor={"period_T_w": 0.1, "period_T_p": 0.1, "period_T_a": 0.1,
                                         "jitter": 0.003})


def _estimate(log, cfg):  # type: ignore[no-untyped-def]
    est = TouchEstimator(cfg)
    res = est.run(log["t"], log["T_w"], log["T_p"], log["v"], log["T_a"], T_w_cmd=log["T_w_cmd"],
                  fresh=infer_fresh(log)[0])
    return est, res


@pytest.mark.parametrize("seed", [1, 2])
def test_no_false_alarm_from_a_coarse_pipe_converter(seed: int) -> None:
    """Two minutes of no touch, the pump switching and the tank drifting by 30 mK: no event
    (the code before: 5 and 6), and the pipe's converter step found exactly."""
    cfg = _ten_hz()
    sc = Scenario(name="quiet", description="", duration=120.0, T_a=20.0, touches=(), pump="logic",
                  T_p_drift=0.03, T_p_period=50.0)
    log = simulate(sc, cfg, boards=dataclasses.replace(cfg.sensor, quantum_T=QUANTUM, seed=seed))
    assert np.allclose(np.round(log["T_w"] / QUANTUM) * QUANTUM, log["T_w"])  # the board's steps
    est, res = _estimate(log, cfg)
    assert est.st[K.QW] == QUANTUM
    assert res.events == [], [(e.detected_at, e.sign, e.peak_dq) for e in res.events]


def test_touches_below_such_a_board_say_so_and_invent_nothing() -> None:
    """The `fingers` scenario through those boards: no false alarm, and the one-finger SNR the
    estimator figures is below the line (what such boards can resolve). Its tank reads one
    step throughout, so the tank's step is never known: the code before asked for both steps
    before it took the pipe's as coarse, the evidence's dispersion never began, and no SNR was
    figured at all (NaN: no line)."""
    cfg = _ten_hz()
    sc = SCENARIOS["fingers"].with_duration(90.0)
    log = simulate(sc, cfg, boards=dataclasses.replace(cfg.sensor, quantum_T=QUANTUM))
    est, res = _estimate(log, cfg)
    m = match_events(sc.touches, res.events)
    assert m.false_alarms == 0, [(e.detected_at, e.sign) for e in m.spurious]
    lt = learnt(est.st, cfg)
    assert lt.snr < SNR_MIN and "snr" in notices(lt, cfg)
    # the tank's readings never changed (one step throughout): its noise is not known, and no
    # note advises one (it read 1 mK, and the note said to set it)
    assert np.unique(log["T_p"]).size == 1 and "T_p" in lt.still
    assert "noise_T_p" not in notices(lt, cfg) and "T_p not known" in lt.lines()[0]


def _one_khz_quarter_kelvin(seed: int, duration: float):  # type: ignore[no-untyped-def]
    """A no-touch log of 1 kHz boards with a 1/4 K step (the default configuration: 1/128 K), the
    tank drifting by 30 mK over 50 s within one step of its readings."""
    cfg = load_config()
    sc = Scenario(name="quiet", description="", duration=duration, T_a=20.0, touches=(),
                  pump="logic", T_p_drift=0.03, T_p_period=50.0)
    return cfg, simulate(sc, cfg, boards=dataclasses.replace(cfg.sensor, quantum_T=QUANTUM, seed=seed))


@pytest.mark.parametrize("seed", [3, 4])
def test_a_tank_drifting_within_one_step_widens_the_detector(seed: int) -> None:
    """At 1 kHz a 1/4 K step is not dithered by 0.02 K of noise: the tank reads one step while
    it drifts within it, and the drift reads as a touch heat of +-0.3 W coming and going with
    the pump over tens of seconds (the mismatch grid's 1/4 K row: 57 false alarms in 1.2 h).
    Over the short windows (0.4 s) the evidence looks nearly white; over the long ones (8 s)
    it is spread far beyond chi2(1), and the detector is widened by it. Without the long
    windows the same log gives false contacts."""
    cfg, log = _one_khz_quarter_kelvin(seed, 240.0)
    assert np.unique(log["T_p"]).size <= 2  # the tank on one step (or two) throughout
    est, res = _estimate(log, cfg)
    assert res.events == [], [(e.detected_at, e.sign, e.peak_dq) for e in res.events]
    lt = learnt(est.st, cfg)
    assert est.st[K.RHOL] > 3.0 * est.st[K.RHOS] and est.st[K.RHO] == est.st[K.RHOL]
    assert lt.snr < SNR_MIN and "snr" in notices(lt, cfg)
    _, res0 = _estimate(log, cfg.replace(detector={"rho_window_long": 0.0}))
    assert len(res0.events) >= 2
