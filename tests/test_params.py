"""Parameters: Table I preset, validation messages, TOML load/save."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from pathlib import Path

import pytest

from thermoskin.params import (
    _SECTION_TYPES,
    PRESETS,
    Config,
    ConfigError,
    ObserverParams,
    SensorParams,
    SkinParams,
    load_config,
    save_config,
    to_toml,
)

# Table I of the paper (*Detection of Human Contact by Thermal Exchange Observer of Robot Skin*),
# typed in from its text.
TABLE_I = {
    "C_w": 0.134,  # J/K
    "C_g": 0.0124,  # J/K
    "R_g": 10.0,  # K/W
    "R_aw": 2100.0,  # K/W
    "R_ag": 1.0,  # K/W
    "A": 3.2e-3,  # m^2
    "V": 3.2e-5,  # m^3
    "d": 3.0e-3,  # m
    "L": 0.11,  # m
}


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "cfg.toml"
    p.write_text(text, encoding="utf-8")
    return p


@pytest.mark.parametrize("preset", ["paper", "paper-table-fluid"])
def test_presets_hold_table_i(preset: str) -> None:
    cfg = PRESETS[preset]
    for key, value in TABLE_I.items():
        assert getattr(cfg.skin, key) == pytest.approx(value, rel=1e-12), key
    assert cfg.sampling.t_s == pytest.approx(1.0e-3, rel=1e-12)
    assert cfg.pump.v_on == pytest.approx(0.141, rel=1e-12)
    assert cfg.skin.R_w_flowing is None
    assert cfg.skin.R_w_stopped is None


def test_preset_water_sources() -> None:
    assert PRESETS["paper"].skin.water == "iapws"
    assert PRESETS["paper-table-fluid"].skin.water == "table1"
    assert load_config() == PRESETS["paper"]
    assert load_config(preset="paper-table-fluid") == PRESETS["paper-table-fluid"]


def test_toml_overrides_a_subset(tmp_path: Path) -> None:
    p = _write(tmp_path, """
[skin]
R_g = 12.5
R_w_flowing = 0.25

[observer]
n_init = 50
tau_r = 0.1

