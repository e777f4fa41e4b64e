"""Estimation and detection on a skin of many patches: ``thermoskin observe LOG --skin LAYOUT.toml``.

Per patch, the one-patch estimator of the compiled kernel
(:class:`~thermoskin.estimation.patches.PatchEstimators`, one state row per patch,
``kernel.run_rows`` over the long-format rows), each patch with

- **its own model**: the network of its ``[skin]`` (Table I scaled to its size, ``skin.py``)
  and its loop's flow (eq. 1's ``R_w(v)``, the loop's pump), :func:`patch_config`;
- **its own inlet water** as the input ``T_p`` (``skin_inlet``): the upstream patch's outlet
  carried through the pipe between them (the tank's water, delayed, for the first patch), so
  that heat a touch upstream put into the water is an input downstream, not a touch there;
- **its reading corrected for the transport its lumped pipe node leaves out** (a patch fed
  through a pipe, ``skin_transport``): ``T_w - c``, ``c`` the patch's spatial model minus its
  lumped network, both driven by that inlet, the air and the pump, no touch.

Events gain ``patch`` (its name), ``position`` and ``position_sd`` (m from the patch's inlet,
``skin_position``; NaN where not identifiable) and ``heat`` (W, the position fit's heat into
the sheet). Events of neighbouring patches are grouped into body contacts (``skin_groups``).

**The estimator's noise for a patch of a skin.** The paper's network lumps the pipe into one
node, which tracks its inlet within ``R_w C_w`` (about 26 ms); a patch of a skin is fed water whose
temperature steps from parcel to parcel (the upstream patch's outlet swings with the pump's
on/off chatter, the tank's with the supply pipe's delay), and its pipe is many cells. The
lumped model then errs at every pump switch. Fed through a pipe, the transport correction
above takes that misfit out (the innovations fall to the thermocouple's noise), and
:data:`SKIN_ESTIMATOR` keeps a little pipe noise (``S_w``) and lets the inlet's rate follow its
steps (``S_p``); the detector waits :data:`SKIN_DETECTOR` ``t_warmup`` for its baseline.
On a patch fed straight from the tank the misfit is the same shape in every cycle of the
pump's chatter (the water carried along the pipe's cells, not mixed into one node: the
reading lags the node after a switch to flow, then overtakes it); the estimator's pump-cycle
correction (``estimator.switch_bins``: the mean no-touch innovation of ``T_w`` per sample
since the last switch, learned and subtracted) takes it out, so :data:`TANK_FED_ESTIMATOR`
needs less pipe noise (docs/skin.md).
On boards slower than the loop the water that comes in between two readings upstream is
unseen; :data:`FLOW_NOISE` lets the pipe node go while the pump runs, by the boards' period.
A key the user's config sets above these is kept.

**Live and offline, one estimator.** :class:`SkinEstimator` takes the rows block by block
(``thermoskin run --skin`` hands it every block of the closed loop as it is written); its inlet
water is :class:`~thermoskin.skin.inlet.InletStream` and every patch's filter and detector keep
their state from block to block, so the outputs do not depend on where the blocks are cut.
:func:`observe_skin` is the same estimator fed a log in memory as one block, and
:func:`observe_skin_file` (``observe --skin``) fed a log file block by block, memory bounded
whatever its length: on a run's log they give the run's live contacts again. The position along
the pipe needs the whole contact and the samples before it, so it is computed from the log
(:func:`observe_skin_file` reads back only those samples, :func:`~thermoskin.skin.position.window`).
"""

from __future__ import annotations

import dataclasses
import math
import os
import tempfile
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from thermoskin.estimation import kernel as K  # noqa: N812
from thermoskin.estimation.events import ContactEvent
from thermoskin.estimation.freshness import CHANNEL_BITS, FreshInference, loop_t_s
from thermoskin.estimation.model import fixed_sensors
from thermoskin.estimation.patches import PatchEstimators
from thermoskin.logio.units import Units
from thermoskin.params import Config
from thermoskin.skin.inlet import InletStream
from thermoskin.skin.layout import NETWORK_KEYS, Skin, tc_fresh_bit
from thermoskin.skin.log import CHUNK_SAMPLES, SkinLog, SkinLogReader, long_block
from thermoskin.skin.position import NAN_POSITION, PatchLocator, Position, window
from thermoskin.skin.transport import TransportCorrection

