"""A skin on 10 Hz thermocouple boards: its loops' pumps count the boards' new readings.

The pump stays stopped for ``pump.still_readings`` (2) new pipe readings (``control/pump.py``):
with 10 Hz boards about 200 ms of still water, which is what lets slow boards see a touch
(``docs/model.md``, What 10 Hz boards allow). The skin's loop passed no fresh bits to its
controllers, so every held 1 kHz sample counted as a reading and the pump stopped for one
board interval (100 ms), as the paper's rule would.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from thermoskin.params import load_config
from thermoskin.runtime.skin_loop import run_skin
from thermoskin.sim.scenarios import Scenario
from thermoskin.sim.skin_scenarios import SkinScenario
from thermoskin.skin.layout import load_skin
from thermoskin.skin.log import read_skin_log

ROOT = Path(__file__).resolve().parents[1]
BOARDS_10HZ = {"period_T_w": 0.1, "period_T_p": 0.1, "period_T_a": 0.1, "jitter": 0.003}


def test_the_skins_pump_stays_still_for_two_board_readings(tmp_path: Path) -> None:
    skin = load_skin(ROOT / "examples" / "single.toml", load_config().replace(sensor=BOARDS_10HZ))
    base = Scenario("still", "no touch", duration=6.0, T_w_cmd=24.0, T_a=20.0, pump="logic")
    run_skin(skin, SkinScenario("still", "no touch", base, ()), tmp_path / "s.csv")
    log = read_skin_log(tmp_path / "s.csv", skin)
    on = log.cols["v"][:, 0] > 0.0
    fresh_w = (log.cols["fresh"][:, 0].astype(np.int64) & 1) != 0
    edges = np.flatnonzero(np.diff(on.astype(np.int8))) + 1  # first sample of each new state
    stops = [(a, b) for a, b in itertools.pairwise(edges) if not on[a]]
    assert len(stops) >= 10  # the pump chatters around the command
    for a, b in stops:
        # the readings that came while it stood still, counted from the log's own fresh bits
        assert np.count_nonzero(fresh_w[a:b]) >= 2, (a, b)
    lengths = np.array([b - a for a, b in stops])
    assert lengths.min() >= 190  # two readings 100 +- 3 ms apart (1 ms samples)


def test_slow_boards_are_warned_about_as_measured() -> None:
    """A skin fed through pipes was clean only on 1 kHz boards, a tank-fed patch down to 200 Hz
    (benchmarks/skin_detection.py --rate): each warns under its own rate, in one line."""
    from thermoskin.skin.observe import board_warnings

    forearm = load_skin(ROOT / "examples" / "forearm.toml", load_config())
    single = load_skin(ROOT / "examples" / "single.toml", load_config())
    for skin, quiet, loud in ((forearm, (1000.0, 960.0), (900.0, 500.0, 200.0, 10.0)),
                              (single, (1000.0, 200.0, 192.0), (100.0, 50.0, 10.0))):
        for rate in quiet:
            assert board_warnings(skin, rate) == [], (skin.name, rate)
        for rate in loud:
            (w,) = board_warnings(skin, rate)
            assert f"about {rate:.0f} readings a second" in w
    assert "false alarms" in board_warnings(forearm, 100.0)[0]
    assert "missed" in board_warnings(single, 10.0)[0]
    assert board_warnings(forearm, 0.0) == []  # no rate known: nothing said
    # no boards in the config: their period was read from the log; other boards: what to set;
    # the boards the log shows: nothing more
    assert "took the boards' period, 0.1 s, from the log" in board_warnings(forearm, 10.0, 0.1)[0]
    assert "set it to 0.1 s" in board_warnings(forearm, 10.0)[0]  # the config's: every sample
    assert "period" not in board_warnings(single, 10.0, 0.1)[0]  # a tank-fed patch: not used
    ten = load_skin(ROOT / "examples" / "forearm.toml", load_config().replace(sensor=BOARDS_10HZ))
    assert "set it to 0.01 s" in board_warnings(ten, 100.0)[0]
    (w,) = board_warnings(ten, 10.0)
    assert "period_T_w" not in w


def test_the_boards_rate_is_read_from_the_log(tmp_path: Path) -> None:
    """`observe --skin` counts the new pipe readings a second from the log's fresh bits, or from
    the values' changes where a log has no bits, and warns on 10 Hz boards; `run --skin` warns
    from the config before it starts."""
    from click.testing import CliRunner

    from thermoskin.cli import main
    from thermoskin.skin.observe import observe_skin

    single = ROOT / "examples" / "single.toml"
    skin = load_skin(single, load_config().replace(sensor=BOARDS_10HZ))
    base = Scenario("still", "no touch", duration=4.0, T_w_cmd=24.0, T_a=20.0, pump="logic")
    run_skin(skin, SkinScenario("still", "no touch", base, ()), tmp_path / "s.csv")
    log = read_skin_log(tmp_path / "s.csv", skin)
    obs = observe_skin(log, skin, locate=False)
    assert 9.5 < obs.reading_rate < 10.5 and len(obs.warnings) == 1
    del log.cols["fresh"]  # held values never change: the same rate from the values
    assert 9.5 < observe_skin(log, skin, locate=False).reading_rate < 10.5
    fast = load_skin(single, load_config())
    run_skin(fast, SkinScenario("still", "no touch", base, ()), tmp_path / "f.csv")
    obs = observe_skin(read_skin_log(tmp_path / "f.csv", fast), fast, locate=False)
    assert abs(obs.reading_rate - 1000.0) < 1.0 and obs.warnings == []
    res = CliRunner().invoke(main, ["observe", "--skin", str(single), str(tmp_path / "s.csv"),
                                    "-o", str(tmp_path / "o.csv")])
    assert res.exit_code == 0, res.stderr
    assert res.stderr.count("thermoskin: warning:") == 1 and "about 10 readings a second" in res.stderr
    cfg = tmp_path / "boards.toml"
    cfg.write_text("[sensor]\nperiod_T_w = 0.1\nperiod_T_p = 0.1\nperiod_T_a = 0.1\n")
    res = CliRunner().invoke(main, ["run", "--skin", str(single), "--config", str(cfg), "--duration", "2",
                                    "--log", str(tmp_path / "r.csv")])
    assert res.exit_code == 0, res.stderr
    assert "about 10 readings a second" in res.stderr


def test_a_skin_log_without_fresh_bits_is_read_from_its_values(tmp_path: Path) -> None:
    """A lab's own logger writes no `fresh` column: the held readings of slow boards are found
    from the values (a held reading never changes), as the single patch's `observe` finds them,
    and the touch is found as with the column; at 1 kHz every sample stays a reading."""
    from thermoskin.physics.finger import Touch
    from thermoskin.sim.skin_scenarios import SkinContact
    from thermoskin.skin.observe import SkinFreshInference, observe_skin

    single = ROOT / "examples" / "single.toml"
    p = 1.0 / 200.0
    skin = load_skin(single, load_config().replace(sensor={"period_T_w": p, "period_T_p": p, "period_T_a": p,
                                                           "jitter": 0.03 * p}))
    base = Scenario("touch", "one touch", duration=12.0, T_w_cmd=24.0, T_a=20.0, pump="logic")
    touch = Touch(t_on=7.0, duration=2.0, n_fingers=2, person="man1")
    contact = SkinContact(touch, patch="patch", position=0.015)
    run_skin(skin, SkinScenario("touch", "one touch", base, (contact,)), tmp_path / "s.csv")
    log = read_skin_log(tmp_path / "s.csv", skin)
    for k in ("q_i", "contact_true", "position_true"):
        log.cols.pop(k)
    bits = log.cols["fresh"].astype(np.int64)
    inferred = SkinFreshInference(skin).feed({k: v for k, v in log.cols.items() if k != "fresh"})
    assert inferred is not None
    for bit in (1, 2, 4):  # a changed value is a reading; a reading equal to the last is missed
        true, got = (bits & bit) != 0, (inferred & bit) != 0
        assert not (got & ~true)[1:].any()
        assert got.sum() >= 0.8 * true.sum()
    no_bits = {k: v for k, v in log.cols.items() if k != "fresh"}
    for cuts in ([1, 2, 30], [63, 1], [64], [500, 7]):  # the bits do not depend on the blocks
        inf, parts, k = SkinFreshInference(skin), [], 0
        for m in [*cuts, len(log.t)]:
            parts.append(inf.feed({c: v[k:k + m] for c, v in no_bits.items()}))
            k += m
        assert np.array_equal(np.concatenate(parts), inferred)
    with_bits = observe_skin(log, skin, locate=False)
    del log.cols["fresh"]
    without = observe_skin(log, skin, locate=False)
    for obs in (with_bits, without):
        events = obs.events
        assert len(events) == 1 and 7.0 <= events[0].event.detected_at <= 9.0, events
        # 200 Hz boards, read as such (a reading equal to the last, missed without bits, does not
        # lower it), and no warning for a tank-fed patch, clean at that rate
        assert abs(obs.reading_rate - 200.0) < 2.0 and obs.warnings == [], obs.reading_rate
    fast = load_skin(single, load_config())
    run_skin(fast, SkinScenario("still", "no touch", base, ()), tmp_path / "f.csv")
    cols = read_skin_log(tmp_path / "f.csv", fast).cols
    bits = SkinFreshInference(fast).feed({k: v for k, v in cols.items() if k != "fresh"})
    assert ((bits[SkinFreshInference.DECIDE_ROWS:] & 7) == 7).all()  # 1 kHz: every sample a reading


def test_flow_noise_only_while_the_pump_runs() -> None:
    """``estimator.S_w_flow`` adds process noise on the pipe node in the pumping rows only: the
    added covariance is ``int_0^t_s e^{As} dS e^{A's} ds``, here by quadrature (scipy's
    ``quad_vec``) against the tables' Van Loan block exponential; the still rows are unchanged."""
    from scipy.integrate import quad_vec
    from scipy.linalg import expm

    from thermoskin.estimation.model import I_TW, R_w_of, build_tables, patch_matrices

    cfg = load_config()
    x = 0.3
    t_s = cfg.sampling.t_s
    v_on = cfg.pump.v_on
    base = build_tables(cfg, t_s, (0.0, v_on))
    flow = build_tables(cfg.replace(estimator={"S_w_flow": x}), t_s, (0.0, v_on))
    for Q0, Q1 in ((base.Q, flow.Q), (base.Q_idle, flow.Q_idle)):
        np.testing.assert_array_equal(Q1[0], Q0[0])  # the pump stands still: nothing comes in
        A = patch_matrices(cfg, R_w_of(v_on, cfg.skin))[0]
        dS = np.zeros_like(A)
        dS[I_TW, I_TW] = x
        want = quad_vec(lambda s, A=A, dS=dS: expm(A * s) @ dS @ expm(A * s).T, 0.0, t_s, epsabs=1e-16)[0]
        np.testing.assert_allclose(Q1[1] - Q0[1], want, rtol=1e-6, atol=1e-15)
        assert want[I_TW, I_TW] > 0.9 * x * t_s
    np.testing.assert_array_equal(flow.Phi, base.Phi)


