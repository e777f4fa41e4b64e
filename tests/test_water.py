"""Water properties: the package's IAPWS values against textbook values and CoolProp; Table I."""

from __future__ import annotations

import pytest

from thermoskin.physics.water import TABLE1_WATER, properties_for, water_properties

# Textbook values for liquid water at 1 atm (Incropera/DeWitt Table A.6, CRC Handbook):
# T degC: (rho kg/m^3, c_p J/kgK, k W/mK, mu Pa s, Pr)
TEXTBOOK = {
    20.0: (998.2, 4182.0, 0.598, 1.002e-3, 7.01),
    24.0: (997.3, 4181.0, 0.605, 0.911e-3, 6.29),
    30.0: (995.7, 4178.0, 0.615, 0.798e-3, 5.42),
}


@pytest.mark.parametrize("T", sorted(TEXTBOOK))
def test_matches_textbook(T: float) -> None:
    rho, cp, k, mu, pr = TEXTBOOK[T]
    w = water_properties(T)
    assert w.rho == pytest.approx(rho, rel=1e-3)
    assert w.c_p == pytest.approx(cp, rel=3e-3)
    assert w.k_c == pytest.approx(k, rel=1.5e-2)
    assert w.mu == pytest.approx(mu, rel=2e-2)
    assert w.Pr == pytest.approx(pr, rel=3e-2)


@pytest.mark.parametrize("T", [1.0, 5.0, 20.0, 24.0, 30.0, 60.0, 95.0])
def test_matches_coolprop(T: float) -> None:
    """CoolProp (IAPWS-95 and the IAPWS transport formulations) as an independent library."""
    from CoolProp.CoolProp import PropsSI  # (2 s to import: not in every worker's collection)

    Tk, P = T + 273.15, 101_325.0
    w = water_properties(T)
    assert w.rho == pytest.approx(PropsSI("D", "T", Tk, "P", P, "Water"), rel=1e-6)
    assert w.c_p == pytest.approx(PropsSI("C", "T", Tk, "P", P, "Water"), rel=1e-6)
    assert w.mu == pytest.approx(PropsSI("V", "T", Tk, "P", P, "Water"), rel=1e-4)
    assert w.k_c == pytest.approx(PropsSI("L", "T", Tk, "P", P, "Water"), rel=1e-4)
    assert w.Pr == pytest.approx(PropsSI("Prandtl", "T", Tk, "P", P, "Water"), rel=2e-4)


@pytest.mark.parametrize("T", [5.0, 24.0, 60.0])
def test_prandtl_is_consistent(T: float) -> None:
    """Pr = c_p mu / k, an identity the property library must satisfy."""
    w = water_properties(T)
    assert w.Pr == pytest.approx(w.c_p * w.mu / w.k_c, rel=1e-6)


def test_trends_with_temperature() -> None:
    a, b = water_properties(10.0), water_properties(40.0)
    assert b.mu < a.mu  # viscosity falls
    assert b.k_c > a.k_c  # conductivity rises
    assert b.rho < a.rho  # density falls above 4 degC
    assert b.Pr < a.Pr


def test_prandtl_near_table_value_at_5C() -> None:
    """docs/model.md: Table I's Pr = 11.35 is water's near 5 degC."""
    assert water_properties(5.0).Pr == pytest.approx(11.35, rel=0.03)


@pytest.mark.parametrize("T", [-5.0, 0.0, 100.0, 150.0])
def test_out_of_liquid_range(T: float) -> None:
    with pytest.raises(ValueError):
        water_properties(T)


def test_table1_as_printed() -> None:
    w = TABLE1_WATER
    assert w.k_c == pytest.approx(0.1e-3, rel=1e-12)  # 0.1 mW/mK
    assert w.c_p == pytest.approx(4208.0, rel=1e-12)  # 4.208 kJ/kgK
    assert w.rho == pytest.approx(999.8, rel=1e-12)
    assert w.mu == pytest.approx(1.55, rel=1e-12)  # kg/ms
    assert w.Pr == pytest.approx(11.35, rel=1e-12)


def test_properties_for() -> None:
    assert properties_for("table1", 24.0) == TABLE1_WATER
    assert properties_for("table1", 80.0) == TABLE1_WATER
    w = properties_for("iapws", 20.0)
    assert w.rho == pytest.approx(998.2, rel=1e-3)
    # rounding to 1 mK for the cache does not move the values measurably
    assert properties_for("iapws", 24.0001).mu == pytest.approx(water_properties(24.0).mu, rel=1e-5)
    with pytest.raises(ValueError):
        properties_for("seawater", 24.0)
