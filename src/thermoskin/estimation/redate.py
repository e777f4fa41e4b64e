"""Dating a contact again when it ends: a pulse fit on a detection-free filter.

The detector dates an onset when it fires and a release when its release test trips, each
from the readings it has by then. When the contact has ended, more is known: the readings
after the release, and that the heat came as one pulse of one height. Where the pipe
readings are slow (10 Hz boards, a 100 Hz log) that dates the contact better, and the
event (:class:`~thermoskin.estimation.events.ContactEvent`) is written with the fit's onset and
release, ``detector.redate_tail`` after the detector's release.

The fit is the generalised likelihood ratio of a rectangular pulse of heat of free height
from ``t_on`` to ``t_off`` (Willsky and Jones 1976; Basseville and Nikiforov 1993, sec. 2.4)
on the innovations of the estimator's own Kalman filter run with detection off (so it
never jumps), over a 10 ms grid of both times within ``detector.redate_reach`` of the
detector's own:

    LLR(t_on, t_off) = a^2 / b,   a = sum_k rho_k e_k / S_k,   b = sum_k rho_k^2 / S_k,

``e_k, S_k`` the innovations and their variances (times the learnt scale squared), ``rho_k``
what a unit pulse would have left in them: a unit step of ``q_i`` at ``t_on`` carried through
the filter, ``mu <- Phi (I - K H) mu``, minus the same from ``t_off``. Each time written is its
posterior mean over the grid, weights ``exp(LLR / 2)`` (:func:`pulse_fit`). The filter's state
error where the evidence starts (:data:`NUISANCE_S` before the earliest candidate) is a
nuisance of free value: its signatures are projected out (Willsky and Jones's unknown
initial state), so the filter needs only :data:`HISTORY_S` of readings before it to learn
the innovations' scale. A contact longer than :data:`LONGEST_S` (or whose start has left
the buffer) has its release alone dated again, as a step down.

The fit's cost grows with the pipe readings it weighs and the rows it runs the filter over
(1.5-3 ms a contact); where the readings are more than ``detector.redate_readings`` (3000: a
contact longer than 0.7 s at 1 kHz) the detector's own dating is kept, which is within 0.3 s
there. The live loop and offline analysis run this on the same
rows at the same moments (the first sample at or after the due time, or the next contact's
detection), so they write the same events. A live loop may hand the fit to a worker thread
(``background``): the loop's sample then costs what any other does, and the event, the same,
comes a few milliseconds later (a realtime loop with 10 Hz boards: the fit took 3-5 ms of
the 1 ms sample, an overrun at every contact's end).
"""

from __future__ import annotations

import dataclasses
import math
import os
import threading
from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor
from typing import NamedTuple, Protocol

import numpy as np
from numpy.typing import NDArray

from thermoskin._jit import njit
from thermoskin.estimation import kernel as K  # noqa: N812
from thermoskin.estimation.events import ContactEvent
from thermoskin.params import Config

Array = NDArray[np.float64]


class TracedModel(Protocol):
    """What the re-dating reads of the estimator: the kernel's parameters and tables, and the
    pump-cycle correction as it stands (``K.TPL``, ``2 K.NPH`` values)."""

    pr: Array
    tabs: tuple[Array, ...]

    @property
    def switch_table(self) -> Array: ...


GRID_S = 0.01      #: candidate spacing, s
NUISANCE_S = 1.0   #: evidence used before the earliest candidate, to pin the state error there, s
HISTORY_S = 5.0    #: the detection-free filter runs this long before that, s
LONGEST_S = 30.0   #: a contact longer than this has its release alone dated again, s
NCOL = 8           #: the input buffer's columns: t, T_w, T_p, T_a, T_w_cmd, pump row, drive, fresh
NREC = 2 * K.NUR + 5  #: per row of the trace: the two updates, the pump row, ready, switch corrections,
#                        the pipe thermocouple's bead weight a
RIV, RREADY, RSWB, RSWA, RLAGA = (2 * K.NUR, 2 * K.NUR + 1, 2 * K.NUR + 2, 2 * K.NUR + 3,
                                  2 * K.NUR + 4)
