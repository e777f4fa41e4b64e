"""Touchers: physical models of what touches the skin (a hand, or an object).

:mod:`thermoskin.physics.finger` is the simple touch: a fixed conductance to a body held
at a fixed temperature. Here the toucher has a body of its own, so that the heat it
brings changes over a touch the way a real one does: a hand's surface cools and its blood
flow holds it up; a metal can from the fridge pulls heat for minutes; wood or foam warm
at the surface within a second and then barely take any more.

**The contact.** The toucher's surface node (temperature ``T_s``) exchanges with the
sheet (``T_g``) through the interface conductance ``G`` (W/K, 0 = no contact)::

    q_i = G (T_s - T_g)                    heat into the sheet, W (docs/model.md's q_i)
    G   = h_c(p) A                         contact coefficient times contact area

with ``h_c`` growing with the contact pressure ``p`` (:func:`h_contact`).

**The body** (every toucher): a 1-D chain of finite volumes below the contact area
``A``, vertex-centred (node 0 *is* the surface, so ``T_s = T[0]``), on a geometric grid
(thin at the surface, coarser below). Node ``i`` has capacity ``C_i = rho c A dx_i``
(half an interval on each side), neighbours are joined by ``K_i = k A / (x_{i+1} - x_i)``,
and a node may exchange with a fixed temperature through a conductance ``S_i``
(perfusion, a convective back face, ambient air) and carry a source ``P_i``::

    C_i dT_i/dt = K_{i-1}(T_{i-1} - T_i) + K_i (T_{i+1} - T_i) + S_i (T_ext,i - T_i) + P_i
                  [+ G (T_g - T_0) at the surface]

**Human tissue** (:class:`HumanTissue`): the Pennes bioheat equation (Pennes 1948)::

    rho c dT/dt = k d2T/dx2 + w_b rho_b c_b (T_art - T) + q_met

so ``S_i = w_b rho_b c_b A dx_i`` (to ``T_art`` = 37 °C) and ``P_i = q_met A dx_i``,
over the depth ``L`` of a finger's, palm's or hand's half-thickness with a zero-flux
deep face (the symmetry plane: the heat comes with the blood, not from a 37 °C core
a few mm down, which would not let a finger be cooler than about 34 °C). At rest the
surface loses heat to the room through ``h_env`` (convection and radiation); that loss
stops under contact. The resting surface temperature ``T_start`` (30-36 °C) is set, as
in the body, by the blood flow: :meth:`HumanTissue.reset` finds the perfusion ``w_b``
whose steady state has ``T_s = T_start`` (vasoconstricted cool fingers have little
flow, warm ones much more). After a touch the surface recovers towards ``T_start``.

**Objects** (:class:`Solid`): plies of materials (thickness, ``k, rho, c``); a zero-flux
back face unless a convective one is given; optionally a well-mixed reservoir behind
the last ply (water in a cup or a can: capacity ``rho_w c_w V``, joined to the wall by
a natural-convection film ``h_film A``, losing to the room through ``G_amb``). Between
contacts the object's surface does not exchange with the air (its warming in the room
takes minutes; the reservoir's loss ``G_amb`` is the exception).

**Time step.** Backward Euler over one sample ``t_s`` with ``T_g`` held: unconditionally
stable (any ``G``, any layer), and it conserves energy exactly (the chain is one
tridiagonal system, solved by elimination from the deep end, so only the surface pivot
depends on ``G``)::

    T_s' = (b_0 + G T_g)/(m_0 + G),   q_i = G_eff (T_eff - T_g)
    G_eff = G m_0/(m_0 + G),           T_eff = b_0/m_0

``m_0`` is the surface pivot (the capacity and everything behind the surface seen over
one step) and ``b_0`` the eliminated right-hand side; ``T_eff`` is the temperature the
surface would reach over the step if nothing touched it. Over the coming sample the
toucher is thus *exactly* a conductance ``G_eff`` to a source at ``T_eff``, the
``(G_c, T_f)`` pair that :meth:`thermoskin.sim.skin.SimulatedSkin.step` already takes:
``begin(G)`` gives them, the skin steps with them (treating the contact implicitly, so
even a hand on metal at tens of W/K is stable at 1 ms), and ``end(T_g)`` completes the
toucher's step with the sheet temperature over the sample (the mean of its start and
end values keeps the energy exchanged the same on both sides to second order).
``step(T_g, G)`` is ``begin`` and ``end`` in one call.

Presets (:func:`toucher`; ``e = sqrt(k rho c)`` of the material that sets the touch, the
surface's or, for the water bag, the water's, in W s^0.5/(m² K),
``T_s`` the default surface temperature, ``G`` the default contact conductance
``h_c(p) A``; every name in :data:`MATERIALS` is also a kind, a 20 mm slab at 22 °C,
10 cm² at 2 kPa)::

    kind              class           e       T_s °C  A cm²  p kPa  G W/K
    finger            human           1180    33.0    1.5    6.7    0.051
    palm              human           1180    33.0    60     1.7    0.57
    hand              human           1180    33.0    100    1.5    0.84
    can_cold          metal           19855   5.0     10     2      0.11
    aluminium_block   metal           24047   22.0    10     2      0.11
    steel_tool        metal           13248   22.0    2      5      0.052
    mug_hot           glass-ceramic   1585    60.0    10     2      0.11
    glass_of_water    glass-ceramic   1369    20.0    10     2      0.11
    water_bag         water           1581    20.0    20     1      0.11
    plastic_box       plastic         600     22.0    10     2      0.11
    wood_block        wood            442     22.0    10     2      0.11
    foam_block        foam            72      22.0    10     2      0.11

(tests/test_contact.py recomputes this table.) The simulator integration reads
``q_i``, ``T_s`` and :attr:`Toucher.truth` (``toucher_true`` 'human'/'object',
``material_true``, ``class_true``, ``T_f_true`` the surface temperature at reset,
``G_true`` the preset's contact conductance, ``area_true``, ``kind``).

Cost: one step is two passes over the nodes in plain Python (no arrays, no allocation
but the floats), 0.6-1.5 µs for the presets (``benchmarks/toucher_step.py``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

# ---------------------------------------------------------------------------------------
# Materials
# ---------------------------------------------------------------------------------------

CLASSES = ("human", "metal", "glass-ceramic", "plastic", "wood", "foam", "water")
"""Material classes (Bhattacharjee, Wade & Kemp, RSS 2015, recognise materials by touch
from heat transfer in such classes)."""

_INCROPERA_A1 = ("Incropera, DeWitt, Bergman & Lavine, Fundamentals of Heat and Mass Transfer, "
                 "6th ed., Table A.1 (metallic solids, 300 K)")
_DIN_12524 = ("DIN EN 12524:2000 (tabulated design values), as in ht.insulation.building_materials")
_ASHRAE = "ASHRAE Handbook of Fundamentals 2013, Ch. 26, as in ht.insulation.ASHRAE"


@dataclass(frozen=True)
class Material:
    """A homogeneous material: conductivity ``k`` W/(m K), density ``rho`` kg/m³,
    specific heat ``c`` J/(kg K), its class (:data:`CLASSES`) and the source of the values."""

    name: str
    cls: str
    k: float
    rho: float
    c: float
    source: str

    def __post_init__(self) -> None:
        if self.cls not in CLASSES:
            raise ValueError(f"Material {self.name!r}: class {self.cls!r} is not one of {CLASSES}")
        for what, v in (("k", self.k), ("rho", self.rho), ("c", self.c)):
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"Material {self.name!r}: {what} = {v} must be > 0")

    @property
    def effusivity(self) -> float:
        """``e = sqrt(k rho c)``, W s^0.5/(m² K): sets the contact temperature of two bodies."""
        return math.sqrt(self.k * self.rho * self.c)

    @property
    def diffusivity(self) -> float:
        """``alpha = k/(rho c)``, m²/s."""
        return self.k / (self.rho * self.c)


def _m(name: str, cls: str, k: float, rho: float, c: float, source: str) -> tuple[str, Material]:
    return name, Material(name, cls, k, rho, c, source)


MATERIALS: dict[str, Material] = dict([
    # metals
    _m("aluminium", "metal", 237.0, 2702.0, 903.0, _INCROPERA_A1 + ": pure aluminium"),
    _m("aluminium_alloy", "metal", 160.0, 2800.0, 880.0, _DIN_12524 + ": 'Metals, aluminium alloys'"),
    _m("copper", "metal", 380.0, 8900.0, 380.0, _DIN_12524 + ": 'Metals, copper'"),
    _m("steel", "metal", 50.0, 7800.0, 450.0, _DIN_12524 + ": 'Metals, steel'"),
    _m("stainless_steel", "metal", 17.0, 7900.0, 460.0, _DIN_12524 + ": 'Metals, stainless steel'"),
    # glass and ceramics
    _m("glass", "glass-ceramic", 1.0, 2500.0, 750.0, _DIN_12524 + ": 'Glass, soda lime'"),
    _m("quartz_glass", "glass-ceramic", 1.4, 2200.0, 750.0, _DIN_12524 + ": 'Glass, quartz'"),
    _m("porcelain", "glass-ceramic", 1.3, 2300.0, 840.0, _DIN_12524 + ": 'Tiles, ceramic or porcelain'"),
    # plastics and rubber
    _m("pmma", "plastic", 0.18, 1180.0, 1500.0,
       _DIN_12524 + ": 'Plastics, polymethylmethacrylate (PMMA)'"),
    _m("polycarbonate", "plastic", 0.2, 1200.0, 1200.0, _DIN_12524 + ": 'Plastics, polycarbonates'"),
    _m("pvc", "plastic", 0.17, 1390.0, 900.0, _DIN_12524 + ": 'Plastics, Polyvinylchloride (PVC)'"),
    _m("polypropylene", "plastic", 0.22, 910.0, 1800.0, _DIN_12524 + ": 'Plastics, polypropylene'"),
    _m("hdpe", "plastic", 0.5, 980.0, 1800.0,
       _DIN_12524 + ": 'Plastics, polyethylene / polythene, high density'"),
    _m("ldpe", "plastic", 0.33, 920.0, 2200.0,
       _DIN_12524 + ": 'Plastics, polyethylene / polythene, low density'"),
    _m("nylon", "plastic", 0.25, 1150.0, 1600.0, _DIN_12524 + ": 'Plastics, polyamide (nylon)'"),
    _m("rubber", "plastic", 0.13, 910.0, 1100.0, _DIN_12524 + ": 'Rubber, natural'"),
    # woods
    _m("oak", "wood", 0.17, 705.0, 1630.0, _ASHRAE + ": 'Oak'"),
    _m("pine", "wood", 0.15, 615.0, 1630.0, _ASHRAE + ": 'Southern pine'"),
    _m("plywood", "wood", 0.13, 500.0, 1600.0, _DIN_12524 + ": 'Wood, plywood 500 kg/m^3'"),
    _m("fibreboard", "wood", 0.18, 800.0, 1700.0, _DIN_12524 + ": 'Wood, fibreboard, 800 kg/m^3'"),
    # foams
    _m("pu_foam", "foam", 0.05, 70.0, 1500.0, _DIN_12524 + ": 'Sealant, polyurethane (PU) foam'"),
    _m("foam_rubber", "foam", 0.06, 70.0, 1500.0, _DIN_12524 + ": 'Rubber, foam rubber'"),
    _m("eps", "foam", 0.0355, 20.0, 1470.0, _ASHRAE + ": 'Expanded polystyrene, molded beads'"),
    # water at 20 °C and 1 atm (IAPWS-95, IAPWS 2011 conductivity; physics.water gives the same)
    _m("water", "water", 0.5984, 998.2, 4184.0, "IAPWS-95 / IAPWS 2011 at 20 °C (physics.water)"),
])
"""Object materials by name (values and their sources in each entry's ``source``)."""

SKIN = Material("skin", "human", 0.37, 1109.0, 3391.0,
                "IT'IS Foundation tissue properties database v4.1 (Hasgall et al. 2022): 'Skin'")
"""Skin (the tissue of every human toucher; the deeper tissue is taken with skin's values).

Its effusivity, 1180 W s^0.5/(m² K), lies within in-vivo measurements: Vendrik & Vos
(1957, J. Appl. Physiol. 11:211) found ``k rho c = 1.4e-3 cal² cm⁻⁴ s⁻¹ K⁻²`` on the
forearm (``e`` about 1560); the review of skin properties in Burns 43:909 (2017, Table 3)
lists in-vivo ``k rho c`` for skin as one layer mostly between 1.0e6 and 3.2e6
W² s/(m⁴ K²) (``e`` 1000-1800). The IT'IS values here and below are quoted as we know
them from the database's tables; no copy of the database was at hand to re-check them."""

RHO_BLOOD = 1050.0
"""Blood density, kg/m³ (IT'IS database v4.1, 'Blood')."""
C_BLOOD = 3617.0
"""Blood specific heat, J/(kg K) (IT'IS database v4.1, 'Blood')."""
T_ARTERIAL = 37.0
"""Arterial (core) blood temperature, °C (Pennes 1948)."""
Q_MET_SKIN = 1.65 * 1109.0
"""Metabolic heat of skin, W/m³ (IT'IS database v4.1, 'Skin', heat generation 1.65 W/kg).
Its effect is ``q_met/(w_b rho_b c_b)``: 0.2-1 K at the perfusions here, which the
perfusion found for a resting temperature absorbs."""
W_B_SKIN = 106e-6 / 60.0 * 1109.0
"""Average skin perfusion, 1/s (IT'IS v4.1: 106 ml/(min kg)), about 2e-3 1/s: the scale
against which the perfusion found from a resting surface temperature is read."""
H_ENV = 10.0
"""Heat-transfer coefficient of resting skin to the room (convection and radiation),
W/(m² K): Scott, Farmer & English (J. Trauma 30:422, 1990) measured 9.7 combined."""
T_ENV = 22.0
"""Default room (air and walls) temperature seen by a resting toucher, °C."""

# ---------------------------------------------------------------------------------------
# Contact coefficient
# ---------------------------------------------------------------------------------------

H_C_REF = 500.0
"""Contact coefficient at :data:`P_REF`, W/(m² K). Anchored to docs/model.md's fingertip
(about 0.05 W/K over about 1 cm² at a light press): 1 N over a 1.5 cm² finger pad
(6.7 kPa) gives 0.051 W/K. Skin-object contact resistances of this order, falling with
pressure over 0.7-11 kPa, were measured by Ho & Jones (2008, J. Biomech. Eng.
130:021005) and Galie, Ho & Jones (2009, World Haptics, 587-592); the value is an
anchor of this project, not a fit to their data."""
P_REF = 10.0e3
"""Reference contact pressure, Pa."""
N_H_C = 0.94
"""Pressure exponent of ``h_c``: the elastic asperity contact correlation of Mikic (1974,
Int. J. Heat Mass Transfer 17:205), ``h_c = 1.54 k_s (m/sigma)(p/(m E'))^0.94``, the
form the Yovanovich-type models keep for soft (elastic) contacts; skin is the soft side."""
P_MAX = 100.0e3
"""Largest pressure accepted, Pa (a hard press on a fingertip is some tens of kPa)."""


def h_contact(pressure: float) -> float:
    """Contact coefficient ``h_c(p) = H_C_REF (p/P_REF)^N_H_C``, W/(m² K) (``pressure`` in Pa)."""
    if not (math.isfinite(pressure) and 0.0 < pressure <= P_MAX):
        raise ValueError(f"h_contact: pressure = {pressure} Pa must be in (0, {P_MAX:g}]")
    return H_C_REF * (pressure / P_REF) ** N_H_C


def G_contact(area: float, pressure: float) -> float:
    """Contact conductance ``G = h_c(p) A``, W/K (``area`` in m², ``pressure`` in Pa)."""
    if not (math.isfinite(area) and 0.0 < area <= 1.0):
        raise ValueError(f"G_contact: area = {area} m² must be in (0, 1]")
    return h_contact(pressure) * area


# ---------------------------------------------------------------------------------------
# Grid
# ---------------------------------------------------------------------------------------

def geometric_grid(depth: float, n_nodes: int, dx0: float) -> list[float]:
    """Node positions ``0 = x_0 < ... < x_{n-1} = depth`` with spacings ``dx0 r^j``.

    ``r >= 1`` is solved from ``dx0 (r^(n-1) - 1)/(r - 1) = depth``; a uniform grid when
    ``dx0 >= depth/(n-1)``.
    """
    if n_nodes < 2:
        raise ValueError(f"geometric_grid: n_nodes = {n_nodes} must be >= 2")
    if not (depth > 0 and dx0 > 0):
        raise ValueError(f"geometric_grid: depth = {depth} m and dx0 = {dx0} m must be > 0")
    n = n_nodes - 1
    if dx0 * n >= depth:
        return [depth * j / n for j in range(n_nodes)]
    ratio = depth / dx0

    def span(r: float) -> float:
        return (r ** n - 1.0) / (r - 1.0) - ratio

    from scipy.optimize import brentq  # here: scipy.optimize takes 0.5 s to import

    r = brentq(span, 1.0 + 1e-12, 2.0 * ratio ** (1.0 / max(n - 1, 1)) + 2.0, xtol=1e-14)
    xs = [0.0]
    for j in range(n):
        xs.append(xs[-1] + dx0 * r ** j)
    xs[-1] = depth
    return xs


def _dx0(material: Material, thickness: float, n_nodes: int, tau0: float) -> float:
    """First spacing: the surface layer's diffusion time ``dx0²/alpha`` equals ``tau0``."""
    return min(math.sqrt(material.diffusivity * tau0), thickness / (n_nodes - 1))


TAU0 = 0.1
"""Diffusion time of the first grid interval, s: faster than anything the observer sees
(its time constants are ``R_g C_w`` = 1.3 s and longer). With 9 nodes a thick slab's heat
flow after a step of its surface temperature is within 3 % (2.5 % for oak) of the
semi-infinite ``e (T1 - T2)/sqrt(pi t)`` from 0.3 s to 30 s (tests/test_contact.py)."""


# ---------------------------------------------------------------------------------------
# The chain (every toucher)
# ---------------------------------------------------------------------------------------

class Toucher:
    """A 1-D finite-volume body touching the sheet, stepped by backward Euler at ``t_s``.

    Built from capacities ``C`` (J/K), conductances ``K`` between neighbours (W/K), node
    sinks ``S`` (W/K) to temperatures ``T_ext`` and sources ``P`` (W); ``H_env`` (W/K) to
    ``T_env`` at the surface while ``G = 0``. State: ``T`` (°C per node), ``T_s`` (the
    surface), ``q_i`` (W, the last step's heat into the sheet).
    """

    __slots__ = (
        "C",
        "G_eff",
        "H_env",
        "K",
        "P",
        "S",
        "T",
        "T_eff",
        "T_env",
        "T_ext",
        "T_s",
        "_G",
        "_b",
        "_c",
        "_down",
        "_m0",
        "_n",
        "_r",
        "_s",
        "_u",
        "_up",
        "_v",
        "area",
        "kind",
        "q_i",
        "t_s",
        "truth",
        "x",
    )

    def __init__(self, C: Sequence[float], K: Sequence[float], S: Sequence[float],
                 T_ext: Sequence[float], P: Sequence[float], t_s: float, *, H_env: float = 0.0,
                 T_env: float = T_ENV, x: Sequence[float] | None = None, area: float = 1.0,
                 kind: str = "") -> None:
        n = len(C)
        if n < 1 or len(K) != n - 1 or len(S) != n or len(T_ext) != n or len(P) != n:
            raise ValueError(f"Toucher: {n} capacities need {n - 1} conductances and {n} sinks, "
                             f"sink temperatures and sources")
        if not (math.isfinite(t_s) and t_s > 0):
            raise ValueError(f"Toucher: t_s = {t_s} s must be > 0")
        if min(C) <= 0 or (K and min(K) <= 0) or min(S) < 0 or H_env < 0:
            raise ValueError("Toucher: capacities and conductances must be > 0, sinks and H_env >= 0")
        self.C = [float(v) for v in C]
        self.K = [float(v) for v in K]
        self.S = [float(v) for v in S]
        self.T_ext = [float(v) for v in T_ext]
        self.P = [float(v) for v in P]
        self.t_s = float(t_s)
        self.H_env = float(H_env)
        self.T_env = float(T_env)
        self.x = list(x) if x is not None else []
        self.area = float(area)
        self.kind = kind
        self._n = n
        self._factor()
        self.T = [0.0] * n
        self._b = [0.0] * n
        self._G = 0.0
        self.G_eff = 0.0
        self.T_eff = 0.0
        self.T_s = 0.0
        self.q_i = 0.0
        self.truth: dict[str, Any] = {}

    # -- factorisation (once per set of coefficients) -------------------------------------
    def _factor(self) -> None:
        """Pivots of the elimination from the deep end (independent of ``G``).

        ``D_i = C_i/t_s + K_{i-1} + K_i + S_i``, ``m_{n-1} = D_{n-1}``,
        ``m_i = D_i - K_i²/m_{i+1}``; ``r_i = K_i/m_{i+1}``, ``u_i = 1/m_i``, ``v_i = K_{i-1}/m_i``.
        """
        n, C, K, S = self._n, self.C, self.K, self.S
        c = [Ci / self.t_s for Ci in C]
        D = [c[i] + S[i] + (K[i - 1] if i > 0 else 0.0) + (K[i] if i < n - 1 else 0.0)
             for i in range(n)]
        m = [0.0] * n
        m[n - 1] = D[n - 1]
        for i in range(n - 2, -1, -1):
            m[i] = D[i] - K[i] * K[i] / m[i + 1]
        self._c = c
        self._s = [S[i] * self.T_ext[i] + self.P[i] for i in range(n)]
        self._r = [K[i] / m[i + 1] for i in range(n - 1)] + [0.0]
        self._u = [1.0 / mi for mi in m]
        self._v = [0.0] + [K[i - 1] / m[i] for i in range(1, n)]
        self._m0 = m[0]
        self._up = list(range(n - 2, -1, -1))
        self._down = list(range(1, n))

    def set_sinks(self, S: Sequence[float], P: Sequence[float]) -> None:
        """Replace the node sinks and sources (e.g. a new perfusion) and refactor."""
        if len(S) != self._n or len(P) != self._n or min(S) < 0:
            raise ValueError(f"Toucher.set_sinks: need {self._n} sinks >= 0 and sources")
        self.S = [float(v) for v in S]
        self.P = [float(v) for v in P]
        self._factor()

    # -- state -----------------------------------------------------------------------------
    def reset(self, T_start: float) -> None:
        """Start uniform at ``T_start`` °C (human tissue: its resting profile, see subclass)."""
        if not (math.isfinite(T_start) and -40.0 <= T_start <= 100.0):
            raise ValueError(f"{type(self).__name__}.reset: T_start = {T_start} °C must be in [-40, 100]")
        self.set_state([float(T_start)] * self._n)

    def set_state(self, T: Sequence[float]) -> None:
        """Set every node's temperature (°C) and clear the contact."""
        if len(T) != self._n:
            raise ValueError(f"Toucher.set_state: need {self._n} temperatures, got {len(T)}")
        self.T[:] = [float(v) for v in T]
        self.T_s = self.T[0]
        self._G = 0.0
        self.G_eff = 0.0
        self.T_eff = self.T[0]
        self.q_i = 0.0

    def steady_state(self, G: float = 0.0, T_g: float = 0.0) -> list[float]:
        """The chain's equilibrium for a constant contact ``G`` to ``T_g`` (``G = 0``: at rest)."""
        n = self._n
        A = np.zeros((n, n))
        rhs = np.array(self._s, dtype=float)
        for i in range(n):
            A[i, i] = self.S[i]
        for i, Ki in enumerate(self.K):
            A[i, i] += Ki
            A[i + 1, i + 1] += Ki
            A[i, i + 1] -= Ki
            A[i + 1, i] -= Ki
        g = G if G > 0.0 else self.H_env
        if g <= 0.0 and max(self.S) <= 0.0:
            raise ValueError(f"{type(self).__name__}({self.kind}): no steady state, the body "
                             "exchanges heat with nothing")
        A[0, 0] += g
        rhs[0] += g * (T_g if G > 0.0 else self.T_env)
        return [float(v) for v in np.linalg.solve(A, rhs)]

    def energy(self) -> float:
        """Heat content ``sum C_i T_i`` relative to 0 °C, J."""
        return math.fsum(c * t for c, t in zip(self.C, self.T, strict=True))

    # -- per sample ------------------------------------------------------------------------
    def begin(self, G: float) -> None:
        """First half of a step: eliminate from the deep end with contact ``G`` (W/K).

        Sets ``G_eff`` and ``T_eff``: over the coming sample ``q_i = G_eff (T_eff - T_g)``
        for whatever ``T_g`` the sheet holds (pass them to the skin as ``G_c, T_f``).
        """
        T, c, s, r, b = self.T, self._c, self._s, self._r, self._b
        n1 = self._n - 1
        acc = c[n1] * T[n1] + s[n1]
        b[n1] = acc
        for i in self._up:
            acc = c[i] * T[i] + s[i] + r[i] * acc
            b[i] = acc
        m0 = self._m0
        if G > 0.0:
            self._G = G
            self.G_eff = G * m0 / (m0 + G)
            self.T_eff = acc / m0
        else:
            h = self.H_env
            self._G = 0.0
            self.G_eff = 0.0
            self.T_eff = (acc + h * self.T_env) / (m0 + h)

    def end(self, T_g: float) -> float:
        """Second half: the sheet held ``T_g`` over the sample; returns ``q_i`` (W)."""
        T, b, u, v = self.T, self._b, self._u, self._v
        G = self._G
        if G > 0.0:
            t = (b[0] + G * T_g) / (self._m0 + G)
            q = self.G_eff * (self.T_eff - T_g)
        else:
            t = self.T_eff
            q = 0.0
        T[0] = t
        for i in self._down:
            t = b[i] * u[i] + v[i] * t
            T[i] = t
        self.T_s = T[0]
        self.q_i = q
        return q

    def step(self, T_g: float, G: float) -> float:
        """One sample with the sheet at ``T_g`` (°C) and contact ``G`` (W/K): ``q_i``, W
        (``begin(G)`` then ``end(T_g)``; written out, it saved 0.1 of 1.3 µs a sample)."""
        self.begin(G)
        return self.end(T_g)


def _plies_chain(plies: Sequence[tuple[Material, float, int]], area: float, tau0: float
                 ) -> tuple[list[float], list[float], list[float], list[float]]:
    """Capacities, conductances, node positions and node volumes of stacked plies.

    Each ply ``(material, thickness, n_nodes)`` is gridded geometrically from its front
    face; neighbouring plies share their interface node.
    """
    xs: list[float] = [0.0]
    C: list[float] = [0.0]
    V: list[float] = [0.0]
    K: list[float] = []
    for mat, thick, n_nodes in plies:
        if not (math.isfinite(thick) and thick > 0):
            raise ValueError(f"ply of {mat.name}: thickness = {thick} m must be > 0")
        grid = geometric_grid(thick, n_nodes, _dx0(mat, thick, n_nodes, tau0))
        x0 = xs[-1]
        for j in range(1, len(grid)):
            dx = grid[j] - grid[j - 1]
            half = 0.5 * dx * area
            C[-1] += mat.rho * mat.c * half
            V[-1] += half
            K.append(mat.k * area / dx)
            xs.append(x0 + grid[j])
            C.append(mat.rho * mat.c * half)
            V.append(half)
    return C, K, xs, V


# ---------------------------------------------------------------------------------------
# Human tissue
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class BodyPart:
    """A human contact: area ``area`` (m²) at ``pressure`` (Pa), tissue ``depth`` (m) to the
    zero-flux symmetry plane, ``n_nodes`` grid nodes."""

    name: str
    area: float
    pressure: float
    depth: float
    n_nodes: int = 9
    note: str = ""


HUMANS: dict[str, BodyPart] = {
    "finger": BodyPart("finger", 1.5e-4, 6.7e3, 6e-3, note=(
        "finger pad under about 1 N: 1-2 cm² (the brief); depth half a fingertip's thickness")),
    "palm": BodyPart("palm", 60e-4, 1.7e3, 10e-3, note=(
        "palm flat on a surface, about 10 N: 50-80 cm² of the palm's ~90 cm² (about 0.5 % of "
        "the body surface, Rossiter, Chapman & Haywood, Burns, 1996)")),
    "hand": BodyPart("hand", 100e-4, 1.5e3, 10e-3, note=(
        "palm and fingers flat, about 15 N: part of the ~140 cm² of palm with digits "
        "(about 0.8 % of the body surface, Rossiter et al. 1996)")),
}
"""Human presets. The person sets the resting surface temperature (``T_start``, 30-36 °C,
e.g. ``finger.PERSONS[name].T_body``); the areas and pressures are assumptions in the
quoted ranges."""

T_SKIN_DEFAULT = 33.0
"""Default resting surface temperature of a human toucher, °C."""


class HumanTissue(Toucher):
    """Perfused tissue (Pennes 1948) under a contact: a finger, a palm or a hand.

    ``reset(T_start)`` finds the perfusion ``w_b`` (1/s) whose resting steady state
    (surface losing ``h_env`` to ``T_env``) has the surface at ``T_start``, and starts
    there. ``w_b`` stays fixed through contacts: the surface then settles at the level
    the blood flow holds against the sheet, and recovers after release.
    """

    __slots__ = ("T_art", "V", "part", "q_met", "w_b")

    def __init__(self, part: BodyPart | str = "finger", *, area: float | None = None, t_s: float = 1e-3,
                 T_env: float = T_ENV, h_env: float = H_ENV, T_art: float = T_ARTERIAL,
                 q_met: float = Q_MET_SKIN, tissue: Material = SKIN, n_nodes: int | None = None,
                 tau0: float = TAU0, depth: float | None = None) -> None:
        if isinstance(part, str):
            try:
                part = HUMANS[part]
            except KeyError:
                raise ValueError(f"HumanTissue: unknown body part {part!r} (known: {', '.join(HUMANS)})"
                                 ) from None
        A = part.area if area is None else float(area)
        if not (math.isfinite(A) and 0.0 < A <= 1.0):
            raise ValueError(f"HumanTissue: area = {A} m² must be in (0, 1]")
        L = part.depth if depth is None else float(depth)
        n = part.n_nodes if n_nodes is None else int(n_nodes)
        C, K, xs, V = _plies_chain([(tissue, L, n)], A, tau0)
        self.part = part
        self.V = V
        self.T_art = float(T_art)
        self.q_met = float(q_met)
        self.w_b = 0.0
        n = len(C)
        super().__init__(C, K, [0.0] * n, [self.T_art] * n, [self.q_met * v for v in V], t_s,
                         H_env=h_env * A, T_env=T_env, x=xs, area=A, kind=part.name)

    def set_perfusion(self, w_b: float) -> None:
        """Blood perfusion ``w_b`` (1/s, volume of blood per volume of tissue per second)."""
        if not (math.isfinite(w_b) and w_b >= 0.0):
            raise ValueError(f"HumanTissue: w_b = {w_b} 1/s must be >= 0")
        self.w_b = float(w_b)
        wc = w_b * RHO_BLOOD * C_BLOOD
        self.set_sinks([wc * v for v in self.V], [self.q_met * v for v in self.V])

    def perfusion_for(self, T_surface: float) -> float:
        """The ``w_b`` whose resting steady state has the surface at ``T_surface`` °C."""
        def gap(w: float) -> float:
            self.set_perfusion(w)
            return self.steady_state()[0] - T_surface

        lo, hi = 0.0, 0.5
        g_lo, g_hi = gap(lo), gap(hi)
        if not g_lo < 0.0 < g_hi:
            raise ValueError(f"HumanTissue({self.kind}): a resting surface at {T_surface} °C is out of "
                             f"reach ({g_lo + T_surface:.2f}..{g_hi + T_surface:.2f} °C with room at "
                             f"{self.T_env} °C, arterial blood at {self.T_art} °C)")
        from scipy.optimize import brentq

        return float(brentq(gap, lo, hi, xtol=1e-12, rtol=1e-12))

    def reset(self, T_start: float) -> None:
        """Rest with the surface at ``T_start`` °C: perfusion found, steady profile set."""
        if not (math.isfinite(T_start) and 25.0 <= T_start < self.T_art):
            raise ValueError(f"HumanTissue({self.kind}).reset: T_start = {T_start} °C must be in "
                             f"[25, {self.T_art})")
        self.set_perfusion(self.perfusion_for(T_start))
        self.set_state(self.steady_state())


# ---------------------------------------------------------------------------------------
# Objects
# ---------------------------------------------------------------------------------------

G_ACC = 9.80665  # m/s², standard gravity


FILM_DT = 5.0
"""Wall-to-water temperature difference at which the natural-convection film is linearised, K."""


def h_natural_water(T: float, height: float, dT: float = FILM_DT) -> float:
    """Natural-convection coefficient of water on a vertical wall, W/(m² K).

    Churchill & Chu (1975) for a vertical plate of ``height`` (m) at ``dT`` (K) from the
    water, properties at the film temperature ``T`` °C
    (``ht.conv_free_immersed.Nu_vertical_plate_Churchill``; water from IAPWS,
    :mod:`thermoskin.physics.water`, ``beta`` from the density's slope)::

        Gr = g beta dT H^3/nu^2,  Nu = [0.825 + 0.387 (Gr Pr)^(1/6)/(1 + (0.492/Pr)^(9/16))^(8/27)]^2

    The film is linearised at ``dT``: its dependence on the temperature difference
    (``h ~ dT^(1/3)``) is left out. Near 4 °C water hardly expands and the film is weak
    (a can from the fridge: about 300 W/(m² K) against about 1000 at room temperature).
    """
    from ht.conv_free_immersed import Nu_vertical_plate_Churchill

    from thermoskin.physics.water import water_properties

    Tw = min(max(T, 1.0), 95.0)
    w = water_properties(Tw)
    beta = -(water_properties(Tw + 0.5).rho - water_properties(Tw - 0.5).rho) / w.rho
    nu = w.mu / w.rho
    Gr = G_ACC * abs(beta) * dT * height ** 3 / nu ** 2
    return Nu_vertical_plate_Churchill(w.Pr, Gr) * w.k_c / height


@dataclass(frozen=True)
class Reservoir:
    """Well-mixed liquid behind the wall: volume ``volume`` (m³) of ``liquid``, a film of
    ``h_film`` W/(m² K) at the wall (``None``: Churchill-Chu for a wall of ``height`` m),
    and a loss ``G_amb`` (W/K) of the whole container to the room."""

    volume: float
    liquid: Material = MATERIALS["water"]
    h_film: float | None = None
    height: float = 0.1
    G_amb: float = 0.0


@dataclass(frozen=True)
class ObjectPreset:
    """An object: plies ``(material name, thickness m)`` from the touched face, optional
    reservoir, default temperature (°C), area (m²), pressure (Pa), class."""

    name: str
    plies: tuple[tuple[str, float], ...]
    T_start: float
    area: float = 10e-4
    pressure: float = 2.0e3
    reservoir: Reservoir | None = None
    cls: str | None = None
    note: str = ""

    @property
    def material(self) -> Material:
        """The touched (surface) material."""
        return MATERIALS[self.plies[0][0]]

    @property
    def class_(self) -> str:
        """Material class of the object (the surface material's unless set)."""
        return self.cls if self.cls is not None else self.material.cls

    @property
    def material_true(self) -> Material:
        """The material that sets the touch: the contents when the class says so, else the surface."""
        if self.cls == "water" and self.reservoir is not None:
            return self.reservoir.liquid
        return self.material


OBJECTS: dict[str, ObjectPreset] = {
    "can_cold": ObjectPreset(
        "can_cold", (("aluminium_alloy", 0.1e-3),), 5.0,
        reservoir=Reservoir(330e-6, height=0.115, G_amb=0.3),
        note="beverage can from the fridge: 0.1 mm aluminium wall, 330 ml of water-like drink"),
    "aluminium_block": ObjectPreset("aluminium_block", (("aluminium", 20e-3),), 22.0,
                                    note="a 20 mm aluminium block or plate"),
    "steel_tool": ObjectPreset("steel_tool", (("steel", 10e-3),), 22.0, area=2e-4, pressure=5.0e3,
                               note="a 10 mm steel tool handle"),
    "mug_hot": ObjectPreset(
        "mug_hot", (("porcelain", 4e-3),), 60.0,
        reservoir=Reservoir(250e-6, height=0.09, G_amb=0.25),
        note="porcelain mug, 4 mm wall, 250 ml of hot water"),
    "glass_of_water": ObjectPreset(
        "glass_of_water", (("glass", 2.5e-3),), 20.0,
        reservoir=Reservoir(250e-6, height=0.12, G_amb=0.25),
        note="drinking glass, 2.5 mm wall, 250 ml of tap water"),
    "water_bag": ObjectPreset(
        "water_bag", (("ldpe", 0.05e-3),), 20.0, area=20e-4, pressure=1.0e3,
        reservoir=Reservoir(500e-6, height=0.05, G_amb=0.3), cls="water",
        note="500 ml of water in a thin polyethylene bag: the film is thermally invisible"),
    "plastic_box": ObjectPreset("plastic_box", (("polypropylene", 3e-3),), 22.0,
                                note="polypropylene box wall, 3 mm, air behind"),
    "wood_block": ObjectPreset("wood_block", (("oak", 20e-3),), 22.0, note="oak, 20 mm"),
    "foam_block": ObjectPreset("foam_block", (("pu_foam", 30e-3),), 22.0, note="polyurethane foam, 30 mm"),
}
"""Object presets (areas and pressures are assumptions: a can or mug held against the
skin, a tool handle pressed, a block resting). ``G_amb``: natural convection and
radiation, about 10 W/(m² K) (Incropera, Table 1.1 range for free convection in gases
plus linearised radiation), over the container's outer surface."""

SLAB_THICKNESS = 20e-3
"""Thickness of the plain slab made for a material name used as a kind, m."""


class Solid(Toucher):
    """A passive object: plies, a zero-flux or convective back, an optional reservoir."""

    __slots__ = ("_film", "plies", "reservoir")

    def __init__(self, plies: Sequence[tuple[Material | str, float]], area: float, *, t_s: float = 1e-3,
                 reservoir: Reservoir | None = None, back_h: float = 0.0, T_back: float = T_ENV,
                 n_nodes: int = 9, tau0: float = TAU0, kind: str = "") -> None:
        if not (math.isfinite(area) and 0.0 < area <= 1.0):
            raise ValueError(f"Solid: area = {area} m² must be in (0, 1]")
        mats: list[tuple[Material, float, int]] = []
        for m, d in plies:
            mat = _material(m) if isinstance(m, str) else m
            # as many intervals as the ply holds surface layers (a thin wall is one), at most n_nodes - 1
            n = min(n_nodes, max(2, math.ceil(d / math.sqrt(mat.diffusivity * tau0)) + 1))
            mats.append((mat, float(d), n))
        if not mats:
            raise ValueError("Solid: at least one ply is needed")
        C, K, xs, _ = _plies_chain(mats, area, tau0)
        n = len(C)
        S = [0.0] * n
        T_ext = [T_back] * n
        if back_h < 0:
            raise ValueError(f"Solid: back_h = {back_h} W/(m² K) must be >= 0")
        if reservoir is not None:
            liq = reservoir.liquid
            if not reservoir.volume > 0 or reservoir.G_amb < 0:
                raise ValueError("Solid: reservoir volume must be > 0 and G_amb >= 0")
            h = reservoir.h_film
            if h is None:
                h = h_natural_water(_film_T(T_back, T_back), reservoir.height)
            C.append(liq.rho * liq.c * reservoir.volume)
            K.append(h * area)
            xs.append(math.nan)
            S.append(reservoir.G_amb)
            T_ext.append(T_back)
            n += 1
        else:
            S[-1] += back_h * area
        self.plies = tuple(mats)
        self.reservoir = reservoir
        self._film = reservoir is not None and reservoir.h_film is None
        super().__init__(C, K, S, T_ext, [0.0] * n, t_s, x=xs, area=area, kind=kind)

    def reset(self, T_start: float) -> None:
        """Uniform at ``T_start`` °C; a Churchill-Chu film is re-evaluated at that temperature."""
        if self.reservoir is not None and self.reservoir.liquid.cls == "water" and not 0.5 <= T_start <= 99.0:
            raise ValueError(f"Solid({self.kind}).reset: T_start = {T_start} °C: the water inside "
                             "must be liquid (0.5-99 °C)")
        super().reset(T_start)
        if self._film and self.reservoir is not None:
            self.K[-1] = h_natural_water(_film_T(T_start, self.T_ext[-1]), self.reservoir.height) * self.area
            self._factor()


def _film_T(T_bulk: float, T_room: float) -> float:
    """Film temperature: half :data:`FILM_DT` from the bulk towards the room (the skin's side)."""
    return T_bulk + (0.5 * FILM_DT if T_room >= T_bulk else -0.5 * FILM_DT)


def _material(name: str) -> Material:
    try:
        return MATERIALS[name]
    except KeyError:
        raise ValueError(f"unknown material {name!r} (known: {', '.join(MATERIALS)})") from None


# ---------------------------------------------------------------------------------------
# Factory
# ---------------------------------------------------------------------------------------

def kinds() -> list[str]:
    """Every kind :func:`toucher` accepts: human parts, object presets, material names."""
    return [*HUMANS, *OBJECTS, *MATERIALS]


def toucher(kind: str, T_start: float | None = None, area: float | None = None,
            pressure: float | None = None, *, t_s: float = 1e-3, T_env: float = T_ENV) -> Toucher:
    """A toucher of ``kind`` (see :func:`kinds`), reset to ``T_start`` °C and ready to step.

    ``area`` (m²) and ``pressure`` (Pa) override the preset's; the contact conductance to
    ramp to is ``toucher.truth['G_true'] = h_c(pressure) area``. ``T_env`` is the room
    temperature a resting human toucher loses heat to (and the back of a cup's loss).
    """
    if not isinstance(kind, str):
        raise ValueError(f"toucher: kind must be a string, got {kind!r}")
    for what, v in (("T_start", T_start), ("area", area), ("pressure", pressure)):
        if v is not None and not (isinstance(v, int | float) and math.isfinite(v)):
            raise ValueError(f"toucher({kind!r}): {what} = {v!r} must be a finite number")
    if kind in HUMANS:
        part = HUMANS[kind]
        A = part.area if area is None else float(area)
        p = part.pressure if pressure is None else float(pressure)
        G = G_contact(A, p)
        hum = HumanTissue(part, area=A, t_s=t_s, T_env=T_env)
        T0 = T_SKIN_DEFAULT if T_start is None else float(T_start)
        hum.reset(T0)
        hum.truth = {"toucher_true": "human", "material_true": SKIN.name, "class_true": "human",
                     "contents_true": None, "perfusion_true": hum.w_b}
        tch: Toucher = hum
    else:
        if kind in OBJECTS:
            pre = OBJECTS[kind]
        elif kind in MATERIALS:
            pre = ObjectPreset(kind, ((kind, SLAB_THICKNESS),), T_ENV)
        else:
            raise ValueError(f"toucher: unknown kind {kind!r} (known: {', '.join(kinds())})")
        A = pre.area if area is None else float(area)
        p = pre.pressure if pressure is None else float(pressure)
        G = G_contact(A, p)
        tch = Solid([(MATERIALS[m], d) for m, d in pre.plies], A, t_s=t_s, reservoir=pre.reservoir,
                    T_back=T_env, kind=kind)
        T0 = pre.T_start if T_start is None else float(T_start)
        tch.reset(T0)
        tch.truth = {"toucher_true": "object", "material_true": pre.material_true.name,
                     "class_true": pre.class_,
                     "contents_true": None if pre.reservoir is None else pre.reservoir.liquid.name}
    tch.truth.update({"kind": kind, "T_f_true": T0, "G_true": G, "area_true": A, "pressure_true": p,
                      "effusivity_true": SKIN.effusivity if kind in HUMANS else
                      MATERIALS[tch.truth["material_true"]].effusivity})
    return tch
