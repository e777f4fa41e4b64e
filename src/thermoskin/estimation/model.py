"""The sensor-aware estimator's model: the network of Fig. 3 with the touch heat and the tank as states.

Patch state ``x = [T_w, T_g, q_i, T_p, r_p]`` (°C, °C, W, °C, K/s), inputs ``T_a`` (°C) and
the Peltier ``drive`` (in [-1, 1])::

    C_w dT_w/dt = (T_p - T_w)/R_w(v) - (T_w - T_a)/R_aw - (T_w - T_g)/R_g + w_w   (eqs. 1, 3; Fig. 3)
    C_g dT_g/dt = (T_w - T_g)/R_g + q_i - (T_g - T_a)/R_ag                        (eq. 4; Fig. 3)
    dq_i/dt = w_q          the touch's heat into the sheet: a random walk (S_q, W²/s)
    C_t dT_p/dt = C_t (r_p + β drive) - (T_p - T_w)/R_w(v) - (T_p - T_a)/R_ta      the tank
    dr_p/dt = w_p          the rest of the tank's rate (Joule heat, the sink): a random walk (S_p)

The tank's response to the drive is the Peltier's, linearised at zero drive:
``β = n S_m I_max (T_ref + 273.15) / C_tank`` (K/s per unit drive; the Peltier heat of
``physics.peltier``), unless ``estimator.tank_gain`` gives it. A log without the drive is
estimated with ``drive = 0``: ``r_p`` then carries the whole rate (a constant-velocity model).

``q_i`` is the paper's touch heat (``q_i`` of Fig. 3), so the estimate is of the heat the
touch brings to the sheet, not of its share that reaches the pipe. ``w`` is white process
noise with spectral densities ``S`` (``w_w`` for model error on the pipe node, ``S_w``; while
the pump runs ``S_w + S_w_flow``).

Each sample the state is advanced over ``t_s`` with ``v`` and ``T_a`` held (zero-order hold),
exactly (Van Loan, *Computing integrals involving the matrix exponential*, 1978)::

    Phi = e^{A t_s},   Gamma = ∫_0^{t_s} e^{A s} B ds,   Q_d = ∫_0^{t_s} e^{A s} S e^{A' s} ds

from one matrix exponential each: ``exp([[A, B], [0, 0]] t_s)`` and
``exp([[-A, S], [0, A']] t_s)``. ``R_w`` (eq. 1) depends on the pump's velocity, so the
tables are built per distinct ``v``.

The ambient filter ``x_a = [T_a, T_as]`` (true air, air sensor): ``dT_a/dt = w_a`` (S_a,
K²/s), ``tau_a dT_as/dt = T_a - T_as`` (a bead in still air lags the air by ``tau_a``);
the sensor reads ``T_as``. With ``tau_a = 0`` the sensor reads ``T_a`` itself.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from thermoskin.params import Config
from thermoskin.physics.convection import R_w as R_w_of
from thermoskin.physics.expm import expm
from thermoskin.physics.network import discretize

Array = NDArray[np.float64]

NX = 5
"""Patch state size: ``T_w, T_g, q_i, T_p, r_p``."""
I_TW, I_TG, I_Q, I_TP, I_DTP = range(NX)

RATE_TOL = 1e-6
"""The onset threshold follows the pipe readings' rate once the rate has moved by more than
this (relative) since the threshold was set: it then moves by at most ``h_rate`` 1e-6."""


def patch_matrices(cfg: Config, R_w: float, S_q: float | None = None) -> tuple[Array, Array, Array]:
    """Continuous ``(A, B, S)`` of the patch state for a water-to-pipe resistance ``R_w`` (K/W)
    (``S_q``: the touch heat's random-walk density, default ``estimator.S_q``)."""
    sk, es = cfg.skin, cfg.estimator
    Cw, Cg, Rg, Raw, Rag = sk.C_w, sk.C_g, sk.R_g, sk.R_aw, sk.R_ag
    A = np.zeros((NX, NX))
    A[I_TW, I_TW] = -(1 / R_w + 1 / Raw + 1 / Rg) / Cw
    A[I_TW, I_TG] = 1 / (Rg * Cw)
    A[I_TW, I_TP] = 1 / (R_w * Cw)
    A[I_TG, I_TW] = 1 / (Rg * Cg)
    A[I_TG, I_TG] = -(1 / Rg + 1 / Rag) / Cg
    A[I_TG, I_Q] = 1 / Cg
    Ct, Rta = cfg.peltier.C_tank, cfg.peltier.R_tank_air
    A[I_TP, I_DTP] = 1.0
    A[I_TP, I_TP] = -(1 / R_w + 1 / Rta) / Ct
    A[I_TP, I_TW] = 1 / (R_w * Ct)
    B = np.zeros((NX, 2))
    B[I_TW, 0] = 1 / (Raw * Cw)
    B[I_TG, 0] = 1 / (Rag * Cg)
    B[I_TP, 0] = 1 / (Rta * Ct)
    B[I_TP, 1] = tank_gain(cfg)
    S = np.diag([es.S_w, 0.0, es.S_q if S_q is None else S_q, 0.0, es.S_p])
    return A, B, S


def tank_gain(cfg: Config) -> float:
    """``β``, the tank's rate per unit drive (K/s): configured, or the Peltier's linearised."""
    if cfg.estimator.tank_gain is not None:
        return cfg.estimator.tank_gain
    pe = cfg.peltier
    return pe.n_modules * pe.S_m * pe.I_max * (cfg.skin.T_ref + 273.15) / pe.C_tank


def van_loan(A: Array, B: Array, S: Array, t_s: float) -> tuple[Array, Array, Array]:
    """Exact ZOH discretisation ``(Phi, Gamma, Q_d)`` of ``dx = A x dt + B u dt + dw``,
    ``E[dw dw'] = S dt``: ``Q_d = int_0^t_s e^{A s} S e^{A' s} ds`` by Van Loan's exponential
    of ``[[-A, S], [0, A']] h`` over a step ``h`` short enough that ``e^{-A h}`` stays moderate
    (``|A| h <= 2``), then doubled up to ``t_s``: ``Q(2h) = Phi(h) Q(h) Phi(h)' + Q(h)``. In one
    step over a long interval the formula cancels catastrophically (the network's fast mode,
    -89/s: at ``t_s`` = 0.5 s it gave a ``Q_d`` with a negative eigenvalue); up to 50 Hz
    (``|A| t_s`` about 1.8) it is one step, as before."""
    n = A.shape[0]
    Phi, Gam = discretize(A, B, t_s)
    a_h = float(np.abs(A).sum(axis=0).max()) * t_s
    k = math.ceil(math.log2(a_h / 2.0)) if a_h > 2.0 else 0
    h = t_s / 2**k
    F = np.zeros((2 * n, 2 * n))
    F[:n, :n] = -A
    F[:n, n:] = S
    F[n:, n:] = A.T
    G = expm(F * h)
    Q = G[n:, n:].T @ G[:n, n:]
    Phi_h = G[n:, n:].T  # e^{A h}
    for _ in range(k):
        Q = Phi_h @ Q @ Phi_h.T + Q
        Phi_h = Phi_h @ Phi_h
    Q = 0.5 * (Q + Q.T)
    return Phi, (Gam[:, 0] if B.ndim == 1 else Gam), Q


def ambient_matrices(tau_a: float, S_a: float) -> tuple[Array, Array]:
    """Continuous ``(A, S)`` of the ambient filter ``[T_a, T_as]``."""
    A = np.zeros((2, 2))
    if tau_a > 0.0:
        A[1, 0] = 1.0 / tau_a
        A[1, 1] = -1.0 / tau_a
    return A, np.diag([S_a, 0.0])


@dataclass(frozen=True)
class ModelTables:
    """The discretised model, ready for the kernel.

    ``Phi[i], Gam[i], Q[i]`` for the pump velocity ``v_values[i]`` (``Q`` while in contact,
    ``Q_idle`` while idle: only slow drift of ``q_i``); ``Phi_a, Q_a`` the ambient
    filter; ``R_T`` the thermocouple measurement variance (K²); ``amb_idx`` the ambient
    state the air sensor reads (1 with a lag, 0 without).
    """

    t_s: float
    v_values: tuple[float, ...]
    Phi: Array
    Gam: Array
    Q: Array
    Q_idle: Array
    Phi_a: Array
    Q_a: Array
    R_T: float
    amb_idx: int

    def index(self, v: float) -> int:
        """Row of the tables for velocity ``v`` (exact match; KeyError otherwise)."""
        try:
            return self.v_values.index(v)
        except ValueError:
            raise KeyError(f"no model tables for v = {v!r} m/s") from None


def measurement_variance(cfg: Config, channel: str = "T_w") -> float:
    """A channel's reading variance as configured (the estimator's prior; it learns the
    readings' own): ``noise² + quantum_T²/12`` (K²), ``noise`` the channel's
    (``sensor.noise_T_w`` etc., or ``noise_T``)."""
    s = cfg.sensor
    return s.noise(channel) ** 2 + s.quantum_T**2 / 12.0 + 1e-12


def build_tables(cfg: Config, t_s: float, v_values: tuple[float, ...] | list[float]) -> ModelTables:
    """Discretise the patch model for each velocity and the ambient filter at ``t_s``."""
    vs = tuple(dict.fromkeys(float(v) for v in v_values))
    Phi = np.empty((len(vs), NX, NX))
    Gam = np.empty((len(vs), NX, 2))
    Q = np.empty((len(vs), NX, NX))
    Q_idle = np.empty((len(vs), NX, NX))
    for i, v in enumerate(vs):
        A, B, S = patch_matrices(cfg, R_w_of(v, cfg.skin))
        if v > 0.0:  # water flowing in: the pipe node's own extra noise (estimator.S_w_flow)
            S[I_TW, I_TW] += cfg.estimator.S_w_flow
        Phi[i], Gam[i], Q[i] = van_loan(A, B, S, t_s)
        S[I_Q, I_Q] = cfg.estimator.S_q_idle  # idle: only slow drift of q_i
        Q_idle[i] = van_loan(A, B, S, t_s)[2]
    # q_i and r_p are random walks: their rows of Phi are unit rows and of Gamma zero, up to
    # the matrix exponential's rounding; made exact (the kernel relies on it)
    for r in (I_Q, I_DTP):
        assert np.allclose(Phi[:, r, :], np.eye(NX)[r], atol=1e-12) and np.allclose(Gam[:, r], 0.0)
        Phi[:, r, :] = np.eye(NX)[r]
        Gam[:, r, :] = 0.0
    tau_a = cfg.sensor.lag_T_a
    Aa, Sa = ambient_matrices(tau_a, cfg.estimator.S_a)
    Phi_a, _, Q_a = van_loan(Aa, np.zeros(2), Sa, t_s)
    return ModelTables(t_s=t_s, v_values=vs, Phi=Phi, Gam=Gam, Q=Q, Q_idle=Q_idle, Phi_a=Phi_a, Q_a=Q_a,
                       R_T=measurement_variance(cfg), amb_idx=1 if tau_a > 0.0 else 0)


def fixed_sensors(cfg: Config) -> Config:
    """``cfg`` with nothing learnt of the sensors: each channel's variance as configured
    (``estimator.tau_noise`` 0), the offsets and the pipe thermocouple's lag as configured
    (``sensor.offset_sd``, ``sensor.lag_sd`` 0), no dispersion (``detector.rho_window`` 0) and
    no pump-cycle correction (``estimator.switch_bins`` 0; a skin's patch fed from its tank
    sets its own): the filter as it was before it learnt them, linear in its readings (the
    tests of a mechanism that learning would blur use it)."""
    return cfg.replace(estimator={"tau_noise": 0.0, "switch_bins": 0},
                       sensor={"offset_sd": 0.0, "lag_sd": 0.0}, detector={"rho_window": 0.0})


def sheet_equilibrium(cfg: Config, T_w: float, T_a: float) -> float:
    """No-touch sheet temperature for a pipe at ``T_w`` (``dT_g/dt = 0``, ``q_i = 0``)."""
    Rg, Rag = cfg.skin.R_g, cfg.skin.R_ag
    return (T_w / Rg + T_a / Rag) / (1.0 / Rg + 1.0 / Rag)
