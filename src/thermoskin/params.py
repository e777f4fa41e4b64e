"""Typed, frozen parameter sets, the paper's Table I preset, and TOML load/save.

Every field carries its unit and allowed range in its metadata; ``validate`` (called
from ``__post_init__``) raises :class:`ConfigError` naming the key, the value and the
range. A TOML file overrides any subset of a preset::

    [skin]
    R_g = 12.0
    R_w_flowing = 0.25   # K/W, replaces the convection model while the pump runs

Tables: ``[skin] [sampling] [observer] [estimator] [detector] [sensor] [pump] [peltier] [control]
[safety] [plausible] [peltier_model]``. Every number has a physical range on both sides: a value outside it
(``C_w = 1e300``, ``t_s = 1e-12``) is refused with one line naming the key and the range.
"""

from __future__ import annotations

import dataclasses
import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

INF = math.inf


class ConfigError(ValueError):
    """A configuration value or key is wrong; the message names which and where."""


def _p(default: Any, unit: str, lo: float = -INF, hi: float = INF, *, lo_open: bool = False,
       doc: str = "", optional: bool = False, choices: tuple[str, ...] = ()) -> Any:
    """A parameter field with unit, range and doc in its metadata."""
    meta = {"unit": unit, "lo": lo, "hi": hi, "lo_open": lo_open, "doc": doc,
            "optional": optional, "choices": choices}
    return field(default=default, metadata=meta)


def _unit_text(meta: dict[str, Any]) -> str:
    """`` (unit)`` for a message, nothing for a unitless value."""
    return f" ({meta['unit']})" if meta["unit"] else ""


def _range_text(meta: dict[str, Any]) -> str:
    if meta["choices"]:
        return "one of " + ", ".join(repr(c) for c in meta["choices"])
    lo, hi = meta["lo"], meta["hi"]
    left = f"> {lo:g}" if meta["lo_open"] else f">= {lo:g}"
    if hi == INF:
        return left
    return f"{left} and <= {hi:g}"


class _Validated:
    """Mixin: range-check every field of a frozen dataclass after construction."""

    section: str = ""

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            meta = f.metadata
            if not meta:
                continue
            value = getattr(self, f.name)
            key = f"{self.section}.{f.name}"
            if value is None and meta["optional"]:
                continue
            if meta["choices"]:
                if value not in meta["choices"]:
                    raise ConfigError(f"{key} = {value!r} is not allowed: must be "
                                      f"{_range_text(meta)}")
                continue
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ConfigError(f"{key} = {value!r} is not a number: must be "
                                  f"{_range_text(meta)}{_unit_text(meta)}")
            v = float(value)
            is_int = isinstance(f.default, int) and not isinstance(f.default, bool)
            if is_int and not v.is_integer():
                raise ConfigError(f"{key} = {value!r} is not a whole number: must be "
                                  f"{_range_text(meta)}{_unit_text(meta)}")
            lo, hi = meta["lo"], meta["hi"]
            bad = (not math.isfinite(v) or v > hi or v < lo or (meta["lo_open"] and v <= lo))
            if bad:
                raise ConfigError(f"{key} = {value!r} is out of range: must be "
                                  f"{_range_text(meta)}{_unit_text(meta)}")
            object.__setattr__(self, f.name, int(v) if is_int else v)


@dataclass(frozen=True)
class SkinParams(_Validated):
    """The skin's thermal network (Fig. 3) and water-flow geometry (eqs. 1-2).

    Defaults are Table I, taken as the identified values of the paper's prototype.
    """

    section = "skin"
    C_w: float = _p(0.134, "J/K", 1e-4, 1e4, doc="thermal capacitance of the water pipe")
    C_g: float = _p(0.0124, "J/K", 1e-5, 1e3, doc="thermal capacitance of the graphite sheet")
    R_g: float = _p(10.0, "K/W", 1e-3, 1e4, doc="thermal resistance pipe to sheet")
    R_aw: float = _p(2100.0, "K/W", 1e-2, 1e6, doc="thermal resistance pipe to air")
    R_ag: float = _p(1.0, "K/W", 1e-3, 1e4, doc="thermal resistance sheet to air")
    A: float = _p(3.2e-3, "m^2", 1e-6, 1.0, doc="heat-exchange area of the water tank (eq. 1)")
    V: float = _p(3.2e-5, "m^3", 1e-9, 1e-2, doc="volume of the water tank (eq. 2)")
    d: float = _p(3.0e-3, "m", 1e-4, 0.1, doc="characteristic pipe diameter")
    L: float = _p(0.11, "m", 1e-3, 10.0, doc="length of the pipe and the tank")
    R_w_flowing: float | None = _p(None, "K/W", 1e-3, 1e5, optional=True,
                                   doc="R_w while the pump runs; replaces the convection model")
    R_w_stopped: float | None = _p(None, "K/W", 1e-3, 1e5, optional=True,
                                   doc="R_w while the pump is stopped; replaces the conduction model")
    water: str = _p("iapws", "", choices=("iapws", "table1"),
                    doc="water properties: IAPWS formulations at T_ref, or Table I's printed values")
    T_ref: float = _p(24.0, "degC", 0.5, 99.0, doc="water temperature for the properties")


@dataclass(frozen=True)
class SamplingParams(_Validated):
    """Sampling of the loop."""

    section = "sampling"
    t_s: float = _p(1.0e-3, "s", 1e-4, 1.0, doc="sampling time (Table I)")


