"""The skin description (skin.py): the examples, the size scaling, every error path one line."""

from __future__ import annotations

import copy
import math
import tomllib
from pathlib import Path
from typing import Any

import pytest

from thermoskin.params import Config, ConfigError
from thermoskin.skin.layout import SINGLE, Pipe, load_skin, parse_skin, single_skin

ROOT = Path(__file__).resolve().parent.parent
FOREARM = ROOT / "examples" / "forearm.toml"

BASE: dict[str, Any] = {
    "name": "t",
    "links": {"arm": {"length": 0.2, "circumference": 0.1, "origin": [0.0, 0.0]}},
    "loops": {"a": {"patches": ["p", "q"], "pipes": [0.1, 0.02, 0.1]}},
    "patches": {"p": {"link": "arm", "centre": [0.05, 0.05]},
                "q": {"link": "arm", "centre": [0.1, 0.05], "thermocouples": [0.03, 0.0]}},
}


def test_forearm_example() -> None:
    skin = load_skin(FOREARM)
    assert len(skin.patches) >= 8 and len(skin.loops) >= 2
    assert max(len(lp.patches) for lp in skin.loops) >= 3
    assert [p.index for p in skin.patches] == list(range(len(skin.patches)))
    names = [p.name for p in skin.patches]
    assert names[:4] == ["dorsal1", "dorsal2", "dorsal3", "dorsal4"]  # the file's order
    dorsal = skin.loops[0]
    assert [skin.patches[i].name for i in dorsal.patches] == ["dorsal1", "dorsal2", "dorsal3", "dorsal4",
                                                                "hand_back"]
    assert dorsal.feedback == skin.patch("hand_back").index  # the last by default
    assert len(dorsal.pipes) == len(dorsal.patches) + 1
    assert dorsal.pipes[0] == Pipe(0.15, 100.0)
    assert skin.patch("dorsal1").thermocouples == (0.03, 0.0)
    assert skin.patch("dorsal3").thermocouples == (0.03,)  # default: the outlet
    assert skin.patch("ventral3").skin.R_g == 12.0
    assert dorsal.cfg.control.W2 == 3.0 and skin.cfg.control.W2 == Config().control.W2
    assert skin.log_columns() == ["t", "patch", "T_w", "T_p", "v", "T_a", "T_w2", "q_i", "contact_true",
                                  "position_true", "fresh"]


def test_the_benchmarks_held_out_skin_loads() -> None:
    """benchmarks/skins/upper_arm.toml (skin_detection.py's check of FLOW_NOISE on a skin it was
    not fitted on) stays a valid skin: a chain of six patches and a loop of three."""
    skin = load_skin(ROOT / "benchmarks" / "skins" / "upper_arm.toml")
    assert sorted(len(lp.patches) for lp in skin.loops) == [3, 6]
    assert skin.patch("lat1").thermocouples == (0.03, 0.0)


def test_single_example_is_the_papers_patch() -> None:
    a, b = load_skin(ROOT / "examples" / "single.toml"), single_skin()
    assert (ROOT / "examples" / "single.toml").read_text() == SINGLE
    assert a.patches == b.patches and a.loops == b.loops
    p = a.patches[0]
    cfg = Config()
    assert p.skin == cfg.skin  # Table I unchanged for the paper's 30 x 10 mm patch
    assert (p.length, p.width, p.thermocouples) == (0.03, 0.01, (0.03,))
    assert p.tc_cells == (0,)  # the single patch's thermocouple cell
    assert a.loops[0].pipes == (Pipe(0.0), Pipe(0.0))
    assert load_skin(None).patches == b.patches


