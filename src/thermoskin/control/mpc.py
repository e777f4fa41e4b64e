"""Model predictive control of the pipe temperature ``T_w`` (Sec. V, eqs. 9-11).

Prediction model (eq. 10, with the sampling time ``t_s`` restored on the loss term, see
docs/model.md)::

    T_w(k+1) = (1 - t_s/(R_w C_w)) T_w(k) + t_s/(R_w C_w) T_p(k) - t_s q_loss(k)/C_w     (10)

Loss readings (``loss=``):

* ``"paper"``: ``q_loss = q_aw = (T_w - T_a)/R_aw``, eq. 10 as printed.
* ``"network"`` (default): ``q_loss = (T_w - T_a)/R_aw + (T_w - T_a)/(R_g + R_ag)``, which
  adds the steady loss from the pipe through the graphite sheet to air (Fig. 3, the sheet
  node at its steady state). Eq. 10 ignores this path; with Table I it is about 190 times
  ``q_aw`` (``R_g + R_ag = 11 K/W`` against ``R_aw = 2100 K/W``), so a model without it
  settles ``T_w`` below its command whenever the cost has no integral action, and its
  steady-state input ``T_p_ss`` (``cost="deviation"``) is wrong by ``R_w (T_w - T_a)/11``.

Either way the model is affine, ``T_w(k+1) = a T_w(k) + b T_p(k) + c T_a`` with::

    b = t_s/(R_w C_w),   G = 1/R_aw [+ 1/(R_g + R_ag)],   a = 1 - b - t_s G/C_w,   c = t_s G/C_w

``R_w`` is the flowing value ``R_w(v_on)`` (convection model or ``skin.R_w_flowing``).

Cost (eq. 9) over the horizon ``H``, reference held constant, ``u = (T_p(k) .. T_p(k+H-1))``::

    J = W1 sum_{i=1..H} (T_w(k+i|k) - T_w_cmd)^2 + W2 sum_{i=0..H-1} rho_i(u)^2          (9)

with the input term ``rho_i`` chosen by ``ControlParams.cost``:

* ``"absolute"``: ``rho_i = T_p(k+i)``, eq. 9 as printed. It pulls ``T_p`` towards 0 °C,
  so ``T_w`` settles below its command (0.71 K at 24 °C, T_a = 20 °C, Table I): kept to show it.
* ``"rate"`` (default): ``rho_i = T_p(k+i) - T_p(k+i-1)`` with ``T_p(k-1)`` the previous
  command. It "suppresses rapid change of the input" as the text says; no offset.
* ``"deviation"``: ``rho_i = T_p(k+i) - T_p_ss``, the steady-state input that holds
  ``T_w = T_w_cmd`` in the model: ``T_p_ss = ((1 - a) T_w_cmd - c T_a)/b``; no offset.

Constraints (eq. 11): ``T_p_min <= T_p(k+i) <= T_p_max``.

Condensed QP. Stacking the predictions, ``x = Phi T_w(k) + Gam u + s T_a`` with
``Phi_i = a^i``, ``Gam_ij = a^(i-1-j) b`` (``j < i``), ``s_i = c (1 + a + ... + a^(i-1))``,
and writing the input term as ``rho = D u - d``, ``J/2 = 0.5 u'Pu + q'u + const`` with::

    P = W1 Gam'Gam + W2 D'D,     q = W1 Gam'(Phi T_w + s T_a - 1 T_w_cmd) - W2 D'd

``P`` and the bounds never change; ``q`` is linear in ``theta = (T_w, T_a, T_w_cmd, T_p_prev)``,
so ``q = F theta`` with ``F`` (H x 4) precomputed. A QP sample costs one small mat-vec, an
``update(f=q)`` of a persistent ``daqp.Model`` (set up once: ``P`` factored once, the
active set of the previous solve reused as warm start) and one ``solve``; most samples
need none of it (fast path, below). The output is the first element, ``T_p_cmd = u_0``.

Fast path (``fast=True``, default). ``P`` is positive definite, so the QP is strictly
convex and its unconstrained minimiser ``u* = -P^-1 q = K theta`` (``K = -P^-1 F``,
H x 4, precomputed) minimises the cost over all of ``R^H``. If ``u*`` lies in the box of
eq. 11 it is feasible and no feasible point costs less, so it *is* the constrained
minimiser (the KKT conditions hold with all multipliers zero), and unique. If any element
leaves the box, the constrained minimiser differs from ``u*``, and the QP is needed:
checking ``u*_0`` alone is not enough, since a bound active later in the horizon moves
``u_0``. Each sample therefore tests the whole sequence against both bounds and returns
``u*_0`` (four products on plain floats) when it passes; only otherwise is daqp called.
The test (``Mpc.feasible``): first a sufficient interval bound on plain floats (the
column ranges of ``K`` times the state's distance from ``T_p_prev``; it settles nearly
every sample while a set-point is held), and when that is inconclusive the exact one,
``g = Gx (theta, 1) <= 0`` with ``Gx = [K, -T_p_max; -K, T_p_min]`` (2H x 5), one
preallocated mat-vec (which also yields ``q`` for daqp) and one reduction. It is exact up
to rounding (a few 1e-15 K), far inside daqp's own primal tolerance (1e-6). With
``cost="absolute"`` the input term pulls the horizon's tail towards 0 °C, below
``T_p_min``, so ``u*`` is never feasible and daqp runs every sample.

Warm start across the two paths. daqp starts each solve from the working set its last
solve ended with. Solving every sample, a sample whose optimum is unconstrained ends with
an empty working set; the fast path skips daqp, whose workspace would still hold the last
QP's (non-empty) working set. So on the first fast-path sample after a QP solve the
working set is cleared (``update(sense=0)``, once per switch, not per sample): at every
QP call daqp then starts from exactly the state it would have had if it had solved every
sample. The solution is unique either way; the reset keeps the iteration counts, and so
the timing and the rounding, those of the every-sample solve. ``fast=False`` (or setting
the attribute) solves the QP every sample, for comparison.

Pump stopped. While ``T_w`` is above its command the pump stops (``v = 0``) and ``T_p`` no
longer reaches the pipe: the MPC has no authority. ``on_stop="solve"`` (default) keeps
solving with the flowing ``R_w`` as if the pump ran: ``T_w`` just above the command then
asks for a slightly colder tank, so ``T_p`` is where it needs to be when the pump restarts
and the warm start stays current. ``on_stop="hold"`` skips the solve and repeats the
previous command (the tank keeps its temperature while the pipe cools by natural loss).

Failures. A NaN input repeats the previous command. If daqp reports a failure
(exit flag <= 0) the command is the unconstrained optimum's first element, clipped to the
bounds (``u = -P^-1 q``, precomputed as a gain on ``theta``), and ``n_fallback`` counts it.
"""

