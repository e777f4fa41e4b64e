"""The simulated skin of many patches: water loops carrying heat from patch to patch.

Per sample ``k`` (``t_k = k t_s``), as :class:`~thermoskin.sim.plant.SimulatedPlant`::

    plant.measure()             # the boards' readings at t_k (T_w_read, T_p_read, T_a_read, fresh)
    plant.apply(drive, v)       # per loop: hold the Peltier drive and the pump over [t_k, t_k+1)

**Patches.** Each is the spatial skin of ``physics.spatial`` (cells along its pipe, the sheet
conducting along it, the water advected from the inlet, ``x = 1``, to the outlet, ``x = 0``),
advanced exactly over the sample with its inputs held (zero-order hold); ``u = [T_in, T_a,
0, T_f]`` with ``T_in`` the water entering its inlet. All patches are stepped at once (one
batched matrix product). The same augmented matrix exponential gives, exactly, the mean over
the sample of the outlet cell's and the inlet cell's temperatures::

    d/dt [x; u; y] = [[A, B, 0], [0, 0, 0], [C, 0, 0]] [x; u; y],   y(t_s) = C int_0^t_s x dt

so that the water a patch sends on over a sample is what its cells gave it, to rounding.

**Water.** A loop's pump moves its water through all its patches in series at one capacity
rate ``W = 1/R_w(v)`` (eq. 1, the loop's ``[skin]`` flow keys; the spatial model's reading of
``R_w``). Running, the tank sends ``T_p(t_k)`` into the supply pipe; a pipe is a plug flow of
``D = round(L / (v_on t_s))`` parcels, one sample's water each, moved one parcel per sample
at ``v_on`` (``v / v_on`` parcels per sample for a modulated pump), cooling towards the air
while in the pipe::

    T_out = T_a + (T_in - T_a) exp(-age / tau_loss),   age = (k_used - k_sent) t_s

(exact for an air constant over the transit). Patch ``i``'s mean outlet over sample ``k`` is
the next patch's inlet from sample ``k + max(D, 1)`` on (patches are stepped together: a
connecting pipe delays by one sample at least); the last patch's outlet returns to the tank
after the return pipe's ``D`` samples, and the tank loses ``q_p = W (T_p - T_return)``. With
one patch and no pipes this is :class:`SimulatedPlant`'s spatial skin exactly. Stopped
(``v = 0``), the water stands: the first patch's inlet end and the last patch's outlet end
reach the tank through still water (``W(0)/2`` each, ``physics.spatial``'s ``still_ends``), the
tank loses what they take, and the parcels in the pipes wait (and cool).

**Tanks.** Per loop a Peltier tank (``physics.peltier``, the loop's ``[peltier]``) driven by
its ``drive``, or (``tank="prescribed"``) ``T_p = scenario.base.T_p(t)`` for every loop.

**Touches** (``sim.skin_scenarios``): each contact's conductance ``G`` on the cells under it
(``contact_cells`` with the patch's fingertip footprint) at its place along the pipe, that
place on a grid of ``1/(8 N)`` of the patch's travel (a stroke's position is held on the
grid: a new transition matrix per grid point, cached, instead of one per sample). Several
contacts on one patch add their cell conductances; their bodies' temperature is then their
conductance-weighted mean (exact for equal temperatures).

**Sensors.** ``sim.sensors.Board`` per thermocouple (its pipe cell, ``Patch.tc_cells``) and,
per loop, one for the tank and one for the air, all from ``[sensor]``. Seeds: the first
thermocouple of the first patch and the first loop's tank and air boards take the
single-patch :class:`~thermoskin.sim.sensors.Sensors`' streams (``SeedSequence(seed)``'s
children 0-5); every other board its own (children ``(6 + kind, unit)``), so a skin's
readings are reproducible and its first patch reads as the single patch would.

Truth at sample ``k``: ``q_i`` per patch, ``sum_i G_i (T_f - T_g,i)`` with the contact applied
from ``t_k`` on; ``contact_true``; ``position_true`` (m from the inlet: the conductance-weighted
mean of the contacts' places on the grid; NaN without contact).

Memory does not grow with the duration: contacts, ambient and prescribed tank are evaluated
in blocks of ``block`` samples.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from thermoskin._jit import njit
from thermoskin.params import SkinParams
from thermoskin.physics.convection import FlowResistance
from thermoskin.physics.finger import T_F_IDLE
from thermoskin.physics.peltier import PeltierTank
from thermoskin.physics.spatial import (
    SpatialParams,
    capacitances,
    contact_cells,
    spatial_state_space,
    spatial_steady_state,
)
from thermoskin.sim.board_bank import BoardBank
from thermoskin.sim.sensors import Board
from thermoskin.sim.skin_scenarios import SkinScenario, contact_arrays
from thermoskin.skin.layout import Skin, tc_fresh_bit

Array = NDArray[np.float64]

TANKS = ("peltier", "prescribed")
STARTS = ("ambient", "equilibrium")
GRID = 8
"""Contact places per cell along the travel of a patch's footprint (``1/(8 N)``)."""
CACHE_SIZE = 4096
"""Most transition matrices kept per patch model (the oldest go first)."""
OUTLET_CELL = 0
"""The outlet is the end ``x = 0`` of the spatial model (its ``inlet = "far"``)."""


