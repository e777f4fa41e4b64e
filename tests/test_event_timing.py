"""Each event's onset and duration against the touch, where the detector used to get them wrong.

Simulated conditions (``sim.conditions``) on tuning seeds; each case was off by more than
0.3 s before the change it tests (in brackets):

- a tap whose estimate overshot after the onset (only ``q_i`` took the jump; the sheet and
  pipe states left behind): its release dated 0.3 s early (duration -0.34 s);
- a weak touch (0.02 W/K) that the design-D CUSUM lost and found again: dated 0.85 s late;
- a two-finger touch seen first by the fingertip CUSUM, which had gathered noise since
  1.1 s before the touch: dated 1.1 s early.
"""

from __future__ import annotations

import pytest

from thermoskin.analysis.observe import observe
from thermoskin.params import load_config
from thermoskin.sim.conditions import get_condition
from thermoskin.sim.run import simulate


@pytest.mark.parametrize(("name", "seed", "t_end"), [("taps", 101, 16.0), ("weak", 106, 120.0),
                                                      ("noisy", 103, 70.0)])
def test_onset_and_duration_within_0_3_s(name: str, seed: int, t_end: float) -> None:
    cond = get_condition(name, seed)
    cfg = cond.config(load_config())
    sc = cond.scenario.with_duration(t_end)
    res = observe(simulate(sc, cfg), cfg)
    touches = [tc for tc in sc.touches if tc.t_on + tc.duration < t_end - 1.0]
    assert touches
    for tc in touches:
        ev = [e for e in res.events if tc.t_on <= e.detected_at <= tc.t_on + tc.duration]
        assert len(ev) == 1, (tc, res.events)
        e = ev[0]
        assert abs(e.onset - tc.t_on) <= 0.3, (tc.t_on, e.onset)
        assert abs(e.duration - tc.duration) <= 0.3, (tc.duration, e.duration)
    assert len(res.events) == len(touches) + sum(1 for tc in sc.touches if tc not in touches
                                                 and tc.t_on < t_end)
