"""Identify a discrete ARX model of the Peltier tank's ``T_p`` against the drive (Sec. V).

The paper models the Peltier response with a discrete "ARMA" model identified from data;
we fit its input-output form, an ARX model, at a model sample time ``t_m``::

    A(q) T_p[k] = B(q) drive[k] + d T_a[k-1] + c
    A(q) = 1 + a_1 q^-1 + ... + a_na q^-na
    B(q) = b_1 q^-nk + ... + b_nb q^-(nk+nb-1)

(``d`` only with ``with_T_a=True``) by ordinary least squares (``numpy.linalg.lstsq``) on
the regression ``y[k] = φ[k]ᵀ θ``, ``φ = [-y[k-1..k-na], u[k-nk..k-nk-nb+1], (T_a[k-1]), 1]``.

Steps of :func:`identify`:

1. Decimation by block averaging (``m = t_m / t_s`` samples per block): a moving-average
   anti-alias filter applied alike to input and output (an LTI filter commutes with the
   plant, so the filtered signals obey the same model), then one value per block. It also
   averages the thermocouple noise down by ``sqrt(m)``.
2. ``t_m`` automatic (``t_model=None``): a provisional second-order fit at 1 s gives the
   poles; ``t_m`` is the largest of ``T_MODEL_CANDIDATES`` (multiples of the log's ``t_s``)
   not above ``τ_fast / 20``, where ``τ_fast = -t / ln p`` of the fastest real stable pole,
   limited to ``[0.1, 1] s``. The Peltier tank's fastest mode (the heat sink, ~15 s) gives 0.5-1 s.
3. Orders ``(na, nb, nk)`` on a grid (``na <= na_max``, ``nb <= nb_max``,
   ``nk_min <= nk <= nk_max``; ``nk = 0`` is allowed by default because a block mean of
   ``T_p`` already responds to the drive applied within its own block), each fitted on the
   first ``1 - val_fraction`` of the data and scored by an information criterion of its
   one-step residuals (all fits on the same rows)::

       AIC = N ln(σ²) + 2 p,    BIC = N ln(σ²) + p ln N,    σ² = RSS / N

   the smallest wins (ties: fewer parameters).
4. The fit on the held-back last ``val_fraction``: the *simulation* fit
   ``NRMSE = 1 - ||y - y_sim|| / ||y - mean(y)||``, ``y_sim`` run from the measured
   outputs before the validation window with the measured drive only. The final model
   keeps the estimation-split coefficients (those the validation judged).
"""

from __future__ import annotations

import dataclasses
import math
import os
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from thermoskin.logio import LogError, read_log
from thermoskin.params import toml_number

Array = NDArray[np.float64]

T_MODEL_CANDIDATES: tuple[float, ...] = (0.1, 0.2, 0.5, 1.0)
"""Model sample times (s) the automatic choice picks from."""
MIN_SAMPLES = 60
"""Fewest decimated samples in the estimation split."""


class IdentifyError(ValueError):
    """A user error in the identification input (one-line message)."""