def test_size_scaling() -> None:
    """Pipe quantities with the length, sheet quantities with the area (Table I for 30 x 10 mm)."""
    skin = load_skin(FOREARM)
    palm = skin.patch("palm")  # 40 x 20 mm
    t1 = Config().skin
    lr, ar = 40 / 30, 40 * 20 / (30 * 10)
    assert palm.skin.C_w == pytest.approx(0.134 * lr, rel=1e-12)
    assert palm.skin.R_g == pytest.approx(10.0 / lr, rel=1e-12)
    assert palm.skin.R_aw == pytest.approx(2100.0 / lr, rel=1e-12)
    assert palm.skin.C_g == pytest.approx(0.0124 * ar, rel=1e-12)
    assert palm.skin.R_ag == pytest.approx(1.0 / ar, rel=1e-12)
    assert (palm.spatial.length, palm.spatial.width) == (0.04, 0.02)
    data = copy.deepcopy(BASE)
    data["patches"]["p"].update(length=0.06, skin={"R_g": 7.0})
    p = parse_skin(data, "t.toml").patch("p")
    assert p.skin.R_g == 7.0  # a patch's own key is kept as given
    assert p.skin.C_w == pytest.approx(2 * t1.C_w, rel=1e-12)


def test_geometry() -> None:
    skin = parse_skin(copy.deepcopy(BASE), "t.toml")
    p = skin.patch("p")
    assert p.point_at(0.0) == pytest.approx((0.035, 0.05))  # inlet: centre - length/2 along the axis
    assert p.locate(0.04, 0.052) == pytest.approx(0.005)
    assert p.locate(0.04, 0.06) is None  # beyond the width
    assert p.cell_of(0.03) == 0 and p.cell_of(0.0) == 14  # outlet cell 0 (x = 0), inlet cell N - 1
    data = copy.deepcopy(BASE)
    data["patches"]["p"]["angle"] = 90.0
    q = parse_skin(data, "t.toml").patch("p")
    assert q.point_at(0.03) == pytest.approx((0.05, 0.065))


def _mut(path: str, value: Any) -> dict[str, Any]:
    """``BASE`` with the key at ``path`` (dots) set to ``value`` (``DELETE``: removed)."""
    data = copy.deepcopy(BASE)
    *head, last = path.split(".")
    node = data
    for k in head:
        node = node[k]
    if value is DELETE:
        del node[last]
    else:
        node[last] = value
    return data


DELETE = object()

