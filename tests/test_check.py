"""``thermoskin check``: a log's sensors and the configured skin, against what the simulator was
given (boards set here in full, offsets added to the logged readings: an independent truth)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from thermoskin.cli import main
from thermoskin.fit import check as chk
from thermoskin.logio import write_log
from thermoskin.params import Config, load_config
from thermoskin.physics.network import state_space
from thermoskin.sim.run import simulate
from thermoskin.sim.scenarios import Scenario, step_schedule

TRUE_SKIN = {"C_w": 0.134, "R_g": 8.0, "R_ag": 1.3, "R_w_flowing": 0.25, "R_w_stopped": 40.0}
BOARDS = {"noise_T": 0.02, "quantum_T": 1 / 128, "period_T_w": 0.0, "period_T_p": 0.0, "period_T_a": 0.0,
          "jitter": 0.0, "lag_T_w": 0.0, "lag_T_p": 0.0, "lag_T_a": 0.0, "offset_T_w": 0.0,
          "offset_T_p": 0.0, "offset_T_a": 0.0}
OFFSETS = {"T_w": 0.3, "T_p": -0.2, "T_a": 0.5}
COLS = ("t", "T_w", "T_p", "v", "T_a", "T_w_cmd", "fresh")


def log_of(duration: float, seed: int, offsets: dict[str, float] | None = None, **sensor: float) -> dict:
    sc = Scenario("calibration", "", duration, setpoints=step_schedule(duration, seed=seed))
    log = simulate(sc, Config().replace(skin=TRUE_SKIN, sensor={**BOARDS, "seed": seed, **sensor}))
    for ch, b in (offsets or {}).items():
        log[ch] = log[ch] + b
    return {k: log[k] for k in COLS}


@pytest.fixture(scope="module")
def slow() -> dict:
    """120 s of 10 Hz boards (5 ms of jitter), a 0.1 s pipe sensor, offsets."""
    return log_of(120.0, 3, OFFSETS, period_T_w=0.1, period_T_p=0.1, period_T_a=0.1, jitter=0.005,
                  lag_T_w=0.1)


def test_period_and_quantum_of_readings():
    """The period from the fresh bits and, without them, from the changes of a held value."""
    t_s = 1e-3
    k = np.arange(20_000)
    fresh = (k % 100) == 0
    x = (24.0 + 0.02 * np.random.default_rng(1).standard_normal(k.size))[(k // 100) * 100]
    assert chk.period_of(x, t_s, fresh)[:2] == (pytest.approx(0.1), pytest.approx(0.0))
    period, _, src = chk.period_of(x, t_s, None)
    assert period == pytest.approx(0.1) and src == "value changes"
    assert chk.period_of(24.0 + 0.02 * np.random.default_rng(2).standard_normal(5000), t_s, None)[0] == 0.0


def test_touch_heat_is_the_sheets_balance():
    """A fingertip's heat against the network's steady state: the sheet node with the touch as a
    conductance to a body, solved as a linear system (physics.network's matrices)."""
    cfg = Config().replace(skin=TRUE_SKIN)
    T_w, T_a = 24.0, 20.0
    q = chk.touch_heat(T_w, T_a, cfg)
    sk = cfg.skin
    # sheet balance with the pipe held: (T_w - T_g)/R_g + G (T_f - T_g) - (T_g - T_a)/R_ag = 0
    A = np.array([[-(1 / sk.R_g + 1 / sk.R_ag + chk.FINGER_G)]])
    T_g = float(np.linalg.solve(A, [-(T_w / sk.R_g + T_a / sk.R_ag + chk.FINGER_G * chk.FINGER_T)])[0])
    assert q == pytest.approx(chk.FINGER_G * (chk.FINGER_T - T_g), rel=1e-12)
    # how much it moves the pipe, the pump running: the network's steady state, by hand
    A2, B2 = state_space(sk, 0.25)
    dx = np.linalg.solve(A2, -B2[:, 2] * q)
    assert chk.touch_step(cfg, 0.25, q) == pytest.approx(dx[0], rel=1e-12)


def test_check_finds_the_boards_and_says_what_to_set(slow, tmp_path: Path):
    """10 Hz boards: the period from the fresh column, the 1/128 K step, the noise (the model's
    residual: the pipe zigzags between readings), the offsets relative to T_w's within 0.03 K,
    the pipe sensor's lag within 20 %; the advice sets them, and --write-config writes a
    config that loads with them."""
    rep = chk.check(slow, Config())
    for ch, c in rep.channels.items():
        assert c.period == pytest.approx(0.1, abs=0.002) and c.period_from == "fresh column"
        assert c.quantum == pytest.approx(1 / 128, rel=1e-6)
        assert c.noise == pytest.approx(0.02, rel=0.25), ch
    for ch in ("T_p", "T_a"):
        assert rep.found[f"offset_{ch}"] == pytest.approx(OFFSETS[ch] - OFFSETS["T_w"], abs=0.03)
    assert rep.found["lag_T_w"] == pytest.approx(0.1, rel=0.2)
    assert rep.found["period_T_w"] == pytest.approx(0.1, abs=0.002)
    text = " ".join(rep.advice)
    assert "set in [sensor]" in text and "offset_T_p" in text and "lag_T_w" in text
    assert "calibrate" in text  # the preset's skin is not this one
    assert rep.snr_found > rep.snr_now
    out = chk.save(rep, Config(), tmp_path / "found.toml", source="slow")
    cfg = load_config(out)
    assert cfg.sensor.offset_T_p == pytest.approx(rep.found["offset_T_p"])
    assert cfg.sensor.period_T_a == pytest.approx(rep.found["period_T_a"])
    assert cfg.sensor.lag_T_w == pytest.approx(rep.found["lag_T_w"])
    # each board's noise its own, over a configured per-channel one (which noise_T alone left)
    cfg = load_config(chk.save(rep, Config().replace(sensor={"noise_T_w": 0.3}), tmp_path / "f2.toml",
                               source="slow"))
    for ch, c in rep.channels.items():
        assert cfg.sensor.noise(ch) == pytest.approx(c.noise), ch


def test_nothing_to_do_when_the_configuration_is_the_truth():
    """The configuration the simulator was given, offsets included: nothing to set, nothing
    to calibrate, the SNR of a finger well above 5."""
    log = log_of(90.0, 5)
    truth = Config().replace(skin=TRUE_SKIN, sensor=BOARDS)
    rep = chk.check(log, truth)
    assert rep.advice == ["nothing to do: the configuration fits these readings"], rep.advice
    assert rep.snr_now > chk.SNR_MIN
    assert rep.fits[0].rms == pytest.approx(0.02, rel=0.3)  # the readings' noise, per reading


def test_a_coarse_converter_is_said_to_be_below_a_touch():
    """A 0.25 K converter at 10 Hz with 20 mK of noise (a MAX31855): the step found, and the
    advice says a one-finger touch is below what the readings resolve."""
    log = log_of(60.0, 2, quantum_T=0.25, period_T_w=0.1, period_T_p=0.1, period_T_a=0.1)
    rep = chk.check(log, Config().replace(skin=TRUE_SKIN))
    assert rep.channels["T_w"].quantum == pytest.approx(0.25)
    assert rep.touch_step < 0.125
    assert any("below what these readings resolve" in a for a in rep.advice)


def test_cli_check_prints_and_writes(slow, tmp_path: Path):
    path = tmp_path / "slow.csv"
    write_log(path, slow)
    out = tmp_path / "found.toml"
    res = CliRunner().invoke(main, ["check", str(path), "--write-config", str(out)])
    assert res.exit_code == 0, res.stderr
    assert "Next:" in res.stdout and "offset" in res.stdout and f"wrote {out}" in res.stdout
    assert math.isclose(load_config(out).sensor.period_T_w, 0.1, abs_tol=0.002)


@pytest.mark.parametrize(("args", "match"), [
    (("--write-config", "x.csv"), ".toml"),
    (("--contact-column", "touching"), "no such column"),
    (("--config", "nope.toml"), "nope.toml"),
])
def test_cli_check_bad_requests_one_line_exit_2(tmp_path: Path, args, match):
    path = tmp_path / "log.csv"
    write_log(path, log_of(8.0, 1))
    args = tuple(str(tmp_path / a) if a.endswith(".toml") else a for a in args)
    res = CliRunner().invoke(main, ["check", str(path), *args])
    assert res.exit_code == 2
    assert res.stderr.count("\n") == 1 and res.stderr.startswith("thermoskin: error:") and match in res.stderr


def test_cli_check_of_a_short_or_missing_log(tmp_path: Path):
    short = tmp_path / "short.csv"
    write_log(short, log_of(3.0, 1))
    for path, match in ((short, "too short"), (tmp_path / "nope.csv", "nope.csv")):
        res = CliRunner().invoke(main, ["check", str(path)])
        assert res.exit_code == 2 and match in res.stderr and res.stderr.count("\n") == 1


def test_a_log_with_touches_and_no_contact_column():
    """A lab's log of touches and doors (the ``ambient-step`` condition, 120 s: a door at 33.4 s,
    touches every 8-12 s) through an air sensor lagging 3 s, no contact column: checked as it is,
    the touches read as the skin's misfit (the air's offset fitted beyond 1 K, the residual
    several times the noise); without the contacts the estimator finds, the residual is the
    noise's and the air's lag is found (within 10 %), the log's own air offset none."""
    from thermoskin.sim.conditions import get_condition

    sc = get_condition("ambient-step", 4242).scenario.with_duration(120.0)
    log = simulate(sc, Config().replace(sensor={**BOARDS, "lag_T_a": 3.0, "seed": 5}))
    log = {k: log[k] for k in COLS}
    plain = chk._check(log, Config(), None, "")
    assert abs(plain.found.get("offset_T_a", 0.0)) > 1.0 or plain.fits[-1].rms > 3 * 0.02
    rep = chk.check(log, Config())
    assert "estimator" in rep.contacts_from and 5.0 < rep.contact_s < 60.0
    assert rep.fits[-1].rms < 1.5 * 0.02
    assert rep.found["lag_T_a"] == pytest.approx(3.0, rel=0.1)
    assert abs(rep.found.get("offset_T_a", 0.0)) < 0.05
