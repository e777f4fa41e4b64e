"""The spatial skin as a drop-in replacement of :class:`~thermoskin.sim.skin.SimulatedSkin`.

The network of :mod:`thermoskin.physics.spatial` (cells along the pipe, water carried by
the flow, graphite sheet conducting along its length, thermocouple on the pipe of cell 0)
is advanced over one sample ``t_s`` with the inputs held (zero-order hold)::

    x[k+1] = Phi x[k] + Gamma u[k],   [Phi Gamma; 0 I] = expm([A B; 0 0] t_s)

exact for piecewise-constant inputs. ``[Phi | Gamma]`` is cached per
``(v, G_c, position)``; a step is one matrix-vector product on preallocated arrays.

With ``track_exchange`` set, a step also gives ``q_water``: the heat the water (or, the pump
stopped, the still water at the two ends) brought into the skin, averaged over the sample,
exactly (the integral of ``c_x x + c_u u`` over the sample from the same augmented matrix
exponential, ``c_x, c_u`` the water's terms of the model). A tank that loses ``q_water`` loses
exactly what the skin gains: the loop conserves energy.

Outputs, as :class:`SimulatedSkin`'s: ``T_w`` is the pipe at the thermocouple (cell 0,
what the real prototype measures); ``T_g`` is the sheet *under the touch* (the
contact-weighted mean of the touched cells at the last ``position``), which is the
temperature the finger feels; ``q_i = G_c (T_f - T_g)`` is then the touch's heat flow
exactly. ``T_w_cells``, ``T_g_cells`` give the profiles and ``T_g_mean`` the sheet mean.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from thermoskin.params import Config
from thermoskin.physics.convection import FlowResistance
from thermoskin.physics.finger import T_F_IDLE
from thermoskin.physics.spatial import (
    TC_CELL,
    SpatialParams,
    capacitances,
    spatial_state_space,
    spatial_steady_state,
)

Array = NDArray[np.float64]

CACHE_SIZE = 1024
"""Most ``(v, G_c, position)`` discretisations kept (8 kB each for 15 cells); a new key
costs one ``expm`` of the (n + 4)-square augmented matrix, about a millisecond."""


class SpatialSkin:
    """The spatial skin stepped exactly one ``t_s`` at a time (same interface as ``SimulatedSkin``).

    ``step(..., position=x)`` puts the touch (``G_c``, ``T_f``) and ``q_x`` on the cell(s)
    at normalised position ``x`` (0 = the thermocouple end, 1 = the far end).
    """

    def __init__(self, cfg: Config, sp: SpatialParams | None = None) -> None:
        self.cfg = cfg
        self.skin = cfg.skin
        self.sp = sp or SpatialParams()
        self.t_s = cfg.sampling.t_s
        self.R_w = FlowResistance(cfg.skin)
        self.n = self.sp.n_states
        self.N = self.sp.n_cells
        self.C = capacitances(self.skin, self.sp)
        self._cache: dict[tuple[float, float, float], Array] = {}
        self._key: tuple[float, float, float] | None = None
        self._M: Array = np.zeros((self.n, self.n + 4))
        self._z = np.full(self.n + 4, math.nan)  # [x; u]
        self._x_new = np.empty(self.n)
        self._xcache: dict[tuple[float, float, float], Array] = {}
        self._row: Array = np.zeros(self.n + 4)
        self.track_exchange = False
        self.q_water = 0.0
        self.G_c = 0.0
        self.T_f = T_F_IDLE
        self.position = 0.0
        self._weights: dict[int, float] = {TC_CELL: 1.0}
        self.k = 0

    # -- discretisation ------------------------------------------------------------------
    def matrices(self, v: float, G_c: float, position: float = 0.0) -> tuple[Array, Array]:
        """Continuous ``(A, B)`` for velocity ``v``, contact ``G_c`` at ``position``."""
        if G_c < 0.0 or v < 0.0:
            raise ValueError(f"SpatialSkin: v = {v} m/s and G_c = {G_c} W/K must be >= 0")
        shares = self.sp.shares(position)
        contact = {i: G_c * s for i, s in shares.items()}
        return spatial_state_space(self.skin, self.sp, v, self.R_w(v), contact, q_weights=shares)

    def transition(self, v: float, G_c: float, position: float = 0.0) -> Array:
        """``[Phi | Gamma]`` (n x (n + 4)) for one sample, exact ZOH (cached)."""
        key = (v, G_c, position)
        M = self._cache.get(key)
        if M is None:
            A, B = self.matrices(v, G_c, position)
            n = self.n
            aug = np.zeros((n + 4, n + 4))
            aug[:n, :n] = A
            aug[:n, n:] = B
            M = np.ascontiguousarray(scipy.linalg.expm(aug * self.t_s)[:n, :])
            if len(self._cache) < CACHE_SIZE:
                self._cache[key] = M
        return M

    def exchange_row(self, v: float, G_c: float, position: float = 0.0) -> Array:
        """Row ``r`` (length n + 4): ``r . [x_k; u_k]`` is the mean heat, W, the water brings to the
        skin over the sample (cached)."""
        key = (v, G_c, position)
        r = self._xcache.get(key)
        if r is None:
            A, B = self.matrices(v, G_c, position)
            cx, cu = water_exchange(A, B, self.C, self.N, self.sp.inlet, v)
            n = self.n
            aug = np.zeros((n + 5, n + 5))
            aug[:n, :n] = A
            aug[:n, n + 1:] = B
            aug[n, :n] = cx
            aug[n, n + 1:] = cu
            E = scipy.linalg.expm(aug * self.t_s)
            r = np.concatenate([E[n, :n], E[n, n + 1:]]) / self.t_s
            if len(self._xcache) < CACHE_SIZE:
                self._xcache[key] = r
        return r

    # -- state ---------------------------------------------------------------------------
    @property
    def x(self) -> Array:
        """The state vector (a view): pipe cells, sheet cells (, foam cells), °C."""
        return self._z[:self.n]

    @property
    def T_w(self) -> float:
        """Pipe (with its water) at the thermocouple, cell 0, °C."""
        return float(self._z[TC_CELL])

    @property
    def T_w_cells(self) -> Array:
        """Pipe temperatures of all cells, °C (a copy)."""
        return self._z[:self.N].copy()

    @property
    def T_g_cells(self) -> Array:
        """Sheet temperatures of all cells, °C (a copy)."""
        return self._z[self.N:2 * self.N].copy()

    @property
    def T_g(self) -> float:
        """Sheet under the touch: ``sum_i s_i T_g_i`` with the touch's shares ``s_i``, °C."""
        z, N = self._z, self.N
        return float(sum(s * z[N + i] for i, s in self._weights.items()))

    @property
    def T_g_mean(self) -> float:
        """Mean sheet temperature, °C."""
        return float(np.mean(self._z[self.N:2 * self.N]))

    @property
    def q_i(self) -> float:
        """Heat flow from the touch into the sheet, W: ``G_c (T_f - T_g)``."""
        return self.G_c * (self.T_f - self.T_g)

    @property
    def t(self) -> float:
        """Time since the last reset, s."""
        return self.k * self.t_s

    def _set_contact(self, G_c: float, T_f: float, position: float) -> None:
        self.G_c = float(G_c)
        self.T_f = float(T_f)
        if position != self.position:
            self._weights = self.sp.shares(position)
            self.position = float(position)

    def reset(self, T_w0: float, T_g0: float | None = None, *, T_a: float = 20.0, G_c: float = 0.0,
              T_f: float = T_F_IDLE, q_x: float = 0.0, position: float = 0.0) -> None:
        """Start with every pipe cell at ``T_w0``.

        ``T_g0`` given: every sheet cell at ``T_g0`` (and foam cells between). Otherwise the
        sheet (and foam) take their equilibrium for the pipe held at ``T_w0`` and the inputs,
        lateral conduction included (the spatial analogue of
        ``SimulatedSkin.T_g_equilibrium``).
        """
        self._weights = self.sp.shares(position)
        self.position = float(position)
        N, n = self.N, self.n
        z = self._z
        z[:N] = float(T_w0)
        if T_g0 is not None:
            z[N:2 * N] = float(T_g0)
            if self.sp.has_foam:
                z[2 * N:n] = 0.5 * (float(T_w0) + float(T_a))
        else:
            A, B = self.matrices(0.0, G_c, position)
            u = np.array([0.0, T_a, q_x, T_f])
            rest = slice(N, n)
            rhs = -(A[rest, :N] @ z[:N] + B[rest] @ u)
            z[N:n] = np.linalg.solve(A[rest, rest], rhs)
        self._set_contact(G_c, T_f, position)
        self._key = None
        self.k = 0

    def reset_equilibrium(self, T_p: float, v: float, T_a: float, G_c: float = 0.0,
                          T_f: float = T_F_IDLE, q_x: float = 0.0, position: float = 0.0) -> None:
        """Start in the network's equilibrium for constant inputs (``A x + B u = 0``)."""
        shares = self.sp.shares(position)
        contact = {i: G_c * s for i, s in shares.items()}
        x = spatial_steady_state(self.skin, self.sp, v, self.R_w(v), np.array([T_p, T_a, q_x, T_f]),
                                 contact, q_weights=shares)
        self._z[:self.n] = x
        self._weights = shares
        self.position = float(position)
        self._set_contact(G_c, T_f, position)
        self._key = None
        self.k = 0

    def step(self, T_p: float, v: float, T_a: float, G_c: float, T_f: float, q_x: float = 0.0,
             position: float = 0.0) -> None:
        """Advance one ``t_s`` with the inputs held over the sample (exact for ZOH inputs)."""
        key = (v, G_c, position)
        if key != self._key:
            self._M = self.transition(v, G_c, position)
            if self.track_exchange:
                self._row = self.exchange_row(v, G_c, position)
            self._key = key
        z = self._z
        n = self.n
        z[n] = T_p
        z[n + 1] = T_a
        z[n + 2] = q_x
        z[n + 3] = T_f
        if self.track_exchange:
            self.q_water = float(np.dot(self._row, z))
        np.dot(self._M, z, out=self._x_new)
        z[:n] = self._x_new
        self.G_c = G_c
        self.T_f = T_f
        if position != self.position:
            self._weights = self.sp.shares(position)
            self.position = position
        self.k += 1

    def energy(self, T_ref: float = 0.0) -> float:
        """Stored heat relative to ``T_ref``, J: ``sum_i C_i (x_i - T_ref)``."""
        return float(self.C @ (self._z[:self.n] - T_ref))


def water_exchange(A: Array, B: Array, C: Array, N: int, inlet: str, v: float) -> tuple[Array, Array]:
    """``(c_x, c_u)``: the heat the water brings into the skin, ``c_x . x + c_u . u`` (W).

    Read off the model itself: the terms of ``C_i dx_i/dt`` (``C`` the capacitances) that
    involve ``u[0]`` (the inlet water, or the tank through still water), plus, flowing, the
    water leaving the outlet cell (``-W T_w,out``, so that the sum is ``W (T_in - T_w,out)``),
    or, still, the ends' own ``-W/2 T_w,end`` terms.
    """
    n = A.shape[0]
    cu = np.zeros(4)
    cx = np.zeros(n)
    g_in = B[:N, 0] * C[:N]  # conductance of each pipe cell to u[0], W/K
    cu[0] = float(g_in.sum())
    if v > 0.0:
        out = 0 if inlet == "far" else N - 1
        cx[out] -= cu[0]
    else:
        cx[:N] -= g_in
    return cx, cu