@dataclass(frozen=True)
class ObserverParams(_Validated):
    """Thermal exchange observer (eq. 8) and its contact residual."""

    section = "observer"
    n_init: int = _p(1000, "samples", 1, 10_000,
                     doc="first samples averaged for the steady-state start")
    tau_r: float = _p(0.05, "s", 1e-4, 10.0,
                      doc="time constant of the contact residual's double low-pass")
    max_gap_s: float = _p(2.0, "s", 1e-3, 3600.0,
                          doc="longest NaN gap held over; longer gaps restart the observer")


@dataclass(frozen=True)
class EstimatorParams(_Validated):
    """The sensor-aware touch estimator (``estimation.model``): a Kalman filter on the network.

    Spectral densities of the model's white process noises; they set how fast the estimate
    follows a change (``S_q``) and how much the model trusts itself between readings.
    """

    section = "estimator"
    S_q: float = _p(1.0, "W^2/s", 1e-9, 1e6,
                    doc="random-walk density of the touch heat q_i in a contact: how fast the "
                        "estimate follows it")
    S_q_idle: float = _p(1e-4, "W^2/s", 1e-12, 1e6,
                         doc="the same while no contact is detected: slow drift only, so that a "
                             "touch is not absorbed before it is detected")
    S_p: float = _p(0.01, "K^2/s^3", 1e-12, 1e6,
                    doc="acceleration density of the tank temperature T_p (constant-velocity model)")
    S_a: float = _p(1e-3, "K^2/s", 1e-12, 1e6,
                    doc="random-walk density of the ambient temperature T_a")
    S_w: float = _p(1e-8, "K^2/s", 0.0, 1e6, doc="model error on the pipe node")
    S_w_flow: float = _p(0.0, "K^2/s", 0.0, 1e6,
                         doc="more model error on the pipe node while the pump runs: water comes in "
                             "whose temperature the inlet's thermocouple, read only now and then, "
                             "has not seen (a skin sets it from its boards' period, docs/skin.md)")
    switch_bins: int = _p(64, "samples", 0, 64,
                          doc="pump-cycle correction of T_w: the mean no-touch misfit per sample "
                              "since the last pump switch, this many bins per direction (a skin "
                              "unlike its configuration, docs/model.md; a pipe of many cells, "
                              "docs/skin.md; learnt from 200 readings a second and more; 0: none)")
    switch_learn: float = _p(0.02, "", 1e-6, 1.0,
                             doc="its learning weight per no-touch reading")
    tank_gain: float | None = _p(None, "K/s", 0.0, 1e3, optional=True,
                                 doc="the tank's rate per unit Peltier drive; default: the [peltier] "
                                     "modules' Peltier heat over the tank's capacitance")
    tank_jump: float = _p(4.0, "sd", 1.0, 100.0,
                          doc="a T_p reading this many standard deviations off is a manoeuvre of "
                              "the tank (a drive step): its slope is let go")
    tau_noise: float = _p(3.0, "s", 0.0, 3600.0,
                          doc="each channel's reading variance is learnt from its innovations over "
                              "about this long (0: the configured noise_T and quantum_T are taken as "
                              "they are)")
    phase_tol: float = _p(0.004, "s", 0.0, 0.1,
                          doc="a slow board's pipe reading (below 200 a second) is paired with the "
                              "last one at the same point of the pump's cycle to within this, its "
                              "noise learnt from their difference (0: held at its configured value)")
    lag_drift: float = _p(1e-6, "s^2/s", 0.0, 1.0,
                          doc="the learnt lag's random walk")
    lag_max: float = _p(1.0, "s", 0.0, 60.0, doc="the longest pipe-thermocouple lag learnt")
    offset_drift: float = _p(1e-6, "K^2/s", 0.0, 1.0,
                             doc="the learnt offset's random walk (it follows slow changes: a board "
                                 "warming, a skin slightly off at a new operating point)")
    tank_jump_s: float = _p(0.3, "s", 1e-3, 60.0,
                            doc="time over which such a jump is taken as a change of slope")
    max_gap_s: float = _p(2.0, "s", 1e-3, 3600.0,
                          doc="a pipe reading missing for longer restarts the estimate")


