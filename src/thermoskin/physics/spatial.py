"""A spatial skin: cells along the pipe, calibrated so that, lumped, it is Table I's network.

Why: the two-node network of Fig. 3 has one pipe node and one sheet node, so it cannot
tell *where* a finger touches. The paper's Fig. 19 shows the estimate falling with the
distance between the touch and the thermocouple ("thermal attenuation"); this model
reproduces that for the simulator while the observer keeps its two-node model, as on the
real prototype.

Geometry (paper, Sec. III): a skin of ``length x width = 30 mm x 10 mm``; a nickel-copper
pipe of inner diameter 1.9 mm runs along its length between a graphite sheet of 0.5 mm
(above) and a foam of 5 mm (below). The skin is cut into ``N`` cells of length
``dx = length / N`` along the pipe; cell ``i`` is centred at ``x_i = (i + 1/2)/N``
(normalised position, 0 = the thermocouple end). The thermocouple sits on the pipe of
cell 0.

States (°C), ``x = [T_w_0 .. T_w_{N-1}, T_g_0 .. T_g_{N-1}, (T_f_0 .. T_f_{N-1})]``: the pipe
wall with its water, the sheet above it and, when ``C_foam > 0``, the foam below it.
Inputs, as in :func:`thermoskin.physics.network.state_space`: ``u = [T_p, T_a, q_x, T_f]``.
Per cell, with ``c_i = C_w/N`` and so on (every per-cell value is Table I's lumped value
divided by ``N``, see *calibration*)::

    C_w/N dT_w_i/dt = a_i + G_wl (T_w_{i-1} - 2 T_w_i + T_w_{i+1})
                      - (T_w_i - T_a) / (N R_aw) - (T_w_i - T_g_i) / (N R_g)
    C_g/N dT_g_i/dt = (T_w_i - T_g_i) / (N R_g) + G_gl (T_g_{i-1} - 2 T_g_i + T_g_{i+1})
                      - (T_g_i - T_a) / (N R_ag) + G_c,i (T_f - T_g_i) + w_i q_x

(no conduction past the two ends: a missing neighbour drops its term).

- Lateral conduction: sheet ``G_gl = k_sheet width t_sheet / dx``; pipe wall and the water
  in it ``G_wl = (k_pipe A_wall + k_water A_bore) / dx``, ``A_wall = pi/4 (d_o^2 - d_i^2)``,
  ``A_bore = pi/4 d_i^2``, ``d_o = d_i + 2 t_wall``.
- Water, ``a_i`` (the heat the water brings to cell ``i``). Eq. 1's ``R_w(v)`` lumps the
  tank-to-pipe exchange. We keep it, and carry it along the pipe:

  * pump running (``v > 0``): upwind advection with heat-capacity rate ``W = 1/R_w(v)``
    (W/K), the water entering the inlet cell at ``T_p``::

        a_i = W (T_w_{up(i)} - T_w_i),   T_w_{up(inlet)} = T_p,

    ``up(i)`` the neighbour upstream. Summed over the cells this is
    ``q_p = W (T_p - T_w_outlet)``: for a uniform pipe exactly eq. 1.
  * pump stopped (``v = 0``): still water, pure conduction from the tank through both
    silicone pipes (the loop reaches the skin at both ends):
    ``a_0 = (T_p - T_w_0)/(2 R_w)``, ``a_{N-1} = (T_p - T_w_{N-1})/(2 R_w)``; again eq. 1
    for a uniform pipe.

  *Where is the inlet?* ``inlet = "far"`` (default) lets the water enter at ``x = 1`` and
  leave past the thermocouple at ``x = 0``. Then ``W (T_p - T_w_0)``, the observer's
  ``q_p = (T_p - T_w)/R_w`` with the measured ``T_w``, is *exactly* the heat the water
  brings into the skin, whatever the temperature profile (the outlet temperature sums
  every cell's exchange): the observer's pump path stays right. The paper does not say
  which end is which; ``inlet = "near"`` is the other choice (the thermocouple then sees
  fresh tank water while the pump runs, and a touch downstream hardly reaches it).
  The physical capacity rate of the flow, ``rho c_p v pi d_i^2/4`` ≈ 1.7 W/K at 0.141 m/s,
  is of the order of ``1/R_w`` ≈ 5 W/K; we take ``1/R_w`` so that the lumped limit holds.
- Foam: Table I has no foam node (its storage and loss were identified into ``C_w``,
  ``R_aw``), so by default (``C_foam = 0``) the foam is the resistance ``N R_aw`` from each
  pipe cell to air. With ``C_foam > 0`` each cell gets a foam node of ``C_foam/N`` between
  the pipe and the air, the resistance ``N R_aw`` split ``foam_split : 1 - foam_split``::

      C_foam/N dT_f_i/dt = (T_w_i - T_f_i)/(s N R_aw) - (T_f_i - T_a)/((1 - s) N R_aw)

  (and the pipe's air term becomes ``-(T_w_i - T_f_i)/(s N R_aw)``): in steady state the
  pipe still loses ``(T_w - T_a)/R_aw``.
- Touch: ``G_c,i = G_c s_i`` with the shares ``s_i`` of :func:`contact_cells`: a touch at
  ``x`` covers the cells under a fingertip (``contact_length``, 10 mm: a third of the skin);
  ``w_i`` the share of ``q_x`` of cell ``i`` (by default the touch's shares).

Calibration (the lumped limit): per-cell values are Table I's divided by ``N``, so that
``sum C_w,i = C_w``, ``sum C_g,i = C_g``, ``sum 1/R_g,i = 1/R_g``, ``sum 1/R_ag,i = 1/R_ag``,
``sum 1/R_aw,i = 1/R_aw`` and the water brings ``(T_p - T_w)/R_w`` to a uniform pipe.
Lateral conduction and advection cancel in the sums, so with a uniform state the summed
equations *are* the two-node network, and for infinite lateral conductivity the model
is the two-node network. With the real graphite (``k_sheet`` a few hundred W/(m K)) the
sheet's decay length ``sqrt(k_sheet t_sheet width R_ag length)`` ≈ 7 mm is a quarter of
the skin: a touch is local, which is the point of the model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from thermoskin.params import ConfigError, SkinParams, _p, _Validated

Array = NDArray[np.float64]

TC_CELL = 0
"""Index of the cell whose pipe carries the thermocouple (the end ``x = 0``)."""


@dataclass(frozen=True)
class SpatialParams(_Validated):
    """Geometry and materials of the spatial skin (see the module docstring).

    Sources: geometry from the paper (Sec. III). ``k_sheet``: natural (flexible) graphite
    sheet conducts a few hundred W/(m K) in plane, rising with its density (Cermak,
    Perez, Collins, Bahrami, "Material properties and structure of natural graphite
    sheet", Sci. Rep. 10, 18672, 2020; Solfiti and Berto, "A review on thermophysical
    properties of flexible graphite", Procedia Struct. Integr. 26, 2020); thin pyrolytic
    films (PGS) reach 700-1900 W/(m K), a 0.5 mm sheet is the natural kind, 300 W/(m K) is
    taken. ``k_pipe``: copper-nickel alloys (CuNi 70/30 about 29, CuNi 90/10 about
    45 W/(m K)); the wall thickness is not given in the paper (assumption).
    """

    section = "spatial"
    n_cells: int = _p(15, "", 1, 200, doc="cells along the pipe")
    length: float = _p(0.03, "m", 0, 1.0, lo_open=True, doc="length of the skin along the pipe")
    width: float = _p(0.01, "m", 0, 1.0, lo_open=True, doc="width of the skin (sheet)")
    t_sheet: float = _p(0.5e-3, "m", 0, 0.01, lo_open=True, doc="graphite sheet thickness")
    k_sheet: float = _p(300.0, "W/(m K)", 0, 1e7, doc="in-plane conductivity of the graphite sheet")
    d_i: float = _p(1.9e-3, "m", 0, 0.05, lo_open=True, doc="inner diameter of the skin's pipe")
    t_wall: float = _p(0.2e-3, "m", 0, 0.01, doc="pipe wall thickness (assumption)")
    k_pipe: float = _p(30.0, "W/(m K)", 0, 1e7, doc="conductivity of the nickel-copper pipe wall")
    k_water: float = _p(0.6, "W/(m K)", 0, 1e7, doc="conductivity of the water along the bore")
    C_foam: float = _p(0.0, "J/K", 0, 100.0,
                       doc="heat capacity of the foam; 0 = no foam nodes (Table I has none)")
    foam_split: float = _p(0.5, "", 0, 1.0, lo_open=True,
                           doc="share of R_aw between pipe and foam node (C_foam > 0)")
    contact_length: float = _p(0.01, "m", 0, 1.0,
                               doc="length of a touch along the skin (a fingertip of about 1 cm^2 on "
                                   "the 10 mm wide skin); 0 = a point")
    inlet: str = _p("far", "", choices=("far", "near"),
                    doc="end where the water enters: far (x = 1) or near (x = 0, thermocouple)")

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.contact_length > self.length:
            raise ConfigError(f"spatial.contact_length = {self.contact_length} m must not exceed "
                              f"spatial.length = {self.length} m")
        if self.C_foam > 0 and self.foam_split >= 1.0:
            raise ConfigError(f"spatial.foam_split = {self.foam_split} must be < 1 when C_foam > 0")

    @property
    def dx(self) -> float:
        """Cell length, m."""
        return self.length / self.n_cells

    @property
    def has_foam(self) -> bool:
        """Whether the foam has nodes (``C_foam > 0``)."""
        return self.C_foam > 0.0

    @property
    def n_states(self) -> int:
        """``2 N`` or ``3 N`` with foam nodes."""
        return (3 if self.has_foam else 2) * self.n_cells

    def G_sheet_lateral(self) -> float:
        """``k_sheet width t_sheet / dx``, W/K, between neighbouring sheet cells."""
        return self.k_sheet * self.width * self.t_sheet / self.dx

    def G_pipe_lateral(self) -> float:
        """``(k_pipe A_wall + k_water A_bore)/dx``, W/K, between neighbouring pipe cells."""
        d_o = self.d_i + 2.0 * self.t_wall
        a_wall = 0.25 * math.pi * (d_o**2 - self.d_i**2)
        a_bore = 0.25 * math.pi * self.d_i**2
        return (self.k_pipe * a_wall + self.k_water * a_bore) / self.dx

    @property
    def footprint(self) -> float:
        """``contact_length / length``, the touch's share of the skin's length."""
        return self.contact_length / self.length

    def shares(self, position: float) -> dict[int, float]:
        """:func:`contact_cells` of a touch at ``position`` with this skin's footprint."""
        return contact_cells(position, self.n_cells, self.footprint)

    def centres(self) -> Array:
        """Normalised cell centres ``(i + 1/2)/N``."""
        return (np.arange(self.n_cells) + 0.5) / self.n_cells


def contact_cells(position: float, n_cells: int, footprint: float = 0.0) -> dict[int, float]:
    """Shares of a touch at normalised ``position`` in ``[0, 1]`` over the cells (sum 1).

    ``footprint`` is the contact's length as a fraction of the skin's (``contact_length /
    length``). The contact covers ``[c - f/2, c + f/2]`` with ``c = f/2 + position (1 - f)``,
    so that ``position = 0`` puts its edge on the thermocouple end and ``1`` on the far
    end; each cell gets the share of the footprint it overlaps.

    A point touch (``footprint = 0``) sits between the two cell centres around it and is
    split linearly: ``s = position N - 1/2`` clipped to ``[0, N - 1]``, share ``1 - (s -
    floor s)`` on ``floor s`` and ``s - floor s`` on the next.
    """
    if not (math.isfinite(position) and 0.0 <= position <= 1.0):
        raise ValueError(f"contact position = {position} must be in [0, 1]")
    if not (math.isfinite(footprint) and 0.0 <= footprint <= 1.0):
        raise ValueError(f"contact footprint = {footprint} must be in [0, 1]")
    if footprint * n_cells > 1e-9:
        lo = position * (1.0 - footprint)
        hi = lo + footprint
        shares: dict[int, float] = {}
        for i in range(max(0, math.floor(lo * n_cells)), min(n_cells, math.ceil(hi * n_cells))):
            overlap = min(hi, (i + 1) / n_cells) - max(lo, i / n_cells)
            if overlap > 1e-12:
                shares[i] = overlap / footprint
        total = sum(shares.values())
        return {i: s / total for i, s in shares.items()}
    s = min(max(position * n_cells - 0.5, 0.0), n_cells - 1.0)
    i = min(math.floor(s), n_cells - 1)
    f = s - i
    if f <= 1e-12 or i + 1 >= n_cells:
        return {i: 1.0}
    return {i: 1.0 - f, i + 1: f}


def spatial_state_space(skin: SkinParams, sp: SpatialParams, v: float, R_w: float,
                        contact: dict[int, float] | None = None,
                        q_weights: dict[int, float] | None = None,
                        still_ends: tuple[bool, bool] = (True, True)) -> tuple[Array, Array]:
    """``(A, B)`` of the spatial network (module docstring), ``dx/dt = A x + B u``.

    ``x = [T_w_0..T_w_{N-1}, T_g_0..T_g_{N-1}(, T_f_0..T_f_{N-1})]``,
    ``u = [T_p, T_a, q_x, T_f]``. ``v`` (m/s) only selects advection (``v > 0``) or still
    water; ``R_w`` (K/W) is eq. 1's resistance at that ``v``. ``contact`` maps a cell to its
    contact conductance ``G_c,i`` (W/K); ``q_weights`` maps a cell to its share of ``q_x``
    (default: the contact's shares, or all on cell 0 without contact).

    ``still_ends = (inlet, outlet)``: which ends of the pipe reach the tank through still
    water (each ``W/2``) when the pump is stopped; both for the paper's single patch. A patch
    in the middle of a loop of several (``skin.py``) has neither: its ends meet the still
    water of the connecting pipes, whose conduction (``k A / L``, about 1e-5 W/K) is left out.
    """
    N = sp.n_cells
    contact = dict(contact or {})
    for i, g in contact.items():
        if not 0 <= i < N or g < 0.0:
            raise ValueError(f"contact cell {i} (of {N}) with G_c = {g} W/K: need 0 <= cell < N, G_c >= 0")
    if q_weights is None:
        total = sum(contact.values())
        q_weights = {i: g / total for i, g in contact.items()} if total > 0 else {TC_CELL: 1.0}
    if v < 0.0 or not R_w > 0.0:
        raise ValueError(f"spatial_state_space: v = {v} m/s must be >= 0 and R_w = {R_w} K/W > 0")
    n = sp.n_states
    w = np.arange(N)
    g = N + w
    G = np.zeros((n, n))  # conductance matrix (heat flows, W), divided by C at the end
    Bq = np.zeros((n, 4))

    def link(a: int, b: int, cond: float) -> None:
        G[a, a] -= cond
        G[a, b] += cond
        G[b, b] -= cond
        G[b, a] += cond

    G_wl, G_gl = sp.G_pipe_lateral(), sp.G_sheet_lateral()
    for i in range(N - 1):
        link(w[i], w[i + 1], G_wl)
        link(g[i], g[i + 1], G_gl)
    g_wg, g_ag, g_aw = 1.0 / (N * skin.R_g), 1.0 / (N * skin.R_ag), 1.0 / (N * skin.R_aw)
    for i in range(N):
        link(w[i], g[i], g_wg)
        G[g[i], g[i]] -= g_ag
        Bq[g[i], 1] += g_ag
        if sp.has_foam:
            f = 2 * N + i
            link(w[i], f, g_aw / sp.foam_split)
            g_fa = g_aw / (1.0 - sp.foam_split)
            G[f, f] -= g_fa
            Bq[f, 1] += g_fa
        else:
            G[w[i], w[i]] -= g_aw
            Bq[w[i], 1] += g_aw
    for i, gc in contact.items():
        G[g[i], g[i]] -= gc
        Bq[g[i], 3] += gc
    for i, share in q_weights.items():
        Bq[g[i], 2] += share
    W = 1.0 / R_w
    if v > 0.0:
        # upwind: flow from the inlet end towards the outlet end
        order = list(range(N - 1, -1, -1)) if sp.inlet == "far" else list(range(N))
        up: int | None = None
        for i in order:
            G[w[i], w[i]] -= W
            if up is None:
                Bq[w[i], 0] += W
            else:
                G[w[i], w[up]] += W
            up = i
    else:
        inlet_cell, outlet_cell = (N - 1, 0) if sp.inlet == "far" else (0, N - 1)
        ends = [c for c, on in ((inlet_cell, still_ends[0]), (outlet_cell, still_ends[1])) if on]
        if N == 1 and len(ends) == 2:
            ends = [0]  # one cell is both ends: the whole W (as W/2 + W/2)
            share = W
        else:
            share = W / 2.0
        for i in ends:
            G[w[i], w[i]] -= share
            Bq[w[i], 0] += share
    cap = capacitances(skin, sp)
    return G / cap[:, None], Bq / cap[:, None]


def capacitances(skin: SkinParams, sp: SpatialParams) -> Array:
    """Node capacitances, J/K: ``C_w/N`` (pipe), ``C_g/N`` (sheet), ``C_foam/N`` (foam)."""
    N = sp.n_cells
    parts = [np.full(N, skin.C_w / N), np.full(N, skin.C_g / N)]
    if sp.has_foam:
        parts.append(np.full(N, sp.C_foam / N))
    return np.concatenate(parts)


def spatial_steady_state(skin: SkinParams, sp: SpatialParams, v: float, R_w: float, u: Array,
                         contact: dict[int, float] | None = None,
                         q_weights: dict[int, float] | None = None) -> Array:
    """Equilibrium for constant ``u = [T_p, T_a, q_x, T_f]`` (solves ``A x + B u = 0``)."""
    A, B = spatial_state_space(skin, sp, v, R_w, contact, q_weights)
    return np.linalg.solve(A, -B @ np.asarray(u, dtype=float))
