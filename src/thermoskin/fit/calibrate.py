"""Fit the skin's network (Fig. 3, eqs. 3-7), ``R_w`` and the thermocouples' offsets and lags to a log.

**Model.** The two-node network of ``physics.network`` with no touch (``q_i = 0``)::

    C_w dT_w/dt = (T_p - T_w)/R_w(v) - (T_w - T_a)/R_aw - (T_w - T_g)/R_g
    C_g dT_g/dt = (T_w - T_g)/R_g - (T_g - T_a)/R_ag

``R_w(v) = R_w_flowing`` while the pump runs (``v > 0``), ``R_w_stopped`` while it is
stopped (config keys ``skin.R_w_flowing``, ``skin.R_w_stopped``; eq. 1 where neither is set).

**Sensors** (``[sensor]``, not in the paper). A reading is ``lag(T) + b`` plus noise: the
true temperature through a first-order lag of time constant ``lag_T_*`` (s), plus a constant
offset ``offset_T_*`` (K, reading minus truth). The network is driven by the true ``T_p`` and
``T_a``, the readings less their offsets, and the ``T_w`` it predicts is read through the pipe
sensor's lag plus its offset:

- *Offsets.* Only their differences reach the readings: the network's rows sum to zero
  (``A 1 + B 1 = 0``: every temperature shifted by ``c`` leaves every heat flow as it was), so
  ``b_w, b_p, b_a`` all shifted by ``c`` predict the same ``T_w``. One channel is the
  *reference* whose offset is held at its config value (``T_w`` by default, 0 unless set);
  the others are fitted relative to it. What makes them observable is the pump: at steady
  state ``T_w = g(v) T_p + (1 - g(v)) T_a`` with ``g`` near 1 while the water flows and near
  0.2 while it stands, so ``b_w - g b_p - (1 - g) b_a`` changes at every switch, a touch's
  heat does not. A log where the pump never switches leaves them undetermined (said so).
  The prediction is linear in the offsets: they are eliminated by linear least squares at
  every step of the fit (variable projection, with each stretch's start; below), so they
  cost one model run, not one per offset and iteration.
- *The pipe sensor's lag* ``lag_T_w``: a third state ``y`` with ``tau_w dy/dt = T_w - y``; the
  reading is ``y``. Exact, discretised with the network.
- *The air sensor's lag* ``lag_T_a``: the true air is ``T_a = y_a + tau_a dy_a/dt`` with
  ``y_a`` the (smoothed) reading. Its derivative is not needed: with ``z = x - tau_a B_a y_a``
  (``B_a`` the air's input column, the same whatever the pump does, so ``z`` is continuous
  at a switch) the network is ``dz/dt = A z + B_p T_p + (I + tau_a A) B_a y_a`` and
  ``T_w = z_w + tau_a B_a[0] y_a``: exact for the reading as the network's input.
- The tank sensor's lag is not modelled (its ``B_p`` changes with the pump: no such exact
  form); the tank is slow (its ARX time constants are tens of seconds).

**Output error.** The network is simulated from the log's inputs ``T_p, v, T_a`` alone
and compared with the measured ``T_w``; the measured ``T_w`` is never fed back. (A
one-step predictor would take the noisy ``T_w`` as its state and bias every parameter:
errors in the variables. The output error is unbiased for white sensor noise, at the
price of residuals that are correlated wherever the model is wrong; see *Intervals*.)
Rows where the ``T_w`` board made no new reading (a ``fresh`` column without bit 1: a
10 Hz board holds its reading for 100 samples) weigh nothing: a held reading is an old one.

**Blocks.** The log is cut into blocks of at most ``m = t_fit / t_s`` samples (10 ms by
default) that never straddle a pump switch. Over a block of ``n`` samples the inputs are
held at their block means and, with ``Phi, Gamma`` the exact ZOH discretisation at ``t_s``
of the model above (``physics.network.discretize``) and ``c`` the row that is read::

    x_{k+n} = Phi^n x_k + S_n u,               S_n = sum_{i<n} Phi^i Gamma
    mean_{i<n} c x_{k+i} = M_n x_k + N_n u,    M_n = (1/n) sum_{i<n} c Phi^i,
                                                N_n = (1/n) sum_{i<n} c S_i

exact for inputs constant over the block (:func:`model_tables`, by recursion; held to
Sylvester's closed form of the two-node network, :func:`block_tables`, in the tests).
Block ``j``'s residual is ``e_j = sqrt(n_j) (mean T_w - mean T_w_hat)``: with white sensor
noise of standard deviation ``sigma`` every ``e_j`` has variance ``sigma^2``, so each sample
weighs alike at the cost of one block instead of ``n`` samples. The pump switches on the
very reading of ``T_w`` it is fitted to (its logic runs on the measured ``T_w``): that
reading is a block of its own (a *point* block). In its block's mean (the block's mode
then depends on a reading inside it) it biased ``R_g`` and ``R_w_flowing`` by 2.2 standard
deviations on a chattering log; on its own, 10 ms blocks are as unbiased as single samples
(z means +0.4 against +0.6 over 16 seeds). A board that converts less often than the log
(a ``fresh`` column without bit 1) gives point blocks at its new readings only; the rows
holding a reading weigh nothing and carry the model on.

**Inputs.** A held ``T_p`` or ``T_a`` (a slow board) is taken as lines between its readings
(:func:`between_readings`): held for 100 ms, a ramping tank lagged by 15 mK and biased
``R_w_flowing`` by 6 %. ``T_a`` is smoothed over :data:`SMOOTH_T_A` (the air is slow).
``T_p``'s noise, fed into the network, biases the fit (errors in the variables), most where
the pump chatters and the log moves little else (at 0.1 K of noise ``R_w_flowing`` came out
at twice the truth); a mean over the tank's readings removes it and bends its ramps at
their kinks (0.2 s put ``R_g`` 2.3 sd off on a stepping log with 20 mK). So it is tested at
each optimum: four draws of as much noise again on the tank's input, and a Gauss-Newton
step from the optimum on each (its own Jacobian), say how far twice the noise would move
each parameter (:data:`EIV_DRAWS`); where one would move by more than half its sd (and
:data:`EIV_FLOOR`), the tank's readings are smoothed over the next of
:data:`SMOOTH_WIDTHS` and the fit made again. A parameter running to a bound tries a
smoother tank first.

**Stretches and their start.** Usable rows (finite readings, away from flagged contacts)
form stretches; each starts from its measured ``T_w`` (the mean of its first
:data:`N_START` samples), the sheet in equilibrium with it and the air,
``T_g = (T_w/R_g + T_a/R_ag) / (1/R_g + 1/R_ag)``, and the pipe sensor settled. The
prediction is linear in that start, so its correction ``d`` is eliminated by linear least
squares per stretch, with the offsets (variable projection): ``e = w (T_w - y_0) - d h -
sum_c b_c r_c``, ``h`` the response to a unit start, ``r_c`` to a unit offset of channel
``c``, solved per stretch for ``d`` and over the log for ``b`` (:func:`evaluate`).

**Fit.** ``scipy.optimize.least_squares`` (trust-region reflective) on ``theta = ln p``
for the skin (positivity) and ``ln(tau + t_s)`` for a lag (0 allowed), bounded to
``prior x/÷`` :data:`BOUND` within the config's own ranges (lags: 0 to :data:`LAG_MAX`).
A parameter that ends at a bound is a finding, not an estimate: it is held at its prior,
said so in the table, and the rest fitted again (a misfit, such as an offset or a lag left
out, drives a parameter there).

**Intervals.** At the optimum, with ``J`` the Jacobian of the residuals in ``theta`` and
the offsets (central differences) and ``H = J'J`` (:func:`covariance`)::

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
has its weight. 95 % intervals: ``exp(theta ± 1.96 sd)`` (offsets: ``b ± 1.96 sd``). The
inputs' noise also biases the fit (*Inputs*).

**What a log can determine.** Temperatures fix the network only up to a common scale of
heat: every ``C`` times ``k`` and every ``R`` over ``k`` leave every temperature as it
was. One heat-carrying parameter must be held; by default ``C_w``
(:data:`DEFAULT_PARAMS`), and the fitted values are relative to it. With a constant
ambient, ``R_aw`` trades exactly against ``R_g, R_ag, C_g`` (only ``1/R_aw + 1/R_g``,
``C_g/R_g^2`` and ``(1/R_g + 1/R_ag)/C_g`` reach ``T_w``). The sheet, ten times faster
than the pipe, is seen through ``T_w`` almost as a static divider: ``C_g`` and the split
of ``R_g + R_ag`` are barely determined. ``R_w_stopped`` needs the pump to stop for long
enough (chattering stops of 50 ms tell little), ``R_w_flowing`` to run. An air sensor's
lag needs the air to change (a door, a draught).

Those limits are found from the data, not assumed. Before the fit, a direction the fit does
not change along is held, and so is a skin parameter whose direction is known to worse than
``×/÷ exp(1.96 SD_MAX)`` (95 %) for the noise, linearised at the prior (provisionally: the
fit's residual may release it). After each fit, if the worst-known direction of the
covariance is known to worse than that (an offset: to worse than :data:`OFFSET_SD_MAX` K),
a parameter is held and the rest are fitted again: the one whose holding leaves the rest
known, a skin parameter before a lag before an offset (:func:`to_hold`). An offset held is
kept in the model at its least-squares value (held at 0, tenths of a kelvin off, it drove
the rest to their bounds). A fitted parameter's value then depends on what the held ones
were set to: :attr:`Calibration.dependence` gives those elasticities, ``d ln p_fit / d ln
p_held`` (the least-squares response to a held parameter's change); an offset whose value
a held parameter's prior :data:`SKIN_DOUBT` off would move by more than
:data:`OFFSET_DEP_TOL` is not determined (the air's on a chattering log trades with
``R_g``), kept in the model, not written.

**Touch logs.** A touch heats the sheet by an unknown, varying heat flow. Rows flagged in
a ``contact`` column are left out, with :data:`PAD_BEFORE` s before (the detector's
latency) and :data:`PAD_AFTER` s after (the recovery); each stretch between restarts
(above). Unknown piecewise-constant heat inputs per contact were not used: a finger is a
conductance to a body, so its heat falls through a contact; the detector's flags lag
the onset; and the touch heat reaching the pipe is scaled by the very ``R_g : R_ag``
split the log cannot determine, so such inputs would add unknowns without adding
information about the skin.

**Speed.** One model run over a 300 s log at 1 kHz (300 000 samples) is one compiled pass
computing the prediction and its responses to the start and the offsets. The start's
response decays to nothing within seconds; it is set to zero below 1e-30 rather than left
to underflow into subnormal numbers, on which every operation is a hundred times slower
(that alone took a 300 s calibration from about a minute to a few seconds).
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
from thermoskin.params import Config, SensorParams, SkinParams, to_toml
from thermoskin.physics.convection import R_w as R_w_model
from thermoskin.physics.network import discretize, state_space

Array = NDArray[np.float64]

SKIN_PARAMS: tuple[str, ...] = ("C_w", "C_g", "R_g", "R_aw", "R_ag", "R_w_flowing", "R_w_stopped")
"""The network's parameters (keys of ``[skin]``)."""
CHANNELS: tuple[str, ...] = ("T_w", "T_p", "T_a")
OFFSETS: tuple[str, ...] = ("offset_T_w", "offset_T_p", "offset_T_a")
"""The readings' offsets (keys of ``[sensor]``, K, reading minus truth)."""
LAGS: tuple[str, ...] = ("lag_T_w", "lag_T_a")
"""The sensors' lags :func:`calibrate` can fit (keys of ``[sensor]``, s)."""
PARAMS: tuple[str, ...] = (*SKIN_PARAMS, *OFFSETS, *LAGS)
"""Every parameter :func:`calibrate` can fit."""
REFERENCE = "T_w"
"""The channel whose offset is held by default (only differences of offsets are observable)."""
DEFAULT_PARAMS: tuple[str, ...] = (*SKIN_PARAMS[1:], "offset_T_p", "offset_T_a")
"""Fitted by default: the network but ``C_w``, which holds the heat scale (module doc), and the
offsets of ``T_p`` and ``T_a`` relative to ``T_w`` (:data:`REFERENCE`); lags where asked."""
UNITS = {"C_w": "J/K", "C_g": "J/K", "R_g": "K/W", "R_aw": "K/W", "R_ag": "K/W",
         "R_w_flowing": "K/W", "R_w_stopped": "K/W", "offset_T_w": "K", "offset_T_p": "K",
         "offset_T_a": "K", "lag_T_w": "s", "lag_T_a": "s"}