@dataclass
class ArxModel:
    """``A(q) y = B(q) u + d T_a[k-1] + c`` at sample time ``t_s`` (see the module doc).

    ``a = [a_1..a_na]``, ``b = [b_1..b_nb]`` (``b_1`` at delay ``nk``), ``d`` the ``T_a``
    coefficient (0 without that input). Fit metrics: ``nrmse`` (validation, simulation),
    ``nrmse_est`` (estimation split, simulation), ``criterion`` and its value ``ic``,
    ``rmse`` (validation, K), ``n_est``/``n_val`` (decimated samples), ``t_s_log`` (s).
    """

    na: int
    nb: int
    nk: int
    a: Array
    b: Array
    c: float
    t_s: float
    d: float = 0.0
    with_T_a: bool = False
    nrmse: float = math.nan
    nrmse_est: float = math.nan
    rmse: float = math.nan
    criterion: str = "bic"
    ic: float = math.nan
    n_est: int = 0
    n_val: int = 0
    t_s_log: float = math.nan
    candidates: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.a = np.asarray(self.a, dtype=float).ravel()
        self.b = np.asarray(self.b, dtype=float).ravel()
        if self.a.size != self.na or self.b.size != self.nb:
            raise ValueError(f"ArxModel: a has {self.a.size} values for na = {self.na}, "
                             f"b has {self.b.size} for nb = {self.nb}")

    # -- properties ----------------------------------------------------------------------
    @property
    def poles(self) -> Array:
        """Roots of ``z^na A(z)``."""
        return np.roots(np.r_[1.0, self.a]) if self.na else np.zeros(0)

    def steady_state_gain(self) -> float:
        """``B(1)/A(1)``, K per unit drive."""
        return float(self.b.sum() / (1.0 + self.a.sum()))

    def steady_state(self, drive: float, T_a: float = 20.0) -> float:
        """Steady ``T_p`` for a held drive (and ``T_a``): ``(B(1) u + d T_a + c)/A(1)``."""
        return float((self.b.sum() * drive + self.d * T_a + self.c) / (1.0 + self.a.sum()))

    def time_constants(self) -> Array:
        """``-t_s / ln p`` of the real positive poles (s), largest first."""
        p = self.poles
        p = p[(np.abs(p.imag) < 1e-9) & (p.real > 0.0) & (p.real < 1.0)].real
        return np.sort(-self.t_s / np.log(p))[::-1]

    # -- simulation ----------------------------------------------------------------------
    def simulate(self, drive: ArrayLike, y0: float | ArrayLike, T_a: ArrayLike | float | None = None,
                 u0: float | ArrayLike | None = None) -> Array:
        """Free-run output ``y[0..N-1]`` for the drive ``u[0..N-1]`` (one value per ``t_s``).

        ``y0``: the output before sample 0, a scalar (all ``na`` past values equal) or the
        last ``na`` past values, oldest first. ``u0``: past drives, likewise (default
        ``drive[0]``). ``T_a``: scalar or array (needed only with ``with_T_a``; default 20 °C).
        """
        u = np.asarray(drive, dtype=float).ravel()
        N = u.size
        na, nb, nk = self.na, self.nb, self.nk
        nu = nk + nb - 1
        yp = np.broadcast_to(np.asarray(y0, dtype=float), (na,)) if na else np.zeros(0)
        if u0 is None:
            up = np.full(nu, u[0] if N else 0.0)
        else:
            up = np.broadcast_to(np.asarray(u0, dtype=float), (nu,))
        ta = np.broadcast_to(np.asarray(20.0 if T_a is None else T_a, dtype=float), (N,))
        ta_prev = np.r_[ta[:1], ta[:-1]] if N else ta  # T_a[k-1], T_a[-1] taken as T_a[0]
        return _simulate(self.a, self.b, nk, self.c, self.d if self.with_T_a else 0.0,
                         u, ta_prev, np.asarray(yp, float), np.asarray(up, float))

    # -- TOML ----------------------------------------------------------------------------
    def to_toml(self, use: str = "feedforward") -> str:
        """The model as a configuration file that ``thermoskin run --config`` accepts: a
        ``[peltier_model]`` table (:class:`~thermoskin.params.PeltierModelParams`) whose
        ``use = "feedforward"`` makes the inner loop add the model's steady-state drive."""
        num = toml_number  # rounded: the log's median step carries its clock's last bits

        def arr(x: Array) -> str:
            return "[" + ", ".join(num(v) for v in x) + "]"

        lines = [
            "# thermoskin identify: an ARX model of T_p against the Peltier drive,",
            "#   A(q) T_p[k] = B(q) drive[k] + d T_a[k-1] + c   (at t_s, q the shift operator)",
            f"# orders na = {self.na}, nb = {self.nb}, nk = {self.nk} by {self.criterion.upper()} "
            f"({self.criterion} = {num(self.ic)}); {self.n_est} samples for the fit, {self.n_val} held "
            f"back; log sampled every {num(self.t_s_log)} s.",
            f"# steady-state gain {num(self.steady_state_gain())} K per unit drive.",
            "# A config for `thermoskin run --config FILE` (alone or added to another config):",
            '# with use = "feedforward" the inner loop adds the drive that holds T_p_cmd in the',
            "# model's steady state, and its PI corrects the rest.",
            "[peltier_model]",
            f'use = "{use}"',
            f"t_s = {num(self.t_s)}  # s",
            f"nk = {self.nk}",
            f"a = {arr(self.a)}", f"b = {arr(self.b)}",
            f"c = {num(self.c)}", f"d = {num(self.d)}",
            f"with_T_a = {'true' if self.with_T_a else 'false'}",
        ]
        for name in ("nrmse", "nrmse_est", "rmse"):
            x = getattr(self, name)
            if math.isfinite(x):
                lines.append(f"{name} = {num(x)}")
        return "\n".join([*lines, ""])

    @classmethod
    def from_toml(cls, text: str) -> ArxModel:
        """Parse :meth:`to_toml`'s text (``[peltier_model]``, or the older ``[arx]`` table);
        raises :class:`IdentifyError` on a bad file."""
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as e:
            raise IdentifyError(f"model is not valid TOML: {e}") from None
        if isinstance(data.get("peltier_model"), dict):
            from thermoskin.params import ConfigError, PeltierModelParams

            t = dict(data["peltier_model"])
            t.pop("use", None)
            try:
                pm = PeltierModelParams(**{"use": "off", **t})
            except (ConfigError, TypeError) as e:
                raise IdentifyError(f"bad [peltier_model]: {e}") from None
            if not pm.a or not pm.b:
                raise IdentifyError("model lacks key(s) a, b in [peltier_model]")
            kw: dict[str, Any] = {"na": len(pm.a), "nb": len(pm.b), "nk": pm.nk, "a": pm.a, "b": pm.b,
                                  "c": pm.c, "d": pm.d, "t_s": pm.t_s, "with_T_a": pm.with_T_a}
            kw.update({k: getattr(pm, k) for k in ("nrmse", "nrmse_est", "rmse")
                       if getattr(pm, k) is not None})
            return cls(**kw)
        t = data.get("arx")
        if not isinstance(t, dict):
            raise IdentifyError("model has no [peltier_model] (or [arx]) table")
        fit = t.pop("fit", {})
        known = {f.name for f in dataclasses.fields(cls)}
        kw = {}
        for key, value in [*t.items(), *fit.items()]:
            if key not in known:
                raise IdentifyError(f"unknown key {key!r} in the model's [arx] table")
            kw[key] = value
        missing = [k for k in ("na", "nb", "nk", "a", "b", "c", "t_s") if k not in kw]
        if missing:
            raise IdentifyError(f"model lacks key(s) {', '.join(missing)} in [arx]")
        try:
            return cls(**kw)
        except (TypeError, ValueError) as e:
            raise IdentifyError(f"bad model: {e}") from None

    def save_model(self, path: str | os.PathLike[str], use: str = "feedforward") -> Path:
        """Write :meth:`to_toml` to ``path``."""
        return save_model(self, path, use)


