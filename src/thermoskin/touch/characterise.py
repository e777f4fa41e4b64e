"""What touched the skin: contact conductance, the toucher's temperature and effusivity, person or object.

Read from the estimator's outputs over a contact (its estimated touch heat ``dq_i_hat``)
and the measured pipe and air temperatures, by Bayes' rule on a physical model of the
toucher, with the world of :mod:`thermoskin.physics.world` as the prior.

**The sheet as the toucher sees it.** The sheet's time constant ``C_g R_par`` (11 ms with
Table I) is far below anything seen here, so the sheet is in balance at every sample
(Fig. 3, eq. 4 with ``dT_g/dt = 0``)::

    T_g = T_x + R_par q_i,   T_x = R_par (T_w/R_g + T_a/R_ag),   1/R_par = 1/R_g + 1/R_ag

``T_x`` is the sheet's no-touch temperature, known from the readings. A toucher whose
surface ``T_s`` meets the sheet through a contact conductance ``G`` (``q_i = G (T_s - T_g)``)
thus sees a conductance ``G' = G/(1 + G R_par)`` to ``T_x``: ``q_i = G' (T_s - T_x)``.

**The toucher** is a body of effusivity ``e`` behind that conductance, semi-infinite over
the seconds that matter (a finger's tissue, a block, a mug's wall), starting at ``T_0`` (its
surface temperature at the onset ``t_0``). For a constant ``T_x`` its heat flow is the
classical one (Carslaw & Jaeger, *Conduction of Heat in Solids*, 1959, §2.7, a surface
exchanging through a film)::

    q_i(t) = G' (T_0 - T_x) F(κ sqrt(t - t_0)),   F(x) = exp(x²) erfc(x),   κ = G'/(A e)

(``A`` the contact area); a well-mixed drink behind a thin wall is the limit ``κ = 0``. For a
varying ``T_x`` (a pump, a set-point being modulated), by superposition (Duhamel)::

    q_i(t) = G' [T_0 F(κ sqrt(τ)) - u_2(t)],   u_2 = T_x(t_0) F(κ sqrt(τ)) + ∫ F(κ sqrt(t - s)) dT_x(s)

which is linear in ``a = G' T_0`` and ``b = G'`` for each ``κ``.

**What the data hold.** The estimate and ``T_x`` are averaged over bins of ``BIN_S``; on
each bin ``q_b = a u_1 - b u_2 + noise`` (``u_1 = F``). The noise of a bin is read from the
data (the spread of successive differences, inflated for their correlation), plus a
model error of ``MODEL_ERR`` of the flow and the filter's jump just after detection (its
estimate overshoots for some 0.1-0.3 s: ``TRANSIENT_REL |q| e^{-(t - t_det)/TRANSIENT_S}``).
Only ``a - b T_x`` is seen while ``T_x`` is still: ``G`` and ``T_0`` separate only as far as
``T_x`` moves during the contact. With the paper's skin (``R_ag`` = 1 K/W, ``R_g`` = 10 K/W)
the sheet follows the air, not the pipe: a change of the set-point moves ``T_x`` by
``R_par/R_g`` = 1/11 of itself. ``κ`` shows in how fast the flow falls.

**The posterior** is computed on a grid of ``(component, κ, T_0, G')``: the components are
the world's kinds of toucher (a finger, a palm, a hand; each object preset at each of its
temperatures), each with its share, a prior on ``T_0`` and a prior on ``(G', κ, ln e)``
drawn from its areas, pressures and materials (:func:`component_priors`). From it:
``p_human``, the material class, and the posterior means and standard deviations of
``T_0`` (``T_f_hat``), ``G`` (``G_hat``) and ``e``.

**Identifiable or not.** ``G_hat`` and ``T_f_hat`` are given only where the data alone fix
them (the least-squares fit at the best ``κ``: relative s.d. of ``G`` at most
``G_RSD_MAX``, s.d. of ``T_0`` at most ``T_SD_MAX``), so a prior never passes for a
measurement; ``effusivity_hat`` where the posterior s.d. of ``ln e`` is at most
``E_LSD_MAX`` (it rests on the class: the decay gives ``G'/(A e)`` and the area is not
seen); ``toucher`` where ``p_human`` is at least ``P_DECIDE`` or at most ``1 - P_DECIDE``;
``material`` where the class's probability is at least ``P_MATERIAL``. ``p_human`` is
always given (the prior's 0.5 when the contact has not shown itself yet).

**Kind**: ``tap`` or ``hold`` from the contact on its patch
(:func:`thermoskin.estimation.events.one_patch_kind`); ``stroke`` and ``grasp`` need the contacts
of several patches together (:func:`thermoskin.touch.kinds.touches`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from thermoskin.estimation.events import ContactEvent, one_patch_kind
from thermoskin.params import Config

Array = NDArray[np.float64]

BIN_S = 0.05
"""Bin of the estimate and of ``T_x``, s."""
PRE_S = 0.5
"""``T_x(t_0)``: the mean over this long before the onset, s."""
MAX_S = 10.0
"""The contact's first seconds characterise it (later bins are left out), s."""

