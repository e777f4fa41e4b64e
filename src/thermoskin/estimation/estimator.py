"""Touch estimation as one block: the paper's observer (eq. 8) and the sensor-aware estimator.

Per sample (``step``, the live loop) or over a whole log (``run``, offline), with the same
compiled kernel (:mod:`thermoskin.estimation.kernel`), so the two agree bit for bit:

- ``q_i_hat``: the paper's thermal exchange observer, eq. 8 with its ``q_ag`` correction
  (:class:`~thermoskin.estimation.observer.ThermalExchangeObserver`), kept as the paper defines it;
- ``dq_i_hat``: the touch's heat into the sheet, W, from a Kalman filter on the network of
  Fig. 3 that updates only on fresh readings (:mod:`thermoskin.estimation.model`), minus its
  no-touch baseline; its standard deviation ``sd``;
- ``contact`` and the events of a two-sided detector on that estimate (a warm body heats
  the skin, a cold object cools it; every event carries its sign).

In a loop that holds the skin at a command, detection is armed once ``T_w`` has stayed
within ``detector.arm_band`` of ``T_w_cmd`` for ``detector.t_arm`` s: while the skin warms
from ambient the estimate's start would otherwise become the detector's baseline. Without
a command (``T_w_cmd`` NaN) it is armed from the first sample.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from thermoskin.estimation import kernel as K  # noqa: N812
from thermoskin.estimation.events import ContactEvent
from thermoskin.estimation.learnt import Learnt, learnt
from thermoskin.estimation.model import ModelTables, build_tables, measurement_variance
from thermoskin.estimation.observer import ThermalExchangeObserver
from thermoskin.estimation.redate import Redater
from thermoskin.estimation.redate import load as redate_load
from thermoskin.params import Config
from thermoskin.physics.convection import FlowResistance

Array = NDArray[np.float64]

def kernel_params(cfg: Config, tables: ModelTables, eq8: ThermalExchangeObserver) -> Array:
    """The kernel's parameter vector for ``cfg`` at the tables' sampling time (``eq8``: the
    paper's observer at that time, whose discretised filters the kernel runs)."""
    d, t_s = cfg.detector, tables.t_s
    pr = np.zeros(K.NPARAM)
    n_warm = max(2, round(d.t_warmup / t_s))
    pr[K.PR_TS] = t_s
    pr[K.PR_RT] = tables.R_T
    pr[K.PR_AMB] = tables.amb_idx
    pr[K.PR_D] = d.dq_design
    pr[K.PR_H] = d.h_on
    pr[K.PR_KOFF] = d.k_off
    pr[K.PR_FOFF] = d.f_off
    pr[K.PR_HOFF] = d.h_off
    pr[K.PR_KREL] = d.k_rel
    pr[K.PR_ALVL] = min(1.0, t_s / d.tau_level)
    pr[K.PR_NWARM] = n_warm
    pr[K.PR_WSTRIDE] = max(1, math.ceil(n_warm / K.NWB))
    pr[K.PR_S0] = d.z_scale
    pr[K.PR_HSLOPE] = d.h_rate
    pr[K.PR_HMIN] = d.h_min
    pr[K.PR_ARATE] = 0.05
    pr[K.PR_TCMD] = 2.0
    pr[K.PR_AJUMP] = 1.0
    pr[K.PR_KAIR] = 1.0
    pr[K.PR_HAIR] = 8.0
    pr[K.PR_ASLMAX] = d.air_rate
    pr[K.PR_MEANMIN] = d.confirm_mean * d.dq_design_lo
    pr[K.PR_EMIN] = d.confirm_mean * d.dq_design_lo * d.confirm_time
    pr[K.PR_TRETR] = 1.0
    pr[K.PR_TCONF] = d.t_confirm
    pr[K.PR_TPAIR] = d.t_pair
    pr[K.PR_RELN] = d.release_readings
    pr[K.PR_DLO] = d.dq_design_lo
    pr[K.PR_HLO] = d.h_lo
    pr[K.PR_OSJ] = d.onset_state_jump
    pr[K.PR_GLR] = d.onset_glr
    pr[K.PR_GPOOL] = d.onset_glr_pool
    pr[K.PR_DHI] = d.dq_design_hi
    # a log coarser than the loop holds each pump switch up to one of its intervals late
    pr[K.PR_VSW] = 0.29 if t_s > 1.5 * cfg.sampling.t_s else 0.0
    pr[K.PR_ICW] = 1.0 / cfg.skin.C_w
    pr[K.PR_NPH] = cfg.estimator.switch_bins
    pr[K.PR_APH] = cfg.estimator.switch_learn
    pr[K.PR_TAMBH] = d.t_air + cfg.sensor.lag_T_a
    F1, F2 = eq8.filters
    (pr[K.PR_F1B0], pr[K.PR_F1B1], pr[K.PR_F1B2]), (_, pr[K.PR_F1A1], pr[K.PR_F1A2]) = F1.b, F1.a
    pr[K.PR_F1DC] = F1.dc
    (pr[K.PR_F2B0], pr[K.PR_F2B1]), (_, pr[K.PR_F2A1]) = F2.b, F2.a
    pr[K.PR_F2DC] = F2.dc
    pr[K.PR_IRAW] = 1.0 / cfg.skin.R_aw
    pr[K.PR_IRAG] = 1.0 / cfg.skin.R_ag
    pr[K.PR_NINIT] = cfg.observer.n_init
    pr[K.PR_MAXGAP8] = max(1, round(cfg.observer.max_gap_s / t_s))
    pr[K.PR_CMAN] = cfg.estimator.tank_jump
    pr[K.PR_TMAN] = cfg.estimator.tank_jump_s
    pr[K.PR_TREF] = d.t_refractory
    pr[K.PR_TSETTLE] = d.t_settle
    pr[K.PR_AB] = min(1.0, 1.25 * t_s / d.tau_baseline)
    eta = min(0.5, 2.0 * t_s / d.tau_sigma)
    pr[K.PR_UP] = math.exp(0.5 * eta)
    pr[K.PR_DOWN] = math.exp(-0.5 * eta)
    pr[K.PR_NMAX] = max(1, round(d.max_contact_s / t_s))
    pr[K.PR_MAXGAP] = max(1, round(cfg.estimator.max_gap_s / t_s))
    pr[K.PR_P0Q] = 1.0
    pr[K.PR_RG] = cfg.skin.R_g
    pr[K.PR_RAG] = cfg.skin.R_ag
    pr[K.PR_BAND] = d.arm_band
    pr[K.PR_NARM] = max(1, round(d.t_arm / t_s))
    # what is learnt of the sensors: their priors (the configuration) and how fast
    sn, es = cfg.sensor, cfg.estimator
    pr[K.PR_RW0] = measurement_variance(cfg, "T_w")
    pr[K.PR_RP0] = measurement_variance(cfg, "T_p")
    pr[K.PR_RA0] = measurement_variance(cfg, "T_a")
    pr[K.PR_OFW], pr[K.PR_OFP], pr[K.PR_OFA] = sn.offset_T_w, sn.offset_T_p, sn.offset_T_a
    pr[K.PR_BD0] = 0.0
    # the slow states learn from logs of 100 Hz and faster only: at 50 Hz the pump switches
    # between rows and the model's misfit there looks like an offset (0.1 K learnt where there
    # was none, the detector's evidence drowned in its uncertainty)
    slow_ok = t_s <= K.SLOW_TS_MAX
    pr[K.PR_PB0] = sn.offset_sd**2 if slow_ok else 0.0
    pr[K.PR_SB] = es.offset_drift
    pr[K.PR_TAUR] = es.tau_noise
    pr[K.PR_LEARN] = 1.0
    pr[K.PR_RMIN] = 400.0
    pr[K.PR_RHOW] = d.rho_window
    pr[K.PR_RHOETA] = 0.03
    pr[K.PR_RHOWL] = d.rho_window_long
    pr[K.PR_RHOPH] = float(d.rho_phases)
    pr[K.PR_RELPH] = float(d.release_phases)
    pr[K.PR_DOORQ] = float(d.door_follow)
    pr[K.PR_PBTOL] = es.phase_tol
    pr[K.PR_RHODB] = d.rho_deadband
    pr[K.PR_RHOSET] = 0.5
    pr[K.PR_LAG0] = sn.lag_T_w
    pr[K.PR_PT0] = sn.lag_sd**2 if slow_ok else 0.0
    pr[K.PR_ST] = es.lag_drift
    pr[K.PR_TAUMAX] = max(es.lag_max, sn.lag_T_w)
    pr[K.PR_DBMAX] = 1e-3  # K a reading: 1 K/s at 1 kHz
    pr[K.PR_DTMAX] = 5e-4  # s a reading: 0.5 s/s at 1 kHz
    pr[K.PR_LDELAY] = 0.5
    pr[K.PR_SWIN] = 0.4
    pr[K.PR_RSLOT] = 0.5
    pr[K.PR_RFAST] = K.FAST_READINGS
    pr[K.PR_RHOPB] = 0.03**2
    pr[K.PR_RHOPT] = 0.01**2
    pr[K.PR_RHODB_] = 0.02
    pr[K.PR_RHODT] = 0.005
    pr[K.PR_RHOEARLY] = 10.0
    pr[K.PR_RHO0] = d.rho_prior
    pr[K.PR_RHOCAP] = 1e6
    pr[K.PR_SLOWCU] = 0.25
    # converter steps up to twice the pipe reading's configured sd are dithered by the noise
    pr[K.PR_QFINE] = K.QFINE_SD * math.sqrt(pr[K.PR_RW0])
    pr[K.PR_SLOWON] = 1.0 if (pr[K.PR_PB0] > 0 or pr[K.PR_PT0] > 0 or sn.lag_T_w > 0) else 0.0
    pr[K.PR_AIR] = min(1.0, t_s / 10.0)
    return pr


@dataclass
class Observation:
    """Per-sample outputs (``q_i_hat, dq_i_hat, sd, contact, gap``) and the detected events."""

    columns: dict[str, Array]
    events: list[ContactEvent]


def warm_up(cfg: Config, fits: bool = True) -> None:
    """Load what estimation needs (numba, the compiled kernel and, with ``fits``, the fit at a
    contact's end from its cache, the water's properties for the tables; about half a second)
    by running a two-sample estimate: a caller that has other work in flight meanwhile
    (``observe`` reading ahead) hides that time. Without ``fits`` the fit is loaded at the
    first contact's end (about 20 ms then; an offline caller, which no sample waits for)."""
    t_s = cfg.sampling.t_s
    x = np.full(2, 24.0)
    est = TouchEstimator(cfg)
    est.feed(np.array([0.0, t_s]), x, x, np.zeros(2), x, T_w_cmd=x)
    if fits and cfg.detector.redate_readings > 0:
        redate_load(est)  # the fit at a contact's end, compiled


class TouchEstimator:
    """Eq. 8, the sensor-aware estimate and the detector of one patch, stepped together.

    ``step`` (one sample, the live loop), ``feed`` (a chunk of a log, continuing) and
    ``run`` (a whole log) all run :func:`thermoskin.estimation.kernel.step`.
    """

    def __init__(self, cfg: Config, t_s: float | None = None,
                 v_values: tuple[float, ...] = (), background_fits: bool = False) -> None:
        """``background_fits``: a contact's re-dating fit, due live in :meth:`step`, runs in a
        worker thread; its event comes at a later sample (the same event; see
        :mod:`~thermoskin.estimation.redate`). For a realtime loop, whose sample must not wait
        for it."""
        self.cfg = cfg
        self.background_fits = background_fits
        self.t_s = cfg.sampling.t_s if t_s is None else float(t_s)
        if not (math.isfinite(self.t_s) and self.t_s > 0):
            raise ValueError(f"TouchEstimator: t_s = {t_s} s must be > 0")
        self._eq8 = ThermalExchangeObserver(cfg.skin, cfg.observer, self.t_s)
        self._R_w = FlowResistance(cfg.skin)
        self._build((0.0, cfg.pump.v_on, *v_values))
        self._ev = np.zeros(K.NEV)
        self._b_cfg = cfg.sensor.offset_T_p - cfg.sensor.offset_T_w
        self.reset()

    def _build(self, v_values: tuple[float, ...]) -> None:
        self.tables = build_tables(self.cfg, self.t_s, v_values)
        tb = self.tables
        Rw = np.array([self._R_w(v) for v in tb.v_values])
        self.tabs = (tb.Phi, tb.Gam, tb.Q_idle, tb.Q, tb.Phi_a, tb.Q_a, Rw)
        self._iv = {v: i for i, v in enumerate(tb.v_values)}
        self.pr = kernel_params(self.cfg, tb, self._eq8)

    def _index(self, v: float) -> int:
        """Table row of ``v`` (-1 for NaN); a velocity not seen before gets its tables now."""
        i = self._iv.get(v)
        if i is None:
            if v != v:
                return -1
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"pump velocity v = {v!r} m/s must be >= 0 and finite")
            self._build((*self.tables.v_values, float(v)))
            i = self._iv[v]
        return i

    def rows_of(self, v: Array) -> NDArray[np.int64]:
        """Table rows of an array of pump velocities (-1 for NaN)."""
        iv = np.full(len(v), -2, dtype=np.int64)
        for x, i in list(self._iv.items()):
            iv[v == x] = i
        iv[np.isnan(v)] = -1
        for x in np.unique(v[iv == -2]).tolist():  # velocities not seen before: new tables
            iv[v == x] = self._index(float(x))
        return iv

    def reset(self) -> None:
        """Everything afresh; disarmed until the set-point is held (if there is one)."""
        self.st = K.new_state()
        self.events: list[ContactEvent] = []
        old = getattr(self, "_redater", None)
        if old is not None:
            old.close()
        self._redater = (Redater(self.cfg, self.t_s, self.background_fits)
                         if self.cfg.detector.redate_readings > 0 else None)
        #: the events the last :meth:`step` wrote: a contact ended then, or (dated again,
        #: :mod:`~thermoskin.estimation.redate`) a while before
        self.written: list[ContactEvent] | tuple[()] = ()
        self.contact = 0
        self.started = self.ended = False

    # -- outputs ----------------------------------------------------------------------------
    @property
    def q_i_hat(self) -> float:
        """The paper's estimate, eq. 8 with its ``q_ag`` correction, W."""
        return float(self.st[K.QIH])

    @property
    def dq_i_hat(self) -> float:
        """The touch's heat into the sheet minus its no-touch baseline, W."""
        return float(self.st[K.DQ])

    @property
    def sd(self) -> float:
        """Standard deviation of the estimate (the Kalman filter's), W."""
        return float(self.st[K.SQ])

    @property
    def T_g_hat(self) -> float:
        """The estimated sheet temperature, degC (the Kalman filter's state)."""
        return float(self.st[K.X + 1])

    @property
    def switch_table(self) -> NDArray[np.float64]:
        """The pump-cycle correction as it stands (``estimator.switch_bins``; a view), K."""
        return self.st[K.TPL:K.TPL + 2 * K.NPH]

    @property
    def b_p_hat(self) -> float:
        """The T_p readings' offset against the T_w readings (configured and learnt), K."""
        return float(self.st[K.BD]) + self._b_cfg

    def learnt(self) -> Learnt:
        """What the estimator has learnt of its sensors (:mod:`~thermoskin.estimation.learnt`)."""
        return learnt(self.st, self.cfg)

    @property
    def gap(self) -> bool:
        """A reading is NaN at this sample (held over)."""
        return bool(self.st[K.GAP])

    @property
    def armed(self) -> bool:
        return bool(self.st[K.ARMED])

    # -- streaming --------------------------------------------------------------------------
    def step(self, t: float, T_w: float, T_p: float, v: float, T_a: float,
             T_w_cmd: float = math.nan, fresh: int = 7, drive: float = math.nan) -> int:
        """One sample; returns ``contact``. The events it writes are :attr:`written`.

        ``v`` and ``drive``: the pump command and the Peltier drive applied from ``t`` on
        (``drive`` NaN: unknown, the tank is then a constant-velocity model); ``fresh``: the
        bitmask of channels with a new reading (1 ``T_w``, 2 ``T_p``, 4 ``T_a``).
        """
        iv = self._iv.get(v)
        if iv is None:
            iv = self._index(v)
        code = K.step(self.st, self.pr, *self.tabs, t, T_w, T_p, T_a, T_w_cmd, iv, drive, fresh,
                      self._ev)
        self.started = bool(code & K.C_STARTED)
        self.ended = bool(code & K.C_ENDED)
        rd = self._redater
        self.written = ()
        if rd is None:
            if self.ended:
                self.written = [ContactEvent.from_kernel(self._ev)]
        else:
            rd.push((t, T_w, T_p, T_a, T_w_cmd, iv, drive, fresh))
            if self.background_fits and rd.busy:  # fits done in the background, in order
                self.written = rd.ready()
            if self.started or self.ended or t >= rd.due:
                self.written = [*self.written, *rd.on_row(
                    self, rd.n - 1, t, self.st[K.ONSET] if self.started else math.nan,
                    ContactEvent.from_kernel(self._ev) if self.ended else None,
                    learnt=self._ev if self.ended else None)]
        if self.written:
            self.events.extend(self.written)
        self.contact = code & K.C_CONTACT
        return self.contact

    def finish(self, t: float) -> None:
        """End a contact still open at ``t`` (the end of a run or a log)."""
        rd = self._redater
        if rd is not None:
            self.events.extend(rd.flush(self))
        if K.finish(self.st, t, self._ev):
            e = ContactEvent.from_kernel(self._ev)
            self.events.append(e if rd is None else rd.redate(self, e, rd.n - 1, math.inf,
                                                              open_end=True, learnt=self._ev))
            self.contact = 0

    # -- arrays -----------------------------------------------------------------------------
    def feed(self, t: Array, T_w: Array, T_p: Array, v: Array, T_a: Array,
             T_w_cmd: Array | None = None, fresh: Any = None, drive: Array | None = None
             ) -> tuple[dict[str, Array], list[ContactEvent]]:
        """The next chunk of a log (continuing from the last sample stepped): per-sample
        columns ``q_i_hat, dq_i_hat, sd, contact, gap`` (and the filter's ``T_g_hat``, the
        sheet's temperature, with ``cov_qg``, the covariance of the ``q_i`` and ``T_g``
        estimates; ``b_p_hat`` and ``b_p_sd``, the T_p readings' offset against the T_w
        readings, configured and learnt, K) and the contacts that ended in it."""
        t, T_w, T_p, v, T_a = (np.ascontiguousarray(x, dtype=float) for x in (t, T_w, T_p, v, T_a))
        n = len(t)
        cmd = np.full(n, math.nan) if T_w_cmd is None else np.ascontiguousarray(T_w_cmd, dtype=float)
        drv = np.full(n, math.nan) if drive is None else np.ascontiguousarray(drive, dtype=float)
        fr = (np.full(n, 7, dtype=np.int64) if fresh is None
              else np.ascontiguousarray(fresh, dtype=np.int64))
        iv = self.rows_of(v)
        rd = self._redater
        out = np.empty((K.NOUT, n))
        events = np.empty((max(16, n // 50), K.NEV))
        marks = np.empty((2 * len(events), 3))
        ne, nm = K.run(self.st, self.pr, *self.tabs, t, T_w, T_p, T_a, cmd, iv, drv, fr, out,
                       events, self._ev, marks)
        new = [ContactEvent.from_kernel(events[i]) for i in range(min(ne, len(events)))]
        if rd is not None:
            new = self._redate_chunk(rd, new, (t, T_w, T_p, T_a, cmd, iv, drv, fr),
                                     marks[:min(nm, len(marks))], events)
        self.events.extend(new)
        self.contact = int(self.st[K.CONTACT])
        cols = {"q_i_hat": out[0], "dq_i_hat": out[1], "sd": out[3],
                "contact": out[4].astype(np.int8), "gap": out[5].astype(np.int8),
                "T_g_hat": out[6], "cov_qg": out[7], "b_p_hat": out[8] + self._b_cfg, "b_p_sd": out[9]}
        return cols, new

    def _redate_chunk(self, rd: Redater, ended: list[ContactEvent], block: tuple[Array, ...],
                      marks: Array, records: Array) -> list[ContactEvent]:
        """The chunk's rows where a contact started or ended (``marks``: row, bits, onset), or
        the waiting one fell due, in order, as :meth:`step` hands them to the re-dating one
        sample at a time."""
        t = block[0]
        n0 = rd.n
        it = iter(ended)
        ie = 0  # the next ended contact's kernel record
        written: list[ContactEvent] = []
        pos, im = 0, 0
        while True:
            k = int(marks[im, 0]) if im < len(marks) else len(t)
            if rd.pending is not None:
                k = min(k, pos + int(np.searchsorted(t[pos:], rd.due, side="left")))
            if k >= len(t):
                break
            c = int(marks[im, 1]) if im < len(marks) and marks[im, 0] == k else 0
            learnt = None
            if c & K.C_ENDED:
                learnt = records[ie]
                ie += 1
            written.extend(rd.on_row(self, n0 + k, float(t[k]),
                                     float(marks[im, 2]) if c & K.C_STARTED else math.nan,
                                     next(it) if c & K.C_ENDED else None, block, n0, learnt))
            if c:
                im += 1
            pos = k + 1
        rd.push_block(block)
        return written

    def run(self, t: Array, T_w: Array, T_p: Array, v: Array, T_a: Array,
            T_w_cmd: Array | None = None, fresh: Any = None, drive: Array | None = None) -> Observation:
        """``reset``, then every sample, then ``finish``: equal to ``step`` per sample."""
        self.reset()
        cols, _ = self.feed(t, T_w, T_p, v, T_a, T_w_cmd, fresh, drive)
        if len(t):
            self.finish(float(np.asarray(t, dtype=float)[-1]))
        return Observation(columns=cols, events=list(self.events))