NS = 6  #: the filter's states the signatures carry: the patch's five and the pipe thermocouple's bead


@njit(cache=True, nogil=True)
def trace(st, pr, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, t, T_w, T_p, T_a, T_w_cmd, iv, drive, fresh,
          rec, ev):
    """The kernel's sample step (``pr[PR_TRACE]`` = 1: no detection) over rows; ``rec[k]``: the
    row's pipe and tank updates (``K.UREC`` layout), the pump row its prediction used, and
    whether the filter was initialised."""
    n = t.shape[0]
    for k in range(n):
        K.step(st, pr, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, t[k], T_w[k], T_p[k], T_a[k], T_w_cmd[k],
               iv[k], drive[k], fresh[k], ev)
        for j in range(2 * K.NUR):
            rec[k, j] = st[K.UREC + j]
        rec[k, RIV] = st[K.IVP]
        rec[k, RREADY] = st[K.READY]
        rec[k, RSWB] = st[K.SWB]
        rec[k, RSWA] = st[K.SWA]
        rec[k, RLAGA] = st[K.LAGA]


@njit(cache=True, nogil=True, forceinline=True)
def _left_mul(F, la, B, col, tmp):
    """``B[:, col] = Phi_aug @ B[:, col]`` (``NS`` x ``NS``, in place): the model's step of the
    patch's five states (``F``, rows 2 and 4 unit rows as any) and the bead's,
    ``m <- (1 - a) T_w + a m`` (``la`` = a), from the column before the step."""
    for m in range(NS):
        tmp[m] = B[m, col]
    for m in range(5):
        s = 0.0
        for q in range(5):
            s += F[m, q] * tmp[q]
        B[m, col] = s
    B[5, col] = (1.0 - la) * tmp[0] + la * tmp[5]


@njit(cache=True, nogil=True, forceinline=True)
def _switch(M, c):
    """A coarse log's pump-switch correction on the map: ``x_Tw += c (x_Tp - x_Tw)``."""
    if c != 0.0:
        for q in range(NS):
            M[0, q] += c * (M[3, q] - M[0, q])


@njit(cache=True, nogil=True, forceinline=True)
def _idle(col, no, nc, p_on, p_off):
    """A candidate's column whose step has not started yet (all zero: skipped)."""
    return (col < no and col >= p_on) or (no <= col < nc and col - no >= p_off)


@njit(cache=True, nogil=True, forceinline=True)
def _flush(mu, M, v, W, WM, a, d, cn, nn, x, no, nc, p_on, p_off):
    """Add a stretch's sums to the fit's (``a += v' mu``, ``G += mu' W mu`` for the blocks
    kept) and carry the active columns over it (``mu <- M mu``)."""
    for col in range(nc + NS):
        if _idle(col, no, nc, p_on, p_off):
            continue
        s = 0.0
        for m in range(NS):
            s += v[m] * mu[m, col]
        a[col] += s
        for m in range(NS):
            s = 0.0
            for q in range(NS):
                s += W[m, q] * mu[q, col]
            WM[m, col] = s
    for m in range(NS):  # the nuisance's block
        for q in range(NS):
            s = 0.0
            for l_ in range(NS):
                s += mu[l_, nc + m] * WM[l_, nc + q]
            nn[m, q] += s
    for col in range(nc):
        if _idle(col, no, nc, p_on, p_off):
            continue
        s = 0.0
        for l_ in range(NS):
            s += mu[l_, col] * WM[l_, col]
        d[col] += s
        for m in range(NS):
            s = 0.0
            for l_ in range(NS):
                s += mu[l_, col] * WM[l_, nc + m]
            cn[col, m] += s
    for c in range(p_on):
        for b in range(p_off):
            s = 0.0
            for l_ in range(NS):
                s += mu[l_, c] * WM[l_, no + b]
            x[c, b] += s
    tmp = np.empty(NS)
    for col in range(nc + NS):
        if not _idle(col, no, nc, p_on, p_off):
            for m in range(NS):
                tmp[m] = mu[m, col]
            for m in range(NS):
                s = 0.0
                for q in range(NS):
                    s += M[m, q] * tmp[q]
                mu[m, col] = s


