"""Calibration of the skin's network: model against the simulator, statistics, recovery, CLI.

The logs are simulated with a skin that is not the preset (C_w 0.2, R_g 8, R_ag 1.3,
R_w_flowing 0.25, R_w_stopped 40) and the fit starts from the preset (R_g 10, R_w from
eq. 1: 0.19 and 57 K/W). ``C_w`` holds the heat scale, so the prior gets the true
``C_w``; where a test needs the sheet held at the truth, the prior gets ``R_ag`` too.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from thermoskin.cli import main
from thermoskin.fit import calibrate as cal
from thermoskin.logio import write_log
from thermoskin.params import Config, load_config
from thermoskin.physics.network import discretize, state_space
from thermoskin.sim.run import simulate
from thermoskin.sim.scenarios import Scenario, step_schedule

TRUE_SKIN = {"C_w": 0.2, "R_g": 8.0, "R_ag": 1.3, "R_w_flowing": 0.25, "R_w_stopped": 40.0}
TRUE = {"C_g": 0.0124, "R_g": 8.0, "R_aw": 2100.0, "R_ag": 1.3, "R_w_flowing": 0.25, "R_w_stopped": 40.0}
IDENTIFIABLE = ("R_g", "R_w_flowing", "R_w_stopped")
PRIOR = Config().replace(skin={"C_w": 0.2})              # the heat scale known, the rest the preset
PRIOR_SHEET = Config().replace(skin={"C_w": 0.2, "R_ag": 1.3})  # ... and the sheet's split


def steps(duration: float, seed: int) -> Scenario:
    """No touch, commands stepping every 5 s: long pump-on and pump-off stretches."""
    return Scenario("steps", "", duration, setpoints=step_schedule(duration, seed=seed))


def log_of(sc: Scenario, seed: int = 0, **sensor: float) -> dict[str, np.ndarray]:
    return simulate(sc, Config().replace(skin=TRUE_SKIN, sensor={"seed": seed, **sensor}))


@pytest.fixture(scope="module")
def log60() -> dict[str, np.ndarray]:
    return log_of(steps(60.0, 101), seed=1)


# ---------------------------------------------------------------------------- the model
@pytest.mark.parametrize("R_w", [0.25, 40.0])
def test_block_tables_are_powers_and_sums_of_the_zoh_step(R_w):
    """Sylvester's closed form against scipy's matrix exponential, stepped and summed by hand."""
    skin = dataclasses.replace(PRIOR.skin, **{k: v for k, v in TRUE_SKIN.items() if not k.startswith("R_w")})
    A, B = state_space(skin, R_w)
    B = B[:, :2]
    tab = cal.block_tables(A, B, 1e-3, 12)
    Phi, Gam = discretize(A, B, 1e-3)
    x_rows, u_rows = [np.eye(2)], [np.zeros((2, 2))]  # x_i = Phi^i x_0 + S_i u
    for _ in range(12):
        x_rows.append(Phi @ x_rows[-1])
        u_rows.append(Phi @ u_rows[-1] + Gam)
    for n in range(1, 13):
        np.testing.assert_allclose(tab[n, 0:4], x_rows[n].ravel(), atol=1e-13)
        np.testing.assert_allclose(tab[n, 4:8], u_rows[n].ravel(), atol=1e-13)
        np.testing.assert_allclose(tab[n, 8:10], np.mean(x_rows[:n], axis=0)[0], atol=1e-13)
        np.testing.assert_allclose(tab[n, 10:12], np.mean(u_rows[:n], axis=0)[0], atol=1e-13)


def test_prediction_is_the_simulated_skin_at_the_true_parameters():
    """Noise-free log of the simulator (its own closed-form ZOH, sample by sample): at the true
    parameters the block means are reproduced exactly where the inputs are constant (T_p, T_a
    fixed, the pump chattering); where the tank ramps (0.3 K/s) a block's mean input misses its
    slope by r h^2 / (12 tau) ~ 50 µK (h = 10 ms, tau = 50 ms), far below the noise."""
    for sc, tol in ((Scenario("none", "", 5.0), 1e-9), (steps(10.0, 3), 1e-4)):
        log = log_of(sc, noise_T=0.0, quantum_T=0.0)
        t_s = 1e-3
        blocks = cal.make_blocks(log, t_s, cal.usable_rows(log, t_s), t_fit=0.01)
        assert blocks.m == 10
        e = cal.residuals(blocks, TRUE, PRIOR) / np.sqrt(blocks.nlen)
        assert np.max(np.abs(e)) < tol
        # and a wrong parameter is seen
        assert np.max(np.abs(cal.residuals(blocks, {**TRUE, "R_w_flowing": 0.3}, PRIOR))) > 1e-3


def test_blocks_never_straddle_a_pump_switch_and_cover_the_usable_rows(log60):
    t_s = 1e-3
    usable = cal.usable_rows(log60, t_s)
    usable[20_000:20_500] = False  # a gap
    b = cal.make_blocks(log60, t_s, usable, t_fit=0.01)
    covered = np.zeros(usable.size, dtype=bool)
    for f, n in zip(b.first, b.nlen, strict=True):
        assert not covered[f:f + n].any()
        covered[f:f + n] = True
        assert np.unique(log60["v"][f:f + n]).size == 1
        assert n <= b.m
    assert np.array_equal(covered, usable)
    assert b.w0.size == 2 and b.start.sum() == 2


def test_centred_mean_leaves_a_line_and_averages_noise():
    x = 3.0 + 0.5 * np.arange(1000)
    np.testing.assert_allclose(cal.centred_mean(x, [(0, 1000)], 20), x, rtol=0, atol=1e-9)
    noise = np.random.default_rng(0).standard_normal(100_000)
    sm = cal.centred_mean(noise, [(0, 100_000)], 50)
    assert abs(np.std(sm[100:-100]) - 1 / math.sqrt(101)) < 0.01


# ---------------------------------------------------------------------------- statistics
@pytest.mark.parametrize("phi", [0.0, 0.5, 0.8])
def test_autocorrelation_time_of_an_ar1(phi):
    """tau = (1 + phi)/(1 - phi) for x_k = phi x_{k-1} + w_k."""
    rng = np.random.default_rng(1)
    w = rng.standard_normal(200_000)
    x = np.empty_like(w)
    x[0] = w[0]
    for k in range(1, w.size):
        x[k] = phi * x[k - 1] + w[k]
    assert cal.autocorrelation_time(x) == pytest.approx((1 + phi) / (1 - phi), rel=0.08)


def test_input_noise_of_quantised_readings():
    """sd of white noise read in 1/128 K steps: sqrt(sigma^2 + q^2/12) (Sheppard), on a slow ramp."""
    rng = np.random.default_rng(2)
    n, q = 50_000, 1 / 128
    x = np.round((24.0 + 0.3e-3 * np.arange(n) + 0.02 * rng.standard_normal(n)) / q) * q
    log = {"t": np.arange(n) * 1e-3, "T_w": x, "T_p": x, "T_a": x, "v": np.zeros(n)}
    b = cal.make_blocks(log, 1e-3, np.ones(n, dtype=bool))
    assert cal.input_noise(x, b) == pytest.approx(math.sqrt(0.02**2 + q**2 / 12), rel=0.03)


def test_the_heat_scale_is_not_in_the_temperatures():
    """Every C times k and every R over k: the simulator's T_w is the same to rounding."""
    k = 1.7
    sc = steps(8.0, 4)
    base = Config().replace(skin=TRUE_SKIN, sensor={"noise_T": 0.0, "quantum_T": 0.0})
    sk = base.skin
    scaled = base.replace(skin={"C_w": sk.C_w * k, "C_g": sk.C_g * k, "R_g": sk.R_g / k,
                                "R_aw": sk.R_aw / k, "R_ag": sk.R_ag / k,
                                "R_w_flowing": 0.25 / k, "R_w_stopped": 40.0 / k})
    a, b = simulate(sc, base)["T_w"], simulate(sc, scaled)["T_w"]
    assert np.max(np.abs(a - b)) < 1e-9
    with pytest.raises(cal.CalibrationError, match="common scale of heat"):
        cal.calibrate(simulate(sc, base), PRIOR, cal.PARAMS)


