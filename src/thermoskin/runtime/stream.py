"""Feed samples one by one through the observer and the detector, as a live loop does.

This is the per-sample path of ``thermoskin run``: the same ``step`` calls a loop on
hardware makes, with a listener told of each contact as it starts and ends. Over a whole
log it gives the same result as the vectorised ``pipeline.observe``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from thermoskin.detector import ContactEvent
from thermoskin.estimator import TouchEstimator
from thermoskin.params import Config
from thermoskin.pipeline import Observation


def stream(log: dict[str, NDArray[np.float64]], cfg: Config, *,
           on_start: Callable[[float], None] | None = None,
           on_event: Callable[[ContactEvent], None] | None = None,
           progress: Callable[[float], None] | None = None) -> Observation:
    """Observer and detector ``step`` per sample over ``log``; callbacks as contacts occur."""
    est = TouchEstimator(cfg)
    obs, det = est.observer, est.detector
    t, T_w, T_p, v, T_a = (np.asarray(log[k], dtype=float).tolist()
                           for k in ("t", "T_w", "T_p", "v", "T_a"))
    n = len(t)
    q_i_hat = np.empty(n)
    dq_i_hat = np.empty(n)
    contact = np.zeros(n, dtype=np.int8)
    gap = np.zeros(n, dtype=np.int8)
    every = max(1, n // 200)
    est_step = est.step
    for k in range(n):
        contact[k] = est_step(t[k], T_w[k], T_p[k], v[k], T_a[k])
        q_i_hat[k] = obs.q_i_hat
        dq_i_hat[k] = obs.dq_i_hat
        gap[k] = obs.gap
        if det.started and on_start is not None:
            on_start(t[k])
        if det.ended and on_event is not None:
            on_event(det.events[-1])
        if progress is not None and k % every == 0:
            progress(k / n)
    if n:
        n_events = len(det.events)
        det.finish(t[-1])
        if on_event is not None and len(det.events) > n_events:
            on_event(det.events[-1])
    if progress is not None:
        progress(1.0)
    cols = {"q_i_hat": q_i_hat, "dq_i_hat": dq_i_hat, "contact": contact, "gap": gap}
    return Observation(columns=cols, events=det.events)