Array = NDArray[np.float64]

SKIN_ESTIMATOR = {"S_w": 1e-3, "S_p": 100.0}
"""Process noise of a skin patch fed through a pipe (module doc): K^2/s on the pipe node, K^2/s^3
on the inlet's rate (the paper's single patch: 1e-8 and 0.01; 3e-3 on the pipe node before the
transport correction)."""
TANK_FED_ESTIMATOR = {"S_w": 3e-4, "S_p": 100.0, "switch_bins": 64}
"""The same for a patch fed straight from the tank (first of its loop, no supply pipe): its
misfit is locked to the pump's cycle, which the pump-cycle correction learns (``switch_bins``,
module doc), so the pipe node needs ten times less noise."""
FLOW_NOISE = 14.0
"""``estimator.S_w_flow`` of a skin patch fed through a pipe, K^2/s per s^1.5 of the period of
the board that reads its inlet (:func:`patch_config`): ``FLOW_NOISE * period^1.5`` (0 for boards
read at least every 1.5 samples). Between two readings of the thermocouple upstream, the water
the pump brings in was not seen; the pipe node is then let go while the pump runs, not while it
stands still, when a touch shows best.
Fitted to the trade of touches found against false alarms on ``forearm.toml`` (docs/skin.md,
On slow thermocouple boards): at 200 Hz 106 of 108 found with 1 false alarm (16 without), at
10 Hz 74 with 81 (75 with 330). Not for a patch fed straight from its tank (it had no false
alarm to lose, and found fewer touches with it: 8 of 12 at 100 Hz against 11)."""
SKIN_DETECTOR = {"t_warmup": 5.0}
"""Detector settings of a skin patch (the paper's single patch: ``t_warmup`` 1 s)."""
SKIN_ONSET_STATE_JUMP = 0.0
"""At an onset a skin patch's ``q_i`` alone takes the jump (``detector.onset_state_jump``): the
step's signature through its lumped pipe node, fed the lagged inlet it then had, set the pipe and
sheet so that the estimate fell back to its baseline at once (the forearm's 2 s touch on dorsal1
was released after 35 ms); with the transport correction the whole-state jump still lost one
touch of 54 and added a false alarm (docs/skin.md)."""

PIPED_BOARDS_HZ = 1000.0
"""A skin whose patches are fed through pipes (``forearm.toml``) found every touch with no false
alarm on thermocouple boards of this rate (fresh every 1 ms sample); on 500 Hz boards it found
108 of 108 with 2 false alarms, on 200 Hz boards 106 with 1, on 100 Hz 90 with 23, on 10 Hz 74
with 81 (``benchmarks/skin_detection.py --rate``, with :data:`FLOW_NOISE`; docs/skin.md)."""
TANK_FED_BOARDS_HZ = 200.0
"""A skin whose patches are all fed straight from their tanks (``single.toml``) found every touch
on boards of this rate and faster; on 100 Hz boards 11 of 12, on 50 Hz 9 (the same benchmark)."""

SKIN_EVENT_COLUMNS = ("patch", "onset", "detected", "release", "duration", "sign", "peak_dq", "mean_dq",
                      "energy", "position", "position_sd", "heat")
"""Columns of a skin's events table: the patch's name, :data:`~thermoskin.estimation.events.EVENT_COLUMNS`,
the position along its pipe and its sd (m from the inlet; empty where not identifiable), the
heat of the position fit (W)."""