@dataclass(frozen=True)
class DetectorParams(_Validated):
    """Two-sided contact detector on the estimator's standardised touch heat."""

    section = "detector"
    dq_design: float = _p(0.3, "W", 1e-4, 100.0,
                          doc="the changes of the touch heat two CUSUMs are tuned to: this one (a "
                              "light fingertip) ...")
    dq_design_hi: float = _p(0.6, "W", 1e-4, 100.0,
                             doc="... and this one (two fingers and more)")
    dq_design_lo: float = _p(0.15, "W", 1e-4, 100.0,
                             doc="a third pair of CUSUMs, of this design: it dates and sizes a step "
                                 "weaker than dq_design ...")
    h_lo: float = _p(2.0, "", 0.0, 1000.0,
                     doc="... and fires only this far above the onset threshold (1000: never)")
    onset_state_jump: float = _p(1.0, "", 0.0, 1.0,
                                 doc="1: at an onset the whole state takes the step as it would have "
                                     "left it (its signature); 0: q_i alone takes the jump (a skin "
                                     "patch, whose pipe node the signature misleads)")
    onset_glr: float = _p(1.0, "", 0.0, 1.0,
                          doc="1: an onset is dated by the generalised likelihood ratio over the "
                              "change time within the firing CUSUM's window; 0: at that CUSUM's "
                              "last zero")
    onset_glr_pool: float = _p(0.0125, "s", 0.0, 10.0,
                               doc="its buffer of 256 entries pools the readings less than this "
                                   "after an entry's first (1 kHz: 13 readings, 3.3 s held; 100 Hz: "
                                   "2, 5 s; 10 Hz boards: one cycle of the T_w and T_p boards, 25 s)")
    h_on: float = _p(6.0, "", 0.0, 1000.0, lo_open=True,
                     doc="onset threshold, log-likelihood ratio of a touch against none, for one "
                         "pipe reading a second ...")
    h_rate: float = _p(1.52, "", 0.0, 100.0,
                       doc="... plus this times ln(readings per second): more readings, more "
                           "chances of a false alarm (10 Hz boards: 9.5, 100 Hz: 13.0, 1 kHz: 16.5)")
    rho_window: float = _p(0.4, "s", 0.0, 60.0,
                           doc="window of the onset evidence's dispersion, learnt while idle: where "
                               "the model does not fit the readings the detector needs that much more "
                               "evidence (0: none)")
    rho_window_long: float = _p(8.0, "s", 0.0, 600.0,
                                doc="the dispersion's long window, where a converter's step is coarse "
                                    "and the boards fast: a misfit slower than rho_window (a tank "
                                    "drifting within one step) widens the detector too (0: none)")
    rho_phases: int = _p(1, "", 0, 1,
                         doc="the dispersion also over each phase of the pump's cycle, boards of 200 "
                             "readings a second and more: a misfit locked to the cycle (a skin "
                             "unlike its configuration), which cancels within rho_window, widens "
                             "the detector too (0: not)")
    rho_deadband: float = _p(1.5, "", 1.0, 100.0,
                             doc="a dispersion up to this is taken as none (its tracker's own scatter)")
    rho_prior: float = _p(1.0, "", 0.001, 100.0,
                          doc="the dispersion before it has three windows of its own (1: the model "
                              "fits; above rho_deadband a touch then needs that much more evidence)")
    h_min: float = _p(11.9, "", 0.0, 1000.0,
                      doc="... and never below this: a CUSUM alarms on noise about once in e^h "
                          "readings (Lorden), so at a few readings a second each carries much "
                          "evidence; 11.9 is once in 4 h at 10 readings a second (10 Hz boards: "
                          "11.9 rather than 9.5, which alarmed about once in 22 min)")
    redate_readings: float = _p(3000.0, "", 0.0, 1e7,
                                doc="a contact's onset and release are dated again when it ends, by "
                                    "a pulse fit on a detection-free filter, where that fit weighs at "
                                    "most this many pipe readings (its cost grows with the readings "
                                    "and rows it runs over: 1.5-3 ms a contact): with 10 Hz boards or "
                                    "a 100 Hz log every contact up to 27 s, at 1 kHz taps up to 0.7 s; "
                                    "0: never")
    redate_reach: float = _p(0.5, "s", 0.01, 5.0,
                             doc="the fit's onset and release lie within this of the detector's")
    redate_tail: float = _p(0.8, "s", 0.0, 10.0,
                            doc="readings used after the detector's release (the event is "
                                "written this much after it)")
    k_off: float = _p(1.0, "sigma", 0.0, 100.0, doc="release threshold in noise standard deviations")
    f_off: float = _p(0.35, "", 0.0, 1.0,
                      doc="release threshold as a fraction of the contact's smoothed level")
    tau_level: float = _p(0.1, "s", 1e-4, 60.0,
                          doc="smoothing of the contact's level for the release threshold")
    k_rel: float = _p(1.0, "sigma", 0.0, 100.0,
                      doc="release CUSUM drift: evidence accrues while the estimate is this far below")
    h_off: float = _p(0.05, "sigma s", 1e-4, 100.0,
                      doc="release CUSUM threshold")
    t_warmup: float = _p(1.0, "s", 0.0, 600.0, doc="initial no-touch time to learn noise")
    t_confirm: float = _p(0.2, "s", 0.0, 60.0,
                          doc="a contact ended this soon after its detection, with no reading since "
                              "the detection favouring it over no touch, is withdrawn (noise; no "
                              "event); 0: never")
    confirm_mean: float = _p(0.5, "", 0.0, 10.0,
                             doc="... and so is a contact whose mean heat over it is below this "
                                 "share of dq_design_lo (its sign's way): it brought nothing")
    confirm_time: float = _p(0.2, "s", 0.0, 60.0,
                             doc="... or whose heat over it (its mean times its duration, J) is "
                                 "below confirm_mean x dq_design_lo over this long: the shortest "
                                 "touch the detector is made for (a tap); 0: never")
    t_refractory: float = _p(3.0, "s", 0.0, 60.0,
                             doc="after a release, no onset of the opposite sign for this long")
    t_pair: float = _p(5.0, "s", 0.0, 600.0,
                       doc="a negative onset this soon after positive evidence above half the "
                           "threshold that came to no contact is that touch's end (a touch too "
                           "weak to detect): the estimate takes it, no contact; 0: never")
    release_readings: float = _p(3.0, "", 0.0, 1000.0,
                                 doc="a release needs its evidence over at least this many pipe "
                                     "readings (a slow board's one reading off ends no touch)")
    release_phases: int = _p(1, "", 0, 1,
                             doc="where the dispersion over the pump's phases is above rho_deadband "
                                 "(a misfit locked to the pump's cycle, rho_phases), a release needs "
                                 "its evidence over the last whole pump phase and this one: a dip "
                                 "at one pulse ends no touch (0: not)")
    door_follow: int = _p(1, "", 0, 1,
                          doc="armed, from a door's start (a sudden change of the air) for t_air plus "
                              "the air sensor's lag, the estimate follows the sheet's heat as in a "
                              "contact: an air sensor slower than configured leaves the sheet a heat "
                              "no model has while the door lasts, which the estimate otherwise gave "
                              "back over seconds after the hold, read as a touch (0: not)")
    t_air: float = _p(1.0, "s", 0.0, 600.0,
                      doc="after a sudden change of the air (a door), no onset for this long plus "
                          "the air sensor's lag (its CUSUMs gather evidence, the baseline and "
                          "what is learnt stay)")
    air_rate: float = _p(0.1, "K/s", 0.0, 100.0,
                         doc="... and while the air's reading moves faster than this (over 0.5 s): "
                             "a sensor that lags more than configured reads a door as a ramp, "
                             "while the sheet feels the air itself (0: never)")
    t_settle: float = _p(2.0, "s", 0.0, 600.0,
                         doc="after a release, time before the baseline learns again")
    tau_baseline: float = _p(20.0, "s", 0.1, 3600.0,
                             doc="time constant of the no-touch baseline")
    tau_sigma: float = _p(20.0, "s", 0.1, 3600.0,
                          doc="time constant of the innovations' scale estimate")
    z_scale: float = _p(0.6, "", 1e-3, 100.0,
                        doc="standard deviation of the contact estimate over its filter's own sd "
                            "(for the release threshold)")
    arm_band: float = _p(0.5, "K", 1e-3, 50.0,
                         doc="in a loop with a command: detection starts once |T_w - T_w_cmd| ...")
    t_arm: float = _p(3.0, "s", 0.0, 600.0, doc="... has stayed within arm_band this long")
    max_contact_s: float = _p(300.0, "s", 0.1, 1e6,
                              doc="a contact longer than this is taken as a drift and ended")


