"""Touch detection on the observer's contact residual.

The detector works on ``r`` (W), the heat a touch adds to the pipe through the sheet, as
the observer computes it from the no-touch network (``observer.py``): with no touch it is
zero whatever the pump and the set-point do, so a touch is a step of ``r`` in noise.

- Baseline ``b`` and noise ``sigma`` of ``r``: learnt over the first ``t_warmup`` seconds
  (median and median absolute deviation, robust to a stray spike), then exponential
  averages (``tau_baseline``, ``tau_sigma``) updated only while idle, so
  a long touch is never swallowed; ``sigma`` may be fixed by config instead.
- Onset: a one-sided CUSUM (Page's test) on the standardised residual,
  ``g <- max(0, g + (r - b - k_drift sigma) t_s)``, fires when ``g > h_on sigma``: a large
  step is caught in a few ms, a small one after it has accrued the same evidence. The
  event's ``onset`` is back-dated to the last sample at which ``g`` was zero.
- Release: ``r - b < max(k_off sigma, f_off * peak)`` held for ``t_off``.
- After a release, ``t_refractory`` with no onset and no learning; the slow estimate
  ``dq_i_hat`` keeps decaying for several ``R_g C_w``, so its baseline waits ``t_settle``.

Each contact is characterised on ``dq_i_hat`` (the change of the paper's estimate from its
no-touch value, W) minus its baseline at onset: peak, mean and energy (J) over the contact.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from thermoskin.params import DetectorParams

IDLE, CONTACT, REFRACTORY = 0, 1, 2


@dataclass(frozen=True)
class ContactEvent:
    """One detected contact. Times in s, heat flows in W, energy in J."""

    onset: float
    detected_at: float
    release: float
    duration: float
    peak_dq: float
    mean_dq: float
    energy: float
    peak_r: float

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


class ContactDetector:
    """Streaming contact detector (``step``); ``run`` applies it over arrays."""

    def __init__(self, params: DetectorParams | None = None, t_s: float = 1e-3) -> None:
        p = self.params = params or DetectorParams()
        self.t_s = t_s
        self._n_warm = max(2, round(p.t_warmup / t_s))
        self._n_off = max(1, round(p.t_off / t_s))
        self._n_ref = round(p.t_refractory / t_s)
        self._n_settle = round(p.t_settle / t_s)
        self._n_max = round(p.max_contact_s / t_s)
        self._a_b = t_s / p.tau_baseline
        self._a_s = t_s / p.tau_sigma
        self.reset()

    def reset(self) -> None:
        """Forget everything: the next ``t_warmup`` seconds are learnt as no-touch."""
        self.events: list[ContactEvent] = []
        self.mode = IDLE
        self.contact = 0
        self.started = self.ended = False
        self._n = 0
        self._warm = np.empty(self._n_warm)
        self._mean_dq = 0.0
        self.b = self.b_dq = 0.0
        fixed = self.params.sigma
        self.sigma = fixed if fixed is not None else math.inf
        self._var = self.sigma**2
        self._run = 0
        self._g = 0.0
        self._t_quiet = 0.0
        self._since = 0
        self._since_release = 1 << 62
        self._onset = self._detected = self._t_first_below = 0.0
        self._peak_r = self._peak_dq = self._sum_dq = 0.0
        self._b_dq_onset = 0.0
        self._count = 0

    def step(self, t: float, r: float, dq: float, gap: bool = False) -> int:
        """One sample: ``t`` (s), residual ``r`` (W), ``dq`` = ``dq_i_hat`` (W). Returns 0/1."""
        self.started = self.ended = False
        if gap or r != r or dq != dq:
            return self.contact
        p = self.params
        self._since_release += 1
        if self._n < self._n_warm:  # learning the no-touch baseline and noise
            self._warm[self._n] = r
            self._n += 1
            self._mean_dq += (dq - self._mean_dq) / self._n
            self.b_dq = self._mean_dq
            if self._n == self._n_warm:
                self._learnt()
            self._t_quiet = t
            return 0
        s = r - self.b
        sig = self.sigma
        if self.mode == CONTACT:
            return self._in_contact(t, s, dq, sig)
        if self.mode == REFRACTORY:
            self._since += 1
            if self._since >= self._n_ref:
                self.mode = IDLE
            self._learn_dq(dq)
            return 0
        # idle: CUSUM for a rise of r above its baseline
        g = self._g + (s - p.k_drift * sig) * self.t_s
        if g <= 0.0:
            g = 0.0
            self._t_quiet = t
        self._g = g
        if g > p.h_on * sig:
            self._start(t, s, dq)
            return 1
        if g == 0.0:  # no evidence of a touch: learn the baseline and the noise
            self.b += self._a_b * s
            if p.sigma is None:  # clipped, so that a rising edge cannot inflate sigma
                s2 = min(s * s, 9.0 * self._var)
                self._var += self._a_s * (s2 - self._var)
                self.sigma = math.sqrt(self._var)
        self._learn_dq(dq)
        return 0

    def _learnt(self) -> None:
        """End of warm-up: baseline = median, sigma = 1.4826 * median absolute deviation."""
        w = self._warm
        self.b = float(np.median(w))
        if self.params.sigma is None:
            self.sigma = max(1.4826 * float(np.median(np.abs(w - self.b))), 1e-12)
            self._var = self.sigma**2

    def _learn_dq(self, dq: float) -> None:
        if self._since_release >= self._n_settle:
            self.b_dq += self._a_b * (dq - self.b_dq)

    def _start(self, t: float, s: float, dq: float) -> None:
        self.mode = CONTACT
        self.contact = 1
        self.started = True
        self._onset = self._t_quiet
        self._detected = t
        self._g = 0.0
        self._run = 0
        self._since = 0
        self._peak_r = s
        self._b_dq_onset = self.b_dq
        d = dq - self.b_dq
        self._peak_dq = self._sum_dq = d
        self._count = 1

    def _in_contact(self, t: float, s: float, dq: float, sig: float) -> int:
        p = self.params
        self._since += 1
        if s > self._peak_r:
            self._peak_r = s
        d = dq - self._b_dq_onset
        if d > self._peak_dq:
            self._peak_dq = d
        self._sum_dq += d
        self._count += 1
        limit = max(p.k_off * sig, p.f_off * self._peak_r)
        if s < limit:
            if self._run == 0:
                self._t_first_below = t
            self._run += 1
            if self._run >= self._n_off:
                self._end(self._t_first_below, rebaseline=False)
                return 0
        else:
            self._run = 0
        if self._since >= self._n_max:  # a drift, not a touch: end it and relearn
            self._end(t, rebaseline=True)
            self.b += s
            return 0
        return 1

    def _end(self, t_release: float, rebaseline: bool) -> None:
        n = self._count
        mean = self._sum_dq / n
        self.events.append(ContactEvent(
            onset=self._onset, detected_at=self._detected, release=t_release,
            duration=t_release - self._onset, peak_dq=self._peak_dq, mean_dq=mean,
            energy=mean * (t_release - self._onset), peak_r=self._peak_r))
        self.mode = REFRACTORY
        self.contact = 0
        self.ended = True
        self._run = 0
        self._since = 0
        self._since_release = 0
        if rebaseline:
            self._since_release = self._n_settle

    def finish(self, t: float) -> None:
        """End a contact still open at the end of a log (released at ``t``)."""
        if self.mode == CONTACT:
            self._end(t, rebaseline=False)

    def run(self, t: NDArray[np.float64], r: NDArray[np.float64], dq: NDArray[np.float64],
            gap: NDArray[np.bool_] | None = None) -> NDArray[np.int8]:
        """``reset``, then ``step`` over arrays; returns the contact flags. Events in ``events``.

        The detector is a state machine, so this path is the per-sample loop over plain
        floats (about 1 µs a sample); the observer in front of it is vectorised.
        """
        self.reset()
        n = len(t)
        g = np.zeros(n, dtype=bool) if gap is None else np.asarray(gap, dtype=bool)
        out = np.zeros(n, dtype=np.int8)
        step = self.step
        for k, (tk, rk, dk, gk) in enumerate(zip(t.tolist(), r.tolist(), dq.tolist(), g.tolist(),
                                                 strict=True)):
            out[k] = step(tk, rk, dk, gk)
        if n:
            self.finish(float(t[-1]))
        return out