def test_a_wrong_heat_scale_scales_every_fitted_resistance(log60):
    """C_w held at 2/3 of the truth: the fit finds every R at 3/2 of the truth (same time
    constants), within its interval."""
    k = 2 / 3
    res = cal.calibrate(log60, Config().replace(skin={"C_w": 0.2 * k, "R_ag": 1.3 / k, "C_g": 0.0124 * k}),
                        IDENTIFIABLE)
    for p in IDENTIFIABLE:
        lo, hi = res.interval(p)
        assert lo <= TRUE[p] / k <= hi, (p, res.estimate[p], lo, hi)


# ---------------------------------------------------------------------------- recovery
def test_recovery_and_coverage_over_seeds():
    """Each identifiable parameter within its 95 % interval; |z| below 4 always, coverage of
    at least 10/12 (nominal 95 %; benchmarks/calibrate.py measures it over more seeds)."""
    inside, zs = 0, []
    for seed in range(4):
        res = cal.calibrate(log_of(steps(40.0, 200 + seed), seed=seed), PRIOR_SHEET, IDENTIFIABLE)
        assert res.names == IDENTIFIABLE and not res.held
        for p in IDENTIFIABLE:
            lo, hi = res.interval(p)
            inside += lo <= TRUE[p] <= hi
            zs.append((math.log(res.estimate[p]) - math.log(TRUE[p])) / res.sd_log[p])
            assert res.estimate[p] == pytest.approx(TRUE[p], rel=0.05)
        assert res.sigma == pytest.approx(0.02, rel=0.15)  # the sensor's noise, 1/128 K quanta
    assert inside >= 10
    assert max(abs(z) for z in zs) < 4.0