@dataclass(frozen=True)
class SensorParams(_Validated):
    """Thermocouple boards of the simulated skin (``sim.sensors``): one per channel.

    Each board converts every ``period_*`` s (0: every sample) at instants jittered by up
    to ``jitter`` s and holds its reading in between; its sensing element lags the true
    temperature with time constant ``lag_*`` s (0: none). The defaults are ideal sensors:
    a fresh reading every sample, noise and quantum only.
    """

    section = "sensor"
    noise_T: float = _p(0.02, "K", 0.0, 10.0, doc="thermocouple noise (standard deviation)")
    noise_T_w: float | None = _p(None, "K", 0.0, 10.0, optional=True,
                                 doc="the T_w board's noise (standard deviation; unset: noise_T)")
    noise_T_p: float | None = _p(None, "K", 0.0, 10.0, optional=True,
                                 doc="the T_p board's noise (unset: noise_T)")
    noise_T_a: float | None = _p(None, "K", 0.0, 10.0, optional=True,
                                 doc="the T_a board's noise (unset: noise_T)")
    quantum_T: float = _p(0.0078125, "K", 0.0, 10.0,
                          doc="thermocouple resolution (0 = none); 1/128 K as a MAX31856")
    seed: int = _p(0, "", 0, 2**32 - 1, doc="random seed of the sensor noise and jitter")
    period_T_w: float = _p(0.0, "s", 0.0, 60.0,
                           doc="conversion period of the T_w board (0 = every sample; 0.1 = a "
                               "10 Hz MAX31856); the reading is held in between")
    period_T_p: float = _p(0.0, "s", 0.0, 60.0, doc="conversion period of the T_p board (0 = every sample)")
    period_T_a: float = _p(0.0, "s", 0.0, 60.0, doc="conversion period of the T_a board (0 = every sample)")
    jitter: float = _p(0.0, "s", 0.0, 1.0,
                       doc="conversion instants uniform within +-jitter of their nominal j*period "
                           "(below half of every non-zero period)")
    lag_T_w: float = _p(0.0, "s", 0.0, 600.0,
                        doc="time constant of the T_w sensing element's first-order lag (0 = none)")
    lag_T_p: float = _p(0.0, "s", 0.0, 600.0,
                        doc="time constant of the T_p sensing element's first-order lag (0 = none)")
    lag_T_a: float = _p(0.0, "s", 0.0, 600.0,
                        doc="time constant of the air sensor's lag (0 = none; a bead in still air "
                            "about 1 s)")
    offset_T_w: float = _p(0.0, "K", -5.0, 5.0,
                           doc="the T_w reading's offset: reading minus true temperature (a board's "
                               "cold junction); only the differences between channels are observable")
    offset_T_p: float = _p(0.0, "K", -5.0, 5.0, doc="the T_p reading's offset (as offset_T_w)")
    offset_T_a: float = _p(0.0, "K", -5.0, 5.0, doc="the T_a reading's offset (as offset_T_w)")
    lag_sd: float = _p(0.05, "s", 0.0, 60.0,
                       doc="how far the T_w thermocouple's lag may be from lag_T_w (the prior of the "
                           "lag the estimator learns; 0: lag_T_w is taken as it is): a bead in water "
                           "lags tens of ms")
    offset_sd: float = _p(0.3, "K", 0.0, 5.0,
                          doc="how far the T_p readings' offset against the T_w readings' may be from "
                              "the configured ones (the prior of the offset the estimator learns; "
                              "0: not learnt): type K boards are within about 0.3 K of each other")

    def noise(self, channel: str) -> float:
        """The noise of ``channel``'s board (``T_w``, ``T_p`` or ``T_a``), K: its own key, or
        ``noise_T``."""
        own = getattr(self, f"noise_{channel}")
        return self.noise_T if own is None else own

    def __post_init__(self) -> None:
        super().__post_init__()
        for ch in ("T_w", "T_p", "T_a"):
            period = getattr(self, f"period_{ch}")
            if period > 0.0 and not self.jitter < 0.5 * period:
                raise ConfigError(f"sensor.jitter = {self.jitter!r} is out of range: must be below "
                                  f"half of sensor.period_{ch} = {period!r} (s)")


