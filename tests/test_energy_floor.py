"""Contacts that bring less heat than a touch (``detector.confirm_time``; docs/model.md).

A skin 30 % lighter than configured (what a lab has before it calibrates) misfits at the
pump's switches: now and then a noise excursion on that misfit crosses the onset threshold
and the estimate falls back within 16-120 ms, a contact of 0.2 W mean bringing 3-26 mJ (13
false alarms in the mismatch grid's 1.2 h). The shortest touch the detector is made for is a
tap of 0.2 s and its weakest design step 0.15 W: a contact whose heat over it is below
``confirm_mean`` (0.5) of that, 15 mJ, is withdrawn at its release (no event). The taps of
the detection table bring 58 mJ and more (``tests/test_detection.py`` holds them all found).
"""

from __future__ import annotations

import dataclasses

from thermoskin.analysis.evaluation import match_events
from thermoskin.estimation.estimator import TouchEstimator
from thermoskin.estimation.freshness import infer_fresh
from thermoskin.params import load_config
from thermoskin.sim.conditions import finger_train, mis_sized_skin
from thermoskin.sim.run import simulate


def _lighter_skin_log(seed: int, duration: float):  # type: ignore[no-untyped-def]
    """Touches of 1-3 fingers every 5-9 s, the tank drifting, on a skin 30 % lighter than the
    configuration says (the mismatch grid's recipe)."""
    cfg = load_config()
    sc = finger_train(seed, duration)
    return sc, simulate(sc, cfg.replace(skin=mis_sized_skin(cfg.skin, -0.3)),
                        boards=dataclasses.replace(cfg.sensor, seed=seed))


def _events(log, **detector):  # type: ignore[no-untyped-def]
    est = TouchEstimator(load_config().replace(detector=detector) if detector else load_config())
    return est.run(log["t"], log["T_w"], log["T_p"], log["v"], log["T_a"], T_w_cmd=log["T_w_cmd"],
                   fresh=infer_fresh(log)[0]).events


def test_a_lighter_skin_s_short_contacts_are_withdrawn() -> None:
    sc, log = _lighter_skin_log(8102, 20.0)
    m = match_events(sc.touches, _events(log))
    assert m.false_alarms == 0 and m.misses == 0, [(e.detected_at, e.energy) for e in m.spurious]
    # (the mechanism on its own: the dispersion over the pump's phases, which widens the
    # detector against this misfit, keeps these excursions under the threshold here too)
    assert match_events(sc.touches, _events(log, confirm_time=0.0)).false_alarms == 0
    m0 = match_events(sc.touches, _events(log, confirm_time=0.0, rho_phases=0))
    assert m0.misses == 0 and m0.false_alarms >= 1
    assert all(abs(e.energy) < 0.03 and e.duration < 0.2 for e in m0.spurious), m0.spurious
