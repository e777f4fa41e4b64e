"""What the estimator learns of its sensors from the readings (``docs/model.md``, Sensors that
calibrate themselves), each against an independent truth: the offset against the one injected
into the simulated boards and against an augmented Kalman filter written here the textbook way
(the two-stage filter's equal for a constant offset); the noise and the converter's step
against the boards' own; the lag against the bead's; the dispersion against coloured noise the
model does not have; the boards a lab buys, and ``--ideal-sensors``."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from thermoskin.estimation import kernel as K  # noqa: N812
from thermoskin.estimation.estimator import TouchEstimator
from thermoskin.estimation.learnt import learnt, notices, one_finger_snr
from thermoskin.estimation.model import I_Q, I_TP, I_TW, fixed_sensors, measurement_variance
from thermoskin.params import load_config
from thermoskin.sim.boards import LAB, lab_boards
from thermoskin.sim.run import simulate
from thermoskin.sim.scenarios import SCENARIOS


def _quiet(duration: float, **boards: float) -> tuple[object, dict[str, np.ndarray]]:
    """A no-touch log of the default skin read through boards unlike the configured ones."""
    cfg = load_config()
    b = dataclasses.replace(cfg.sensor, seed=31, **boards)
    return cfg, simulate(SCENARIOS["none"].with_duration(duration), cfg, boards=b)


def _run(cfg, log, **kw):  # type: ignore[no-untyped-def]
    est = TouchEstimator(cfg, **kw)
    res = est.run(log["t"], log["T_w"], log["T_p"], log["v"], log["T_a"], T_w_cmd=log["T_w_cmd"],
                  fresh=log["fresh"])
    return est, res


@pytest.mark.parametrize("offsets", [{"offset_T_w": 0.1}, {"offset_T_w": 0.3, "offset_T_p": -0.2,
                                                            "offset_T_a": 0.5}, {"offset_T_p": 0.5}])
def test_offset_learnt_is_the_one_injected(offsets: dict[str, float]) -> None:
    """The T_p readings' offset against the T_w readings, injected into the simulated boards and
    not told to the estimator, learnt within 10 mK in 40 s of no touch, with no false contact."""
    cfg, log = _quiet(40.0, **offsets)
    est, res = _run(cfg, log)
    truth = offsets.get("offset_T_p", 0.0) - offsets.get("offset_T_w", 0.0)
    lt = est.learnt()
    assert lt.offset_p == pytest.approx(truth, abs=0.01)
    assert lt.offset_p_sd < 0.01
    assert res.columns["b_p_hat"][-1] == lt.offset_p  # the log's column says the same
    assert not res.events
    # without learning the same readings give false contacts (the switching's apparent heat)
    _, plain = _run(fixed_sensors(cfg), log)
    assert len(plain.events) >= 5


def test_two_stage_offset_equals_the_augmented_filter() -> None:
    """The kernel's two-stage filter (the patch's filter as if the offset were known, its
    sensitivity V, the offset's own gain) against the augmented Kalman filter with the offset a
    sixth, constant state, written here with numpy: the same estimates to rounding, on 10 s of
    1 kHz readings with an offset of 0.2 K on T_p (no detection, each update taken whole)."""
    cfg0, log = _quiet(10.0, offset_T_p=0.2)
    cfg = fixed_sensors(cfg0).replace(sensor={"offset_sd": 0.3}, estimator={"offset_drift": 0.0})
    est = TouchEstimator(cfg)
    pr = est.pr
    pr[K.PR_TRACE] = 1.0  # no detection: the filter alone
    pr[K.PR_DBMAX] = pr[K.PR_SWIN] = 1e9  # every update whole, no window's letting go
    pr[K.PR_LDELAY] = 0.0
    pr[K.PR_CMAN] = 1e9  # no tank manoeuvre (the augmented filter here has none)
    tb = est.tables
    R = est.pr[K.PR_RW0]
    Pb0 = 0.3**2
    x6 = None
    P6 = np.zeros((6, 6))
    worst = 0.0
    for k in range(len(log["t"])):
        t, Tw, Tp, v, Ta = (float(log[c][k]) for c in ("t", "T_w", "T_p", "v", "T_a"))
        iv = tb.index(v)
        F = np.eye(6)
        F[:5, :5] = tb.Phi[iv]
        Q = np.zeros((6, 6))
        Q[:5, :5] = tb.Q_idle[iv]
        if x6 is not None:
            for y, h in ((Tw, np.eye(6)[I_TW]), (Tp, np.eye(6)[I_TP] + np.eye(6)[5])):
                S = h @ P6 @ h + R
                Kg = P6 @ h / S
                x6 = x6 + Kg * (y - h @ x6)
                P6 = P6 - np.outer(Kg, h @ P6)
        est.step(t, Tw, Tp, v, Ta, float(log["T_w_cmd"][k]), 7)
        if x6 is None:  # the kernel's start: the readings (the tank's holds the offset), predicted
            x6 = np.append(est.st[K.X:K.X + 5], 0.0)
            P6 = np.zeros((6, 6))
            P6[:5, :5] = np.diag([R, R, 1.0, R, 1e-4])
            P6[I_TP, I_TP] += Pb0  # x_Tp = T_p + b + n: its error holds the offset's ...
            P6[5, 5] = Pb0
            P6[I_TP, 5] = P6[5, I_TP] = -Pb0  # ... against the offset's, -b
            P6 = F @ P6 @ F.T + Q
            continue
        # the model's step, with the air as the kernel has it (its own filter)
        x6 = F @ x6
        x6[:5] += tb.Gam[iv] @ np.array([est.st[K.XA], 0.0])
        P6 = F @ P6 @ F.T + Q
        worst = max(worst, float(np.abs(est.st[K.X:K.X + 5] - x6[:5]).max()))
    assert est.st[K.BD] == pytest.approx(x6[5], abs=1e-9)
    assert est.st[K.BD] == pytest.approx(0.2, abs=0.01)
    assert worst < 1e-9, worst


def test_noise_and_step_learnt_from_the_readings() -> None:
    """Boards of 0.05 K noise, configured as 0.02 K: each channel's noise learnt within 10 % (the
    pipe's from its innovations, the tank's and the air's from their second differences); with a
    1/16 K step the step is found exactly, the pipe's noise still within 10 %, the tank's and the
    air's within 35 % (their second differences then take a few values only, whose median is
    low: a limit); without a step, none is found."""
    cfg, log = _quiet(40.0, noise_T=0.05)
    est, _ = _run(cfg, log)
    lt = est.learnt()
    true = math.sqrt(0.05**2 + (1 / 128) ** 2 / 12)
    for ch in ("T_w", "T_p", "T_a"):
        assert lt.noise[ch] == pytest.approx(true, rel=0.1), ch
    cfg, log = _quiet(40.0, noise_T=0.05, quantum_T=1 / 16)
    est, _ = _run(cfg, log)
    lt = est.learnt()
    true = math.sqrt(0.05**2 + (1 / 16) ** 2 / 12)
    for ch in ("T_w", "T_p", "T_a"):
        assert lt.noise[ch] == pytest.approx(true, rel=0.1 if ch == "T_w" else 0.35), ch
        assert lt.quantum[ch] == 1 / 16
    assert "noise_T_w" in notices(lt, cfg)  # said, with the key that sets it
    cfg, log = _quiet(5.0, quantum_T=0.0)
    est, _ = _run(cfg, log)
    assert all(q == 0.0 for q in est.learnt().quantum.values())


SLOW = {"period_T_w": 0.1, "period_T_p": 0.1, "period_T_a": 0.1}


@pytest.mark.parametrize("jitter", [0.0, 0.003])
def test_a_slow_boards_pipe_noise_learnt_at_the_same_point_of_the_pump_cycle(jitter: float) -> None:
    """10 Hz boards, the pipe's 0.049 K (the emulator's default boards'), configured as 0.02 K: its
    noise learnt within 20 % of the board's from the changes between readings at the same point
    of the pump's cycle (its second differences hold the pump's kinks, its innovations the
    model's prediction), in 2 min of no touch with no false contact and the evidence's dispersion
    that of white noise. Where the pump never switches, no two readings share a point of its
    cycle, and the variance is its prior."""
    cfg, log = _quiet(120.0, noise_T_w=0.049, jitter=jitter, **SLOW)
    cfg = cfg.replace(sensor=SLOW)
    est, res = _run(cfg, log)
    true = math.sqrt(0.049**2 + (1 / 128) ** 2 / 12)
    assert est.learnt().noise["T_w"] == pytest.approx(true, rel=0.2)
    assert not res.events
    assert est.learnt().rho < 1.5  # (held at its prior: 3.7, and contacts, on the emulator's)
    assert not est.learnt().held
    still = {k: np.full_like(v, 0.0) if k == "v" else v for k, v in log.items()}
    est, _ = _run(cfg, still)
    lt = est.learnt()
    assert lt.noise["T_w"] == pytest.approx(math.sqrt(measurement_variance(cfg, "T_w")))
    assert lt.held == ("T_w",) and "as configured (not learnt" in lt.lines()[0]
    # where the evidence does not fit, the held noise is named with it, with what measures it
    assert "check" in notices(dataclasses.replace(lt, rho=10.0), cfg)["noise_T_w"]
    assert "noise_T_w" not in notices(dataclasses.replace(lt, rho=1.0), cfg)


def test_lag_learnt_is_the_beads() -> None:
    """A pipe thermocouple lagging 60 ms (none configured), learnt within 15 ms in 40 s."""
    cfg, log = _quiet(40.0, lag_T_w=0.06)
    est, res = _run(cfg, log)
    assert est.learnt().lag_w == pytest.approx(0.06, abs=0.015)
    assert not res.events


def test_dispersion_widens_what_the_detector_needs() -> None:
    """Readings whose noise is coloured (an AR(1) of 80 ms on the pipe's, twice the white noise,
    which the model takes for white): the evidence's dispersion is learnt well above 1, the
    misfit is said, and once it is learnt (the first 15 s) no contact is invented, where the
    same readings with the dispersion off give false contacts throughout. (Before it is learnt
    a false contact or two can come: a limit of learning it from the readings.)"""
    cfg, log = _quiet(120.0)
    rng = np.random.default_rng(5)
    n = len(log["t"])
    a = math.exp(-1e-3 / 0.08)
    w = rng.standard_normal(n) * 0.04 * math.sqrt(1 - a * a)
    ar = np.zeros(n)
    for k in range(1, n):
        ar[k] = a * ar[k - 1] + w[k]
    log = {**log, "T_w": log["T_w"] + ar}
    est, res = _run(cfg, log)
    assert est.learnt().rho > 3.0
    assert "misfit" in notices(est.learnt(), cfg)
    assert len(res.events) <= 3 and all(e.detected_at < 15.0 for e in res.events)
    _, off = _run(cfg.replace(detector={"rho_window": 0.0}), log)
    assert sum(e.detected_at >= 15.0 for e in off.events) >= 5


def test_before_its_windows_the_dispersion_is_its_prior() -> None:
    """Until the dispersion has windows of its own it is ``detector.rho_prior``, and the onset
    CUSUMs weigh each reading's evidence by ``rho_deadband / rho_prior`` where that is below 1:
    a CUSUM ``g <- max(0, g + w l)`` scales with ``w`` (so prior 3 gives exactly half of prior
    1's, at every sample of 10 Hz readings before the first window), and a prior within the dead
    band (1, 1.5) weighs nothing."""
    cfg, log = _quiet(8.0, period_T_w=0.1, period_T_p=0.1, period_T_a=0.1)
    cfg = cfg.replace(sensor={"period_T_w": 0.1, "period_T_p": 0.1, "period_T_a": 0.1})
    cus = {}
    for prior in (1.0, 1.5, 3.0):
        est = TouchEstimator(cfg.replace(detector={"rho_prior": prior}))
        rows = []
        for k in range(len(log["t"])):
            est.step(*(float(log[x][k]) for x in ("t", "T_w", "T_p", "v", "T_a", "T_w_cmd")),
                     int(log["fresh"][k]))
            if est.st[K.RHON] > 0:  # its first window: the prior's part ends
                break
            assert est.st[K.RHO] == prior and not est.contact
            rows.append([est.st[K.CU + 4 * j] for j in range(K.NCU)])
        cus[prior] = np.array(rows)
    assert len(cus[1.0]) > 2000  # the detector armed (from 1 s) and idle for seconds before it
    assert (cus[1.0] > 0.5).any()  # the CUSUMs moved (a no-touch log's noise)
    np.testing.assert_array_equal(cus[1.5], cus[1.0])
    np.testing.assert_allclose(cus[3.0], 0.5 * cus[1.0], rtol=1e-12, atol=1e-12)


def test_one_finger_snr() -> None:
    """The SNR: a fingertip's heat over the sd of its estimate from 0.3 s of readings."""
    assert one_finger_snr(1000.0, 20.0) == pytest.approx(0.05 * 13.0 * math.sqrt(300.0))
    assert math.isnan(one_finger_snr(0.0, 20.0))
    cfg, log = _quiet(20.0)
    est, _ = _run(cfg, log)
    assert est.learnt().snr > 5.0  # ideal 1 kHz boards: a fingertip well above the noise
    cfg, log = _quiet(20.0, noise_T=0.2)
    est, _ = _run(cfg, log)
    lt = est.learnt()
    assert lt.snr < 5.0 and "snr" in notices(lt, cfg)


def test_learnt_held_through_a_contact_and_live_equals_offline() -> None:
    """The learnt offset does not move during a contact; a sample at a time (live) and a log at
    once (offline) learn the same, bit for bit."""
    cfg = load_config()
    b = lab_boards(dataclasses.replace(cfg.sensor, seed=4))
    log = simulate(SCENARIOS["one-finger"].with_duration(25.0), cfg, boards=b)
    est, res = _run(cfg, log)
    c, bp = res.columns["contact"].astype(bool), res.columns["b_p_hat"]
    inside = np.flatnonzero(c[1:] & c[:-1]) + 1
    assert len(inside) > 1000 and np.all(bp[inside] == bp[inside - 1])
    live = TouchEstimator(cfg)
    for k in range(len(log["t"])):
        live.step(*(float(log[x][k]) for x in ("t", "T_w", "T_p", "v", "T_a", "T_w_cmd")),
                  int(log["fresh"][k]))
    assert np.array_equal(live.st, est.st, equal_nan=True) or all(
        live.st[i] == est.st[i] or (live.st[i] != live.st[i] and est.st[i] != est.st[i])
        for i in (K.RW, K.RP, K.RA, K.BD, K.PBB, K.LAGT, K.RHO, K.IRATE))
    assert live.learnt() == est.learnt()


def test_lab_boards() -> None:
    """A lab's boards: within the documented ranges, the same for a seed, others for another,
    their periods and jitter as configured."""
    s = load_config().sensor.replace if False else dataclasses.replace(
        load_config().sensor, period_T_w=0.1, jitter=0.003)
    a, b, c = lab_boards(s, 3), lab_boards(s, 3), lab_boards(s, 4)
    assert a == b and a != c
    for ch in ("T_w", "T_p", "T_a"):
        assert LAB["offset"][0] <= getattr(a, f"offset_{ch}") <= LAB["offset"][1]
        assert LAB["noise"][0] <= a.noise(ch) <= LAB["noise"][1]
        lo, hi = LAB[f"lag_{ch}"]
        assert lo <= getattr(a, f"lag_{ch}") <= hi
    assert a.quantum_T == 1 / 128 and a.period_T_w == 0.1 and a.jitter == 0.003


def test_main_job_on_a_labs_boards() -> None:
    """``thermoskin run``'s job (the fingers, from ambient) on a lab's boards (seed 0, the
    default's: the pipe's noise 0.049 K, offsets of tenths, beads of 18-30 ms): every touch,
    no false alarm, the offset learnt within 30 mK, the SNR above 5 by the end."""
    from thermoskin.analysis.evaluation import match_events
    from thermoskin.runtime.closed_loop import run_closed_loop
    from thermoskin.sim.scenarios import get_scenario

    cfg = load_config()
    b = lab_boards(cfg.sensor)
    sc = get_scenario("fingers").shifted(10.0)
    res = run_closed_loop(sc, cfg, boards=b)
    m = match_events(sc.touches, res.events)
    assert m.misses == 0 and m.false_alarms == 0
    assert np.median(m.latencies) <= 0.3


def test_learnt_before_the_start_is_the_prior() -> None:
    cfg = load_config()
    lt = learnt(K.new_state(), cfg)
    assert lt.noise["T_w"] == pytest.approx(math.sqrt(0.02**2 + (1 / 128) ** 2 / 12))
    assert lt.offset_p == 0.0 and lt.offset_p_sd == pytest.approx(0.3) and math.isnan(lt.snr)
    assert I_Q == 2 and I_TW == 0  # (the layout the learnt figures read)


@pytest.mark.parametrize("name", ["fingers", "one-finger", "persons"])
def test_a_touch_while_still_learning(name: str) -> None:
    """A log whose first touch comes 5 s in, while the slow states are still learning, through
    boards offset by 0.3, -0.2, 0.5 K (not told to the estimator): every touch, no false alarm,
    the offset still learnt within 10 mK. (Learnt from the readings between a touch's onset and
    its detection, the lag and the offset had moved and then read as heat at each pump switch:
    a flood that the hold during contacts kept.)"""
    from thermoskin.analysis.evaluation import match_events

    cfg = load_config()
    sc = SCENARIOS[name]
    assert sc.touches[0].t_on <= 5.0
    b = dataclasses.replace(cfg.sensor, offset_T_w=0.3, offset_T_p=-0.2, offset_T_a=0.5)
    log = simulate(sc, cfg, boards=b)
    est, res = _run(cfg, log)
    m = match_events(sc.touches, res.events)
    assert m.misses == 0 and m.false_alarms == 0
    assert est.learnt().offset_p == pytest.approx(-0.5, abs=0.01)


def test_slow_states_not_learnt_while_the_evidence_builds() -> None:
    """While an onset CUSUM is above a quarter of the threshold the slow states do not move (the
    readings are those of a touch not yet detected); below it, they learn."""
    cfg, log = _quiet(6.0, offset_T_p=0.2)
    est = TouchEstimator(cfg)
    n = len(log["t"])
    held = moved = 0
    for k in range(n):
        before = (est.st[K.BD], est.st[K.LAGT])
        g = max(est.st[K.CU + 4 * j] for j in range(K.NCU))
        building = est.st[K.MODE] == K.IDLE and g > 0.25 * est.st[K.HTH]
        # a contact's onset evidence, built by hand: the largest CUSUM lifted to half the threshold
        if k % 50 == 0 and est.st[K.MODE] == K.IDLE and log["t"][k] > 4.0:
            est.st[K.CU] = 0.5 * est.st[K.HTH]
            building = True
        est.step(*(float(log[x][k]) for x in ("t", "T_w", "T_p", "v", "T_a", "T_w_cmd")),
                 int(log["fresh"][k]))
        if building:
            held += 1
            assert (est.st[K.BD], est.st[K.LAGT]) == before
        elif log["t"][k] > 1.0 and (est.st[K.BD], est.st[K.LAGT]) != before:
            moved += 1
    assert held >= 10 and moved > 1000


def test_slow_states_learnt_from_fast_logs_only() -> None:
    """A 50 Hz log (1 kHz readings decimated by 20, an offset of 0.2 K on T_p): the offset is not
    learnt (its prior is 0, it stays at the configured 0); the same readings at 100 Hz learn it
    within 20 mK. Both the kernel's parameters and the reference's prior say the same, and the
    summary says the 50 Hz log's offset and lag are the configured ones, not learnt (not
    "+0.000 ± 0.000 K", as if measured exactly), with what measures them."""
    from thermoskin.estimation.reference import ReferenceEstimator
    from thermoskin.sim.conditions import decimate

    cfg, log = _quiet(40.0, offset_T_p=0.2)
    for factor, learns in ((20, False), (10, True)):
        d = decimate(log, factor)
        est = TouchEstimator(cfg, t_s=factor * cfg.sampling.t_s)
        est.run(d["t"], d["T_w"], d["T_p"], d["v"], d["T_a"], T_w_cmd=d["T_w_cmd"])
        ref = ReferenceEstimator(cfg, t_s=factor * cfg.sampling.t_s)
        lt = est.learnt()
        assert (est.pr[K.PR_PB0] > 0) == learns and bool(ref.P_B[0, 0] > 0) == learns
        said = notices(lt, cfg)
        if learns:
            assert lt.offset_p == pytest.approx(0.2, abs=0.02)
            assert "not_learnt" not in said and "(not learnt)" not in lt.lines()[1]
        else:
            assert lt.offset_p == 0.0 and lt.lag_w == 0.0
            assert "as configured (not learnt)" in lt.lines()[1] and "±" not in lt.lines()[1]
            assert "1 kHz no-touch log" in said["not_learnt"] and "offset" not in said


def test_a_slow_state_not_learnt_is_not_let_go() -> None:
    """With ``lag_sd = 0`` the lag stays at its configured value (0) on readings whose pipe
    thermocouple lags by 0.1 s, which the windows' test would otherwise take as a reason to let
    its variance go and learn it."""
    cfg0, log = _quiet(30.0, lag_T_w=0.1)
    cfg = cfg0.replace(sensor={"lag_sd": 0.0})
    est, _ = _run(cfg, log)
    assert est.st[K.LAGT] == 0.0 and est.st[K.PTT] == 0.0
    est1, _ = _run(cfg0, log)
    assert est1.learnt().lag_w > 0.05  # (learnt where it may be)
