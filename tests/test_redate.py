"""Dating a contact again when it ends (``estimation.redate``).

The compiled fit is held to an independent one: the plain-Python reference filter
(:class:`~thermoskin.estimation.reference.ReferenceEstimator`, detection off, its updates
recorded), the pulse's and the nuisance's signatures carried row by row, the nuisance
projected out of the readings themselves (an SVD), not out of the sums.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import sys

import numpy as np
import pytest

from thermoskin.analysis.observe import observe
from thermoskin.estimation import kernel as K  # noqa: N812
from thermoskin.estimation import redate as RD  # noqa: N812
from thermoskin.estimation.estimator import TouchEstimator
from thermoskin.estimation.freshness import loop_t_s, sample_interval
from thermoskin.estimation.model import I_Q
from thermoskin.estimation.reference import ReferenceEstimator
from thermoskin.params import Config, load_config
from thermoskin.sim.conditions import decimate, get_condition
from thermoskin.sim.run import simulate
from thermoskin.sim.scenarios import SCENARIOS


def _log(name: str, seed: int, duration: float | None = None
         ) -> tuple[Config, dict[str, np.ndarray], object]:
    cond = get_condition(name, seed)
    cfg = cond.config(load_config())
    sc = cond.scenario if duration is None else cond.scenario.with_duration(duration)
    log = simulate(sc, cfg)
    if cond.decimate > 1:
        log = decimate(log, cond.decimate)
    return cfg, log, sc


def _block(log: dict[str, np.ndarray], est: TouchEstimator) -> tuple[np.ndarray, ...]:
    """The log's rows as the re-dating's input columns."""
    n = len(log["t"])
    nan = np.full(n, math.nan)
    return (log["t"], log["T_w"], log["T_p"], log["T_a"], log.get("T_w_cmd", nan),
            est.rows_of(log["v"]).astype(float), log.get("drive", nan), log["fresh"].astype(float))


def _reference_fit(log: dict[str, np.ndarray], cfg: Config, k0: int, end: int, j_first: int,
                   cand_on: np.ndarray, cand_off: np.ndarray, sign: float) -> tuple[float, float]:
    """The pulse fit the textbook way, on rows ``k0..end-1`` (evidence from ``j_first`` on)."""
    t = log["t"]
    est = ReferenceEstimator(cfg, loop_t_s(sample_interval(t), cfg), detect=False)
    est.hold(est.R0, 0.0, cfg.sensor.lag_T_w)  # as the re-dating's filter holds them
    est.record_switches = True
    cmd = log.get("T_w_cmd")
    rows, phis = [], []
    for k in range(k0, end):
        est.updates = []
        est.step(float(t[k]), float(log["T_w"][k]), float(log["T_p"][k]), float(log["v"][k]),
                 float(log["T_a"][k]), float(cmd[k]) if cmd is not None else math.nan,
                 int(log["fresh"][k]), float(log["drive"][k]) if "drive" in log else math.nan)
        rows.append(est.updates)
        F = np.zeros((6, 6))  # the model's step and the pipe thermocouple's bead's
        F[:5, :5] = est.tables.Phi[est.iv_prev]
        F[5, 0], F[5, 5] = 1.0 - est.a, est.a
        phis.append(F)
    tt = t[k0:end]
    s_on, s_off = np.searchsorted(tt, cand_on), np.searchsorted(tt, cand_off)
    keep = s_off < len(tt) - 1
    cand_off, s_off = cand_off[keep], s_off[keep]
    start = np.concatenate([s_on, s_off])
    n = len(start)
    mu = np.zeros((6, n + 6))
    mu[:, n:] = np.eye(6)
    cols, z = [], []
    for j in range(j_first, len(tt)):
        new = start == j
        mu[:, :n][:, new] = 0.0
        mu[I_Q, :n][new] = 1.0
        for i, e, Se, Kg, evidence, h in rows[j]:
            if i < 0:  # a pump switch's correction: x_Tw += c (x_Tp - x_Tw)
                mu[0] += e * (mu[3] - mu[0])
                continue
            rho = h @ mu  # the reading's row (the pipe's: its bead's)
            if evidence:
                cols.append(rho / math.sqrt(Se))
                z.append(e / math.sqrt(Se))
            mu -= np.outer(Kg, rho)
        mu = phis[j] @ mu
    R = np.array(cols).T
    zz = np.array(z)
    U, sv, _ = np.linalg.svd(R[n:].T, full_matrices=False)
    U = U[:, sv > 1e-6 * sv[0]]
    Rp = R[:n] - (R[:n] @ U) @ U.T
    zp = zz - U @ (U.T @ zz)
    a = Rp @ zp
    G = Rp @ Rp.T
    no = len(s_on)
    if no == 0 or len(s_off) == 0:  # one edge: the release as a step down, or the onset up
        sg = -sign if no == 0 else sign
        num, den = a, np.diag(G)
        ok = (num * sg > 0) & (den > 1e-9 * np.diag(G @ G.T) ** 0.5)
        llr = np.where(ok, num * num / np.where(ok, den, 1.0), -np.inf)
        w = np.exp(0.5 * (llr - llr.max()))
        mean = float(np.sum(w * (cand_off if no == 0 else cand_on)) / np.sum(w))
        return (math.nan, mean) if no == 0 else (mean, math.nan)
    ia = np.arange(no)[:, None]
    ib = no + np.arange(len(s_off))[None, :]
    num = a[ia] - a[ib]
    den = G[ia, ia] + G[ib, ib] - 2.0 * G[ia, ib]
    ok = (num * sign > 0) & (start[ia] < start[ib]) & (den > 1e-9 * (G[ia, ia] + G[ib, ib]))
    llr = np.where(ok, num * num / np.where(ok, den, 1.0), -np.inf)
    # each time's posterior mean: the pairs weighed by their likelihood ratio, exp(a^2 / 2b)
    on, off = np.meshgrid(cand_on, cand_off, indexing="ij")
    w = np.exp(0.5 * (llr - llr.max()))
    return float(np.sum(w * on) / np.sum(w)), float(np.sum(w * off) / np.sum(w))


@pytest.mark.parametrize("lag", [False, True], ids=["no lag", "a lagging pipe thermocouple"])
def test_pulse_sums_against_row_by_row_signatures(lag: bool) -> None:
    """The compiled sums (transitions between readings multiplied together first) against the
    signatures carried row by row and summed directly, on a random trace with sparse readings;
    with a lag, the pipe's reading is its bead's, ``(1 - a) T_w + a m``, and the bead steps as
    ``m <- (1 - a) T_w + a m`` (six states)."""
    rng = np.random.default_rng(3)
    n = 400
    rec = np.zeros((n, RD.NREC))
    Phi = np.stack([np.eye(5) + 0.02 * rng.standard_normal((5, 5)) for _ in range(2)])
    for j in range(n):
        la = 0.6 + 0.3 * rng.random() if lag else 0.0
        for u, every in ((0, 7), (1, 11)):
            if j % every == 0:
                o = u * K.NUR
                rec[j, o] = 1.0
                rec[j, o + 1] = rng.standard_normal()
                rec[j, o + 2] = 0.5 + rng.random()
                rec[j, o + 3] = 1.0 if rng.random() > 0.1 else 0.0
                rec[j, o + 4:o + 10] = 0.3 * rng.standard_normal(6)
                rec[j, o + 10] = la if u == 0 else 0.0
        rec[j, RD.RIV] = float(rng.integers(2))
        rec[j, RD.RREADY] = 1.0
        rec[j, RD.RLAGA] = la
        if j % 13 == 5:
            rec[j, RD.RSWB if j % 2 else RD.RSWA] = 0.2 * rng.standard_normal()
    j_first = 20
    s_on = np.sort(rng.integers(25, 120, 9)).astype(np.int64)
    s_off = np.sort(rng.integers(150, 390, 7)).astype(np.int64)
    a, d, cn, nn, x = RD.pulse_sums(rec, Phi, j_first, s_on, s_off)
    start = np.concatenate([s_on, s_off])
    nc = len(start)
    ns = RD.NS
    mu = np.zeros((ns, nc + ns))
    mu[:, nc:] = np.eye(ns)
    Rcols, z = [], []
    for j in range(j_first, n):
        for c in np.flatnonzero(start == j):
            mu[:, c] = np.eye(ns)[I_Q]
        mu[0] += rec[j, RD.RSWB] * (mu[3] - mu[0])
        for u in (0, 1):
            o = u * K.NUR
            if rec[j, o]:
                la = rec[j, o + 10]
                rho = (1.0 - la) * mu[0] + la * mu[5] if u == 0 else mu[3].copy()
                if rec[j, o + 3]:
                    Rcols.append(rho / math.sqrt(rec[j, o + 2]))
                    z.append(rec[j, o + 1] / math.sqrt(rec[j, o + 2]))
                mu -= np.outer(rec[j, o + 4:o + 10], rho)
        mu[0] += rec[j, RD.RSWA] * (mu[3] - mu[0])
        la = rec[j, RD.RLAGA]
        F = np.zeros((ns, ns))
        F[:5, :5] = Phi[int(rec[j, RD.RIV])]
        F[5, 0], F[5, 5] = 1.0 - la, la
        mu = F @ mu
    R = np.array(Rcols).T
    G = R @ R.T
    np.testing.assert_allclose(a, R @ np.array(z), rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(d, np.diag(G)[:nc], rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(cn, G[:nc, nc:], rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(nn, G[nc:, nc:], rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(x, G[:len(s_on), len(s_on):nc], rtol=1e-10, atol=1e-12)


def test_fit_against_the_reference_filter_and_svd_projection() -> None:
    """Each contact of a 100 Hz log dated again by the estimator's re-dating and by the
    textbook fit on the plain-Python filter over the same rows: the same onset and release
    (each its posterior mean over the grid)."""
    cfg, log, _ = _log("log-100hz", 101)
    est = TouchEstimator(cfg, t_s=loop_t_s(sample_interval(log["t"]), cfg))
    raw = observe(log, cfg.replace(detector={"redate_readings": 0.0})).events
    assert len(raw) >= 8
    rd = RD.Redater(cfg, est.t_s)
    block = _block(log, est)
    t = log["t"]
    reach = cfg.detector.redate_reach
    moved = 0
    for e in raw:
        t_end = e.release + cfg.detector.redate_tail
        got = rd.redate(est, e, int(np.searchsorted(t, t_end)), t_end, block, 0)
        t0 = e.onset - reach - RD.NUISANCE_S
        k0, j0 = int(np.searchsorted(t, t0 - RD.HISTORY_S)), int(np.searchsorted(t, t0))
        end = int(np.searchsorted(t, t_end))
        on, off = _reference_fit(log, cfg, k0, end, j0 - k0,
                                 np.arange(e.onset - reach, min(e.onset + reach, e.detected_at) + 1e-9,
                                           RD.GRID_S),
                                 np.arange(e.release - reach, e.release + reach + 1e-9, RD.GRID_S),
                                 float(e.sign))
        assert got.onset == pytest.approx(on, abs=1e-4)
        assert got.release == pytest.approx(off, abs=1e-4)
        moved += abs(got.onset - e.onset) > 0.005 or abs(got.release - e.release) > 0.005
        assert got.duration == pytest.approx(got.release - got.onset)
        assert got.energy == pytest.approx(e.mean_dq * got.duration)
    assert moved >= len(raw) // 2  # the fit did date them again


def test_step_and_chunks_write_the_same_events() -> None:
    """Live (a sample at a time) and offline (chunks of any size) re-date at the same rows."""
    cfg, log, _ = _log("boards-10hz", 102, duration=80.0)
    t, n = log["t"], len(log["t"])
    a = TouchEstimator(cfg)
    for k in range(n):
        a.step(float(t[k]), float(log["T_w"][k]), float(log["T_p"][k]), float(log["v"][k]),
               float(log["T_a"][k]), float(log["T_w_cmd"][k]), int(log["fresh"][k]))
    a.finish(float(t[-1]))
    assert len(a.events) >= 4
    for size in (997, 25_000, n):
        b = TouchEstimator(cfg)
        for s in range(0, n, size):
            sl = slice(s, s + size)
            b.feed(t[sl], log["T_w"][sl], log["T_p"][sl], log["v"][sl], log["T_a"][sl],
                   log["T_w_cmd"][sl], log["fresh"][sl])
        b.finish(float(t[-1]))
        assert b.events == a.events, size


def test_fits_in_the_background_write_the_same_events() -> None:
    """A live loop's fits in a worker thread (``background_fits``): the same events in the same
    order as fitted in the sample itself, each written at a later sample (the sample that
    made it due does not wait for it), none lost at the end. (This loop never sleeps, as a
    realtime loop does between samples: the interpreter's switch interval set as that loop
    sets it, or the worker waits 5 ms at each of its turns.)"""
    cfg, log, _ = _log("boards-10hz", 102, duration=80.0)
    t, n = log["t"], len(log["t"])
    runs = {}
    old = sys.getswitchinterval()
    sys.setswitchinterval(1e-4)
    try:
        for bg in (False, True):
            e = TouchEstimator(cfg, background_fits=bg)
            at = []
            for k in range(n):
                e.step(float(t[k]), float(log["T_w"][k]), float(log["T_p"][k]), float(log["v"][k]),
                       float(log["T_a"][k]), float(log["T_w_cmd"][k]), int(log["fresh"][k]))
                at.extend([k] * len(e.written))
            e.finish(float(t[-1]))
            runs[bg] = (e.events, at)
    finally:
        sys.setswitchinterval(old)
    (ev_fg, at_fg), (ev_bg, at_bg) = runs[False], runs[True]
    assert len(ev_fg) >= 4 and ev_bg == ev_fg  # the rest collected by finish: none lost
    # written live, in order, each at a later sample (a loaded machine may leave the last
    # fits, due in the log's last seconds, to finish)
    assert 0 < len(at_bg) <= len(at_fg)
    assert all(b > a for a, b in zip(at_fg, at_bg, strict=False))


def _duration_errors(events: list, touches: tuple) -> np.ndarray:
    out = []
    for tc in touches:
        e = next((e for e in events if tc.t_on <= e.detected_at <= tc.t_on + tc.duration + 1.0), None)
        if e is not None:
            out.append(e.duration - tc.duration)
    return np.abs(np.array(out))


@pytest.mark.parametrize("name,seed", [("boards-10hz", 103), ("log-100hz", 104)])
def test_redating_brings_durations_nearer_the_truth(name: str, seed: int) -> None:
    """Against the scenario's own touches: no more durations off by over 0.3 s, and a smaller
    mean error, than the detector's own dates."""
    cfg, log, sc = _log(name, seed)
    raw = _duration_errors(observe(log, cfg.replace(detector={"redate_readings": 0.0})).events, sc.touches)
    new = _duration_errors(observe(log, cfg).events, sc.touches)
    assert len(new) == len(raw) >= 8
    assert np.sum(new > 0.3) <= np.sum(raw > 0.3)
    assert new.mean() < raw.mean()