@njit(cache=True, nogil=True)
def pulse_sums(rec, Phi, j_first, s_on, s_off):
    """The fit's sums over the trace's rows ``j_first..``: with the candidates' columns (onsets
    ``s_on``, releases ``s_off``: the rows they start at, ascending) and the ``NS`` nuisance
    columns (a unit error of each state, the pipe thermocouple's bead included, at ``j_first``),
    ``a = R z`` and the blocks of ``R R'`` the fit reads: ``d`` (candidates' diagonal), ``cn``
    (candidates x nuisance), ``nn``, ``x`` (onsets x releases). ``R``'s column for a reading is
    ``rho / sqrt(S)``, ``z = e / sqrt(S)``, ``rho`` a column's signature at that reading (the
    pipe's reading reads ``(1 - a) T_w + a m``, the bead's weighed in).

    Between two candidate starts every column is carried by the same map ``M`` (the filter's
    ``I - K H``, a coarse log's switch correction and ``Phi`` with the bead's step, multiplied
    together), so a reading's ``rho = h' mu0`` with ``h`` its row of ``M`` and ``mu0`` the
    columns where the stretch began: the stretch's readings add ``v = sum w z h`` and ``W = sum
    w^2 h h'`` (``w = 1/sqrt(S)``), and the columns are touched once a stretch, not once a
    reading (the same sums, in another order)."""
    no, nc = s_on.shape[0], s_on.shape[0] + s_off.shape[0]
    nf = nc - no
    mu = np.zeros((NS, nc + NS))
    for m in range(NS):
        mu[m, nc + m] = 1.0
    a = np.zeros(nc + NS)
    d = np.zeros(nc)
    cn = np.zeros((nc, NS))
    nn = np.zeros((NS, NS))
    x = np.zeros((no, nf))
    M = np.eye(NS)
    v = np.zeros(NS)
    W = np.zeros((NS, NS))
    WM = np.zeros((NS, nc + NS))
    tmp = np.zeros(NS)
    h = np.zeros(NS)
    p_on = p_off = 0
    n = rec.shape[0]
    for j in range(j_first, n):
        if (p_on < no and s_on[p_on] <= j) or (p_off < nf and s_off[p_off] <= j):
            _flush(mu, M, v, W, WM, a, d, cn, nn, x, no, nc, p_on, p_off)
            M[:, :] = 0.0
            for m in range(NS):
                M[m, m] = 1.0
            v[:] = 0.0
            W[:, :] = 0.0
            while p_on < no and s_on[p_on] <= j:
                mu[2, p_on] = 1.0
                p_on += 1
            while p_off < nf and s_off[p_off] <= j:
                mu[2, no + p_off] = 1.0
                p_off += 1
        _switch(M, rec[j, RSWB])  # before this row's updates
        for u in range(2):
            o = u * K.NUR
            if rec[j, o] == 0.0:
                continue
            if u == 0:  # the pipe's reading: its bead, (1 - a) T_w + a m
                la = rec[j, o + 10]
                for q in range(NS):
                    h[q] = (1.0 - la) * M[0, q] + la * M[5, q]
            else:
                for q in range(NS):
                    h[q] = M[3, q]
            if rec[j, o + 3] != 0.0:  # evidence
                w = 1.0 / math.sqrt(rec[j, o + 2])
                wz = rec[j, o + 1] * w * w
                w2 = w * w
                for m in range(NS):
                    hm = h[m]
                    v[m] += wz * hm
                    for q in range(NS):
                        W[m, q] += w2 * hm * h[q]
            for m in range(NS):  # M <- (I - K h') M, the bead's gain last
                km = rec[j, o + 4 + m] if m < 5 else rec[j, o + 9]
                for q in range(NS):
                    M[m, q] -= km * h[q]
        _switch(M, rec[j, RSWA])  # after them
        F = Phi[int(rec[j, RIV])]  # M <- Phi_aug M
        la = rec[j, RLAGA]
        for q in range(NS):
            _left_mul(F, la, M, q, tmp)
    _flush(mu, M, v, W, WM, a, d, cn, nn, x, no, nc, p_on, p_off)
    return a, d, cn, nn, x