NETWORK = ("C_w", "C_g", "R_g", "R_aw", "R_ag")
COLUMNS = ("t", "T_w", "T_p", "v", "T_a")

T_FIT = 0.01
"""Longest block, s; 0: every sample its own (the default; see the module doc)."""
N_START = 5
"""Samples averaged for the measured ``T_w`` a stretch starts from."""
PAD_BEFORE = 0.5
"""Seconds left out before a flagged contact (the detector's latency)."""
PAD_AFTER = 1.0
"""Seconds left out after a flagged contact (the sheet's and the pipe's recovery)."""
SMOOTH_T_P: float | None = None
"""Width of the centred moving mean on ``T_p``, s; ``None``: the one of :data:`SMOOTH_WIDTHS`
that passes the test of errors in the variables (module doc, *Inputs*); 0: none."""
SMOOTH_WIDTHS: tuple[float, ...] = (0.0, 0.05, 0.2, 0.5, 1.0)
"""The widths of the mean on ``T_p`` the fit chooses from, s (the narrowest that passes)."""
EIV_DRAWS = 4
"""Draws of twice the tank's noise for the test of errors in the variables."""
EIV_FLOOR = {"skin": 0.01, "lag": 0.02, "offset": 0.005}
"""A shift below this (``ln p``; ``ln(tau + t_s)``; K) passes the test of errors in the variables
whatever the parameter's sd (a long log's sd shrinks below any bias that matters)."""
SMOOTH_T_A = 1.0
"""Width of the centred moving mean on ``T_a``, s."""
MIN_USABLE_S = 5.0
"""Fewest seconds of usable samples (finite, away from contacts)."""
MIN_STRETCH_S = 0.2
"""Shorter usable stretches are dropped."""
BOUND = 1000.0
"""Bounds of the fit: ``prior / BOUND <= p <= prior * BOUND`` (within the config's ranges)."""
LAG_MAX = 60.0
"""Largest lag the fit tries, s (and at most a fifth of the log)."""
AT_BOUND = 1e-3
"""A parameter within this of a bound (in ``theta``) ended there."""
SD_MAX = 0.2
"""A direction of ``ln p`` known to a standard deviation above this is not determined
(95 % interval wider than ×/÷ 1.5): weakly determined directions are the first a small
bias (the tank's noise, the pump deciding on the readings) throws off by several sd."""
OFFSET_SD_MAX = 0.05
"""An offset known to a standard deviation above this (K) is not determined (its share of a
weak direction is measured in units of ``OFFSET_SD_MAX / SD_MAX`` K)."""
SKIN_DOUBT = 0.3
"""How far a lab's prior of a skin parameter may be off (before calibrating: 15-30 %)."""
OFFSET_DEP_TOL = 0.02
"""K: an offset that held parameters' priors ``SKIN_DOUBT`` off would move by more is not
determined by the log (it rests on those priors): not written."""
OFFSET_LIMIT = 5.0
"""An offset found beyond ``± OFFSET_LIMIT`` K (the config's range) is a finding, not an estimate."""
NULL_RTOL = 1e-6
"""A direction whose singular value is below this fraction of the largest is not seen at all."""
DEP_FACTOR = 2.0
DEP_MIN = 0.001
"""A fitted parameter depends on a held one if the held one off by ×/÷ ``DEP_FACTOR`` would
move it by more than its standard deviation (and the elasticity is at least ``DEP_MIN``)."""
Z95 = 1.959963984540054
TRIM = 3.5
"""Differences beyond this many robust standard deviations are the signal's, not noise
(:func:`noise_of_differences`)."""
CHI2_95 = 3.841458820694124
"""95 % point of the chi-square distribution with one degree of freedom."""
N_DRAWS = 100
"""Monte Carlo draws of the tank sensor's noise for the covariance."""
N_DRAWS_CHECK = 20
"""... for the covariance that only decides whether a direction is determined."""
TINY = 1e-30
"""The start's response below this is zero (module doc, *Speed*)."""


class CalibrationError(ValueError):
    """The log or the request cannot be calibrated; the one-line message says why."""


def kind(name: str) -> str:
    """``skin``, ``offset`` or ``lag``."""
    return "offset" if name in OFFSETS else "lag" if name in LAGS else "skin"


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
    Ta0: Array              # (smoothed) T_a reading there
    smooth_T_p: float = 0.0  # width of the mean the tank's readings were smoothed by, s
    tank: dict[float, Array] = field(default_factory=dict)  # Tp under each width to choose from
    usable: NDArray[np.bool_] | None = None  # the log's rows the blocks cover
    point: NDArray[np.bool_] | None = None  # compared by the first reading, not the mean (None: no)
    seen: NDArray[np.bool_] | None = None  # the block starts with a fresh T_w reading (None: all do)

    @property
    def n_samples(self) -> int:
        return int(self.nlen.sum())

    @functools.cached_property
    def weight(self) -> Array:
        """``sqrt(n_j)`` (a point block: 1): every reading weighs alike; 0 where ``T_w`` held an
        old reading."""
        w = np.sqrt(self.nlen.astype(float))
        if self.point is not None:
            w[self.point] = 1.0
        return w if self.seen is None else np.where(self.seen, w, 0.0)

    @property
    def n_seen(self) -> int:
        """``T_w`` readings the fit weighs."""
        return int(np.sum(self.weight ** 2).round())

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


def fresh_rows(log: Mapping[str, ArrayLike], bit: int = 1) -> NDArray[np.bool_] | None:
    """Rows with a new reading of the channel of ``fresh`` bit ``bit`` (1 ``T_w``, 2 ``T_p``,
    4 ``T_a``); ``None`` if the log has no ``fresh`` column or every row is fresh."""
    if "fresh" not in log:
        return None
    f = np.nan_to_num(np.asarray(log["fresh"], dtype=float), nan=7.0).astype(np.int64)
    seen = (f & bit) != 0
    return None if seen.all() else seen


