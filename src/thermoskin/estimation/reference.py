"""The estimator in plain Python: the readable reference the compiled kernel is tested against.

The same algorithm as :mod:`thermoskin.estimation.kernel` (see its docstring and
``docs/model.md``), written the textbook way: matrices and vectors with ``numpy``, the paper's
observer (eq. 8) from :class:`thermoskin.estimation.observer.ThermalExchangeObserver`, the detector as a
small state machine. It is slow (tens of µs a sample) and not used at run time; the tests and
``benchmarks/patches.py`` hold the kernel to it.

The filter's state is the patch's five (``T_w, T_g, q_i, T_p, r_p``) and the pipe
thermocouple's bead ``m`` (its first-order lag: the pipe's reading is ``(1 - a) T_w + a m``,
``m <- (1 - a) T_w + a m`` a sample, ``a = exp(-t_s / tau)``), six in all, with a full 6 x 6
covariance: the kernel keeps the bead's row apart (nothing depends on it). What the estimator
learns of its sensors (each channel's reading variance, its converter's step, the tank
readings' offset against the pipe's and the pipe thermocouple's lag) is learnt here the same
way: the offset and the lag as the slow states of a two-stage filter (``V`` the state's
sensitivity to their errors, ``P_B`` their covariance).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from thermoskin.estimation.events import ContactEvent
from thermoskin.estimation.model import (
    I_DTP,
    I_Q,
    I_TG,
    I_TP,
    I_TW,
    RATE_TOL,
    ModelTables,
    build_tables,
    measurement_variance,
)
from thermoskin.estimation.observer import ThermalExchangeObserver
from thermoskin.params import Config
from thermoskin.physics.convection import FlowResistance

Array = NDArray[np.float64]


I_M = 5
"""The pipe thermocouple's bead in the reference's six states."""
NA = 6


def _unit_q() -> Array:
    mu = np.zeros(NA)
    mu[I_Q] = 1.0
    return mu


@dataclass
class _Cusum:
    """One onset CUSUM: statistic, last time it was zero, evidence sums since then, and
    ``mu``: what remains in the filter's error of a unit step of ``q_i`` at that time."""

    design: float
    g: float = 0.0
    t_zero: float = 0.0
    sum_ge: float = 0.0
    sum_gg: float = 0.0
    mu: Array = field(default_factory=_unit_q)

    def reset(self, t: float) -> None:
        self.g, self.t_zero, self.sum_ge, self.sum_gg = 0.0, t, 0.0, 0.0
        self.mu = _unit_q()


#: The kernel's fixed constants of learning (``estimation.estimator.kernel_params``).
R_RANGE = 400.0      # a learnt reading variance stays within this factor of its prior
ETA_MAX = 0.01       # a reading's largest weight in a variance's tracker
DB_MAX = 1e-3        # the most a reading moves the learnt offset, K
DT_MAX = 5e-4        # ... and the lag, s
LEARN_DELAY = 0.5    # the slow states learn from this long after the filter's start, s
RHO_ETA = 0.03       # the dispersion tracker's least step
RHOL_ETA = 0.1      # the long windows' tracker's least step
RHOP_ETA = 0.02     # the phase windows' tracker's least step
PB_N = 32            # a slow board's pipe readings kept to pair each with one at the same
#                      point of the pump's cycle (to within estimator.phase_tol)
PB_REACH = 1.0       # ... no further back than this, s
PB_START = 1.0       # ... from this long after the filter's start (the boards' rate known), s
RHO_FIRST = 16       # the dispersion is the median of the first windows' first (before the
RHO_CAP = 1e6        # third: detector.rho_prior; at most RHO_CAP: a touch among them)
RHO_PB = 0.03**2     # ... once the offset's variance is below this, K^2,
RHO_PT = 0.01**2     # and the lag's below this, s^2
SWITCH_LEAK = 0.1    # the pump-cycle correction leaks at this share of its weight (slow states)
SWITCH_SETTLE = 10.0  # ... and learns nothing this long after a release, s
RHO_MOVED = (0.02, 0.005)  # a window over which the offset (K) or the lag (s) moved this much,
RHO_EARLY = 10.0             # in the filter's first seconds: not taken
RHO_SETTLE = 0.5     # its windows begin this long after a release, s
IRATE_TAU = 10.0     # the information rate's time constant, s
SLOW_WINDOW = 0.4    # the slow states' window, s
SLOW_HOLD_CU = 0.25  # the slow states do not learn while an onset CUSUM is above this share of h
SLOW_TS_MAX = 0.0100001  # ... and are learnt from logs of 100 Hz and faster only, s
QFINE_SD = 2.0       # ... and while both converter steps are at most this times the T_w reading's sd
R_SLOT = 0.5         # the pipe reading variance's steps are gathered in slots this long, s
FAST_READINGS = 200.0  # ... learnt from pipe readings this many a second or more
N_SLOTS = 4          # and taken into it N_SLOTS - 1 slots late (dropped at a detection)
ARM_TAU = 1.0        # the arming's mean of the T_w readings: a first-order lag this long, s
ARM_STEADY = 0.2     # armed also once that mean held within this share of arm_band of one value
ARM_HOLD = 3.0       # ... for this many times t_arm
PAIR_FLOOR = 0.5     # a warm touch's evidence above this share of h pairs with a negative onset
ASL_TAU = 0.5        # the air estimate's rate is its mean over about this long, s


def fgcd(g: float, d: float) -> float:
    """Euclid's greatest common divisor of two positive numbers, to within 1e-9."""
    a, b = (g, d) if g > d else (d, g)
    for _ in range(64):
        if b <= 1e-9:
            break
        a, b = b, a % b
    return a


def _track(r: float, a: float, b: float, eta: float) -> float:
    """A dispersion tracker's step: up by ``eta`` in its logarithm where the window's ``a²/b``
    is above ``r`` times chi2(1)'s median, else down; at least 1e-3 (kernel: ``_track``)."""
    return max(1e-3, r * math.exp(eta if 0.4549 * r * b < a * a else -eta))