def board_warnings(skin: Skin, rate_hz: float, log_period: float | None = None) -> list[str]:
    """What detection on ``skin`` is worth with its pipe thermocouples read ``rate_hz`` times a
    second (measured: :data:`PIPED_BOARDS_HZ`, :data:`TANK_FED_BOARDS_HZ`): one line, or none.
    For a skin with patches fed through pipes (:data:`FLOW_NOISE`) the line also says where the
    boards' period came from: ``log_period``, read from the log (:func:`log_boards_period`), or
    what to set where the config's boards (``sensor.period_T_w``) are not these."""
    piped = [skin.patches[i].name for i in range(len(skin.patches)) if not tank_fed(skin, i)]
    need = PIPED_BOARDS_HZ if piped else TANK_FED_BOARDS_HZ
    if not (rate_hz > 0.0) or rate_hz >= 0.95 * need:  # 5 %: a board's jitter and the count's edges
        return []
    if piped:
        why = (f"a skin whose patches are fed through pipes ({', '.join(piped[:3])}"
               f"{', ...' if len(piped) > 3 else ''}) was measured free of false alarms and missed touches "
               f"only on boards of {need:.0f} Hz: expect some of both, more the slower the boards")
    else:
        why = (f"a patch fed from its tank found every touch on boards of {need:.0f} Hz and faster: "
               "expect late or missed touches")
    period = max(skin.cfg.sensor.period_T_w, skin.cfg.sampling.t_s)  # 0: every sample
    if piped and log_period is not None:
        why += (f"; the estimator took the boards' period, {log_period:.3g} s, from the log "
                "([sensor] period_T_w)")
    elif piped and abs(period * rate_hz - 1.0) > 0.3:  # the config describes other boards
        why += (f"; [sensor] period_T_w is {skin.cfg.sensor.period_T_w:g} s in the config: set it to "
                f"{1.0 / rate_hz:.3g} s, so that the estimator lets the pipe node go while the pump runs "
                "as these boards need")
    return [f"the pipe thermocouples give about {rate_hz:.0f} readings a second: {why} (docs/skin.md, "
            "On slow thermocouple boards)"]


def tank_fed(skin: Skin, i: int) -> bool:
    """Patch ``i`` is fed straight from its tank: the first of its loop, with no supply pipe."""
    lp = skin.loops[skin.patches[i].loop]
    return lp.patches[0] == i and lp.pipes[0].length == 0.0


def patch_config(skin: Skin, i: int, boards_period: float | None = None) -> Config:
    """The estimator's config of patch ``i``: its loop's config, its own network, the skin's
    noise (module doc). :data:`FLOW_NOISE`'s share is set by the period of the board that reads
    the patch's inlet: ``boards_period`` (s) if given, else the config's (``sensor.period_T_p``,
    the tank's, for the first patch of a loop; ``period_T_w``, the outlet upstream, for the
    others); none for boards read at least every 1.5 rows (at the loop's rate)."""
    if boards_period is not None and not (math.isfinite(boards_period) and boards_period >= 0.0):
        raise ValueError(f"boards_period = {boards_period} s must be finite and >= 0")
    p = skin.patches[i]
    lc = skin.loops[p.loop].cfg
    net = {k: getattr(p.skin, k) for k in NETWORK_KEYS}
    cfg = dataclasses.replace(lc, skin=dataclasses.replace(lc.skin, **net))
    if tank_fed(skin, i):  # its inlet is the tank's own reading: no unseen water (FLOW_NOISE)
        own = dict(TANK_FED_ESTIMATOR)
    else:
        first = skin.loops[p.loop].patches[0] == i  # fed from the tank through its supply pipe
        period = boards_period if boards_period is not None else (
            cfg.sensor.period_T_p if first else cfg.sensor.period_T_w)
        unseen = period >= 1.5 * cfg.sampling.t_s  # water comes in between two readings
        own = dict(SKIN_ESTIMATOR, S_w_flow=FLOW_NOISE * period ** 1.5 if unseen else 0.0)
    # (the pump-cycle correction: the patch's own, a piped patch none, docs/skin.md; not the
    # one-patch estimator's default)
    es = {k: max(v, getattr(cfg.estimator, k)) for k, v in own.items() if k != "switch_bins"}
    es["switch_bins"] = own.get("switch_bins", 0)
    de = {k: max(v, getattr(cfg.detector, k)) for k, v in SKIN_DETECTOR.items()}
    de["onset_state_jump"] = SKIN_ONSET_STATE_JUMP
    # a patch keeps its sensors as configured (fixed_sensors): what the one-patch estimator
    # learns of its boards (offsets, lag, noise) is not learnt per patch of a skin
    fs = fixed_sensors(cfg)
    return dataclasses.replace(fs, estimator=dataclasses.replace(fs.estimator, **es),
                               detector=dataclasses.replace(fs.detector, **de))


