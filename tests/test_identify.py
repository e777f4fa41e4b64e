"""ARX identification: recovery of a synthetic ARX system, orders, the Peltier log, errors, TOML."""

from __future__ import annotations

import re

import numpy as np
import pytest
from scipy.signal import lfilter

from thermoskin.fit.identify import ArxModel, IdentifyError, identify, load_model, save_model
from thermoskin.logio import write_log
from thermoskin.params import Config
from thermoskin.sim.excitation import simulate_excitation

A_TRUE = np.array([-1.5, 0.7])
B_TRUE = np.array([0.4, 0.25])
C_TRUE = 0.3


def synthetic(n: int = 4000, noise: float = 0.02, seed: int = 0):
    """y = B/A u + (c + e)/A with nk = 2, simulated with scipy.signal.lfilter."""
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.choice([-1.0, 0.0, 1.0], n // 5), 5)
    e = noise * rng.standard_normal(n)
    num = np.r_[0.0, 0.0, B_TRUE]
    den = np.r_[1.0, A_TRUE]
    y = lfilter(num, den, u) + lfilter([1.0], den, C_TRUE + e)
    return {"t": np.arange(n) * 1.0, "T_p": y, "drive": u}


def test_recovers_synthetic_arx():
    m = identify(synthetic(), t_model=1.0, nk_max=3)
    assert (m.na, m.nb, m.nk) == (2, 2, 2)
    assert m.a == pytest.approx(A_TRUE, abs=0.01)
    assert m.b == pytest.approx(B_TRUE, abs=0.01)
    assert m.c == pytest.approx(C_TRUE, abs=0.02)
    assert m.steady_state_gain() == pytest.approx(B_TRUE.sum() / (1 + A_TRUE.sum()), rel=0.03)
    assert m.nrmse > 0.95


def test_aic_also_finds_orders():
    m = identify(synthetic(seed=3), t_model=1.0, criterion="aic", na_max=3, nb_max=3)
    assert (m.na, m.nb, m.nk) == (2, 2, 2)


def test_simulate_matches_lfilter():
    m = ArxModel(na=2, nb=2, nk=2, a=A_TRUE, b=B_TRUE, c=C_TRUE, t_s=1.0)
    u = np.sin(np.arange(200) / 7.0)
    y_ref = lfilter(np.r_[0.0, 0.0, B_TRUE], np.r_[1.0, A_TRUE], u) + lfilter([1.0], np.r_[1, A_TRUE],
                                                                              np.full(200, C_TRUE))
    y = m.simulate(u, 0.0, u0=0.0)
    assert y == pytest.approx(y_ref, abs=1e-12)
    y_ss = m.steady_state(0.5)
    assert m.simulate(np.full(50, 0.5), y_ss)[-1] == pytest.approx(y_ss, abs=1e-12)


@pytest.fixture(scope="module")
def peltier_log():
    return simulate_excitation(Config(), duration=600.0, seed=0)


def test_peltier_log(peltier_log):
    m = identify(peltier_log)
    print(f"Peltier ARX: t_s={m.t_s:g} s orders={(m.na, m.nb, m.nk)} NRMSE={m.nrmse:.3f}")
    assert 0.1 <= m.t_s <= 1.0 + 1e-9
    assert m.nrmse > 0.9
    assert 100 < m.steady_state_gain() < 250  # true local gain near 190 K per unit drive
    assert np.all(np.abs(m.poles) < 1.0)


def test_toml_roundtrip(tmp_path, peltier_log):
    m = identify(peltier_log, t_model=1.0)
    p = save_model(m, tmp_path / "m.toml")
    m2 = load_model(p)
    assert (m2.na, m2.nb, m2.nk, m2.t_s) == (m.na, m.nb, m.nk, m.t_s)
    assert m.t_s == 1.0 and m.t_s_log == 1e-3  # the log's median step, not its clock's last bits
    assert m2.a == pytest.approx(m.a, rel=1e-11, abs=0)  # written to 12 significant digits
    assert m2.b == pytest.approx(m.b, rel=1e-11, abs=0)
    assert m2.nrmse == pytest.approx(m.nrmse, rel=1e-11)
    text = p.read_text()
    assert all(len(v.split("e")[0].strip("-").replace(".", "").lstrip("0")) <= 12
               for v in re.findall(r"-?\d+\.\d+(?:e-?\d+)?", text))
    with pytest.raises(IdentifyError, match="not found"):
        load_model(tmp_path / "none.toml")
    (tmp_path / "bad.toml").write_text("[arx]\nna = 1\n")
    with pytest.raises(IdentifyError, match="lacks"):
        load_model(tmp_path / "bad.toml")


def test_identify_from_csv(tmp_path):
    d = synthetic(n=600)
    write_log(tmp_path / "x.csv", d)
    m = identify(tmp_path / "x.csv", t_model=1.0)
    assert m.na >= 1
    with pytest.raises(IdentifyError, match="missing required column"):
        write_log(tmp_path / "y.csv", {"t": d["t"], "T_p": d["T_p"]})
        identify(tmp_path / "y.csv")


def test_errors():
    d = synthetic(n=600)
    with pytest.raises(IdentifyError, match="lacks column") as e:
        identify({"t": d["t"], "T_p": d["T_p"]})
    assert "\n" not in str(e.value)
    with pytest.raises(IdentifyError, match="no excitation"):
        identify({**d, "drive": np.zeros(600)}, t_model=1.0)
    bad = d["T_p"].copy()
    bad[100] = np.nan
    with pytest.raises(IdentifyError, match="NaN"):
        identify({**d, "T_p": bad}, t_model=1.0)
    with pytest.raises(IdentifyError, match="too short"):
        identify({k: v[:50] for k, v in d.items()}, t_model=1.0)
    with pytest.raises(IdentifyError, match="T_a is constant"):
        identify({**d, "T_a": np.full(600, 20.0)}, t_model=1.0, with_T_a=True)
    with pytest.raises(IdentifyError, match="criterion"):
        identify(d, criterion="xyz")
    # a drive logged in other units (percent, volts) would fit a gain off by that factor
    with pytest.raises(IdentifyError, match=r"'drive' is outside \[-1, 1\] in 600 row"):
        identify({**d, "drive": d["drive"] * 100.0 + 2.0}, t_model=1.0)


def test_written_model_is_a_config_the_controller_uses(tmp_path, peltier_log):
    """`identify` writes [peltier_model]: `load_config` takes it, and the inner loop's
    feed-forward is the drive that holds T_p_cmd in the model's steady state, checked by
    running the model itself (its free run, tested against lfilter above) to steady state."""
    from thermoskin.params import load_config
    from thermoskin.runtime.controller import SkinController

    m = identify(peltier_log)
    cfg = load_config(save_model(m, tmp_path / "peltier.toml"))
    pm = cfg.peltier_model
    assert pm.use == "feedforward"
    assert pm.a == pytest.approx(tuple(m.a), rel=1e-11) and pm.b == pytest.approx(tuple(m.b), rel=1e-11)
    inner = SkinController(cfg).inner
    T_a, T_p_cmd = 20.0, 30.0
    inner.reset(0.0)
    u = inner.step(T_p_cmd, T_p_cmd, T_a)  # no error: the feed-forward alone
    assert u == pytest.approx(inner.ff) and inner.ff != 0.0
    T_zero = m.simulate(np.zeros(20_000), T_a)[-1]  # the tank's zero-drive temperature in the model
    T_ss = m.simulate(np.full(20_000, u), T_zero, u0=0.0)[-1]
    assert T_ss - T_zero == pytest.approx(T_p_cmd - T_a, rel=1e-6)
    # without it the same loop has no feed-forward
    assert SkinController(load_config()).inner.step(T_p_cmd, T_p_cmd, T_a) == 0.0


def test_model_config_refuses_what_cannot_drive_a_loop(tmp_path):
    from thermoskin.params import ConfigError, load_config

    p = tmp_path / "m.toml"
    for body, needle in (('use = "feedforward"\na = [-1.5]\nb = [-0.1]\n', "unstable"),
                         ('use = "feedforward"\na = [-0.5]\nb = [-0.1]\n', "must be > 0"),
                         ('use = "feedforward"\na = [-0.5]\n', "at least one"),
                         ('a = ["x"]\n', "not a number")):
        p.write_text("[peltier_model]\n" + body)
        with pytest.raises(ConfigError, match=needle):
            load_config(p)
