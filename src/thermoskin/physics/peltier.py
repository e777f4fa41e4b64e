"""Peltier modules between the water tank (``T_p``) and a heat sink with fan.

Per module, with current ``I = drive * I_max`` (``drive`` clipped to the drive limits;
``I > 0`` heats the tank), absolute temperatures ``θ = T + 273.15`` K in the Seebeck
(Peltier) terms, and the standard thermoelectric equations (Peltier heat ``S_m I θ`` at each
junction, half the Joule heat ``I^2 R_m`` to each face, conduction ``K_m`` through the legs)::

    Q_t = S_m I θ_t + ½ I² R_m - K_m (T_t - T_s)     heat into the tank face, W
    Q_s = -S_m I θ_s + ½ I² R_m + K_m (T_t - T_s)    heat into the sink face, W
    P   = S_m I (θ_t - θ_s) + I² R_m                 electric power (Seebeck voltage + ohmic)

so that ``Q_t + Q_s = P`` (first law: everything the module takes in as electricity goes
out through its two faces). With ``I < 0`` the tank face is the cold face:
``Q_t = -S_m |I| θ_t + ½ I² R_m - K_m ΔT`` is the textbook cooling capacity ``Q_c`` with
the sign flipped, and ``-Q_s`` is the heat the module draws from the sink, here negative:
the sink receives ``Q_h = Q_c + P``. Signs follow the current: reversing ``I`` swaps which
face is hot, the Joule term heats both faces whatever the sign. That term makes heating
and cooling asymmetric (``Q_t(+I) + Q_t(-I) = I² R_m - 2 K_m ΔT``), and ``I θ`` makes the
gain depend on the temperature: the tank's response to the drive is nonlinear.

The ``n_modules`` modules work in parallel (same current each). The two thermal nodes::

    C_tank dT_t/dt = n Q_t - (T_t - T_a)/R_tank_air - q_out
    C_sink dT_s/dt = n Q_s - (T_s - T_a)/R_sink

with ``q_out`` the heat the skin's water circuit takes from the tank (``q_p`` of docs/model.md).
For a held drive the right-hand side is *linear* in ``(T_t, T_s)`` (the nonlinearity is
in the drive: ``I θ`` and ``I²``), so the steady state is a 2x2 linear solve.

Integration: with the default parameters the fastest time constant is about 16 s (sink:
``C_sink / (1/R_sink + n K_m)``) and the slowest about 170 s, so a ``t_s = 1 ms`` step is
1e-4 of the fastest one. :meth:`PeltierTank.step` takes classical RK4 sub-steps no longer
than ``τ_min / 50`` (one sub-step at 1 ms); the local error is then ~1e-20 relative and the
step is exact to rounding for a drive held over the sample (zero-order hold). Tests
compare it with ``solve_ivp``.
"""

from __future__ import annotations

import math

import numpy as np

from thermoskin.params import PeltierParams

KELVIN = 273.15


def module_heats(i_m: float, T_t: float, T_s: float, p: PeltierParams) -> tuple[float, float, float]:
    """``(Q_t, Q_s, P)`` of one module at current ``i_m`` (A), W (see the module doc); T in °C."""
    th_t = T_t + KELVIN
    th_s = T_s + KELVIN
    joule = 0.5 * i_m * i_m * p.R_m
    cond = p.K_m * (T_t - T_s)
    Q_t = p.S_m * i_m * th_t + joule - cond
    Q_s = -p.S_m * i_m * th_s + joule + cond
    P = p.S_m * i_m * (th_t - th_s) + i_m * i_m * p.R_m
    return Q_t, Q_s, P


def tank_linear(n: float, S_m: float, K_m: float, R_m: float, C_tank: float, C_sink: float,
                g_tank: float, g_sink: float, i_m: float, T_a: float,
                q_out: float) -> tuple[float, float, float, float, float, float]:
    """The two nodes' ``dT/dt = A T + b`` for a held module current ``i_m`` (A), ``T_a`` and
    ``q_out`` (module doc; ``g_tank = 1/R_tank_air``, ``g_sink = 1/R_sink``):
    ``(a11, a12, a21, a22, b1, b2)``. Plain floats in, plain floats out: the sweep's batch
    compiles this same function (``sweep.kernel``)."""
    SI = S_m * i_m
    joule = 0.5 * (i_m * i_m * R_m)
    a11 = (n * (SI - K_m) - g_tank) / C_tank
    a12 = n * K_m / C_tank
    a21 = n * K_m / C_sink
    a22 = (n * (-SI - K_m) - g_sink) / C_sink
    b1 = (n * (SI * KELVIN + joule) + g_tank * T_a - q_out) / C_tank
    b2 = (n * (-SI * KELVIN + joule) + g_sink * T_a) / C_sink
    return a11, a12, a21, a22, b1, b2