def test_a_skin_lets_its_pipe_node_go_by_its_boards_period() -> None:
    """A skin patch fed through a pipe has ``S_w_flow`` = ``FLOW_NOISE * period^1.5`` of its
    boards (0 for boards read every sample), a patch fed from its tank none; a larger value the
    user's config sets is kept."""
    from thermoskin.skin.observe import FLOW_NOISE, patch_config

    path = ROOT / "examples" / "forearm.toml"
    every = load_skin(path)
    slow = load_skin(path, every.cfg.replace(sensor=BOARDS_10HZ))
    mine = load_skin(path, every.cfg.replace(sensor=BOARDS_10HZ, estimator={"S_w_flow": 5.0}))
    loop_rate = load_skin(path, every.cfg.replace(sensor={"period_T_w": 0.001, "period_T_p": 0.001}))
    tank_slow = load_skin(path, every.cfg.replace(sensor={"period_T_p": 0.1}))  # the tank's board only
    firsts = {lp.patches[0] for lp in every.loops}
    for i in range(len(every.patches)):
        assert patch_config(every, i).estimator.S_w_flow == 0.0
        assert patch_config(loop_rate, i).estimator.S_w_flow == 0.0  # read every sample: none
        assert patch_config(slow, i).estimator.S_w_flow == FLOW_NOISE * 0.1**1.5
        assert patch_config(mine, i).estimator.S_w_flow == 5.0
        # the board that reads the patch's inlet: the tank's for the first patch of a loop
        assert (patch_config(tank_slow, i).estimator.S_w_flow > 0.0) == (i in firsts)
        assert patch_config(every, i, 0.1).estimator.S_w_flow == FLOW_NOISE * 0.1**1.5
    with pytest.raises(ValueError, match="boards_period"):
        patch_config(every, 1, -0.1)
    assert load_config().estimator.S_w_flow == 0.0  # the paper's single patch: unchanged
    single = load_skin(ROOT / "examples" / "single.toml", load_config().replace(sensor=BOARDS_10HZ))
    assert patch_config(single, 0).estimator.S_w_flow == 0.0  # fed from its tank


