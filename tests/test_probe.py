"""Active sensing: the set-point probe's square wave, and its cost in closed loop (detection
and regulation with and without it on the same seeded run)."""

from __future__ import annotations

import numpy as np
import pytest

from thermoskin.control.probe import SetpointProbe
from thermoskin.params import Config
from thermoskin.physics.finger import Touch
from thermoskin.runtime.closed_loop import run_closed_loop
from thermoskin.sim.scenarios import Scenario


def test_square_wave_schedule() -> None:
    p = SetpointProbe(A=0.3, period=2.0, delay=0.3, max_s=6.0)
    assert p.offset(0.0) == 0.0 and p.offset(0.29) == 0.0  # a tap is over before it starts
    assert p.offset(0.3) == 0.3 and p.offset(1.29) == 0.3
    assert p.offset(1.31) == -0.3 and p.offset(2.29) == -0.3
    assert p.offset(2.31) == 0.3
    assert p.offset(6.0) == 0.0 and p.offset(60.0) == 0.0  # at most max_s after the detection
    assert SetpointProbe(A=0.5, period=0.0).offset(3.0) == 0.5  # one step


@pytest.mark.parametrize(("kw", "what"), [({"A": -0.1}, "A"), ({"A": 3.0}, "A"), ({"period": -1.0}, "period"),
                                          ({"delay": float("nan")}, "delay"), ({"max_s": -2.0}, "max_s")])
def test_bad_probe_is_one_line(kw: dict[str, float], what: str) -> None:
    with pytest.raises(ValueError, match=f"SetpointProbe: {what} = "):
        SetpointProbe(**kw)


@pytest.fixture(scope="module")
def runs() -> tuple[object, object]:
    sc = Scenario(name="palm", description="a palm at 33 °C held 6 s", duration=26.0, T_w_cmd=24.0,
                  T_a=20.0, touches=(Touch(t_on=15.0, duration=6.0, toucher="palm", n_fingers=0,
                                           T_body=33.0),), pump="logic")
    cfg = Config()
    return run_closed_loop(sc, cfg), run_closed_loop(sc, cfg, probe=SetpointProbe())


def test_probe_leaves_everything_before_it_untouched(runs: tuple) -> None:
    plain, probed = runs
    (e0,), (e1,) = plain.events, probed.events
    k = round((e0.detected_at + SetpointProbe().delay) / 1e-3)
    for col in ("T_w", "T_p", "v", "drive", "q_i_hat"):
        np.testing.assert_array_equal(plain.columns[col][:k], probed.columns[col][:k])
    assert e1.onset == e0.onset and e1.detected_at == e0.detected_at


def test_probe_moves_the_water_without_disturbing_detection_or_regulation(runs: tuple) -> None:
    plain, probed = runs
    (e0,), (e1,) = plain.events, probed.events
    assert abs(e1.release - e0.release) <= 0.05  # the release is seen as well
    t = probed.columns["t"]
    on = (t > e1.detected_at + 0.3) & (t < e1.release)
    moved = probed.columns["T_w_true"][on] - plain.columns["T_w_true"][on]
    print(f"the probe moved the pipe by {np.std(moved):.3f} K rms, {np.ptp(moved):.3f} K peak to peak")
    assert np.std(moved) >= 0.05 and np.ptp(moved) >= 0.2  # the wave shows in the pipe (lagged)
    for res in runs:  # regulation: |T_w - T_w_cmd| during the contact within the pump's band + A
        cc = res.columns
        inc = (cc["t"] > e0.detected_at + 0.3) & (cc["t"] < e0.release)
        assert np.percentile(np.abs(cc["T_w"] - cc["T_w_cmd"])[inc], 99) <= 1.2
    err = [np.abs(r.columns["T_w"] - r.columns["T_w_cmd"]) for r in runs]
    after = (t > e1.release + 3.0)
    assert abs(err[1][after].mean() - err[0][after].mean()) <= 0.05