MODEL_ERR = 0.03
"""Model error of the flow (relative): layered bodies, perfusion, the filter's lag."""
TRANSIENT_REL = 1.0
"""Uncertainty of the estimate just after detection, relative to the flow (the jump overshoots)."""
TRANSIENT_S = 0.15
"""Decay time of that uncertainty, s."""
SIGMA_MIN = 0.005
"""Smallest noise of a bin, W."""
SIGMA_FEW = 0.1
"""Noise of a bin when fewer than 4 bins are there to measure it, W."""

T_SD_MAX = 0.75
"""``T_f_hat`` is given where the data fix ``T_0`` to this s.d. (K): ±1.5 K at 2 s.d."""
G_RSD_MAX = 0.25
"""``G_hat`` is given where the data fix ``G`` to this relative s.d."""
E_LSD_MAX = 0.4
"""``effusivity_hat`` is given where the posterior s.d. of ``ln e`` is at most this."""
P_DECIDE = 0.8
"""``toucher`` is named where ``p_human`` (or ``1 - p_human``) is at least this."""
P_MATERIAL = 0.5
"""``material`` is named where its class's probability is at least this."""

KAPPA = np.concatenate(([0.0], np.geomspace(2e-3, 6.0, 31)))
"""Grid of ``κ``, s^-1/2."""
N_G = 120
"""Points of the (logarithmic) grid of ``G'`` (steps of 5 %)."""
G_SMOOTH = 0.1
"""The ``G'`` priors are smoothed by a Gaussian of this s.d. in ``ln G'``."""
G_MIN = 4e-3
"""Smallest ``G'`` of the grid, W/K (the largest: ``0.95/R_par``)."""
PRIOR_SAMPLES = 4000
"""Draws per component for its ``(G', κ, ln e)`` prior."""
PRIOR_SEED = 20150713
"""Seed of those draws (fixed: the prior is a constant of the module)."""
T0_SMOOTH = 0.5
"""Edges of the ``T_0`` priors softened by a Gaussian of this s.d., K."""


# --------------------------------------------------------------------------------- model
def flux_kernel(kappa: float | Array, tau: float | Array) -> Array:
    """``F(κ sqrt(τ)) = exp(x²) erfc(x)``: the flow of a semi-infinite body behind a film,
    relative to its start (Carslaw & Jaeger §2.7); ``τ <= 0`` gives 1."""
    from scipy.special import erfcx

    x = np.asarray(kappa, dtype=float) * np.sqrt(np.maximum(np.asarray(tau, dtype=float), 0.0))
    return np.asarray(erfcx(x), dtype=float)


def sheet_coupling(cfg: Config) -> float:
    """``R_par = 1/(1/R_g + 1/R_ag)``, K/W: the sheet's resistance to its surroundings."""
    return 1.0 / (1.0 / cfg.skin.R_g + 1.0 / cfg.skin.R_ag)


def no_touch_sheet(cfg: Config, T_w: Array | float, T_a: Array | float) -> Array:
    """``T_x = R_par (T_w/R_g + T_a/R_ag)``: the sheet's temperature without a touch, °C
    (:func:`thermoskin.estimation.model.sheet_equilibrium`, over arrays)."""
    from thermoskin.estimation.model import sheet_equilibrium

    return np.asarray(sheet_equilibrium(cfg, np.asarray(T_w), np.asarray(T_a)))  # type: ignore[arg-type]


def regressors(kappa: float, tau: Array, T_x: Array, T_x0: float) -> tuple[Array, Array]:
    """``(u_1, u_2)`` at bin times ``tau`` (s since the onset) for the bins' ``T_x`` (their
    steps taken at the bin starts ``tau - BIN_S/2``) and ``T_x(t_0) = T_x0``; ``q = a u_1 - b u_2``."""
    u1 = flux_kernel(kappa, tau)
    steps = np.diff(np.concatenate(([T_x0], T_x)))
    s = tau - 0.5 * BIN_S
    lag = tau[:, None] - s[None, :]
    K = np.where(lag > 0.0, flux_kernel(kappa, lag), 0.0)
    u2 = T_x0 * u1 + K @ steps
    return u1, u2


# --------------------------------------------------------------------------------- priors
@dataclass(frozen=True)
class Component:
    """One kind of toucher in the prior: ``name``, material class ``cls``, ``share`` of
    touches, ``T_0`` uniform in ``T_range`` (°C; relative to the room's air if ``room``),
    and its drawn ``(G', κ, ln e)``."""

    name: str
    cls: str
    share: float
    T_range: tuple[float, float]
    room: bool
    G1: Array
    kappa: Array
    ln_e: Array

    @property
    def human(self) -> bool:
        return self.cls == "human"


