"""Water properties as functions of temperature (CoolProp), and Table I's printed values.

CoolProp is slow for a 1 kHz loop (about 1 ms for a property set), so properties are
evaluated once per temperature and cached; nothing here runs per sample.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

from CoolProp.CoolProp import PropsSI

P_ATM = 101_325.0  # Pa


@dataclass(frozen=True)
class WaterProperties:
    """Thermophysical properties of the water at one temperature.

    k_c: thermal conductivity, W/(m K); c_p: specific heat, J/(kg K); rho: density,
    kg/m^3; mu: dynamic viscosity, Pa s; Pr: Prandtl number.
    """

    k_c: float
    c_p: float
    rho: float
    mu: float
    Pr: float


@lru_cache(maxsize=256)
def water_properties(T: float) -> WaterProperties:
    """Liquid water at ``T`` °C and 1 atm, from CoolProp (IAPWS-95)."""
    if not 0.1 <= T <= 99.0:
        raise ValueError(f"water temperature {T} degC is outside the liquid range 0.1..99")
    Tk = T + 273.15
    return WaterProperties(
        k_c=PropsSI("L", "T", Tk, "P", P_ATM, "Water"),
        c_p=PropsSI("C", "T", Tk, "P", P_ATM, "Water"),
        rho=PropsSI("D", "T", Tk, "P", P_ATM, "Water"),
        mu=PropsSI("V", "T", Tk, "P", P_ATM, "Water"),
        Pr=PropsSI("Prandtl", "T", Tk, "P", P_ATM, "Water"),
    )


#: Table I as printed. k_c (0.1 mW/mK) and mu (1.55 kg/ms) are not water's; Pr = 11.35
#: is water's near 5 degC. Kept so that the paper's numbers can be reproduced.
TABLE1_WATER = WaterProperties(k_c=0.1e-3, c_p=4208.0, rho=999.8, mu=1.55, Pr=11.35)


def properties_for(source: str, T: float) -> WaterProperties:
    """Water properties from ``source`` ('coolprop' or 'table1') at ``T`` °C."""
    if source == "table1":
        return TABLE1_WATER
    if source == "coolprop":
        return water_properties(round(T, 3))
    raise ValueError(f"unknown water property source {source!r}")