@dataclass(frozen=True)
class SkinEvent:
    """A contact on one patch: the one-patch event, the patch, its position along the pipe."""

    patch: int
    name: str
    event: ContactEvent
    position: Position = NAN_POSITION

    def row(self) -> dict[str, float | str]:
        r: dict[str, float | str] = {"patch": self.name}
        r.update(self.event.row())
        pos = self.position
        r.update({"position": pos.mean, "position_sd": pos.sd, "heat": pos.heat})
        return r


@dataclass
class SkinObservation:
    """Per (sample, patch) outputs ``(n, P)`` and the events, in order of onset."""

    columns: dict[str, Array]
    events: list[SkinEvent]
    T_in: Array
    fresh_in: NDArray[np.int64]
    groups: list[object] = field(default_factory=list)
    reading_rate: float = 0.0
    """New pipe readings a second, from the log (:attr:`SkinEstimator.reading_rate`)."""
    warnings: list[str] = field(default_factory=list)
    """What the boards' rate costs detection (:func:`board_warnings`)."""


def thermocouples(log: SkinLog, skin: Skin) -> list[Array]:
    """The log's thermocouple columns ``T_w, T_w2, ...`` (``(n, P)``; NaN where absent)."""
    return block_thermocouples(log.cols, skin)


def block_thermocouples(cols: Mapping[str, Array], skin: Skin) -> list[Array]:
    """The thermocouple columns ``T_w, T_w2, ...`` of ``(m, P)`` columns (NaN where absent)."""
    out = [cols["T_w"]]
    for j in range(2, skin.n_thermocouples + 1):
        out.append(cols.get(f"T_w{j}", np.full_like(cols["T_w"], math.nan)))
    return out


def _channels(skin: Skin) -> list[tuple[str, int]]:
    """A skin log's read channels and their ``fresh`` bits."""
    return [*CHANNEL_BITS, *((f"T_w{j}", tc_fresh_bit(j - 1)) for j in range(2, skin.n_thermocouples + 1))]


class SkinFreshInference(FreshInference):
    """The ``fresh`` bits of a skin log, block by block: the single patch's
    :class:`~thermoskin.estimation.freshness.FreshInference` per patch, over the skin's channels
    (every thermocouple of a patch)."""

    def __init__(self, skin: Skin) -> None:
        super().__init__(_channels(skin))


@dataclass(frozen=True)
class Change:
    """A contact flag's change on one patch: detected (``on``) or released, at the row's time ``t``;
    ``sign`` the contact's (+1 heat in, -1 heat out); ``event`` the finished contact at a release."""

    t: float
    patch: int
    on: bool
    sign: int
    event: ContactEvent | None = None


@dataclass
class SkinBlock:
    """One block's outputs, ``(m, P)`` each, and its contact changes in time order."""

    columns: dict[str, Array]
    T_in: Array
    fresh_in: NDArray[np.int64]
    changes: list[Change]
    fresh: NDArray[np.int64]
    """The bits the block was estimated with (:class:`SkinFreshInference`): the log's with the
    changes of its values, or read from its values where it has none."""


class ReadingCounter:
    """New ``T_w`` readings a second over the patches of a skin, from their fresh bits block by
    block: one over the mean interval between a patch's readings (over every patch; 0 before
    there are 20), of the intervals within a row of their median. A reading equal to the one
    before it, missed where a log has no bits, doubles a few intervals, which fall outside; a
    board between two sample rates (700 Hz: 1 and 2 rows apart) is averaged."""

    BINS = 4096
    """Intervals between readings counted up to this many rows (longer ones in the last bin)."""

    def __init__(self, n_patches: int, t_s: float) -> None:
        self.P, self.t_s = n_patches, float(t_s)
        self._rows = 0
        self._last_read = np.full(n_patches, -1, dtype=np.int64)  # each patch's last reading (row)
        self._gaps = np.zeros(self.BINS, dtype=np.int64)  # rows between readings, all patches

    def count(self, fresh: NDArray[np.int64]) -> None:
        """Count the readings (bit 1) of the next ``(m, P)`` block of fresh bits."""
        m = len(fresh)
        k0 = self._rows
        self._rows = k0 + m
        for i in range(self.P):
            rows = k0 + np.flatnonzero(fresh[:, i] & 1)
            if not len(rows):
                continue
            prev = self._last_read[i]
            gaps = np.diff(rows) if prev < 0 else np.diff(np.concatenate(([prev], rows)))
            np.add.at(self._gaps, np.minimum(gaps, self.BINS - 1), 1)
            self._last_read[i] = rows[-1]

    @property
    def rate(self) -> float:
        """Readings a second so far (class doc)."""
        n = int(self._gaps.sum())
        if n < 20:
            return 0.0
        med = int(np.searchsorted(np.cumsum(self._gaps), 0.5 * n))  # bin j: j rows apart
        j = np.arange(max(med - 1, 1), min(med + 2, self.BINS))  # its neighbours: a board
        w = self._gaps[j]                                        # between two sample rates
        return 1.0 / (float((j * w).sum()) / float(w.sum()) * self.t_s)


