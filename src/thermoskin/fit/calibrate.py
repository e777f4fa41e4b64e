"""Fit the skin's network parameters (Fig. 3, eqs. 3-7) and ``R_w`` to a recorded log.

**Model.** The two-node network of ``physics.network`` with no touch (``q_i = 0``)::

    C_w dT_w/dt = (T_p - T_w)/R_w(v) - (T_w - T_a)/R_aw - (T_w - T_g)/R_g
    C_g dT_g/dt = (T_w - T_g)/R_g - (T_g - T_a)/R_ag

``R_w(v) = R_w_flowing`` while the pump runs (``v > 0``), ``R_w_stopped`` while it is
stopped (config keys ``skin.R_w_flowing``, ``skin.R_w_stopped``; eq. 1 where neither is set).

**Output error.** The network is simulated from the log's inputs ``T_p, v, T_a`` alone
and compared with the measured ``T_w``; the measured ``T_w`` is never fed back. (A
one-step predictor would take the noisy ``T_w`` as its state and bias every parameter:
errors in the variables. The output error is unbiased for white sensor noise, at the
price of residuals that are correlated wherever the model is wrong; see *Intervals*.)

**Blocks.** The log is cut into blocks of at most ``m = t_fit / t_s`` samples that never
straddle a pump switch. Over a block of ``n`` samples the inputs are held at their block
means and, with ``Phi, Gamma`` the exact ZOH discretisation at ``t_s`` of
``physics.network.state_space`` (in closed form, :func:`block_tables`; tested against
``physics.network.discretize``)::

    x_{k+n} = Phi^n x_k + S_n u,               S_n = sum_{i<n} Phi^i Gamma
    mean_{i<n} x_{k+i} = M_n x_k + N_n u,      M_n = (1/n) sum_{i<n} Phi^i,
                                                N_n = (1/n) sum_{i<n} S_i

exact for inputs constant over the block. Block ``j``'s residual is
``e_j = sqrt(n_j) (mean T_w - mean T_w_hat)``: with white sensor noise of standard
deviation ``sigma`` every ``e_j`` has variance ``sigma^2``, so each sample weighs alike at
the cost of one block instead of ``n`` samples. Blocks are an option (``t_fit``), not the
default: the pump switches on the very reading of ``T_w`` it is fitted to (its logic runs
on the measured ``T_w``), so a block mixes a reading with the model's response to the
switch that reading caused; on a chattering log 10 ms blocks biased ``R_g`` and
``R_w_flowing`` by 2.2 standard deviations, single samples (``t_fit = 0``) by 0.6.

**Stretches and their start.** Usable rows (finite readings, away from flagged contacts)
form stretches; each starts from its measured ``T_w`` (the mean of its first
:data:`N_START` samples) and the sheet's equilibrium for it,
``T_g = (T_w/R_g + T_a/R_ag) / (1/R_g + 1/R_ag)``. The prediction is linear in that
starting ``T_w``, so its correction ``d`` is eliminated per stretch by linear least
squares (variable projection): ``d = sum e_j h_j / sum h_j^2`` with ``h_j`` the
response of block ``j`` to a unit start (``sqrt(n_j)`` weighted), ``e_j -= h_j d``.

**Fit.** ``scipy.optimize.least_squares`` (trust-region reflective) on ``theta = ln p``
(positivity), bounded to ``prior x/÷`` :data:`BOUND`.

**Intervals.** At the optimum, with ``J`` the Jacobian of the residuals in ``theta``
(central differences) and ``H = J'J`` (:func:`covariance`)::

    Cov theta = f H^-1 (s_w^2 H + E[J' G n_p n_p' G' J]) H^-1

The first term is the white ``T_w`` noise; the second the tank sensor's noise ``n_p``
(its level from the first differences of ``T_p``, :func:`input_noise`) carried through
the network ``G`` into the prediction, by Monte Carlo draws through the model (linear
in its inputs); ``s_w^2`` is the residual variance less that share. ``f = max(1,
tau / tau_model)`` inflates for colour the noise model does not explain (model error):
``tau = 1 + 2 sum_k rho_k`` is the residuals' integrated autocorrelation time (Geyer's
initial positive sequence, :func:`autocorrelation_time`), ``tau_model`` that of a
residual drawn from the noise model. A scalar ``tau`` alone (``s^2 tau H^-1``, an
effective sample size) was measured to give intervals 1.3-1.65 times too narrow: the
filtered tank noise is a small share of the residuals' variance but sits where ``J``
has its weight. 95 % intervals: ``exp(theta ± 1.96 sd)``. The inputs' noise also biases
the fit a little (errors in the variables); ``T_a`` is smoothed over :data:`SMOOTH_T_A`
first (the air is slow), ``T_p`` is not (a ramping tank's kinks would bias more).

**What a log can determine.** Temperatures fix the network only up to a common scale of
heat: every ``C`` times ``k`` and every ``R`` over ``k`` leave every temperature as it
was. One heat-carrying parameter must be held; by default ``C_w``
(:data:`DEFAULT_PARAMS`), and the fitted values are relative to it. With a constant
ambient, ``R_aw`` trades exactly against ``R_g, R_ag, C_g`` (only ``1/R_aw + 1/R_g``,
``C_g/R_g^2`` and ``(1/R_g + 1/R_ag)/C_g`` reach ``T_w``). The sheet, ten times faster
than the pipe, is seen through ``T_w`` almost as a static divider: ``C_g`` and the split
of ``R_g + R_ag`` are barely determined. ``R_w_stopped`` needs the pump to stop for long
enough (chattering stops of 50 ms tell little), ``R_w_flowing`` to run.

Those limits are found from the data, not assumed: after each fit, if the weakest
direction of ``J`` (its smallest singular value) is known to worse than ``×/÷
exp(1.96 SD_MAX)`` (95 %), the parameter with the largest share in it is held at its
prior and the rest are fitted again. A fitted parameter's value then depends on what
the held ones were set to: :attr:`Calibration.dependence` gives those elasticities,
``d ln p_fit / d ln p_held`` (the least-squares response to a held parameter's change).

**Touch logs.** A touch heats the sheet by an unknown, varying heat flow. Rows flagged in
a ``contact`` column are left out, with :data:`PAD_BEFORE` s before (the detector's
latency) and :data:`PAD_AFTER` s after (the recovery); each stretch between restarts
(above). Unknown piecewise-constant heat inputs per contact were not used: a finger is a
conductance to a body, so its heat falls through a contact; the detector's flags lag
the onset; and the touch heat reaching the pipe is scaled by the very ``R_g : R_ag``
split the log cannot determine, so such inputs would add unknowns without adding
information about the skin.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from thermoskin._jit import njit
from thermoskin.atomic import write_text
from thermoskin.params import Config, to_toml
from thermoskin.physics.convection import R_w as R_w_model
from thermoskin.physics.network import state_space

Array = NDArray[np.float64]

PARAMS: tuple[str, ...] = ("C_w", "C_g", "R_g", "R_aw", "R_ag", "R_w_flowing", "R_w_stopped")
"""Every parameter :func:`calibrate` can fit (keys of ``[skin]``)."""
DEFAULT_PARAMS: tuple[str, ...] = PARAMS[1:]
"""Fitted by default: all but ``C_w``, which holds the heat scale (module doc)."""
UNITS = {"C_w": "J/K", "C_g": "J/K", "R_g": "K/W", "R_aw": "K/W", "R_ag": "K/W",
         "R_w_flowing": "K/W", "R_w_stopped": "K/W"}
NETWORK = ("C_w", "C_g", "R_g", "R_aw", "R_ag")
COLUMNS = ("t", "T_w", "T_p", "v", "T_a")

T_FIT = 0.0
"""Longest block, s; 0: every sample its own (the default; see the module doc)."""
N_START = 5
"""Samples averaged for the measured ``T_w`` a stretch starts from."""
PAD_BEFORE = 0.5
"""Seconds left out before a flagged contact (the detector's latency)."""
PAD_AFTER = 1.0
"""Seconds left out after a flagged contact (the sheet's and the pipe's recovery)."""
SMOOTH_T_P = 0.0
"""Width of the centred moving mean on ``T_p``, s (0: none; the noise of ``T_p`` enters the
covariance instead: a mean over 0.1 s biases the fit more, at the kinks of a ramping tank)."""
SMOOTH_T_A = 1.0
"""Width of the centred moving mean on ``T_a``, s."""
MIN_USABLE_S = 5.0
"""Fewest seconds of usable samples (finite, away from contacts)."""
MIN_STRETCH_S = 0.2
"""Shorter usable stretches are dropped."""
BOUND = 1000.0
"""Bounds of the fit: ``prior / BOUND <= p <= prior * BOUND``."""
SD_MAX = 0.2
"""A direction of ``ln p`` known to a standard deviation above this is not determined
(95 % interval wider than ×/÷ 1.5): weakly determined directions are the first a small
bias (the tank's noise, the pump deciding on the readings) throws off by several sd."""
NULL_RTOL = 1e-6
"""A direction whose singular value is below this fraction of the largest is not seen at all."""
DEP_FACTOR = 2.0
DEP_MIN = 0.001
"""A fitted parameter depends on a held one if the held one off by ×/÷ ``DEP_FACTOR`` would
move it by more than its standard deviation (and the elasticity is at least ``DEP_MIN``)."""
Z95 = 1.959963984540054
N_DRAWS = 100
"""Monte Carlo draws of the tank sensor's noise for the covariance."""


class CalibrationError(ValueError):
    """The log or the request cannot be calibrated; the one-line message says why."""


# ---------------------------------------------------------------------------- blocks
@dataclass(frozen=True)
class Blocks:
    """The log cut into blocks (module doc): one entry per block; ``w0, Ta0`` per stretch."""

    t0: float               # time of the log's first row, s
    t_s: float
    m: int
    v_modes: Array          # the distinct pump velocities, m/s
    mode: NDArray[np.int64]  # index into v_modes
    nlen: NDArray[np.int64]
    first: NDArray[np.int64]  # first row of each block
    stretch: NDArray[np.int64]  # stretch of each block
    Tp: Array
    Ta: Array
    Tw: Array               # measured block means
    start: NDArray[np.bool_]
    w0: Array               # measured T_w each stretch starts from
    Ta0: Array

    @property
    def n_samples(self) -> int:
        return int(self.nlen.sum())

    @functools.cached_property
    def weight(self) -> Array:
        """``sqrt(n_j)``: every sample weighs alike."""
        return np.sqrt(self.nlen.astype(float))

    @property
    def t_mid(self) -> Array:
        """Mid time of each block, s (the log's clock)."""
        return self.t0 + (self.first + 0.5 * (self.nlen - 1)) * self.t_s


def _runs(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """Index ranges ``[a, b)`` where ``mask`` holds."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(), strict=True))


def usable_rows(log: Mapping[str, Array], t_s: float, contact: ArrayLike | None = None,
                pad: tuple[float, float] = (PAD_BEFORE, PAD_AFTER)) -> NDArray[np.bool_]:
    """Rows with finite ``T_w, T_p, T_a, v`` and, if ``contact`` is given, ``pad`` s away from contacts."""
    ok = np.ones(len(log["t"]), dtype=bool)
    for k in ("T_w", "T_p", "T_a", "v"):
        ok &= np.isfinite(np.asarray(log[k], dtype=float))
    if contact is not None:
        c = np.nan_to_num(np.asarray(contact, dtype=float)) > 0.5
        before, after = round(pad[0] / t_s), round(pad[1] / t_s)
        for a, b in _runs(c):
            ok[max(0, a - before):b + after] = False
    return ok


def centred_mean(x: ArrayLike, runs: Sequence[tuple[int, int]], half: int) -> Array:
    """Centred moving mean over ``2 h + 1`` samples, ``h = min(half, distance to the run's ends)``,
    within each run ``[a, b)``; rows outside the runs are left as they are.

    Symmetric everywhere (zero phase): a straight line is left as it is.
    """
    out = np.array(x, dtype=float)
    if half <= 0:
        return out
    for a, b in runs:
        cs = np.concatenate([[0.0], np.cumsum(out[a:b])])
        i = np.arange(b - a)
        h = np.minimum(half, np.minimum(i, b - a - 1 - i))
        out[a:b] = (cs[i + h + 1] - cs[i - h]) / (2 * h + 1)
    return out


def make_blocks(log: Mapping[str, ArrayLike], t_s: float, usable: NDArray[np.bool_],
                t_fit: float = T_FIT, smooth: tuple[float, float] = (SMOOTH_T_P, SMOOTH_T_A)) -> Blocks:
    """Cut the usable rows into blocks of at most ``t_fit`` s that never straddle a pump switch.

    The inputs ``T_p`` and ``T_a`` are first smoothed by centred moving means of ``smooth`` s
    (tank and air are slow; their sensor noise, fed into the model, would bias the fit).
    """
    v = np.asarray(log["v"], dtype=float)
    m = max(1, min(round(t_fit / t_s), len(v)))  # a block is at most the whole log
    v_modes = np.unique(v[usable])
    min_len = max(2, round(MIN_STRETCH_S / t_s))
    T_w = np.asarray(log["T_w"], dtype=float)
    T_a = np.asarray(log["T_a"], dtype=float)
    firsts: list[int] = []
    lens: list[int] = []
    starts: list[bool] = []
    sids: list[int] = []
    w0: list[float] = []
    Ta0: list[float] = []
    for a, b in _runs(usable):
        if b - a < min_len:
            continue
        sid = len(w0)
        w0.append(float(np.mean(T_w[a:a + N_START])))
        Ta0.append(float(T_a[a]))
        edges = [a, *(a + 1 + np.flatnonzero(np.diff(v[a:b]) != 0)).tolist(), b]
        for c0, c1 in itertools.pairwise(edges):
            for s in range(c0, c1, m):
                starts.append(len(sids) == 0 or sids[-1] != sid)
                firsts.append(s)
                lens.append(min(m, c1 - s))
                sids.append(sid)
    first = np.asarray(firsts, dtype=np.int64)
    nlen = np.asarray(lens, dtype=np.int64)

    runs = _runs(usable)
    inputs = {"T_w": np.asarray(log["T_w"], dtype=float),
              "T_p": centred_mean(log["T_p"], runs, round(0.5 * smooth[0] / t_s)),
              "T_a": centred_mean(log["T_a"], runs, round(0.5 * smooth[1] / t_s))}

    def means(name: str) -> Array:
        x = np.where(usable, inputs[name], 0.0)  # no NaN in the sums
        csum = np.concatenate([[0.0], np.cumsum(x)])
        return (csum[first + nlen] - csum[first]) / nlen if first.size else np.zeros(0)

    t = np.asarray(log["t"], dtype=float)
    return Blocks(t0=float(t[0]) if t.size else 0.0, t_s=t_s, m=m, v_modes=v_modes,
                  mode=np.searchsorted(v_modes, v[first]).astype(np.int64), nlen=nlen, first=first,
                  stretch=np.asarray(sids, dtype=np.int64), Tp=means("T_p"), Ta=means("T_a"),
                  Tw=means("T_w"), start=np.asarray(starts, dtype=np.bool_), w0=np.asarray(w0),
                  Ta0=np.asarray(Ta0))


# ---------------------------------------------------------------------------- the model
def block_tables(A: Array, B: Array, t_s: float, m: int) -> Array:
    """``(m + 1, 12)`` rows ``[Phi^n (4), S_n (4), M_n[0, :] (2), N_n[0, :] (2)]``, ``n = 0..m``.

    ``A`` 2x2 with real distinct eigenvalues ``l_1, l_2`` (a thermal network: ``A_12 A_21 > 0``),
    ``B`` 2x2 (inputs ``T_p, T_a``); matrices row-major; row 0 unused. By Sylvester's formula,
    with ``E_i = (A - l_j I)/(l_i - l_j)`` (so ``sum E_i = I``, ``A E_i = l_i E_i``) and
    ``q_i = exp(l_i t_s)``::

        Phi^n = sum_i q_i^n E_i,                S_n = sum_i (q_i^n - 1)/l_i E_i B
        M_n = sum_i mu_i(n) E_i,                N_n = sum_i (mu_i(n) - 1)/l_i E_i B
        mu_i(n) = (1/n) sum_{k<n} q_i^k = (q_i^n - 1) / (n (q_i - 1))
    """
    a, b, c, d = float(A[0, 0]), float(A[0, 1]), float(A[1, 0]), float(A[1, 1])
    mid = 0.5 * (a + d)
    disc = (0.5 * (a - d)) ** 2 + b * c
    if not disc > 0.0:
        raise ValueError("block_tables: A needs real distinct eigenvalues (A_12 A_21 > 0)")
    delta = math.sqrt(disc)
    lam = np.array([mid + delta, mid - delta])
    E = np.stack([(A - lam[1] * np.eye(2)) / (lam[0] - lam[1]),
                  (A - lam[0] * np.eye(2)) / (lam[1] - lam[0])])  # (2, 2, 2)
    EB = E @ B
    n = np.arange(1, m + 1, dtype=float)[:, None]                  # (m, 1)
    x = lam[None, :] * n * t_s                                     # (m, 2)
    qn = np.exp(x)
    sn = np.expm1(x) / lam                                         # (q^n - 1)/l
    mu = np.expm1(x) / (n * np.expm1(lam * t_s))
    out = np.zeros((m + 1, 12))
    out[1:, 0:4] = (qn @ E.reshape(2, 4))
    out[1:, 4:8] = (sn @ EB.reshape(2, 4))
    out[1:, 8:10] = mu @ E[:, 0, :]
    out[1:, 10:12] = ((mu - 1.0) / lam) @ EB[:, 0, :]
    return out


@njit(cache=True)
def _predict(tab, mode, nlen, Tp, Ta, start, w0, g0, kg, out, out_h):  # pragma: no cover - compiled
    """Block means of the predicted ``T_w`` (``out``) and of the response to a unit start (``out_h``)."""
    w = 0.0
    g = 0.0
    wh = 0.0
    gh = 0.0
    s = 0
    for j in range(mode.shape[0]):
        if start[j]:
            w = w0[s]
            g = g0[s]
            wh = 1.0
            gh = kg
            s += 1
        c = tab[mode[j], nlen[j]]
        p = Tp[j]
        a = Ta[j]
        out[j] = c[8] * w + c[9] * g + c[10] * p + c[11] * a
        out_h[j] = c[8] * wh + c[9] * gh
        w, g = (c[0] * w + c[1] * g + c[4] * p + c[5] * a,
                c[2] * w + c[3] * g + c[6] * p + c[7] * a)
        wh, gh = c[0] * wh + c[1] * gh, c[2] * wh + c[3] * gh


def predict(blocks: Blocks, values: Mapping[str, float], cfg: Config) -> tuple[Array, Array]:
    """Block means of ``T_w`` predicted with ``values`` (others from ``cfg``), and of the
    response to a unit change of each stretch's starting ``T_w`` (module doc)."""
    skin = dataclasses.replace(cfg.skin, **{k: values[k] for k in NETWORK if k in values})
    tabs = np.empty((blocks.v_modes.size, blocks.m + 1, 12))
    for i, v in enumerate(blocks.v_modes.tolist()):
        key = "R_w_flowing" if v > 0 else "R_w_stopped"
        A, B = state_space(skin, values[key] if key in values else R_w_model(v, skin))
        tabs[i] = block_tables(A, B[:, :2], blocks.t_s, blocks.m)
    Rg, Rag = skin.R_g, skin.R_ag
    kg = (1.0 / Rg) / (1.0 / Rg + 1.0 / Rag)
    g0 = kg * blocks.w0 + (1.0 - kg) * blocks.Ta0
    out = np.empty(blocks.mode.size)
    out_h = np.empty(blocks.mode.size)
    _predict(tabs, blocks.mode, blocks.nlen, blocks.Tp, blocks.Ta, blocks.start, blocks.w0, g0, kg,
             out, out_h)
    return out, out_h


@njit(cache=True)
def _project(Tw, w, y, h, stretch, n_stretch, e):  # pragma: no cover - compiled
    """``e = w (Tw - y)`` less, per stretch, its least-squares fit by ``w h`` (module doc)."""
    num = np.zeros(n_stretch)
    den = np.zeros(n_stretch)
    for j in range(Tw.shape[0]):
        e[j] = w[j] * (Tw[j] - y[j])
        hw = w[j] * h[j]
        num[stretch[j]] += hw * e[j]
        den[stretch[j]] += hw * hw
    for j in range(Tw.shape[0]):
        k = stretch[j]
        if den[k] > 0.0:
            e[j] -= w[j] * h[j] * num[k] / den[k]


def residuals(blocks: Blocks, values: Mapping[str, float], cfg: Config) -> Array:
    """Weighted block residuals ``e_j`` with each stretch's start projected out (module doc)."""
    y, h = predict(blocks, values, cfg)
    e = np.empty(y.size)
    _project(blocks.Tw, blocks.weight, y, h, blocks.stretch, blocks.w0.size, e)
    return e


def prior_values(cfg: Config, v_on: float | None = None) -> dict[str, float]:
    """Every parameter of :data:`PARAMS` as ``cfg`` has it (``R_w`` by eq. 1 where not set).

    ``v_on``: the velocity of the flowing ``R_w``, m/s (default ``cfg.pump.v_on``).
    """
    vals = {k: float(getattr(cfg.skin, k)) for k in NETWORK}
    vals["R_w_flowing"] = float(R_w_model(cfg.pump.v_on if v_on is None else v_on, cfg.skin))
    vals["R_w_stopped"] = float(R_w_model(0.0, cfg.skin))
    return vals


# ---------------------------------------------------------------------------- statistics
def autocorrelation_time(x: ArrayLike) -> float:
    """``tau = 1 + 2 sum_{k>=1} rho_k`` by Geyer's initial positive sequence, floored at 1.

    Sums ``Gamma_j = rho_{2j} + rho_{2j+1}`` while positive, made non-increasing:
    ``tau = -1 + 2 sum_j Gamma_j``. For an AR(1) of coefficient ``phi``,
    ``tau = (1 + phi)/(1 - phi)``. ``N / tau`` is the effective sample size.
    """
    xx = np.asarray(x, dtype=float)
    xx = xx - xx.mean()
    n = xx.size
    if n < 4 or not np.any(xx):
        return 1.0
    nfft = 1 << (2 * n - 1).bit_length()
    f = np.fft.rfft(xx, nfft)
    acf = np.fft.irfft(f * np.conj(f), nfft)[:n]
    rho = acf / acf[0]
    tau = -1.0
    prev = math.inf
    for j in range(n // 2):
        g = rho[2 * j] + rho[2 * j + 1]
        if g <= 0.0:
            break
        g = min(g, prev)
        tau += 2.0 * g
        prev = g
    return max(1.0, tau)


def jacobian(fun: Callable[[Array], Array], theta: Array, h: float = 1e-5) -> Array:
    """Central-difference Jacobian of ``fun`` at ``theta``."""
    cols = []
    for i in range(theta.size):
        d = np.zeros_like(theta)
        d[i] = h
        cols.append((fun(theta + d) - fun(theta - d)) / (2.0 * h))
    return np.column_stack(cols) if cols else np.zeros((fun(theta).size, 0))


def input_noise(x: Array, blocks: Blocks) -> float:
    """Standard deviation of an input's sensor noise from its first differences in the stretches.

    ``sd(diff x) / sqrt(2)`` over consecutive rows of each stretch, differences beyond six
    robust standard deviations (``1.4826 MAD``) left out: the tank's temperature moves by far
    less than its noise in one sample, so the differences are noise. (The MAD alone reads
    low on quantised readings: 16 mK for 20 mK of noise in 1/128 K steps.)
    """
    xx = np.asarray(x, dtype=float)
    last = blocks.first + blocks.nlen  # one past each block's last row
    ends = np.flatnonzero(np.r_[blocks.start[1:], True])  # last block of each stretch
    begins = np.flatnonzero(blocks.start)
    d = np.concatenate([np.diff(xx[blocks.first[i]:last[j]]) for i, j in zip(begins, ends, strict=True)]
                       or [np.zeros(0)])
    if d.size < 10:
        return 0.0
    s0 = 1.4826 * float(np.median(np.abs(d - np.median(d))))
    if s0 > 0.0:
        d = d[np.abs(d - np.median(d)) <= 6.0 * s0]
    return float(np.std(d) / math.sqrt(2.0))


def covariance(blocks: Blocks, values: Mapping[str, float], cfg: Config, J: Array, e: Array,
               svd: tuple[Array, Array], sigma_p: float, draws: int = N_DRAWS,
               seed: int = 0) -> tuple[Array, float, float]:
    """Covariance of ``ln p`` at the optimum, the residuals' ``tau`` and the colour factor.

    The residual is ``e = w - G n_p + (model error)``: white sensor noise on ``T_w`` (variance
    ``s_w^2`` per sample) and the tank sensor's noise ``n_p`` (``sigma_p``, white, ``sigma_p^2 / n_j``
    on a block mean) filtered by the network. With ``H = J'J``::

        Cov = f H^-1 (s_w^2 H + E[J' G n_p n_p' G' J]) H^-1

    the expectation by ``draws`` Monte Carlo draws of ``n_p`` through the model (it is linear
    in its inputs), ``s_w^2 = s^2 - mean (G n_p)^2``. ``f = max(1, tau / tau_model)`` inflates
    for colour the noise model does not explain (model error): ``tau`` of the residuals over
    ``tau`` of a residual drawn from the noise model (:func:`autocorrelation_time`).
    """
    S, Vt = svd
    H_inv = (Vt.T / S**2) @ Vt
    n, p = J.shape
    s2 = float(e @ e) / max(n - p, 1)
    rng = np.random.default_rng(seed)
    e0 = residuals(blocks, values, cfg)
    C_p = np.zeros((p, p))
    var_p = 0.0
    e_p = np.zeros(n)
    if sigma_p > 0.0:
        sd_block = sigma_p / np.sqrt(blocks.nlen.astype(float))
        for _ in range(draws):
            b = dataclasses.replace(blocks, Tp=blocks.Tp + sd_block * rng.standard_normal(n))
            e_p = residuals(b, values, cfg) - e0
            g = J.T @ e_p
            C_p += np.outer(g, g) / draws
            var_p += float(e_p @ e_p) / (n * draws)
    s2_w = max(s2 - var_p, 0.0)
    tau = autocorrelation_time(e)
    tau_model = autocorrelation_time(math.sqrt(s2_w) * rng.standard_normal(n) + e_p)
    colour = max(1.0, tau / tau_model)
    return colour * (s2_w * H_inv + H_inv @ C_p @ H_inv), tau, colour


def _svd(J: Array) -> tuple[Array, Array]:
    """Singular values (descending, floored at 1e-12 of the largest) and right vectors of ``J``.

    From the eigen-decomposition of ``J'J`` (p x p): a tall SVD is slow on a busy machine.
    """
    w, V = np.linalg.eigh(J.T @ J)
    w, V = w[::-1], V[:, ::-1]
    S = np.sqrt(np.maximum(w, 0.0))
    return np.maximum(S, max(S[0], 1e-300) * 1e-12), V.T


def combination(names: Sequence[str], v: Array, keep: float = 0.05) -> str:
    """A direction of ``ln p`` as text, largest terms first: ``0.82 ln C_g - 0.56 ln R_ag``."""
    order = np.argsort(-np.abs(v))
    terms = [(float(v[i]), names[i]) for i in order if abs(v[i]) >= keep]
    if terms and terms[0][0] < 0:
        terms = [(-c, n) for c, n in terms]
    text = ""
    for c, n in terms:
        text += (f"{c:.2f}" if not text else (f" + {c:.2f}" if c >= 0 else f" - {-c:.2f}")) + f" ln {n}"
    return text


# ---------------------------------------------------------------------------- result
@dataclass(frozen=True)
class Calibration:
    """What :func:`calibrate` found.

    ``estimate``, ``low``, ``high`` (95 %) and ``sd_log`` (standard deviation of ``ln p``)
    hold every requested parameter. Those in ``held`` (name -> why) kept their prior:
    ``estimate`` is the prior and ``low, high`` the interval of the last fit that still
    freed them (NaN if none did). ``covariance`` and ``correlation`` are of ``ln p`` over
    ``names`` (the final fit's parameters), ``tau`` included. ``dependence[p][q]`` is
    ``d ln p / d ln q`` of a fitted ``p`` on a held ``q`` where it matters (:data:`DEP_FACTOR`).
    ``rms``: block residual (measured minus fitted block means), K; ``sigma``: the
    per-sample noise the residuals imply, K.
    """

    prior: Config
    requested: tuple[str, ...]
    names: tuple[str, ...]
    estimate: dict[str, float]
    low: dict[str, float]
    high: dict[str, float]
    sd_log: dict[str, float]
    covariance: Array
    correlation: Array
    held: dict[str, str]
    dependence: dict[str, dict[str, float]]
    prior_values: dict[str, float]
    rms: float
    sigma: float
    sigma_p: float
    tau: float
    colour: float
    n_samples: int
    n_stretches: int
    duration: float
    t_fit: float
    nfev: int
    wall_s: float
    blocks: Blocks = field(repr=False)
    fitted: Array = field(repr=False)

    @property
    def config(self) -> Config:
        """``prior`` with the fitted ``[skin]`` values; held parameters as they were."""
        return self.prior.replace(skin={k: self.estimate[k] for k in self.names})

    def interval(self, name: str) -> tuple[float, float]:
        """The 95 % interval of ``name``."""
        return self.low[name], self.high[name]

    @property
    def residuals(self) -> Array:
        """Measured minus fitted block means of ``T_w``, K."""
        return self.blocks.Tw - self.fitted

    def status(self, name: str) -> str:
        """``fitted``, ``fitted given R_ag, ...`` (its dependences) or ``held (why, short)``."""
        if name in self.held:
            why = self.held[name]
            return ("held: pump never " + ("stops" if "stops" in why else "runs") if "pump" in why
                    else "held: not determined")
        dep = self.dependence.get(name, {})
        return "fitted given " + ", ".join(dep) if dep else "fitted"


def _check_log(log: Mapping[str, ArrayLike]) -> tuple[dict[str, Array], float]:
    """The five columns as float arrays and the sample time; one-line errors."""
    missing = [k for k in COLUMNS if k not in log]
    if missing:
        raise CalibrationError(f"the log has no column {', '.join(missing)} (needs {', '.join(COLUMNS)})")
    cols = {k: np.asarray(log[k], dtype=float).ravel() for k in COLUMNS}
    n = cols["t"].size
    for k, a in cols.items():
        if a.size != n:
            raise CalibrationError(f"column {k} has {a.size} rows, t has {n}")
    if n < 2:
        raise CalibrationError(f"the log has {n} row(s): too short to calibrate")
    dt = np.diff(cols["t"])
    bad = np.flatnonzero(~(dt > 0))
    if bad.size or not np.isfinite(cols["t"]).all():
        row = int(bad[0]) + 2 if bad.size else int(np.flatnonzero(~np.isfinite(cols["t"]))[0]) + 1
        raise CalibrationError(f"t is not finite and strictly increasing at row {row}")
    t_s = float(np.median(dt))
    bad = np.flatnonzero(np.abs(dt - t_s) > 0.01 * t_s)
    if bad.size:
        raise CalibrationError(f"t is not uniformly sampled: interval {dt[bad[0]]:g} s at row "
                               f"{bad[0] + 2} (median {t_s:g} s)")
    neg = np.flatnonzero(cols["v"] < 0)
    if neg.size:
        raise CalibrationError(f"v = {cols['v'][neg[0]]:g} m/s at row {neg[0] + 1}: must be >= 0")
    return cols, t_s


def calibrate(log: Mapping[str, ArrayLike], cfg: Config, params: Sequence[str] = DEFAULT_PARAMS, *,
              t_fit: float = T_FIT, contact: ArrayLike | None = None,
              pad: tuple[float, float] = (PAD_BEFORE, PAD_AFTER),
              smooth: tuple[float, float] = (SMOOTH_T_P, SMOOTH_T_A),
              progress: Callable[[int, float], None] | None = None) -> Calibration:
    """Fit ``params`` (of :data:`PARAMS`) of ``cfg.skin`` to the log (module doc).

    ``log``: ``{column: array}`` with ``t, T_w, T_p, v, T_a`` (``logio.read_log``), uniformly
    sampled. ``contact``: rows to leave out, padded by ``pad`` s (default: the log's
    ``contact`` column, if any). ``progress(nfev, rms)`` after every model run (rms of the
    weighted residuals, K). Raises :class:`CalibrationError` for a log or request that
    cannot be calibrated.
    """
    from threadpoolctl import threadpool_limits

    # the linear algebra here is on tall, thin matrices: threads only contend (10x slower when busy)
    with threadpool_limits(limits=1, user_api="blas"):
        return _calibrate(log, cfg, params, t_fit=t_fit, contact=contact, pad=pad, smooth=smooth,
                          progress=progress)


def _calibrate(log: Mapping[str, ArrayLike], cfg: Config, params: Sequence[str], *, t_fit: float,
               contact: ArrayLike | None, pad: tuple[float, float], smooth: tuple[float, float],
               progress: Callable[[int, float], None] | None) -> Calibration:
    t_start = time.perf_counter()
    unknown = [p for p in params if p not in PARAMS]
    if unknown:
        raise CalibrationError(f"unknown parameter(s) {', '.join(unknown)} (known: {', '.join(PARAMS)})")
    requested = tuple(dict.fromkeys(params))
    if not requested:
        raise CalibrationError("no parameter to fit")
    if not (math.isfinite(t_fit) and t_fit >= 0):
        raise CalibrationError(f"t_fit = {t_fit} s must be >= 0")
    cols, t_s = _check_log(log)
    if contact is None and "contact" in log:
        contact = log["contact"]
    if contact is not None and np.size(contact) != cols["t"].size:
        raise CalibrationError(f"the contact column has {np.size(contact)} rows, t has {cols['t'].size}")
    blocks = make_blocks(cols, t_s, usable_rows(cols, t_s, contact, pad), t_fit, smooth)
    usable_s = blocks.n_samples * t_s
    if usable_s < MIN_USABLE_S:
        raise CalibrationError(f"too short: {usable_s:.2f} s of usable samples (finite, away from "
                               f"contacts, in stretches of {MIN_STRETCH_S:g} s or more); calibration "
                               f"needs {MIN_USABLE_S:g} s")
    runs, stops = bool(np.any(blocks.v_modes > 0)), bool(np.any(blocks.v_modes == 0))
    v_on = float(np.median(blocks.v_modes[blocks.v_modes > 0])) if runs else None
    prior = prior_values(cfg, v_on)
    held: dict[str, str] = {}
    if "R_w_stopped" in requested and not stops:
        held["R_w_stopped"] = "the pump never stops in this log: not identifiable"
    if "R_w_flowing" in requested and not runs:
        held["R_w_flowing"] = "the pump never runs in this log: not identifiable"
    free = [p for p in requested if p not in held]
    sensitive = set(NETWORK) | ({"R_w_flowing"} if runs else set()) | ({"R_w_stopped"} if stops else set())
    if sensitive <= set(free):
        raise CalibrationError(
            f"{', '.join(p for p in PARAMS if p in sensitive)} cannot all be fitted: temperatures fix "
            "the network only up to a common scale of heat (every C times k, every R over k); hold "
            "one at its config value (C_w by default)")

    nfev = 0

    def residual_fn(names: Sequence[str]) -> Callable[[Array], Array]:
        def fun(theta: Array) -> Array:
            nonlocal nfev
            e = residuals(blocks, dict(zip(names, np.exp(theta).tolist(), strict=True)), cfg)
            nfev += 1
            if progress is not None:
                progress(nfev, float(np.sqrt(np.mean(e * e))))
            return e

        return fun

    from scipy.optimize import least_squares

    estimate = dict(prior)
    low = dict.fromkeys(requested, math.nan)
    high = dict.fromkeys(requested, math.nan)
    sd_log = dict.fromkeys(requested, math.nan)
    undetermined: list[str] = []

    def hold(p: str, why: str) -> None:
        held[p] = f"not determined by this log: {why}"
        undetermined.append(p)
        free.remove(p)

    # directions the log does not see at all (an exact trade-off, e.g. R_aw at a constant ambient)
    if free:
        free0 = list(free)
        J0 = jacobian(residual_fn(free0), np.log([prior[p] for p in free0]))
        while free:
            S, Vt = _svd(J0[:, [free0.index(p) for p in free]])
            if S[-1] > NULL_RTOL * S[0]:
                break
            hold(free[int(np.argmax(np.abs(Vt[-1])))],
                 f"the fit does not change along {combination(free, Vt[-1])}")

    z = Z95
    sigma_p = input_noise(cols["T_p"], blocks)
    cov = np.zeros((0, 0))
    tau = colour = 1.0
    fun = residual_fn([])
    theta = np.zeros(0)
    J = np.zeros((blocks.mode.size, 0))
    while free:
        fun = residual_fn(free)
        lo = np.log([prior[p] / BOUND for p in free])
        hi = np.log([prior[p] * BOUND for p in free])
        th0 = np.log([prior[p] for p in free])  # from the prior: not from where a weak direction drifted
        res = least_squares(fun, th0, bounds=(lo, hi), x_scale="jac", method="trf",
                            xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=100 * (len(free) + 1))
        theta = res.x
        e = fun(theta)
        J = jacobian(fun, theta)
        vals = {**{q: estimate[q] for q in undetermined}, **dict(zip(free, np.exp(theta).tolist(),
                                                                       strict=True))}
        S, Vt = _svd(J)
        cov, tau, colour = covariance(blocks, vals, cfg, J, e, (S, Vt), sigma_p)
        sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
        for i, p in enumerate(free):
            half = min(z * float(sd[i]), 700.0)  # beyond: a factor above 1e300, as good as none
            estimate[p] = float(np.exp(theta[i]))
            sd_log[p] = float(sd[i])
            low[p] = float(np.exp(theta[i] - half))
            high[p] = float(np.exp(theta[i] + half))
        sd_weak = math.sqrt(max(float(Vt[-1] @ cov @ Vt[-1]), 0.0))
        if sd_weak <= SD_MAX:
            break
        worst = free[int(np.argmax(np.abs(Vt[-1])))]
        factor = math.exp(min(z * sd_weak, 700.0))
        hold(worst, f"{combination(free, Vt[-1])} is known only to ×/÷ {factor:.3g} (95 %)")
        estimate[worst] = prior[worst]
        cov = np.zeros((0, 0))
    if not free:
        theta = np.zeros(0)
        e = fun(theta)
        J = np.zeros((e.size, 0))

    # elasticities of the fitted parameters on the held ones: d theta_f = -pinv(J_f) J_h d theta_h
    dependence: dict[str, dict[str, float]] = {}
    if free and undetermined:
        vals = {p: estimate[p] for p in (*free, *undetermined)}

        def fun_h(th_h: Array) -> Array:
            v = dict(vals)
            v.update(zip(undetermined, np.exp(th_h).tolist(), strict=True))
            return residuals(blocks, v, cfg)

        J_h = jacobian(fun_h, np.log([vals[q] for q in undetermined]))
        D = -np.linalg.lstsq(J, J_h, rcond=None)[0]
        for i, p in enumerate(free):
            dep = {q: float(D[i, k]) for k, q in enumerate(undetermined)
                   if abs(D[i, k]) >= DEP_MIN and abs(D[i, k]) * math.log(DEP_FACTOR) > sd_log[p]}
            if dep:
                dependence[p] = dep

    w = blocks.weight
    sd = np.sqrt(np.diag(cov))
    corr = cov / np.outer(sd, sd) if sd.size else cov
    return Calibration(
        prior=cfg, requested=requested, names=tuple(free),
        estimate={p: estimate[p] for p in requested}, low=low, high=high, sd_log=sd_log,
        covariance=cov, correlation=corr, held=held, dependence=dependence,
        prior_values={p: prior[p] for p in requested},
        rms=float(np.sqrt(np.mean((e / w) ** 2))),
        sigma=float(np.sqrt((e @ e) / max(e.size - len(free), 1))), sigma_p=sigma_p, tau=tau,
        colour=colour,
        n_samples=blocks.n_samples, n_stretches=int(blocks.w0.size),
        duration=float(cols["t"][-1] - cols["t"][0] + t_s), t_fit=blocks.m * t_s, nfev=nfev,
        wall_s=time.perf_counter() - t_start, blocks=blocks, fitted=blocks.Tw - e / w)


# ---------------------------------------------------------------------------- output
def _g(x: float) -> str:
    return f"{x:.4g}" if math.isfinite(x) else "nan"


def summary_lines(cal: Calibration) -> list[str]:
    """How the fit was made and what it found, one line each (for the TOML and the terminal)."""
    lines = [
        f"output-error least squares on {cal.n_samples} usable samples "
        f"({cal.n_samples * cal.blocks.t_s:.1f} s of {cal.duration:.1f} s, {cal.n_stretches} stretch(es)) "
        + ("per sample; " if cal.blocks.m == 1 else f"in blocks of {cal.t_fit * 1e3:.0f} ms; ") +
        f"{cal.nfev} model runs, {cal.wall_s:.1f} s",
        (f"residual rms {cal.rms * 1e3:.2f} mK per block, {cal.sigma * 1e3:.1f} mK per sample; "
         if cal.blocks.m > 1 else f"residual rms {cal.sigma * 1e3:.1f} mK; ")
        + f"T_p noise {cal.sigma_p * 1e3:.1f} mK; residual autocorrelation time {cal.tau:.2f} "
        + ("blocks" if cal.blocks.m > 1 else "samples"),
        "95 % intervals exp(ln p ± 1.96 sd): Gauss-Newton covariance at the optimum with the T_w noise "
        "white and the T_p noise carried through the network; colour beyond that model: covariance "
        f"x {cal.colour:.2f}",
    ]
    if "C_w" not in cal.requested:
        lines.append(f"heat scale: C_w held at {_g(cal.prior.skin.C_w)} J/K (temperatures cannot fix it); "
                     "every fitted value is relative to it")
    for p, why in cal.held.items():
        lines.append(f"{p} held at {_g(cal.estimate[p])} {UNITS[p]}: {why}")
    for p, dep in cal.dependence.items():
        txt = ", ".join(f"{q} ({e:+.2g})" for q, e in dep.items())
        lines.append(f"{p} depends on the held {txt}: d ln {p} / d ln held")
    return lines


def to_toml_text(cal: Calibration, source: str = "") -> str:
    """``cal.config`` as TOML with the intervals and the fit's summary as comments."""
    head = ["# thermoskin calibrate" + (f": skin parameters fitted to {source}" if source else "")]
    head += [f"# {line}" for line in summary_lines(cal)]
    if len(cal.names) > 1:
        head.append("# correlation of ln p: " + ", ".join(cal.names))
        head += ["#   " + " ".join(f"{x:+.2f}" for x in row) for row in cal.correlation]
    out: list[str] = []
    section = ""
    for line in to_toml(cal.config).splitlines():
        if line.startswith("["):
            section = line.strip("[]")
        key = line.split("=", 1)[0].strip() if "=" in line else ""
        if section == "skin" and key in cal.requested:
            lo, hi = cal.interval(key)
            note = (f"fitted, 95 % interval [{_g(lo)}, {_g(hi)}]" if key in cal.names
                    else "held: " + cal.held[key].split(":")[0])
            line = f"{line}; {note}"
        out.append(line)
    return "\n".join(head) + "\n\n" + "\n".join(out) + "\n"


def save(cal: Calibration, path: str | Path, source: str = "") -> Path:
    """Write :func:`to_toml_text` to ``path`` (a config ``load_config`` reads)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    write_text(p, to_toml_text(cal, source))  # whole or not at all
    return p
