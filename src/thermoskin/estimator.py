"""Touch estimation as one block: the paper's observer (eq. 8) and the sensor-aware estimator.

Per sample (``step``, the live loop) or over a whole log (``run``, offline), with the same
compiled kernel (:mod:`thermoskin.estimation.kernel`), so the two agree bit for bit:

- ``q_i_hat``: the paper's thermal exchange observer, eq. 8 with its ``q_ag`` correction
  (:class:`~thermoskin.observer.ThermalExchangeObserver`), kept as the paper defines it;
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
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from thermoskin.estimation import kernel as K  # noqa: N812
from thermoskin.estimation.model import ModelTables, build_tables
from thermoskin.observer import ThermalExchangeObserver
from thermoskin.params import Config

Array = NDArray[np.float64]

#: Columns of the events table (``--events``): s, s, s, s, +1/-1, W, W, J.
EVENT_COLUMNS = ("onset", "detected", "release", "duration", "sign", "peak_dq", "mean_dq", "energy")


@dataclass(frozen=True)
class ContactEvent:
    """One detected contact. Times in s; heat flows (signed: negative when heat leaves the
    skin, a cold object) in W; energy in J; ``sign`` +1 (heat in) or -1 (heat out)."""

    onset: float
    detected_at: float
    release: float
    duration: float
    sign: int
    peak_dq: float
    mean_dq: float
    energy: float

    def as_dict(self) -> dict[str, float]:
        return asdict(self)

    def row(self) -> dict[str, float]:
        """The event as a row of :data:`EVENT_COLUMNS`."""
        return {"onset": self.onset, "detected": self.detected_at, "release": self.release,
                "duration": self.duration, "sign": self.sign, "peak_dq": self.peak_dq,
                "mean_dq": self.mean_dq, "energy": self.energy}

    @classmethod
    def from_kernel(cls, ev: Array) -> ContactEvent:
        return cls(onset=float(ev[K.EV_ONSET]), detected_at=float(ev[K.EV_DETECTED]),
                   release=float(ev[K.EV_RELEASE]), duration=float(ev[K.EV_DURATION]),
                   sign=int(ev[K.EV_SIGN]), peak_dq=float(ev[K.EV_PEAK]),
                   mean_dq=float(ev[K.EV_MEAN]), energy=float(ev[K.EV_ENERGY]))


def kernel_params(cfg: Config, tables: ModelTables) -> Array:
    """The kernel's parameter vector for ``cfg`` at the tables' sampling time."""
    d, t_s = cfg.detector, tables.t_s
    pr = np.zeros(K.NPARAM)
    n_warm = max(2, round(d.t_warmup / t_s))
    pr[K.PR_TS] = t_s
    pr[K.PR_RT] = tables.R_T
    pr[K.PR_AMB] = tables.amb_idx
    pr[K.PR_K] = d.k_drift
    pr[K.PR_H] = d.h_on
    pr[K.PR_KOFF] = d.k_off
    pr[K.PR_FOFF] = d.f_off
    pr[K.PR_HOFF] = d.h_off
    pr[K.PR_KREL] = d.k_rel
    pr[K.PR_ALVL] = min(1.0, t_s / d.tau_level)
    pr[K.PR_NWARM] = n_warm
    pr[K.PR_WSTRIDE] = max(1, math.ceil(n_warm / K.NWB))
    pr[K.PR_TREF] = d.t_refractory
    pr[K.PR_TSETTLE] = d.t_settle
    pr[K.PR_AB] = min(1.0, t_s / d.tau_baseline)
    pr[K.PR_AS] = min(1.0, t_s / d.tau_sigma)
    pr[K.PR_NMAX] = max(1, round(d.max_contact_s / t_s))
    pr[K.PR_MAXGAP] = max(1, round(cfg.estimator.max_gap_s / t_s))
    pr[K.PR_P0Q] = 1.0
    pr[K.PR_RG] = cfg.skin.R_g
    pr[K.PR_RAG] = cfg.skin.R_ag
    pr[K.PR_BAND] = d.arm_band
    pr[K.PR_NARM] = max(1, round(d.t_arm / t_s))
    return pr


@dataclass
class Observation:
    """Per-sample outputs (``q_i_hat, dq_i_hat, sd, contact, gap``) and the detected events."""

    columns: dict[str, Array]
    events: list[ContactEvent]


class TouchEstimator:
    """Eq. 8, the sensor-aware estimate and the detector of one patch, stepped together."""

    def __init__(self, cfg: Config, t_s: float | None = None,
                 v_values: tuple[float, ...] = ()) -> None:
        self.cfg = cfg
        self.t_s = cfg.sampling.t_s if t_s is None else float(t_s)
        self.observer = ThermalExchangeObserver(cfg.skin, cfg.observer, self.t_s)
        self._build((0.0, cfg.pump.v_on, *v_values))
        self._ev = np.zeros(K.NEV)
        self.reset()

    def _build(self, v_values: tuple[float, ...]) -> None:
        self.tables = build_tables(self.cfg, self.t_s, v_values)
        tb = self.tables
        self._tabs = (tb.Phi, tb.Gam, tb.Q, tb.Phi_a, tb.Q_a)
        self._iv = {v: i for i, v in enumerate(tb.v_values)}
        self.pr = kernel_params(self.cfg, tb)

    def _index(self, v: float) -> int:
        """Table row of ``v``; a velocity not seen before gets its tables now."""
        i = self._iv.get(v)
        if i is None:
            self._build((*self.tables.v_values, float(v)))
            i = self._iv[v]
        return i

    def reset(self) -> None:
        """Everything afresh; disarmed until the set-point is held (if there is one)."""
        self.observer.reset()
        self.st = K.new_state()
        self.events: list[ContactEvent] = []
        self.contact = 0
        self.started = self.ended = False
        self.q_i_hat = math.nan

    # -- outputs ----------------------------------------------------------------------------
    @property
    def dq_i_hat(self) -> float:
        """The touch's heat into the sheet minus its no-touch baseline, W."""
        return float(self.st[K.DQ])

    @property
    def sd(self) -> float:
        """Standard deviation of the estimate (the Kalman filter's), W."""
        return float(self.st[K.SQ])

    @property
    def gap(self) -> bool:
        """A reading is NaN at this sample (held over)."""
        return bool(self.st[K.GAP])

    @property
    def armed(self) -> bool:
        return bool(self.st[K.ARMED])

    # -- streaming --------------------------------------------------------------------------
    def step(self, t: float, T_w: float, T_p: float, v: float, T_a: float,
             T_w_cmd: float = math.nan, fresh: int = 7) -> int:
        """One sample (``v`` the pump command applied from ``t`` on; ``fresh`` the bitmask of
        channels with a new reading: 1 ``T_w``, 2 ``T_p``, 4 ``T_a``); returns ``contact``."""
        self.q_i_hat = self.observer.step(T_w, T_p, v, T_a)
        iv = self._iv.get(v)
        if iv is None:
            iv = self._index(v)
        code = K.step(self.st, self.pr, *self._tabs, t, T_w, T_p, T_a, T_w_cmd, iv, fresh, self._ev)
        self.started = bool(code & K.C_STARTED)
        self.ended = bool(code & K.C_ENDED)
        if self.ended:
            self.events.append(ContactEvent.from_kernel(self._ev))
        self.contact = code & K.C_CONTACT
        return self.contact

    def finish(self, t: float) -> None:
        """End a contact still open at ``t`` (the end of a run or a log)."""
        if K.finish(self.st, t, self._ev):
            self.events.append(ContactEvent.from_kernel(self._ev))
            self.contact = 0

    # -- arrays -----------------------------------------------------------------------------
    def run(self, t: Array, T_w: Array, T_p: Array, v: Array, T_a: Array,
            T_w_cmd: Array | None = None, fresh: Any = None) -> Observation:
        """``reset``, then every sample, then ``finish``: equal to ``step`` per sample."""
        self.reset()
        t, T_w, T_p, v, T_a = (np.ascontiguousarray(x, dtype=float) for x in (t, T_w, T_p, v, T_a))
        n = len(t)
        cmd = np.full(n, math.nan) if T_w_cmd is None else np.ascontiguousarray(T_w_cmd, dtype=float)
        fr = (np.full(n, 7, dtype=np.int64) if fresh is None
              else np.ascontiguousarray(fresh, dtype=np.int64))
        vals, inv = np.unique(v, return_inverse=True)
        idx = np.array([self._index(float(x)) for x in vals], dtype=np.int64)
        iv = idx[inv] if n else np.zeros(0, dtype=np.int64)
        o = self.observer.run(T_w, T_p, v, T_a)
        dq, q, sq, contact = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
        events = np.empty((max(16, n // 100), K.NEV))
        ne = K.run(self.st, self.pr, *self._tabs, t, T_w, T_p, T_a, cmd, iv, fr, dq, q, sq, contact,
                   events)
        self.events = [ContactEvent.from_kernel(events[i]) for i in range(min(ne, len(events)))]
        if n:
            self.finish(float(t[-1]))
        cols = {"q_i_hat": o.q_i_hat, "dq_i_hat": dq, "sd": sq,
                "contact": contact.astype(np.int8), "gap": o.gap.astype(np.int8)}
        return Observation(columns=cols, events=list(self.events))