def between_readings(x: ArrayLike, fresh: NDArray[np.bool_]) -> Array:
    """A reading held between its board's conversions (``fresh``) as straight lines from one
    new reading to the next (held before the first and after the last; NaN readings left out).
    An input held for 100 ms lags a tank ramping at 0.3 K/s by 15 mK on average, which the
    network passes to ``T_w`` almost whole; a line between the readings is exact for a ramp."""
    xx = np.asarray(x, dtype=float)
    k = np.flatnonzero(fresh & np.isfinite(xx))
    if k.size == 0:
        return xx.copy()
    return np.interp(np.arange(xx.size, dtype=float), k.astype(float), xx[k])


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
                t_fit: float = T_FIT, smooth: tuple[float | None, float] = (SMOOTH_T_P, SMOOTH_T_A),
                fresh: NDArray[np.bool_] | None = None, isolate_switch: bool = True) -> Blocks:
    """Cut the usable rows into blocks of at most ``t_fit`` s that never straddle a pump switch.

    A block is compared with the model by its mean (a *mean* block) or is a single reading (a
    *point* block). Point blocks are: the first row after each pump switch (the reading the
    pump switched on, module doc), and, where ``fresh`` is given (rows with a new ``T_w``
    reading, :func:`fresh_rows`), each new reading; the rows that hold it (an old reading says
    nothing new) are blocks of at most ``t_fit`` s that weigh nothing and only carry the model on.
    ``isolate_switch=False`` leaves the switching reading in its block's mean (biased; tests).
    The inputs ``T_p`` and ``T_a`` are first smoothed by centred moving means of ``smooth`` s
    (``None``: 0; tank and air are slow; their sensor noise, fed into the model, would bias
    the fit), then held at their block means.
    """
    smooth = (smooth[0] or 0.0, smooth[1] or 0.0)
    v = np.asarray(log["v"], dtype=float)
    m = max(1, min(round(t_fit / t_s), len(v)))  # a block is at most the whole log
    v_modes = np.unique(v[usable])
    min_len = max(2, round(MIN_STRETCH_S / t_s))
    T_w = np.asarray(log["T_w"], dtype=float)
    runs = _runs(usable)
    inputs = {"T_w": T_w,
              "T_p": centred_mean(log["T_p"], runs, round(0.5 * smooth[0] / t_s)),
              "T_a": centred_mean(log["T_a"], runs, round(0.5 * smooth[1] / t_s))}
    firsts: list[int] = []
    lens: list[int] = []
    starts: list[bool] = []
    sids: list[int] = []
    points: list[bool] = []
    w0: list[float] = []
    Ta0: list[float] = []

    def add(s: int, n: int, sid: int, point: bool) -> None:
        starts.append(len(sids) == 0 or sids[-1] != sid)
        firsts.append(s)
        lens.append(n)
        sids.append(sid)
        points.append(point)

    for a, b in runs:
        if b - a < min_len:
            continue
        sid = len(w0)
        head = np.arange(a, b) if fresh is None else a + np.flatnonzero(fresh[a:b])
        w0.append(float(np.mean(T_w[head[:N_START]])) if head.size else float(T_w[a]))
        Ta0.append(float(inputs["T_a"][a]))
        edges = [a, *(a + 1 + np.flatnonzero(np.diff(v[a:b]) != 0)).tolist(), b]
        for c0, c1 in itertools.pairwise(edges):
            if fresh is not None:
                cuts = [c0, *(c0 + np.flatnonzero(fresh[c0:c1])).tolist(), c1]
                for x, y in itertools.pairwise(dict.fromkeys(cuts)):
                    add(x, 1, sid, True)  # the reading; then the rows it holds, in steps of m
                    for x1 in range(x + 1, y, m):
                        add(x1, min(m, y - x1), sid, False)
                continue
            s = c0
            if c0 > a and m > 1 and isolate_switch:  # the reading the pump switched on: its own block
                add(c0, 1, sid, True)
                s = c0 + 1
            for x in range(s, c1, m):
                add(x, min(m, c1 - x), sid, m == 1)
    first = np.asarray(firsts, dtype=np.int64)
    nlen = np.asarray(lens, dtype=np.int64)
    point = np.asarray(points, dtype=np.bool_)

    def means(name: str) -> Array:
        x = np.where(usable, inputs[name], 0.0)  # no NaN in the sums
        csum = np.concatenate([[0.0], np.cumsum(x)])
        return (csum[first + nlen] - csum[first]) / nlen if first.size else np.zeros(0)

    Tw = means("T_w")
    Tw[point] = T_w[first[point]]
    t = np.asarray(log["t"], dtype=float)
    return Blocks(t0=float(t[0]) if t.size else 0.0, t_s=t_s, m=int(nlen.max(initial=1)),
                  v_modes=v_modes, mode=np.searchsorted(v_modes, v[first]).astype(np.int64), nlen=nlen,
                  first=first, stretch=np.asarray(sids, dtype=np.int64), Tp=means("T_p"), Ta=means("T_a"),
                  Tw=Tw, start=np.asarray(starts, dtype=np.bool_), w0=np.asarray(w0), Ta0=np.asarray(Ta0),
                  smooth_T_p=smooth[0], point=point, seen=None if fresh is None else fresh[first])


def _block_means(x: Array, usable: NDArray[np.bool_], blocks: Blocks) -> Array:
    """Means of ``x`` over each block's rows."""
    csum = np.concatenate([[0.0], np.cumsum(np.where(usable, x, 0.0))])
    return (csum[blocks.first + blocks.nlen] - csum[blocks.first]) / blocks.nlen if blocks.first.size \
        else np.zeros(0)


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


ROW = 20
"""A table row: ``Phi^n`` (9), ``S_n`` (6), ``M_n`` (3), ``N_n`` (2, the air's with the feed-through)."""


def sensor_values(values: Mapping[str, float], cfg: Config) -> dict[str, float]:
    """The offsets and lags: from ``values`` where given, else ``cfg.sensor``."""
    return {k: float(values[k]) if k in values else float(getattr(cfg.sensor, k)) for k in (*OFFSETS, *LAGS)}


def model_matrices(skin: SkinParams, R_w: float, lag_w: float = 0.0,
                   lag_a: float = 0.0) -> tuple[Array, Array, Array, float]:
    """``(A, B, c, D)`` of the model of the readings (module doc, *Sensors*) for one pump state.

    State ``[z_w, z_g, y]`` (``z = [T_w, T_g] - lag_a B_a y_a``; ``y`` the pipe sensor's element),
    inputs ``[T_p, y_a]`` (true tank, air reading less its offset); the ``T_w`` reading less its
    offset is ``c x + D y_a``. Without a pipe lag (``lag_w = 0``) ``y`` is not read (``c`` picks
    ``z_w``) and decays on its own.
    """
    A, B = state_space(skin, R_w)
    Bp, Ba = B[:, 0], B[:, 1]
    A3 = np.zeros((3, 3))
    B3 = np.zeros((3, 2))
    A3[:2, :2] = A
    B3[:2, 0] = Bp
    B3[:2, 1] = Ba + lag_a * (A @ Ba)
    D = lag_a * float(Ba[0])
    if lag_w > 0.0:
        A3[2, 0] = 1.0 / lag_w
        A3[2, 2] = -1.0 / lag_w
        B3[2, 1] = D / lag_w
        return A3, B3, np.array([0.0, 0.0, 1.0]), 0.0
    A3[2, 2] = -1.0
    return A3, B3, np.array([1.0, 0.0, 0.0]), D


def model_tables(A: Array, B: Array, c: Array, D: float, t_s: float, m: int) -> Array:
    """``(m + 1, ROW)`` rows ``[Phi^n, S_n, M_n, N_n]`` for ``n = 0..m`` (module doc, *Blocks*;
    row 0 unused), by recursion from ``Phi, Gamma`` (``physics.network.discretize``); ``N_n``'s
    air term carries the feed-through ``D``."""
    Phi, Gam = discretize(A, B, t_s)
    out = np.zeros((m + 1, ROW))
    P = np.eye(3)
    S = np.zeros((3, 2))
    Msum = np.zeros(3)
    Nsum = np.zeros(2)
    for n in range(1, m + 1):
        Msum += c @ P
        Nsum += c @ S
        P = Phi @ P
        S = Phi @ S + Gam
        out[n, 0:9] = P.ravel()
        out[n, 9:15] = S.ravel()
        out[n, 15:18] = Msum / n
        out[n, 18:20] = Nsum / n
        out[n, 19] += D
    return out


@njit(cache=True)
def _model(tab, idx, oidx, Tp, Ta, Tw, w, start, stretch, X0, bp, ba, bw, lag, do_p, do_a,
           E0, H, RP, RA, hh, he, hr, rr, re):  # pragma: no cover - compiled
    """One pass of the model over the blocks (module doc, *Stretches*, *Speed*).

    Four runs side by side from their starts ``X0[c, s]`` at stretch ``s``: the prediction
    (inputs ``Tp - bp, Ta - ba``; the reading less ``bw``), the response to a unit start, and
    to a unit offset of ``T_p`` and of ``T_a`` (inputs -1; only if ``do_p``, ``do_a``). Block
    ``j`` steps the state by row ``tab[idx[j]]`` and is read by row ``tab[oidx[j]]`` (its own:
    the block's mean; row 1: its first sample). Writes the weighted ``E0 = w (Tw - bw -
    prediction)``, ``H``, ``RP``, ``RA`` and accumulates, per stretch, ``h'h, h'e, h'r`` and over
    the log ``r'r, r'e`` for the offset columns ``r = (w, RP, RA)``. ``lag``: the third state
    (the pipe sensor) is read; otherwise it is not run. The start's response is set to zero
    once below :data:`TINY` (no subnormal numbers).
    """
    x0 = x1 = x2 = 0.0
    h0 = h1 = h2 = 0.0
    p0 = p1 = p2 = 0.0
    a0 = a1 = a2 = 0.0
    live = False
    s = -1
    for j in range(idx.shape[0]):
        if start[j]:
            s += 1
            x0, x1, x2 = X0[0, s, 0], X0[0, s, 1], X0[0, s, 2]
            h0, h1, h2 = X0[1, s, 0], X0[1, s, 1], X0[1, s, 2]
            p0, p1, p2 = X0[2, s, 0], X0[2, s, 1], X0[2, s, 2]
            a0, a1, a2 = X0[3, s, 0], X0[3, s, 1], X0[3, s, 2]
            live = True
        r = tab[idx[j]]
        o = tab[oidx[j]]
        u = Tp[j] - bp
        v = Ta[j] - ba
        wj = w[j]
        y = o[15] * x0 + o[16] * x1 + o[17] * x2 + o[18] * u + o[19] * v
        n0 = r[0] * x0 + r[1] * x1 + r[2] * x2 + r[9] * u + r[10] * v
        n1 = r[3] * x0 + r[4] * x1 + r[5] * x2 + r[11] * u + r[12] * v
        if lag:
            x2 = r[6] * x0 + r[7] * x1 + r[8] * x2 + r[13] * u + r[14] * v
        x0 = n0
        x1 = n1
        e = wj * (Tw[j] - bw - y)
        E0[j] = e
        hw = 0.0
        if live:
            hw = wj * (o[15] * h0 + o[16] * h1 + o[17] * h2)
            n0 = r[0] * h0 + r[1] * h1 + r[2] * h2
            n1 = r[3] * h0 + r[4] * h1 + r[5] * h2
            if lag:
                h2 = r[6] * h0 + r[7] * h1 + r[8] * h2
            h0 = n0
            h1 = n1
            if abs(h0) + abs(h1) + abs(h2) < TINY:
                h0 = h1 = h2 = 0.0
                live = False
        H[j] = hw
        hh[s] += hw * hw
        he[s] += hw * e
        rp = 0.0
        ra = 0.0
        if do_p:
            rp = wj * (o[15] * p0 + o[16] * p1 + o[17] * p2 - o[18])
            n0 = r[0] * p0 + r[1] * p1 + r[2] * p2 - r[9]
            n1 = r[3] * p0 + r[4] * p1 + r[5] * p2 - r[11]
            if lag:
                p2 = r[6] * p0 + r[7] * p1 + r[8] * p2 - r[13]
            p0 = n0
            p1 = n1
            RP[j] = rp
        if do_a:
            ra = wj * (o[15] * a0 + o[16] * a1 + o[17] * a2 - o[19])
            n0 = r[0] * a0 + r[1] * a1 + r[2] * a2 - r[10]
            n1 = r[3] * a0 + r[4] * a1 + r[5] * a2 - r[12]
            if lag:
                a2 = r[6] * a0 + r[7] * a1 + r[8] * a2 - r[14]
            a0 = n0
            a1 = n1
            RA[j] = ra
        hr[s, 0] += hw * wj
        hr[s, 1] += hw * rp
        hr[s, 2] += hw * ra
        re[0] += wj * e
        re[1] += rp * e
        re[2] += ra * e
        rr[0, 0] += wj * wj
        rr[1, 0] += rp * wj
        rr[1, 1] += rp * rp
        rr[2, 0] += ra * wj
        rr[2, 1] += ra * rp
        rr[2, 2] += ra * ra