def save_model(model: ArxModel, path: str | os.PathLike[str], use: str = "feedforward") -> Path:
    """Write the model as a config file (:meth:`ArxModel.to_toml`), atomically; returns the path."""
    from thermoskin.atomic import write_text

    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    write_text(p, model.to_toml(use))
    return p


def load_model(path: str | os.PathLike[str]) -> ArxModel:
    """Read a model written by :func:`save_model`."""
    p = Path(path)
    if not p.is_file():
        raise IdentifyError(f"{p}: model file not found")
    try:
        return ArxModel.from_toml(p.read_text(encoding="utf-8"))
    except IdentifyError as e:
        raise IdentifyError(f"{p}: {e}") from None


# --------------------------------------------------------------------------- core


def _simulate(a: Array, b: Array, nk: int, c: float, d: float, u: Array, ta_prev: Array,
              yp: Array, up: Array) -> Array:
    """Free run: past outputs ``yp`` (na, oldest first), past inputs ``up`` (nk+nb-1, oldest
    first), ``ta_prev[k] = T_a[k-1]``."""
    na, nb = a.size, b.size
    N = u.size
    off = up.size
    al = (-a).tolist()
    bl = b.tolist()
    yl = [*yp.tolist(), *([0.0] * N)]
    ul = [*up.tolist(), *u.tolist()]  # ul[off + j] = u[j]
    base = (c + d * ta_prev).tolist() if d else [c] * N
    for k in range(N):
        acc = base[k]
        for i in range(na):
            acc += al[i] * yl[na + k - 1 - i]
        for j in range(nb):
            acc += bl[j] * ul[off + k - nk - j]
        yl[na + k] = acc
    return np.asarray(yl[na:])