def _posterior(num: Array, den: Array, ok: NDArray[np.bool_]) -> Array | None:
    """The candidates' weights ``exp(LLR / 2)``, ``LLR = num^2 / den`` (twice the log-likelihood
    ratio), summing to 1, zero where not ``ok``; None where a ratio overflows (sums near
    float64's end: no fit)."""
    with np.errstate(over="ignore"):
        llr = np.where(ok, num * num / np.where(ok, den, 1.0), -np.inf)
    if not np.isfinite(llr[ok]).all():
        return None
    w = np.exp(0.5 * (llr - llr.max()))
    return w / w.sum()


def pulse_fit(a: Array, d: Array, cn: Array, nn: Array, x: Array, no: int, sign: float,
              s_on: NDArray[np.int64], s_off: NDArray[np.int64], c_on: Array,
              c_off: Array) -> tuple[float | None, float | None] | None:
    """Onset and release (s; None: that edge not fitted, the onsets or releases empty: the
    release alone as a step down, or the onset alone as a step up) of a pulse of sign
    ``sign``; None if none fits (or the sums are not finite). The nuisance is projected out,
    ``G_p = G - G_cn G_nn^+ G_nc``, ``a_p = a - G_cn G_nn^+ a_n``. Each time is its posterior
    mean over the candidates ``c_on``, ``c_off`` (rows ``s_on``, ``s_off``) with a flat prior
    and the pulse's height at its most likely value, weights ``exp(LLR/2)``: not the most
    likely pair, which jumps to a far candidate that explains the readings barely better
    (a finger's heat fades during a touch; the model's pulse is flat), where the mean stays
    between them (the estimate of least squared error; Smith 1975, Biometrika 62:407)."""
    nc = d.shape[0]
    if not (np.isfinite(a).all() and np.isfinite(d).all() and np.isfinite(cn).all()
            and np.isfinite(nn).all() and np.isfinite(x).all()):
        return None  # readings far out of range: no fit (the detector's dates stand)
    try:
        w, V = np.linalg.eigh(nn)
    except np.linalg.LinAlgError:
        return None
    keep = w > 1e-12 * max(float(w.max()), 1e-300)
    Vk = V[:, keep] / np.sqrt(w[keep])  # nn^+ = Vk Vk'
    C = cn @ Vk                          # candidates x kept
    an = a[nc:] @ Vk
    ap = a[:nc] - C @ an
    dp = d - np.einsum("ij,ij->i", C, C)
    if no == 0 or nc == no:  # one edge alone: the release as a step down, or the onset up
        sg = -sign if no == 0 else sign
        ok = (sg * ap > 0) & (dp > 1e-12 * d) & (d > 0)
        if not ok.any():
            return None
        w = _posterior(ap, dp, ok)
        if w is None:
            return None
        return (None, float(w @ c_off)) if no == 0 else (float(w @ c_on), None)
    xp = x - C[:no] @ C[no:].T
    num = ap[:no, None] - ap[None, no:]
    den = dp[:no, None] + dp[None, no:] - 2.0 * xp
    ok = ((num * sign > 0) & (s_on[:, None] < s_off[None, :])
          & (den > 1e-12 * (d[:no, None] + d[None, no:])) & (d[None, no:] > 0))
    if not ok.any():
        return None
    w = _posterior(num, den, ok)
    if w is None:
        return None
    return float(w.sum(axis=1) @ c_on), float(w.sum(axis=0) @ c_off)  # each time's marginal