[sensor]
noise_T = 0.0
""")
    cfg = load_config(p)
    base = PRESETS["paper"]
    assert cfg.skin.R_g == 12.5
    assert cfg.skin.R_w_flowing == 0.25
    assert cfg.skin.R_w_stopped is None
    assert cfg.observer.n_init == 50
    assert cfg.observer.tau_r == 0.1
    assert cfg.sensor.noise_T == 0.0
    # everything else untouched
    assert dataclasses.replace(cfg.skin, R_g=base.skin.R_g, R_w_flowing=None) == base.skin
    assert cfg.sampling == base.sampling
    assert cfg.detector == base.detector
    assert cfg.pump == base.pump
    # an integer in TOML for a float field becomes a float
    cfg2 = load_config(_write(tmp_path, "[skin]\nR_g = 12\n"))
    assert isinstance(cfg2.skin.R_g, float)
    assert cfg2.skin.R_g == 12.0


def test_toml_on_top_of_other_preset(tmp_path: Path) -> None:
    cfg = load_config(_write(tmp_path, "[skin]\nC_w = 0.2\n"), preset="paper-table-fluid")
    assert cfg.skin.water == "table1"
    assert cfg.skin.C_w == 0.2


def test_unknown_table_raises(tmp_path: Path) -> None:
    p = _write(tmp_path, "[skn]\nR_g = 1.0\n")
    with pytest.raises(ConfigError, match=r"skn"):
        load_config(p)


def test_unknown_key_raises(tmp_path: Path) -> None:
    p = _write(tmp_path, "[skin]\nR_gg = 1.0\n")
    with pytest.raises(ConfigError) as e:
        load_config(p)
    assert "skin.R_gg" in str(e.value)
    assert str(p) in str(e.value)


def test_non_table_section_raises(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="skin"):
        load_config(_write(tmp_path, "skin = 3\n"))


@pytest.mark.parametrize(
    ("toml", "key", "value", "range_text"),
    [
        ("[skin]\nC_w = -0.5\n", "skin.C_w", "-0.5", ">= 0.0001 and <= 10000"),
        ("[skin]\nC_w = 1e300\n", "skin.C_w", "1e+300", ">= 0.0001 and <= 10000"),
        ("[sampling]\nt_s = 1e-12\n", "sampling.t_s", "1e-12", ">= 0.0001"),
        ("[skin]\nR_g = 0.0\n", "skin.R_g", "0.0", ">= 0.001"),
        ("[skin]\nd = 0.5\n", "skin.d", "0.5", "<= 0.1"),
        ("[skin]\nT_ref = 120.0\n", "skin.T_ref", "120.0", "<= 99"),
        ("[sampling]\nt_s = 2.0\n", "sampling.t_s", "2.0", "<= 1"),
        ("[observer]\nn_init = 0\n", "observer.n_init", "0", ">= 1"),
        ("[detector]\nf_off = 1.5\n", "detector.f_off", "1.5", "<= 1"),
        ("[pump]\nv_on = -0.1\n", "pump.v_on", "-0.1", ">= 0.001"),
        ("[skin]\nR_w_flowing = -1.0\n", "skin.R_w_flowing", "-1.0", ">= 0.001"),
        ("[skin]\nR_g = nan\n", "skin.R_g", "nan", ">= 0.001"),
        ("[skin]\nR_g = inf\n", "skin.R_g", "inf", ">= 0.001"),
        ("[peltier]\nC_tank = 1e9\n", "peltier.C_tank", "1000000000.0", "<= 100000"),
        ("[plausible]\nv_max = -1.0\n", "plausible.v_max", "-1.0", ">= 0"),
    ],
)
def test_out_of_range_message(tmp_path: Path, toml: str, key: str, value: str,
                              range_text: str) -> None:
    p = _write(tmp_path, toml)
    with pytest.raises(ConfigError) as e:
        load_config(p)
    msg = str(e.value)
    assert key in msg
    assert value in msg
    assert range_text in msg


def test_bad_choice_message() -> None:
    with pytest.raises(ConfigError) as e:
        SkinParams(water="seawater")
    msg = str(e.value)
    assert "skin.water" in msg and "seawater" in msg
    assert "iapws" in msg and "table1" in msg


@pytest.mark.parametrize("bad", ["abc", True, [1.0]])
def test_non_numeric_names_key_and_value(bad: object) -> None:
    with pytest.raises(ConfigError) as e:
        SkinParams(C_w=bad)  # type: ignore[arg-type]
    msg = str(e.value)
    assert "skin.C_w" in msg
    assert repr(bad) in msg


def test_non_numeric_names_range() -> None:
    with pytest.raises(ConfigError) as e:
        SkinParams(C_w="abc")  # type: ignore[arg-type]
    assert ">= 0.0001 and <= 10000" in str(e.value)


def test_non_numeric_in_toml(tmp_path: Path) -> None:
    with pytest.raises(ConfigError) as e:
        load_config(_write(tmp_path, '[skin]\nR_g = "ten"\n'))
    assert "skin.R_g" in str(e.value) and "ten" in str(e.value)


@pytest.mark.parametrize("make", [lambda: ObserverParams(n_init=2.5),  # type: ignore[arg-type]
                                  lambda: SensorParams(seed=1.5)])  # type: ignore[arg-type]
def test_integer_fields_reject_fractions(make: Callable[[], object]) -> None:
    with pytest.raises(ConfigError, match="whole number"):
        make()


def test_integer_fields_stay_int() -> None:
    assert type(ObserverParams(n_init=300.0).n_init) is int  # type: ignore[arg-type]


def test_optional_R_w_fields() -> None:
    s = SkinParams(R_w_flowing=0.3, R_w_stopped=40.0)
    assert (s.R_w_flowing, s.R_w_stopped) == (0.3, 40.0)
    assert SkinParams(R_w_flowing=None).R_w_flowing is None
    with pytest.raises(ConfigError, match=r"skin\.R_w_stopped"):
        SkinParams(R_w_stopped=0.0)


def test_config_replace() -> None:
    cfg = Config().replace(skin={"R_g": 5.0}, pump={"hysteresis": 0.1})
    assert cfg.skin.R_g == 5.0 and cfg.pump.hysteresis == 0.1
    assert cfg.skin.C_w == TABLE_I["C_w"]
    with pytest.raises(ConfigError, match=r"skin\.R_g"):
        Config().replace(skin={"R_g": -5.0})
    with pytest.raises(ConfigError, match="nope"):
        Config().replace(nope={"x": 1})


def test_frozen() -> None:
    with pytest.raises(dataclasses.FrozenInstanceError):
        PRESETS["paper"].skin.R_g = 3.0  # type: ignore[misc]


def test_load_errors(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="preset"):
        load_config(preset="nonexistent")
    with pytest.raises(ConfigError, match="does not exist"):
        load_config(tmp_path / "missing.toml")
    with pytest.raises(ConfigError, match="is a directory"):
        load_config(tmp_path)
    with pytest.raises(ConfigError, match="TOML"):
        load_config(_write(tmp_path, "[skin\nR_g = 1\n"))


def test_round_trip(tmp_path: Path) -> None:
    cfg = Config().replace(
        skin={"R_g": 7.25, "C_g": 3.3e-5, "R_w_flowing": 0.21, "water": "table1", "T_ref": 30.0},
        observer={"n_init": 17, "max_gap_s": 0.5},
        detector={"h_on": 0.2}, estimator={"S_q": 2.5},
        sensor={"seed": 12345, "quantum_T": 0.0},
    )
    p = tmp_path / "out.toml"
    save_config(cfg, p)
    back = load_config(p)
    assert back == cfg
    assert isinstance(back.observer.n_init, int)
    # the text is also valid for the other preset and gives the same config
    assert load_config(p, preset="paper-table-fluid") == cfg
    # None values are left out
    assert "R_w_stopped" not in to_toml(cfg)
    assert "R_w_flowing = 0.21" in to_toml(cfg)


def test_round_trip_defaults(tmp_path: Path) -> None:
    p = tmp_path / "d.toml"
    save_config(PRESETS["paper"], p)
    assert load_config(p) == PRESETS["paper"]
    assert all(math.isfinite(getattr(PRESETS["paper"].skin, k)) for k in TABLE_I)


def test_every_number_has_a_range_on_both_sides() -> None:
    """No parameter is open-ended: a finite lower and upper bound on every number."""
    for name, cls in _SECTION_TYPES.items():
        for f in dataclasses.fields(cls):
            meta = f.metadata
            if meta and not meta["choices"]:
                assert math.isfinite(meta["lo"]) and math.isfinite(meta["hi"]), f"{name}.{f.name}"
                assert meta["lo"] < meta["hi"], f"{name}.{f.name}"


def test_plausible_ranges_ordered() -> None:
    with pytest.raises(ConfigError, match=r"plausible\.T_w_min"):
        Config().replace(plausible={"T_w_min": 200.0})


def test_range_messages_name_the_unit_only_where_there_is_one() -> None:
    with pytest.raises(ConfigError) as e:
        Config().replace(detector={"h_on": -3.0})
    assert str(e.value).startswith("detector.h_on = -3.0 is out of range: must be > 0 and <= 1000 in ")
    with pytest.raises(ConfigError) as e:
        Config().replace(detector={"k_off": -3.0})
    assert "must be >= 0 and <= 100 (sigma) in " in str(e.value)