def regressors(y: Array, u: Array, ta: Array | None, na: int, nb: int, nk: int,
               start: int, stop: int) -> tuple[Array, Array]:
    """``(Φ, y[start:stop])`` with rows ``[-y[k-1..k-na], u[k-nk..], (T_a[k-1]), 1]``."""
    if start < max(na, nk + nb - 1, 1):
        raise ValueError("regressors: start too early for the orders")
    k = np.arange(start, stop)
    cols = [-y[k - i] for i in range(1, na + 1)]
    cols += [u[k - nk - j] for j in range(nb)]
    if ta is not None:
        cols.append(ta[k - 1])
    cols.append(np.ones(k.size))
    return np.column_stack(cols), y[start:stop]


def _fit(y: Array, u: Array, ta: Array | None, na: int, nb: int, nk: int,
         start: int, stop: int) -> tuple[Array, float, int]:
    """Least squares; returns ``(θ, RSS, N)``."""
    Phi, Y = regressors(y, u, ta, na, nb, nk, start, stop)
    scale = np.linalg.norm(Phi, axis=0)
    scale[scale == 0.0] = 1.0
    th, *_ = np.linalg.lstsq(Phi / scale, Y, rcond=None)
    th = th / scale
    r = Y - Phi @ th
    return th, float(r @ r), Y.size


def _unpack(th: Array, na: int, nb: int, with_ta: bool) -> tuple[Array, Array, float, float]:
    a = th[:na]
    b = th[na:na + nb]
    d = float(th[na + nb]) if with_ta else 0.0
    return a, b, d, float(th[-1])


def nrmse(y: ArrayLike, y_hat: ArrayLike) -> float:
    """``1 - ||y - ŷ|| / ||y - mean(y)||`` (1 is perfect, 0 is as good as the mean)."""
    yy = np.asarray(y, dtype=float)
    e = np.linalg.norm(yy - np.asarray(y_hat, dtype=float))
    s = np.linalg.norm(yy - yy.mean())
    return float(1.0 - e / s) if s > 0 else math.nan


def _sim_fit(y: Array, u: Array, ta: Array | None, a: Array, b: Array, nk: int, c: float, d: float,
             start: int, stop: int) -> tuple[float, float]:
    """Simulation NRMSE and RMSE of ``y[start:stop]``, run from the measured past."""
    na, nb = a.size, b.size
    nu = nk + nb - 1
    yp = y[start - na:start]
    up = u[start - nu:start]
    ta_prev = ta[start - 1:stop - 1] if ta is not None else np.zeros(stop - start)
    with np.errstate(over="ignore", invalid="ignore"):
        ysim = _simulate(a, b, nk, c, d, u[start:stop], ta_prev, yp, up)
        Y = y[start:stop]
        return nrmse(Y, ysim), float(np.sqrt(np.mean((Y - ysim) ** 2)))