@dataclass(frozen=True)
class PumpParams(_Validated):
    """Water pump: runs at ``v_on`` and stops while ``T_w`` is above its command."""

    section = "pump"
    v_on: float = _p(0.141, "m/s", 1e-3, 10.0, doc="water velocity when running")
    hysteresis: float = _p(0.0, "K", 0.0, 10.0,
                           doc="band around the command; 0 gives the paper's chattering")
    min_dwell: float = _p(0.05, "s", 0.0, 60.0,
                          doc="shortest time the pump holds a state (a real pump's inertia)")
    still_readings: int = _p(2, "readings", 1, 1000,
                             doc="once stopped, the pump stays stopped for at least this many new "
                                 "T_w readings (1: the paper's rule)")


@dataclass(frozen=True)
class PeltierParams(_Validated):
    """Peltier modules heating or cooling the water tank, with heat sink and fan.

    Defaults: two common 40 x 40 mm modules (TEC1-12706 class: 127 couples, about 6 A,
    15 V), as in the paper's setup (Sec. VI-A); the tank of Table I (``V = 3.2e-5 m^3``).
    """

    section = "peltier"
    n_modules: int = _p(2, "", 1, 16, doc="modules in parallel on the tank")
    S_m: float = _p(0.053, "V/K", 1e-4, 1.0, doc="module Seebeck coefficient")
    R_m: float = _p(2.0, "ohm", 1e-3, 100.0, doc="module electrical resistance")
    K_m: float = _p(0.45, "W/K", 1e-3, 100.0, doc="module thermal conductance")
    I_max: float = _p(6.0, "A", 1e-2, 100.0, doc="drive current at |drive| = 1")
    C_tank: float = _p(150.0, "J/K", 1.0, 1e5, doc="tank water and plate")
    R_tank_air: float = _p(8.0, "K/W", 1e-2, 1e4, doc="tank to air")
    C_sink: float = _p(80.0, "J/K", 1.0, 1e5, doc="heat sink")
    R_sink: float = _p(0.25, "K/W", 1e-3, 1e3, doc="heat sink to air, fan running")


@dataclass(frozen=True)
class ControlParams(_Validated):
    """Temperature control (Sec. V): MPC of eqs. 9-11, inner loop on the Peltier drive."""

    section = "control"
    H: int = _p(100, "samples", 1, 2000, doc="prediction horizon (Table I)")
    W1: float = _p(1.0, "1/K^2", 0.0, 1e6, doc="weight of the tracking error (eq. 9)")
    W2: float = _p(0.03, "1/K^2", 0.0, 1e6, doc="weight of the input term (eq. 9)")
    cost: str = _p("rate", "", choices=("rate", "deviation", "absolute"),
                   doc="eq. 9's input term: rate of T_p (default), deviation from the "
                       "steady-state input, or the absolute T_p as printed")
    T_p_min: float = _p(7.0, "degC", -20.0, 80.0, doc="lower bound of T_p_cmd (Table I)")
    T_p_max: float = _p(37.0, "degC", -20.0, 80.0, doc="upper bound of T_p_cmd (Table I)")
    Kp: float = _p(0.1, "1/K", 0.0, 100.0, doc="inner loop proportional gain (Table I)")
    Ki: float = _p(0.03, "1/(K s)", 0.0, 100.0, doc="inner loop integral gain (Table I)")
    drive_min: float = _p(-1.0, "", -1.0, 0.0, doc="lowest drive (full cooling)")
    drive_max: float = _p(1.0, "", 0.0, 1.0, doc="highest drive (full heating)")


@dataclass(frozen=True)
class SafetyParams(_Validated):
    """The safety supervisor between the blocks and the device (``runtime.supervisor``).

    ``T_touch_max`` defaults to 40 degC: 3 K under the 43 degC that ISO 13732-1:2006 gives
    as the burn threshold for contact of 8 h and longer with any material, and that
    IEC 60601-1 (Table 24) allows for applied parts in contact for 10 min and longer.
    """

    section = "safety"
    T_p_min: float = _p(4.0, "degC", -20.0, 80.0, doc="lowest allowed T_p reading (tank)")
    T_p_max: float = _p(40.0, "degC", -20.0, 80.0, doc="highest allowed T_p reading (tank)")
    T_touch_max: float = _p(40.0, "degC", 20.0, 60.0,
                            doc="touch-safe limit on the estimated surface temperature")
    surface: str = _p("pipe", "", choices=("pipe", "network"),
                      doc="surface estimate: T_w (upper bound while heating) or the network's "
                          "steady no-touch sheet temperature")
    max_nan_s: float = _p(0.15, "s", 0.0, 10.0,
                          doc="a NaN reading lasting longer trips (shorter gaps are held over)")
    link_timeout_s: float = _p(0.05, "s", 1e-3, 10.0,
                               doc="no sample from the device for longer trips")
    stale_s: float = _p(0.5, "s", 1e-3, 60.0,
                        doc="a thermocouple with no new reading for longer trips")
    stuck_readings: int = _p(10, "readings", 0, 10_000,
                             doc="this many equal new readings in a row trip (0: off)")