def boards_period(skin: Skin, t_s: float, rate: float) -> float | None:
    """The pipe thermocouples' period from their readings a second ``rate`` (a log's, counted by
    :class:`ReadingCounter`), as :func:`log_boards_period` takes it; None where the config gives
    one or the boards read as fast as the loop."""
    if skin.cfg.sensor.period_T_w != 0.0 or skin.cfg.sensor.period_T_p != 0.0:
        return None
    return 1.0 / rate if 0.0 < rate <= 1.0 / (1.5 * t_s) else None


def log_boards_period(log: SkinLog, skin: Skin, t_s: float,
                      fresh: NDArray[np.int64] | None = None) -> float | None:
    """The pipe thermocouples' period read from ``log`` (s) where the config gives none
    (``sensor.period_T_w`` and ``period_T_p`` 0) and the log's boards read at most every 1.5
    rows (as :func:`patch_config` asks; a log at the loop's rate without bits, whose repeated
    readings look like a board of 1.1-1.3 rows, is not taken for slow boards); else None (the
    config's, as the live loop takes it). An estimate (a board's jitter): the run's own period
    within a fraction of a percent. ``fresh``: the log's fresh bits where already inferred
    (:class:`SkinFreshInference`)."""
    if skin.cfg.sensor.period_T_w != 0.0 or skin.cfg.sensor.period_T_p != 0.0:
        return None
    rc = ReadingCounter(len(skin.patches), t_s)
    rc.count(SkinFreshInference(skin).feed(log.cols) if fresh is None else fresh)
    return boards_period(skin, t_s, rc.rate)