def test_long_contacts_at_1khz_keep_the_detector_dates() -> None:
    """At 1 kHz a contact of 2 s weighs more readings than ``redate_readings``: the events are
    the detector's own; its taps (0.2-0.5 s) are dated again."""
    cfg = load_config()
    log = simulate(SCENARIOS["one-finger"].with_duration(25.0), cfg)
    off = observe(log, cfg.replace(detector={"redate_readings": 0.0})).events
    assert len(off) >= 3 and all(e.duration > 1.0 for e in off)
    assert observe(log, cfg).events == off
    cfg, log, _ = _log("taps", 105, duration=60.0)
    on = observe(log, cfg).events
    off = observe(log, cfg.replace(detector={"redate_readings": 0.0})).events
    assert len(on) == len(off) >= 3
    assert all(a.onset != b.onset or a.release != b.release for a, b in zip(on, off, strict=True))


def test_one_edge_fits_against_the_reference_filter() -> None:
    """The release alone (a contact whose start has left the buffer: a step down) and the
    onset alone (a contact still open: a step up), each against the textbook fit on the
    plain-Python filter over the same rows, for every contact of a 100 Hz log; the fits move
    the detector's dates."""
    cfg, log, _ = _log("log-100hz", 101)
    est = TouchEstimator(cfg, t_s=loop_t_s(sample_interval(log["t"]), cfg))
    raw = observe(log, cfg.replace(detector={"redate_readings": 0.0})).events
    block = _block(log, est)
    t = log["t"]
    reach, tail = cfg.detector.redate_reach, cfg.detector.redate_tail
    moved = 0
    for e in raw:
        # the release alone
        t_end = e.release + tail
        end = int(np.searchsorted(t, t_end))
        long = dataclasses.replace(e, onset=e.release - RD.LONGEST_S - 1.0)
        got = RD.Redater(cfg, est.t_s).redate(est, long, end, t_end, block, 0)
        t0 = e.release - reach - RD.NUISANCE_S
        k0, j0 = int(np.searchsorted(t, t0 - RD.HISTORY_S)), int(np.searchsorted(t, t0))
        _, off = _reference_fit(log, cfg, k0, end, j0 - k0, np.zeros(0),
                                np.arange(e.release - reach, e.release + reach + 1e-9, RD.GRID_S),
                                float(e.sign))
        assert got.onset == long.onset
        assert got.release == pytest.approx(off, abs=1e-4)
        # the onset alone: the log ends 0.3 s after the detection, in the contact
        t_cut = e.detected_at + 0.3
        cut = int(np.searchsorted(t, t_cut))
        open_e = dataclasses.replace(e, release=float(t[cut - 1]))
        got = RD.Redater(cfg, est.t_s).redate(est, open_e, cut - 1, math.inf, block, 0,
                                             open_end=True)  # as finish calls it
        t0 = e.onset - reach - RD.NUISANCE_S
        k0, j0 = int(np.searchsorted(t, t0 - RD.HISTORY_S)), int(np.searchsorted(t, t0))
        on, _ = _reference_fit(log, cfg, k0, cut, j0 - k0,
                               np.arange(e.onset - reach, min(e.onset + reach, e.detected_at) + 1e-9,
                                         RD.GRID_S), np.zeros(0), float(e.sign))
        assert got.release == open_e.release
        assert got.onset == pytest.approx(on, abs=1e-4)
        moved += abs(got.onset - e.onset) > 0.005
    assert moved >= len(raw) // 2