@njit(cache=True)
def _final(E0, H, RP, RA, w, beta, d, stretch, e):  # pragma: no cover - compiled
    """``e = E0 - d[stretch] H - beta_0 w - beta_1 RP - beta_2 RA`` (:func:`_model`'s columns;
    ``RP``, ``RA`` only where their ``beta`` is not 0)."""
    bw, bp, ba = beta[0], beta[1], beta[2]
    for j in range(E0.shape[0]):
        v = E0[j] - d[stretch[j]] * H[j] - bw * w[j]
        if bp != 0.0:
            v -= bp * RP[j]
        if ba != 0.0:
            v -= ba * RA[j]
        e[j] = v


@njit(cache=True)
def _smoothed_means(x, h, first, nlen, out):  # pragma: no cover - compiled
    """Block means (``first``, ``nlen``) of ``x`` smoothed by a centred moving mean over ``2 h + 1``
    rows (fewer at the ends of ``x``)."""
    n = x.shape[0]
    cs = np.empty(n + 1)
    cs[0] = 0.0
    for i in range(n):
        cs[i + 1] = cs[i] + x[i]
    for j in range(first.shape[0]):
        acc = 0.0
        for i in range(first[j], first[j] + nlen[j]):
            lo = max(i - h, 0)
            hi = min(i + h + 1, n)
            acc += (cs[hi] - cs[lo]) / (hi - lo)
        out[j] = acc / nlen[j]


@dataclass(frozen=True)
class Evaluation:
    """One run of the model (:func:`evaluate`): weighted residuals ``e``, the offsets solved for,
    each stretch's start correction ``d``, and (if asked) the prediction of the ``T_w`` reading
    (block means, K)."""

    e: Array
    offsets: dict[str, float]
    d: Array
    fitted: Array | None = None


def evaluate(blocks: Blocks, values: Mapping[str, float], cfg: Config,
             solve: Sequence[str] = (), fitted: bool = False) -> Evaluation:
    """The model with ``values`` (others from ``cfg``), the offsets in ``solve`` and each
    stretch's start found by linear least squares (module doc, *Stretches*)."""
    skin = dataclasses.replace(cfg.skin, **{k: values[k] for k in NETWORK if k in values})
    sens = sensor_values(values, cfg)
    lag_w, lag_a = sens["lag_T_w"], sens["lag_T_a"]
    b_w, b_p, b_a = (0.0 if f"offset_{ch}" in solve else sens[f"offset_{ch}"] for ch in CHANNELS)
    m1 = blocks.m + 1
    tabs = np.empty((blocks.v_modes.size * m1, ROW))
    for i, v in enumerate(blocks.v_modes.tolist()):
        key = "R_w_flowing" if v > 0 else "R_w_stopped"
        R_w = values[key] if key in values else R_w_model(v, skin)
        A3, B3, c, D = model_matrices(skin, R_w, lag_w, lag_a)
        tabs[i * m1:(i + 1) * m1] = model_tables(A3, B3, c, D, blocks.t_s, blocks.m)
    Ba = state_space(skin, 1.0)[1][:, 1]
    kg = (1.0 / skin.R_g) / (1.0 / skin.R_g + 1.0 / skin.R_ag)
    nS = blocks.w0.size
    X0 = np.zeros((4, nS, 3))
    w_true = blocks.w0 - b_w
    a_true = blocks.Ta0 - b_a
    X0[0, :, 0] = w_true - lag_a * Ba[0] * a_true
    X0[0, :, 1] = kg * w_true + (1.0 - kg) * a_true - lag_a * Ba[1] * a_true
    X0[0, :, 2] = w_true
    X0[1, :, :] = (1.0, kg, 1.0)
    X0[3, :, 0] = lag_a * Ba[0]
    X0[3, :, 1] = -(1.0 - kg) + lag_a * Ba[1]
    if lag_w == 0.0:
        X0[:, :, 2] = 0.0  # not run (and the start's response must decay to zero)
    use = [f"offset_{ch}" in solve for ch in CHANNELS]
    n = blocks.mode.size
    E0, H = np.empty(n), np.empty(n)
    RP, RA = np.empty(n if use[1] else 0), np.empty(n if use[2] else 0)
    hh, he, hr = np.zeros(nS), np.zeros(nS), np.zeros((nS, 3))
    rr, re = np.zeros((3, 3)), np.zeros(3)
    w = blocks.weight
    idx = blocks.mode * m1 + blocks.nlen
    oidx = np.where(blocks.point, blocks.mode * m1 + 1, idx) if blocks.point is not None else idx
    _model(tabs, idx, oidx, blocks.Tp, blocks.Ta, blocks.Tw, w, blocks.start, blocks.stretch, X0,
           b_p, b_a, b_w, lag_w > 0.0, use[1], use[2], E0, H, RP, RA, hh, he, hr, rr, re)
    rr = np.tril(rr) + np.tril(rr, -1).T
    ok = hh > 0.0
    inv = np.where(ok, 1.0 / np.where(ok, hh, 1.0), 0.0)
    k = np.flatnonzero(use)
    beta = np.zeros(3)
    if k.size:
        hk = hr[:, k]
        G = rr[np.ix_(k, k)] - (hk.T * inv) @ hk
        g = re[k] - (hk.T * inv) @ he
        beta[k] = np.linalg.lstsq(G, g, rcond=1e-12)[0]
    d = (he - hr @ beta) * inv
    e = np.empty(n)
    _final(E0, H, RP, RA, w, beta, d, blocks.stretch, e)
    found = {f"offset_{CHANNELS[i]}": float(beta[i]) for i in k.tolist()}
    pred = None
    if fitted:  # the prediction, where the weight is 0 too: the same pass with unit weights
        one = np.ones(n)
        E1, H1 = np.empty(n), np.empty(n)
        RP1, RA1 = np.empty(RP.size), np.empty(RA.size)
        _model(tabs, idx, oidx, blocks.Tp, blocks.Ta, np.zeros(n), one, blocks.start, blocks.stretch, X0,
               b_p, b_a, 0.0, lag_w > 0.0, use[1], use[2], E1, H1, RP1, RA1, np.zeros(nS), np.zeros(nS),
               np.zeros((nS, 3)), np.zeros((3, 3)), np.zeros(3))
        pred = -E1 + b_w + beta[0] + d[blocks.stretch] * H1  # E1 = 0 - prediction
        if use[1]:
            pred += beta[1] * RP1
        if use[2]:
            pred += beta[2] * RA1
    return Evaluation(e=e, offsets=found, d=d, fitted=pred)


def residuals(blocks: Blocks, values: Mapping[str, float], cfg: Config, solve: Sequence[str] = ()) -> Array:
    """Weighted block residuals ``e_j`` with each stretch's start (and the offsets in ``solve``)
    projected out (:func:`evaluate`)."""
    return evaluate(blocks, values, cfg, solve).e


def prior_values(cfg: Config, v_on: float | None = None) -> dict[str, float]:
    """Every parameter of :data:`PARAMS` as ``cfg`` has it (``R_w`` by eq. 1 where not set).

    ``v_on``: the velocity of the flowing ``R_w``, m/s (default ``cfg.pump.v_on``).
    """
    vals = {k: float(getattr(cfg.skin, k)) for k in NETWORK}
    vals["R_w_flowing"] = float(R_w_model(cfg.pump.v_on if v_on is None else v_on, cfg.skin))
    vals["R_w_stopped"] = float(R_w_model(0.0, cfg.skin))
    vals.update(sensor_values({}, cfg))
    return vals