def rk4_pair(x: float, y: float, a11: float, a12: float, a21: float, a22: float, b1: float,
             b2: float, h: float, n_sub: int) -> tuple[float, float]:
    """``n_sub`` classical RK4 steps of ``h`` of ``d(x, y)/dt = A (x, y) + b`` (the tank and the
    sink for a held drive); compiled by the sweep's batch too."""
    h2 = 0.5 * h
    h6 = h / 6.0
    for _ in range(n_sub):
        k1x = a11 * x + a12 * y + b1
        k1y = a21 * x + a22 * y + b2
        x2, y2 = x + h2 * k1x, y + h2 * k1y
        k2x = a11 * x2 + a12 * y2 + b1
        k2y = a21 * x2 + a22 * y2 + b2
        x3, y3 = x + h2 * k2x, y + h2 * k2y
        k3x = a11 * x3 + a12 * y3 + b1
        k3y = a21 * x3 + a22 * y3 + b2
        x4, y4 = x + h * k3x, y + h * k3y
        k4x = a11 * x4 + a12 * y4 + b1
        k4y = a21 * x4 + a22 * y4 + b2
        x += h6 * (k1x + 2.0 * (k2x + k3x) + k4x)
        y += h6 * (k1y + 2.0 * (k2y + k3y) + k4y)
    return x, y


def cop(i_m: float, T_t: float, T_s: float, p: PeltierParams) -> float:
    """Coefficient of performance of the tank side: heating ``Q_t/P`` (``I > 0``) or cooling ``-Q_t/P``."""
    Q_t, _, P = module_heats(i_m, T_t, T_s, p)
    return (Q_t if i_m > 0 else -Q_t) / P