def test_release_alone_when_the_start_is_gone() -> None:
    """A contact longer than the buffer's reach has its release alone dated again (a step down)."""
    cfg, log, _ = _log("log-100hz", 101)
    raw = observe(log, cfg.replace(detector={"redate_readings": 0.0})).events
    e0 = raw[2]
    est = TouchEstimator(cfg, t_s=loop_t_s(sample_interval(log["t"]), cfg))
    rd = RD.Redater(cfg, est.t_s)
    block = _block(log, est)
    t_end = e0.release + cfg.detector.redate_tail
    k = int(np.searchsorted(log["t"], t_end))
    long = dataclasses.replace(e0, onset=e0.release - RD.LONGEST_S - 1.0)
    got = rd.redate(est, long, k, t_end, block, 0)
    assert got.onset == long.onset
    assert abs(got.release - e0.release) <= cfg.detector.redate_reach + 1e-9
    both = RD.Redater(cfg, est.t_s).redate(est, e0, k, t_end, block, 0)  # nothing written before
    assert abs(got.release - both.release) <= 0.1


def test_close_taps_are_not_dated_into_each_other() -> None:
    """Taps 0.3 s long, 0.3-0.45 s apart, on a 100 Hz log: each contact's onset is dated after
    the release of the one written before it (the evidence starts there too)."""
    cond = get_condition("log-100hz", 2)
    cfg = cond.config(load_config())
    proto = get_condition("tap-burst", 2).scenario.touches[0]
    rng = np.random.default_rng(2)
    touches, t = [], 6.0
    while t < 60.0:
        for _ in range(4):
            touches.append(dataclasses.replace(proto, t_on=t, duration=0.3))
            t += 0.3 + rng.uniform(0.3, 0.45)
        t += 6.0
    sc = dataclasses.replace(cond.scenario, touches=tuple(touches), duration=65.0)
    log = decimate(simulate(sc, cfg), cond.decimate)
    on = observe(log, cfg).events
    off = observe(log, cfg.replace(detector={"redate_readings": 0.0})).events
    assert [e.detected_at for e in on] == [e.detected_at for e in off] and len(on) >= 12
    assert all(b.onset > a.release for a, b in itertools.pairwise(on))
    assert sum(a != b for a, b in zip(on, off, strict=True)) >= len(on) // 2  # and they are dated again