_POOL: list[Any] = []


def _one_blas_thread() -> Any:
    """A context holding BLAS to one thread (``threadpoolctl``; small matrices lose on more)."""
    if not _POOL:
        from threadpoolctl import ThreadpoolController

        _POOL.append(ThreadpoolController())
    return _POOL[0].limit(limits=1, user_api="blas")


@dataclass(frozen=True)
class _Model:
    """What a patch's transition matrices depend on, besides the pump and its contacts."""

    skin: SkinParams
    spatial: SpatialParams
    flow: SkinParams
    still_ends: tuple[bool, bool]


REC_ROWS = ("T_p", "v", "T_a", "q_i", "contact_true", "position_true", "fresh")
"""Rows of :attr:`SkinPlant.rec` after the thermocouples' (the log's columns, per patch)."""


@njit(cache=True)
def _gather(Z, tc_p, tc_cell, T_p, T_a, x):  # pragma: no cover - compiled
    """The boards' true temperatures: thermocouples' pipe cells, then tanks, then air."""
    n = tc_p.shape[0]
    L = T_p.shape[0]
    for b in range(n):
        x[b] = Z[tc_p[b], tc_cell[b]]
    for j in range(L):
        x[n + j] = T_p[j]
        x[n + L + j] = T_a


@njit(cache=True)
def _scatter(value, fresh, tc_p, tc_j, tc_bit, loop_of, rec, r_tp, r_ta, r_fr, Tp, Ta):  # pragma: no cover
    """The boards' readings into the per-patch row (and per loop ``Tp``, ``Ta``)."""
    n = tc_p.shape[0]
    L = Tp.shape[0]
    P = rec.shape[1]
    for i in range(P):
        rec[r_fr, i] = 0.0
    for b in range(n):
        rec[tc_j[b], tc_p[b]] = value[b]
        if fresh[b]:
            rec[r_fr, tc_p[b]] += tc_bit[b]
    for j in range(L):
        Tp[j] = value[n + j]
        Ta[j] = value[n + L + j]
    for i in range(P):
        j = loop_of[i]
        rec[r_tp, i] = Tp[j]
        rec[r_ta, i] = Ta[j]
        if fresh[n + j]:
            rec[r_fr, i] += 2.0
        if fresh[n + L + j]:
            rec[r_fr, i] += 4.0


# pipe table columns: ints (D, ring position, sample the head parcel was sent), floats (head, rate)
_D, _POS, _HK = 0, 1, 2
_HT, _RATE = 0, 1
# loop table columns
_V, _VON, _ACC, _TP, _W, _W0, _STEPS = 0, 1, 2, 3, 4, 5, 6


@njit(cache=True)
def _push(pv, pk, pi, pf, g, T, k):  # pragma: no cover - compiled
    D = pi[g, _D]
    if D == 0:
        pf[g, _HT] = T
        pi[g, _HK] = k
        return
    pos = pi[g, _POS]
    pf[g, _HT] = pv[g, pos]
    pi[g, _HK] = pk[g, pos]
    pv[g, pos] = T
    pk[g, pos] = k
    pi[g, _POS] = pos + 1 if pos + 1 < D else 0


@njit(cache=True)
def _out(pi, pf, g, k, T_a):  # pragma: no cover - compiled
    rate = pf[g, _RATE]
    if rate == 0.0:
        return pf[g, _HT]
    return T_a + (pf[g, _HT] - T_a) * math.exp(-(k - pi[g, _HK]) * rate)