def config_range(name: str) -> tuple[float, float]:
    """The range the config allows for ``name`` (``params``' metadata)."""
    cls = SensorParams if name in (*OFFSETS, *LAGS) else SkinParams
    meta = next(f.metadata for f in dataclasses.fields(cls) if f.name == name)
    return float(meta["lo"]), float(meta["hi"])


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


def quantum_of(x: ArrayLike, rtol: float = 0.02, share: float = 0.99) -> float:
    """The converter's step: the greatest ``q`` of which the steps between the distinct readings
    are whole multiples (within ``rtol`` of ``q``, for ``share`` of them); 0 where the readings
    show none (as many distinct values as readings, or steps of no common measure).

    The smallest step between distinct readings is the candidate (a converter's readings
    fill every level their noise reaches), refined as the sum of the steps over the sum of
    their multiples."""
    xx = np.asarray(x, dtype=float)
    xx = xx[np.isfinite(xx)]
    u = np.unique(xx)
    if u.size < 3 or u.size > 0.5 * xx.size:
        return 0.0
    d = np.diff(u)
    scale = max(1.0, float(np.max(np.abs(u))))
    d = d[d > 1e-9 * scale]
    if d.size == 0:
        return 0.0
    q0 = float(np.min(d))
    n = np.round(d / q0)
    if np.mean(np.abs(d / q0 - n) <= rtol) < share:
        return 0.0
    return float(np.sum(d) / np.sum(n))


def input_noise(x: Array, blocks: Blocks, fresh: NDArray[np.bool_] | None = None) -> float:
    """Standard deviation of an input's sensor noise from its first differences in the stretches.

    ``sd(diff x) / sqrt(2)`` over consecutive rows (``fresh``: consecutive new readings) of
    each stretch, differences beyond six
    robust standard deviations (``1.4826 MAD``) left out: the tank's temperature moves by far
    less than its noise in one sample, so the differences are noise. (The MAD alone reads
    low on quantised readings: 16 mK for 20 mK of noise in 1/128 K steps.)
    """
    xx = np.asarray(x, dtype=float)
    last = blocks.first + blocks.nlen  # one past each block's last row
    ends = np.flatnonzero(np.r_[blocks.start[1:], True])  # last block of each stretch
    begins = np.flatnonzero(blocks.start)
    parts = []
    for i, j in zip(begins, ends, strict=True):
        seg = xx[blocks.first[i]:last[j]]
        parts.append(np.diff(seg if fresh is None else seg[fresh[blocks.first[i]:last[j]]]))
    d = np.concatenate(parts or [np.zeros(0)])
    if d.size < 10:
        return 0.0
    s0 = 1.4826 * float(np.median(np.abs(d - np.median(d))))
    if s0 > 0.0:
        d = d[np.abs(d - np.median(d)) <= 6.0 * s0]
    return float(np.std(d) / math.sqrt(2.0))


def covariance(blocks: Blocks, values: Mapping[str, float], cfg: Config, J: Array, e: Array,
               svd: tuple[Array, Array], sigma_p: float, draws: int = N_DRAWS, seed: int = 0,
               tank_noise: Callable[[np.random.Generator], Array] | None = None
               ) -> tuple[Array, float, float]:
    """Covariance of ``ln p`` at the optimum, the residuals' ``tau`` and the colour factor.

    The residual is ``e = w - G n_p + (model error)``: white sensor noise on ``T_w`` (variance
    ``s_w^2`` per sample) and the tank sensor's noise ``n_p`` (``sigma_p``, white, ``sigma_p^2 / n_j``
    on a block mean) filtered by the network. With ``H = J'J``::

        Cov = f H^-1 (s_w^2 H + E[J' G n_p n_p' G' J]) H^-1

    the expectation by ``draws`` Monte Carlo draws of ``n_p`` through the model (it is linear
    in its inputs), ``s_w^2 = s^2 - mean (G n_p)^2``. ``f = max(1, tau / tau_model)`` inflates
    for colour the noise model does not explain (model error): ``tau`` of the residuals over
    ``tau`` of a residual drawn from the noise model (:func:`autocorrelation_time`).
    ``tank_noise(rng)``: one draw of ``n_p`` on the blocks (default: white, ``sigma_p`` per
    sample; the fit gives it the readings' own timing and smoothing).
    """
    S, Vt = svd
    H_inv = (Vt.T / S**2) @ Vt
    n, p = J.shape
    seen = blocks.weight > 0.0  # rows with a fresh T_w reading: the others' residuals are 0
    n_seen = int(seen.sum())
    s2 = float(e @ e) / max(n_seen - p, 1)
    rng = np.random.default_rng(seed)
    e0 = residuals(blocks, values, cfg)
    C_p = np.zeros((p, p))
    var_p = 0.0
    e_p = np.zeros(n)
    if sigma_p > 0.0:
        sd_block = sigma_p / np.sqrt(blocks.nlen.astype(float))
        for _ in range(draws):
            n_p = sd_block * rng.standard_normal(n) if tank_noise is None else tank_noise(rng)
            b = dataclasses.replace(blocks, Tp=blocks.Tp + n_p)
            e_p = residuals(b, values, cfg) - e0
            g = J.T @ e_p
            C_p += np.outer(g, g) / draws
            var_p += float(e_p @ e_p) / (n_seen * draws)
    s2_w = max(s2 - var_p, 0.0)
    tau = autocorrelation_time(e[seen])
    tau_model = autocorrelation_time(math.sqrt(s2_w) * rng.standard_normal(n_seen) + e_p[seen])
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


def to_hold(names: Sequence[str], C: Array) -> str:
    """Which parameter to hold when the worst-known direction of the covariance ``C`` (the fit's
    vector: ``theta``, offsets in units of ``OFFSET_SD_MAX / SD_MAX`` K) is known to worse than
    ``SD_MAX``: of those whose holding leaves the rest known to ``SD_MAX`` (the conditional
    covariance given it), a skin parameter before a lag before an offset, then the one leaving
    the rest best known; if none does, the one leaving the rest best known. An offset's prior,
    0, is typically tenths of a kelvin off, a skin's tens of percent: held wrong, an offset
    drove the rest to their bounds on a noisy log, and held at its fitted value it let the skin
    it traded with look determined."""
    rank = {"skin": 0, "lag": 1, "offset": 2}
    worst: list[tuple[float, str]] = []
    for i, p in enumerate(names):
        keep = [k for k in range(len(names)) if k != i]
        if not keep:
            return p
        Cc = C[np.ix_(keep, keep)] - np.outer(C[keep, i], C[i, keep]) / max(C[i, i], 1e-300)
        worst.append((math.sqrt(max(float(np.linalg.eigvalsh(Cc)[-1]), 0.0)), p))
    fixes = [(sd, p) for sd, p in worst if sd <= SD_MAX]
    if fixes:
        return min(fixes, key=lambda t: (rank[kind(t[1])], t[0]))[1]
    return min(worst, key=lambda t: (t[0], rank[kind(t[1])]))[1]


def weak_text(names: Sequence[str], v: Array, sd: float) -> str:
    """How well a weak direction ``v`` (of the fit's vector: ``theta``, offsets in units of
    ``OFFSET_SD_MAX / SD_MAX`` K) is known: ``0.99 ln C_g - 0.1 ln R_ag is known only to ×/÷ 3.2``."""
    if all(kind(p) == "offset" for p, x in zip(names, v, strict=True) if abs(x) >= 0.05):
        return f"{combination(names, v)} is known only to ±{Z95 * sd * OFFSET_SD_MAX / SD_MAX:.3g} K (95 %)"
    return f"{combination(names, v)} is known only to ×/÷ {math.exp(min(Z95 * sd, 700.0)):.3g} (95 %)"


def noise_of_differences(d: ArrayLike, order: int) -> float:
    """``sd`` of white noise from its differences ``d`` of ``order`` (1-3): ``sd(d) / sqrt(C(2k, k))``,
    those beyond :data:`TRIM` robust standard deviations (``1.4826 MAD``) left out (the signal's
    own moves). NaN with fewer than 10 differences."""
    dd = np.asarray(d, dtype=float)
    dd = dd[np.isfinite(dd)]
    if dd.size < 10:
        return math.nan
    s0 = 1.4826 * float(np.median(np.abs(dd - np.median(dd))))
    if s0 > 0.0:
        dd = dd[np.abs(dd - np.median(dd)) <= TRIM * s0]
    return float(np.std(dd) / math.sqrt(math.comb(2 * order, order)))


def reading_noise(x: ArrayLike, blocks: Blocks | None = None,
                  fresh: NDArray[np.bool_] | None = None) -> float:
    """Standard deviation of a reading's noise, model-free: the least of
    :func:`noise_of_differences` of orders 1, 2 and 3 over consecutive (``fresh``: new) readings
    of each stretch (of ``blocks``; else the whole of ``x``). Each order reads high where the
    signal moves between readings in a way it does not cancel (a ramp for the first, the
    pipe's zigzag under a pump switching at every 10 Hz reading for the second), so the least
    is the nearest; on white noise all three agree (tests). 0 if there are too few readings."""
    xx = np.asarray(x, dtype=float)
    if blocks is None:
        spans = [(0, xx.size)]
    else:
        last = blocks.first + blocks.nlen
        ends = np.flatnonzero(np.r_[blocks.start[1:], True])
        spans = [(int(blocks.first[i]), int(last[j]))
                 for i, j in zip(np.flatnonzero(blocks.start), ends, strict=True)]
    segs = [xx[a:b] if fresh is None else xx[a:b][fresh[a:b]] for a, b in spans]
    sds = [noise_of_differences(np.concatenate([np.diff(sg, k) for sg in segs if sg.size > k] or [[]]), k)
           for k in (1, 2, 3)]
    sds = [x for x in sds if math.isfinite(x)]
    return min(sds) if sds else 0.0


