"""The estimator over a whole log: the offline path of ``thermoskin observe``.

It runs the same compiled kernel as the live loop (:class:`~thermoskin.estimator.TouchEstimator`),
on the log's own sampling interval, with the log's ``T_w_cmd`` (if it has one: the detector
is then armed the way the loop armed it) and the log's ``fresh`` column (if it has one;
otherwise each channel's update rate is read from the data, :mod:`thermoskin.estimation.freshness`).
On a log written by ``thermoskin run`` it therefore reproduces the live estimates and events.

Before the estimator, implausible values (outside the ``[plausible]`` ranges) are dropped
as the loop drops them (:func:`thermoskin.plausible.clean_log`): held over and flagged
``gap``. A sampling interval the estimator cannot work at (outside ``sampling.t_s``'s range)
is refused with :class:`~thermoskin.logio.LogError`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from thermoskin.estimation.freshness import infer_fresh
from thermoskin.estimator import Observation, TouchEstimator
from thermoskin.events import ContactEvent
from thermoskin.logio import LogError
from thermoskin.params import Config, SamplingParams
from thermoskin.plausible import clean_log

INPUT_COLUMNS = ("t", "T_w", "T_p", "v", "T_a")

__all__ = ["INPUT_COLUMNS", "ContactEvent", "Observation", "observe", "sample_interval"]


def sample_interval(t: NDArray[np.float64]) -> float:
    """The log's sampling interval: the median step of ``t`` (s)."""
    t = np.asarray(t, dtype=float)
    if len(t) < 2:
        raise ValueError("a log needs at least 2 samples to have a sampling interval")
    return float(np.median(np.diff(t)))


def check_interval(t_s: float, where: str = "the log") -> None:
    """Refuse a sampling interval outside ``sampling.t_s``'s range (one-line :class:`LogError`)."""
    import dataclasses

    meta = {f.name: f.metadata for f in dataclasses.fields(SamplingParams)}["t_s"]
    if not meta["lo"] <= t_s <= meta["hi"]:
        raise LogError(f"{where} is sampled every {t_s:.3g} s; the estimator works at "
                       f"{meta['lo']:g} to {meta['hi']:g} s per sample")


def observe(log: dict[str, NDArray[np.float64]], cfg: Config, t_s: float | None = None,
            warnings: list[str] | None = None) -> Observation:
    """Estimate and detect over ``log`` (columns of the shared schema).

    ``t_s`` defaults to the log's own sampling interval, so a log at 100 Hz is estimated at
    100 Hz; where that interval is the configured ``sampling.t_s`` (within 0.1 %, the
    rounding of a written time column), the configured value itself, as the live loop used.
    """
    t = np.asarray(log["t"], dtype=float)
    if t_s is None:
        t_s = sample_interval(t)
        if abs(t_s - cfg.sampling.t_s) <= 1e-3 * cfg.sampling.t_s:
            t_s = cfg.sampling.t_s
    check_interval(t_s)
    fresh, _ = infer_fresh(log)
    clean = clean_log(log, cfg)
    if warnings is not None:
        warnings.extend(clean.warnings(cfg))
    log = clean.columns
    est = TouchEstimator(cfg, t_s=t_s)
    res = est.run(t, log["T_w"], log["T_p"], log["v"], log["T_a"],
                  T_w_cmd=log.get("T_w_cmd"), fresh=fresh, drive=log.get("drive"))
    if clean.rejected.any():
        res.columns["gap"] = (res.columns["gap"] | clean.rejected).astype(np.int8)
    return res