@njit(cache=True)
def _advance(Z, M, Y, nst, T_f, T_a, k, lpat, loff, lf, pv, pk, pi, pf, q_out):  # pragma: no cover
    """One sample of every patch and pipe (module doc); ``q_out`` per loop."""
    P = Z.shape[0]
    nm = Y.shape[1] - 2
    L = loff.shape[0] - 1
    for j in range(L):
        p0, p1 = loff[j], loff[j + 1]
        g0 = p0 + j  # the loop's supply pipe; pipe q + 1 follows its patch q
        T_p = lf[j, _TP]
        if lf[j, _V] > 0.0:
            acc = lf[j, _ACC] + lf[j, _V] / lf[j, _VON]
            steps = math.floor(acc)
            lf[j, _ACC] = acc - steps
            lf[j, _STEPS] = steps
            for _ in range(steps):
                _push(pv, pk, pi, pf, g0, T_p, k)
            for q in range(p1 - p0):
                Z[lpat[p0 + q], nm] = _out(pi, pf, g0 + q, k, T_a)
        else:
            lf[j, _STEPS] = 0.0
            for q in range(p1 - p0):
                Z[lpat[p0 + q], nm] = T_p
    for i in range(P):
        Z[i, nm + 1] = T_a
        Z[i, nm + 2] = 0.0
        Z[i, nm + 3] = T_f[i]
        n = nst[i]
        # Y = M z as columns (M stored transposed): the sums in the order of a row's dot
        # product, the rows side by side (vectorised)
        for r in range(nm + 2):
            Y[i, r] = 0.0
        for c in range(nm + 4):
            if n <= c < nm:
                continue
            zc = Z[i, c]
            for r in range(nm + 2):
                Y[i, r] += M[i, c, r] * zc
        for r in range(n):
            Z[i, r] = Y[i, r]
    for j in range(L):
        p0, p1 = loff[j], loff[j + 1]
        g0 = p0 + j
        T_p = lf[j, _TP]
        if lf[j, _V] > 0.0:
            steps = int(lf[j, _STEPS])
            for q in range(p1 - p0):
                y = Y[lpat[p0 + q], nm]
                for _ in range(steps):
                    _push(pv, pk, pi, pf, g0 + q + 1, y, k)
            q_out[j] = lf[j, _W] * (T_p - _out(pi, pf, g0 + p1 - p0, k, T_a))
        else:
            first, last = lpat[p0], lpat[p1 - 1]
            q_out[j] = 0.5 * lf[j, _W0] * ((T_p - Y[first, nm + 1]) + (T_p - Y[last, nm]))