def decimate_blocks(x: Array, m: int) -> Array:
    """Means of consecutive blocks of ``m`` samples (the tail shorter than ``m`` is dropped)."""
    n = (x.size // m) * m
    return x[:n].reshape(-1, m).mean(axis=1)


def _check_log(log: Mapping[str, ArrayLike], with_T_a: bool) -> tuple[Array, Array, Array, Array | None]:
    need = ["t", "T_p", "drive"] + (["T_a"] if with_T_a else [])
    missing = [n for n in need if n not in log]
    if missing:
        raise IdentifyError(f"log lacks column(s) {', '.join(missing)} (has: {', '.join(log)})")
    cols = {}
    for n in need:
        x = np.asarray(log[n], dtype=float).ravel()
        cols[n] = x
    sizes = {x.size for x in cols.values()}
    if len(sizes) != 1:
        raise IdentifyError("log columns have different lengths: "
                            + ", ".join(f"{n}={x.size}" for n, x in cols.items()))
    t = cols["t"]
    for n, x in cols.items():
        bad = ~np.isfinite(x)
        if bad.any():
            i = int(np.argmax(bad))
            at = f"t = {t[i]:g} s" if n != "t" and math.isfinite(t[i]) else f"row {i}"
            raise IdentifyError(f"column {n!r} has {int(bad.sum())} NaN/inf value(s), first at {at}; "
                                "cut or repair the log before identifying")
    if t.size < 3:
        raise IdentifyError(f"log too short: {t.size} sample(s)")
    dt = np.diff(t)
    if np.any(dt <= 0):
        raise IdentifyError(f"column 't' is not strictly increasing (at row {int(np.argmax(dt <= 0)) + 1})")
    u = cols["drive"]
    out = np.abs(u) > 1.0 + 1e-9
    if out.any():  # the drive is the Peltier's duty, -1 to 1 (plausible.drive_min/max)
        i = int(np.argmax(out))
        raise IdentifyError(f"column 'drive' is outside [-1, 1] in {int(out.sum())} row(s), first "
                            f"{u[i]:g} at t = {t[i]:g} s: the drive is the Peltier's duty (-1 to 1); "
                            "a log with the drive in other units would give a wrong gain")
    if np.ptp(u) <= 1e-9 * max(1.0, float(np.max(np.abs(u)))):
        raise IdentifyError(f"drive has no excitation (constant {u[0]:g} over the log); "
                            "identify from a log with a varying drive (thermoskin excitation)")
    return t, cols["T_p"], u, cols.get("T_a")


def _auto_t_model(t_s: float, y: Array, u: Array, n_blocks_min: int) -> float:
    """See the module doc, step 2."""
    cands = [c for c in T_MODEL_CANDIDATES if c >= t_s * (1 - 1e-9)]
    if not cands:
        return t_s
    probe = cands[-1]
    m = max(1, round(probe / t_s))
    yd, ud = decimate_blocks(y, m), decimate_blocks(u, m)
    if yd.size < n_blocks_min:
        return cands[0]
    try:
        th, _, _ = _fit(yd, ud, None, 2, 2, 0, 2, yd.size)
    except np.linalg.LinAlgError:
        return cands[-1]
    p = np.roots(np.r_[1.0, th[:2]])
    p = p[(np.abs(p.imag) < 1e-9) & (p.real > 0.0) & (p.real < 1.0)].real
    if p.size == 0:
        return cands[-1]
    tau_fast = float(np.min(-m * t_s / np.log(p)))
    ok = [c for c in cands if c <= tau_fast / 20.0]
    return ok[-1] if ok else cands[0]


def identify(log: Mapping[str, ArrayLike] | str | os.PathLike[str], *, t_model: float | None = None,
             na_max: int = 4, nb_max: int = 4, nk_max: int = 3, nk_min: int = 0,
             criterion: str = "bic", val_fraction: float = 0.3, with_T_a: bool = False,
             orders: Sequence[int] | None = None) -> ArxModel:
    """Fit an :class:`ArxModel` of ``T_p`` against ``drive`` (see the module doc).

    ``log``: columns ``t, T_p, drive`` (and ``T_a`` with ``with_T_a``), or a CSV path.
    ``orders = (na, nb, nk)`` skips the order search.
    Raises :class:`IdentifyError`.
    """
    if isinstance(log, str | os.PathLike):
        try:
            need = ("t", "T_p", "drive") + (("T_a",) if with_T_a else ())
            log = read_log(log, required=need, one_patch=True, keep=need)
        except LogError as e:
            raise IdentifyError(str(e)) from None
    if criterion not in ("aic", "bic"):
        raise IdentifyError(f"criterion = {criterion!r}: must be 'aic' or 'bic'")
    if not 0.05 <= val_fraction <= 0.8:
        raise IdentifyError(f"val_fraction = {val_fraction}: must be between 0.05 and 0.8")
    if min(na_max, nb_max) < 1 or nk_max < nk_min or nk_min < 0:
        raise IdentifyError("orders: need na_max >= 1, nb_max >= 1, 0 <= nk_min <= nk_max")
    t, y_full, u_full, ta_full = _check_log(log, with_T_a)
    # the median step, to a config's digits: a clock's last bits are not the log's rate
    t_s_log = float(toml_number(float(np.median(np.diff(t)))))
    if orders is None:
        lag = max(na_max, nk_max + nb_max - 1, 1)
    else:
        lag = max(orders[0], orders[2] + orders[1] - 1, 1)
    n_min = math.ceil((MIN_SAMPLES + lag) / (1.0 - val_fraction))

    if t_model is None:
        t_model = _auto_t_model(t_s_log, y_full, u_full, n_min)
    elif not t_model > 0.0:
        raise IdentifyError(f"t_model = {t_model} s must be > 0")
    m = max(1, round(t_model / t_s_log))
    t_m = m * t_s_log
    y = decimate_blocks(y_full, m)
    u = decimate_blocks(u_full, m)
    ta = decimate_blocks(ta_full, m) if ta_full is not None else None
    N = y.size
    if n_min > N:
        raise IdentifyError(f"log too short: {t[-1] - t[0] + t_s_log:.3g} s gives {N} samples at the model "
                            f"sample time {t_m:g} s; need at least {n_min} ({n_min * t_m:.3g} s)")
    if ta is not None and np.ptp(ta) < 1e-6:
        raise IdentifyError("T_a is constant: its coefficient cannot be told from the constant c; "
                            "identify without with_T_a")
    n_est = round(N * (1.0 - val_fraction))
    if np.ptp(u[:n_est]) <= 1e-9:
        raise IdentifyError("drive has no excitation in the estimation part (the first "
                            f"{100 * (1 - val_fraction):.0f} % of the log)")

    grid = ([tuple(orders)] if orders is not None else
            [(na, nb, nk) for na in range(1, na_max + 1) for nb in range(1, nb_max + 1)
             for nk in range(nk_min, nk_max + 1)])
    start = lag
    best: tuple[float, int, tuple[int, int, int], Array] | None = None
    scores: dict[str, float] = {}
    for na, nb, nk in grid:
        th, rss, n_rows = _fit(y, u, ta, na, nb, nk, start, n_est)
        p = th.size
        sigma2 = max(rss / n_rows, 1e-300)
        pen = 2.0 * p if criterion == "aic" else p * math.log(n_rows)
        ic = n_rows * math.log(sigma2) + pen
        scores[f"{na},{nb},{nk}"] = ic
        if best is None or (ic, p) < (best[0], best[1]):
            best = (ic, p, (na, nb, nk), th)
    assert best is not None
    ic, _, (na, nb, nk), th = best
    a, b, d, c = _unpack(th, na, nb, ta is not None)
    fit_est, _ = _sim_fit(y, u, ta, a, b, nk, c, d, start, n_est)
    fit_val, rmse = _sim_fit(y, u, ta, a, b, nk, c, d, n_est, N)
    return ArxModel(na=na, nb=nb, nk=nk, a=a, b=b, c=c, t_s=t_m, d=d, with_T_a=ta is not None,
                    nrmse=fit_val, nrmse_est=fit_est, rmse=rmse, criterion=criterion, ic=ic,
                    n_est=n_est, n_val=N - n_est, t_s_log=t_s_log, candidates=scores)
