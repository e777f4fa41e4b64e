"""The compiled estimation kernel against its plain-Python reference, and over many patches."""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path

import numpy as np
import pytest

from thermoskin.estimation import kernel as K  # noqa: N812
from thermoskin.estimation.estimator import TouchEstimator
from thermoskin.estimation.freshness import infer_fresh
from thermoskin.estimation.reference import ReferenceEstimator
from thermoskin.logio import read_log
from thermoskin.params import load_config
from thermoskin.sim.conditions import decimate, get_condition, mis_sized_skin
from thermoskin.sim.run import simulate
from thermoskin.sim.scenarios import SCENARIOS, Scenario


@functools.cache
def _one() -> dict[str, np.ndarray]:
    log = simulate(SCENARIOS["one-finger"].with_duration(25.0), load_config())
    log["T_w"][9000:9050] = np.nan  # a loose thermocouple
    return log


def _door_early(sc: Scenario, duration: float) -> Scenario:
    """``sc`` (the ambient-step condition's) with its ambient steps 12 s earlier (the first, 20 ->
    21 degC, at 21.4 s, 5.3 s before the touch at 26.7 s), ``duration`` long: what the reference
    filter steps through, shorter (it takes about 0.2 ms a sample)."""
    return dataclasses.replace(sc.with_duration(duration),
                               ambient=tuple((t - 12.0, T) for t, T in sc.ambient))


def _case(name: str):  # type: ignore[no-untyped-def]
    """The case's configuration and log, made by the worker that runs it (not at collection)."""
    cfg = load_config()
    if name == "1 kHz, a NaN burst":
        return cfg, _one()
    if name == "pump-cycle correction":  # 16 bins: the 50 ms phases clip at the last bin
        es = dataclasses.replace(cfg.estimator, switch_bins=16, switch_learn=0.05)
        return dataclasses.replace(cfg, estimator=es), _one()
    if name == "pump-cycle correction learnt":  # the default's rule, on a skin 30 % lighter
        true = cfg.replace(skin=mis_sized_skin(cfg.skin, -0.3))  # than configured: no touch
        return cfg, simulate(SCENARIOS["none"].with_duration(25.0), true)
    if name == "q_i alone jumps at an onset":
        # a skin patch's onset: the kernel then keeps no step signatures; the reference still
        # carries them, unread
        de = dataclasses.replace(cfg.detector, onset_state_jump=0.0)
        return dataclasses.replace(cfg, detector=de), _one()
    if name == "the emulator's 10 Hz session, two contacts withdrawn":  # (of no heat: 46, 48 s)
        log = read_log(Path(__file__).parent / "data" / "emulator_10hz_lab_seed0_loaded.parquet")
        log = {k: v[:50_000] for k, v in log.items()}
        log["v"] = np.where(log["v"] > 0, cfg.pump.v_on, 0.0)  # (the device's float32 speed)
        return cfg, log
    if name == "a 0.3 s pipe bead, a release over two pump phases":  # (its touch at 13 s)
        return cfg, simulate(SCENARIOS["one-finger"].with_duration(25.0), cfg,
                             boards=dataclasses.replace(cfg.sensor, lag_T_w=0.3))
    if name == "1/16 K boards":  # the air's one-step CUSUM passes its threshold: no door
        return cfg, simulate(SCENARIOS["fingers"].with_duration(30.0), cfg,
                             boards=dataclasses.replace(cfg.sensor, quantum_T=1 / 16))
    if name == "1/4 K boards at 1 kHz, the tank drifting within a step":  # the long windows
        sc = Scenario(name="quiet", description="", duration=40.0, T_a=20.0, touches=(),
                      pump="logic", T_p_drift=0.03, T_p_period=50.0)
        return cfg, simulate(sc, cfg, boards=dataclasses.replace(cfg.sensor, quantum_T=0.25, seed=3))
    if name.startswith("a door"):  # the air sensor lags 3 s: the onsets held while it catches
        # up (a touch 5.3 s after the door), found by its CUSUM where the lag is configured and
        # by the reading's rate where it is not
        sc = _door_early(get_condition("ambient-step", 4242).scenario, 33.0)
        true = cfg.replace(sensor={"lag_T_a": 3.0})
        return (true if "lag configured" in name else cfg), simulate(sc, true)
    if name in ("boards-10hz", "ambient-step", "cold", "setpoints"):
        cond = get_condition(name, 4242)
        c = cond.config(cfg)
        sc = cond.scenario.with_duration(30.0 if name == "cold" else 40.0)
        if name == "ambient-step":
            sc = _door_early(cond.scenario, 28.0)
        if name == "setpoints":  # its command changes (first at 83 s) brought early: up, then down
            sc = dataclasses.replace(cond.scenario.with_duration(48.0),
                                     setpoints=((0.0, 24.0), (12.0, 26.0), (30.0, 23.0)))
        return c, simulate(sc, c)
    # logs coarser than the loop (the pump-switch correction): 1 kHz thermocouples logged at
    # 50 Hz (the correction at the row), and 10 Hz boards logged at 100 Hz (a board's reading
    # new in a switch's row comes first, the correction after it)
    cname, factor = {"log-100hz logged every 20 ms": ("log-100hz", 20),
                     "boards-10hz logged every 10 ms": ("boards-10hz", 10)}[name]
    cond = get_condition(cname, 4243)
    c = cond.config(cfg)
    slow = decimate(simulate(cond.scenario.with_duration(60.0), c), factor)
    if cname == "log-100hz":  # a NaN reading (flagged fresh) in the row before some switches:
        # the next reading is still one a row, its switch corrected before it
        sw = np.flatnonzero(np.diff(slow["v"]) != 0)[5:60:5]
        slow["T_w"][sw] = np.nan
    slow["fresh"] = infer_fresh(slow)[0].astype(float)
    return c, slow