from __future__ import annotations

import math

import daqp
import numpy as np

from thermoskin.params import ConfigError, ControlParams, SkinParams
from thermoskin.physics.convection import R_w as R_w_of_v

LOSSES = ("network", "paper")
ON_STOP = ("solve", "hold")


def model_coefficients(skin: SkinParams, R_w: float, t_s: float, loss: str = "network"
                       ) -> tuple[float, float, float]:
    """``(a, b, c)`` of eq. 10 as ``T_w(k+1) = a T_w(k) + b T_p(k) + c T_a``.

    ``b = t_s/(R_w C_w)``, ``G = 1/R_aw`` (+ ``1/(R_g + R_ag)`` for ``loss="network"``),
    ``a = 1 - b - t_s G / C_w``, ``c = t_s G / C_w``.
    """
    if loss not in LOSSES:
        raise ValueError(f"loss = {loss!r} must be one of {LOSSES}")
    G = 1.0 / skin.R_aw
    if loss == "network":
        G += 1.0 / (skin.R_g + skin.R_ag)
    b = t_s / (R_w * skin.C_w)
    c = t_s * G / skin.C_w
    return 1.0 - b - c, b, c


def check_step(skin: SkinParams, R_w: float, t_s: float, loss: str = "network") -> None:
    """Raise :class:`~thermoskin.params.ConfigError` unless eq. 10's Euler step is stable.

    The model's pole ``a = 1 - t_s (1/R_w + G)/C_w`` must lie inside the unit circle, i.e.
    ``t_s < 2 tau`` with ``tau = C_w/(1/R_w + G)`` the pipe node's time constant with the
    pump running; beyond it the predictions grow without bound (overflow, a singular QP).
    """
    a, _, _ = model_coefficients(skin, R_w, t_s, loss)
    if not abs(a) < 1.0:
        tau = t_s / (1.0 - a) if a != 1.0 else math.inf
        raise ConfigError(f"sampling.t_s = {t_s:g} s is too long for the MPC's model (eq. 10, an "
                          f"Euler step): the pipe's time constant with the pump running, "
                          f"C_w/(1/R_w + G) with R_w = {R_w:.3g} K/W, is {tau:.3g} s and t_s must "
                          f"be below twice it, {2 * tau:.3g} s (check sampling.t_s, skin.C_w, "
                          "skin.R_w_flowing, skin.A)")