class SkinEstimator:
    """Every patch of ``skin`` estimated and its contacts detected, block by block (module doc).

    :meth:`block` takes the next ``m`` samples as ``(m, P)`` columns (``T_w``, ``T_w2``, ...,
    ``T_p``, ``v``, ``T_a``, optional ``fresh`` and ``T_w_cmd``) with their times ``t`` (``m``);
    :attr:`events` collects the finished contacts ``(patch, ContactEvent)`` in the order they end.
    """

    def __init__(self, skin: Skin, t_s: float, boards_period: float | None = None) -> None:
        """``boards_period``: the pipe thermocouples' period (s) where not the config's
        (:func:`log_boards_period`)."""
        from thermoskin.estimation.freshness import check_interval

        check_interval(t_s)
        self.skin, self.t_s = skin, float(t_s)
        self.P = len(skin.patches)
        cfgs = [patch_config(skin, i, boards_period) for i in range(self.P)]
        self.est = PatchEstimators(cfgs, t_s=self.t_s, parallel=False)
        self.inlet = InletStream(skin, self.t_s)
        self.transport = TransportCorrection(skin, self.t_s, [c.skin for c in cfgs],
                                             [i for i in range(self.P) if not tank_fed(skin, i)])
        self._contact = np.zeros(self.P, dtype=np.int64)
        self._on_t = np.full(self.P, np.nan)  # when each patch's open contact was detected
        self._patch = np.zeros(0, dtype=np.int64)
        self._infer = SkinFreshInference(skin)  # the blocks' fresh bits (with or without the column)
        self._readings = ReadingCounter(self.P, self.t_s)

    @property
    def reading_rate(self) -> float:
        """New ``T_w`` readings a second so far (:class:`ReadingCounter`)."""
        return self._readings.rate

    @property
    def events(self) -> list[tuple[int, ContactEvent]]:
        return self.est.events

    def block(self, t: Array, cols: Mapping[str, Array],
              fresh: NDArray[np.int64] | None = None) -> SkinBlock:
        """Estimate the next block (class doc); ``fresh``: its fresh bits where already inferred
        (:func:`observe_skin`'s, once for the whole log), else inferred here."""
        m, P = len(t), self.P
        if fresh is None:
            fresh = self._infer.feed(cols)
        self._readings.count(fresh)
        T_in, fr = self.inlet.push(block_thermocouples(cols, self.skin), cols["T_p"], cols["v"],
                                   cols["T_a"], fresh)
        if len(self._patch) < m * P:
            self._patch = np.tile(np.arange(P, dtype=np.int64), m)
        T_w = cols["T_w"] - self.transport.push(T_in, cols["T_a"], cols["v"])
        cmd = cols["T_w_cmd"].ravel() if "T_w_cmd" in cols else None
        out, ended = self.est.run_rows(self._patch[:m * P], np.repeat(t, P), T_w.ravel(),
                                       T_in.ravel(), cols["v"].ravel(), cols["T_a"].ravel(), T_w_cmd=cmd,
                                       fresh=fr.ravel())
        res = {k: out[k].reshape(m, P) for k in ("q_i_hat", "dq_i_hat", "contact", "gap")}
        return SkinBlock(res, T_in, fr, self._changes(t, res["contact"], ended), fresh)

    def _changes(self, t: Array, contact: NDArray[np.generic],
                 ended: list[tuple[int, ContactEvent]]) -> list[Change]:
        """The block's contact changes. A release carries the event of its contact: the ended
        event detected when the contact came on (none if the detector withdrew the contact,
        ``detector.t_confirm``); a detection's sign is that event's if the contact ended in the
        block, else the patch's detector state (it is still on)."""
        c = contact.astype(np.int64)
        prev = np.vstack((self._contact[None, :], c[:-1]))
        ks, ps = np.nonzero(c != prev)
        if not len(ks):
            return []
        by_detection = {(i, ev.detected_at): ev for i, ev in ended}
        self._contact = c[-1].copy()
        out: list[Change] = []
        for k, i in zip(ks.tolist(), ps.tolist(), strict=True):
            tk = float(t[k])
            if c[k, i]:
                self._on_t[i] = tk
                ev = by_detection.get((i, tk))
                sign = int(ev.sign) if ev is not None else int(self.est.ST[i, K.SIGN])
                out.append(Change(tk, i, True, sign))
            else:
                ev = by_detection.get((i, self._on_t[i]))
                out.append(Change(tk, i, False, int(ev.sign) if ev is not None else 0, ev))
        return out

    def finish(self, t: float) -> None:
        """End every contact still open at ``t`` (the end of the run or log)."""
        self.est.finish(t)


@dataclass
class SkinFileObservation:
    """What :func:`observe_skin_file` found: the events in order of onset, the log's samples and
    interval, the new pipe readings a second, the warnings (:func:`board_warnings`)."""

    events: list[SkinEvent]
    n: int
    t_s: float
    reading_rate: float
    warnings: list[str]


