"""Doors through an air sensor slower than configured, and contacts that bring no heat
(``detector.air_rate``, ``detector.confirm_mean``, the onsets' hold after a sudden change of the
air; docs/sensors.md).

The door logs are the ``ambient-step`` condition's scenario (seed 4242: the air steps by 1 K at
33.4 s, a touch 5.5 s after it), simulated with an air sensor lagging 1 or 3 s; the estimator
is given the default configuration (no lag) or the true lag. The withdrawal log is one serial
session as a lab's bench gives it: `thermoskin run --device serial://...` against
`thermoskin device-emulator` (its default boards: a lab's, drawn from seed 0, every 0.1 s;
scenario `fingers`, 75 s), the third of three on one emulator, beside two CPU-bound processes,
its readings and commands only (`tests/data/emulator_10hz_lab_seed0_loaded.parquet`).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from thermoskin.analysis.evaluation import match_events
from thermoskin.analysis.observe import observe
from thermoskin.estimation import kernel as K  # noqa: N812
from thermoskin.estimation.estimator import TouchEstimator
from thermoskin.params import load_config
from thermoskin.sim.conditions import get_condition
from thermoskin.sim.run import simulate
from thermoskin.sim.scenarios import SCENARIOS

DOOR_AT = 33.4


def _door_log(lag: float, duration: float = 60.0):  # type: ignore[no-untyped-def]
    sc = get_condition("ambient-step", 4242).scenario.with_duration(duration)
    assert abs(sc.ambient[0][0] - DOOR_AT) < 0.1 and sc.ambient[1][1] - sc.ambient[0][1] == 1.0
    return sc, simulate(sc, load_config().replace(sensor={"lag_T_a": lag}))


def _score(sc, log, **cfg):  # type: ignore[no-untyped-def]
    ev = observe(log, load_config().replace(**cfg) if cfg else load_config()).events
    return match_events(sc.touches, ev), ev


@pytest.mark.parametrize("lag", [1.0, 3.0])
def test_a_door_through_an_air_sensor_slower_than_configured_is_no_touch(lag: float) -> None:
    """The air filter follows the lagging reading as a ramp (its CUSUM never fires) while the
    sheet feels the air itself: without the air's rate the door is a contact; with it every
    touch is found, the one 5.5 s after the door too, and there is no false alarm."""
    sc, log = _door_log(lag)
    m, _ = _score(sc, log)
    assert m.false_alarms == 0 and m.misses == 0, [(e.onset, e.sign) for e in m.spurious]
    m0, _ = _score(sc, log, detector={"air_rate": 0.0})
    assert m0.false_alarms >= 1
    assert all(DOOR_AT < e.detected_at < DOOR_AT + 2.0 for e in m0.spurious), m0.spurious


def test_a_touch_after_a_door_through_a_configured_slow_sensor() -> None:
    """The lag configured (3 s): the hold after the door is 1 + 3 s (three lags before: the
    touch 5.5 s after the door was lost), and while it holds the CUSUMs gather their evidence
    without firing rather than being zeroed (zeroed, the hold took a touch within it for no
    touch, and the baseline and the offset learnt it: a flood of false alarms after it in
    the grid's door logs). Every touch, no false alarm, the one after the door within 0.3 s."""
    sc, log = _door_log(3.0)
    m, _ = _score(sc, log, sensor={"lag_T_a": 3.0})
    assert m.false_alarms == 0 and m.misses == 0, [(e.onset, e.sign) for e in m.spurious]
    after = [lat for t, lat in zip(sc.touches, m.latency_by_touch(), strict=True)
             if DOOR_AT < t.t_on < DOOR_AT + 10.0]
    assert len(after) == 1 and after[0] is not None and after[0] <= 0.3


def test_a_coarse_air_converter_s_step_is_no_door() -> None:
    """1/16 K boards, no door: the air's reading steps by one quantum now and then, which its
    filter takes in slowly enough for the air's CUSUM to pass its threshold; that is no sudden
    change of the air (it withdrew a touch just detected), so the time of the last one stays
    unset."""
    cfg = load_config()
    sc = SCENARIOS["fingers"].with_duration(60.0)
    log = simulate(sc, cfg, boards=dataclasses.replace(cfg.sensor, quantum_T=1 / 16))
    est = TouchEstimator(cfg)
    tamb = []
    cols = [log[k] for k in ("t", "T_w", "T_p", "v", "T_a", "T_w_cmd")]
    for row in zip(*cols, strict=True):
        est.step(*row)
        tamb.append(est.st[K.TAMB])
    assert max(tamb) < 0.0  # never set
    assert est.st[K.QA] == pytest.approx(1 / 16)


@pytest.fixture(scope="module")
def session(serial_session):  # type: ignore[no-untyped-def]
    return serial_session("emulator_10hz_lab_seed0_loaded")


def test_a_contact_that_brings_no_heat_is_withdrawn(session) -> None:  # type: ignore[no-untyped-def]
    """After the two-finger touch of 40.0-42.8 s the filter's estimate recovers for seconds from
    what the touch left; with 10 Hz boards that recovery reached the threshold twice (46.1 and
    48.2 s live), contacts of 0.01 W and -0.16 W over them. Withdrawn (no event), the session
    has no false alarm and the same touches: the strong ones (two and three fingers) each
    found."""
    log, touches = session
    m = match_events(touches, observe(log, load_config()).events)
    assert m.false_alarms == 0, [(e.onset, e.detected_at, e.mean_dq) for e in m.spurious]
    lat = m.latency_by_touch()
    assert all(lat[i] is not None for i, t in enumerate(touches) if t.n_fingers >= 2), lat
    # the rule off (only a contact of the other sign's mean withdrawn): the 46.1 s one is back,
    # a positive contact of next to no heat, 3.3 s after the touch's end
    # (with the pipe's noise held at its prior, 0.02 K for the board's 0.049 K, as the rule was
    # made: with the noise learnt the recovery brings no contact to withdraw at all)
    held = load_config().replace(estimator={"phase_tol": 0.0})
    assert not match_events(touches, observe(log, held).events).spurious
    m0 = match_events(touches, observe(log, held.replace(detector={"confirm_mean": 0.0})).events)
    assert len(m0.spurious) == 1
    (e,) = m0.spurious
    assert e.sign > 0 and 45.5 < e.detected_at < 46.5 and abs(e.mean_dq) < 0.05
    # every event the default reports brought at least that heat (the weakest touches of the
    # detection table bring 0.18 W and more)
    d = load_config().detector
    ev = observe(log, load_config()).events
    assert min(e.sign * e.mean_dq for e in ev) >= d.confirm_mean * d.dq_design_lo
    assert np.all(np.diff([e.onset for e in ev]) > 0)