@dataclass(frozen=True)
class PeltierModelParams(_Validated):
    """An identified model of the Peltier tank, as ``thermoskin identify`` writes it.

    The ARX model ``A(q) T_p[k] = B(q) drive[k] + d T_a[k-1] + c`` at sample time ``t_s``
    (``A = 1 + a_1 q^-1 + ...``, ``B = b_1 q^-nk + ...``; :mod:`thermoskin.fit.identify`). With
    ``use = "feedforward"`` the inner loop adds the drive that holds the commanded ``T_p`` in
    the model's steady state, ``drive_ff = (T_p_cmd - T_a) A(1)/B(1)`` (without the ``T_a``
    input; the tank at zero drive sits at the air) or ``(A(1) T_p_cmd - d T_a - c)/B(1)``
    (with it), and its PI only corrects the rest (``control.inner``). ``use = "off"``
    keeps the model for reference only. The fit figures are informational.
    """

    section = "peltier_model"
    use: str = _p("off", "", choices=("off", "feedforward"),
                  doc="what the controller does with the model: nothing, or a feedforward on the drive")
    t_s: float = _p(0.1, "s", 1e-4, 60.0, doc="the model's sample time")
    nk: int = _p(0, "samples", 0, 100, doc="input delay of B(q)")
    a: tuple[float, ...] = ()
    """``a_1 .. a_na`` (1 to 20 values)."""
    b: tuple[float, ...] = ()
    """``b_1 .. b_nb`` (1 to 20 values)."""
    c: float = _p(0.0, "K", -1e6, 1e6, doc="constant of the ARX equation")
    d: float = _p(0.0, "", -1e3, 1e3, doc="coefficient of T_a[k-1] (0 without that input)")
    with_T_a: bool = False
    nrmse: float | None = _p(None, "", -1e9, 1.0, optional=True,
                             doc="simulation fit on the held-back data (1 = perfect)")
    nrmse_est: float | None = _p(None, "", -1e9, 1.0, optional=True,
                                 doc="simulation fit on the estimation data")
    rmse: float | None = _p(None, "K", 0.0, 1e6, optional=True, doc="RMSE on the held-back data")

    def __post_init__(self) -> None:
        super().__post_init__()
        for name in ("a", "b"):
            raw = getattr(self, name)
            if not isinstance(raw, list | tuple) or len(raw) > 20:
                raise ConfigError(f"peltier_model.{name} = {raw!r} must be a list of at most 20 numbers")
            vals = []
            for x in raw:
                if isinstance(x, bool) or not isinstance(x, int | float) or not -1e6 <= x <= 1e6:
                    raise ConfigError(f"peltier_model.{name} = {raw!r}: {x!r} is not a number within "
                                      "[-1e6, 1e6]")
                vals.append(float(x))
            object.__setattr__(self, name, tuple(vals))
        if not isinstance(self.with_T_a, bool):
            raise ConfigError(f"peltier_model.with_T_a = {self.with_T_a!r} must be true or false")
        if self.use == "off" and not self.a and not self.b:
            return
        if not self.a or not self.b:
            raise ConfigError("peltier_model: a and b must each hold at least one coefficient "
                              "(write the table with `thermoskin identify`)")
        A1 = 1.0 + sum(self.a)
        gain = sum(self.b) / A1 if A1 != 0.0 else math.inf
        if not (math.isfinite(gain) and gain > 0.0):
            raise ConfigError(f"peltier_model: the steady-state gain B(1)/A(1) = {gain:g} K per unit "
                              "drive must be > 0 (heating warms the tank)")
        import numpy as np

        poles = np.roots((1.0, *self.a))
        if not np.all(np.abs(poles) < 1.0):
            raise ConfigError("peltier_model: the model is unstable (a pole of A(q) on or outside the "
                              f"unit circle, |p| = {float(np.max(np.abs(poles))):.4g})")

    def steady_state_gain(self) -> float:
        """``B(1)/A(1)``, K per unit drive."""
        return sum(self.b) / (1.0 + sum(self.a))


@dataclass(frozen=True)
class PlausibleParams(_Validated):
    """Physical ranges of the measured columns (``thermoskin.logio.plausible``).

    A reading outside its column's range is no reading: it is treated as a NaN (held over,
    flagged ``gap``) before it reaches any filter, live and offline. ``T_w_cmd`` is checked
    against the ``T_w`` range (an implausible command holds the last one); ``drive`` outside
    its range is an unknown drive.
    """

    section = "plausible"
    T_w_min: float = _p(-50.0, "degC", -273.15, 1000.0, doc="lowest plausible pipe reading")
    T_w_max: float = _p(150.0, "degC", -273.15, 1000.0, doc="highest plausible pipe reading")
    T_p_min: float = _p(-50.0, "degC", -273.15, 1000.0, doc="lowest plausible tank reading")
    T_p_max: float = _p(150.0, "degC", -273.15, 1000.0, doc="highest plausible tank reading")
    T_a_min: float = _p(-50.0, "degC", -273.15, 1000.0, doc="lowest plausible air reading")
    T_a_max: float = _p(150.0, "degC", -273.15, 1000.0, doc="highest plausible air reading")
    v_min: float = _p(0.0, "m/s", 0.0, 100.0, doc="lowest plausible water velocity")
    v_max: float = _p(10.0, "m/s", 0.0, 100.0, doc="highest plausible water velocity")
    drive_min: float = _p(-1.0, "", -10.0, 10.0, doc="lowest plausible Peltier drive")
    drive_max: float = _p(1.0, "", -10.0, 10.0, doc="highest plausible Peltier drive")

    def __post_init__(self) -> None:
        super().__post_init__()
        for col in ("T_w", "T_p", "T_a", "v", "drive"):
            lo, hi = getattr(self, f"{col}_min"), getattr(self, f"{col}_max")
            if not lo < hi:
                raise ConfigError(f"plausible.{col}_min = {lo!r} must be below plausible.{col}_max = {hi!r}")