@dataclass
class ReferenceEstimator:
    """One patch: eq. 8, the Kalman filter on the network, the detector (plain Python)."""

    cfg: Config
    t_s: float
    #: False: the filter alone, never a contact (the kernel's ``PR_TRACE``; the re-dating's
    #: detection-free filter, with :attr:`updates` recorded)
    detect: bool = True
    tables: ModelTables = field(init=False)

    def __post_init__(self) -> None:
        self.tables = build_tables(self.cfg, self.t_s, (0.0, self.cfg.pump.v_on))
        self.eq8 = ThermalExchangeObserver(self.cfg.skin, self.cfg.observer, self.t_s)
        self.R_w = FlowResistance(self.cfg.skin)
        d, es, sn = self.cfg.detector, self.cfg.estimator, self.cfg.sensor
        self.n_warm = max(2, round(d.t_warmup / self.t_s))
        self.stride = max(1, math.ceil(self.n_warm / 256))
        self.n_arm = max(1, round(d.t_arm / self.t_s))
        self.max_gap = max(1, round(es.max_gap_s / self.t_s))
        self.n_max = max(1, round(d.max_contact_s / self.t_s))
        eta = min(0.5, 2.0 * self.t_s / d.tau_sigma)
        self.up, self.down = math.exp(0.5 * eta), math.exp(-0.5 * eta)
        self.a_b = min(1.0, 1.25 * self.t_s / d.tau_baseline)
        self.a_lvl = min(1.0, self.t_s / d.tau_level)
        self.t_amb_hold = d.t_air + sn.lag_T_a
        self.vsw = 0.29 if self.t_s > 1.5 * self.cfg.sampling.t_s else 0.0
        # what is learnt of the sensors: priors (the configuration)
        self.R0 = {ch: measurement_variance(self.cfg, ch) for ch in ("T_w", "T_p", "T_a")}
        self.q_fine = QFINE_SD * math.sqrt(self.R0["T_w"])
        self.R = dict(self.R0)
        self.r_slots, self.r_slot, self.t_rslot = [0.0] * N_SLOTS, 0, 0.0
        self.r_count = dict.fromkeys(self.R0, 0)
        self.quantum = {ch: 1e300 for ch in self.R0}
        self.last_y = {ch: math.nan for ch in self.R0}
        self.prev_y = {"T_p": math.nan, "T_a": math.nan}
        self.offsets = (sn.offset_T_w, sn.offset_T_p, sn.offset_T_a)
        #: the learning on (off: the re-dating's filter holds what it is given)
        self.learn = True
        self.b_hat, self.tau = 0.0, sn.lag_T_w  # the slow states: offset (K), lag (s)
        slow_ok = self.t_s <= SLOW_TS_MAX  # (kernel: the estimator's PR_PB0, PR_PT0)
        self.P_B = np.diag([sn.offset_sd**2, sn.lag_sd**2]) if slow_ok else np.zeros((2, 2))
        self.slow_prior = self.P_B.diagonal() > 0  # a state with no prior is not let go
        self.window = np.zeros(4)  # the slow states' window: sum s e/S, s^2/S (offset, lag)
        self.t_window = 0.0
        self.t_init = -1e300
        self.rho = self.cfg.detector.rho_prior if self.cfg.detector.rho_window > 0 else 1.0
        self.rho_s, self.rho_l = self.rho, 1.0  # the short and the long windows' (rho the larger)
        self.rho_n, self.rho_first = 0, []
        self.rho_ln, self.rho_lwin = 0, np.zeros(3)  # the long window: sums of g e/S, g^2/S, time
        self.rho_lfrom = (0.0, 0.0)
        self.rho_from = (0.0, 0.0)  # the slow states where the window began
        self.rho_win, self.t_rho = np.zeros(2), 0.0
        # the pump's phases: their tracker, the windows seen, the present one's sums, and
        # whether no contact has been seen in it
        self.rho_p, self.rho_pn, self.rho_pwin, self.rho_pok = 1.0, 0, np.zeros(2), False
        self.info_rate = 0.0
        self.w1 = self.w2 = 0.0  # the model's pipe rate through the lag once and twice
        self.events: list[ContactEvent] = []
        self.ready = False
        self.x = np.zeros(NA)
        self.P = np.zeros((NA, NA))
        self.V = np.zeros((NA, 2))  # the state's sensitivity to errors of (offset, lag)
        self.xa = np.zeros(2)
        self.Pa = np.zeros((2, 2))
        self.kappa, self.rate, self.t_last_w = 1.0, 0.0, -1e300
        self.t_last_p = self.t_last_a = -1e300
        self.rate_h, self.h = 0.0, math.nan  # the onset threshold and the rate it is for
        self.t_fresh_w = -1e300  # the last pipe reading flagged fresh, NaN or not
        self.gap_run = 0
        self.iv_prev = 0
        self.phase, self.ph_dir, self.ph_prev = 0, 0, 0
        #: a slow board's last fresh T_w readings: (time, reading, ph_dir, phase s, ph_prev s)
        self.phase_readings: deque[tuple[float, float, int, float, float]] = deque(maxlen=PB_N)
        self.tpl = np.zeros((2, max(1, self.cfg.estimator.switch_bins)))
        self.cmd = math.nan
        self.armed, self.n_in = False, 0
        self.arm_mean, self.arm_ref, self.n_steady = math.nan, math.nan, 0
        self.updates: list[tuple[int, float, float, Array, bool, Array]] | None = None
        # with updates recorded: also each pump-switch correction, as (-1, c, 0, K, False, h),
        # x_Tw += c (x_Tp - x_Tw) (the re-dating's signatures carry it)
        self.record_switches = False
        self.mode, self.n_seen, self.warm = "warm", 0, []
        self.b = 0.0
        self.b_moved = 0.0  # the baseline's moves with the slow states, summed
        self.cusums = [_Cusum(d.dq_design), _Cusum(-d.dq_design),
                       _Cusum(d.dq_design_hi), _Cusum(-d.dq_design_hi),
                       _Cusum(d.dq_design_lo), _Cusum(-d.dq_design_lo)]
        # the onset dating's buffer: [time of the last reading pooled, sum g e/S, sum g²/S]
        self.glr: deque[list[float]] = deque(maxlen=256)
        self.glr_t0 = 0.0  # time of the first reading pooled in the newest entry
        self.t_rel, self.last_sign = -1e300, 0.0
        self.t_xp = -1e300  # when a positive design CUSUM was last above half the threshold
        self.t_air, self.air_up, self.air_down = -1e300, 0.0, 0.0
        self.t_door = -1e300  # the start of the last sudden change of the air (not its renewals)
        self.air_held = False
        self.air_rate, self.xa_last, self.t_air_last = 0.0, 0.0, None
        self.contact = 0
        self.dq = 0.0

    @property
    def a(self) -> float:
        """The bead's weight a sample, ``exp(-t_s / tau)`` (0 without a lag)."""
        return math.exp(-self.t_s / self.tau) if self.tau > 0 else 0.0

    def hold(self, R: dict[str, float], b_hat: float, tau: float) -> None:
        """Hold what is learnt of the sensors at these values (the re-dating's filter)."""
        self.learn = False
        self.rho = self.rho_s = self.rho_l = self.rho_p = 1.0
        self.R0 = dict(R)
        self.b_hat, self.tau = b_hat, tau
        self.P_B = np.zeros((2, 2))

    # ---------------------------------------------------------------- the sensors
    def _coarse(self) -> bool:
        """A converter step of T_w or T_p known and coarser than the slow states learn from."""
        qw, qp = self.quantum["T_w"], self.quantum["T_p"]
        return self.q_fine < qw < 1e299 or self.q_fine < qp < 1e299  # either alone

    def _slow_learnt(self) -> bool:
        """The slow states' variances below RHO_PB and RHO_PT (kernel: ``_slow_learnt``)."""
        return bool(self.P_B[0, 0] <= RHO_PB and self.P_B[1, 1] <= RHO_PT)

    def _r_step(self, ch: str, up: bool, eta: float) -> None:
        """A reading variance's median tracker (kernel: ``_r_step``)."""
        r = self.R[ch] * (1 + eta) if up else self.R[ch] / (1 + eta)
        q = self.quantum[ch]
        lo = max(self.R0[ch] / R_RANGE, q * q / 12 if q < 1e299 else 0.0)
        self.R[ch] = min(max(r, lo), self.R0[ch] * R_RANGE)

    def _r_slots(self, t: float) -> None:
        """The oldest slot of the pipe reading variance's steps into it; a fresh slot begun."""
        k = (self.r_slot + 1) % N_SLOTS
        if self.r_slots[k] != 0:
            q = self.quantum["T_w"]
            lo = max(self.R0["T_w"] / R_RANGE, q * q / 12 if q < 1e299 else 0.0)
            self.R["T_w"] = min(max(self.R["T_w"] * math.exp(self.r_slots[k]), lo), self.R0["T_w"] * R_RANGE)
        self.r_slots[k] = 0.0
        self.r_slot, self.t_rslot = k, t

    def _eta(self, ch: str, dt: float) -> float:
        """A reading's weight in ``ch``'s variance tracker: at first ``1/(n + 4)`` (a running
        median), then ``min(0.01, dt/tau_noise)`` (kernel: ``_eta``)."""
        n = self.r_count[ch]
        self.r_count[ch] = n + 1
        return max(min(ETA_MAX, dt / self.cfg.estimator.tau_noise), 1.0 / (n + 4.0))

    def _sensor(self, ch: str, y: float, dt: float) -> None:
        """A fresh reading of ``ch``: its second difference (the tank's, the air's variance)
        and its converter's step (the changes' greatest common divisor)."""
        if not math.isfinite(y):
            return
        learn_r = self.learn and self.cfg.estimator.tau_noise > 0
        if ch != "T_w":
            y1, y2 = self.last_y[ch], self.prev_y[ch]
            self.prev_y[ch] = y1
            if learn_r and y1 == y1 and y2 == y2:
                d2 = y - 2 * y1 + y2
                self._r_step(ch, d2 * d2 > 6 * 0.4549 * self.R[ch], self._eta(ch, dt))
        d = abs(y - self.last_y[ch])
        if d > 1e-9:
            g = self.quantum[ch]
            self.quantum[ch] = d if g >= 1e299 else fgcd(g, d)
        self.last_y[ch] = y

    def _noise_phase(self, t: float, y: float) -> None:
        """A slow board's pipe reading variance: the change since the last reading (within
        ``PB_REACH``) at the same point of the pump's cycle (its last switch's direction, the time
        since it, the phase before it, to within ``estimator.phase_tol``) is ``2 R`` in variance; its median
        tracker (kernel: ``_noise_phase``)."""
        if not math.isfinite(y):
            return
        sig = (self.ph_dir, self.phase * self.t_s, self.ph_prev * self.t_s)
        tol = self.cfg.estimator.phase_tol
        for tj, yj, dj, pj, vj in reversed(self.phase_readings):
            if t - tj > PB_REACH:
                break
            if dj == sig[0] and abs(pj - sig[1]) <= tol and abs(vj - sig[2]) <= tol:
                d = y - yj
                self._r_step("T_w", d * d > 2 * 0.4549 * self.R["T_w"],
                             self._eta("T_w", t - self.t_last_w))
                break
        self.phase_readings.append((t, y, *sig))

    # ---------------------------------------------------------------- the filter
    def _update(self, i: int, y: float, slow: bool, eta: float) -> tuple[float, float]:
        """Scalar update with the pipe's reading (``i`` = 0: its bead, ``(1 - a) T_w + a m``) or the
        tank's (3); returns the evidence ``(g e / S, g² / S)``. Where :attr:`updates` is a list,
        each update is appended to it as ``(i, e, κ² S, K, evidence, h)``. The slow states
        (offset, lag) learn from it where ``slow``; the pipe's reading variance where ``eta``."""
        a = self.a
        h = np.zeros(NA)
        C = np.zeros(2)
        if i == I_TW:
            h[I_TW], h[I_M] = 1.0 - a, a
            C[1] = -self.w2  # the lag's derivative: -s/(tau s + 1)^2 of the pipe's temperature
            qw = self.quantum["T_w"]  # at least its converter step's q²/12, learnt or not,
            # once the warm-up has seen the readings (kernel: _update)
            R = max(self.R["T_w"], qw * qw / 12.0 if qw < 1e299 and self.mode != "warm" else 0.0)
        else:
            h[I_TP] = 1.0
            C[0] = 1.0  # the offset of the tank's readings
            R = self.R["T_p"]
        s = C - h @ self.V
        # (not with a coarse converter: the slow states are not learnt from its readings, nor
        # their uncertainty taken into the innovations' variance)
        sps = 0.0 if self._coarse() else float(s @ self.P_B @ s)
        e = y - h @ self.x
        k2 = self.kappa**2
        man = False
        if i == I_TP:
            man = abs(e) > self.cfg.estimator.tank_jump * self.kappa * math.sqrt(h @ self.P @ h + R + sps)
            if man:  # the tank manoeuvres: its slope let go, no evidence about q_i
                self.P[I_TP, I_TP] += e * e
                self.P[I_DTP, I_DTP] += (e / self.cfg.estimator.tank_jump_s) ** 2
        r = self.P @ h  # the reading's covariance with the state
        S = float(h @ r) + R
        Sf = S + sps
        ge = gg = 0.0
        if not man:
            g = r[I_Q] / self.P[I_Q, I_Q] if self.P[I_Q, I_Q] > 0 else 0.0
            ge, gg = g * e / (k2 * Sf), g * g / (k2 * Sf)
            self.kappa *= self.up if abs(e) > 0.6745 * self.kappa * math.sqrt(Sf) else self.down
            if self.kappa < 1.0 and self.learn and self._coarse():
                self.kappa = 1.0  # (a coarse step's innovations: mostly nought, their median no scale)
            if eta > 0 and i == I_TW:  # a step of its variance's tracker, into this slot
                self.r_slots[self.r_slot] += (1 if e * e > 0.4549 * Sf else -1) * math.log(1 + eta)
        K = r / S
        if self.updates is not None:
            self.updates.append((i, e, k2 * Sf, K, not man, h))
        for c in self.cusums:  # the step signatures: mu <- (I - K h') mu
            c.mu = c.mu - K * (h @ c.mu)
        self.x = self.x + K * e
        self.V = self.V + np.outer(K, s)  # V <- V - K (h' V - C)
        if slow and sps > 0 and not man and e * e < 64 * Sf:  # (an outlier: no evidence)
            self.window += (s[0] * e / Sf, s[0] ** 2 / Sf, s[1] * e / Sf, s[1] ** 2 / Sf)
            hB = self.P_B @ s
            kB = hB / Sf
            dB = kB * e
            f = 1.0  # a reading moves them by at most DB_MAX, DT_MAX (its share of one)
            if abs(dB[0]) > DB_MAX:
                f = DB_MAX / abs(dB[0])
            if abs(dB[1]) > DT_MAX:
                f = min(f, DT_MAX / abs(dB[1]))
            dB = dB * f
            self.P_B = self.P_B - f * np.outer(kB, hB)
            self.b_hat += dB[0]
            tau = min(max(self.tau + dB[1], 0.0), max(self.cfg.estimator.lag_max, self.cfg.sensor.lag_T_w))
            dB[1] = tau - self.tau
            self.tau = tau
            self.b -= self.V[I_Q] @ dB  # the no-touch baseline moves with the estimate
            self.b_moved -= self.V[I_Q] @ dB  # (the warm-up's values kept less it)
            self.x = self.x - self.V @ dB
        self.P = self.P - np.outer(K, r)
        return ge, gg

    def _air_changed(self, t: float) -> None:
        """A sudden change of the air at ``t``; where no hold is on, a door's start."""
        if not t - self.t_air < self.t_amb_hold:
            self.t_door = t
        self.t_air = t

    def _ambient(self, t: float, y: float) -> None:
        idx = self.tables.amb_idx
        S = self.Pa[idx, idx] + self.R["T_a"]
        e = y - self.xa[idx]
        z = e / math.sqrt(S)
        self.air_up = max(0.0, self.air_up + z - 1.0)
        self.air_down = max(0.0, self.air_down - z - 1.0)
        q = self.quantum["T_a"]
        if (self.air_up > 8.0 or self.air_down > 8.0) and not (q < 1e299 and abs(e) < 2.0 * q):
            self.Pa[0, 0] += 1.0
            S = self.Pa[idx, idx] + self.R["T_a"]
            self._air_changed(t)
            self.air_up = self.air_down = 0.0
        K = self.Pa[:, idx] / S
        self.xa = self.xa + K * e
        self.Pa = self.Pa - np.outer(K, self.Pa[idx, :])
        # the air's rate over about ASL_TAU s: moving faster than air_rate, a sudden change too
        if self.t_air_last is not None and t > self.t_air_last:
            dt = t - self.t_air_last
            w = min(1.0, dt / ASL_TAU)
            self.air_rate += w * ((self.xa[0] - self.xa_last) / dt - self.air_rate)
            q = self.quantum["T_a"]
            lim = max(self.cfg.detector.air_rate, 2.0 * q / ASL_TAU if q < 1e299 else 0.0)
            if self.cfg.detector.air_rate > 0 and abs(self.air_rate) > lim:
                self._air_changed(t)
        self.xa_last, self.t_air_last = self.xa[0], t

    def _slow_window(self) -> None:
        """A window's evidence says a slow state is off by more than 3 sd: let its variance go
        to the square of that difference (kernel: ``_slow_window``)."""
        tau_max = max(self.cfg.estimator.lag_max, self.cfg.sensor.lag_T_w)
        for j, k, cap in ((0, 0, 1.0), (2, 1, tau_max**2)):
            A, Bw = self.window[j], self.window[j + 1]
            if (self.slow_prior[k] and self.rate >= FAST_READINGS and Bw > 0 and 9 * Bw < A * A
                    and min((A / Bw) ** 2, cap) > self.P_B[k, k]):
                self.P_B[k, k] = min((A / Bw) ** 2, cap)
                self.P_B[0, 1] = self.P_B[1, 0] = 0.0
        self.window[:] = 0.0

    def _dispersion(self, t: float, ge: float, gg: float, on: bool) -> None:
        """The onset evidence's dispersion and the information rate (kernel: ``_dispersion``)."""
        rw = self.cfg.detector.rho_window
        if self.phase == 0:  # the pump switched: the phase window that ended (a fast board's)
            A, Bw = self.rho_pwin
            if (self.rho_pok and Bw > 0 and self.rate >= FAST_READINGS
                    and self.cfg.detector.rho_phases):
                self.rho_pn += 1
                self.rho_p = _track(self.rho_p, A, Bw, max(RHOP_ETA, 1.0 / self.rho_pn))
                self.rho = max(self.rho_s, self.rho_l, self.rho_p)
            self.rho_pwin[:] = 0.0
            self.rho_pok = True
        if not on:
            self.rho_win[:] = 0.0
            self.t_rho = t
            self.rho_from = (self.b_hat, self.tau)
            self.rho_pok = False
            return
        self.rho_pwin += (ge, gg)
        self.info_rate += min(1.0, self.t_s / IRATE_TAU) * (gg * self._irho() / self.t_s - self.info_rate)
        self.rho_win += (ge, gg)
        self.rho_lwin += (ge, gg, self.t_s)  # (over contacts: while none is seen)
        rl = self.cfg.detector.rho_window_long
        if rl > 0 and self.rho_lwin[2] >= rl:  # the long window: its own tracker, from 1
            A, Bw, _ = self.rho_lwin
            if (Bw > 0 and not self._moved(t, self.rho_lfrom) and self.rate >= FAST_READINGS
                    and self._coarse()):
                eta = max(RHOL_ETA, 1.0 / (self.rho_ln + 1))
                self.rho_ln += 1
                self.rho_l = _track(self.rho_l, A, Bw, eta)
                self.rho = max(self.rho_s, self.rho_l, self.rho_p)
            self.rho_lwin[:] = 0.0
            self.rho_lfrom = (self.b_hat, self.tau)
        if t - self.t_rho >= rw:
            A, Bw = self.rho_win
            if Bw > 0 and not self._moved(t, self.rho_from):  # (slow states moved: not taken)
                self.rho_n += 1
                if self.rho_n <= RHO_FIRST:  # the first windows: their median (from the third)
                    self.rho_first.append(A * A / (0.4549 * Bw))
                    if self.rho_n >= 3:
                        self.rho_s = min(max(1e-3, float(np.median(self.rho_first))), RHO_CAP)
                else:  # then a tracker of it
                    self.rho_s = _track(self.rho_s, A, Bw, max(RHO_ETA, 1.0 / self.rho_n))
                self.rho = max(self.rho_s, self.rho_l, self.rho_p)
            self.rho_win[:] = 0.0
            self.t_rho = t
            self.rho_from = (self.b_hat, self.tau)

    def _moved(self, t: float, start: tuple[float, float]) -> bool:
        """The slow states moved over a window (from ``start``) in the filter's first seconds."""
        return t - self.t_init < RHO_EARLY and (abs(self.b_hat - start[0]) > RHO_MOVED[0]
                                                or abs(self.tau - start[1]) > RHO_MOVED[1])

    def _irho(self) -> float:
        return 1.0 / max(1.0, self.rho / self.cfg.detector.rho_deadband)

    # ---------------------------------------------------------------- one sample
    def step(self, t: float, T_w: float, T_p: float, v: float, T_a: float,
             T_w_cmd: float = math.nan, fresh: int = 7, drive: float = math.nan) -> int:
        self.q_i_hat = self.eq8.step(T_w, T_p, v, T_a)
        tb = self.tables
        iv_old = None  # a switch whose correction waits for this sample's pipe reading
        if v == v:
            iv = tb.index(v)
            if iv != self.iv_prev and self.vsw > 0 and self.ready:
                if fresh & 1 and math.isfinite(T_w) and 1.5 * self.t_s < t - self.t_fresh_w < 1e299:
                    iv_old = self.iv_prev  # a slow board's reading (the last rows ago), before the switch
                else:
                    self._switch_correction(self.iv_prev, iv)
            if iv != self.iv_prev:
                self.ph_prev, self.phase = self.phase, 0
                self.ph_dir = 0 if (self.R_w(tb.v_values[iv]) < self.R_w(tb.v_values[self.iv_prev])) else 1
            else:
                self.phase += 1
            self.iv_prev = iv
        else:
            iv = self.iv_prev
            self.phase += 1
        if fresh & 1:
            self.t_fresh_w = t
        self.gap = not (math.isfinite(T_w) and math.isfinite(T_p) and math.isfinite(T_a) and v == v)
        ge = gg = 0.0
        self.q_prior = self.x[I_Q]
        # the sensors' own figures (raw readings), then the configured offsets off the readings
        if fresh & 1:
            if (self.learn and self.cfg.estimator.tau_noise > 0 and self.cfg.estimator.phase_tol > 0
                    and self.vsw == 0 and self.rate < FAST_READINGS
                    and self.ready and t - self.t_init >= PB_START and v == v
                    and self.mode != "contact" and t - self.t_rel >= self.cfg.detector.t_settle):
                self._noise_phase(t, T_w)
            self._sensor("T_w", T_w, 0.0)
        if fresh & 2:
            self._sensor("T_p", T_p, t - self.t_last_p)
        if fresh & 4:
            self._sensor("T_a", T_a, t - self.t_last_a)
        T_w_raw = T_w
        T_w, T_p, T_a = T_w - self.offsets[0], T_p - self.offsets[1], T_a - self.offsets[2]
        learn_r = (self.learn and self.cfg.estimator.tau_noise > 0 and self.mode != "contact"
                   and t - self.t_rel >= self.cfg.detector.t_settle and self.rate >= FAST_READINGS)
        if self.learn and t - self.t_rslot >= R_SLOT:
            self._r_slots(t)
        slow = (self.learn and self.mode != "contact" and t - self.t_rel >= self.cfg.detector.t_settle
                and t - self.t_init >= LEARN_DELAY and self.quantum["T_w"] <= self.q_fine
                and self.quantum["T_p"] <= self.q_fine)
        # nor while the detector's evidence of an onset builds (the window goes on without them)
        learn_slow = slow and not (self.mode == "idle"
                                   and any(c.g > SLOW_HOLD_CU * self.h for c in self.cusums))
        if not self.ready:
            if self.gap:
                return self.contact
            self._init(T_w, T_p - self.b_hat, T_a)
            self.t_init = self.t_last_p = self.t_last_a = t
        else:
            if fresh & 4 and math.isfinite(T_a):
                self._ambient(t, T_a)
                self.t_last_a = t
                if self.t_air == t and self.mode == "contact" and t - self.detected < 1.0:
                    self.mode, self.contact = "idle", 0
                    self.x[I_Q] = self.b
                    self.V[I_Q] = 0.0
                    self._reset_cusums(t)
            if fresh & 1 and math.isfinite(T_w):
                y = T_w
                nph = self.cfg.estimator.switch_bins
                if nph > 0:  # the pump-cycle correction (kernel: PR_NPH)
                    j = (self.ph_dir, min(self.phase, nph - 1))
                    corr = self.tpl[j]
                    # (against the predicted reading, from fast boards, once the slow states
                    # are learnt and while they learn: the kernel's rule)
                    w = self.cfg.estimator.switch_learn
                    if self.slow_prior.any():
                        if (learn_slow and self.rate >= FAST_READINGS and self._slow_learnt()
                                and t - self.t_init >= RHO_EARLY and t - self.t_rel >= SWITCH_SETTLE):
                            a = self.a
                            m = T_w - (1.0 - a) * self.x[I_TW] - a * self.x[I_M]
                            self.tpl[j] = corr + w * (m - corr) - w * SWITCH_LEAK * corr  # (a prior)
                    elif self.mode != "contact" and self.learn:  # nothing learnt of the sensors
                        self.tpl[j] = corr + w * (T_w - self.x[I_TW] - corr)
                    y = T_w - corr
                eta = min(ETA_MAX, (t - self.t_last_w) / self.cfg.estimator.tau_noise) if learn_r else 0.0
                a, c = self._update(I_TW, y, learn_slow, eta)
                ge, gg = ge + a, gg + c
                self.gap_run = 0
                dt = t - self.t_last_w
                if dt > 0:
                    self.rate = 1 / dt if self.rate == 0 else self.rate + 0.05 * (1 / dt - self.rate)
                    self._threshold()
                self.t_last_w = t
            else:
                self.gap_run += 1
            if fresh & 2 and math.isfinite(T_p):
                a, c = self._update(I_TP, T_p - self.b_hat, learn_slow, 0.0)
                ge, gg = ge + a, gg + c
                self.t_last_p = t
        if iv_old is not None:
            self._switch_correction(iv_old, iv)
        if slow and t - self.t_window >= SLOW_WINDOW:
            self._slow_window()
            self.t_window = t
        elif not slow:
            self.window[:] = 0.0
            self.t_window = t
        if self.cfg.detector.rho_window > 0 and self.learn:
            self._dispersion(t, ge, gg, not self.gap and self.mode != "contact"
                             and t - self.t_air >= self.t_amb_hold and t - self.t_rel >= RHO_SETTLE
                             and (self._slow_learnt() or self._coarse()))
        self.sd = math.sqrt(self.P[I_Q, I_Q]) if self.ready else math.nan
        if T_w_cmd == T_w_cmd:
            if self.cmd == self.cmd and abs(T_w_cmd - self.cmd) > 1e-9:
                self.P[I_DTP, I_DTP] += ((T_w_cmd - self.cmd) / 2.0) ** 2
                self._reset_cusums(t)
            self.cmd = T_w_cmd
        if not self.armed:
            if T_w_cmd != T_w_cmd:
                self.armed = True
            elif math.isfinite(T_w_raw):
                self._arm(T_w_raw, T_w_cmd)
            else:
                self.n_in = 0
        code = 0
        if self.gap:
            code = self.contact
        elif self.armed and self.detect:
            code = self._detect(t, ge, gg)
        else:
            self.dq = self.x[I_Q] - self.b
        # predict: the bead (from the pipe at the sample's start), then the model
        self.xa = tb.Phi_a @ self.xa
        self.Pa = tb.Phi_a @ self.Pa @ tb.Phi_a.T + tb.Q_a
        # (and through the air's hold from a door's start, armed: the sheet takes a heat no
        # model has, which the estimate follows as in a contact)
        door = bool(self.cfg.detector.door_follow) and self.armed and t - self.t_door < self.t_amb_hold
        Q = tb.Q[iv] if self.mode == "contact" or door else tb.Q_idle[iv]
        u = np.array([self.xa[0], drive if drive == drive else 0.0])
        a = self.a
        F = np.zeros((NA, NA))
        F[:5, :5] = tb.Phi[iv]
        F[I_M, I_TW], F[I_M, I_M] = 1.0 - a, a
        QA = np.zeros((NA, NA))
        QA[:5, :5] = Q
        x0 = self.x[I_TW]
        self.x = F @ self.x
        self.x[:5] += tb.Gam[iv] @ u
        self.P = F @ self.P @ F.T + QA
        self.V = F @ self.V
        for c in self.cusums:
            c.mu = F @ c.mu
        if self.P_B[0, 0] > 0:
            self.P_B[0, 0] += self.cfg.estimator.offset_drift * self.t_s
        if self.P_B[1, 1] > 0:
            self.P_B[1, 1] += self.cfg.estimator.lag_drift * self.t_s
        rate = min(max((self.x[I_TW] - x0) / self.t_s, -1e3), 1e3)  # a pipe moves slower than 1000 K/s
        self.w1 = a * self.w1 + (1 - a) * rate
        self.w2 = a * self.w2 + (1 - a) * self.w1
        if self.gap_run > self.max_gap:
            self.ready = False
        return code

    def _switch_correction(self, iv_old: int, iv: int) -> None:
        """The pump switched within the last interval of a coarse log (kernel: ``_switch_correction``)."""
        vs = self.tables.v_values
        share = (1 / self.R_w(vs[iv]) - 1 / self.R_w(vs[iv_old])) * self.t_s / self.cfg.skin.C_w
        dT = (self.x[I_TP] - self.x[I_TW]) * share
        self.x[I_TW] += 0.5 * dT
        self.V[I_TW] += 0.5 * share * (self.V[I_TP] - self.V[I_TW])
        self.P[I_TW, I_TW] += (self.vsw * dT) ** 2
        if self.updates is not None and self.record_switches:
            self.updates.append((-1, 0.5 * share, 0.0, np.zeros(NA), False, np.zeros(NA)))

    def _init(self, T_w: float, T_p: float, T_a: float) -> None:
        Rg, Rag = self.cfg.skin.R_g, self.cfg.skin.R_ag
        R, Rp = self.R["T_w"], self.R["T_p"]
        self.x = np.array([T_w, (T_w / Rg + T_a / Rag) / (1 / Rg + 1 / Rag), 0.0, T_p, 0.0, T_w])
        self.P = np.diag([R, R, 1.0, Rp, 1e-4, R])
        self.P[I_TW, I_M] = self.P[I_M, I_TW] = R  # the bead at the pipe's reading
        self.V = np.zeros((NA, 2))
        self.V[I_TP, 0] = 1.0  # the tank's state is its reading: its offset's error is all in it
        self.w1 = self.w2 = 0.0
        self.xa = np.array([T_a, T_a])
        self.Pa = np.full((2, 2), self.R["T_a"])
        self.t_air_last = None  # the air's rate from the next reading
        for c in self.cusums:
            c.mu = _unit_q()
        self.ready = True
        self.gap_run = 0
        self._threshold()

    def _threshold(self) -> None:
        """``h = max(h_on + h_rate ln(readings/s), h_min)``, renewed when the rate has moved
        by more than :data:`~thermoskin.estimation.model.RATE_TOL` (relative) since."""
        d = self.cfg.detector
        rate = self.rate if self.rate > 0 else 1 / self.t_s
        if self.rate_h > 0 and abs(rate - self.rate_h) <= RATE_TOL * self.rate_h:
            return
        self.rate_h = rate
        self.h = max(d.h_on + d.h_rate * math.log(max(rate, 1.0)), d.h_min)

    def _arm(self, T_w_raw: float, T_w_cmd: float) -> None:
        """Armed once the T_w readings' mean (a first-order lag of ARM_TAU) has held within
        arm_band of the command for t_arm, or within ARM_STEADY x arm_band of one value for
        ARM_HOLD x t_arm (a skin settled off its command)."""
        band = self.cfg.detector.arm_band
        w = min(1.0, self.t_s / ARM_TAU)
        m = T_w_raw if math.isnan(self.arm_mean) else self.arm_mean + w * (T_w_raw - self.arm_mean)
        self.arm_mean = m
        self.n_in = self.n_in + 1 if abs(m - T_w_cmd) <= band else 0
        if not math.isnan(self.arm_ref) and abs(m - self.arm_ref) <= ARM_STEADY * band:
            self.n_steady += 1
        else:
            self.arm_ref, self.n_steady = m, 0
        self.armed = self.n_in >= self.n_arm or self.n_steady >= ARM_HOLD * self.n_arm

    def _reset_cusums(self, t: float) -> None:
        for c in self.cusums:
            c.reset(t)

    # ---------------------------------------------------------------- the detector
    def _detect(self, t: float, ge: float, gg: float) -> int:
        d = self.cfg.detector
        q, sq = self.x[I_Q], math.sqrt(self.P[I_Q, I_Q])
        if self.mode == "warm":
            if self.n_seen % self.stride == 0 and len(self.warm) < 256:
                self.warm.append(q - self.b_moved)
            self.n_seen += 1
            self.b += (q - self.b) / self.n_seen
            if self.n_seen >= self.n_warm:
                # their median as they would stand now, the slow states' moves since included
                self.b = float(np.median(self.warm)) + self.b_moved
                self.mode = "idle"
                self._reset_cusums(t)
            self.dq = q - self.b
            return 0
        if self.mode == "idle":
            h = self.h
            if d.onset_glr and (gg > 0 or self.t_last_w == t):  # a pipe reading, for dating
                if self.glr and t - self.glr_t0 < d.onset_glr_pool:
                    e = self.glr[-1]
                    e[0], e[1], e[2] = t, e[1] + ge, e[2] + gg
                else:
                    self.glr.append([t, ge, gg])
                    self.glr_t0 = t
            fire, best, quiet = None, 0.0, True
            if self.air_held and t - self.t_air >= self.t_amb_hold:
                self.air_held = False  # the hold over: the CUSUMs start again
                self._reset_cusums(t)
            irho = self._irho()
            for k, c in enumerate(self.cusums):
                g = c.g + (c.design * ge - 0.5 * c.design**2 * gg) * irho  # the dispersion weighs it
                if (t - self.t_rel < d.t_refractory and self.last_sign != 0
                        and np.sign(c.design) != self.last_sign):
                    g = 0.0
                if g <= 0:  # the zero is dated at a pipe reading or where the evidence fell
                    if c.g > 0 or self.t_last_w == t:
                        c.reset(t)  # (and the step's signature starts there)
                    else:
                        c.g, c.sum_ge, c.sum_gg = 0.0, 0.0, 0.0
                else:
                    c.g, c.sum_ge, c.sum_gg = g, c.sum_ge + ge, c.sum_gg + gg
                    if k >= 4:  # the weak-step pair dates and sizes, and fires only further up
                        if g > h + d.h_lo and g - h - d.h_lo > best:
                            fire, best = c, g - h - d.h_lo
                        continue
                    quiet = False
                    if g > h and g - h > best:
                        fire, best = c, g - h
            if t - self.t_air < self.t_amb_hold:
                fire = None  # the air's sensor catches up: the evidence gathers, no onset
                self.air_held = True
            if fire is not None:
                # of the CUSUMs of its sign, the step that explains the readings best
                fit = fire.sum_ge**2 / fire.sum_gg if fire.sum_gg > 0 else 0.0
                for c in self.cusums:
                    if (c is not fire and c.design * fire.design > 0 and c.g > 0 and c.sum_gg > 0
                            and c.sum_ge**2 / c.sum_gg > fit):
                        fire, fit = c, c.sum_ge**2 / c.sum_gg
                sg = 1.0 if fire.design > 0 else -1.0
                D = abs(fire.design)
                jump = fire.sum_ge / fire.sum_gg if fire.sum_gg > 0 else sg * D
                if sg * jump < D:
                    jump = sg * D
                if self.cfg.detector.onset_state_jump:
                    # the whole state as the step at t_zero would have left it (not q_i alone)
                    self.x = self.x + jump * fire.mu
                    self.P = self.P + 0.25 * jump**2 * np.outer(fire.mu, fire.mu)
                else:  # q_i alone (a skin's patch)
                    self.x[I_Q] += jump
                    self.P[I_Q, I_Q] += 0.25 * jump**2
                if sg < 0 and t - self.t_xp < d.t_pair:
                    # the end of a warm touch too weak to detect: the state takes the change,
                    # q_i stays at its baseline, no contact; as after that touch's release
                    self.t_rel, self.last_sign = t, 1.0
                    self.x[I_Q] = self.b
                    self.V[I_Q] = 0.0
                    self.dq = 0.0
                    self.t_xp = -1e300
                    self._reset_cusums(t)
                    self.r_slots = [0.0] * N_SLOTS
                    return 0
                q = self.x[I_Q]
                self.mode, self.contact, self.sign = "contact", 1, sg
                tau = self._glr_time(fire, sg) if d.onset_glr else fire.t_zero
                self.onset, self.detected = self._between(tau, t), t
                dd = sg * (q - self.b)
                self.peak = self.sum = self.level = self.level_max = dd
                self.count, self.since = 1, 0
                self.run_rel = self.run_lik = 0.0
                self.t_below = self.t_lik = t
                self._reset_cusums(t)
                self.r_slots = [0.0] * N_SLOTS  # the variance's steps not yet taken: the onset's
                self.t_xp = -1e300
                self.dq = q - self.b
                return 3
            if (d.t_pair > 0 and max(self.cusums[0].g, self.cusums[2].g) > PAIR_FLOOR * h
                    and not (self.last_sign < 0 and t - self.t_rel < d.t_refractory + d.t_pair)):
                self.t_xp = t  # a warm touch's evidence, for pairing its end
            if quiet and t - self.t_rel >= d.t_settle:
                self.b += self.a_b * sq * (1 if q > self.b else -1)
            self.dq = q - self.b
            return 0
        # in contact
        sg, b = self.sign, self.b
        dd = sg * (q - b)
        self.dq = q - b
        self.peak = max(self.peak, dd)
        self.sum += dd
        self.count += 1
        self.since += 1
        self.level += self.a_lvl * (dd - self.level)
        self.level_max = max(self.level_max, self.level)
        sd = d.z_scale * self.kappa * sq
        thr = max(d.k_off * sd, d.f_off * self.level_max)
        g = self.run_rel + ((thr - dd) / sd - d.k_rel) * self.t_s
        if g <= 0:
            g, self.t_below = 0.0, t
        self.run_rel = g
        # log-likelihood ratio of q at b against q at b + sg L, L the contact's mean level
        # (anchored at them, not at the estimate)
        L = max(self.sum / self.count, d.dq_design)
        Dr = -sg * L
        gl = self.run_lik + Dr * ge - 0.5 * Dr * (2 * (b - self.q_prior) + sg * L) * gg
        if gl <= 0:
            if self.run_lik > 0 or self.t_last_w == t:
                self.t_lik = t
            gl = 0.0
        self.run_lik = gl
        if g > d.h_off:
            unconfirmed = self.t_lik == self.detected and t - self.detected < d.t_confirm
            if not unconfirmed and (
                    (t - self.t_below) * self.rate < d.release_readings  # one reading off ends no touch
                    # nor one pulse's dip where the misfit is locked to the pump's cycle: the
                    # evidence over the last whole phase and this one (kernel: _release_waits)
                    or (d.release_phases and self.rho_p > d.rho_deadband
                        and self.rate >= FAST_READINGS
                        and t - self.t_below < (self.phase + self.ph_prev) * self.t_s)):
                return 1
            if self.detected <= self.t_lik < self.t_below:
                t_rel = self._between(self.t_lik, t)
            else:
                t_rel = self.t_below
            lm = self.sum / self.count
            nothing = (lm < d.confirm_mean * d.dq_design_lo
                       or lm * (t_rel - self.onset) < d.confirm_mean * d.dq_design_lo * d.confirm_time)
            if unconfirmed or nothing:
                # never confirmed by a reading since the detection, and over at once: noise;
                # or its heat over it came to nothing
                self.mode, self.contact = "idle", 0
                self.x[I_Q] = b
                self.V[I_Q] = 0.0
                self.P[I_Q, I_Q] += 0.25 * self.level**2
                self.dq = 0.0
                self._reset_cusums(t)
                if not unconfirmed:  # and then as after a release, but no sign waits
                    self.t_rel, self.last_sign = t, 0.0
                return 0
            self._end(t_rel)
            self.x[I_Q] = b
            self.V[I_Q] = 0.0
            self.P[I_Q, I_Q] += 0.25 * self.level**2
            self.dq = 0.0
            return 4
        if self.since >= self.n_max:
            self._end(t)
            self.b = q
            return 4
        return 1

    def _glr_time(self, c: _Cusum, sg: float) -> float:
        """The change time by the GLR over it (Basseville and Nikiforov 1993, sec. 2.4): of
        ``c.t_zero`` (the CUSUM's own sums) and the end of each buffer entry since, the one after
        which a step of free size and sign ``sg`` explains the readings best,
        ``max (sum g e/S)² / (2 sum g²/S)`` over the readings after it."""
        cands = [(c.t_zero, c.sum_ge, c.sum_gg)]
        a = b = 0.0  # the sums over the readings after tk, back from now (plain sums, as the kernel)
        for tk, ge, gg in reversed([r for r in self.glr if r[0] > c.t_zero]):
            cands.append((tk, a, b))
            a, b = a + ge, b + gg
        best_t, best = c.t_zero, 0.0
        for tk, a, b in cands:  # of equals (within 1e-12, relative), the first
            llr = a * a / b if sg * a > 0 and b > 0 else 0.0
            if llr > best * (1.0 + 1e-12):
                best_t, best = tk, llr
        return best_t

    def _between(self, t_zero: float, t: float) -> float:
        """Half a reading interval after the last reading with no news of the change, not after ``t``."""
        tc = t_zero + 0.5 / self.rate if self.rate > 0 else t_zero
        return min(tc, t)

    def _end(self, t_release: float) -> None:
        mean = self.sum / self.count
        dur = t_release - self.onset
        sg = self.sign
        self.events.append(ContactEvent(onset=self.onset, detected_at=self.detected, release=t_release,
                                        duration=dur, sign=int(sg), peak_dq=sg * self.peak,
                                        mean_dq=sg * mean, energy=sg * mean * dur))
        self.mode, self.contact = "idle", 0
        self.t_rel, self.last_sign = t_release, sg
        self._reset_cusums(t_release)

    @property
    def T_g_hat(self) -> float:
        return float(self.x[I_TG])
