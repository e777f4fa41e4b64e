"""Water properties as functions of temperature, and Table I's printed values.

Properties come from ``chemicals`` (the property library behind ``ht`` and ``fluids``):
density and heat capacity from IAPWS-95, viscosity and thermal conductivity from the
IAPWS 2008 and 2011 formulations. CoolProp gives the same numbers (IAPWS-95 too) but its
import alone takes about 2.5 s, which every command-line call would pay; ``chemicals``
imports in about 0.3 s. Properties are evaluated once per temperature and cached;
nothing here runs per sample.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

from chemicals.iapws import iapws95_properties, iapws95_rho
from chemicals.thermal_conductivity import k_IAPWS
from chemicals.viscosity import mu_IAPWS

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
    """Liquid water at ``T`` °C and 1 atm (IAPWS-95, IAPWS viscosity and conductivity)."""
    if not 0.1 <= T <= 99.0:
        raise ValueError(f"water temperature {T} degC is outside the liquid range 0.1..99")
    Tk = T + 273.15
    rho = iapws95_rho(Tk, P_ATM)
    c_p = iapws95_properties(Tk, P_ATM)[5]  # (rho, U, S, H, Cv, Cp, ...), J/(kg K)
    mu = mu_IAPWS(Tk, rho)
    k_c = k_IAPWS(Tk, rho)
    return WaterProperties(k_c=k_c, c_p=c_p, rho=rho, mu=mu, Pr=c_p * mu / k_c)


#: Table I as printed. k_c (0.1 mW/mK) and mu (1.55 kg/ms) are not water's; Pr = 11.35
#: is water's near 5 degC. Kept so that the paper's numbers can be reproduced.
TABLE1_WATER = WaterProperties(k_c=0.1e-3, c_p=4208.0, rho=999.8, mu=1.55, Pr=11.35)


def properties_for(source: str, T: float) -> WaterProperties:
    """Water properties from ``source`` ('iapws' or 'table1') at ``T`` °C."""
    if source == "table1":
        return TABLE1_WATER
    if source == "iapws":
        return water_properties(round(T, 3))
    raise ValueError(f"unknown water property source {source!r}")