CASES = ["1 kHz, a NaN burst", "pump-cycle correction", "pump-cycle correction learnt",
         "q_i alone jumps at an onset", "boards-10hz",
         "ambient-step", "a door, the air sensor's 3 s lag configured",
         "a door, the air sensor 3 s slower than configured",
         "the emulator's 10 Hz session, two contacts withdrawn",
         "a 0.3 s pipe bead, a release over two pump phases", "1/16 K boards",
         "1/4 K boards at 1 kHz, the tank drifting within a step",
         "cold", "setpoints", "log-100hz logged every 20 ms",
         "boards-10hz logged every 10 ms"]


@pytest.mark.parametrize("name", CASES)
def test_kernel_equals_reference(name: str) -> None:
    cfg, log = _case(name)
    t_s = float(log["t"][1] - log["t"][0])
    t_s = cfg.sampling.t_s if abs(t_s - cfg.sampling.t_s) < 1e-9 else round(t_s, 6)
    # the detector's own events: the reference has no re-dating (tests/test_redate.py holds it)
    est = TouchEstimator(cfg.replace(detector={"redate_readings": 0.0}), t_s=t_s)
    ref = ReferenceEstimator(cfg, t_s)
    keys = ("t", "T_w", "T_p", "v", "T_a", "T_w_cmd", "fresh", "drive")
    if "drive" not in log:  # (a log of the loop has it: the tank model takes it)
        log = {**log, "drive": np.full(len(log["t"]), np.nan)}
    worst = {"q_i_hat": 0.0, "dq_i_hat": 0.0, "sd": 0.0, "T_g_hat": 0.0}
    for row in zip(*(log[k].tolist() for k in keys), strict=True):
        t, T_w, T_p, v, T_a, cmd, fr, dr = row
        c1 = est.step(t, T_w, T_p, v, T_a, cmd, int(fr), dr)
        c2 = ref.step(t, T_w, T_p, v, T_a, cmd, int(fr), dr)
        assert (c1 & 1) == (c2 & 1), (name, t)
        assert est.st[K.TAMB] == ref.t_air, (name, t)  # the air's sudden changes, and its holds
        for k, a, b in (("q_i_hat", est.q_i_hat, ref.q_i_hat), ("dq_i_hat", est.dq_i_hat, ref.dq),
                        ("sd", est.sd, ref.sd), ("T_g_hat", est.T_g_hat, ref.T_g_hat)):
            if not (a == b or (a != a and b != b)):
                worst[k] = max(worst[k], abs(a - b))
    assert all(v <= 1e-9 for v in worst.values()), worst
    # the dispersion of the short windows, of the long ones
    assert est.st[K.RHOS] == pytest.approx(ref.rho_s, rel=1e-9)
    assert est.st[K.RHOL] == pytest.approx(ref.rho_l, rel=1e-9)
    assert est.st[K.RHOP] == pytest.approx(ref.rho_p, rel=1e-9)  # and of the pump's phases
    if "within a step" in name:
        assert ref.rho_ln >= 3 and ref.rho_l > 2.0  # (the long windows taken, and up from 1)
    if name == "pump-cycle correction learnt":  # (the phases taken: the tracker went its way
        assert ref.rho_pn >= 100 and ref.rho_p != 1.0  # as the correction learnt the misfit)
    nb = cfg.estimator.switch_bins  # the pump-cycle correction's table, as learnt
    if nb:
        np.testing.assert_allclose(est.switch_table[:2 * nb].reshape(2, nb), ref.tpl, rtol=0, atol=1e-12)
    assert [e.sign for e in est.events] == [e.sign for e in ref.events]
    for a, b in zip(est.events, ref.events, strict=True):
        assert a.onset == pytest.approx(b.onset, abs=1e-9) and a.release == pytest.approx(b.release, abs=1e-9)
        assert a.peak_dq == pytest.approx(b.peak_dq, abs=1e-9)
        assert a.mean_dq == pytest.approx(b.mean_dq, abs=1e-9)


