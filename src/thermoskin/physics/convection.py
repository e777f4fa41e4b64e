"""Heat transfer between the tank water and the pipe: ``h(v)``, ``R_w`` (eq. 1), ``C_w`` (eq. 2).

Flowing water (``v > 0``): the paper's lost formula uses ``k_c, d, L, rho, mu, v, Pr``; the
laminar entrance correlation of Sieder and Tate fits those symbols::

    Re = rho v d / mu,   Nu = 1.86 (Re Pr d / L)^(1/3),   h = Nu k_c / d

taken from ``ht.conv_internal.laminar_entry_Seider_Tate``, floored at the fully developed
value ``Nu = 3.66`` (an entrance correlation cannot fall below it).

Still water (``v = 0``): the paper says heat then moves by pure conduction through the
water; its formula did not survive. We read it as conduction through a still water
column of the pipe-and-tank length ``L``, kept in the form of eq. 1::

    h_still = k_c / L   (Nu_L = 1),   R_w = 1 / (h A) = L / (k_c A)

With water at 24 °C and Table I's geometry this is about 57 K/W against 0.19 K/W when the
pump runs. A configured ``R_w_flowing`` / ``R_w_stopped`` replaces either.
"""

from __future__ import annotations

from ht.conv_internal import laminar_entry_Seider_Tate

from thermoskin.params import SkinParams
from thermoskin.physics.water import WaterProperties, properties_for

NU_FULLY_DEVELOPED = 3.66  # laminar, constant wall temperature


def reynolds(v: float, d: float, w: WaterProperties) -> float:
    """``Re = rho v d / mu``."""
    return w.rho * v * d / w.mu


def h_flowing(v: float, d: float, L: float, w: WaterProperties) -> float:
    """Convection coefficient of flowing water, W/(m^2 K) (Sieder-Tate, floored at 3.66)."""
    if v <= 0:
        raise ValueError(f"h_flowing needs v > 0, got {v}")
    nu = laminar_entry_Seider_Tate(Re=reynolds(v, d, w), Pr=w.Pr, L=L, Di=d)
    return max(nu, NU_FULLY_DEVELOPED) * w.k_c / d


def h_still(L: float, w: WaterProperties) -> float:
    """Conduction through still water over the length ``L``: ``h = k_c / L``, W/(m^2 K)."""
    return w.k_c / L


def R_w(v: float, skin: SkinParams, T: float | None = None) -> float:
    """Thermal resistance tank water to pipe, K/W (eq. 1: ``R_w = 1/(h A)``).

    ``T`` is the water temperature for the properties (default ``skin.T_ref``).
    """
    if v > 0 and skin.R_w_flowing is not None:
        return skin.R_w_flowing
    if v <= 0 and skin.R_w_stopped is not None:
        return skin.R_w_stopped
    w = properties_for(skin.water, skin.T_ref if T is None else T)
    h = h_flowing(v, skin.d, skin.L, w) if v > 0 else h_still(skin.L, w)
    return 1.0 / (h * skin.A)


def C_w_from_tank(skin: SkinParams, T: float | None = None) -> float:
    """Eq. 2, ``C_w = c_p rho V``, J/K: the tank's water (about 134 J/K for Table I)."""
    w = properties_for(skin.water, skin.T_ref if T is None else T)
    return w.c_p * w.rho * skin.V


class FlowResistance:
    """``R_w(v)`` cached per velocity, for per-sample use (no property calls in the loop)."""

    __slots__ = ("_cache", "_skin")

    def __init__(self, skin: SkinParams) -> None:
        self._skin = skin
        self._cache: dict[float, float] = {}

    def __call__(self, v: float) -> float:
        r = self._cache.get(v)
        if r is None:
            r = R_w(v, self._skin)
            self._cache[v] = r
        return r