def combination(names: Sequence[str], v: Array, keep: float = 0.05) -> str:
    """A direction of the fit's vector as text, largest terms first: ``0.82 ln C_g - 0.56 ln R_ag``
    (a lag: ``ln(lag_T_w + t_s)``; an offset: ``offset_T_a / 0.25 K``, its unit in the vector)."""
    order = np.argsort(-np.abs(v))
    terms = [(float(v[i]), names[i]) for i in order if abs(v[i]) >= keep]
    if terms and terms[0][0] < 0:
        terms = [(-c, n) for c, n in terms]
    text = ""
    for c, n in terms:
        what = {"skin": f" ln {n}", "lag": f" ln({n} + t_s)",
                "offset": f" {n}/{OFFSET_SD_MAX / SD_MAX:g} K"}[kind(n)]
        text += (f"{c:.2f}" if not text else (f" + {c:.2f}" if c >= 0 else f" - {-c:.2f}")) + what
    return text


# ---------------------------------------------------------------------------- result
@dataclass(frozen=True)
class Calibration:
    """What :func:`calibrate` found.

    ``estimate``, ``low``, ``high`` (95 %) hold every requested parameter; ``sd_log`` the
    standard deviation of ``ln p`` (a skin parameter), of ``ln(tau + t_s)`` (a lag) or of the
    offset itself (K). Those in ``held`` (name -> why) kept their prior (a lag that ran to
    zero: zero): ``estimate`` is that value and ``low, high`` the interval of the last fit that
    still freed them (NaN if none did). ``covariance`` and ``correlation`` are over ``names``
    (the final fit's parameters; ``theta`` for the skin and lags, K for offsets), ``tau``
    included. ``dependence[p][q]`` is ``d ln p / d ln q`` of a fitted ``p`` on a held ``q``
    where it matters (:data:`DEP_FACTOR`). ``reference``: the channel whose offset was held
    (only differences are observable). ``rms``: block residual (measured minus fitted block
    means), K; ``sigma``: the per-sample noise the residuals imply, K.
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
    reference: str = REFERENCE
    written: tuple[str, ...] = ()

    @property
    def config(self) -> Config:
        """``prior`` with the fitted values (and a lag found to be zero); held parameters as
        they were."""
        vals = {k: self.estimate[k] for k in self.written}
        return self.prior.replace(skin={k: v for k, v in vals.items() if kind(k) == "skin"},
                                  sensor={k: v for k, v in vals.items() if kind(k) != "skin"})

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
            if why.startswith("no lag"):
                return "no lag seen: 0"
            if ("bound" in why or "beyond" in why) and not why.startswith("not determined"):
                return "at a bound: " + why.split(":")[0]
            return ("held: pump never " + ("stops" if "stops" in why else "runs") if "pump" in why
                    else "held: not determined")
        dep = self.dependence.get(name, {})
        return "fitted given " + ", ".join(dep) if dep else "fitted"

    @property
    def findings(self) -> dict[str, str]:
        """Parameters that ran to a bound (the model does not fit there), with why."""
        return {p: why for p, why in self.held.items() if ("bound" in why or "beyond" in why)
                and not why.startswith("no lag")}


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


def prepare(log: Mapping[str, ArrayLike], *, t_fit: float = T_FIT, contact: ArrayLike | None = None,
            pad: tuple[float, float] = (PAD_BEFORE, PAD_AFTER),
            smooth: tuple[float | None, float] = (SMOOTH_T_P, SMOOTH_T_A)) -> tuple[dict[str, Array], Blocks]:
    """The log's columns and its blocks (one-line :class:`CalibrationError` for a bad log)."""
    if not (math.isfinite(t_fit) and t_fit >= 0):
        raise CalibrationError(f"t_fit = {t_fit} s must be >= 0")
    cols, t_s = _check_log(log)
    if contact is None and "contact" in log:
        contact = log["contact"]
    if contact is not None and np.size(contact) != cols["t"].size:
        raise CalibrationError(f"the contact column has {np.size(contact)} rows, t has {cols['t'].size}")
    fresh = fresh_rows(log, 1)
    for ch, bit in (("T_p", 2), ("T_a", 4)):  # an input held between conversions: lines between them
        seen = fresh_rows(log, bit)
        if seen is not None:
            cols[ch] = between_readings(cols[ch], seen)
    usable = usable_rows(cols, t_s, contact, pad)
    widths = SMOOTH_WIDTHS if smooth[0] is None else (smooth[0],)
    blocks = make_blocks(cols, t_s, usable, t_fit, (widths[0], smooth[1]), fresh)
    runs = _runs(usable)
    tp = {w: _block_means(centred_mean(cols["T_p"], runs, round(0.5 * w / t_s)), usable, blocks)
          for w in widths}
    blocks = dataclasses.replace(blocks, tank=tp, usable=usable)
    usable_s = blocks.n_samples * t_s
    if usable_s < MIN_USABLE_S:
        raise CalibrationError(f"too short: {usable_s:.2f} s of usable samples (finite, away from "
                               f"contacts, in stretches of {MIN_STRETCH_S:g} s or more); calibration "
                               f"needs {MIN_USABLE_S:g} s")
    if blocks.n_seen < 10:
        raise CalibrationError(f"only {blocks.n_seen} fresh T_w readings in the usable rows")
    return cols, blocks


def calibrate(log: Mapping[str, ArrayLike], cfg: Config, params: Sequence[str] = DEFAULT_PARAMS, *,
              t_fit: float = T_FIT, contact: ArrayLike | None = None,
              pad: tuple[float, float] = (PAD_BEFORE, PAD_AFTER),
              smooth: tuple[float | None, float] = (SMOOTH_T_P, SMOOTH_T_A), reference: str = REFERENCE,
              progress: Callable[[int, float], None] | None = None) -> Calibration:
    """Fit ``params`` (of :data:`PARAMS`) to the log (module doc).

    ``log``: ``{column: array}`` with ``t, T_w, T_p, v, T_a`` (``logio.read_log``), uniformly
    sampled; a ``fresh`` column, if any, says which ``T_w`` rows hold a new reading. ``contact``:
    rows to leave out, padded by ``pad`` s (default: the log's ``contact`` column, if any).
    ``reference``: the channel whose offset is held (its ``offset_T_*`` may not be in
    ``params``; with :data:`DEFAULT_PARAMS` the other two offsets are fitted relative to it).
    ``progress(nfev, rms)`` after every model run (rms of the weighted residuals, K). Raises
    :class:`CalibrationError` for a log or request that cannot be calibrated.
    """
    from threadpoolctl import threadpool_limits

    # the linear algebra here is on tall, thin matrices: threads only contend (10x slower when busy)
    with threadpool_limits(limits=1, user_api="blas"):
        return _calibrate(log, cfg, params, t_fit=t_fit, contact=contact, pad=pad, smooth=smooth,
                          reference=reference, progress=progress)


def default_params(reference: str = REFERENCE) -> tuple[str, ...]:
    """:data:`DEFAULT_PARAMS` with the offsets of the channels other than ``reference``."""
    return (*SKIN_PARAMS[1:], *(f"offset_{ch}" for ch in CHANNELS if ch != reference))


def _requested(params: Sequence[str], reference: str) -> tuple[str, ...]:
    unknown = [p for p in params if p not in PARAMS]
    if unknown:
        raise CalibrationError(f"unknown parameter(s) {', '.join(unknown)} (known: {', '.join(PARAMS)})")
    if reference not in CHANNELS:
        raise CalibrationError(f"reference {reference!r} is not a channel (one of {', '.join(CHANNELS)})")
    requested = tuple(dict.fromkeys(params))
    if not requested:
        raise CalibrationError("no parameter to fit")
    if f"offset_{reference}" in requested:
        raise CalibrationError(
            f"offset_{reference} cannot be fitted: {reference} is the reference (only differences "
            "between the channels' offsets reach the readings); choose another reference")
    return requested


