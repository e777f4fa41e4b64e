"""A warm touch too weak to detect ends with no contact of the other sign, and one reading off
ends no touch (``detector.t_pair``, ``detector.release_readings``; docs/model.md).

The log is one serial session as a lab's bench gives it, recorded by `thermoskin run --device
serial://...` against `thermoskin device-emulator --firmware` (the reference firmware on its
MAX31856 models, a lab's boards drawn from seed 0, converting every 98 ms; scenario `fingers`,
75 s), its readings and commands only (`tests/data/firmware_10hz_lab_seed0.parquet`). A
fingertip's SNR there is 1.7: the one-finger touches are below the noise.
"""

from __future__ import annotations

import numpy as np
import pytest

from thermoskin.analysis.evaluation import match_events
from thermoskin.analysis.observe import observe
from thermoskin.params import load_config


@pytest.fixture(scope="module")
def session(serial_session):  # type: ignore[no-untyped-def]
    return serial_session("firmware_10hz_lab_seed0")


# these tests were made, and the pairing and the release over readings found, while a slow
# board's pipe noise was held at its prior (0.02 K; the board's is 0.049 K): the evidence taken
# as surer than it is, the touches' ends and the one reading off showed as contacts. With the
# noise learnt (``estimator.phase_tol``, the default) they do not show in this log at all: the
# log's touches below two fingers' are below its noise; the mechanisms are tested as they were
def _events(log, held: bool = True, **detector):  # type: ignore[no-untyped-def]
    cfg = load_config().replace(detector=detector)
    return observe(log, cfg.replace(estimator={"phase_tol": 0.0}) if held else cfg).events


#: the dispersion's prior these tests were made with (a wary 2: the evidence weighed 0.75 until
#: the dispersion has its windows, 30 s into this log); with the model's own 1 (the default) the
#: touches' ends and releases below fall otherwise, and fewer are missed
WARY = 2.0


def test_no_contact_of_the_other_sign_after_the_touches_missed(session) -> None:  # type: ignore[no-untyped-def]
    """With the pipe's noise held at its prior (as made): every touch of two and three fingers and
    one of three fingertips, no false alarm, no contact of the negative sign."""
    log, touches = session
    events = _events(log)
    m = match_events(touches, events)
    assert m.false_alarms == 0, [(e.onset, e.detected_at, e.sign) for e in m.spurious]
    assert all(e.sign > 0 for e in events)
    assert len(touches) - m.misses >= 6  # every touch of two and three fingers, one of three fingertips
    assert all(t.n_fingers == 1 for t in m.missed)
    # the latency bar of 10 Hz boards (0.4 s) for the touches above the noise: two and three
    # fingers (a fingertip's found late, 1.3-1.8 s, would move a median of all)
    strong = [lat for t, lat in zip(touches, m.latency_by_touch(), strict=True)
              if t.n_fingers >= 2 and lat is not None]
    assert len(strong) == 5 and np.median(strong) <= 0.4, m.latencies


def test_with_the_pipe_noise_learnt_no_false_alarm_and_the_strong_touches(session) -> None:  # type: ignore[no-untyped-def]
    """The default (the pipe's noise learnt, 0.05-0.07 K here): no false alarm and no negative
    contact; the three-finger touches found and at least one of two fingers; what is missed is
    of one or two fingers (a fingertip's SNR here 1.2-1.7, two fingers' about twice that: below
    the line of 5, where the bar asks only the false-alarm rate)."""
    log, touches = session
    events = _events(log, held=False)
    m = match_events(touches, events)
    assert m.false_alarms == 0 and all(e.sign > 0 for e in events)
    found = [t.n_fingers for t, p in zip(touches, m.pairs, strict=True) if p is not None]
    assert found.count(3) == 2 and found.count(2) >= 1
    assert all(t.n_fingers <= 2 for t in m.missed)


def test_without_the_pairing_the_ends_of_the_missed_touches_are_contacts(session) -> None:  # type: ignore[no-untyped-def]
    """The same log with ``t_pair = 0``: a contact of the negative sign within 5 s after the end
    of a one-finger touch (the ends the pairing takes), not a touch. (Without the withdrawal of
    contacts that bring nothing, ``confirm_mean`` 0, which came after the pairing and takes
    such contacts too.) There were three, 8.4, 17.8 and 24.5 s, while the warm-up's baseline
    stood 0.06 W over the estimate (the slow states' moves over it left out); one now."""
    log, touches = session
    neg = [e for e in _events(log, t_pair=0.0, rho_prior=WARY, confirm_mean=0.0) if e.sign < 0]
    assert len(neg) >= 1
    ends = [t.t_off for t in touches if t.n_fingers == 1]
    for e in neg:
        assert any(0.0 < e.onset - t_off < 5.0 for t_off in ends), e


def test_one_reading_off_ends_no_touch(serial_session) -> None:  # type: ignore[no-untyped-def]
    """Without the pairing (as before it), the firmware session's two-finger touch 40.0-42.8 s
    was released 1.2 s early on one reading and found again; since the warm-up's baseline stands
    where the estimate does it is whole either way. The emulator's session of the same boards
    (`tests/data/emulator_10hz_lab_seed0_loaded.parquet`, the pipe's noise held as here) shows
    it on the fingertip's touch 22.5-24.3 s: one contact to its end with the release over three
    readings; with a release on one reading (``release_readings = 0``) it ends 0.6 s early."""
    log, _ = serial_session("emulator_10hz_lab_seed0_loaded")

    def in_touch(**kw):  # type: ignore[no-untyped-def]
        return [e for e in _events(log, **kw) if 22.0 <= e.detected_at <= 24.3]

    (whole,) = in_touch()
    assert whole.release == pytest.approx(24.5, abs=0.25)
    (cut,) = in_touch(release_readings=0.0)
    assert cut.release < 24.3 - 0.4