def test_a_contact_open_at_the_end_keeps_its_release() -> None:
    """A log cut in the middle of a tap: the contact did not end, so its release stays the
    log's end (its onset alone is dated again)."""
    cfg, log, _ = _log("tap-burst", 7, duration=10.4)  # a tap 10.25-10.71 s, detected at 10.31 s
    on = observe(log, cfg).events
    off = observe(log, cfg.replace(detector={"redate_readings": 0.0})).events
    assert on[-1].release == off[-1].release == log["t"][-1]
    assert on[-1].onset <= on[-1].detected_at


def test_absurd_readings_leave_the_detector_dates() -> None:
    """A finite but absurd reading near a contact (1e6 degC for a board's reading) makes the
    fit's sums overflow: the event keeps the detector's dates, no exception."""
    cfg, log, _ = _log("boards-10hz", 5, duration=30.0)
    t = log["t"]
    log["T_w"][(t >= 5.67) & (t < 5.77)] = 1e6
    est = TouchEstimator(cfg)
    for k in range(len(t)):
        est.step(float(t[k]), float(log["T_w"][k]), float(log["T_p"][k]), float(log["v"][k]),
                 float(log["T_a"][k]), float(log["T_w_cmd"][k]), int(log["fresh"][k]))
    est.finish(float(t[-1]))
    assert est.events and all(math.isfinite(e.onset) and math.isfinite(e.release) for e in est.events)


def test_fit_refuses_sums_whose_likelihood_overflows() -> None:
    """Finite sums whose likelihood ratio overflows (a^2 beyond float64) give no fit rather than
    NaN dates, for a pulse and for one edge alone."""
    big = np.array([1e160, 2e160, -1e160, -2e160, 0, 0, 0, 0, 0])
    s_on, s_off = np.array([0, 1]), np.array([5, 6])
    c_on, c_off = np.array([1.0, 1.01]), np.array([2.0, 2.01])
    args = (np.ones(4), np.zeros((4, 5)), np.eye(5))
    assert RD.pulse_fit(big, *args, np.zeros((2, 2)), 2, 1.0, s_on, s_off, c_on, c_off) is None
    assert RD.pulse_fit(big, *args, np.zeros((0, 4)), 0, -1.0, s_on[:0], np.arange(4),
                        c_on[:0], np.arange(4.0)) is None
    small = big * 1e-160  # the same sums, scaled into range: a fit, finite
    on, off = RD.pulse_fit(small, *args, np.zeros((2, 2)), 2, 1.0, s_on, s_off, c_on, c_off)
    assert 1.0 <= on <= 1.01 and 2.0 <= off <= 2.01