def _reservoir_film(kind: str, T_mid: float) -> float | None:
    """Film coefficient of an object whose contents touch through a thin wall (W/(m² K)):
    a wall the heat crosses in under 0.1 s; None for a solid, semi-infinite over seconds."""
    from thermoskin.physics import contact as ct

    pre = ct.OBJECTS[kind]
    if pre.reservoir is None:
        return None
    thick = sum(d for _, d in pre.plies)
    mat = ct.MATERIALS[pre.plies[0][0]]
    if thick * thick / mat.diffusivity > 0.1:
        return None
    if pre.reservoir.h_film is not None:
        return pre.reservoir.h_film
    return ct.h_natural_water(T_mid, pre.reservoir.height)


def _wall_capacity(kind: str) -> float:
    """Heat capacity of an object's wall per area, J/(m² K)."""
    from thermoskin.physics import contact as ct

    return sum(ct.MATERIALS[m].rho * ct.MATERIALS[m].c * d for m, d in ct.OBJECTS[kind].plies)


FIT_TAU = np.linspace(0.2, 3.0, 57)
"""Times (s after the onset) over which a wall-and-contents response is read as ``(G', κ)``."""


def _wall_response(G1: Array, H: Array, C: Array) -> tuple[Array, Array]:
    """A thin wall (capacity ``C``, J/K) between the contact ``G1`` and a film ``H`` (W/K) to
    well-mixed contents: the flow falls from ``G1`` to the series value ``G_s`` as
    ``G_s + (G1 - G_s) e^{-t/τ_w}``, ``τ_w = C/(G1 + H)``. Read as the model's ``c F(κ sqrt(t))``
    by least squares over :data:`FIT_TAU` (grid ``κ``, ``c`` in closed form): returns the
    ``(c G1, κ)`` the characteriser would find on noise-free data."""
    Gs = G1 * H / (G1 + H)
    tw = C / (G1 + H)
    resp = (Gs[:, None] + (G1 - Gs)[:, None] * np.exp(-FIT_TAU[None, :] / tw[:, None])) / G1[:, None]
    F = flux_kernel(KAPPA[:, None], FIT_TAU[None, :])  # (κ, t)
    c = resp @ F.T / np.sum(F * F, axis=1)[None, :]     # (draw, κ)
    rss = np.sum(resp ** 2, axis=1)[:, None] - c ** 2 * np.sum(F * F, axis=1)[None, :]
    k = np.argmin(rss, axis=1)
    return c[np.arange(len(k)), k] * G1, KAPPA[k]


@lru_cache(maxsize=8)
def component_priors(R_par: float, T_room_ref: float = 20.0) -> tuple[Component, ...]:
    """The world's touchers (:mod:`thermoskin.physics.world`) as prior components for a skin
    of ``R_par`` (K/W). ``T_room_ref`` (°C) is where a reservoir's film is evaluated for
    'room' temperatures."""
    from thermoskin.physics import contact as ct
    from thermoskin.physics import world as W  # noqa: N812

    rng = np.random.default_rng(PRIOR_SEED)
    n = PRIOR_SAMPLES
    comps: list[Component] = []
    for part, (share, (a0, a1), (p0, p1)) in W.HUMAN_PARTS.items():
        A = rng.uniform(a0, a1, n)
        p = rng.uniform(p0, p1, n)
        G = ct.H_C_REF * (p / ct.P_REF) ** ct.N_H_C * A
        e = ct.SKIN.effusivity * np.exp(rng.normal(0.0, 0.15, n))
        G1 = G / (1.0 + G * R_par)
        comps.append(Component(part, "human", W.P_HUMAN * share, W.T_SKIN_RANGE, False, G1,
                               G1 / (A * e), np.log(e)))
    n_obj = len(W.OBJECT_TEMPS)
    for kind, modes in W.OBJECT_TEMPS.items():
        pre = ct.OBJECTS[kind]
        w_all = sum(m[0] for m in modes)
        for w, how, lo, hi in modes:
            A = pre.area * rng.uniform(*W.OBJECT_AREA_SCALE, n)
            p = rng.uniform(*W.OBJECT_PRESSURE, n)
            G = ct.H_C_REF * (p / ct.P_REF) ** ct.N_H_C * A
            T_mid = 0.5 * (lo + hi) + (T_room_ref if how == "room" else 0.0)
            film = _reservoir_film(kind, T_mid)
            e_true = ct.MATERIALS[ct.OBJECTS[kind].material_true.name].effusivity
            if film is not None:  # contents behind a thin wall: the wall, then a film to a store
                G1, kap = _wall_response(G / (1.0 + G * R_par), film * A, _wall_capacity(kind) * A)
                e = np.full(n, e_true)
            else:
                e = ct.MATERIALS[pre.plies[0][0]].effusivity * np.exp(rng.normal(0.0, 0.05, n))
                G1 = G / (1.0 + G * R_par)
                kap = G1 / (A * e)
                e = np.full(n, e_true) if pre.cls == "water" else e
            comps.append(Component(f"{kind}/{how}{lo:g}-{hi:g}", pre.class_,
                                   (1.0 - W.P_HUMAN) / n_obj * w / w_all, (lo, hi), how == "room",
                                   G1, kap, np.log(e)))
    return tuple(comps)