def _calibrate(log: Mapping[str, ArrayLike], cfg: Config, params: Sequence[str], *, t_fit: float,
               contact: ArrayLike | None, pad: tuple[float, float], smooth: tuple[float | None, float],
               reference: str, progress: Callable[[int, float], None] | None) -> Calibration:
    t_start = time.perf_counter()
    requested = _requested(params, reference)
    cols, blocks = prepare(log, t_fit=t_fit, contact=contact, pad=pad, smooth=smooth)
    t_s = blocks.t_s
    duration = float(cols["t"][-1] - cols["t"][0] + t_s)
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

    # theta: ln p (skin), ln(tau + t_s) (lags); offsets in units of OFF_UNIT K in the full vector
    off_unit = OFFSET_SD_MAX / SD_MAX

    def to_theta(p: str, x: float) -> float:
        return math.log(x + t_s) if kind(p) == "lag" else math.log(x)

    def from_theta(p: str, th: float) -> float:
        th = min(th, 700.0)  # beyond: a factor above 1e300, as good as none
        return max(math.exp(th) - t_s, 0.0) if kind(p) == "lag" else math.exp(th)

    def bounds(p: str) -> tuple[float, float]:
        lo, hi = config_range(p)
        if kind(p) == "lag":
            return math.log(t_s), math.log(min(LAG_MAX, duration / 5.0, hi) + t_s)
        x = prior[p]
        return (max(math.log(x / BOUND), math.log(lo) + 1e-9),
                min(math.log(x * BOUND), math.log(hi) - 1e-9))

    nfev = 0

    def values_of(names: Sequence[str], phi: Array) -> dict[str, float]:
        out: dict[str, float] = {}
        for p, x in zip(names, phi.tolist(), strict=True):
            out[p] = x * off_unit if kind(p) == "offset" else from_theta(p, x)
        return out

    kept: dict[str, float] = {}

    def fixed() -> dict[str, float]:
        """Held values the config does not have: a lag found to be zero, an undetermined offset
        kept in the model at its least-squares value (``kept``)."""
        return {**{q: estimate[q] for q in held if kind(q) == "lag"}, **kept}

    def fun_vp(names: Sequence[str], solve: Sequence[str]) -> Callable[[Array], Array]:
        base = fixed()

        def fun(theta: Array) -> Array:
            nonlocal nfev
            e = residuals(blocks, {**base, **values_of(names, theta)}, cfg, solve)
            nfev += 1
            if progress is not None:
                progress(nfev, float(np.sqrt(np.mean(e * e))))
            return e

        return fun

    def fun_full(names: Sequence[str], base: Mapping[str, float] | None = None) -> Callable[[Array], Array]:
        def fun(phi: Array) -> Array:
            nonlocal nfev
            nfev += 1
            return residuals(blocks, {**(base or {}), **values_of(names, phi)}, cfg)

        return fun

    def phi_of(names: Sequence[str], vals: Mapping[str, float]) -> Array:
        return np.array([vals[p] / off_unit if kind(p) == "offset" else to_theta(p, vals[p]) for p in names])

    from scipy.optimize import least_squares

    estimate = dict(prior)
    low = dict.fromkeys(requested, math.nan)
    high = dict.fromkeys(requested, math.nan)
    sd_log = dict.fromkeys(requested, math.nan)
    undetermined: list[str] = []

    def hold(p: str, why: str, value: float | None = None) -> None:
        held[p] = why
        if why.startswith("not determined"):
            undetermined.append(p)
        free.remove(p)
        estimate[p] = prior[p] if value is None else value

    n_res = int(np.count_nonzero(blocks.weight))

    def weak_holds(J: Array, names: Sequence[str], sigma: float) -> list[tuple[str, str]]:
        """The skin's parameters to hold, one by one, while the weakest direction of ``J`` over
        them is known to worse than ``SD_MAX`` for noise ``sigma``; with why. (Not the lags: how
        well a lag is seen depends on its size, and its prior is often 0; not the offsets: their
        prior, 0, is typically tenths of a kelvin off, and held there before the fit they drove
        the rest to their bounds on a noisy log. The fit's own check weighs them.)"""
        rest = [p for p in names if kind(p) == "skin"]
        out: list[tuple[str, str]] = []
        while rest and sigma > 0.0:
            S, Vt = _svd(J[:, [names.index(p) for p in rest]])
            sd_weak = sigma / float(S[-1])
            if sd_weak <= SD_MAX:
                break
            worst = to_hold(rest, sigma**2 * ((Vt.T / S**2) @ Vt))
            out.append((worst, f"not determined by this log: {weak_text(rest, Vt[-1], sd_weak)} (for "
                               f"{sigma * 1e3:.3g} mK of noise)"))
            rest.remove(worst)
        return out

    # directions the log does not see at all (an exact trade-off, e.g. R_aw at a constant ambient),
    # then those it sees too weakly for the noise (linearised at the prior, the offsets solved for
    # there; the noise from the readings' differences or, if less, the residual there): held
    # before the fit, which would otherwise wander along them to a bound. Provisional: after
    # the fit, with its residual's noise, those it would not hold are released and fitted.
    def with_width(w: float) -> Blocks:
        return dataclasses.replace(blocks, Tp=blocks.tank[w], smooth_T_p=w)

    fresh_p = fresh_rows(log, 2)
    conv_p = np.flatnonzero(fresh_p) if fresh_p is not None else None
    rows = np.arange(cols["t"].size, dtype=float)

    def tank_noise(rng: np.random.Generator) -> Array:
        """One draw of the tank sensor's noise as the blocks take it: white per reading, lines
        between the readings, smoothed as the fit's input is (one pass over the whole log: a
        draw of noise need not stop at a gap)."""
        assert blocks.usable is not None
        if conv_p is None and blocks.smooth_T_p == 0.0:  # white per row: a block's mean is white too
            return sigma_p / np.sqrt(blocks.nlen.astype(float)) * rng.standard_normal(blocks.nlen.size)
        if conv_p is None:
            x = sigma_p * rng.standard_normal(rows.size)
        else:
            x = np.interp(rows, conv_p.astype(float), sigma_p * rng.standard_normal(conv_p.size))
        out = np.empty(blocks.nlen.size)
        _smoothed_means(x, round(0.5 * blocks.smooth_T_p / t_s), blocks.first, blocks.nlen, out)
        return out

    eiv: dict[float, dict[str, float]] = {}

    def eiv_shift(nl: Sequence[str], off: Sequence[str]) -> tuple[dict[str, float], dict[str, float]]:
        """How far twice the tank's noise would move each fitted parameter (``theta``; offsets in
        K), and the standard error of that: over :data:`EIV_DRAWS` draws of more noise, the
        Gauss-Newton step from the optimum on the noisier input (a Jacobian of its own)."""
        rng = np.random.default_rng(1)
        theta = np.array([to_theta(p, estimate[p]) for p in nl])
        steps = []
        for _ in range(EIV_DRAWS):
            b = dataclasses.replace(blocks, Tp=blocks.Tp + tank_noise(rng))

            def fun(th: Array, b: Blocks = b) -> Array:
                return residuals(b, {**fixed(), **values_of(nl, th)}, cfg, off)

            e = fun(theta)
            th1 = theta
            if nl:
                J1 = np.column_stack([(fun(theta + h) - e) / 1e-5 for h in np.eye(theta.size) * 1e-5])
                th1 = theta + np.linalg.lstsq(J1, -e, rcond=None)[0]
            o1 = evaluate(b, {**fixed(), **values_of(nl, th1)}, cfg, off).offsets
            steps.append([*(th1 - theta), *(o1[p] - estimate[p] for p in off)])
        st = np.asarray(steps)
        names = [*nl, *off]
        mean = dict(zip(names, st.mean(axis=0).tolist(), strict=True))
        se = dict(zip(names, (st.std(axis=0, ddof=1) / math.sqrt(len(st))).tolist(), strict=True))
        return mean, se

    provisional: list[str] = []
    sigma_pre = 0.0
    if free:
        free0 = list(free)
        start = {p: (max(prior[p], 0.01) if kind(p) == "lag" else prior[p]) for p in free0}
        ev0 = evaluate(blocks, start, cfg, [p for p in free0 if kind(p) == "offset"])
        start.update(ev0.offsets)
        sigma_pre = min(reading_noise(cols["T_w"], blocks, fresh_rows(log, 1)),
                        math.sqrt(float(ev0.e @ ev0.e) / max(n_res - len(free0), 1)))
        J0 = jacobian(fun_full(free0), phi_of(free0, start))
        while free:
            S, Vt = _svd(J0[:, [free0.index(p) for p in free]])
            if S[-1] > NULL_RTOL * S[0]:
                break
            hold(free[int(np.argmax(np.abs(Vt[-1])))],
                 f"not determined by this log: the fit does not change along {combination(free, Vt[-1])}")
        for p, why in weak_holds(J0[:, [free0.index(q) for q in free]], list(free), sigma_pre):
            hold(p, why + " at the prior")
            provisional.append(p)

    # a parameter that ran to a bound is held at its prior and the rest fitted again; then, if the
    # fit is about as good without it (chi-square of the difference, for the residuals' colour,
    # below CHI2_95), it was not determined; else the log asks for it beyond the bound: a misfit
    pending: list[tuple[str, float, int, float]] = []

    def settle(ssr_now: float) -> None:
        n_seen = int(np.count_nonzero(blocks.weight))
        for p, ssr_b, n_free, tau_b in pending:
            rise = (ssr_now - ssr_b) / (ssr_b / max(n_seen - n_free, 1)) / tau_b
            if rise <= CHI2_95:
                held[p] = (f"not determined by this log: {held[p]}, and held at its prior the fit is "
                           f"as good (chi-square up {max(rise, 0.0):.2g})")
                undetermined.append(p)
            else:
                held[p] = (f"{held[p]}: the log does not fit the model (chi-square up {rise:.3g} when "
                           "held): a sensor's offset or lag not fitted, a touch, a wrong held value?; "
                           "kept at its prior")
        pending.clear()

    z = Z95
    # the tank's noise; a converter's step coarser than it rounds like noise of q / sqrt(12)
    fr_p = fresh_rows(log, 2)
    sigma_p = max(input_noise(cols["T_p"], blocks, fr_p),
                  quantum_of(cols["T_p"][fr_p] if fr_p is not None else cols["T_p"]) / math.sqrt(12.0))
    cov = np.zeros((0, 0))
    tau = colour = 1.0
    ev = evaluate(blocks, {}, cfg)
    J = np.zeros((blocks.mode.size, 0))
    for attempt in range(3 + len(blocks.tank)):
        while free:
            nl = [p for p in free if kind(p) != "offset"]
            off = [p for p in free if kind(p) == "offset"]
            theta = np.zeros(0)
            if nl:
                lo = np.array([bounds(p)[0] for p in nl])
                hi = np.array([bounds(p)[1] for p in nl])
                # from the prior: not from where a weak direction drifted (a lag from 10 ms: at 0 the
                # fit would start on its bound)
                th0 = np.clip([to_theta(p, max(prior[p], 0.01) if kind(p) == "lag" else prior[p])
                               for p in nl], lo, hi)
                res = least_squares(fun_vp(nl, off), th0, bounds=(lo, hi), x_scale="jac", method="trf",
                                    xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=100 * (len(nl) + 1))
                theta = res.x
                settle(2.0 * float(res.cost))
                # a bound is a finding: hold the parameter (a lag at zero: none seen) and fit the rest again
                at = [(p, "upper" if theta[i] >= hi[i] - AT_BOUND else "lower") for i, p in enumerate(nl)
                      if theta[i] >= hi[i] - AT_BOUND or theta[i] <= lo[i] + AT_BOUND]
                wider = [w for w in sorted(blocks.tank) if w > blocks.smooth_T_p]
                if any(not (kind(p) == "lag" and side == "lower") for p, side in at) and wider \
                        and sigma_p > 0.0:
                    # the tank's noise fed into the network drives parameters to bounds (errors in
                    # the variables): smooth its readings more before calling it a finding
                    blocks = with_width(wider[0])
                    continue
                if at:
                    e_at = fun_vp(nl, off)(theta)
                    for p, side in at:
                        x = from_theta(p, theta[nl.index(p)])
                        if kind(p) == "lag" and side == "lower":
                            hold(p, "no lag seen: the fit ran to 0", 0.0)
                        else:
                            hold(p, f"ran to its {side} bound {x:.4g} {UNITS[p]}")
                            pending.append((p, float(e_at @ e_at), len(free) + 1,
                                            autocorrelation_time(e_at[blocks.weight > 0])))
                    continue
            vals_nl = {p: from_theta(p, float(theta[i])) for i, p in enumerate(nl)}
            ev = evaluate(blocks, {**fixed(), **vals_nl}, cfg, off)
            if not nl:
                settle(float(ev.e @ ev.e))
            beyond = [p for p in off if abs(ev.offsets[p]) > OFFSET_LIMIT]
            if beyond:
                for p in beyond:
                    hold(p, f"beyond ±{OFFSET_LIMIT:g} K ({ev.offsets[p]:+.3g} K): a channel swapped or "
                            "not a thermocouple?; kept at its prior")
                continue
            vals = {**vals_nl, **ev.offsets}
            names = [*nl, *off]
            phi = phi_of(names, vals)
            base = fixed()
            J = jacobian(fun_full(names, base), phi)
            S, Vt = _svd(J)
            tn = tank_noise if blocks.usable is not None else None
            # the weak direction's test from a few draws of the tank's noise; the intervals from all
            cov, tau, colour = covariance(blocks, {**base, **vals}, cfg, J, ev.e, (S, Vt), sigma_p,
                                          draws=N_DRAWS_CHECK, tank_noise=tn)
            lam, U = np.linalg.eigh(cov)  # the worst-known direction: the largest variance
            sd_weak = math.sqrt(max(float(lam[-1]), 0.0))
            if sd_weak <= SD_MAX:
                cov, tau, colour = covariance(blocks, {**base, **vals}, cfg, J, ev.e, (S, Vt), sigma_p,
                                              tank_noise=tn)
            sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
            for i, p in enumerate(names):
                estimate[p] = vals[p]
                if kind(p) == "offset":
                    sd_log[p] = float(sd[i]) * off_unit
                    low[p] = vals[p] - z * sd_log[p]
                    high[p] = vals[p] + z * sd_log[p]
                else:
                    half = min(z * float(sd[i]), 700.0)  # beyond: a factor above 1e300, as good as none
                    sd_log[p] = float(sd[i])
                    low[p] = from_theta(p, phi[i] - half)
                    high[p] = from_theta(p, phi[i] + half)
            if sd_weak <= SD_MAX:
                free = names  # the order of the fit's vector
                break
            worst = to_hold(names, cov)
            why = weak_text(names, U[:, -1], sd_weak)
            if kind(worst) == "offset":  # the model keeps its value (module doc), the config its own
                kept[worst] = estimate[worst]
                why += f"; the fit keeps its least-squares value {kept[worst]:+.3g} K, the config its own"
            hold(worst, f"not determined by this log: {why}")
            cov = np.zeros((0, 0))
        if not free:
            ev = evaluate(blocks, fixed(), cfg)
            J = np.zeros((ev.e.size, 0))

        if pending:  # the fit ended with what ran to a bound held: settle it against the end
            settle(float(ev.e @ ev.e))
        if not free:
            break
        changed = False
        # the tank's noise, fed into the network, biases the fit (errors in the variables): where
        # twice as much would move a parameter by more than half its sd (and EIV_FLOOR), the
        # tank's readings are smoothed over the next width of SMOOTH_WIDTHS and the fit made again
        wider = [w for w in sorted(blocks.tank) if w > blocks.smooth_T_p]
        if wider and sigma_p > 0.0:
            shift, se = eiv_shift([p for p in free if kind(p) != "offset"],
                                  [p for p in free if kind(p) == "offset"])
            eiv[blocks.smooth_T_p] = shift
            if any(abs(shift[p]) - 2.0 * se[p] > max(0.5 * sd_log[p], EIV_FLOOR[kind(p)]) for p in shift):
                blocks = with_width(wider[0])
                changed = True
        if attempt == 0 and provisional:
            # release what the fit's residual noise shows is determined after all
            sigma_post = math.sqrt(float(ev.e @ ev.e) / max(n_res - len(free), 1))
            cand = [*free, *provisional]
            vals_all = {**fixed(), **{p: estimate[p] for p in cand}}
            J_all = jacobian(fun_full(cand, fixed()), phi_of(cand, vals_all))
            keep = {p for p, _ in weak_holds(J_all, cand, sigma_post)}
            for p in provisional:
                if p not in keep:
                    held.pop(p)
                    undetermined.remove(p)
                    free.append(p)
                    changed = True
            provisional = [p for p in provisional if p in keep]
        if not changed:
            break

    # elasticities of the fitted parameters on the held ones: d theta_f = -pinv(J_f) J_h d theta_h
    dependence: dict[str, dict[str, float]] = {}
    und = [q for q in undetermined if kind(q) != "offset"]
    if free and und:
        vals = {**fixed(), **{p: estimate[p] for p in (*free, *und)}}

        def fun_h(th_h: Array) -> Array:
            v = dict(vals)
            v.update({q: from_theta(q, x) for q, x in zip(und, th_h.tolist(), strict=True)})
            return residuals(blocks, v, cfg)

        J_h = jacobian(fun_h, np.array([to_theta(q, vals[q]) for q in und]))
        D = -np.linalg.lstsq(J, J_h, rcond=None)[0]
        doubtful: dict[str, str] = {}
        for i, p in enumerate(free):
            if kind(p) == "offset":
                # an offset resting on a held parameter's prior: a lab's prior being tens of
                # percent off (SKIN_DOUBT) would move it by more than OFFSET_DEP_TOL: not written
                dep_k = {q: float(D[i, k]) * off_unit for k, q in enumerate(und)}
                moved = sum(abs(d) for d in dep_k.values()) * math.log(1.0 + SKIN_DOUBT)
                if moved > OFFSET_DEP_TOL:
                    txt = ", ".join(f"{q} ({d:+.2g} K per unit of ln {q})" for q, d in dep_k.items()
                                    if abs(d) * math.log(1.0 + SKIN_DOUBT) > 0.1 * OFFSET_DEP_TOL)
                    doubtful[p] = (f"not determined by this log: it trades with the held {txt}: their "
                                   f"priors {SKIN_DOUBT:.0%} off would move it by {moved:.2g} K; the fit "
                                   f"keeps {estimate[p]:+.3g} K, the config its own")
                continue
            dep = {q: float(D[i, k]) for k, q in enumerate(und)
                   if abs(D[i, k]) >= DEP_MIN and abs(D[i, k]) * math.log(DEP_FACTOR) > sd_log[p]}
            if dep:
                dependence[p] = dep
        if doubtful:
            keep_idx = [i for i, p in enumerate(free) if p not in doubtful]
            cov = cov[np.ix_(keep_idx, keep_idx)]
            for p, why in doubtful.items():
                kept[p] = estimate[p]
                held[p] = why
                undetermined.append(p)
                estimate[p] = prior[p]
            free = [p for p in free if p not in doubtful]

    w = blocks.weight
    seen = w > 0
    e = ev.e
    sd = np.sqrt(np.diag(cov))
    corr = cov / np.outer(sd, sd) if sd.size else cov
    written = (*free, *(p for p, why in held.items() if why.startswith("no lag")))
    return Calibration(
        prior=cfg, requested=requested, names=tuple(free),
        estimate={p: estimate[p] for p in requested}, low=low, high=high, sd_log=sd_log,
        covariance=cov, correlation=corr, held=held, dependence=dependence,
        prior_values={p: prior[p] for p in requested},
        rms=float(np.sqrt(np.mean((e[seen] / w[seen]) ** 2))),
        sigma=float(np.sqrt((e @ e) / max(int(seen.sum()) - len(free), 1))), sigma_p=sigma_p, tau=tau,
        colour=colour, n_samples=blocks.n_samples, n_stretches=int(blocks.w0.size), duration=duration,
        t_fit=blocks.m * t_s, nfev=nfev, wall_s=time.perf_counter() - t_start, blocks=blocks,
        fitted=evaluate(blocks, {**fixed(), **{p: estimate[p] for p in free}}, cfg,
                        fitted=True).fitted, reference=reference, written=tuple(written))


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
        + f"T_p noise {cal.sigma_p * 1e3:.1f} mK (its readings smoothed over {cal.blocks.smooth_T_p:.3g} s); "
        f"residual autocorrelation time {cal.tau:.2f} "
        + ("blocks" if cal.blocks.m > 1 else "samples"),
        "95 % intervals exp(ln p ± 1.96 sd) (offsets ± 1.96 sd): Gauss-Newton covariance at the "
        "optimum with the T_w noise white and the T_p noise carried through the network; colour "
        f"beyond that model: covariance x {cal.colour:.2f}",
    ]
    if any(kind(p) == "offset" for p in cal.requested):
        lines.append(f"offsets relative to {cal.reference}'s (held at "
                     f"{getattr(cal.prior.sensor, 'offset_' + cal.reference):+.4g} K): only the "
                     "differences between the channels reach the readings")
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
    head = ["# thermoskin calibrate" + (f": skin and sensor parameters fitted to {source}" if source else "")]
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
        if section in ("skin", "sensor") and key in cal.requested:
            lo, hi = cal.interval(key)
            note = (f"fitted, 95 % interval [{_g(lo)}, {_g(hi)}]" if key in cal.names
                    else cal.held[key].split(":")[0] if key in cal.written
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