def test_intervals_shrink_with_a_longer_log():
    """The same 30 s experiment four times over: half the interval (in ln p), within scatter."""
    one = step_schedule(30.0, seed=7)
    four = tuple((t + 30.0 * r, c) for r in range(4) for t, c in one)
    short = cal.calibrate(log_of(Scenario("x", "", 30.0, setpoints=one), seed=3), PRIOR_SHEET, IDENTIFIABLE)
    long = cal.calibrate(log_of(Scenario("x", "", 120.0, setpoints=four), seed=3), PRIOR_SHEET, IDENTIFIABLE)
    for p in IDENTIFIABLE:
        ratio = short.sd_log[p] / long.sd_log[p]
        assert 1.5 < ratio < 2.7, (p, ratio)


def test_what_the_log_cannot_determine_is_held_and_said(log60):
    """Default parameters: R_aw is an exact trade-off at a constant ambient; the sheet is too
    fast to be seen; both held at the prior, said so; R_w fitted. The elasticity reported for
    R_g on a held parameter predicts how R_g moves when that parameter is set to the truth."""
    res = cal.calibrate(log60, PRIOR)
    assert res.held["R_aw"].startswith("not determined by this log: the fit does not change")
    assert "C_g" in res.held and res.estimate["C_g"] == PRIOR.skin.C_g
    for p in ("R_w_flowing", "R_w_stopped", "R_g"):
        assert p in res.names
    assert res.status("R_aw") == "held: not determined"
    assert res.config.skin.R_aw == PRIOR.skin.R_aw
    held_sheet = [q for q in ("R_ag", "C_g") if q in res.held and q in res.dependence.get("R_g", {})]
    assert held_sheet
    q = held_sheet[0]
    refit = cal.calibrate(log60, PRIOR.replace(skin={q: TRUE[q]}), [p for p in res.names])
    moved = math.log(refit.estimate["R_g"] / res.estimate["R_g"])
    predicted = res.dependence["R_g"][q] * math.log(TRUE[q] / res.estimate[q])
    assert moved == pytest.approx(predicted, rel=0.3, abs=0.003)


def test_sample_residuals_are_not_biased_by_the_pump_deciding_on_them():
    """The pump logic switches on the measured T_w it is fitted to. Fitted sample by sample the
    chattering log gives R_g and R_w_flowing within about 2 sd; 10 ms block means mix each
    reading with the response to the switch it caused and come out more than 1.2 sd high."""
    prior = PRIOR_SHEET.replace(skin={"R_w_stopped": 40.0})
    for seed in range(2):
        log = log_of(Scenario("none", "", 40.0), seed=seed)
        for t_fit, lo, hi in ((0.0, -2.2, 2.2), (0.01, 1.2, 6.0)):
            res = cal.calibrate(log, prior, ("R_g", "R_w_flowing"), t_fit=t_fit)
            for p in res.names:
                z = (math.log(res.estimate[p]) - math.log(TRUE[p])) / res.sd_log[p]
                assert lo < z < hi, (seed, t_fit, p, z)


def test_a_pump_that_never_stops_leaves_R_w_stopped_at_its_prior():
    log = log_of(Scenario("on", "", 8.0, pump="on", T_p_drift=1.0, T_p_period=4.0))
    res = cal.calibrate(log, PRIOR_SHEET, IDENTIFIABLE)
    assert res.held["R_w_stopped"].startswith("the pump never stops")
    assert res.estimate["R_w_stopped"] == res.prior_values["R_w_stopped"]
    assert res.config.skin.R_w_stopped is None  # as the prior had it: eq. 1
    assert res.estimate["R_w_flowing"] == pytest.approx(0.25, rel=0.02)


