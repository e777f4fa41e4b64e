"""The simulated skin (digital twin): the two-node network integrated exactly, and its sensors.

The network of docs/model.md (Fig. 3, eqs. 3-7; ``physics.network.state_space``)::

    C_w dT_w/dt = (T_p - T_w)/R_w(v) - (T_w - T_a)/R_aw - (T_w - T_g)/R_g
    C_g dT_g/dt = (T_w - T_g)/R_g + q_x + G_c (T_f - T_g) - (T_g - T_a)/R_ag

is advanced over one sample ``t_s`` with the inputs ``T_p, v, T_a, G_c, T_f, q_x`` held
(zero-order hold)::

    x[k+1] = Phi x[k] + Gamma u[k],   Phi = e^{A t_s},   Gamma = A^{-1} (Phi - I) B

which is exact for piecewise-constant inputs. ``Phi`` of the 2x2 ``A = [[a, b], [c, d]]``
is computed in closed form (``b c > 0``, so the eigenvalues ``m ± δ`` are real)::

    m = (a + d)/2,  δ = sqrt(((a - d)/2)^2 + b c)
    e^{A t} = e^{m t} [cosh(δ t) I + sinh(δ t)/δ (A - m I)]

and cached per ``(v, G_c)``, so that a step is a dozen float multiplications.

:class:`~thermoskin.sim.sensors.Sensors` (re-exported here) turns the true temperatures
into thermocouple readings.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from thermoskin.params import Config
from thermoskin.physics.convection import FlowResistance
from thermoskin.physics.finger import T_F_IDLE
from thermoskin.physics.network import state_space, steady_state
from thermoskin.sim.sensors import Sensors

__all__ = ["Sensors", "SimulatedSkin", "zoh_2x2", "zoh_coefficients", "zoh_scalars"]

Array = NDArray[np.float64]
Coefficients = tuple[float, float, float, float, float, float, float, float, float, float, float, float]

CACHE_SIZE = 4096
"""Most ``(v, G_c)`` discretisations kept; beyond that they are computed on each change."""


def zoh_scalars(a: float, b: float, c: float, d: float,
                t_s: float) -> tuple[float, float, float, float, float, float, float, float]:
    """``Phi = e^{A t_s}`` of ``A = [[a, b], [c, d]]`` with real eigenvalues (``b c >= 0``, module
    doc) and ``M = A^{-1} (Phi - I)`` (so that ``Gamma = M B``): ``(Phi11, Phi12, Phi21, Phi22,
    M11, M12, M21, M22)``. Plain floats: the sweep's batch compiles this same function."""
    m = 0.5 * (a + d)
    delta = math.sqrt((0.5 * (a - d)) ** 2 + b * c)
    x = delta * t_s
    if x < 20.0:
        e = math.exp(m * t_s)
        ch = e * math.cosh(x)
        sh = e * (math.sinh(x) / delta if delta > 0.0 else t_s)
    else:  # cosh and sinh would overflow long before e^{m t} underflows: use the two modes
        e1 = math.exp((m + delta) * t_s)
        e2 = math.exp((m - delta) * t_s)
        ch = 0.5 * (e1 + e2)
        sh = 0.5 * (e1 - e2) / delta
    p11 = ch + sh * (a - m)
    p12 = sh * b
    p21 = sh * c
    p22 = ch + sh * (d - m)
    # M = A^{-1} (Phi - I)
    det = a * d - b * c
    n11, n12, n21, n22 = p11 - 1.0, p12, p21, p22 - 1.0
    m11 = (d * n11 - b * n21) / det
    m12 = (d * n12 - b * n22) / det
    m21 = (-c * n11 + a * n21) / det
    m22 = (-c * n12 + a * n22) / det
    return p11, p12, p21, p22, m11, m12, m21, m22


def zoh_coefficients(A: Array, B: Array, t_s: float) -> Coefficients:
    """Exact ZOH discretisation of a 2x2 ``A`` (real eigenvalues) and 2x4 ``B`` as floats
    (:func:`zoh_scalars`). Returns ``(Phi11, Phi12, Phi21, Phi22, Gamma11..Gamma14,
    Gamma21..Gamma24)``.
    """
    a, b = float(A[0, 0]), float(A[0, 1])
    c, d = float(A[1, 0]), float(A[1, 1])
    if (0.5 * (a - d)) ** 2 + b * c < 0.0:
        raise ValueError("zoh_coefficients: complex eigenvalues (b c < 0 is not a thermal network)")
    p11, p12, p21, p22, m11, m12, m21, m22 = zoh_scalars(a, b, c, d, t_s)
    g1 = [m11 * float(B[0, j]) + m12 * float(B[1, j]) for j in range(4)]
    g2 = [m21 * float(B[0, j]) + m22 * float(B[1, j]) for j in range(4)]
    return (p11, p12, p21, p22, g1[0], g1[1], g1[2], g1[3], g2[0], g2[1], g2[2], g2[3])