def observe_skin_file(path: str | os.PathLike[str], skin: Skin, output: str | os.PathLike[str] | None, *,
                      locate: bool = True, chunk_samples: int = CHUNK_SAMPLES,
                      compiling: Callable[[], None] | None = None,
                      progress: Callable[[float], None] | None = None,
                      units: Units | None = None) -> SkinFileObservation:
    """:func:`observe_skin` on the log at ``path``, streamed: the log's columns and the estimates
    (as ``observe --skin`` writes them) go to ``output`` block by block, so memory does not grow
    with the log's length (``output`` None: a temporary file beside the log, removed at the end;
    ``run --skin`` checks its live contacts so). Three passes:

    1. the log is read and checked whole, and its boards' readings counted
       (:func:`boards_period`), before anything is written or compiled (a bad log: one
       :class:`~thermoskin.logio.LogError`; ``compiling`` is called after it, before the first
       estimate);
    2. the :class:`SkinEstimator` takes it block by block (as ``run --skin`` does live) and
       the blocks are written to ``output`` (whole or not at all), ``progress`` told the share done;
    3. ``output`` is read back for the samples each contact's position needs
       (:func:`~thermoskin.skin.position.window`: a few seconds each), which alone are kept.

    The same outputs and events as :func:`observe_skin` on the whole log (tested). ``units``: the
    log's units (:class:`~thermoskin.logio.units.Units`; the output is in seconds and °C)."""
    from thermoskin.logio import write_blocks

    if output is None:
        with tempfile.TemporaryDirectory(prefix=".thermoskin-observe-", dir=Path(path).parent) as d:
            return observe_skin_file(path, skin, Path(d) / "observed.parquet", locate=locate,
                                     chunk_samples=chunk_samples, compiling=compiling, progress=progress,
                                     units=units)

    P = len(skin.patches)
    reader = SkinLogReader(path, skin, chunk_samples, units)
    infer = SkinFreshInference(skin)
    counter: ReadingCounter | None = None
    t0 = t_end = math.nan
    for t, cols in reader:  # 1: checked whole, readings counted
        if counter is None:
            t0 = float(t[0])
            counter = ReadingCounter(P, loop_t_s(reader.t_s, skin.cfg))
        counter.count(infer.feed(cols))
        t_end = float(t[-1])
    assert counter is not None  # a log has 2 samples at least (SkinLogReader)
    n, log_t_s, t_s = reader.n, reader.t_s, counter.t_s
    period = boards_period(skin, t_s, counter.rate)
    if compiling is not None:
        compiling()
    est = SkinEstimator(skin, t_s, period)
    live = [k for k in ("q_i_hat", "dq_i_hat", "contact", "gap") if k in reader.names]

    def estimated() -> Iterator[dict[str, Array]]:  # 2: estimated block by block, as written
        done = 0
        for t, cols in SkinLogReader(path, skin, chunk_samples, units):
            b = est.block(t, cols)
            extra = {f"{k}_live": cols[k] for k in live}
            extra.update({"T_in": b.T_in, **b.columns})
            yield long_block(cols, reader.names, extra, drop=tuple(live))
            done += len(t)
            if progress is not None:
                progress(done / n)

    write_blocks(output, estimated())
    est.finish(t_end)
    windows = []
    dt = (t_end - t0) / (n - 1)  # the log's own interval (sample k at t0 + k dt)
    for e, (i, ev) in enumerate(est.events):
        if locate and len(skin.patches[i].thermocouples) >= 2:
            k_on, k_off = _samples(ev, t0, dt)
            windows.append((e, i, k_on, k_off, *window(k_on, k_off, n, t_s)))
    pos = _locate_windows(output, skin, windows, t_s, chunk_samples)
    events = [SkinEvent(i, skin.patches[i].name, ev, pos.get(e, NAN_POSITION))
              for e, (i, ev) in enumerate(est.events)]
    events.sort(key=lambda e: (e.event.onset, e.patch))
    return SkinFileObservation(events, n, log_t_s, est.reading_rate,
                               board_warnings(skin, est.reading_rate, period))


def _samples(ev: ContactEvent, t0: float, dt: float) -> tuple[int, int]:
    """The samples of a contact's onset and release in a log whose sample ``k`` is at ``t0 + k dt``
    (its own mean interval: the same however the log is cut, and right on a clock a little off
    the configured one)."""
    return round((ev.onset - t0) / dt), round((ev.release - t0) / dt)


def _located(loc: PatchLocator, k_on: int, k_off: int, T_in: Array, T_a: Array, v: Array,
             Y: list[Array], fresh: NDArray[np.int64], dq: Array) -> Position:
    """:meth:`PatchLocator.locate` on one patch's columns, each thermocouple ``Y[j]`` (of the
    patch's own) read where its fresh bit is set."""
    ntc = len(loc.patch.thermocouples)
    fr = [(fresh & tc_fresh_bit(j)) != 0 for j in range(ntc)]
    return loc.locate(k_on, k_off, T_in, T_a, v, Y[:ntc], fr, dq)


_Window = tuple[int, int, int, int, int, int, int]
"""A contact's index among the events, its patch, onset and release samples, and its
:func:`window` (kb, k0, k1)."""