@dataclass(frozen=True)
class Config:
    """All parameter sets of one run."""

    skin: SkinParams = field(default_factory=SkinParams)
    sampling: SamplingParams = field(default_factory=SamplingParams)
    observer: ObserverParams = field(default_factory=ObserverParams)
    estimator: EstimatorParams = field(default_factory=EstimatorParams)
    detector: DetectorParams = field(default_factory=DetectorParams)
    sensor: SensorParams = field(default_factory=SensorParams)
    pump: PumpParams = field(default_factory=PumpParams)
    peltier: PeltierParams = field(default_factory=PeltierParams)
    control: ControlParams = field(default_factory=ControlParams)
    safety: SafetyParams = field(default_factory=SafetyParams)
    plausible: PlausibleParams = field(default_factory=PlausibleParams)
    peltier_model: PeltierModelParams = field(default_factory=PeltierModelParams)

    def __post_init__(self) -> None:
        if self.control.T_p_min >= self.control.T_p_max:
            raise ConfigError(f"control.T_p_min = {self.control.T_p_min} must be below "
                              f"control.T_p_max = {self.control.T_p_max}")
        if self.control.W1 == 0.0 and self.control.W2 == 0.0:
            raise ConfigError("control.W1 and control.W2 are both 0: the MPC's cost (eq. 9) "
                              "would have no term; give at least one a weight > 0")
        if self.safety.T_p_min >= self.safety.T_p_max:
            raise ConfigError(f"safety.T_p_min = {self.safety.T_p_min} must be below "
                              f"safety.T_p_max = {self.safety.T_p_max}")
        for ch in ("T_w", "T_p", "T_a"):
            period = getattr(self.sensor, f"period_{ch}")
            if 0.0 < period < self.sampling.t_s:
                raise ConfigError(f"sensor.period_{ch} = {period!r} is out of range: must be 0 or "
                                  f">= sampling.t_s = {self.sampling.t_s!r} (s)")

    def replace(self, **sections: dict[str, Any]) -> Config:
        """A copy with some fields of some sections replaced: ``replace(skin={"R_g": 5})``."""
        return _merge(self, sections, source="replace()")


_SECTION_TYPES = {"skin": SkinParams, "sampling": SamplingParams, "observer": ObserverParams,
                  "estimator": EstimatorParams, "detector": DetectorParams, "sensor": SensorParams,
                  "pump": PumpParams, "peltier": PeltierParams, "control": ControlParams,
                  "safety": SafetyParams, "plausible": PlausibleParams,
                  "peltier_model": PeltierModelParams}

PRESETS: dict[str, Config] = {
    "paper": Config(),
    # Table I, with the fluid properties as printed (k_c = 0.1 mW/mK, mu = 1.55 kg/ms, ...);
    # they make R_w so large that the pump barely heats the pipe (see docs/model.md).
    "paper-table-fluid": Config(skin=SkinParams(water="table1")),
}


def _merge(base: Config, data: dict[str, Any], source: str) -> Config:
    sections = {}
    for name, table in data.items():
        if name not in _SECTION_TYPES:
            raise ConfigError(f"unknown table [{name}] in {source} "
                              f"(known: {', '.join(_SECTION_TYPES)})")
        if not isinstance(table, dict):
            raise ConfigError(f"[{name}] in {source} must be a table")
        cls = _SECTION_TYPES[name]
        known = {f.name for f in dataclasses.fields(cls)}
        for key in table:
            if key not in known:
                raise ConfigError(f"unknown key '{name}.{key}' in {source} "
                                  f"(known: {', '.join(sorted(known))})")
        try:
            sections[name] = dataclasses.replace(getattr(base, name), **table)
        except ConfigError as e:
            raise ConfigError(f"{e} in {source}") from None
    try:  # the checks across sections
        return dataclasses.replace(base, **sections)
    except ConfigError as e:
        raise ConfigError(f"{e} in {source}") from None


#: Largest TOML file read (a skin of 10 000 patches takes about 1.5 MB), bytes.
MAX_TOML_BYTES = 16 << 20
#: Deepest nesting of arrays and inline tables in a TOML file (this project's files nest 3 deep;
#: Python's parser recurses, and 400 levels raised ``RecursionError``).
MAX_TOML_DEPTH = 32

_TOML_MARKS = re.compile(r"[\n#\"'\[\]{}]")


def toml_depth(text: str, limit: int = MAX_TOML_DEPTH) -> tuple[int, int]:
    """``(depth, line)``: the deepest nesting of brackets and braces in TOML ``text`` outside its
    strings and comments, up to ``limit + 1`` (then the line where it passed ``limit``); table
    headers count as one or two levels. Linear in the text (a regular expression finds the next
    mark), no recursion."""
    depth = deepest = 0
    line = 1
    i, n = 0, len(text)
    while True:
        m = _TOML_MARKS.search(text, i)
        if m is None:
            return deepest, line
        c, i = m.group(), m.end()
        if c == "\n":
            line += 1
        elif c == "#":
            j = text.find("\n", i)
            i = n if j < 0 else j
        elif c in "\"'":
            if text.startswith(c * 3, i - 1):  # a multi-line string
                end = _string_end(text, i + 2, c * 3)
                line += text.count("\n", i, end)
                i = end
            else:
                i = _string_end(text, i, c)
        elif c in "[{":
            depth += 1
            if depth > deepest:
                deepest = depth
                if deepest > limit:
                    return deepest, line
        else:
            depth = max(0, depth - 1)


def _string_end(text: str, i: int, quote: str) -> int:
    """Index after the string that starts at ``i`` (after its opening ``quote``); a basic
    string's backslash escapes the next character; a one-line string ends at its line's end."""
    n = len(text)
    basic = quote[0] == '"'
    while i < n:
        j = text.find(quote, i)
        nl = text.find("\n", i) if len(quote) == 1 else -1
        if j < 0 or (0 <= nl < j):
            return nl if nl >= 0 else n  # unterminated: the parser says so
        if basic:
            k = j - 1
            slashes = 0
            while k >= i and text[k] == "\\":
                slashes += 1
                k -= 1
            if slashes % 2:
                i = j + 1
                continue
        return j + len(quote)
    return n