def _kappa_index(kap: Array) -> NDArray[np.int64]:
    """Nearest point of :data:`KAPPA` (0 exactly for ``κ = 0``; in ``ln κ`` otherwise)."""
    idx = np.zeros(kap.shape, dtype=np.int64)
    pos = kap > 0.0
    lk = np.log(KAPPA[1:])
    j = np.searchsorted(0.5 * (lk[1:] + lk[:-1]), np.log(kap[pos]))
    idx[pos] = j + 1
    return idx


@dataclass(frozen=True)
class PriorGrid:
    """The components' priors on the grid: ``G1`` (``G'``), log densities ``lp_gk[c, κ, G']``,
    ``E[ln e]`` and ``E[(ln e)²]`` per cell, per component."""

    R_par: float
    G1: Array
    comps: tuple[Component, ...]
    lp_gk: Array
    m1: Array
    m2: Array


@lru_cache(maxsize=8)
def prior_grid(R_par: float) -> PriorGrid:
    """:func:`component_priors` on the ``(κ, G')`` grid: draws binned, smoothed by a Gaussian
    of :data:`G_SMOOTH` in ``ln G'`` and one cell either way in ``κ`` (the draws are finite,
    the world is not), with a floor that keeps every cell possible."""
    from scipy.ndimage import gaussian_filter1d

    comps = component_priors(R_par)
    G1 = np.geomspace(G_MIN, 0.95 / R_par, N_G)
    lg = np.log(G1)
    step = lg[1] - lg[0]
    edges = np.concatenate(([-np.inf], 0.5 * (lg[1:] + lg[:-1]), [np.inf]))
    nk = len(KAPPA)
    lp = np.empty((len(comps), nk, N_G))
    m1 = np.empty_like(lp)
    m2 = np.empty_like(lp)

    def smooth(x: Array) -> Array:
        x = gaussian_filter1d(x, G_SMOOTH / step, axis=1, mode="constant")
        return x + 0.25 * (np.roll(x, 1, 0) + np.roll(x, -1, 0))

    for i, c in enumerate(comps):
        ig = np.clip(np.searchsorted(edges, np.log(np.clip(c.G1, 1e-12, None))) - 1, 0, N_G - 1)
        ik = _kappa_index(c.kappa)
        cnt = np.zeros((nk, N_G))
        s1 = np.zeros((nk, N_G))
        s2 = np.zeros((nk, N_G))
        np.add.at(cnt, (ik, ig), 1.0)
        np.add.at(s1, (ik, ig), c.ln_e)
        np.add.at(s2, (ik, ig), c.ln_e ** 2)
        cnt, s1, s2 = smooth(cnt), smooth(s1), smooth(s2)
        dens = cnt / cnt.sum()
        lp[i] = np.log(dens + 1e-6 / dens.size)
        mean = c.ln_e.mean()
        ok = cnt > 1e-9 * cnt.max()
        with np.errstate(invalid="ignore", divide="ignore"):
            m1[i] = np.where(ok, s1 / cnt, mean)
            m2[i] = np.where(ok, s2 / cnt, mean ** 2 + c.ln_e.var())
    return PriorGrid(R_par, G1, comps, lp, m1, m2)


def t0_box(comp: Component, T_room: float) -> tuple[float, float]:
    """``T_0``'s range for a component (°C; the room's air at ``T_room``), before the
    :data:`T0_SMOOTH` softening of its edges."""
    lo, hi = comp.T_range
    return (lo + T_room, hi + T_room) if comp.room else (lo, hi)


def _log_diff_ndtr(x: Array, y: Array) -> Array:
    """``ln(Φ(x) - Φ(y))`` for ``x > y``, accurate in both tails."""
    from scipy.special import log_ndtr

    hi = np.where(y > 0.0, -y, x)  # Φ(x) - Φ(y) = Φ(-y) - Φ(-x) where both are far right
    lo = np.where(y > 0.0, -x, y)
    la, lb = log_ndtr(hi), log_ndtr(lo)
    return la + np.log1p(-np.exp(np.minimum(lb - la, -1e-300)))


def _edge_moments(z: Array, m: Array, v: Array, r: Array, right: bool) -> tuple[Array, Array]:
    """``E[X Φ(z')]`` and ``E[X² Φ(z')]`` for ``X ~ N(m, v)`` and one softened edge (``z`` as in
    :func:`_box_moments`, ``r = sqrt(v + s²)``): ``Φ((X - c)/s)``, or with ``right`` its
    complement ``Φ(-(X - c)/s)`` (accurate where ``z`` is large), by the same lemma."""
    from scipy.special import ndtr

    phi = np.exp(-0.5 * z * z) / math.sqrt(2.0 * math.pi)
    tilt = phi / r * (m - v * z / r)
    if right:
        Pc = ndtr(-z)
        e1 = m * Pc - v * phi / r
        return e1, m * e1 + v * (Pc - tilt)
    Ph = ndtr(z)
    e1 = m * Ph + v * phi / r
    return e1, m * e1 + v * (Ph + tilt)


