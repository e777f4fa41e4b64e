"""A sensor and model check of a log (``thermoskin check``): what the readings are, how well the
configured skin explains them, whether a one-finger touch would stand out, and what to do next.

**Per channel** (``T_w``, ``T_p``, ``T_a``), from the readings alone:

- *update period*: the median interval between new readings, from the log's ``fresh`` bits
  (1 ``T_w``, 2 ``T_p``, 4 ``T_a``); without them, between changes of the value (an upper
  bound: a reading steadier than its converter's step repeats). The conversions' *jitter*:
  half the spread (1st to 99th percentile) of those intervals.
- *quantum*: the converter's step, the greatest step of which every difference between two
  distinct readings is a whole multiple (:func:`~thermoskin.fit.calibrate.quantum_of`); 0 where
  none is resolved.
- *noise*: :func:`~thermoskin.fit.calibrate.reading_noise` (differences of orders 1-3 of the
  new readings, the least). For ``T_w``, whose readings move with every pump switch, the
  residual of the model fitted below is used where it is lower.

**The model** (:func:`~thermoskin.fit.calibrate.calibrate`, the same fit ``thermoskin
calibrate`` makes): first with the configured skin held and the sensors fitted (the offsets
of ``T_p`` and ``T_a`` relative to ``T_w``'s, the lags of the pipe's and the air's sensor),
then the skin too. What a log cannot tell is said, not guessed: only differences of offsets
reach the readings (``T_w`` is the reference, its offset kept as configured); they are seen
through the pump's switching, the pipe's lag through the transients it causes, and the
air's lag only when the air changes (a door, a draught). The tank sensor's lag is not in the
model. Three residuals say how well the skin fits: the configuration as it is, the
configured skin with the sensors as found, and the calibrated skin; against the ``T_w``
noise.

**SNR of a one-finger touch** (:func:`touch_snr`): a fingertip as a contact conductance of
:data:`FINGER_G` W/K to a body at :data:`FINGER_T` °C on the sheet, in steady state with the
pipe and the air at the log's median readings::

    T_g = (T_w/R_g + T_a/R_ag + G T_f) / (1/R_g + 1/R_ag + G),     q = G (T_f - T_g)

over the standard deviation of the estimator's ``dq_i_hat`` (what the detector watches) run
on the log, no contact flagged, after :data:`T_SKIP` s: as the sweep's ``snr_one_finger``.
Twice: with the configuration as it is, and with the sensor section found (the readings
corrected by the offsets found, each channel's noise, ``noise_T_w`` ..., and ``quantum_T`` as
measured). Below
:data:`SNR_MIN` a touch is not reliably told from noise.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from thermoskin.atomic import write_text
from thermoskin.fit import calibrate as cal
from thermoskin.params import Config, SensorParams, to_toml

Array = NDArray[np.float64]

FINGER_G = 0.05
"""Contact conductance of one fingertip, W/K (``physics.finger``'s order of magnitude)."""
FINGER_T = 33.0
"""Temperature of the finger's body side, °C."""
SNR_MIN = 5.0
"""A touch whose SNR is below this is not reliably told from the noise."""
T_SKIP = 5.0
"""Seconds of the estimator's start left out of its noise."""
BITS = {"T_w": 1, "T_p": 2, "T_a": 4}
NOISE_RTOL = 0.25
"""A channel's measured noise off its configured one by more than this fraction is worth setting."""
MISFIT = 1.05
"""The configured skin's residual above this times the calibrated one: calibrate. (Not a
parameter's change alone: on a chattering log the fit moves weakly seen parameters by small
biases without fitting any better.)"""
SKIN_RTOL = 0.05
"""A calibrated skin parameter off the configured one by more than this (and outside its
interval): calibrate."""
OFFSET_ATOL = 0.02
"""K: an offset found this far from the configured one (and outside its interval) is worth setting."""
LAG_ATOL = 0.02
"""s: likewise a lag."""
AIR_STILL = 0.2
"""K: an air reading (smoothed) that moves less than this shows no air sensor's lag."""


class CheckError(ValueError):
    """The log cannot be checked; the one-line message says why."""


@dataclass(frozen=True)
class Channel:
    """What the readings of one channel show (module doc)."""

    name: str
    readings: int
    period: float            # s; 0: a new reading every row
    period_from: str         # "fresh column", "value changes", "every row"
    jitter: float            # s
    quantum: float           # K; 0: none resolved
    noise: float             # K (standard deviation)
    noise_from: str
    offset: float            # K, relative to the reference's configured offset
    offset_low: float
    offset_high: float
    offset_status: str
    lag: float               # s
    lag_low: float
    lag_high: float
    lag_status: str


@dataclass(frozen=True)
class Fit:
    """A residual of the ``T_w`` prediction: rms per reading (K), autocorrelation time (blocks)."""

    what: str
    rms: float
    tau: float


@dataclass(frozen=True)
class Report:
    """What :func:`check` found; ``advice``: what to do next, one line each."""

    duration: float
    t_s: float
    rows: int
    switches: int
    stopped_s: float          # longest pump stop, s
    air_range: float          # K, of the smoothed air reading
    channels: dict[str, Channel]
    fits: list[Fit]
    sensors: cal.Calibration = field(repr=False)
    skin: cal.Calibration = field(repr=False)
    snr_now: float
    snr_found: float
    touch_W: float
    dq_sd_now: float
    dq_sd_found: float
    touch_step: float         # K: how much a one-finger touch moves T_w in steady state, pump running
    found: dict[str, float]
    advice: list[str]
    wall_s: float
    contacts_from: str = "the log's contact column"
    contact_s: float = 0.0    # s of the log left out as contacts

    def config(self, cfg: Config) -> Config:
        """``cfg`` with the ``[sensor]`` values found."""
        return cfg.replace(sensor=self.found)


# ---------------------------------------------------------------------------- readings
def period_of(x: ArrayLike, t_s: float, fresh: NDArray[np.bool_] | None) -> tuple[float, float, str]:
    """``(period, jitter, from)`` of a channel's conversions (module doc); ``x`` its readings."""
    if fresh is not None:
        k = np.flatnonzero(fresh)
        src = "fresh column"
    else:
        xx = np.asarray(x, dtype=float)
        changed = np.r_[True, (xx[1:] != xx[:-1]) & np.isfinite(xx[1:])]
        if changed.mean() > 0.5:
            return 0.0, 0.0, "every row"
        k = np.flatnonzero(changed)
        src = "value changes"
    if k.size < 3:
        return math.nan, math.nan, src
    d = np.diff(k) * t_s
    period = float(np.median(d))
    if period <= 1.5 * t_s:
        return 0.0, 0.0, src if fresh is not None else "every row"
    lo, hi = np.percentile(d, [1.0, 99.0])
    return period, float(max(hi - period, period - lo, 0.0) / 2.0), src


# ---------------------------------------------------------------------------- the touch
def touch_heat(T_w: float, T_a: float, cfg: Config, G: float = FINGER_G, T_f: float = FINGER_T) -> float:
    """Heat of a fingertip into the sheet in steady state, W (module doc)."""
    sk = cfg.skin
    T_g = (T_w / sk.R_g + T_a / sk.R_ag + G * T_f) / (1.0 / sk.R_g + 1.0 / sk.R_ag + G)
    return G * (T_f - T_g)


def touch_step(cfg: Config, R_w: float, q: float) -> float:
    """How much a heat ``q`` into the sheet moves ``T_w`` in steady state, the pump running at
    ``R_w`` (eq. 3-4's network at rest, ``T_p`` and ``T_a`` held), K."""
    from thermoskin.physics.network import steady_state

    if not (math.isfinite(R_w) and R_w > 0):
        return math.nan
    return float(steady_state(cfg.skin, R_w, np.array([0.0, 0.0, q, 0.0]))[0])


def dq_noise(log: Mapping[str, Array], cfg: Config, quiet: NDArray[np.bool_],
             dq: Array | None = None) -> float:
    """Standard deviation of the estimator's ``dq_i_hat`` on the log over the rows ``quiet``
    (module doc), W; NaN where there are fewer than 100. ``dq``: that estimate, if already run."""
    dq = np.asarray(_run(log, cfg).columns["dq_i_hat"] if dq is None else dq, dtype=float)
    ok = quiet & np.isfinite(dq)
    return float(np.std(dq[ok])) if ok.sum() >= 100 else math.nan


def _run(log: Mapping[str, ArrayLike], cfg: Config):  # type: ignore[no-untyped-def]
    from thermoskin.estimation.estimator import TouchEstimator

    # the re-dating of contacts changes their events, not dq_i_hat: not run (a misconfigured
    # skin's false contacts would each cost a fit)
    t = np.asarray(log["t"], dtype=float)
    est = TouchEstimator(cfg.replace(detector={"redate_readings": 0}), t_s=float(np.median(np.diff(t))))
    cmd = log.get("T_w_cmd")
    return est.run(t, *(np.asarray(log[k], dtype=float) for k in ("T_w", "T_p", "v", "T_a")),
                   None if cmd is None else np.asarray(cmd, dtype=float), log.get("fresh"))


def touch_snr(log: Mapping[str, Array], cfg: Config, quiet: NDArray[np.bool_],
              dq: Array | None = None) -> tuple[float, float, float]:
    """``(snr, touch heat W, dq noise W)`` of a one-finger touch on this log with ``cfg``
    (``dq``: the estimator's ``dq_i_hat`` on it, if already run)."""
    q = touch_heat(float(np.nanmedian(log["T_w"])), float(np.nanmedian(log["T_a"])), cfg)
    sd = dq_noise(log, cfg, quiet, dq)
    return (abs(q) / sd if sd > 0 else math.nan), q, sd


# ---------------------------------------------------------------------------- the check
def _fresh(log: Mapping[str, ArrayLike], bit: int) -> NDArray[np.bool_] | None:
    if "fresh" not in log:
        return None
    f = np.nan_to_num(np.asarray(log["fresh"], dtype=float), nan=7.0).astype(np.int64)
    return (f & bit) != 0


def _g(x: float, unit: str = "") -> str:
    return (f"{x:.4g}" + (f" {unit}" if unit else "")) if math.isfinite(x) else "n/a"


def check(log: Mapping[str, ArrayLike], cfg: Config, *, contact: ArrayLike | None = None) -> Report:
    """Check the log against ``cfg`` (module doc). ``log`` as :func:`~thermoskin.fit.calibrate.calibrate`
    takes it (``fresh``, ``T_w_cmd``, ``contact`` used where present). Raises :class:`CheckError`.

    A log with no contact column (a lab's own, touches in it or not) is checked twice: as it is,
    and without the contacts the estimator finds on it with ``cfg`` (as ``observe`` would); the
    one whose calibrated residual is the lower by a fifth is kept. Touches read as the skin's
    misfit drove the air's offset to +121 K and a fingertip's SNR to a third; but on a log
    without touches a misconfigured estimator's false contacts (a third of a calibration log's
    set-point steps) took away what the fit needed."""
    t_start = time.perf_counter()
    if contact is None and "contact" not in log:
        # one run of the estimator as configured: its contacts (as `observe` would find them;
        # the fit pads them itself), and its dq_i_hat for the SNR as configured, in both checks
        obs = _run(log, cfg).columns
        dq = np.asarray(obs["dq_i_hat"], dtype=float)
        plain = _check(log, cfg, None, "none: the log has no contact column", dq)
        c = np.asarray(obs["contact"], dtype=float) > 0.5
        if c.any():
            masked = _check(log, cfg, c, "the estimator's, the log having no contact column", dq)
            if masked.fits[-1].rms < 0.8 * plain.fits[-1].rms:
                plain = masked
        return dataclasses.replace(plain, wall_s=time.perf_counter() - t_start)
    report = _check(log, cfg, contact if contact is not None else log["contact"],
                    "those given" if contact is not None else "the log's contact column")
    return dataclasses.replace(report, wall_s=time.perf_counter() - t_start)


def _check(log: Mapping[str, ArrayLike], cfg: Config, contact: ArrayLike | None,
           contacts_from: str, dq_now: Array | None = None) -> Report:
    try:
        cols, blocks = cal.prepare(log, contact=contact)
    except cal.CalibrationError as e:
        raise CheckError(str(e)) from None
    t_s = blocks.t_s
    n = cols["t"].size
    duration = float(cols["t"][-1] - cols["t"][0] + t_s)
    v = cols["v"]
    on = v > 0
    switches = int(np.count_nonzero(on[1:] != on[:-1]))
    stops = cal._runs(~on & np.isfinite(v))
    stopped_s = max((b - a for a, b in stops), default=0) * t_s
    runs = cal._runs(np.isfinite(cols["T_a"]))
    air = cal.centred_mean(cols["T_a"], runs, round(0.5 * cal.SMOOTH_T_A / t_s))
    air_range = float(np.nanmax(air) - np.nanmin(air)) if np.isfinite(air).any() else 0.0

    # the sensors with the configured skin, then the skin too
    off = tuple(f"offset_{ch}" for ch in ("T_p", "T_a"))
    lags = ("lag_T_w", *(("lag_T_a",) if air_range >= AIR_STILL else ()))
    try:
        sens = cal.calibrate(log, cfg, (*off, *lags), contact=contact)
        full = cal.calibrate(log, cfg, (*cal.default_params(), *(p for p in lags if p in sens.written
                                                                  and sens.estimate[p] > 0.0)),
                             contact=contact)
    except cal.CalibrationError as e:
        raise CheckError(str(e)) from None
    as_is = cal.evaluate(blocks, {}, cfg)  # the configuration as it is

    w = blocks.weight
    seen = w > 0

    def fit_of(what: str, r: Array) -> Fit:
        """``r``: measured minus predicted (block means), K; the rms per reading (a block's mean
        weighed by its readings: white noise of ``sigma`` gives ``sigma``)."""
        e = (r * w)[seen]
        return Fit(what, float(np.sqrt(np.mean(e**2))), cal.autocorrelation_time(e))

    fits = [fit_of("as configured", as_is.e / np.where(seen, w, 1.0)),
            fit_of("configured skin, sensors as found", sens.residuals),
            fit_of("calibrated skin and sensors", full.residuals)]

    def pick(key: str) -> tuple[float, float, float, str, bool] | None:
        """A sensor parameter from the full fit where it is fitted there (written), else from the
        fit with the configured skin (said so; a lag written, an offset not: it rests on the
        skin); ``None`` if neither determined it."""
        for c, given in ((full, ""), (sens, " given the configured skin")):
            if key in c.requested and (key in c.names or c.held.get(key, "").startswith("no lag")):
                write = c is full or cal.kind(key) == "lag"
                return (c.estimate[key], c.low[key], c.high[key], c.status(key) + given
                        + ("" if write else "; not written: it rests on the skin's losses here "
                           "(record the pump stopping for seconds, commands stepping, and calibrate)"),
                        write)
        return None

    channels: dict[str, Channel] = {}
    found: dict[str, float] = {}
    for ch in cal.CHANNELS:
        x = cols[ch]
        fr = _fresh(log, BITS[ch])  # all rows fresh: a new reading every row (not guessed from changes)
        period, jitter, pfrom = period_of(x, t_s, fr)
        readings = x[fr] if fr is not None else (x if pfrom != "value changes" else
                                                  x[np.r_[True, x[1:] != x[:-1]]])
        q = cal.quantum_of(readings)
        noise = cal.reading_noise(x, blocks, fr if fr is not None else None)
        nfrom = "differences of the readings"
        if ch == "T_w" and math.isfinite(full.sigma) and full.sigma < noise:
            noise, nfrom = full.sigma, "residual of the calibrated model"
        key = f"offset_{ch}"
        o = float(getattr(cfg.sensor, key))
        olo = ohi = math.nan
        if ch == cal.REFERENCE:
            ost = "reference (only differences of offsets are seen)"
        elif (got := pick(key)) is not None:
            o, olo, ohi, ost, write = got
            if write:
                found[key] = o
        else:
            ost = "not determined, kept: " + _why(full.held.get(key) or sens.held.get(key, ""))
        lkey = f"lag_{ch}"
        lg = float(getattr(cfg.sensor, lkey))
        llo = lhi = math.nan
        if ch == "T_p":
            lst = "not in the model (kept as configured)"
        elif lkey not in sens.requested:
            lst = (f"not determined, kept: the air moved only {air_range:.2g} K (a lag shows at a door, "
                   "a draught)")
        elif (got := pick(lkey)) is not None:
            lg, llo, lhi, lst, write = got
            if write:
                found[lkey] = lg
        else:
            lst = "not determined, kept: " + _why(sens.held.get(lkey, ""))
        channels[ch] = Channel(ch, int(fr.sum()) if fr is not None else n, period, pfrom, jitter, q, noise,
                               nfrom, o, olo, ohi, ost, lg, llo, lhi, lst)
        if math.isfinite(period):
            found[f"period_{ch}"] = period
    c_w = channels["T_w"]
    found["noise_T"] = c_w.noise
    for ch, c in channels.items():  # each board's own (a configured noise_T_w, say, would
        found[f"noise_{ch}"] = c.noise  # otherwise outlive the noise_T found)
    found["quantum_T"] = c_w.quantum
    jit = max((c.jitter for c in channels.values() if c.period > 0 and math.isfinite(c.jitter)), default=0.0)
    periods = [c.period for c in channels.values() if c.period > 0 and math.isfinite(c.period)]
    if periods and jit < 0.5 * min(periods) and jit > t_s:
        found["jitter"] = jit
    else:
        found["jitter"] = 0.0
    found = _valid(found)

    # the SNR of a one-finger touch, as configured and with the sensors found
    quiet = np.ones(n, dtype=bool)
    quiet[: min(n, round(T_SKIP / t_s))] = False
    touched = (np.zeros(n, dtype=bool) if contact is None
               else np.nan_to_num(np.asarray(contact, dtype=float)) > 0.5)
    quiet &= ~touched
    runlog = {k: np.asarray(log[k], dtype=float) for k in ("t", "T_w", "T_p", "v", "T_a") if k in log}
    for k in ("T_w_cmd", "fresh"):
        if k in log:
            runlog[k] = np.asarray(log[k])
    snr_now, q1, sd_now = touch_snr(runlog, cfg, quiet, dq_now)
    # after the advice: the calibrated skin, the sensors found; the readings corrected by the
    # offsets found and the estimator told none (whether or not it reads them itself)
    after = full.config.replace(sensor={**found, **{k: 0.0 for k in cal.OFFSETS}})
    corrected = dict(runlog)
    for ch in cal.CHANNELS:
        key = f"offset_{ch}"
        corrected[ch] = runlog[ch] - found.get(key, float(getattr(cfg.sensor, key)))
    snr_found, _, sd_found = touch_snr(corrected, after, quiet)
    step = touch_step(after, full.estimate.get("R_w_flowing", math.nan), q1)

    report = Report(duration=duration, t_s=t_s, rows=n, switches=switches, stopped_s=stopped_s,
                    air_range=air_range, channels=channels, fits=fits, sensors=sens, skin=full,
                    snr_now=snr_now, snr_found=snr_found, touch_W=q1, dq_sd_now=sd_now,
                    dq_sd_found=sd_found, touch_step=step, found=found, advice=[], wall_s=0.0,
                    contacts_from=contacts_from, contact_s=float(np.count_nonzero(touched)) * t_s)
    return dataclasses.replace(report, advice=advice(report, cfg))


def _why(text: str) -> str:
    """The first clause of a held parameter's reason, short."""
    text = text.removeprefix("not determined by this log: ")
    return text.split(" (for ")[0].split("; ")[0]


def _valid(found: dict[str, float]) -> dict[str, float]:
    """The values found, each within its ``[sensor]`` range (a value outside is left out)."""
    out = {}
    for f in dataclasses.fields(SensorParams):
        if f.name in found and math.isfinite(found[f.name]):
            lo, hi = f.metadata["lo"], f.metadata["hi"]
            if lo <= found[f.name] <= hi:
                out[f.name] = float(found[f.name])
    return out


def advice(r: Report, cfg: Config) -> list[str]:
    """What to do next, most important first; ``nothing to do`` if nothing."""
    out: list[str] = []
    sens = cfg.sensor
    with_sensors, calibrated = r.fits[1].rms, r.fits[2].rms
    noise = r.channels["T_w"].noise
    if r.switches == 0:
        out.append("the pump never switches in this log: offsets and the pipe sensor's lag cannot be "
                   "seen; record one with the pump switching (commands stepping, as the calibration "
                   "scenario)")
    off = {p: (r.skin.prior_values[p], r.skin.estimate[p]) for p in r.skin.names if cal.kind(p) == "skin"
           and abs(math.log(r.skin.estimate[p] / r.skin.prior_values[p])) > math.log(1.0 + SKIN_RTOL)
           and not r.skin.low[p] <= r.skin.prior_values[p] <= r.skin.high[p]}
    if with_sensors > MISFIT * calibrated:
        what = ", ".join(f"{p} {b:.4g} for {a:.4g}" for p, (a, b) in off.items())
        out.append(f"calibrate: the configured skin leaves {with_sensors * 1e3:.3g} mK of residual, the "
                   f"calibrated one {calibrated * 1e3:.3g} mK (noise {noise * 1e3:.3g} mK)"
                   + (f"; it finds {what}" if what else "")
                   + ": thermoskin calibrate LOG --config YOUR.toml -o FITTED.toml")
    for p, why in r.skin.findings.items():
        out.append(f"look at the log: calibrating, {p} {why.split(':')[0]}: a misfit (a touch not "
                   "flagged, a sensor's lag, a wrong held value?)")
    setv: list[str] = []
    unwritten: list[str] = []
    for ch, c in r.channels.items():
        key, lkey, pkey = f"offset_{ch}", f"lag_{ch}", f"period_{ch}"
        if key in r.found and not (math.isfinite(c.offset_low) and c.offset_low <= getattr(sens, key)
                                   <= c.offset_high) and abs(c.offset - getattr(sens, key)) > OFFSET_ATOL:
            setv.append(f"{key} = {c.offset:+.3f}")
        elif "not written" in c.offset_status:
            unwritten.append(key)
        conf_lag = getattr(sens, lkey)
        if lkey in r.found and not (math.isfinite(c.lag_low) and c.lag_low <= conf_lag <= c.lag_high) \
                and abs(c.lag - conf_lag) > max(LAG_ATOL, 0.2 * c.lag):
            setv.append(f"{lkey} = {c.lag:.3g}")
        if pkey in r.found and abs(r.found[pkey] - getattr(sens, pkey)) > max(r.t_s, 0.1 * r.found[pkey]):
            setv.append(f"{pkey} = {r.found[pkey]:.3g}")
    if unwritten:
        out.append(f"{', '.join(unwritten)}: this log tells them only given the skin's losses (the pump "
                   "never stops for long): record one with the commands stepping (the calibration "
                   "scenario: stops of seconds) and calibrate it")
    for ch in ("T_w", "T_p", "T_a"):
        nc = r.found.get(f"noise_{ch}", math.nan)
        if abs(nc - sens.noise(ch)) > NOISE_RTOL * max(sens.noise(ch), 1e-9):
            setv.append(f"noise_{ch} = {nc:.3g}")
    qT = r.found.get("quantum_T", math.nan)
    if abs(qT - sens.quantum_T) > 0.05 * max(sens.quantum_T, qT):
        setv.append(f"quantum_T = {qT:.4g}")
    if setv:
        out.append("set in [sensor]: " + ", ".join(setv) + " (--write-config OUT.toml writes them)")
    c_w = r.channels["T_w"]
    if c_w.quantum > 0 and c_w.noise < 0.5 * c_w.quantum and r.touch_step < 0.5 * c_w.quantum:
        out.append(f"a one-finger touch moves the T_w reading by {r.touch_step * 1e3:.2g} mK in steady state "
                   f"(the pump running), the converter's step is {c_w.quantum * 1e3:.3g} mK and the noise "
                   f"{c_w.noise * 1e3:.2g} mK, too little to dither it: such a touch is below what these "
                   "readings resolve, whatever the estimate's SNR; a finer converter (MAX31856: 1/128 K)")
    elif math.isfinite(r.snr_found) and r.snr_found < SNR_MIN:
        out.append(f"a one-finger touch ({r.touch_W * 1e3:.0f} mW) is below what these readings resolve: "
                   f"SNR {r.snr_found:.2g} with the sensors found (under {SNR_MIN:g}); expect missed "
                   "touches: quieter or finer thermocouple boards, or a larger temperature difference")
    if not out:
        out.append("nothing to do: the configuration fits these readings")
    return out


# ---------------------------------------------------------------------------- output
TABLE = ("channel", "period (ms)", "quantum (mK)", "noise (mK)", "offset (K)", "lag (s)")


def table_rows(r: Report) -> list[tuple[str, ...]]:
    """The per-channel table (:data:`TABLE`): numbers with their 95 % half-widths; ``*``: kept
    as configured (see :func:`notes`)."""
    rows = []
    for ch, c in r.channels.items():
        period = ("every row" if c.period == 0 else f"{c.period * 1e3:.4g}"
                  + (f"±{c.jitter * 1e3:.2g}" if c.jitter > 0 else ""))
        if math.isfinite(c.offset_low):
            offset = f"{c.offset:+.4f}±{0.5 * (c.offset_high - c.offset_low):.1g}"
        else:
            offset = f"{c.offset:+.4f}" + ("" if ch == cal.REFERENCE else "*")
        if math.isfinite(c.lag_low) and c.lag_status.startswith("fitted"):
            lag = f"{c.lag:.3f}±{0.5 * (c.lag_high - c.lag_low):.1g}"
        else:
            lag = f"{c.lag:.3f}" + ("" if c.lag_status.startswith("no lag") else "*")
        rows.append((ch, period, f"{c.quantum * 1e3:.4g}" if c.quantum > 0 else "none",
                     _g(c.noise * 1e3), offset, lag))
    return rows


def notes(r: Report) -> list[str]:
    """How each channel's period, noise, offset and lag were found (or why not)."""
    out = []
    for ch, c in r.channels.items():
        period = {"every row": "a new reading every row", "fresh column": "from the fresh column",
                  "value changes": "from the changes of the value (no fresh column)"}[c.period_from]
        out.append(f"{ch}: {c.readings} readings, period {period}; noise from the {c.noise_from}; offset "
                   f"{c.offset_status}; lag {c.lag_status}")
    return out


def summary_lines(r: Report) -> list[str]:
    """The log, the fits and the SNR, one line each."""
    lines = [f"{r.duration:.1f} s, {r.rows} rows at {r.t_s * 1e3:.3g} ms; pump: {r.switches} switches, "
             f"longest stop {r.stopped_s:.2g} s; air moved {r.air_range:.2g} K; contacts left out: "
             f"{r.contact_s:.3g} s ({r.contacts_from})"]
    for f in r.fits:
        lines.append(f"T_w residual, {f.what}: {f.rms * 1e3:.3g} mK rms (autocorrelation time "
                     f"{f.tau:.3g} {'blocks' if r.skin.blocks.m > 1 else 'samples'})")
    lines.append(f"one-finger touch ({FINGER_G:g} W/K at {FINGER_T:g} °C): {r.touch_W * 1e3:.0f} mW into the "
                 f"sheet, {r.touch_step * 1e3:.2g} mK on T_w at rest; SNR {r.snr_now:.3g} as configured "
                 f"(dq_i_hat noise {r.dq_sd_now * 1e3:.3g} mW), {r.snr_found:.3g} after the advice below "
                 f"(calibrated skin, sensors found: {r.dq_sd_found * 1e3:.3g} mW)")
    lines.append(f"offsets are relative to {cal.REFERENCE}'s (only their differences reach the readings); "
                 f"checked in {r.wall_s:.1f} s")
    return lines


def to_toml_text(r: Report, cfg: Config, source: str = "") -> str:
    """``cfg`` with the ``[sensor]`` section found, as TOML, with what was found as comments."""
    head = ["# thermoskin check" + (f": the [sensor] section found in {source}" if source else "")]
    head += [f"# {line}" for line in summary_lines(r)]
    head += [f"# {line}" for line in notes(r)]
    out = []
    section = ""
    for line in to_toml(r.config(cfg)).splitlines():
        if line.startswith("["):
            section = line.strip("[]")
        key = line.split("=", 1)[0].strip() if "=" in line else ""
        if section == "sensor" and key in r.found:
            line += "; found in the log"
        out.append(line)
    return "\n".join(head) + "\n\n" + "\n".join(out) + "\n"


def save(r: Report, cfg: Config, path: str | Path, source: str = "") -> Path:
    """Write :func:`to_toml_text` to ``path`` (a config ``load_config`` reads), whole or not at all."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    write_text(p, to_toml_text(r, cfg, source))
    return p
