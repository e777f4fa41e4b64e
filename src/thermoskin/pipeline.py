"""Observer then detector over a whole log: the offline path of ``thermoskin observe``."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from thermoskin.detector import ContactDetector, ContactEvent
from thermoskin.observer import ThermalExchangeObserver
from thermoskin.params import Config

INPUT_COLUMNS = ("t", "T_w", "T_p", "v", "T_a")


@dataclass
class Observation:
    """Per-sample outputs (``q_i_hat, dq_i_hat, contact, gap``) and the detected events."""

    columns: dict[str, NDArray[np.float64]]
    events: list[ContactEvent]


def observe(log: dict[str, NDArray[np.float64]], cfg: Config,
            t_s: float | None = None) -> Observation:
    """Run the observer (vectorised) and the detector over ``log`` (columns of MODEL.md).

    ``t_s`` defaults to the configured sampling time; pass the log's own interval for a
    log sampled at another rate.
    """
    t_s = cfg.sampling.t_s if t_s is None else t_s
    obs = ThermalExchangeObserver(cfg.skin, cfg.observer, t_s)
    o = obs.run(log["T_w"], log["T_p"], log["v"], log["T_a"])
    det = ContactDetector(cfg.detector, t_s)
    contact = det.run(np.asarray(log["t"], dtype=float), o.r, o.dq_i_hat, o.gap | ~o.ready)
    cols = {"q_i_hat": o.q_i_hat, "dq_i_hat": o.dq_i_hat, "contact": contact,
            "gap": o.gap.astype(np.int8)}
    return Observation(columns=cols, events=det.events)