def test_observe_takes_the_boards_period_from_the_log(tmp_path: Path) -> None:
    """`observe --skin` with a config that gives no boards reads their period from the log (10 Hz
    boards with 3 ms of jitter: 0.1 s) and models them as the run did with the config that gave
    them: the same contacts on the same patches, detected at the same readings."""
    from thermoskin.physics.finger import Touch
    from thermoskin.sim.skin_scenarios import SkinContact
    from thermoskin.skin.observe import log_boards_period, observe_skin

    path = ROOT / "examples" / "forearm.toml"
    skin10 = load_skin(path, load_config().replace(sensor=BOARDS_10HZ))
    skin0 = load_skin(path, load_config())
    base = Scenario("touch", "two touches", duration=24.0, T_w_cmd=24.0, T_a=20.0, pump="logic")
    contacts = tuple(SkinContact(Touch(t_on=t, duration=2.5, n_fingers=3, person="man1"), patch=name,
                                 position=0.015) for t, name in ((12.0, "dorsal2"), (18.0, "ventral2")))
    run_skin(skin10, SkinScenario("touch", "two touches", base, contacts), tmp_path / "s.parquet")
    log = read_skin_log(tmp_path / "s.parquet", skin10)
    period = log_boards_period(log, skin0, log.t_s)
    assert period is not None and abs(period - 0.1) < 0.003
    assert log_boards_period(log, skin10, log.t_s) is None  # the config's, as the live loop took it
    a = observe_skin(log, skin10, locate=False)
    b = observe_skin(log, skin0, locate=False)
    assert a.events and [(e.name, e.event.detected_at) for e in a.events] == \
        [(e.name, e.event.detected_at) for e in b.events]
    assert "from the log" in b.warnings[0]