def load(est: TracedModel) -> None:
    """Load the compiled fit (from numba's cache) now, not at the first contact's end: a live
    loop pays it before it starts (about 20 ms)."""
    n = 4
    z = np.full(n, 24.0)
    rec = np.zeros((n, NREC))
    trace(K.new_state(), est.pr, *est.tabs, np.arange(n) * 1e-3, z, z, z, z,
          np.zeros(n, dtype=np.int64), np.full(n, np.nan), np.full(n, 7, dtype=np.int64), rec,
          np.zeros(K.NEV))
    one = np.zeros(1, dtype=np.int64)
    pulse_sums(rec, est.tabs[0], 0, one, one + 1)


def held(pr: Array, learnt: Array | None) -> None:
    """``pr`` (a copy of the kernel's parameters) for a filter that holds what the live one had
    learnt (``learnt``: a contact's kernel record, ``EV_RW`` on) instead of learning it again."""
    pr[K.PR_LEARN] = 0.0
    if learnt is not None:
        pr[K.PR_RW0], pr[K.PR_RP0], pr[K.PR_RA0] = learnt[K.EV_RW], learnt[K.EV_RP], learnt[K.EV_RA]
        pr[K.PR_BD0], pr[K.PR_LAG0] = learnt[K.EV_BD], learnt[K.EV_LAG]
    pr[K.PR_PB0] = pr[K.PR_PT0] = 0.0


class _Model(NamedTuple):
    """The estimator's parameters and tables as they were when a fit was handed over."""

    pr: Array
    tabs: tuple[Array, ...]
    switch_table: Array


_worker = threading.local()  # .on: this thread is a re-dating worker


def _worker_start() -> None:
    """A worker started by a realtime loop (``SCHED_FIFO``, whose policy it inherits) runs
    below the loop (priority 5 lower: it never takes the loop's core) but above ordinary work
    (which would otherwise take the worker's core while it holds the interpreter the loop
    waits for)."""
    _worker.on = True
    try:
        if os.sched_getscheduler(0) in (os.SCHED_FIFO, os.SCHED_RR):
            prio = os.sched_getparam(0).sched_priority
            os.sched_setparam(0, os.sched_param(max(1, prio - 5)))
    except (AttributeError, OSError):
        pass


