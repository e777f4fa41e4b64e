"""Onsets dated by the GLR over the change time (``detector.onset_glr``, ``estimation/kernel.py``).

The scan against a brute-force likelihood over every candidate change time (sums taken afresh
for each, from the readings themselves, not the buffer's running sums), a noiseless step whose
change time it must find exactly, the ring buffer's pooling and wrap-around, and a simulated
log where a slow rise of the estimate before a touch dated the onset at the CUSUM's last zero,
0.69 s early (tuning seed 103 of the ``log-100hz`` condition).
"""

from __future__ import annotations

import numpy as np
import pytest

from thermoskin.analysis.observe import observe
from thermoskin.estimation import kernel as K  # noqa: N812
from thermoskin.estimation.model import fixed_sensors
from thermoskin.params import load_config
from thermoskin.sim.conditions import decimate, get_condition
from thermoskin.sim.run import simulate


def _state(readings: list[tuple[float, float, float]], pool: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    st = K.new_state()
    pr = np.zeros(K.NPARAM)
    pr[K.PR_GPOOL] = pool
    for t, ge, gg in readings:
        K._glr_push(st, pr, t, ge, gg)
    return st, pr


def _brute(readings: list[tuple[float, float, float]], t_zero: float, sg: float) -> float:
    """argmax over tau in {t_zero} + readings after it of (sum ge)^2/(2 sum gg) over t > tau."""
    ts = [t_zero] + [t for t, _, _ in readings if t > t_zero]
    best, best_t = 0.0, t_zero
    for tau in ts:
        ge = np.array([g for t, g, _ in readings if t > tau])
        gg = np.array([h for t, _, h in readings if t > tau])
        a, b = float(ge.sum()), float(gg.sum())
        llr = a * a / (2 * b) if sg * a > 0 and b > 0 else 0.0
        if llr > best * (1 + 1e-12):
            best, best_t = llr, tau
    return best_t


def test_noiseless_step_is_dated_at_its_change() -> None:
    # readings g e/S = nu g²/S after the change at t = 3.0 (tenth reading), 0 before
    nu, gg = 0.4, 2.0
    rd = [(0.1 * k, nu * gg if 0.1 * k > 3.05 else 0.0, gg) for k in range(1, 61)]
    st, _ = _state(rd)
    a = sum(r[1] for r in rd)
    b = sum(r[2] for r in rd)
    assert K._glr_time(st, 0.0, 1.0, a, b) == pytest.approx(3.0)
    # the other sign has no candidate: the CUSUM's own zero stays
    assert K._glr_time(st, 0.0, -1.0, a, b) == 0.0


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_scan_is_the_argmax_of_the_step_likelihood(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = 200
    t = np.cumsum(rng.uniform(0.05, 0.15, n))
    gg = rng.uniform(0.1, 3.0, n)
    ge = rng.normal(0.0, np.sqrt(gg)) + np.where(t > t[120], 0.5 * gg, 0.0)
    rd = list(zip(t.tolist(), ge.tolist(), gg.tolist(), strict=True))
    st, _ = _state(rd)
    for t_zero in (t[0] - 1.0, t[60], t[150]):
        after = [r for r in rd if r[0] > t_zero]
        a, b = sum(r[1] for r in after), sum(r[2] for r in after)
        for sg in (1.0, -1.0):
            assert K._glr_time(st, t_zero, sg, a, b) == pytest.approx(_brute(rd, t_zero, sg), abs=1e-12)


def test_buffer_pools_and_wraps() -> None:
    # 1 kHz readings pooled by 12.5 ms: entries of 13 readings; 5000 readings wrap the 256 entries
    rd = [(0.001 * k, 1.0, 2.0) for k in range(5000)]
    st, _ = _state(rd, pool=0.0125)
    assert st[K.GCNT] == K.NGB
    # the newest entry, still pooling: 4.992 ... 4.999 (8 readings; entries begin every 13)
    t_new, ge_new, _ = K.glr_entry(st, 0)
    assert t_new == pytest.approx(4.999) and ge_new == pytest.approx(5000 - 13 * (5000 // 13))
    t_prev, ge_full, gg_full = K.glr_entry(st, 1)  # a whole entry: 13 readings
    assert ge_full == pytest.approx(13.0) and gg_full == pytest.approx(26.0)
    assert t_prev == pytest.approx(t_new - 0.008)  # the last reading before the newest entry's
    assert np.isnan(K.glr_entry(st, K.NGB)[0])  # only NGB held
    # a window longer than the buffer: the part not held has only t_zero as a candidate, with
    # the CUSUM's own sums (here a step at 0.5 s, long before the oldest entry held)
    held_from = K.glr_entry(st, K.NGB - 1)[0]
    assert held_from > 1.0
    assert K._glr_time(st, 0.5, 1.0, 1e6, 1.0) == 0.5


def test_slow_rise_before_a_touch_no_longer_dates_it_early() -> None:
    cond = get_condition("log-100hz", 103)
    # the detector's own dating (re-dated at the release, each version is right: test_redate)
    # nothing learnt of the sensors (the slow rise would be taken in part for a sensor's drift)
    cfg = fixed_sensors(cond.config(load_config())).replace(detector={"redate_readings": 0.0})
    sc = cond.scenario.with_duration(25.0)
    log = decimate(simulate(sc, cfg), cond.decimate)
    tc = next(tc for tc in sc.touches if 20.0 < tc.t_on < 22.0)
    glr = observe(log, cfg)
    # the premise: the estimate rose slowly (by more than 0.03 W) in the 1.5 s before the touch
    t, dq = log["t"], glr.columns["dq_i_hat"]
    before = (t > tc.t_on - 1.5) & (t < tc.t_on)
    slope = np.polyfit(t[before], dq[before], 1)[0]
    assert slope * 1.5 > 0.03
    (ev,) = [e for e in glr.events if tc.t_on <= e.detected_at <= tc.t_off]
    assert abs(ev.onset - tc.t_on) <= 0.3 and abs(ev.duration - tc.duration) <= 0.3
    (old,) = [e for e in observe(log, cfg.replace(detector={"onset_glr": 0.0})).events
              if tc.t_on <= e.detected_at <= tc.t_off]
    assert old.onset - tc.t_on < -0.3  # at the CUSUM's last zero: early
    assert old.detected_at == ev.detected_at  # only the dating differs