def zoh_2x2(A: Array, B: Array, t_s: float) -> tuple[Array, Array]:
    """``(Phi, Gamma)`` as arrays, from :func:`zoh_coefficients`."""
    c = zoh_coefficients(A, B, t_s)
    return np.array([[c[0], c[1]], [c[2], c[3]]]), np.array([c[4:8], c[8:12]])


class SimulatedSkin:
    """The two-node skin, stepped exactly one ``t_s`` at a time.

    True state: ``T_w``, ``T_g`` (°C); ``q_i = G_c (T_f - T_g)`` (W) with the last
    applied contact. ``R_w(v)`` comes from :class:`~thermoskin.physics.convection.FlowResistance`.
    """

    def __init__(self, cfg: Config) -> None:
        self.cfg = cfg
        self.skin = cfg.skin
        self.t_s = cfg.sampling.t_s
        self.R_w = FlowResistance(cfg.skin)
        self._cache: dict[tuple[float, float], Coefficients] = {}
        self._v = math.nan
        self._G = math.nan
        self._c: Coefficients | None = None
        self.T_w = math.nan
        self.T_g = math.nan
        self.G_c = 0.0
        self.T_f = T_F_IDLE
        self.k = 0

    # -- discretisation ------------------------------------------------------------------
    def coefficients(self, v: float, G_c: float) -> Coefficients:
        """``Phi`` and ``Gamma`` (see :func:`zoh_coefficients`) for velocity ``v`` and contact ``G_c``."""
        key = (v, G_c)
        c = self._cache.get(key)
        if c is None:
            if G_c < 0.0 or v < 0.0:
                raise ValueError(f"SimulatedSkin: v = {v} m/s and G_c = {G_c} W/K must be >= 0")
            A, B = state_space(self.skin, self.R_w(v), G_c)
            c = zoh_coefficients(A, B, self.t_s)
            if len(self._cache) < CACHE_SIZE:
                self._cache[key] = c
        return c

    # -- state ---------------------------------------------------------------------------
    def T_g_equilibrium(self, T_w: float, T_a: float, G_c: float = 0.0, T_f: float = T_F_IDLE,
                        q_x: float = 0.0) -> float:
        """Sheet equilibrium for a given pipe temperature (``dT_g/dt = 0``)::

            T_g = (T_w/R_g + T_a/R_ag + G_c T_f + q_x) / (1/R_g + 1/R_ag + G_c)
        """
        Rg, Rag = self.skin.R_g, self.skin.R_ag
        return (T_w / Rg + T_a / Rag + G_c * T_f + q_x) / (1.0 / Rg + 1.0 / Rag + G_c)

    def reset(self, T_w0: float, T_g0: float | None = None, *, T_a: float = 20.0, G_c: float = 0.0,
              T_f: float = T_F_IDLE, q_x: float = 0.0) -> None:
        """Start at ``T_w0``; ``T_g0`` defaults to the sheet's equilibrium for ``T_w0`` and the inputs."""
        self.T_w = float(T_w0)
        self.T_g = float(T_g0) if T_g0 is not None else self.T_g_equilibrium(T_w0, T_a, G_c, T_f, q_x)
        self.G_c = float(G_c)
        self.T_f = float(T_f)
        self.k = 0

    def reset_equilibrium(self, T_p: float, v: float, T_a: float, G_c: float = 0.0,
                          T_f: float = T_F_IDLE, q_x: float = 0.0) -> None:
        """Start in the network's equilibrium for constant inputs (``A x + B u = 0``)."""
        x = steady_state(self.skin, self.R_w(v), np.array([T_p, T_a, q_x, T_f]), G_c)
        self.reset(float(x[0]), float(x[1]), T_a=T_a, G_c=G_c, T_f=T_f, q_x=q_x)

    @property
    def q_i(self) -> float:
        """Heat flow from the touch into the sheet, W: ``G_c (T_f - T_g)``."""
        return self.G_c * (self.T_f - self.T_g)

    @property
    def t(self) -> float:
        """Time since the last reset, s."""
        return self.k * self.t_s

    def step(self, T_p: float, v: float, T_a: float, G_c: float, T_f: float, q_x: float = 0.0) -> None:
        """Advance one ``t_s`` with the inputs held over the sample (exact for ZOH inputs)."""
        if v != self._v or G_c != self._G:
            self._c = self.coefficients(v, G_c)
            self._v = v
            self._G = G_c
        p11, p12, p21, p22, g11, g12, g13, g14, g21, g22, g23, g24 = self._c  # type: ignore[misc]
        w = self.T_w
        g = self.T_g
        self.T_w = p11 * w + p12 * g + g11 * T_p + g12 * T_a + g13 * q_x + g14 * T_f
        self.T_g = p21 * w + p22 * g + g21 * T_p + g22 * T_a + g23 * q_x + g24 * T_f
        self.G_c = G_c
        self.T_f = T_f
        self.k += 1