def test_median_in_place_is_numpys_median() -> None:
    """The warm-up baseline's median, taken without allocating (the kernel runs without
    reference counting), is numpy's: odd and even counts, ties, a NaN, an offset part."""
    from thermoskin.estimation.kernel import _median_in_place

    rng = np.random.default_rng(7)
    for m in (1, 2, 3, 10, 255, 256):
        for kind in ("normal", "ties"):
            x = rng.normal(0.03, 0.01, m) if kind == "normal" else rng.integers(0, 4, m) * 0.25
            a = np.concatenate([[9.0, -9.0], x, [5.0]])
            assert _median_in_place.py_func(a.copy(), 2, m) == np.median(x)
            b = a.copy()
            assert _median_in_place(b, 2, m) == np.median(x)  # compiled
            assert b[0] == 9.0 and b[-1] == 5.0 and np.all(np.diff(b[2:2 + m]) >= 0)
    x = np.array([0.1, np.nan, 0.2])
    assert np.isnan(_median_in_place(x.copy(), 0, 3)) and np.isnan(np.median(x))


def test_no_subnormal_state() -> None:
    """No entry of a patch's state settles on a subnormal number (every product on one is a
    slow microcode assist: a sample cost 540 ns instead of 190 ns once the air filter's cross
    covariance had decayed to 5e-323, 14 s into this log, stepped sample by sample as the
    live loop does); 0 and NaN are fine."""
    from thermoskin.estimation import kernel

    cfg = load_config()
    log = simulate(SCENARIOS["fingers"].with_duration(60.0), cfg)
    est = TouchEstimator(cfg)
    tiny = np.finfo(np.float64).tiny
    t, T_w, T_p, v, T_a = (log[k][:20_000].tolist() for k in ("t", "T_w", "T_p", "v", "T_a"))
    for k in range(20_000):
        est.step(t[k], T_w[k], T_p[k], v[k], T_a[k])
        if k % 1000 == 999:
            sub = np.flatnonzero((np.abs(est.st) < tiny) & (est.st != 0.0))
            assert sub.size == 0, (t[k], sub)
    assert kernel._ftz(5e-323) == 0.0 and kernel._ftz(-1e-310) == 0.0 and kernel._ftz(tiny) == tiny
    assert kernel._ftz(0.0) == 0.0 and np.isnan(kernel._ftz(np.nan)) and kernel._ftz(-2.5) == -2.5


def test_entry_points_without_reference_counting() -> None:
    """The installed numba takes ``_nrt=False`` (a private option; without it the kernel falls
    back to reference counting, about three times slower a patch on one core): this says so."""
    from thermoskin.estimation import kernel

    assert kernel._FAST.get("_nrt") is False
    for f in (kernel.step, kernel.run, kernel.step_many, kernel.step_many_parallel, kernel.run_rows,
              kernel.finish):
        assert f.targetoptions.get("_nrt") is False, f


@pytest.mark.parametrize("period", [1, 7, 15, 100])
def test_onset_threshold_follows_the_reading_rate(period: int) -> None:
    """The onset threshold is ``max(h_on + h_rate ln(readings/s), h_min)`` at the pipe
    thermocouple's actual rate (a reading every ``period`` rows of a 1 kHz log, as boards of
    1000, 143, 67 and 10 Hz give; the last at the floor), computed here from the rate alone;
    the kernel renews it only when the rate moves (``RATE_TOL``), so it agrees to that
    tolerance, not exactly."""
    import math

    from thermoskin.estimation import kernel as K  # noqa: N812

    cfg = load_config()
    d = cfg.detector
    n = 20_000
    t = np.arange(n) * cfg.sampling.t_s
    x = np.full(n, 24.0)
    fresh = np.where(np.arange(n) % period == 0, 7, 6)
    est = TouchEstimator(cfg)
    est.feed(t, x, x, np.zeros(n), x, fresh=fresh)
    rate = 1.0 / (period * cfg.sampling.t_s)
    h = max(d.h_on + d.h_rate * math.log(rate), d.h_min)
    assert est.st[K.HTH] == pytest.approx(h, abs=d.h_rate * 1e-5)