class PeltierTank:
    """The tank and the heat sink driven by the Peltier modules, stepped one ``t_s`` at a time.

    State: ``T_p`` (tank, °C), ``T_sink`` (°C). After :meth:`step`: ``i_module`` (A per module),
    ``P_elec`` (W, all modules, at the start of the step), ``Q_tank`` / ``Q_sink`` (W, all
    modules, into the tank / sink faces at the start of the step).
    """

    def __init__(self, params: PeltierParams, t_s: float,
                 drive_limits: tuple[float, float] = (-1.0, 1.0)) -> None:
        lo, hi = float(drive_limits[0]), float(drive_limits[1])
        if not (-1.0 <= lo <= 0.0 <= hi <= 1.0):
            raise ValueError(f"PeltierTank: drive_limits = {drive_limits} must satisfy "
                             "-1 <= lo <= 0 <= hi <= 1")
        if not (t_s > 0.0 and math.isfinite(t_s)):
            raise ValueError(f"PeltierTank: t_s = {t_s} must be a positive number of seconds")
        self.params = params
        self.t_s = float(t_s)
        self.drive_min, self.drive_max = lo, hi
        p = params
        n = p.n_modules
        # Worst case (largest) rate of the linearised system: any eigenvalue's modulus is below
        # the largest Gershgorin row sum of |A| at |I| = I_max.
        SI = p.S_m * p.I_max
        r_t = (n * (p.K_m + SI) + 1.0 / p.R_tank_air + n * p.K_m) / p.C_tank
        r_s = (n * (p.K_m + SI) + 1.0 / p.R_sink + n * p.K_m) / p.C_sink
        self.tau_min = 1.0 / max(r_t, r_s)
        self.n_sub = max(1, math.ceil(self.t_s / (self.tau_min / 50.0)))
        self._h = self.t_s / self.n_sub
        self._g_tank, self._g_sink = 1.0 / p.R_tank_air, 1.0 / p.R_sink
        self.T_p = math.nan
        self.T_sink = math.nan
        self.i_module = 0.0
        self.P_elec = 0.0
        self.Q_tank = 0.0
        self.Q_sink = 0.0

    # -- helpers -------------------------------------------------------------------------
    def current(self, drive: float) -> float:
        """Module current, A: ``clip(drive, drive_min, drive_max) * I_max``."""
        d = min(max(float(drive), self.drive_min), self.drive_max)
        return d * self.params.I_max

    def _linear(self, i_m: float, T_a: float,
                q_out: float) -> tuple[float, float, float, float, float, float]:
        """``dT/dt = A T + b`` for a held current: ``(a11, a12, a21, a22, b1, b2)`` (:func:`tank_linear`)."""
        p = self.params
        return tank_linear(p.n_modules, p.S_m, p.K_m, p.R_m, p.C_tank, p.C_sink, self._g_tank,
                           self._g_sink, i_m, T_a, q_out)

    def rhs(self, drive: float, T_a: float, T_p: float, T_sink: float,
            q_out: float = 0.0) -> tuple[float, float]:
        """``(dT_p/dt, dT_sink/dt)``, K/s."""
        a11, a12, a21, a22, b1, b2 = self._linear(self.current(drive), T_a, q_out)
        return a11 * T_p + a12 * T_sink + b1, a21 * T_p + a22 * T_sink + b2

    # -- state ---------------------------------------------------------------------------
    def reset(self, T_p: float, T_sink: float | None = None, T_a: float = 20.0) -> None:
        """Start at ``T_p``; ``T_sink`` defaults to ``T_a`` (fan running, module off)."""
        self.T_p = float(T_p)
        self.T_sink = float(T_a if T_sink is None else T_sink)
        self.i_module = 0.0
        self.P_elec = self.Q_tank = self.Q_sink = 0.0

    def reset_steady(self, drive: float, T_a: float = 20.0, q_out: float = 0.0) -> None:
        """Start in the steady state for a held ``drive``, ``T_a`` and ``q_out``."""
        T_p, T_s = self.steady_state(drive, T_a, q_out)
        self.reset(T_p, T_s, T_a)

    def step(self, drive: float, T_a: float, q_out: float = 0.0) -> None:
        """Advance one ``t_s`` with ``drive`` (clipped), ``T_a`` and ``q_out`` held (RK4 sub-steps)."""
        p = self.params
        d = drive if drive < self.drive_max else self.drive_max
        if d < self.drive_min:
            d = self.drive_min
        i_m = d * p.I_max
        n = p.n_modules
        a11, a12, a21, a22, b1, b2 = tank_linear(n, p.S_m, p.K_m, p.R_m, p.C_tank, p.C_sink,
                                                 self._g_tank, self._g_sink, i_m, T_a, q_out)
        SI = p.S_m * i_m
        I2R = i_m * i_m * p.R_m
        x, y = self.T_p, self.T_sink
        dT = x - y
        self.i_module = i_m
        self.P_elec = n * (SI * dT + I2R)
        self.Q_tank = n * (SI * (x + KELVIN) + 0.5 * I2R - p.K_m * dT)
        self.Q_sink = self.P_elec - self.Q_tank
        self.T_p, self.T_sink = rk4_pair(x, y, a11, a12, a21, a22, b1, b2, self._h, self.n_sub)

    # -- steady state --------------------------------------------------------------------
    def steady_state(self, drive: float, T_a: float = 20.0, q_out: float = 0.0) -> tuple[float, float]:
        """``(T_p, T_sink)`` in steady state for a held drive: the 2x2 linear solve ``A T = -b``.

        Raises ``ValueError`` if that equilibrium is unstable (Seebeck feedback
        ``n S_m I`` beyond the losses: the tank would run away).
        """
        a11, a12, a21, a22, b1, b2 = self._linear(self.current(drive), T_a, q_out)
        A = np.array([[a11, a12], [a21, a22]])
        if np.max(np.linalg.eigvals(A).real) >= 0.0:
            raise ValueError(f"PeltierTank.steady_state: no stable equilibrium at drive = {drive}")
        T = np.linalg.solve(A, [-b1, -b2])
        return float(T[0]), float(T[1])

    def drive_for(self, T_p: float, T_a: float = 20.0, q_out: float = 0.0) -> float:
        """The drive whose steady state is ``T_p`` (``scipy.optimize.brentq`` over the drive limits).

        Raises ``ValueError`` if ``T_p`` is out of reach within the limits.
        """
        def f(d: float) -> float:
            return self.steady_state(d, T_a, q_out)[0] - T_p

        lo, hi = self.drive_min, self.drive_max
        f_lo, f_hi = f(lo), f(hi)
        if f_lo > 0.0 or f_hi < 0.0:
            lo_T, hi_T = f_lo + T_p, f_hi + T_p
            raise ValueError(f"PeltierTank.drive_for: T_p = {T_p} °C is out of reach "
                             f"({lo_T:.2f} to {hi_T:.2f} °C at T_a = {T_a} °C)")
        from scipy.optimize import brentq  # here: importing it costs every command 0.4 s

        return float(brentq(f, lo, hi, xtol=1e-12))