def test_a_touch_log_is_fitted_on_its_no_touch_stretches():
    """Touches every few seconds: with the contact column their rows are left out and the fit
    recovers the skin; without it the touch heat biases it far outside its intervals."""
    from thermoskin.physics.finger import Touch

    touches = tuple(Touch(t_on=t, duration=2.0, n_fingers=3, person="man1") for t in (6.0, 16.0, 26.0, 36.0))
    sc = Scenario("touch", "", 45.0, setpoints=step_schedule(45.0, seed=11), touches=touches)
    log = log_of(sc, seed=5)
    log["contact"] = log["contact_true"].astype(float)
    res = cal.calibrate(log, PRIOR_SHEET, IDENTIFIABLE)
    assert res.n_stretches == 5
    for p in IDENTIFIABLE:
        lo, hi = res.interval(p)
        assert lo <= TRUE[p] <= hi, (p, res.estimate[p], lo, hi)
    blind = cal.calibrate(log, PRIOR_SHEET, IDENTIFIABLE, contact=np.zeros_like(log["t"]))
    assert blind.rms > 5 * res.rms
    assert any(not blind.low[p] <= TRUE[p] <= blind.high[p] for p in IDENTIFIABLE)


@pytest.mark.parametrize(("edit", "match"), [
    (lambda lg: lg.pop("T_p"), "no column T_p"),
    (lambda lg: lg.__setitem__("t", lg["t"] * np.r_[np.ones(3000), np.full(lg["t"].size - 3000, 1.5)]),
     "not uniformly sampled"),
    (lambda lg: lg.__setitem__("v", -lg["v"]), "must be >= 0"),
    (lambda lg: lg.__setitem__("T_w", np.where(lg["t"] > 3.0, np.nan, lg["T_w"])), "too short"),
])
def test_bad_logs_raise_one_line(edit, match):
    log = dict(log_of(steps(8.0, 1)))
    edit(log)
    with pytest.raises(cal.CalibrationError, match=match) as e:
        cal.calibrate(log, PRIOR_SHEET, IDENTIFIABLE)
    assert "\n" not in str(e.value)


# ---------------------------------------------------------------------------- command line
def invoke(*args: str) -> tuple[int, str, str]:
    res = CliRunner().invoke(main, list(args))
    return res.exit_code, res.stdout, res.stderr


def test_cli_writes_a_loadable_config_and_a_figure(tmp_path: Path):
    log_path = tmp_path / "log.csv"
    write_log(log_path, log_of(steps(20.0, 9), seed=2))
    skin = tmp_path / "params.toml"
    skin.write_text("[skin]\nC_w = 0.2\nR_ag = 1.3\n")
    truth = tmp_path / "true.toml"
    truth.write_text("[skin]\n" + "".join(f"{k} = {v}\n" for k, v in TRUE_SKIN.items()))
    out = tmp_path / "fitted.toml"
    code, stdout, stderr = invoke("calibrate", str(log_path), "--config", str(skin), "--params",
                                  "R_g,R_w_flowing,R_w_stopped", "--truth", str(truth), "-o", str(out))
    assert code == 0, stderr
    fitted = load_config(out)
    assert fitted.skin.C_w == 0.2 and fitted.skin.R_ag == 1.3
    for p in IDENTIFIABLE:
        assert getattr(fitted.skin, p) == pytest.approx(TRUE[p], rel=0.03)
    text = out.read_text()
    assert "R_w_stopped = " in text and "95 % interval [" in text
    png = out.with_suffix(".png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "true" in stdout and "R_w_flowing" in stdout and f"wrote {out}" in stdout


@pytest.mark.parametrize(("args", "match"), [
    (("--params", "C_w,C_g,R_g,R_aw,R_ag,R_w_flowing,R_w_stopped"), "common scale of heat"),
    (("--params", "R_x"), "unknown parameter"),
    (("--contact-column", "touching"), "no such column"),
])
def test_cli_bad_requests_give_one_line_and_exit_2(tmp_path: Path, args, match):
    log_path = tmp_path / "log.csv"
    write_log(log_path, log_of(steps(6.0, 1)))
    code, _, stderr = invoke("calibrate", str(log_path), "-o", str(tmp_path / "f.toml"), *args)
    assert code == 2
    assert stderr.count("\n") == 1 and stderr.startswith("thermoskin: error:") and match in stderr


def test_cli_bad_logs_give_one_line_and_exit_2(tmp_path: Path):
    short = tmp_path / "short.csv"
    write_log(short, log_of(steps(3.0, 1)))
    missing = tmp_path / "missing.csv"
    lg = log_of(steps(6.0, 1))
    write_log(missing, {k: v for k, v in lg.items() if k != "T_a"})
    for path, match in ((short, "too short"), (missing, "T_a"), (tmp_path / "nope.csv", "nope.csv")):
        code, _, stderr = invoke("calibrate", str(path), "-o", str(tmp_path / "f.toml"))
        assert code == 2, stderr
        assert stderr.count("\n") == 1 and match in stderr