def _locate_windows(output: str | os.PathLike[str], skin: Skin, windows: list[_Window], t_s: float,
                    chunk_samples: int) -> dict[int, Position]:
    """Pass 3 of :func:`observe_skin_file`: each window's samples of its patch gathered from the
    written ``output`` (its log columns, ``T_in``, ``dq_i_hat``; the fresh bits inferred again from
    the same columns) and located (the model at the estimator's ``t_s``: the configured interval
    where the log's is that, not the median of its times, whose last bits follow how the log
    was cut; a contact's samples from its times and the log's mean interval, first to last, the
    same however the log is cut); by the event's index."""
    out: dict[int, Position] = {}
    if not windows:
        return out
    windows = sorted(windows, key=lambda w: w[4])
    parts: dict[int, list[dict[str, Array]]] = {}
    locators: dict[int, PatchLocator] = {}
    infer = SkinFreshInference(skin)
    k = 0
    nxt = 0  # windows[:nxt] have begun
    for _, cols in SkinLogReader(output, skin, chunk_samples):
        m = len(cols["t"])
        fresh = infer.feed(cols)
        Y = block_thermocouples(cols, skin)
        while nxt < len(windows) and windows[nxt][4] < k + m:
            parts[nxt] = []
            nxt += 1
        for w in list(parts):
            e, i, k_on, k_off, kb, _, k1 = windows[w]
            a, b = max(kb, k) - k, min(k1, k + m) - k
            if b > a:
                parts[w].append({"T_in": cols["T_in"][a:b, i], "T_a": cols["T_a"][a:b, i],
                                 "v": cols["v"][a:b, i], "dq": cols["dq_i_hat"][a:b, i],
                                 "fresh": fresh[a:b, i], **{f"Y{j}": y[a:b, i] for j, y in enumerate(Y)}})
            if k1 <= k + m:  # the window is whole: locate, let its samples go
                got = parts.pop(w)
                c = {key: np.concatenate([g[key] for g in got]) if got else np.zeros(0) for key in
                     ("T_in", "T_a", "v", "dq", "fresh", *(f"Y{j}" for j in range(len(Y))))}
                loc = locators.get(i) or locators.setdefault(i, PatchLocator(skin, i, t_s))
                out[e] = _located(loc, k_on - kb, k_off - kb, c["T_in"], c["T_a"], c["v"],
                                  [c[f"Y{j}"] for j in range(len(Y))], c["fresh"].astype(np.int64), c["dq"])
        k += m
    return out


def observe_skin(log: SkinLog, skin: Skin, *, locate: bool = True) -> SkinObservation:
    """Estimate, detect and locate on every patch of ``skin`` over ``log`` (module doc): the
    :class:`SkinEstimator` fed the whole log as one block."""
    t_s = loop_t_s(log.t_s, skin.cfg)
    dt = (float(log.t[-1]) - float(log.t[0])) / (log.n - 1)  # the log's own interval (sample index)
    bits = SkinFreshInference(skin).feed(log.cols)
    period = log_boards_period(log, skin, t_s, bits)
    est = SkinEstimator(skin, t_s, period)
    b = est.block(log.t, log.cols, bits)
    est.finish(float(log.t[-1]))
    out, T_in, fr, fresh = b.columns, b.T_in, b.fresh_in, b.fresh
    Y = thermocouples(log, skin)
    c = log.cols
    events: list[SkinEvent] = []
    locators: dict[int, PatchLocator] = {}
    for i, ev in est.events:
        pos = NAN_POSITION
        if locate and len(skin.patches[i].thermocouples) >= 2:
            loc = locators.get(i) or locators.setdefault(i, PatchLocator(skin, i, t_s))
            k_on, k_off = _samples(ev, float(log.t[0]), dt)
            pos = _located(loc, k_on, k_off, T_in[:, i], c["T_a"][:, i], c["v"][:, i],
                           [y[:, i] for y in Y], fresh[:, i], out["dq_i_hat"][:, i])
        events.append(SkinEvent(i, skin.patches[i].name, ev, pos))
    events.sort(key=lambda e: (e.event.onset, e.patch))
    return SkinObservation(out, events, T_in, fr, reading_rate=est.reading_rate,
                           warnings=board_warnings(skin, est.reading_rate, period))


def events_columns(events: list[SkinEvent]) -> dict[str, NDArray[np.generic]]:
    """The events as columns of :data:`SKIN_EVENT_COLUMNS`."""
    rows = [e.row() for e in events]
    out: dict[str, NDArray[np.generic]] = {}
    for k in SKIN_EVENT_COLUMNS:
        vals = [r[k] for r in rows]
        out[k] = np.array(vals, dtype=object if k == "patch" else np.int64 if k == "sign" else float)
    return out