class Redater:
    """One patch's re-dating: the buffer of its last input rows and the contact waiting for
    its due time. :class:`~thermoskin.estimation.estimator.TouchEstimator` hands it every row it steps
    (:meth:`push`, :meth:`push_block`) and every row where a contact starts or ends or the
    waiting one falls due (:meth:`on_row`), one sample at a time live and a chunk at a time
    offline: the same rows, the same moments, the same events.

    ``background``: the live rows go to the buffer and a fit due at a live row runs in a
    worker thread (one: in order, each fit after the rows before it); the fit's event comes
    from :meth:`ready` once done. The loop's thread only appends rows to a list and hands it
    over, a thousand at a time (writing them to the buffer took 0.3-0.8 ms, once a second)."""

    def __init__(self, cfg: Config, t_s: float, background: bool = False) -> None:
        d = cfg.detector
        self.most, self.reach, self.tail = d.redate_readings, d.redate_reach, d.redate_tail
        span = HISTORY_S + NUISANCE_S + 2 * self.reach + LONGEST_S + self.tail + 1.0
        self.nr = math.ceil(span / t_s)
        self.buf = np.zeros((NCOL, self.nr))  # a column's rows contiguous (searched in place)
        self.n_buf = 0  # rows written to the buffer
        self.n_handed = 0  # rows pushed and gone from the list (to the buffer, or the worker)
        self.rows: list[tuple[float, ...]] = []  # rows pushed one at a time, not yet written
        self.pending: ContactEvent | None = None
        self.learnt: Array | None = None  # the pending contact's kernel record (what was learnt)
        self.due = math.inf
        self.last_release = -math.inf  # the release of the last contact written
        self._pool: ThreadPoolExecutor | None = None  # the worker (background), until closed
        self._jobs: deque[Future[ContactEvent | None]] = deque()  # handed over, in order: fits,
        #                                                            and rows to write (None)
        self._done: list[ContactEvent] = []  # events of fits collected, not yet handed out
        if background:  # started now, not at the first contact's end
            self._pool = ThreadPoolExecutor(1, thread_name_prefix="thermoskin-redate",
                                            initializer=_worker_start)
            self._pool.submit(int).result()

    @property
    def n(self) -> int:
        """Rows pushed."""
        return self.n_handed + len(self.rows)

    # -- the buffer -------------------------------------------------------------------------
    def push(self, row: tuple[float, ...]) -> None:
        """One row (the :data:`NCOL` inputs of a sample; kept in a list, written to the buffer
        a thousand at a time: a numpy row store costs more than the sample step)."""
        self.rows.append(row)
        if len(self.rows) >= 1024:
            self._write()

    def _write(self) -> None:
        """The rows pushed one at a time into the buffer (in the background: handed to the
        worker, which writes them before any fit handed over after them)."""
        if not self.rows or getattr(_worker, "on", False):  # the list is the loop's alone
            return
        rows, self.rows = self.rows, []
        self.n_handed += len(rows)
        if self._pool is not None:
            self._jobs.append(self._pool.submit(self._write_rows, rows))
        else:
            self._write_rows(rows)

    def _write_rows(self, rows: list[tuple[float, ...]]) -> None:
        # 128 rows at a time: the conversion holds the interpreter, which a live loop waits
        # for when the worker converts (1024 rows at once: 0.3-0.8 ms)
        for i in range(0, len(rows), 128):
            self._put(tuple(np.array(rows[i:i + 128], dtype=float).T))

    def push_block(self, cols: tuple[Array, ...]) -> None:
        """Rows given as :data:`NCOL` columns, in order (only the last ``nr`` are kept)."""
        self._write()
        self._collect(True)  # the buffer is this thread's again
        self.n_handed += len(cols[0])
        self._put(cols)

    def _put(self, cols: tuple[Array, ...]) -> None:
        m = len(cols[0])
        skip = max(0, m - self.nr)
        self.n_buf += skip
        m -= skip
        p = self.n_buf % self.nr
        first = min(m, self.nr - p)
        for j, c in enumerate(cols):
            self.buf[j, p:p + first] = c[skip:skip + first]
            self.buf[j, :m - first] = c[skip + first:]
        self.n_buf += m

    def _cols(self, k0: int, k1: int, block: tuple[Array, ...] | None, n0: int,
              which: tuple[int, ...] = tuple(range(NCOL))) -> Array:
        """Columns ``which`` of rows ``k0..k1-1`` (indices since the start; columns x rows), from
        the buffer and from ``block`` (columns not yet pushed, their first row ``n0``)."""
        self._write()
        k_mid = k1 if block is None else max(k0, min(k1, n0))
        # the buffer's one or two stretches, copied as slices (15 000 rows: 0.11 ms, against
        # 0.38 ms gathered through index arrays)
        rows = list(which)
        a, m = k0 % self.nr, max(0, k_mid - k0)
        if a + m <= self.nr:
            old = self.buf[rows, a:a + m]
        else:
            old = np.concatenate([self.buf[rows, a:], self.buf[rows, :a + m - self.nr]], axis=1)
        if k1 <= k_mid:
            return old
        new = np.stack([block[j][k_mid - n0:k1 - n0] for j in which]).astype(float)  # type: ignore[index]
        return new if k_mid == k0 else np.concatenate([old, new], axis=1)

    def _search(self, x: float, k0: int, k1: int, block: tuple[Array, ...] | None, n0: int) -> int:
        """The first row of ``k0..k1-1`` at or after time ``x`` (``k1`` if none), searched in
        place: the buffer's one or two stretches, then ``block``."""
        self._write()
        k_mid = k1 if block is None else max(k0, min(k1, n0))
        if k0 < k_mid:
            a, m = k0 % self.nr, k_mid - k0
            stretches = ([(k0, self.buf[0, a:a + m])] if a + m <= self.nr else
                         [(k0, self.buf[0, a:]), (k0 + self.nr - a, self.buf[0, :a + m - self.nr])])
            for k_start, seg in stretches:
                i = int(np.searchsorted(seg, x))
                if i < len(seg):
                    return k_start + i
        if k1 > k_mid and block is not None:
            return k_mid + int(np.searchsorted(block[0][k_mid - n0:k1 - n0], x))
        return k1

    # -- the contacts -----------------------------------------------------------------------
    def on_row(self, est: TracedModel, k: int, t: float, onset_started: float,
               ended: ContactEvent | None, block: tuple[Array, ...] | None = None, n0: int = 0,
               learnt: Array | None = None) -> list[ContactEvent]:
        """Row ``k`` at ``t``: a contact started there (its onset; NaN if none) or ended
        there (its event as the detector has it; ``learnt``: the kernel's event record, whose
        fields from ``EV_RW`` on say what the estimator had learnt of the sensors then).
        Returns the events to write now: the one waiting, dated again from the rows before its
        due time (or before the new contact's onset), once that time has come or a contact has
        started."""
        out: list[ContactEvent] = []
        if self.pending is not None and (onset_started == onset_started or t >= self.due):
            t_end = min(self.due, onset_started) if onset_started == onset_started else self.due
            out.extend(self._date(est, self.pending, k, t_end, block, n0, self.learnt))
            self.pending, self.due = None, math.inf
        if ended is not None:
            self.pending, self.due = ended, ended.release + self.tail
            self.learnt = None if learnt is None else np.array(learnt, dtype=float)
            if t >= self.due:
                out.extend(self._date(est, ended, k, self.due, block, n0, self.learnt))
                self.pending, self.due = None, math.inf
        return out

    def _date(self, est: TracedModel, e: ContactEvent, k: int, t_end: float,
              block: tuple[Array, ...] | None, n0: int, learnt: Array | None) -> list[ContactEvent]:
        """``e`` dated again now; or, in the background (a live row), handed to the worker:
        nothing now, the event from :meth:`ready`."""
        if self._pool is None or block is not None:
            return [self.redate(est, e, k, t_end, block, n0, learnt=learnt)]
        self._write()  # the rows up to k into the buffer, which alone the worker reads
        # as they are now (a new pump velocity adds tables; the live filter learns on)
        model = _Model(est.pr, est.tabs, est.switch_table.copy())
        self._jobs.append(self._pool.submit(self.redate, model, e, k, t_end, learnt=learnt))
        return []

    @property
    def busy(self) -> bool:
        """Work handed to the worker, or its events, not collected yet."""
        return bool(self._jobs or self._done)

    def _collect(self, block: bool) -> None:
        """The events of the work done (``block``: of all of it, once done), in order."""
        while self._jobs and (block or self._jobs[0].done()):
            e = self._jobs.popleft().result()
            if e is not None:
                self._done.append(e)

    def ready(self) -> list[ContactEvent]:
        """The events of the fits the worker has finished, in order (a live loop asks at
        every sample while :attr:`busy`)."""
        self._collect(False)
        out, self._done = self._done, []
        return out

    def wait(self) -> list[ContactEvent]:
        """The events of every fit handed over, once done."""
        self._collect(True)
        out, self._done = self._done, []
        return out

    def flush(self, est: TracedModel) -> list[ContactEvent]:
        """The end of the log: the fits handed over, then the contact waiting, from the rows
        there are."""
        self._write()
        out = self.wait()
        if self.pending is None:
            return out
        e, self.pending, self.due = self.pending, None, math.inf
        return [*out, self.redate(est, e, self.n - 1, math.inf, learnt=self.learnt)]

    def close(self) -> None:
        """Stop the worker (after the fits handed over)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None

    def redate(self, est: TracedModel, e: ContactEvent, k_now: int, t_end: float,
               block: tuple[Array, ...] | None = None, n0: int = 0, open_end: bool = False,
               learnt: Array | None = None) -> ContactEvent:
        """``e`` dated again from the rows before ``t_end`` that the buffer holds at row
        ``k_now`` (its last ``nr``); ``e`` itself where the readings came fast, or no pulse
        of its sign fits. ``open_end``: the contact had not ended (the log or the run did):
        its onset alone is dated again. Nothing is dated into the contact written before.
        ``learnt``: the contact's kernel record; the filter run again holds what the live one
        had learnt of the sensors when the contact ended (their variances, the offset)."""
        out = self._redate(est, e, k_now, t_end, block, n0, open_end, learnt)
        self.last_release = out.release
        return out

    def _redate(self, est: TracedModel, e: ContactEvent, k_now: int, t_end: float,
                block: tuple[Array, ...] | None, n0: int, open_end: bool,
                learnt: Array | None) -> ContactEvent:
        if self.most <= 0:
            return e
        k_lo, k_hi = max(0, k_now + 1 - self.nr), k_now + 1
        end = self._search(t_end, k_lo, k_hi, block, n0)
        reach = self.reach
        t_first = float(self._cols(k_lo, k_lo + 1, block, n0, (0,))[0, 0])
        # the candidates and the evidence start after the contact before (its end is then a
        # state error where the evidence starts: the nuisance, projected out)
        after = self.last_release + GRID_S
        on_lo = max(e.onset - reach, after)
        with_onset = (e.release - e.onset <= LONGEST_S and on_lo <= e.onset
                      and t_first <= max(on_lo - NUISANCE_S, self.last_release))
        if open_end and not with_onset:
            return e
        t_ev0 = max((on_lo if with_onset else max(e.release - reach, after)) - NUISANCE_S,
                    self.last_release)
        k0 = self._search(t_ev0 - HISTORY_S, k_lo, k_hi, block, n0)
        j0 = self._search(t_ev0, k_lo, k_hi, block, n0)
        if end - j0 < 2:
            return e
        fresh = self._cols(j0, end, block, n0, (7,))[0]
        if np.count_nonzero(fresh.astype(np.int64) & 1) > self.most:
            return e  # the fit would cost more than it is worth (a long contact at 1 kHz)
        w = np.ascontiguousarray(self._cols(k0, end, block, n0))
        tw = w[0]
        pr = est.pr.copy()
        pr[K.PR_TRACE] = 1.0
        pr[K.PR_OSJ] = 0.0  # no step signatures: nothing jumps
        held(pr, learnt)
        rec = np.zeros((len(tw), NREC))
        st0 = K.new_state()
        # the pump-cycle correction as the live filter has it (held: nothing is learnt here)
        st0[K.TPL:K.TPL + 2 * K.NPH] = est.switch_table
        trace(st0, pr, *est.tabs, tw, w[1], w[2], w[3], w[4], w[5].astype(np.int64),
              w[6], w[7].astype(np.int64), rec, np.zeros(K.NEV))
        j_first = j0 - k0
        if not rec[j_first:, RREADY].all():  # the filter restarted: no fit
            return e
        # a touch began before it was detected
        cand_on = (np.arange(on_lo, min(e.onset + reach, e.detected_at) + 1e-9, GRID_S)
                   if with_onset else np.zeros(0))
        cand_off = (np.zeros(0) if open_end else
                    np.arange(max(e.release - reach, after), e.release + reach + 1e-9, GRID_S))
        s_on = np.searchsorted(tw, cand_on).astype(np.int64)
        s_off = np.searchsorted(tw, cand_off).astype(np.int64)
        keep = s_off < len(tw) - 1  # a release with readings after it
        cand_off, s_off = cand_off[keep], s_off[keep]
        if not len(cand_off) and not open_end:
            return e
        best = pulse_fit(*pulse_sums(rec, est.tabs[0], j_first, s_on, s_off), len(s_on),
                         float(e.sign), s_on, s_off, cand_on, cand_off)
        if best is None:
            return e
        onset = e.onset if best[0] is None else best[0]
        release = max(e.release if best[1] is None else best[1], onset)
        dur = release - onset
        return dataclasses.replace(e, onset=onset, release=release, duration=dur,
                                   energy=e.mean_dq * dur)
