"""The estimator over a whole log: the offline path of ``thermoskin observe``.

It runs the same compiled kernel as the live loop (:class:`~thermoskin.estimation.estimator.TouchEstimator`),
on the log's own sampling interval, with the log's ``T_w_cmd`` (if it has one: the detector
is then armed the way the loop armed it) and the log's ``fresh`` column (if it has one;
otherwise each channel's update rate is read from the data, :mod:`thermoskin.estimation.freshness`).
On a log written by ``thermoskin run`` it therefore reproduces the live estimates and events.

Before the estimator, implausible values (outside the ``[plausible]`` ranges) are dropped
as the loop drops them (:func:`thermoskin.logio.plausible.clean_log`): held over and flagged
``gap``. A sampling interval the estimator cannot work at (outside ``sampling.t_s``'s range)
is refused with :class:`~thermoskin.logio.LogError`.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from thermoskin.estimation.estimator import Observation, TouchEstimator, warm_up
from thermoskin.estimation.events import ContactEvent
from thermoskin.estimation.freshness import (
    FreshInference,
    check_interval,
    infer_fresh,
    loop_t_s,
    sample_interval,
)
from thermoskin.estimation.learnt import Learnt, notices
from thermoskin.logio.plausible import Cleaned, clean_log
from thermoskin.logio.units import Units
from thermoskin.params import Config
from thermoskin.touch.characterise import Characteriser

INPUT_COLUMNS = ("t", "T_w", "T_p", "v", "T_a")

__all__ = ["INPUT_COLUMNS", "ContactEvent", "Observation", "StreamResult", "coarse_log_warnings",
           "last_known", "loop_t_s", "observe", "observe_file", "sample_interval", "stuck_warnings",
           "switch_rows"]

#: The estimator's columns written by :func:`observe_file` (a log that had them keeps its own
#: as ``*_live``).
OUTPUT_COLUMNS = ("q_i_hat", "dq_i_hat", "contact", "gap", "b_p_hat", "b_p_sd")
#: Chunks :func:`observe_file` reads ahead (4 of 262 144 rows: about 50 MiB for six columns).
PREFETCH_CHUNKS = 4


def observe(log: dict[str, NDArray[np.float64]], cfg: Config, t_s: float | None = None,
            warnings: list[str] | None = None) -> Observation:
    """Estimate and detect over ``log`` (columns of the shared schema).

    ``t_s`` defaults to the log's own sampling interval, so a log at 100 Hz is estimated at
    100 Hz; where that interval is the configured ``sampling.t_s`` (within 0.1 %, the
    rounding of a written time column), the configured value itself, as the live loop used.
    """
    t = np.asarray(log["t"], dtype=float)
    if t_s is None:
        t_s = loop_t_s(sample_interval(t), cfg)
    check_interval(t_s)
    fresh, periods = infer_fresh(log)
    clean = clean_log(log, cfg)
    log = clean.columns
    if warnings is not None:
        warnings.extend(clean.warnings(cfg))
        warnings.extend(coarse_log_warnings(t_s, cfg, len(t), switch_rows(log["v"])))
        warnings.extend(stuck_warnings(periods, t_s))
    est = TouchEstimator(cfg, t_s=t_s)
    res = est.run(t, log["T_w"], log["T_p"], log["v"], log["T_a"],
                  T_w_cmd=log.get("T_w_cmd"), fresh=fresh, drive=log.get("drive"))
    if clean.rejected.any():
        res.columns["gap"] = (res.columns["gap"] | clean.rejected).astype(np.int8)
    return res


#: The longest sampling interval the estimator is made for (50 Hz), s.
SLOWEST_T_S = 0.02


def coarse_log_warnings(t_s: float, cfg: Config, rows: int, switch_rows: int) -> list[str]:
    """What a log's rate costs: a line if it is slower than 50 Hz (:data:`SLOWEST_T_S`), and one
    if it is coarser than the loop (``t_s`` over 1.5 ``sampling.t_s``) and the pump switched
    within at least 5 % of its ``rows`` (``switch_rows``: rows whose ``v`` differs from the one
    before): when in such a row the pump switched is not in the log, so the reading after it
    tells little about a touch (``docs/model.md``, Logs coarser than the loop)."""
    out = []
    if t_s > SLOWEST_T_S + 1e-12:
        out.append(f"the log is sampled at {1.0 / t_s:.3g} Hz; the estimator is made for 50 Hz to "
                   "1 kHz: the pump switches faster than this log can show, expect late or missed "
                   "contacts")
    if t_s > 1.5 * cfg.sampling.t_s and rows > 0 and switch_rows >= 0.05 * rows:
        out.append(f"the log is sampled at {1.0 / t_s:.4g} Hz, coarser than the loop "
                   f"({1.0 / cfg.sampling.t_s:.4g} Hz), and the pump switched within "
                   f"{100.0 * switch_rows / rows:.0f} % of its rows: when in a row it switched is "
                   "not logged, so those rows tell little about a touch; a light touch (one "
                   "fingertip) may be found late or missed (log at the loop's rate to keep them)")
    return out


#: A pipe thermocouple whose readings change less often than this looks stuck or disconnected
#: (boards update at 5 Hz or faster, and a working one's noise moves its reading at once, unless
#: its steps are coarse against the noise and the water steady), s.
STUCK_S = 10.0


def stuck_warnings(periods: dict[str, float], t_s: float) -> list[str]:
    """A line per pipe channel (``T_w``, ``T_p``) whose update period (``periods``, in samples of
    ``t_s``, as :class:`~thermoskin.estimation.freshness.FreshInference` finds it from runs of
    repeated values) is over :data:`STUCK_S`: the estimates rest on a reading that does not move."""
    out = []
    for ch in ("T_w", "T_p"):
        p = periods.get(ch, 1.0) * t_s
        if p > STUCK_S:
            out.append(f"{ch} changes only every {p:.3g} s (thermocouple boards update at 5 Hz or "
                       "faster): a stuck or disconnected thermocouple, or one too coarse or without "
                       "noise to show its updates? the estimates and contacts rest on it")
    return out


def switch_rows(v: NDArray[np.float64], v_before: float = math.nan) -> int:
    """Rows whose pump velocity differs from the last known one before them (a NaN is unknown:
    skipped, as the estimator holds the last known pump state over it); ``v_before``: the last
    known velocity before the first row (a previous chunk's, :func:`last_known`)."""
    v = np.asarray(v, dtype=float)
    known = np.concatenate([[v_before], v])
    known = known[~np.isnan(known)]
    return int(np.count_nonzero(np.diff(known)))


def last_known(v: NDArray[np.float64], before: float = math.nan) -> float:
    """The last non-NaN value of ``v`` (``before`` if it has none)."""
    ok = np.flatnonzero(~np.isnan(np.asarray(v, dtype=float)))
    return float(v[ok[-1]]) if len(ok) else before


@dataclass
class StreamResult:
    """What :func:`observe_file` found: the contacts, the log's rate, the channels' update
    periods (samples), gaps, and the largest difference from a log's own estimates."""

    events: list[ContactEvent]
    rows: int
    t_s: float
    periods: dict[str, float]
    gaps: int
    live_q_max_abs_diff: float | None = None
    live_contact_mismatches: int | None = None
    duration_s: float = 0.0
    warnings: list[str] = field(default_factory=list)
    """One line per column with implausible values or with no valid sample at all."""
    learnt: Learnt | None = None
    """What the estimator learnt of the sensors by the log's end."""
    notices: dict[str, str] = field(default_factory=dict)
    """What it says of them (:func:`~thermoskin.estimation.learnt.notices`), once each."""


def _prepared(chunks: Iterable[dict[str, NDArray[np.float64]]], cfg: Config, fresh_inf: FreshInference
              ) -> Iterator[tuple[dict[str, NDArray[np.float64]], NDArray[np.int64], Cleaned, int]]:
    """Each chunk of a log with what the estimator needs of it besides the chunk: its fresh
    bits, its cleaned columns and its pump switches; run in :func:`observe_file`'s reading
    thread, beside the kernel (which releases the GIL), not before it."""
    v_last = math.nan
    for chunk in chunks:
        fresh = fresh_inf.feed(chunk)
        clean = clean_log(chunk, cfg)
        v = clean.columns["v"]
        n_sw = switch_rows(v, v_last)
        v_last = last_known(v, v_last)
        yield chunk, fresh, clean, n_sw


def observe_file(path: str | os.PathLike[str], out: str | os.PathLike[str], cfg: Config,
                 progress: Callable[[int, int | None], None] | None = None, *,
                 characterise: bool = True, compiling: Callable[[], None] | None = None,
                 units: Units | None = None,
                 on_first: Callable[[Learnt], None] | None = None) -> StreamResult:
    """:func:`observe` streamed from a log file to another (CSV or Parquet each), in chunks:
    memory does not grow with the log's length. The output holds every input column, the
    input's own estimates renamed ``*_live``, then ``q_i_hat, dq_i_hat, contact, gap``.
    Implausible values are dropped per chunk as :func:`observe` drops them (a log still being
    written, or cut by a kill, is read to its last whole line). ``characterise``: say what
    touched, per contact as it closes (:mod:`thermoskin.touch.characterise`; about 14 ms a contact);
    False leaves the events' character fields empty. ``compiling``: the kernel is not compiled
    yet (a cold cache), so it is compiled only once the first chunk has passed every check
    (a bad log is one error, not a compile first), and ``compiling()`` is called just before;
    otherwise the kernel is loaded while the first chunk is read. ``units``: the log's units
    (:class:`~thermoskin.logio.units.Units`: converted to seconds and °C as read, or checked).
    ``on_first``: given what the estimator has learnt of the sensors by the end of the first
    chunk (262 144 rows, or the whole of a shorter log), its one-finger SNR included: said at
    the start."""
    from thermoskin.logio import LogReader, LogWriter, WriteBehind, prefetch

    with LogReader(path, required=INPUT_COLUMNS, live=True, one_patch=True, units=units) as reader:
        names = list(reader.names)
        live = [k for k in OUTPUT_COLUMNS if k in names]
        out_names = [f"{k}_live" if k in live else k for k in names] + list(OUTPUT_COLUMNS)
        fresh_inf = FreshInference()
        est: TouchEstimator | None = None
        gaps = rows = mism = 0
        q_diff = 0.0
        t_last = 0.0
        t_s = math.nan
        n_switch = 0
        counts: dict[str, int] = {}
        first: dict[str, float] = {}
        valid: dict[str, bool] = {}
        ch = Characteriser(cfg) if characterise else None
        events: list[ContactEvent] = []
        # read ahead and write behind in threads while the kernel (GIL released) estimates
        with (LogWriter(out, out_names, atomic=True) as writer, WriteBehind(writer) as behind,
              prefetch(_prepared(reader, cfg, fresh_inf), depth=PREFETCH_CHUNKS) as chunks):
            if compiling is None:
                # while the first chunks are read; the fit at a contact's end when one ends
                # (a short log may have none: about 2 % of a 2-second log's observe)
                warm_up(cfg, fits=False)
            for chunk, fresh, clean, n_sw in chunks:
                if est is None:
                    t_s = loop_t_s(sample_interval(chunk["t"]), cfg)
                    check_interval(t_s, str(path))
                    if compiling is not None:
                        compiling()
                        warm_up(cfg)
                    est = TouchEstimator(cfg, t_s=t_s)
                for k, n in clean.counts.items():
                    first.setdefault(k, clean.first[k])
                    counts[k] = counts.get(k, 0) + n
                for k in ("T_w", "T_p", "T_a", "v"):
                    valid[k] = valid.get(k, False) or k not in clean.no_valid
                c = clean.columns
                n_switch += n_sw
                cols, new = est.feed(c["t"], c["T_w"], c["T_p"], c["v"], c["T_a"],
                                     T_w_cmd=c.get("T_w_cmd"), fresh=fresh, drive=c.get("drive"))
                if ch is not None:
                    ch.feed(c["t"], cols["dq_i_hat"], c["T_w"], c["T_a"])
                    events.extend(ch.annotate(e) for e in new)  # a closed contact's data are all in
                else:
                    events.extend(new)
                if clean.rejected.any():
                    cols["gap"] = (cols["gap"] | clean.rejected).astype(np.int8)
                if "q_i_hat" in live:
                    d = np.abs(cols["q_i_hat"] - chunk["q_i_hat"])
                    d = d[np.isfinite(d)]
                    q_diff = max(q_diff, float(d.max()) if d.size else 0.0)
                if "contact" in live:
                    mism += int(np.sum(cols["contact"] != np.nan_to_num(chunk["contact"]).astype(np.int8)))
                row = {(f"{k}_live" if k in live else k): chunk[k] for k in names}
                row.update({k: cols[k] for k in OUTPUT_COLUMNS})
                behind.write(row)
                gaps += int(cols["gap"].sum())
                if rows == 0 and on_first is not None:
                    on_first(est.learnt())
                rows += len(chunk["t"])
                t_last = float(chunk["t"][-1])
                if progress is not None:
                    progress(rows, reader.n_rows)
        assert est is not None  # a log has two rows at least (LogReader checks)
        n_closed = len(est.events)
        est.finish(t_last)
        if ch is not None:
            ch.finish()
            events.extend(ch.annotate(e) for e in est.events[len(events):])
        else:
            events.extend(est.events[len(events):])
        assert len(events) == len(est.events) >= n_closed
    return StreamResult(events=events, rows=rows, t_s=t_s, periods=fresh_inf.periods or
                        dict.fromkeys(("T_w", "T_p", "T_a"), 1.0), gaps=gaps,
                        live_q_max_abs_diff=q_diff if "q_i_hat" in live else None,
                        live_contact_mismatches=mism if "contact" in live else None,
                        duration_s=rows * t_s,
                        warnings=Cleaned(columns={}, rejected=np.zeros(0, bool), counts=counts, first=first,
                                         no_valid=[k for k, ok in valid.items() if not ok]).warnings(cfg)
                        + coarse_log_warnings(t_s, cfg, rows, n_switch)
                        + stuck_warnings(fresh_inf.periods, t_s),
                        learnt=est.learnt(), notices=notices(est.learnt(), cfg))
