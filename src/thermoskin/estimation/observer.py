"""The thermal exchange observer (eq. 8, Fig. 5) and its contact residual.

Inputs per sample: ``T_w, T_p, v, T_a``. With ``q_p = (T_p - T_w)/R_w(v)`` (eq. 1) and
``q_aw = (T_w - T_a)/R_aw`` (eq. 3), ``q_net = q_p - q_aw``. Eq. 8,

    q_hat = [D(s) T_w - (R_g C_g s + 1) q_net] / [(R_g C_w s + 1)(R_g C_g s + 1)],

is run as two proper filters, ``q_hat = F1(s) T_w - F2(s) q_net`` with
``F1 = D(s)/((R_g C_w s+1)(R_g C_g s+1))`` and ``F2 = 1/(R_g C_w s+1)``. On the network of
docs/model.md it returns ``Q(s)(q_i - q_ag)``. The paper then adds ``q_ag`` computed with
``T_w`` in place of the unmeasured ``T_g``:

    q_i_hat = q_hat + (T_w - T_a)/R_ag.

Two more outputs serve detection and the characterisation of a touch:

- ``dq_i_hat``, the change of the estimate from its no-touch value: ``q_hat - Q(s)(-q_ag0)``
  with ``q_ag0 = (T_g0 - T_a)/R_ag`` and ``T_g0`` the sheet temperature the network
  predicts from the measured ``T_w, T_a`` with no touch,
  ``(C_g s + 1/R_g + 1/R_ag) T_g0 = T_w/R_g + T_a/R_ag``. It is ``Q(s)`` times the touch's
  change of ``q_i - q_ag``, free of the pump's switching and of the set-point.
- ``r``, the same residual at the pipe node with a faster low-pass
  ``Q_r = 1/(tau_r s + 1)^2``: ``r = Q_r [C_w s T_w - q_net - (T_g0 - T_w)/R_g]``, the heat a
  touch adds to the pipe through the sheet (W). The detector works on it.

All are linear filters of ``T_w, q_net, T_a``, discretised with Tustin (``dsp.Iir``).

Start: the first ``n_init`` valid samples are averaged; meanwhile the outputs are the
steady state of the running means, then the filters start in that steady state (no
start-up spike). NaN samples (a loose thermocouple): the filters are frozen and the
outputs held, the sample is flagged ``gap``; a gap longer than ``max_gap_s`` restarts the
observer from the next valid sample.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from thermoskin.estimation.dsp import Iir
from thermoskin.params import ObserverParams, SkinParams
from thermoskin.physics.convection import FlowResistance
from thermoskin.physics.network import D_poly, Q_den

Array = NDArray[np.float64]


@dataclass
class ObserverOutput:
    """Arrays of the observer over a log, one value per sample."""

    q_hat: Array
    q_i_hat: Array
    dq_i_hat: Array
    r: Array
    gap: NDArray[np.bool_]
    ready: NDArray[np.bool_]


class ThermalExchangeObserver:
    """Eq. 8 as a streaming block (``step``) and over arrays (``run``)."""

    def __init__(self, skin: SkinParams, params: ObserverParams | None = None,
                 t_s: float = 1e-3) -> None:
        self.skin = skin
        self.params = params or ObserverParams()
        self.t_s = t_s
        self.R_w = FlowResistance(skin)
        self._inv_Raw = 1.0 / skin.R_aw
        self._inv_Rag = 1.0 / skin.R_ag
        self._max_gap = max(1, round(self.params.max_gap_s / t_s))
        Cw, Cg, Rg, Rag = skin.C_w, skin.C_g, skin.R_g, skin.R_ag
        tau = self.params.tau_r
        qden = Q_den(skin)
        sden = np.array([Cg, 1 / Rg + 1 / Rag])
        qsden = np.polymul(qden, sden)
        rden = np.polymul([tau, 1.0], [tau, 1.0])
        rsden = np.polymul(rden, sden)
        mk = lambda num, den: Iir(num, den, t_s)  # noqa: E731
        # q_hat = F1 T_w - F2 q_net                                       (eq. 8)
        self._F1 = mk(D_poly(skin), qden)
        self._F2 = mk([1.0], [Rg * Cw, 1.0])
        # dq_i_hat = q_hat + G_w T_w + G_a T_a
        self._G_w = mk([1 / (Rag * Rg)], qsden)
        self._G_a = mk(-np.array([Cg, 1 / Rg]) / Rag, qsden)
        # r = H_w T_w - H_q q_net + H_a T_a
        self._H_w = mk(np.polysub(np.polymul([Cw, 1 / Rg], sden), [1 / Rg**2]), rsden)
        self._H_q = mk([1.0], rden)
        self._H_a = mk([-1 / (Rg * Rag)], rsden)
        self._filters = (self._F1, self._F2, self._G_w, self._G_a, self._H_w, self._H_q,
                         self._H_a)
        self.filters = (self._F1, self._F2)
        """Eq. 8's two filters ``F1, F2`` (the compiled estimator runs the same coefficients)."""
        self.reset()

    # -- streaming -------------------------------------------------------------------
    def reset(self) -> None:
        """Restart: the next ``n_init`` valid samples set the steady state."""
        self._n = 0
        self._sum_w = self._sum_q = self._sum_a = 0.0
        self._gap_run = 0
        self._prev: tuple[float, float, float, float] | None = None
        self.q_hat = self.q_i_hat = self.dq_i_hat = self.r = float("nan")
        self.gap = False
        self.ready = False

    def _steady(self, Tw: float, qn: float, Ta: float) -> None:
        """Outputs for constant inputs (DC gains)."""
        q_hat = self._F1.dc * Tw - self._F2.dc * qn
        self.q_hat = q_hat
        self.q_i_hat = q_hat + (Tw - Ta) * self._inv_Rag
        self.dq_i_hat = q_hat + self._G_w.dc * Tw + self._G_a.dc * Ta
        self.r = self._H_w.dc * Tw - self._H_q.dc * qn + self._H_a.dc * Ta

    def step(self, T_w: float, T_p: float, v: float, T_a: float) -> float:
        """One sample; returns ``q_i_hat`` (W) and sets ``q_hat, dq_i_hat, r, gap``."""
        if T_w != T_w or T_p != T_p or v != v or T_a != T_a:  # NaN: hold
            self._gap_run += 1
            self.gap = True
            return self.q_i_hat
        self.gap = False
        if self._gap_run > self._max_gap:
            self.reset()
        self._gap_run = 0
        if self._prev is None:
            self._prev = (T_w, T_p, v, T_a)
        pw, pp, pv, pa = self._prev
        self._prev = (T_w, T_p, v, T_a)
        # interval [k-1, k]: mean temperatures, the velocity that was applied over it
        mw_k, mp_k, ma_k = 0.5 * (pw + T_w), 0.5 * (pp + T_p), 0.5 * (pa + T_a)
        qn = (mp_k - mw_k) / self.R_w(pv) - (mw_k - ma_k) * self._inv_Raw
        T_w_in, T_a_in = mw_k, ma_k
        if not self.ready:
            self._n += 1
            self._sum_w += T_w_in
            self._sum_q += qn
            self._sum_a += T_a_in
            n = self._n
            mw, mq, ma = self._sum_w / n, self._sum_q / n, self._sum_a / n
            self._steady(mw, mq, ma)
            if n >= self.params.n_init:
                for f, x0 in zip(self._filters, (mw, mq, mw, ma, mw, mq, ma), strict=True):
                    f.reset(x0)
                self.ready = True
            return self.q_i_hat
        q_hat = self._F1.step(T_w_in) - self._F2.step(qn)
        self.q_hat = q_hat
        self.q_i_hat = q_hat + (T_w - T_a) * self._inv_Rag
        self.dq_i_hat = q_hat + self._G_w.step(T_w_in) + self._G_a.step(T_a_in)
        self.r = self._H_w.step(T_w_in) - self._H_q.step(qn) + self._H_a.step(T_a_in)
        return self.q_i_hat

    # -- arrays ----------------------------------------------------------------------
    def q_net(self, T_w: Array, T_p: Array, v: Array, T_a: Array) -> Array:
        """``q_p - q_aw`` over arrays, ``R_w(v)`` looked up per distinct ``v``."""
        vals, inv = np.unique(v, return_inverse=True)
        Rw = np.array([self.R_w(float(x)) for x in vals])[inv]
        return (T_p - T_w) / Rw - (T_w - T_a) * self._inv_Raw

    @staticmethod
    def _interval_means(x: Array) -> Array:
        """``(x[k-1] + x[k]) / 2``, the first sample paired with itself."""
        prev = np.concatenate([x[:1], x[:-1]])
        return 0.5 * (prev + x)

    def run(self, T_w: Array, T_p: Array, v: Array, T_a: Array) -> ObserverOutput:
        """The observer over whole arrays; equal to ``reset`` then ``step`` per sample."""
        T_w, T_p, v, T_a = (np.asarray(x, dtype=float) for x in (T_w, T_p, v, T_a))
        n = len(T_w)
        valid = np.isfinite(T_w) & np.isfinite(T_p) & np.isfinite(v) & np.isfinite(T_a)
        out = {k: np.full(n, np.nan) for k in ("q_hat", "q_i_hat", "dq_i_hat", "r")}
        idx = np.flatnonzero(valid)
        ready = np.zeros(n, dtype=bool)
        if len(idx):
            skipped = np.diff(idx) - 1
            starts = np.concatenate([[0], np.flatnonzero(skipped > self._max_gap) + 1, [len(idx)]])
            for s0, s1 in itertools.pairwise(starts.tolist()):
                rows = idx[s0:s1]
                seg = self._run_segment(T_w[rows], T_p[rows], v[rows], T_a[rows])
                for k in out:
                    out[k][rows] = seg[k]
                ready[rows[self.params.n_init - 1:]] = True
            # hold over gaps: forward-fill from the last valid sample
            last = np.maximum.accumulate(np.where(valid, np.arange(n), -1))
            has = last >= 0
            for k in out:
                out[k][has] = out[k][last[has]]
        self.reset()
        return ObserverOutput(gap=~valid, ready=ready & valid, **out)

    def _run_segment(self, T_w: Array, T_p: Array, v: Array, T_a: Array) -> dict[str, Array]:
        T_w_raw, T_a_raw = T_w, T_a
        T_w, T_p, T_a = (self._interval_means(x) for x in (T_w, T_p, T_a))
        v = np.concatenate([v[:1], v[:-1]])
        qn = self.q_net(T_w, T_p, v, T_a)
        m = min(self.params.n_init, len(T_w))
        k = np.arange(1, m + 1)
        mw, mq, ma = (np.cumsum(x[:m]) / k for x in (T_w, qn, T_a))
        F1, F2, G_w, G_a, H_w, H_q, H_a = self._filters
        q_hat = np.empty(len(T_w))
        dq = np.empty(len(T_w))
        r = np.empty(len(T_w))
        q_hat[:m] = F1.dc * mw - F2.dc * mq
        dq[:m] = q_hat[:m] + G_w.dc * mw + G_a.dc * ma
        r[:m] = H_w.dc * mw - H_q.dc * mq + H_a.dc * ma
        if len(T_w) > m:
            w0, q0, a0 = mw[-1], mq[-1], ma[-1]
            sw, sq, sa = T_w[m:], qn[m:], T_a[m:]
            q_hat[m:] = F1.run(sw, w0) - F2.run(sq, q0)
            dq[m:] = q_hat[m:] + G_w.run(sw, w0) + G_a.run(sa, a0)
            r[m:] = H_w.run(sw, w0) - H_q.run(sq, q0) + H_a.run(sa, a0)
        q_i_hat = q_hat + (T_w_raw - T_a_raw) * self._inv_Rag
        q_i_hat[:m] = q_hat[:m] + (mw - ma) * self._inv_Rag
        return {"q_hat": q_hat, "q_i_hat": q_i_hat, "dq_i_hat": dq, "r": r}