def read_toml(path: str | Path, what: str, error: type[ConfigError] | None = None) -> dict[str, Any]:
    """The TOML file at ``path`` as a dict; ``error`` (default :class:`ConfigError`) with one
    line naming ``what`` (``"config file"``, ``"skin description"``, ...) and the path when
    it is a directory, missing, unreadable, not UTF-8, not valid TOML, larger than
    :data:`MAX_TOML_BYTES` or nested deeper than :data:`MAX_TOML_DEPTH`."""
    err = ConfigError if error is None else error
    p = Path(path)
    if p.is_dir():
        raise err(f"{what} {p} is a directory, not a TOML file")
    if not p.exists():
        raise err(f"{what} {p} does not exist")
    try:
        with open(p, "rb") as fh:
            raw = fh.read(MAX_TOML_BYTES + 1)
    except OSError as e:
        raise err(f"cannot read {what} {p}: {e.strerror or e}") from None
    if len(raw) > MAX_TOML_BYTES:
        raise err(f"{what} {p} is larger than {MAX_TOML_BYTES >> 20} MiB: not one of ours")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise err(f"{p} is not valid TOML: not UTF-8 text") from None
    deepest, line = toml_depth(text)
    if deepest > MAX_TOML_DEPTH:
        raise err(f"{p}: line {line}: arrays or tables nested more than {MAX_TOML_DEPTH} deep: "
                  f"not a {what}")
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise err(f"{p} is not valid TOML: {' '.join(str(e).split())}") from None
    except RecursionError:  # not reached after the depth check; kept as a net
        raise err(f"{p}: nested too deep: not a {what}") from None


#: The three kinds of TOML file the commands take, by what each is given with.
FILE_KINDS = {
    "parameters": "a parameter file (tables such as [skin], [sensor], [detector]: the model and the "
                  "boards as the lab knows them; give it with --config)",
    "layout": "a skin's layout file (links, loops, patches: where the patches lie; give it with --skin)",
    "sweep": "a sweep file ([sweep], [keys]: designs to simulate; give it to `thermoskin sweep`)",
}


def file_kind(data: dict[str, Any]) -> str | None:
    """Which of :data:`FILE_KINDS` a parsed TOML file is, by its top-level tables; None if it
    has none of their marks (an empty file, or a file of none of these kinds)."""
    if "sweep" in data or "keys" in data:
        return "sweep"
    if {"links", "loops", "patches"} & set(data):
        return "layout"
    if set(data) & set(_SECTION_TYPES):
        return "parameters"
    return None


def check_kind(path: str | Path, data: dict[str, Any], want: str,
               error: type[ConfigError] | None = None) -> None:
    """One line when the file at ``path`` is another kind than ``want`` (a layout given where a
    parameter file goes said "unknown table [name]"; the two were both called SKIN.toml)."""
    kind = file_kind(data)
    if kind is not None and kind != want:
        err = ConfigError if error is None else error
        raise err(f"{path} is {FILE_KINDS[kind]}, not {FILE_KINDS[want].split(' (')[0]} as this option takes")


def load_config(path: str | Path | None = None, preset: str = "paper") -> Config:
    """The preset, overridden by the TOML file at ``path`` if given."""
    if preset not in PRESETS:
        raise ConfigError(f"unknown preset {preset!r} (known: {', '.join(PRESETS)})")
    cfg = PRESETS[preset]
    if path is None:
        return cfg
    p = Path(path)
    data = read_toml(p, "parameter file")
    check_kind(p, data, "parameters")
    return _merge(cfg, data, source=str(p))


#: Significant digits a written config keeps: a fitted or measured value's last bits are noise
#: (a log's median step of 0.10000000000012221 s is 0.1 s), and 12 digits are 1e-12 of it.
TOML_DIGITS = 12


def toml_number(x: float) -> str:
    """A float as a config file writes it: rounded to :data:`TOML_DIGITS` significant digits,
    in the shortest form that reads back as that float (``nan``, ``inf``, ``-inf`` as TOML spells them)."""
    x = float(x)
    if not math.isfinite(x):
        return "nan" if math.isnan(x) else ("inf" if x > 0 else "-inf")
    return repr(float(f"{x:.{TOML_DIGITS}g}"))


def to_toml(cfg: Config) -> str:
    """The whole config as TOML text (``None`` values are left out)."""
    lines: list[str] = []
    for name in _SECTION_TYPES:
        section = getattr(cfg, name)
        lines.append(f"[{name}]")
        for f in dataclasses.fields(section):
            value = getattr(section, f.name)
            if value is None:
                continue
            if isinstance(value, str):
                text = f'"{value}"'
            elif isinstance(value, bool):
                text = "true" if value else "false"
            elif isinstance(value, tuple | list):
                text = "[" + ", ".join(toml_number(x) for x in value) + "]"
            elif isinstance(value, float):
                text = toml_number(value)
            else:
                text = repr(value)
            unit = f.metadata.get("unit", "")
            lines.append(f"{f.name} = {text}" + (f"  # {unit}" if unit else ""))
        lines.append("")
    return "\n".join(lines)


def save_config(cfg: Config, path: str | Path) -> None:
    """Write ``cfg`` as TOML, whole or not at all (a full disk leaves an earlier file as it was)."""
    from thermoskin.atomic import write_text

    write_text(path, to_toml(cfg))