class SkinPlant:
    """A skin (``skin.py``) under a :class:`SkinScenario`, sample by sample (see the module doc).

    After :meth:`measure`: ``T_w_read`` (thermocouple, patch; NaN where a patch has fewer),
    ``T_p_read``, ``T_a_read`` (per loop), ``fresh`` (per patch: its thermocouples' bits and its
    loop's ``T_p`` 2, ``T_a`` 4), and the truth ``q_i``, ``contact_true``, ``position_true`` (per
    patch), ``T_p_true`` (per loop).
    """

    def __init__(self, skin: Skin, scenario: SkinScenario, *, tank: str = "peltier",
                 block: int = 1000, n: int | None = None) -> None:
        if tank not in TANKS:
            raise ValueError(f"SkinPlant: tank = {tank!r} must be one of {TANKS}")
        scenario.check(skin)
        cfg = skin.cfg
        self.skin, self.scenario, self.cfg = skin, scenario, cfg
        self.t_s = t_s = cfg.sampling.t_s
        self.n = n if n is not None else max(1, math.floor(scenario.duration / t_s + 1e-9))
        self.block = int(block)
        self.prescribed = tank == "prescribed"
        P, L = len(skin.patches), len(skin.loops)
        self.P, self.L = P, L
        patches = skin.patches
        # -- patch models -----------------------------------------------------------------
        self._flows = [FlowResistance(lp.cfg.skin) for lp in skin.loops]
        models: dict[_Model, int] = {}
        self._model_of: list[int] = []
        for p in patches:
            lp = skin.loops[p.loop]
            ends = (p.index == lp.patches[0], p.index == lp.patches[-1])
            m = _Model(p.skin, p.spatial, lp.cfg.skin, ends)
            self._model_of.append(models.setdefault(m, len(models)))
        self._models = list(models)
        self._cache: list[dict[tuple[float, tuple[tuple[float, float], ...]], Array]] = [{} for _ in models]
        self.N = np.array([p.spatial.n_cells for p in patches])
        self.nst = np.array([p.spatial.n_states for p in patches])
        self.nmax = nmax = int(self.nst.max())
        self.Z = np.zeros((P, nmax + 4))
        self.M = np.zeros((P, nmax + 4, nmax + 2))  # transposed: column c of patch i is M[i, c]
        self.Y = np.zeros((P, nmax + 2))
        self.C = [capacitances(p.skin, p.spatial) for p in patches]
        # -- loops: pipes, tanks, flows -----------------------------------------------------
        self.tanks = [PeltierTank(lp.cfg.peltier, t_s, (lp.cfg.control.drive_min, lp.cfg.control.drive_max))
                      for lp in skin.loops]
        self.v_on = [lp.cfg.pump.v_on for lp in skin.loops]
        self.lpat = np.array([i for lp in skin.loops for i in lp.patches], dtype=np.int64)
        self.loff = np.cumsum([0, *(len(lp.patches) for lp in skin.loops)]).astype(np.int64)
        Ds, rates = [], []
        for j, lp in enumerate(skin.loops):
            for q, pipe in enumerate(lp.pipes):
                D = round(pipe.length / (self.v_on[j] * t_s))
                if 0 < q < len(lp.pipes) - 1:
                    D = max(D - 1, 0)  # plus the sample the patches are stepped together
                Ds.append(D)
                rates.append(0.0 if math.isinf(pipe.tau_loss) else t_s / pipe.tau_loss)
        self.pv = np.zeros((len(Ds), max(1, *Ds)))
        self.pk = np.zeros(self.pv.shape, dtype=np.int64)
        self.pi = np.zeros((len(Ds), 3), dtype=np.int64)
        self.pi[:, _D] = Ds
        self.pf = np.zeros((len(Ds), 2))
        self.pf[:, _RATE] = rates
        self.lf = np.zeros((L, 7))
        self.lf[:, _VON] = self.v_on
        self.lf[:, _W0] = [1.0 / f(0.0) for f in self._flows]
        self._v = [math.nan] * L
        self.q_out = np.zeros(L)
        """Per loop, the heat the tank lost to the water over the last sample, W."""
        # -- sensors ----------------------------------------------------------------------
        sens = cfg.sensor
        root = sens.seed

        def board(name: str, kind: int, unit: int) -> Board:
            ss = np.random.SeedSequence
            noise = ss(root, spawn_key=(kind,)) if unit == 0 else ss(root, spawn_key=(6 + kind, unit))
            jit = ss(root, spawn_key=(3 + kind,)) if unit == 0 else ss(root, spawn_key=(9 + kind, unit))
            ch = ("T_w", "T_p", "T_a")[kind]
            return Board(name, period=getattr(sens, f"period_{ch}"), jitter=sens.jitter,
                         lag=getattr(sens, f"lag_{ch}"), noise_T=sens.noise_T, quantum_T=sens.quantum_T,
                         t_s=t_s, noise_seed=noise, jitter_seed=jit)

        boards: list[Board] = []
        tc_p, tc_cell, tc_j, tc_bit = [], [], [], []
        for p in patches:
            for j, cell in enumerate(p.tc_cells):
                boards.append(board("T_w", 0, len(boards)))
                tc_p.append(p.index)
                tc_cell.append(cell)
                tc_j.append(j)
                tc_bit.append(tc_fresh_bit(j))
        self.n_tcs = n_tcs = len(boards)
        boards += [board("T_p", 1, j) for j in range(L)] + [board("T_a", 2, j) for j in range(L)]
        self.bank = BoardBank(boards)
        self._tc_p, self._tc_cell = np.array(tc_p), np.array(tc_cell)
        self._tc_j, self._tc_bit = np.array(tc_j), np.array(tc_bit, dtype=np.int64)
        self._x = np.zeros(len(boards))
        self._p_slice, self._a_slice = slice(n_tcs, n_tcs + L), slice(n_tcs + L, n_tcs + 2 * L)
        self.n_tc = nt = skin.n_thermocouples
        self.rec = np.full((nt + len(REC_ROWS), P), math.nan)
        """The sample's row per patch: thermocouples, then :data:`REC_ROWS` (float64)."""
        self._r = {name: nt + m for m, name in enumerate(REC_ROWS)}
        self.T_w_read = self.rec[:nt]
        self.T_p_read = np.full(L, math.nan)
        self.T_a_read = np.full(L, math.nan)
        self.fresh = self.rec[self._r["fresh"]]
        self._loop_of = np.array([p.loop for p in patches], dtype=np.int64)
        self._Tp_true = np.zeros(L)
        # -- contacts (per block) -------------------------------------------------------------
        self._contacts = scenario.contacts
        self.q_i = self.rec[self._r["q_i"]]
        self.contact_true = self.rec[self._r["contact_true"]]
        self.position_true = self.rec[self._r["position_true"]]
        self.reset()

    # ------------------------------------------------------------------ matrices
    def transition(self, i: int, v: float, key: tuple[tuple[float, float], ...]) -> Array:
        """Patch ``i``'s ``[[Phi, Gamma], [mean outlet], [mean inlet cell]]`` (padded), cached."""
        mid = self._model_of[i]
        cache = self._cache[mid]
        M = cache.get((v, key))
        if M is not None:
            return M
        m = self._models[mid]
        sp = m.spatial
        N, n, nmax = sp.n_cells, sp.n_states, self.nmax
        if not key:
            shares = sp.shares(0.0)
            contact = {c: 0.0 for c in shares}
            weights = shares
        elif len(key) == 1:
            G, pq = key[0]
            shares = contact_cells(pq, N, sp.footprint)
            contact = {c: G * s for c, s in shares.items()}
            weights = shares
        else:
            contact, weights = {}, {}
            Gt = sum(G for G, _ in key)
            for G, pq in key:
                for c, s in contact_cells(pq, N, sp.footprint).items():
                    contact[c] = contact.get(c, 0.0) + G * s
                    weights[c] = weights.get(c, 0.0) + G * s / Gt
        R_w = self._flows[self.skin.patches[i].loop](v)
        A, B = spatial_state_space(m.skin, sp, v, R_w, contact, weights, still_ends=m.still_ends)
        aug = np.zeros((n + 6, n + 6))
        aug[:n, :n] = A
        aug[:n, n:n + 4] = B
        aug[n + 4, OUTLET_CELL] = 1.0
        aug[n + 5, N - 1] = 1.0
        with _one_blas_thread():  # a 36-square expm on several threads is 4-15x slower (measured)
            E = scipy.linalg.expm(aug * self.t_s)
        M = np.zeros((nmax + 2, nmax + 4))
        M[:n, :n] = E[:n, :n]
        M[:n, nmax:] = E[:n, n:n + 4]
        M[nmax:, :n] = E[n + 4:, :n] / self.t_s
        M[nmax:, nmax:] = E[n + 4:, n:n + 4] / self.t_s
        if len(cache) >= CACHE_SIZE:
            cache.pop(next(iter(cache)))
        cache[(v, key)] = M
        return M

    def _set_matrix(self, i: int) -> None:
        self.M[i] = self.transition(i, self._v[self.skin.patches[i].loop], self._keys[i]).T

    # ------------------------------------------------------------------ state
    def reset(self, start: str = "ambient", *, T_w0: float | None = None) -> None:
        """Back to sample 0, sensors from their seeds.

        ``"ambient"``: tanks, sinks, water and sheets at the air. ``"equilibrium"``: each loop in
        its steady state with the pump running and no touch, its tank such that the feedback
        patch's ``T_w`` (true) is ``T_w0`` (default: the command at 0), held by the drive in
        ``drive0`` (a prescribed tank: the scenario's ``T_p(0)``).
        """
        if start not in STARTS:
            raise ValueError(f"SkinPlant.reset: start = {start!r} must be one of {STARTS}")
        self.k = 0
        self._k_began = -1
        self._block0 = -1
        self.sensors_reset()
        base = self.scenario.base
        T_a = float(base.T_a_at(0.0))
        self.drive0 = [0.0] * self.L
        self._keys: list[tuple[tuple[float, float], ...]] = [()] * self.P
        self._Gcell: list[dict[int, float]] = [{} for _ in range(self.P)]
        self._Gtot = np.zeros(self.P)
        self.T_f = np.full(self.P, T_F_IDLE)
        self.rec[:] = math.nan
        self.q_i[:] = 0.0
        self.contact_true[:] = 0
        self.position_true[:] = math.nan
        self._touched: list[int] = []
        self._block_n = 0
        self._k_read = -1
        self.Z[:] = 0.0
        if start == "ambient":
            for i in range(self.P):
                self.Z[i, :self.nst[i]] = T_a
            for j, tank in enumerate(self.tanks):
                tank.reset(T_a, T_a, T_a)
                for q in range(len(self.skin.loops[j].pipes)):
                    self._fill_pipe(j, q, T_a)
            v0 = [0.0] * self.L
        else:
            cmd = base.T_w_cmd_at(0.0) if T_w0 is None else float(T_w0)
            v0 = list(self.v_on)
            for j in range(self.L):
                T_p = float(base.T_p(0.0)) if self.prescribed else self._equilibrium_T_p(j, cmd, T_a)
                T_ret = self._fill_equilibrium(j, T_p, T_a)
                q_out = (T_p - T_ret) / self._flows[j](self.v_on[j])
                tank = self.tanks[j]
                if self.prescribed:
                    tank.reset(T_p, None, T_a)
                    continue
                try:
                    d = tank.drive_for(T_p, T_a, q_out)
                except ValueError as e:
                    raise ValueError(f"loop {self.skin.loops[j].name!r}: the command {cmd} °C needs a tank "
                                     f"at {T_p:.2f} °C: {e}") from None
                tank.reset_steady(d, T_a, q_out)
                self.drive0[j] = d
        self._v = [math.nan] * self.L
        self.lf[:, _ACC] = 0.0
        self._set_flows(v0)
        self._Tp_true[:] = [tank.T_p for tank in self.tanks]

    def sensors_reset(self) -> None:
        """Every board back to sample 0."""
        self.bank.reset()

    def _pipe(self, j: int, q: int) -> int:
        """Row of loop ``j``'s pipe ``q`` in the pipe tables."""
        return int(self.loff[j]) + j + q

    def _pipe_has_head(self, j: int, q: int) -> bool:
        """A pipe between two patches holds one parcel more: the one the next patch takes next."""
        return 0 < q < len(self.skin.loops[j].pipes) - 1

    def _fill_pipe(self, j: int, q: int, T: float) -> None:
        """Every parcel of the pipe sent at ``T`` before sample 0 (the newest at -1)."""
        g = self._pipe(j, q)
        D = int(self.pi[g, _D])
        head = 1 if self._pipe_has_head(j, q) else 0
        self.pv[g, :] = T
        self.pk[g, :D] = np.arange(-D, 0)  # slot 0 the oldest, next out (sent D samples before use)
        self.pi[g, _POS] = 0
        self.pi[g, _HK] = -D - head
        self.pf[g, _HT] = T

    def _chain(self, j: int, T_p: float, T_a: float) -> tuple[list[Array], list[float], float]:
        """Steady states of loop ``j``'s patches, pump running, no touch: states, inlets, return."""
        lp = self.skin.loops[j]
        v = self.v_on[j]
        R_w = self._flows[j](v)
        xs, inlets = [], []
        T = T_p
        for q, i in enumerate(lp.patches):
            a = self._attenuation(j, q)
            T_in = T_a + (T - T_a) * a
            p = self.skin.patches[i]
            x = spatial_steady_state(p.skin, p.spatial, v, R_w, np.array([T_in, T_a, 0.0, T_F_IDLE]))
            xs.append(x)
            inlets.append(T_in)
            T = float(x[OUTLET_CELL])
        T_ret = T_a + (T - T_a) * self._attenuation(j, len(lp.patches))
        return xs, inlets, T_ret

    def _attenuation(self, j: int, q: int) -> float:
        """Steady share of the excess a parcel keeps through pipe ``q`` of loop ``j`` (running)."""
        return math.exp(-self.delay_samples(j, q) * self.pf[self._pipe(j, q), _RATE])

    def delay_samples(self, j: int, q: int) -> int:
        """Samples loop ``j``'s water takes through its pipe ``q`` at ``v_on``."""
        return int(self.pi[self._pipe(j, q), _D]) + (1 if self._pipe_has_head(j, q) else 0)

    def _equilibrium_T_p(self, j: int, cmd: float, T_a: float) -> float:
        lp = self.skin.loops[j]
        fb = self.skin.patches[lp.feedback]
        xs, _, _ = self._chain(j, T_a + 1.0, T_a)
        gain = float(xs[lp.patches.index(fb.index)][fb.tc_cells[0]]) - T_a
        return T_a + (cmd - T_a) / gain

    def _fill_equilibrium(self, j: int, T_p: float, T_a: float) -> float:
        lp = self.skin.loops[j]
        xs, _, T_ret = self._chain(j, T_p, T_a)
        for i, x in zip(lp.patches, xs, strict=True):
            self.Z[i, :x.size] = x
        outs = [T_p, *(float(x[OUTLET_CELL]) for x in xs)]
        for q, T in enumerate(outs):
            self._fill_pipe(j, q, T)
        return T_ret

    def _set_flows(self, v: list[float]) -> None:
        for j, vj in enumerate(v):
            if vj != self._v[j]:
                self._v[j] = vj
                self.rec[self._r["v"], self.skin.loops[j].patches] = vj
                self.lf[j, _V] = vj
                self.lf[j, _W] = 1.0 / self._flows[j](vj)
                for i in self.skin.loops[j].patches:
                    self._set_matrix(i)

    # ------------------------------------------------------------------ contacts
    def _load_block(self, k0: int) -> None:
        """Contacts, ambient and prescribed tank over samples ``k0 .. k0 + block - 1``."""
        m = min(self.block, self.n - k0)
        t = (k0 + np.arange(m)) * self.t_s
        base = self.scenario.base
        self._T_a = np.asarray(base.T_a_at(t), dtype=float).reshape(m).tolist()
        self._T_p = np.asarray(base.T_p(t), dtype=float).reshape(m).tolist() if self.prescribed else []
        self._block0 = k0
        self._block_n = m
        C = len(self._contacts)
        if C == 0:
            self._events: list[int] = []
            self._ev_pos = 0
            return
        patch, G, s, Tb = contact_arrays(self.skin, self._contacts, t)
        # the place on the grid (contact_cells' parameter) and the position it stands for
        pq = np.zeros((C, m))
        pos = np.full((C, m), math.nan)
        on = patch >= 0
        if on.any():
            pi = patch[on]
            Ls = np.array([p.length for p in self.skin.patches])[pi]
            fs = np.array([p.spatial.footprint for p in self.skin.patches])[pi]
            Q = GRID * self.N[pi]
            xc = 1.0 - s[on] / Ls
            travel = np.where(fs < 1.0, 1.0 - fs, 1.0)
            par = np.clip(np.where(fs < 1.0, (xc - 0.5 * fs) / travel, 0.5), 0.0, 1.0)
            par = np.round(par * Q) / Q
            pq[on] = par
            pos[on] = Ls * (1.0 - (0.5 * fs + par * (1.0 - fs)))
        self._c_patch, self._c_G, self._c_pq, self._c_T, self._c_pos = patch, G, pq, Tb, pos
        # samples where any contact changes (patch, G or place), the block's first included
        change = np.zeros(m, dtype=bool)
        change[0] = True
        if m > 1:
            change[1:] = ((np.diff(patch, axis=1) != 0) | (np.diff(G, axis=1) != 0)
                          | (np.diff(pq, axis=1) != 0)).any(axis=0)
        self._events = np.flatnonzero(change).tolist()
        self._ev_pos = 0

    def _contacts_at(self, kk: int) -> None:
        """Per-patch contact state from the contacts at block sample ``kk``; new matrices where changed."""
        P = self.P
        items: list[list[tuple[float, float]]] = [[] for _ in range(P)]
        heat: list[list[tuple[float, float, float]]] = [[] for _ in range(P)]
        cp, cG, cq, cT, cpos = self._c_patch, self._c_G, self._c_pq, self._c_T, self._c_pos
        for c in range(cp.shape[0]):
            i = int(cp[c, kk])
            if i >= 0:
                G = float(cG[c, kk])
                items[i].append((G, float(cq[c, kk])))
                heat[i].append((G, float(cT[c, kk]), float(cpos[c, kk])))
        for i in range(P):
            key = tuple(sorted(items[i]))
            if key == self._keys[i]:
                continue
            self._keys[i] = key
            self._set_matrix(i)
            if not key:
                if i in self._touched:
                    self._touched.remove(i)
                self.q_i[i] = 0.0
                self._Gcell[i] = {}
                self._Gtot[i] = 0.0
                self.T_f[i] = T_F_IDLE
                self.contact_true[i] = 0
                self.position_true[i] = math.nan
                continue
            sp = self.skin.patches[i].spatial
            cells: dict[int, float] = {}
            for G, pq in key:
                for c, sh in contact_cells(pq, sp.n_cells, sp.footprint).items():
                    cells[c] = cells.get(c, 0.0) + G * sh
            Gt = sum(h[0] for h in heat[i])
            if self._Gtot[i] == 0.0:
                self._touched.append(i)
            self._Gcell[i] = cells
            self._Gtot[i] = Gt
            self.T_f[i] = heat[i][0][1] if len(heat[i]) == 1 else sum(G * T for G, T, _ in heat[i]) / Gt
            self.contact_true[i] = 1
            self.position_true[i] = heat[i][0][2] if len(heat[i]) == 1 else \
                sum(G * x for G, _, x in heat[i]) / Gt

    def _begin(self) -> None:
        """Start sample ``k``: load its block, apply the contact changes due now, the truth."""
        k = self.k
        self._k_began = k
        if self._block0 < 0 or not self._block0 <= k < self._block0 + self._block_n:
            self._load_block(k)
        kk = k - self._block0
        ev = self._events
        while self._ev_pos < len(ev) and ev[self._ev_pos] <= kk:
            if ev[self._ev_pos] == kk:
                self._contacts_at(kk)
            self._ev_pos += 1
        Z, q = self.Z, self.q_i
        for i in self._touched:
            N = int(self.N[i])
            Tf = float(self.T_f[i])
            q[i] = sum(G * (Tf - float(Z[i, N + c])) for c, G in self._Gcell[i].items())

    # ------------------------------------------------------------------ per sample
    @property
    def T_a_true(self) -> float:
        """The true ambient now, °C."""
        if self._k_began != self.k:
            self._begin()
        return self._T_a[self.k - self._block0]

    @property
    def T_p_true(self) -> Array:
        """Each loop's tank now, °C (an array kept by the plant: copy it to keep it)."""
        if self.prescribed:
            if self._k_began != self.k:
                self._begin()
            self._Tp_true[:] = self._T_p[self.k - self._block0]
        return self._Tp_true

    def measure(self) -> None:
        """The boards' readings now (``T_w_read``, ``T_p_read``, ``T_a_read``, ``fresh``); once per
        sample (a second call in the same sample changes nothing)."""
        k = self.k
        if self._k_began != k:
            self._begin()
        if self._k_read == k:
            return
        self._k_read = k
        x = self._x
        _gather(self.Z, self._tc_p, self._tc_cell, self.T_p_true, self._T_a[k - self._block0], x)
        bank = self.bank
        bank.read(x)
        r = self._r
        _scatter(bank.value, bank.fresh, self._tc_p, self._tc_j, self._tc_bit, self._loop_of, self.rec,
                 r["T_p"], r["T_a"], r["fresh"], self.T_p_read, self.T_a_read)

    def apply(self, drive: list[float] | Array, v: list[float] | Array) -> None:
        """Hold each loop's ``drive`` and ``v`` (m/s) over one sample and advance."""
        k = self.k
        if self._k_read != k:
            self.measure()  # the sensors see every sample
        self._set_flows([float(x) for x in v])
        T_a = self._T_a[k - self._block0]
        lf = self.lf
        lf[:, _TP] = self.T_p_true
        _advance(self.Z, self.M, self.Y, self.nst, self.T_f, T_a, k, self.lpat, self.loff, lf, self.pv,
                 self.pk, self.pi, self.pf, self.q_out)
        if not self.prescribed:
            q_out = self.q_out.tolist()
            Tp = self._Tp_true
            for j, tank in enumerate(self.tanks):
                tank.step(drive[j], T_a, q_out[j])
                Tp[j] = tank.T_p
        self.k = k + 1

    # ------------------------------------------------------------------ inspection
    def state(self, i: int) -> Array:
        """Patch ``i``'s state (pipe cells, sheet cells (, foam)), °C: a view."""
        return self.Z[i, :self.nst[i]]

    def pipe_parcels(self, j: int) -> list[list[float]]:
        """Loop ``j``'s water in its pipes at the start of the current sample, °C, per pipe
        (supply, between..., return), oldest first; a pipe between patches ends with the parcel
        its next patch takes now."""
        T_a = float(self.scenario.base.T_a_at(self.k * self.t_s))
        out = []
        for q in range(len(self.skin.loops[j].pipes)):
            g = self._pipe(j, q)
            D, pos = int(self.pi[g, _D]), int(self.pi[g, _POS])
            order = [(pos + m) % D for m in range(D)]
            sent = [(float(self.pv[g, o]), int(self.pk[g, o])) for o in order]
            if self._pipe_has_head(j, q):
                sent.append((float(self.pf[g, _HT]), int(self.pi[g, _HK])))
            rate = float(self.pf[g, _RATE])
            out.append([T_a + (T - T_a) * math.exp(-(self.k - kk) * rate) for T, kk in sent])
        return out

    def last_outlet_means(self) -> Array:
        """Each patch's mean outlet temperature over the last sample, °C."""
        return self.Y[:, self.nmax].copy()