def _box_moments(m: Array, v: Array, lo: float | Array, hi: float | Array, s: float
                 ) -> tuple[Array, Array, Array]:
    """For ``X ~ N(m, v)`` and the box ``[lo, hi]`` softened by ``N(0, s²)`` (elementwise:
    every argument but ``s`` may be an array, broadcast together),
    ``B(x) = Φ((x - lo)/s) - Φ((x - hi)/s)``: ``ln E[B(X)]``, and the mean and variance of
    ``X`` weighted by ``B`` (Stein's lemma: ``E[X Φ((X - c)/s)] = m Φ(z) + v φ(z)/r`` with
    ``r = sqrt(v + s²)``, ``z = (m - c)/r``; ``E[X² Φ] = m E[X Φ] + v (Φ(z) + φ(z)/r (m - v z/r))``)."""

    m, v, lo, hi = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (m, v, lo, hi)))
    r = np.sqrt(v + s * s)
    z_lo, z_hi = (m - lo) / r, (m - hi) / r
    lM0 = _log_diff_ndtr(z_lo, z_hi)
    # E[B X] and E[B X²] as differences over the two edges, each element by the side that is
    # accurate there: both edges left of m (z_hi > 0), Φ(z_lo) - Φ(z_hi) = Φ(-z_hi) - Φ(-z_lo)
    # and the complements' moments (the same lemma with Φ(-(X - c)/s)); else Φ itself
    right = z_hi > 0.0
    d1 = np.empty_like(m)
    d2 = np.empty_like(m)
    for sel, rt in ((~right, False), (right, True)):
        if not sel.any():
            continue
        ms, vs, rs = m[sel], v[sel], r[sel]
        (a1, a2), (b1, b2) = (_edge_moments(z[sel], ms, vs, rs, rt) for z in (z_lo, z_hi))
        d1[sel], d2[sel] = (b1 - a1, b2 - a2) if rt else (a1 - b1, a2 - b2)
    M0 = np.exp(lM0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = d1 / M0
        var = d2 / M0 - mean ** 2
    # far outside the box the differences cancel: the weight is nil there anyway
    bad = ~np.isfinite(mean) | ~np.isfinite(var) | (M0 < 1e-12)
    mean = np.where(bad, np.clip(m, lo, hi), mean)
    var = np.where(bad | (var < 0), np.minimum(v, (hi - lo) ** 2 / 12.0 + s * s), var)
    return lM0, mean, var


# --------------------------------------------------------------------------------- result
@dataclass(frozen=True)
class Character:
    """What touched (module doc): ``kind``, ``toucher`` (``human``/``object``/``""``),
    ``material`` (class or ``""``), ``p_human``, ``G_hat, G_sd`` (W/K), ``T_f_hat, T_f_sd``
    (°C, K), ``effusivity_hat`` (W s^0.5/(m² K)); NaN where not identifiable. Also the
    class probabilities, the posterior moments before the identifiability rules
    (``post``), the data-only standard deviations (``data_sd``) and the seconds of contact used."""

    kind: str
    toucher: str
    material: str
    p_human: float
    G_hat: float
    G_sd: float
    T_f_hat: float
    T_f_sd: float
    effusivity_hat: float
    p_class: dict[str, float]
    post: dict[str, float]
    data_sd: dict[str, float]
    t_used: float

    def fields(self) -> dict[str, str | float]:
        """The event fields (:data:`thermoskin.estimation.events.CHARACTER_COLUMNS`)."""
        return {"kind": self.kind, "toucher": self.toucher, "material": self.material,
                "p_human": self.p_human, "G_hat": self.G_hat, "G_sd": self.G_sd,
                "T_f_hat": self.T_f_hat, "T_f_sd": self.T_f_sd, "effusivity_hat": self.effusivity_hat}


# --------------------------------------------------------------------------------- binning
class Bins:
    """Per-sample signals averaged over :data:`BIN_S` bins as they come: ``dq_i_hat``, ``T_w``,
    ``T_a``. A bin's samples are summed together once it is complete (the open bin's are held
    over to the next chunk), so any chunking of the same samples gives the same bins, bit for
    bit; a bin counts where each signal has a finite sample in it (NaNs are left out).

    ``horizon_s``: bins older than this behind the newest are dropped.
    """

    def __init__(self, horizon_s: float = 400.0) -> None:
        self.horizon = round(horizon_s / BIN_S)
        self.idx: list[int] = []
        self.q: list[float] = []
        self.w: list[float] = []
        self.a: list[float] = []
        self._open = -1
        self._held: tuple[Array, ...] = ()  # the open bin's samples: dq, T_w, T_a

    def _add(self, k: NDArray[np.int64], cols: list[Array]) -> None:
        """Complete bins: ``k`` each sample's bin, one run per bin, in order."""
        starts = np.concatenate(([0], np.flatnonzero(np.diff(k)) + 1))
        fins = [np.isfinite(x) for x in cols]
        n = [np.add.reduceat(f.astype(np.int64), starts) for f in fins]
        sums = [np.add.reduceat(np.where(f, x, 0.0), starts) for x, f in zip(cols, fins, strict=True)]
        ok = (n[0] > 0) & (n[1] > 0) & (n[2] > 0)
        self.idx.extend(k[starts][ok].tolist())
        for out, sm, c in zip((self.q, self.w, self.a), sums, n, strict=True):
            out.extend((sm[ok] / c[ok]).tolist())

    def feed(self, t: Array, dq: Array, T_w: Array, T_a: Array) -> None:
        """The next samples (``t`` increasing; NaN values are left out of their bin)."""
        t = np.asarray(t, dtype=float)
        if not len(t):
            return
        k = np.floor(t / BIN_S + 1e-9).astype(np.int64)
        cols = [np.asarray(x, dtype=float) for x in (dq, T_w, T_a)]
        if self._held:  # the open bin's samples first: a bin is summed whole
            k = np.concatenate((np.full(len(self._held[0]), self._open, dtype=np.int64), k))
            cols = [np.concatenate((h, x)) for h, x in zip(self._held, cols, strict=True)]
        last = int(np.searchsorted(k, k[-1]))  # the newest bin may go on in the next chunk
        if last > 0:
            self._add(k[:last], [x[:last] for x in cols])
        self._open = int(k[-1])
        self._held = tuple(x[last:].copy() for x in cols)
        if len(self.idx) > self.horizon + 1000:
            cut = len(self.idx) - self.horizon
            for lst in (self.idx, self.q, self.w, self.a):
                del lst[:cut]

    def window(self, t0: float, t1: float) -> tuple[Array, Array, Array, Array]:
        """Closed bins with centres in ``[t0, t1]``: ``(t_mid, q, T_w, T_a)``."""
        if not self.idx:
            z = np.zeros(0)
            return z, z, z, z
        idx = np.asarray(self.idx)
        tm = (idx + 0.5) * BIN_S
        lo, hi = np.searchsorted(tm, [t0, t1 + 1e-9])
        return (tm[lo:hi], np.asarray(self.q[lo:hi]), np.asarray(self.w[lo:hi]),
                np.asarray(self.a[lo:hi]))

    def finish(self) -> None:
        """Close the open bin (the end of a log)."""
        if self._held and len(self._held[0]):
            self._add(np.full(len(self._held[0]), self._open, dtype=np.int64), list(self._held))
        self._held = ()
        self._open = -1


# --------------------------------------------------------------------------------- estimate
def _noise(q: Array) -> float:
    """A bin's noise from successive differences (robust: median absolute difference)."""
    if len(q) < 4:
        return SIGMA_FEW
    return max(SIGMA_MIN, 1.4826 * float(np.median(np.abs(np.diff(q)))) / math.sqrt(2.0))


def estimate(tau: Array, q: Array, T_x: Array, T_x0: float, tau_det: float, T_room: float,
             R_par: float, use: NDArray[np.bool_] | None = None
             ) -> tuple[dict[str, float], dict[str, float], dict[str, float]]:
    """The posterior from binned data (module doc): ``(class probabilities, posterior
    moments, data-only standard deviations)``.

    ``tau`` bin times since the onset (s), ``q`` the estimate over them (W), ``T_x`` the
    no-touch sheet (°C) over them and ``T_x0`` before the onset; ``tau_det`` the detection
    (s after the onset); ``T_room`` the air (°C, for room-temperature objects); ``use``
    the bins whose estimate counts (default all; ``T_x`` counts over all of them).
    """
    if use is None:
        use = np.ones(len(tau), dtype=bool)
    pg = prior_grid(R_par)
    comps = pg.comps
    G1 = pg.G1
    nk = len(KAPPA)
    # least squares per κ: sufficient statistics of q = a u1 - b u2 with weights 1/σ_b²
    data = bool(use.any())
    q = q[use]
    sig0 = _noise(q) if data else SIGMA_FEW
    S = np.zeros((nk, 6))  # Sqq, Sq1, Sq2, S11, S12, S22
    best: tuple[float, int, Array, Array] | None = None
    if data:
        extra = TRANSIENT_REL * np.abs(q) * np.exp(-np.maximum(tau[use] - tau_det, 0.0) / TRANSIENT_S)
        var0 = sig0 ** 2 + (MODEL_ERR * q) ** 2 + extra ** 2
        # correlated noise: inflate by (1 + ρ)/(1 - ρ) of the residuals at the best κ (below)
        U = [tuple(u[use] for u in regressors(float(k), tau, T_x, T_x0)) for k in KAPPA]
        w = 1.0 / var0
        for i, (u1, u2) in enumerate(U):
            S[i] = (np.sum(w * q * q), np.sum(w * q * u1), np.sum(w * q * u2), np.sum(w * u1 * u1),
                    np.sum(w * u1 * u2), np.sum(w * u2 * u2))
            M = np.array([[S[i, 3], -S[i, 4]], [-S[i, 4], S[i, 5]]])
            r = np.array([S[i, 1], -S[i, 2]])
            th = np.linalg.lstsq(M, r, rcond=1e-12)[0]
            rss = S[i, 0] - 2 * th @ r + th @ M @ th
            if best is None or rss < best[0]:
                best = (float(rss), i, th, M)
        assert best is not None
        i_b = best[1]
        u1, u2 = U[i_b]
        res = q - best[2][0] * u1 + best[2][1] * u2
        rho = 0.0
        if len(res) >= 8:
            rr = res - res.mean()
            den = float(rr @ rr)
            rho = float(rr[1:] @ rr[:-1]) / den if den > 0 else 0.0
        infl = float(np.clip((1.0 + rho) / (1.0 - rho) if rho < 1 else 5.0, 1.0, 5.0))
        S /= infl
        M = best[3] / infl
    # for each (κ, G' = b) the likelihood is Gaussian in T_0 (a = b T_0):
    #   RSS = C - ... ,  precision P = b² S11, mean μ = (Sq1 + b S12)/(b S11)
    b = G1[None, :]
    Sqq, Sq1, Sq2, S11, S12, S22 = (S[:, i, None] for i in range(6))
    if data:
        P = b * b * S11
        mu = (Sq1 + b * S12) / (b * S11)
        C = Sqq + 2 * b * Sq2 + b * b * S22 - (Sq1 + b * S12) ** 2 / S11
        v = 1.0 / P
        base = -0.5 * C + 0.5 * np.log(2.0 * math.pi * v)
    else:
        mu = np.zeros((len(KAPPA), len(G1)))
        v = np.full_like(mu, 1e12)
        base = np.zeros_like(mu)
    # posterior over (component, κ, G'), T_0 integrated (a softened box prior per component)
    logw = np.empty((len(comps), len(KAPPA), len(G1)))
    T1 = np.empty_like(logw)
    T2 = np.empty_like(logw)
    box = np.array([t0_box(comp, T_room) for comp in comps])  # every component at once
    lo, hi = box[:, 0, None, None], box[:, 1, None, None]
    lM0, mean, var = _box_moments(mu[None], v[None], lo, hi, T0_SMOOTH)
    share = np.log([comp.share for comp in comps])[:, None, None]
    logw[:] = base[None] + lM0 - np.log(hi - lo) + pg.lp_gk + share
    T1[:] = mean
    T2[:] = var + mean * mean
    logw -= logw.max()
    W = np.exp(logw)
    W /= W.sum()
    p_comp = W.sum(axis=(1, 2))
    p_class: dict[str, float] = {}
    for comp, p in zip(comps, p_comp.tolist(), strict=True):
        p_class[comp.cls] = p_class.get(comp.cls, 0.0) + p
    T_mean = float(np.sum(W * T1))
    T_sd = math.sqrt(max(0.0, float(np.sum(W * T2)) - T_mean ** 2))
    wG = W.sum(axis=(0, 1))
    Gc = G1 / (1.0 - G1 * R_par)
    G_mean = float(wG @ Gc)
    G_sd = math.sqrt(max(0.0, float(wG @ Gc ** 2) - G_mean ** 2))
    le1 = float(np.sum(W * pg.m1))
    le2 = float(np.sum(W * pg.m2))
    le_sd = math.sqrt(max(0.0, le2 - le1 ** 2))
    post = {"T_0": T_mean, "T_0_sd": T_sd, "G": G_mean, "G_sd": G_sd, "ln_e": le1, "ln_e_sd": le_sd,
            "kappa": float(KAPPA[int(np.argmax(W.sum(axis=(0, 2))))])}
    # the data alone: the least-squares fit at the best κ
    dsd = {"T_0": math.inf, "G_rel": math.inf}
    if data and best is not None:
        th = best[2]
        try:
            cov = np.linalg.inv(M)
        except np.linalg.LinAlgError:
            cov = None
        b_hat = float(th[1])
        if cov is not None and b_hat > 0 and b_hat * R_par < 1.0 and np.all(np.diag(cov) >= 0):
            T0 = float(th[0]) / b_hat
            var_T = (cov[0, 0] - 2 * T0 * cov[0, 1] + T0 * T0 * cov[1, 1]) / b_hat ** 2
            dsd["T_0"] = math.sqrt(max(var_T, 0.0))
            dsd["G_rel"] = math.sqrt(cov[1, 1]) / b_hat / (1.0 - b_hat * R_par)
            dsd["T_0_fit"] = T0
            dsd["G_fit"] = b_hat / (1.0 - b_hat * R_par)
    post["p_human"] = float(sum(p for comp, p in zip(comps, p_comp.tolist(), strict=True) if comp.human))
    return p_class, post, dsd


class Characteriser:
    """Characterises contacts from the per-sample signals, fed as they come (module doc).

    ``feed(t, dq_i_hat, T_w, T_a)`` with each chunk; ``characterise(event, at=τ)`` uses the
    contact from its onset to its release, or to ``τ`` s after the onset (what a live call
    then would know); ``annotate(event)`` returns the event with the fields filled.
    """

    def __init__(self, cfg: Config) -> None:
        self.cfg = cfg
        self.R_par = sheet_coupling(cfg)
        self.bins = Bins(cfg.detector.max_contact_s + 60.0)

    def feed(self, t: Array, dq_i_hat: Array, T_w: Array, T_a: Array) -> None:
        self.bins.feed(t, dq_i_hat, T_w, T_a)

    def finish(self) -> None:
        """The log ended: close its last bin."""
        self.bins.finish()

    def characterise(self, event: ContactEvent, at: float | None = None) -> Character:
        t0 = event.onset
        end = window_end(event, at)
        tm_pre, _, Tw_pre, Ta_pre = self.bins.window(t0 - PRE_S, t0)
        tm, q, Tw, Ta = self.bins.window(t0, end)
        if len(tm_pre):
            T_room = float(np.mean(Ta_pre))
            T_x0 = float(np.mean(no_touch_sheet(self.cfg, Tw_pre, T_room)))
        elif len(tm):
            T_room = float(Ta[0])
            T_x0 = float(no_touch_sheet(self.cfg, Tw[0], T_room))
        else:
            T_room, T_x0 = math.nan, math.nan
        tau = tm - t0
        T_x = no_touch_sheet(self.cfg, Tw, T_room) if len(tm) else np.zeros(0)
        tau_det = event.detected_at - t0
        use = tm >= event.detected_at
        if not math.isfinite(T_x0):
            use[:] = False
            T_x0, T_room = 20.0, 20.0
        # the bins before the detection still shape T_x's history; only the estimate is left out
        p_class, post, dsd = estimate(tau, q, T_x, T_x0, tau_det, T_room, self.R_par, use)
        return _decide(event, p_class, post, dsd, float(end - t0) if math.isfinite(end) else math.nan,
                       at)

    def annotate(self, event: ContactEvent, at: float | None = None) -> ContactEvent:
        """``event`` with what touched (:data:`thermoskin.estimation.events.CHARACTER_COLUMNS`)."""
        return dataclasses.replace(event, **self.characterise(event, at).fields())  # type: ignore[arg-type]


def _decide(event: ContactEvent, p_class: Mapping[str, float], post: Mapping[str, float],
            dsd: Mapping[str, float], t_used: float, at: float | None) -> Character:
    """The identifiability rules (module doc)."""
    p_h = post["p_human"]
    toucher = "human" if p_h >= P_DECIDE else "object" if p_h <= 1.0 - P_DECIDE else ""
    cls, p_cls = max(p_class.items(), key=lambda kv: kv[1])
    material = cls if p_cls >= P_MATERIAL else ""
    nan = math.nan
    T_ok = dsd["T_0"] <= T_SD_MAX and post["T_0_sd"] <= T_SD_MAX
    G_ok = dsd["G_rel"] <= G_RSD_MAX
    e_ok = post["ln_e_sd"] <= E_LSD_MAX
    duration = event.duration if at is None or event.release <= event.onset + at else nan
    return Character(
        kind=one_patch_kind(duration), toucher=toucher, material=material, p_human=p_h,
        G_hat=post["G"] if G_ok else nan, G_sd=post["G_sd"] if G_ok else nan,
        T_f_hat=post["T_0"] if T_ok else nan, T_f_sd=post["T_0_sd"] if T_ok else nan,
        effusivity_hat=math.exp(post["ln_e"]) if e_ok else nan,
        p_class=dict(p_class), post=dict(post), data_sd=dict(dsd), t_used=t_used)


def window_end(event: ContactEvent, at: float | None = None) -> float:
    """The last time (s) :meth:`Characteriser.characterise` reads for ``event`` (inf: to the
    log's end, a contact still open)."""
    end = event.release if math.isfinite(event.release) else math.inf
    if at is not None:
        end = min(end, event.onset + at)
    return min(end, event.onset + MAX_S)


def characterise_events(events: Sequence[ContactEvent], columns: Mapping[str, Array], cfg: Config,
                        at: float | None = None) -> list[ContactEvent]:
    """The events of a log held in memory (``t, dq_i_hat, T_w, T_a``), annotated. The log is
    fed up to just past each event's window (the characteriser holds only its last minutes of
    bins, so a long log fed whole would have lost an early contact's), which gives the bins
    any chunking gives."""
    ch = Characteriser(cfg)
    t = np.asarray(columns["t"], dtype=float)
    cols = [columns[k] for k in ("dq_i_hat", "T_w", "T_a")]
    out: list[ContactEvent | None] = [None] * len(events)
    k0 = 0
    for i in sorted(range(len(events)), key=lambda i: window_end(events[i], at)):
        k1 = int(np.searchsorted(t, window_end(events[i], at) + BIN_S, side="right")) + 1
        if k1 > k0 and k0 < len(t):  # every bin of its window closed (or the log's end)
            ch.feed(t[k0:k1], *(x[k0:k1] for x in cols))
            k0 = min(k1, len(t))
            if k0 == len(t):
                ch.finish()
        out[i] = ch.annotate(events[i], at)
    return out  # type: ignore[return-value]
