"""h(v), R_w (eq. 1) and C_w (eq. 2) against hand computations."""

from __future__ import annotations

import math

import pytest

from thermoskin.params import SkinParams
from thermoskin.physics.convection import (
    C_w_from_tank,
    FlowResistance,
    R_w,
    h_flowing,
    h_still,
    reynolds,
)
from thermoskin.physics.water import TABLE1_WATER, water_properties

V_ON = 0.141
D, L, A, V = 3.0e-3, 0.11, 3.2e-3, 3.2e-5


def sieder_tate_by_hand(v: float, d: float, length: float, rho: float, mu: float, k: float,
                        pr: float) -> tuple[float, float, float]:
    """Re, Nu and h of Sieder-Tate without wall-viscosity correction, floored at 3.66."""
    re = rho * v * d / mu
    nu = max(1.86 * (re * pr * d / length) ** (1.0 / 3.0), 3.66)
    return re, nu, nu * k / d


def test_reynolds() -> None:
    w = water_properties(24.0)
    assert reynolds(V_ON, D, w) == pytest.approx(w.rho * V_ON * D / w.mu, rel=1e-12)


@pytest.mark.parametrize("T", [20.0, 24.0, 30.0])
@pytest.mark.parametrize("v", [0.05, 0.141, 0.5])
def test_h_flowing_is_sieder_tate(T: float, v: float) -> None:
    w = water_properties(T)
    _, _, h = sieder_tate_by_hand(v, D, L, w.rho, w.mu, w.k_c, w.Pr)
    assert h_flowing(v, D, L, w) == pytest.approx(h, rel=1e-9)


def test_model_md_numbers_at_24C() -> None:
    """docs/model.md: Re ~ 460, Nu ~ 8.0, h ~ 1.6 kW/m^2K, R_w ~ 0.19 K/W with real water at 24 degC."""
    w = water_properties(24.0)
    re = reynolds(V_ON, D, w)
    h = h_flowing(V_ON, D, L, w)
    assert re == pytest.approx(460, rel=0.02)
    assert h * D / w.k_c == pytest.approx(8.0, rel=0.02)
    assert h == pytest.approx(1.6e3, rel=0.03)
    skin = SkinParams()
    assert skin.T_ref == 24.0
    assert R_w(V_ON, skin) == pytest.approx(0.19, rel=0.03)
    assert R_w(V_ON, skin) == pytest.approx(1.0 / (h * A), rel=1e-12)


def test_floor_at_fully_developed() -> None:
    """At a crawl the entrance correlation falls below 3.66; h is floored there."""
    w = water_properties(24.0)
    v = 1e-4
    assert 1.86 * (reynolds(v, D, w) * w.Pr * D / L) ** (1 / 3) < 3.66
    assert h_flowing(v, D, L, w) == pytest.approx(3.66 * w.k_c / D, rel=1e-12)


def test_h_flowing_needs_positive_v() -> None:
    w = water_properties(24.0)
    for v in (0.0, -0.1):
        with pytest.raises(ValueError):
            h_flowing(v, D, L, w)


def test_h_grows_as_cube_root_of_v() -> None:
    w = water_properties(24.0)
    assert h_flowing(8 * 0.05, D, L, w) / h_flowing(0.05, D, L, w) == pytest.approx(2.0, rel=1e-9)


def test_still_water_is_conduction_over_L() -> None:
    w = water_properties(24.0)
    assert h_still(L, w) == pytest.approx(w.k_c / L, rel=1e-12)
    skin = SkinParams()
    assert R_w(0.0, skin) == pytest.approx(L / (w.k_c * A), rel=1e-9)
    assert R_w(0.0, skin) == pytest.approx(57.0, rel=0.02)
    assert R_w(-1.0, skin) == R_w(0.0, skin)
    # a still pipe conducts far worse than a flowing one
    assert R_w(0.0, skin) > 100 * R_w(V_ON, skin)


def test_temperature_argument() -> None:
    skin = SkinParams()
    w = water_properties(30.0)
    _, _, h = sieder_tate_by_hand(V_ON, D, L, w.rho, w.mu, w.k_c, w.Pr)
    assert R_w(V_ON, skin, T=30.0) == pytest.approx(1.0 / (h * A), rel=1e-9)
    assert R_w(V_ON, SkinParams(T_ref=30.0)) == pytest.approx(1.0 / (h * A), rel=1e-9)


def test_table1_fluid() -> None:
    """With Table I's printed fluid values the flow is deep in the floor: R_w ~ 2.6 kK/W."""
    skin = SkinParams(water="table1")
    t = TABLE1_WATER
    re, nu, h = sieder_tate_by_hand(V_ON, D, L, 999.8, 1.55, 0.1e-3, 11.35)
    assert re == pytest.approx(0.273, rel=1e-2)
    assert nu == 3.66
    assert R_w(V_ON, skin) == pytest.approx(1.0 / (h * A), rel=1e-9)
    assert R_w(0.0, skin) == pytest.approx(L / (t.k_c * A), rel=1e-9)
    assert C_w_from_tank(skin) == pytest.approx(4208.0 * 999.8 * V, rel=1e-12)


def test_configured_R_w_overrides() -> None:
    skin = SkinParams(R_w_flowing=0.25)
    assert R_w(V_ON, skin) == 0.25
    assert R_w(0.02, skin) == 0.25
    assert R_w(0.0, skin) == pytest.approx(R_w(0.0, SkinParams()), rel=1e-12)
    skin = SkinParams(R_w_stopped=40.0)
    assert R_w(0.0, skin) == 40.0
    assert R_w(V_ON, skin) == pytest.approx(R_w(V_ON, SkinParams()), rel=1e-12)


def test_C_w_from_tank_eq2() -> None:
    w = water_properties(24.0)
    c = C_w_from_tank(SkinParams())
    assert c == pytest.approx(w.c_p * w.rho * V, rel=1e-12)
    assert c == pytest.approx(134.0, rel=0.01)  # docs/model.md
    # about a thousand times Table I's identified C_w
    assert c / SkinParams().C_w == pytest.approx(1000.0, rel=0.01)


def test_flow_resistance_cache() -> None:
    skin = SkinParams(R_w_stopped=33.0)
    fr = FlowResistance(skin)
    for v in (0.141, 0.0, 0.141, 0.07, 0.0):
        assert fr(v) == R_w(v, skin)
    assert math.isfinite(fr(0.141))