def prediction_matrices(a: float, b: float, c: float, H: int
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(Phi, Gam, s)`` of the stacked prediction ``x = Phi T_w(k) + Gam u + s T_a``.

    ``x_i = T_w(k+i)``, ``i = 1..H`` (row ``i-1``); ``u_j = T_p(k+j)``, ``j = 0..H-1``:
    ``Phi_i = a^i``, ``Gam[i-1, j] = a^(i-1-j) b`` for ``j <= i-1``, ``s_i = c sum_{m<i} a^m``.
    """
    powers = a ** np.arange(H + 1, dtype=float)          # a^0 .. a^H
    Phi = powers[1:].copy()
    idx = np.arange(H)
    lag = idx[:, None] - idx[None, :]                      # (i-1) - j
    Gam = np.where(lag >= 0, b * powers[np.clip(lag, 0, H)], 0.0)
    s = c * np.cumsum(powers[:H])
    return Phi, Gam, s


def interval_ok(T_w: float, T_a: float, T_w_cmd: float, T_p_prev: float, hi0: float, hi1: float,
                hi2: float, lo0: float, lo1: float, lo2: float, s_hi: float, s_lo: float, ub: float,
                lb: float) -> bool:
    """:meth:`Mpc.feasible`'s sufficient interval bound on plain floats: ``u*`` lies within
    ``T_p_prev [s_lo, s_hi] + sum_j d_j [lo_j, hi_j]`` (``d = theta - T_p_prev``); True if
    that is inside ``[lb, ub]``. Plain Python, also compiled as it is by the sweep's batch."""
    d0 = T_w - T_p_prev
    d1 = T_a - T_p_prev
    d2 = T_w_cmd - T_p_prev
    if T_p_prev >= 0.0:
        up = T_p_prev * s_hi
        dn = T_p_prev * s_lo
    else:
        up = T_p_prev * s_lo
        dn = T_p_prev * s_hi
    if d0 >= 0.0:
        up += d0 * hi0
        dn += d0 * lo0
    else:
        up += d0 * lo0
        dn += d0 * hi0
    if d1 >= 0.0:
        up += d1 * hi1
        dn += d1 * lo1
    else:
        up += d1 * lo1
        dn += d1 * hi1
    if d2 >= 0.0:
        up += d2 * hi2
        dn += d2 * lo2
    else:
        up += d2 * lo2
        dn += d2 * hi2
    return up <= ub and dn >= lb


class Mpc:
    """The MPC of eqs. 9-11 on a persistent, warm-started daqp workspace.

    ``step(T_w, T_a, T_w_cmd)`` returns ``T_p_cmd``, the first of the ``H`` optimal inputs.
    After each step: ``status`` (daqp exit flag, 1 = optimal, also for a fast-path sample;
    0 for a held or fallback sample), ``iterations`` and ``solve_time`` (daqp's own, s; 0
    on the fast path), ``u`` (the last full input sequence), ``n_solves`` (QP calls),
    ``n_fast`` (fast-path samples), ``n_fallback``, ``n_held``. ``fast=False`` solves the
    QP every sample.
    """

    def __init__(self, skin: SkinParams, control: ControlParams, t_s: float = 1.0e-3, *,
                 R_w: float | None = None, v_on: float = 0.141, loss: str = "network",
                 cost: str | None = None, on_stop: str = "solve", fast: bool = True) -> None:
        if not (t_s > 0 and math.isfinite(t_s)):
            raise ValueError(f"Mpc: t_s = {t_s} s must be > 0")
        if control.T_p_min >= control.T_p_max:
            raise ValueError(f"Mpc: T_p_min = {control.T_p_min} must be below T_p_max = "
                             f"{control.T_p_max}")
        if on_stop not in ON_STOP:
            raise ValueError(f"Mpc: on_stop = {on_stop!r} must be one of {ON_STOP}")
        cost = control.cost if cost is None else cost
        if cost not in ("rate", "deviation", "absolute"):
            raise ValueError(f"Mpc: cost = {cost!r} must be 'rate', 'deviation' or 'absolute'")
        self.skin = skin
        self.control = control
        self.t_s = float(t_s)
        self.loss = loss
        self.cost = cost
        self.on_stop = on_stop
        self._hold_on_stop = on_stop == "hold"
        self.R_w = float(R_w) if R_w is not None else R_w_of_v(v_on, skin)
        if not (self.R_w > 0 and math.isfinite(self.R_w)):
            raise ValueError(f"Mpc: R_w = {self.R_w} K/W must be > 0")
        H = int(control.H)
        self.H = H
        check_step(skin, self.R_w, self.t_s, loss)
        self.a, self.b, self.c = model_coefficients(skin, self.R_w, self.t_s, loss)
        self.T_p_min = float(control.T_p_min)
        self.T_p_max = float(control.T_p_max)
        self.P, self.F = self._condense()
        # unconstrained optimum u* = K theta, K = -P^-1 F: the fast path and the fallback
        self._K_unc = K = -np.linalg.solve(self.P, self.F)
        self._k0 = tuple(float(x) for x in K[0])            # u*_0 on plain floats
        # one mat-vec on theta1 = (T_w, T_a, T_w_cmd, T_p_prev, 1): the box test
        # g = Gx theta1 <= 0 (rows K_i theta - T_p_max, then T_p_min - K_i theta), then q
        Gq = np.zeros((3 * H, 5))
        Gq[:H, :4] = K
        Gq[:H, 4] = -self.T_p_max
        Gq[H:2 * H, :4] = -K
        Gq[H:2 * H, 4] = self.T_p_min
        Gq[2 * H:, :4] = self.F
        self._Gq = Gq
        self._Fq = Gq[2 * H:]                               # q = Fq theta1 (a view)
        self._gq = np.zeros(3 * H)
        self._g = self._gq[:2 * H]
        self._q = self._gq[2 * H:]                          # daqp's f, a view
        self._theta1 = np.ones(5)
        # the interval bound of feasible(): column ranges of K (T_w, T_a, T_w_cmd), row sums
        s_row = K.sum(axis=1)
        self._interval = (*(float(x) for x in K[:, :3].max(axis=0)),
                          *(float(x) for x in K[:, :3].min(axis=0)),
                          float(s_row.max()), float(s_row.min()))
        self._ub_inner = self.T_p_max - 1e-9
        self._lb_inner = self.T_p_min + 1e-9
        self._theta_fast = (0.0, 0.0, 0.0, 0.0)
        self._no_sense = np.zeros(H, dtype=np.intc)         # an empty working set
        self._ws_set = False                                # daqp's working set may be non-empty
        self._u_fast = False                                # the last u is u* (not stored)
        self.fast = bool(fast)
        self._lb = np.full(H, self.T_p_min)
        self._ub = np.full(H, self.T_p_max)
        self._model = daqp.Model()
        flag, _ = self._model.setup(self.P, self._q, np.zeros((0, H)), self._ub, self._lb)
        if flag < 0:
            raise RuntimeError(f"Mpc: daqp setup failed (exit flag {flag})")
        self.T_p_prev = 0.5 * (self.T_p_min + self.T_p_max)
        self._u = np.full(H, self.T_p_prev)
        self.status = 0
        self.iterations = 0
        self.solve_time = 0.0
        self.n_solves = 0
        self.n_fast = 0
        self.n_fallback = 0
        self.n_held = 0
        self.reset()

    def _condense(self) -> tuple[np.ndarray, np.ndarray]:
        """``P`` (H x H) and ``F`` (H x 4) with ``q = F (T_w, T_a, T_w_cmd, T_p_prev)``."""
        H, W1, W2 = self.H, float(self.control.W1), float(self.control.W2)
        Phi, Gam, s = prediction_matrices(self.a, self.b, self.c, H)
        ones = np.ones(H)
        # input term rho = D u - (d_Tw_cmd T_w_cmd + d_Ta T_a + d_prev T_p_prev)
        D = np.eye(H)
        d = np.zeros((H, 4))
        if self.cost == "rate":
            D -= np.eye(H, k=-1)
            d[0, 3] = 1.0                                   # rho_0 = u_0 - T_p_prev
        elif self.cost == "deviation":
            # T_p_ss = ((1 - a) T_w_cmd - c T_a) / b
            d[:, 2] = (1.0 - self.a) / self.b
            d[:, 1] = -self.c / self.b
        P = W1 * Gam.T @ Gam + W2 * D.T @ D
        P = 0.5 * (P + P.T)
        E = np.zeros((H, 4))                                # free response minus reference
        E[:, 0] = Phi
        E[:, 1] = s
        E[:, 2] = -ones
        F = W1 * Gam.T @ E - W2 * D.T @ d
        return P, F

    def T_p_ss(self, T_w_cmd: float, T_a: float) -> float:
        """Steady-state input of the model holding ``T_w = T_w_cmd``: ``((1-a) T_w_cmd - c T_a)/b``."""
        return ((1.0 - self.a) * T_w_cmd - self.c * T_a) / self.b

    def reset(self, T_p_prev: float | None = None) -> None:
        """Forget the past: previous command ``T_p_prev`` (default mid-range), cold warm start."""
        if T_p_prev is None:
            T_p_prev = 0.5 * (self.T_p_min + self.T_p_max)
        self.T_p_prev = min(max(float(T_p_prev), self.T_p_min), self.T_p_max)
        self._u = np.full(self.H, self.T_p_prev)
        self._u_fast = False
        self.status = 0
        self.iterations = 0
        self.solve_time = 0.0
        self.n_solves = self.n_fast = self.n_fallback = self.n_held = 0
        # drop the active set of earlier solves
        self._model.update(sense=self._no_sense)
        self._ws_set = False

    @property
    def u(self) -> np.ndarray:
        """The last full input sequence (``u*`` after a fast-path sample, computed here)."""
        if self._u_fast:
            return self._K_unc @ np.array(self._theta_fast)
        return self._u

    def feasible(self, T_w: float, T_a: float, T_w_cmd: float, T_p_prev: float) -> bool:
        """Whether ``u* = K theta`` lies within eq. 11 over the whole horizon (no allocation).

        First a sufficient interval bound on plain floats: with ``d = theta - T_p_prev`` and
        the row sums ``s_i = sum_j K_ij``, ``u*_i = T_p_prev s_i + sum_{j<3} K_ij d_j`` lies
        within ``T_p_prev [min s, max s] + sum_j d_j [min_i K_ij, max_i K_ij]``; if that
        interval is inside the box by 1e-9 K (a margin over rounding), ``u*`` is. Otherwise
        the exact test, ``Gx (theta, 1) <= 0`` over all ``2 H`` rows.
        """
        return (self._in_interval(T_w, T_a, T_w_cmd, T_p_prev)
                or self._box_test(T_w, T_a, T_w_cmd, T_p_prev))

    def _in_interval(self, T_w: float, T_a: float, T_w_cmd: float, T_p_prev: float) -> bool:
        """The sufficient interval bound of ``feasible`` (:func:`interval_ok`)."""
        return interval_ok(T_w, T_a, T_w_cmd, T_p_prev, *self._interval, self._ub_inner, self._lb_inner)

    def _box_test(self, T_w: float, T_a: float, T_w_cmd: float, T_p_prev: float) -> bool:
        """The exact test ``Gx (theta, 1) <= 0``; the same mat-vec leaves ``q`` in ``_q``."""
        th = self._theta1
        th[0] = T_w
        th[1] = T_a
        th[2] = T_w_cmd
        th[3] = T_p_prev
        np.dot(self._Gq, th, out=self._gq)
        return bool(self._g.max() <= 0.0)

    def unconstrained(self, T_w: float, T_a: float, T_w_cmd: float,
                      T_p_prev: float | None = None) -> np.ndarray:
        """The unconstrained minimiser ``u* = -P^-1 q`` for a state (a copy)."""
        prev = self.T_p_prev if T_p_prev is None else T_p_prev
        return self._K_unc @ np.array([T_w, T_a, T_w_cmd, prev], dtype=float)

    def q(self, T_w: float, T_a: float, T_w_cmd: float, T_p_prev: float | None = None) -> np.ndarray:
        """The QP's linear term for a state (a copy; ``step`` uses an internal buffer)."""
        prev = self.T_p_prev if T_p_prev is None else T_p_prev
        return self.F @ np.array([T_w, T_a, T_w_cmd, prev], dtype=float)

    def solve(self, T_w: float, T_a: float, T_w_cmd: float, T_p_prev: float | None = None
              ) -> np.ndarray:
        """Solve the QP for one state and return the whole optimal ``u`` (does not advance).

        Updates the warm start and the solve attributes like ``step``.
        """
        th = self._theta1
        th[0] = T_w
        th[1] = T_a
        th[2] = T_w_cmd
        th[3] = self.T_p_prev if T_p_prev is None else T_p_prev
        np.dot(self._Fq, th, out=self._q)
        return self._qp()

    def _qp(self) -> np.ndarray:
        """The warm-started daqp solve for the ``q`` and ``theta`` in the buffers."""
        model = self._model
        model.update(f=self._q)
        x, _, flag, info = model.solve()
        self._ws_set = True
        self._u_fast = False
        self.n_solves += 1
        self.status = flag
        self.iterations = info["iterations"]
        self.solve_time = info["solve_time"]
        if flag <= 0 or not math.isfinite(x[0]):
            self.n_fallback += 1
            x = np.clip(self._K_unc @ self._theta1[:4], self.T_p_min, self.T_p_max)
            model.update(sense=self._no_sense)
        self._u = x
        return x

    def step(self, T_w: float, T_a: float, T_w_cmd: float, pump_on: bool = True) -> float:
        """One sample: ``T_p_cmd`` for the inner loop, within ``[T_p_min, T_p_max]`` (eq. 11)."""
        if (not pump_on and self._hold_on_stop) or not (
                math.isfinite(T_w) and math.isfinite(T_a) and math.isfinite(T_w_cmd)):
            self.n_held += 1
            self.status = 0
            self.iterations = 0
            return self.T_p_prev
        if not self.fast:
            x = self.solve(T_w, T_a, T_w_cmd)
        else:
            prev = self.T_p_prev
            # after a QP sample the interval bound is skipped (a bound was just active)
            if ((not self._ws_set and self._in_interval(T_w, T_a, T_w_cmd, prev))
                    or self._box_test(T_w, T_a, T_w_cmd, prev)):
                # u* within eq. 11: the optimum
                if self._ws_set:                            # as a solve would have left it
                    self._model.update(sense=self._no_sense)
                    self._ws_set = False
                k0, k1, k2, k3 = self._k0
                u0 = k0 * T_w + k1 * T_a + k2 * T_w_cmd + k3 * prev
                u0 = min(max(u0, self.T_p_min), self.T_p_max)   # rounding only
                self._theta_fast = (T_w, T_a, T_w_cmd, prev)
                self._u_fast = True
                self.n_fast += 1
                self.status = 1
                self.iterations = 0
                self.solve_time = 0.0
                self.T_p_prev = u0
                return u0
            x = self._qp()                                  # q left by the box test
        u0 = float(x[0])
        # daqp meets the bounds to its primal tolerance (1e-6): make eq. 11 exact
        u0 = min(max(u0, self.T_p_min), self.T_p_max)
        self.T_p_prev = u0
        return u0


def closed_loop_steady_state(mpc: Mpc, T_w_cmd: float, T_a: float) -> float:
    """Closed-loop steady state of ``T_w`` for an MPC on its own model (unconstrained).

    With ``T_p_cmd = k . theta`` (first row of ``-P^-1 F``) and the model
    ``T_w = a T_w + b T_p_cmd + c T_a``, ``T_p_prev = T_p_cmd``: solve the two linear
    equations. For ``cost="absolute"`` this shows the offset; for the others it is ``T_w_cmd``.
    """
    k = mpc._K_unc[0]
    # T_p = k0 T_w + k1 T_a + k2 r + k3 T_p  ->  T_p = (k0 T_w + k1 T_a + k2 r)/(1 - k3)
    # T_w (1 - a) = b T_p + c T_a
    A = np.array([[1.0 - mpc.a, -mpc.b], [-k[0], 1.0 - k[3]]])
    rhs = np.array([mpc.c * T_a, k[1] * T_a + k[2] * T_w_cmd])
    return float(np.linalg.solve(A, rhs)[0])