ERRORS = [
    ("colour", "x", "colour is not a known key"),
    ("links", DELETE, "[links] is missing"),
    ("links", {}, "[links] is empty"),
    ("links.arm.length", -1.0, "links.arm.length = -1.0 must be a number > 0"),
    ("links.arm.circumference", "big", "links.arm.circumference = 'big' must be a number"),
    ("links.arm.origin", [1.0], "links.arm.origin = [1.0] must be a pair"),
    ("links.arm.shape", "round", "links.arm.shape is not a known key"),
    ("links.arm", {"length": 0.2}, "links.arm.circumference is missing"),
    ("patches", DELETE, "[patches] is missing"),
    ("patches.p.link", "leg", "patches.p.link = 'leg' is not a link of this skin"),
    ("patches.p.centre", [0.5, 0.05], "patches.p.centre = [0.5, 0.05] lies outside link 'arm'"),
    ("patches.p.centre", DELETE, "patches.p.centre is missing"),
    ("patches.p.length", 0.0, "patches.p.length = 0.0 must be a number > 0"),
    ("patches.p.width", math.inf, "patches.p.width = inf must be a number > 0"),
    ("patches.p.angle", math.nan, "patches.p.angle = nan must be a number"),
    ("patches.p.thermocouples", [0.04],
     "patches.p.thermocouples[0] = 0.04 must be a number >= 0 and <= 0.03"),
    ("patches.p.thermocouples", [], "patches.p.thermocouples = [] must be a non-empty list"),
    ("patches.p.thermocouples", [0.01, 0.01],
     "patches.p.thermocouples = [0.01, 0.01] has the same position"),
    ("patches.p.skin", {"R_g": -2.0}, "patches.p.skin.R_g = -2.0 is out of range"),
    ("patches.p.skin", {"Rg": 2.0}, "patches.p.skin.Rg is not a known key"),
    ("patches.p.skin", {"R_w_flowing": 0.2}, "patches.p.skin.R_w_flowing belongs to the water loop"),
    ("patches.p.spatial", {"n_cells": 0}, "patches.p.spatial.n_cells = 0 is out of range"),
    ("patches.p.spatial", {"length": 0.05}, "patches.p.spatial.length cannot be set here"),
    ("patches.p.spatial", {"inlet": "near"}, "patches.p.spatial.inlet cannot be set here"),
    ("patches.p.spatial", {"contact_length": 0.05},
     "patches.p.spatial.contact_length = 0.05 m must not exceed"),
    ("patches.p.size", [1, 2], "patches.p.size is not a known key"),
    ("spatial", {"k_sheet": -1.0}, "spatial.k_sheet = -1.0 is out of range"),
    ("spatial", {"width": 0.02}, "spatial.width cannot be set here"),
    ("pipe", {"tau_loss": 0.0}, "pipe.tau_loss = 0.0 must be a number > 0"),
    ("pipe", {"diameter": 0.002}, "pipe.diameter is not a known key"),
    ("loops", DELETE, "[loops] is missing"),
    ("loops.a.patches", [], "loops.a.patches = [] must be a non-empty list of patch names"),
    ("loops.a.patches", ["p", "r"], "loops.a.patches = 'r' is not a patch of this skin"),
    ("loops.a.patches", ["p", "q", "p"], "loops.a.patches = 'p' is already on loop 'a'"),
    ("loops.a", {"patches": ["p"]}, "patches.q is on no loop"),
    ("loops.a.pipes", [0.1, 0.1], "loops.a.pipes = [0.1, 0.1] has 2 entries: needs 3"),
    ("loops.a.pipes", [0.1, -0.02, 0.1], "loops.a.pipes[1] = -0.02 must be a number >= 0"),
    ("loops.a.pipes", [0.1, {"length": 0.02, "tau_loss": -1.0}, 0.1],
     "loops.a.pipes[1].tau_loss = -1.0 must be a number > 0"),
    ("loops.a.pipes", [0.1, {"lenght": 0.02}, 0.1], "loops.a.pipes[1].lenght is not a known key"),
    ("loops.a.feedback", "z", "loops.a.feedback = 'z' must be one of the loop's patches"),
    ("loops.a.tank", "left", "loops.a.tank = 'left' must be a pair"),
    ("loops.a.pump", {"v_on": -1.0}, "loops.a.pump.v_on = -1.0 is out of range"),
    ("loops.a.pump", {"speed": 1.0}, "loops.a.pump.speed is not a known key"),
    ("loops.a.peltier", {"C_tank": 0.0}, "loops.a.peltier.C_tank = 0.0 is out of range"),
    ("loops.a.control", {"T_p_min": 50.0}, "loops.a: control.T_p_min = 50.0 must be below control.T_p_max"),
    ("loops.a.skin", {"R_g": 3.0}, "loops.a.skin.R_g belongs to the patches"),
    ("loops.a.skin", {"water": "oil"}, "loops.a.skin.water = 'oil' is not allowed"),
    ("loops.a.sensor", {}, "loops.a.sensor is not a known key"),
]


@pytest.mark.parametrize(("path", "value", "expected"), ERRORS,
                         ids=[e[0] + "=" + repr(e[1])[:12] for e in ERRORS])
def test_every_bad_value_is_one_line_naming_file_and_key(path: str, value: Any, expected: str) -> None:
    with pytest.raises(ConfigError) as e:
        parse_skin(_mut(path, value), "skins/t.toml")
    msg = str(e.value)
    assert "\n" not in msg
    assert msg.startswith("skins/t.toml: "), msg
    assert expected in msg, msg


def test_file_errors(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"layout file .*nothere.toml does not exist"):
        load_skin(tmp_path / "nothere.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[links\nx = 1\n")
    with pytest.raises(ConfigError) as e:
        load_skin(bad)
    assert "bad.toml is not valid TOML" in str(e.value) and "\n" not in str(e.value)
    ok = tmp_path / "ok.toml"
    ok.write_text(FOREARM.read_text().replace("length = 0.04                   #", "length = -0.04  #"))
    with pytest.raises(ConfigError, match=r"ok.toml: patches.palm.length = -0.04 must be a number > 0"):
        load_skin(ok)


def test_the_config_is_the_base() -> None:
    cfg = Config().replace(skin={"R_g": 8.0}, pump={"v_on": 0.2})
    skin = parse_skin(tomllib.loads(SINGLE), "s.toml", cfg)
    assert skin.patches[0].skin.R_g == 8.0 and skin.loops[0].cfg.pump.v_on == 0.2
