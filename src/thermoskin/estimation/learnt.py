"""What the estimator has learnt of its sensors, the one-finger SNR, and what to say of it once.

The kernel learns each channel's reading variance and converter step, the tank readings'
offset against the pipe's, the pipe thermocouple's lag and the evidence's dispersion from the
readings (``docs/model.md``, Sensors that calibrate themselves); :func:`learnt` reads them from a
patch's state as a :class:`Learnt`, and :func:`notices` says, each at most once, where they tell
the user something: a fingertip's touch below the noise, readings that do not fit the model, an
offset, a lag or a noise unlike the configured ones (with the key that sets it).

The one-finger SNR: a fingertip (0.05 W/K to a body at 33 °C) brings ``0.05 (33 - T_g)`` W to
the sheet; the readings bring ``I`` W⁻² a second of information on a lasting change of ``q_i``
(over the dispersion), so 0.3 s of them estimate it to ``1/sqrt(0.3 I)``:
``SNR = 0.05 (33 - T_g) sqrt(0.3 I)``. At 5 a step of that size builds a log-likelihood ratio of
``SNR²/2 = 12.5`` in 0.3 s, the detector's threshold with slow boards.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from thermoskin.estimation import kernel as K  # noqa: N812
from thermoskin.params import Config

CHANNELS = ("T_w", "T_p", "T_a")
#: A fingertip: its contact conductance (W/K) and the body's temperature behind it (°C).
FINGER_G = 0.05
FINGER_T = 33.0
#: Seconds of readings the one-finger SNR is figured over (the latency the detector aims at).
SNR_WINDOW = 0.3
#: Below this SNR a fingertip's touch is said to be below the noise.
SNR_MIN = 5.0
#: Above this dispersion (over the detector's dead band) the readings are said not to fit.
RHO_MISFIT = 2.0


@dataclass(frozen=True)
class Learnt:
    """What the estimator has learnt of its sensors (``noise`` K rms per channel, ``quantum`` K
    per channel, 0 where no step was found; ``offset_p`` K: the T_p readings' offset against the
    T_w readings', configured plus learnt, with its sd; ``lag_w`` s: the T_w thermocouple's lag,
    with its sd; ``rho``: the evidence's dispersion, 1 where the model fits; ``info_rate``
    W⁻²/s; ``snr``: the one-finger SNR, NaN before any information; ``T_g`` °C: the sheet;
    ``armed``: the detector armed; ``arm_off`` K: the T_w readings' mean less their command where
    the arming last looked, NaN without a command; ``slow_learnt``: the offset and the lag are
    learnt, False where these readings cannot teach them: rows slower than 100 a second;
    ``still``: the channels whose readings never changed, whose noise is not known: a tank held
    on one step of a coarse converter reads a noise of nought; ``rho_window`` s: the windows
    ``rho`` is over, the short or the long ones, whichever is the larger, 0 where the pump's
    phases give the largest); ``held``: the channels
    whose noise nothing could be learnt from and is as configured: a slow board's pipe readings
    where the pump never switched, a log coarser than the loop, or ``estimator.phase_tol`` 0)."""

    noise: dict[str, float]
    quantum: dict[str, float]
    offset_p: float
    offset_p_sd: float
    lag_w: float
    lag_w_sd: float
    rho: float
    info_rate: float
    snr: float
    T_g: float
    armed: bool = True
    arm_off: float = math.nan
    slow_learnt: bool = True
    still: tuple[str, ...] = ()
    rho_window: float = 0.4
    held: tuple[str, ...] = ()

    def lines(self) -> list[str]:
        """The figures, a line or two for a summary."""
        q = ", ".join((f"{ch} not known (its readings never changed)" if ch in self.still else
                       f"{ch} {self.noise[ch]:.3f} K" + (f" (step {self.quantum[ch]:.4g} K)"
                                                         if self.quantum[ch] > 0 else "")
                       + (" as configured (not learnt from these readings)"
                          if ch in self.held else ""))
                      for ch in CHANNELS)
        snr = f"{self.snr:.1f}" if math.isfinite(self.snr) else "not known yet"
        slow = (f"T_p offset against T_w {self.offset_p:+.3f} ± {self.offset_p_sd:.3f} K, "
                f"T_w lag {self.lag_w * 1e3:.1f} ± {self.lag_w_sd * 1e3:.1f} ms"
                if self.slow_learnt else
                f"T_p offset against T_w {self.offset_p:+.3f} K and T_w lag {self.lag_w * 1e3:.1f} ms "
                "as configured (not learnt)")
        return [f"learnt: noise {q}", f"learnt: {slow}, dispersion {self.rho:.2f}, one-finger SNR {snr}"]


def one_finger_snr(info_rate: float, T_g: float) -> float:
    """A fingertip's touch (:data:`FINGER_G` to :data:`FINGER_T`) over the sd of its estimate from
    :data:`SNR_WINDOW` s of readings bringing ``info_rate`` W⁻²/s; NaN without information."""
    if not (info_rate > 0.0 and math.isfinite(T_g)):
        return math.nan
    return FINGER_G * (FINGER_T - T_g) * math.sqrt(SNR_WINDOW * info_rate)


def learnt(st: NDArray[np.float64], cfg: Config) -> Learnt:
    """What a patch's kernel state ``st`` has learnt (before the filter's start: the priors)."""
    sn = cfg.sensor
    started = st[K.LINIT] != 0.0
    R = (st[K.RW], st[K.RP], st[K.RA]) if started else None
    noise = {ch: (math.sqrt(R[i]) if R is not None else math.sqrt(sn.noise(ch) ** 2
                                                                   + sn.quantum_T**2 / 12.0))
             for i, ch in enumerate(CHANNELS)}
    steps = dict(zip(CHANNELS, (float(st[K.QW]), float(st[K.QP]), float(st[K.QA])), strict=True))
    quantum = {ch: (q if 1e-6 < q < 1e299 else 0.0) for ch, q in steps.items()}
    bd = float(st[K.BD]) if started else 0.0
    pbb = float(st[K.PBB]) if started else sn.offset_sd**2
    lag = float(st[K.LAGT]) if started else sn.lag_T_w
    ptt = float(st[K.PTT]) if started else sn.lag_sd**2
    # the information rate's exponential mean, its start's bias taken off (the weight it has
    # given its samples: 1 - (1 - w)^n after n)
    rate = float(st[K.IRATE]) / float(st[K.IRN]) if st[K.IRN] > 0 else 0.0
    T_g = float(st[K.X + 1]) if started else math.nan
    return Learnt(noise=noise, quantum=quantum, offset_p=sn.offset_T_p - sn.offset_T_w + bd,
                  offset_p_sd=math.sqrt(max(pbb, 0.0)), lag_w=lag, lag_w_sd=math.sqrt(max(ptt, 0.0)),
                  rho=float(st[K.RHO]), info_rate=rate,
                  rho_window=(0.0 if st[K.RHOP] > max(st[K.RHOL], st[K.RHOS]) else
                              cfg.detector.rho_window_long if st[K.RHOL] > st[K.RHOS]
                              else cfg.detector.rho_window), snr=one_finger_snr(rate, T_g), T_g=T_g,
                  armed=bool(st[K.ARMED] != 0.0), arm_off=float(st[K.ARMLP] - st[K.CMD]),
                  slow_learnt=not started or pbb > 0.0 or ptt > 0.0,
                  still=tuple(ch for ch, q in steps.items() if started and q >= 1e299),
                  # a slow board's pipe noise is learnt from pairs at the same point of the
                  # pump's cycle (kernel._noise_phase, counted in NRW): none, it is the prior
                  held=("T_w",) if started and 0.0 < st[K.RATE] < K.FAST_READINGS and st[K.NRW] == 0 else ())


def snr_line(snr: float, where: str = "these readings") -> str:
    """The line that says a fingertip's touch is below the noise (SNR below :data:`SNR_MIN`)."""
    return (f"a fingertip's touch (0.05 W/K at 33 degC) has a one-finger SNR of {snr:.1f} with "
            f"{where}: below {SNR_MIN:g}, expect such touches found late or missed (contacts are "
            "not invented: the detector keeps its false-alarm rate)")


def notices(lt: Learnt, cfg: Config) -> dict[str, str]:
    """What the learnt figures say, keyed so that each is said once: ``snr`` (a fingertip below
    the noise), ``misfit`` (the readings do not fit the model: an unmodelled lag, a skin unlike
    its configuration, coarse converters), ``offset``, ``lag``, ``noise_<ch>`` (a sensor unlike
    its configuration, with the key that sets it), ``unarmed`` (the detector has not armed:
    nothing is reported), ``off_command`` (it armed on readings settled off their command),
    ``not_learnt`` (the offset and the lag cannot be learnt from these readings)."""
    out: dict[str, str] = {}
    sn = cfg.sensor
    d = cfg.detector
    if not lt.armed:
        off = f"{lt.arm_off:+.2f} K from" if math.isfinite(lt.arm_off) else "not yet near"
        out["unarmed"] = (f"the detector has not armed, so no contact is reported: the T_w readings' "
                          f"mean is {off} its command and has neither held within {d.arm_band:g} K "
                          f"of it for {d.t_arm:g} s nor settled (within {K.ARM_STEADY * d.arm_band:g} K "
                          f"for {K.ARM_HOLD * d.t_arm:g} s); [detector] arm_band and t_arm set these")
    elif math.isfinite(lt.arm_off) and abs(lt.arm_off) > d.arm_band:
        out["off_command"] = (f"the T_w readings settled {lt.arm_off:+.2f} K from their command (a T_w "
                              "board's offset the controller does not see, or a command the skin "
                              "cannot reach): the detector armed on their settling")
    if math.isfinite(lt.snr) and lt.snr < SNR_MIN:
        out["snr"] = snr_line(lt.snr)
    rho = lt.rho / cfg.detector.rho_deadband
    over = f"{lt.rho_window:g} s" if lt.rho_window > 0 else "each phase of the pump's cycle"
    if rho > RHO_MISFIT:
        out["misfit"] = (f"the readings do not fit the model: their evidence is {lt.rho:.1f} times as "
                         f"spread as white noise's over {over} (an unmodelled lag, a "
                         "skin unlike its configuration, coarse converters), so the detector asks "
                         "that much more of a touch; `thermoskin calibrate NO_TOUCH_LOG --config "
                         "F.toml -o FITTED.toml` fits the skin")
    cfg_off = sn.offset_T_p - sn.offset_T_w
    if not lt.slow_learnt and (sn.offset_sd > 0 or sn.lag_sd > 0):
        out["not_learnt"] = ("the T_p offset and the T_w lag are not learnt from these readings "
                             "(rows slower than 100 a second: the pump switches between rows, and "
                             "the model's misfit there would look like an offset), the configured "
                             f"ones are used (offset {cfg_off:+.3f} K, lag {sn.lag_T_w * 1e3:.0f} ms); "
                             "`thermoskin check` or `calibrate` of a 1 kHz no-touch log from the same "
                             "boards measures them")
    elif sn.offset_sd > 0 and abs(lt.offset_p - cfg_off) > max(3.0 * lt.offset_p_sd, 0.05):
        out["offset"] = (f"the T_p readings are offset by {lt.offset_p:+.3f} ± {lt.offset_p_sd:.3f} K "
                         f"from the T_w readings (learnt; configured {cfg_off:+.3f} K): "
                         f"[sensor] offset_T_p = {sn.offset_T_w + lt.offset_p:.3f} starts from it")
    if sn.lag_sd > 0 and abs(lt.lag_w - sn.lag_T_w) > max(3.0 * lt.lag_w_sd, 0.005):
        out["lag"] = (f"the T_w thermocouple lags the water by {lt.lag_w * 1e3:.0f} ± "
                      f"{lt.lag_w_sd * 1e3:.0f} ms (learnt; configured {sn.lag_T_w * 1e3:.0f} ms): "
                      f"[sensor] lag_T_w = {lt.lag_w:.3f} starts from it")
    if cfg.estimator.tau_noise > 0:
        for ch in CHANNELS:
            prior = math.sqrt(sn.noise(ch) ** 2 + sn.quantum_T**2 / 12.0)
            # (not of readings that never changed: a tank held on one 1/4 K step read as a
            # noise of 1 mK, and the note advised setting it)
            if ch not in lt.still and not 0.67 < lt.noise[ch] / prior < 1.5:
                out[f"noise_{ch}"] = (f"the {ch} readings' noise is {lt.noise[ch]:.3f} K, not the "
                                      f"configured {prior:.3f} K (learnt): [sensor] noise_{ch} = "
                                      f"{lt.noise[ch]:.3f} starts from it")
    if "T_w" in lt.held and "misfit" in out:
        # (a held pipe noise unlike the board's is one such misfit, and these readings cannot say)
        out["noise_T_w"] = (f"the T_w readings' noise is not learnt from these readings (a board "
                            f"slower than {K.FAST_READINGS:g} readings a second whose pump cycle they "
                            "do not place: a log coarser than the loop, or a pump that never "
                            f"switched); the "
                            f"configured {lt.noise['T_w']:.3f} K is used: `thermoskin check LOG` "
                            "measures it")
    return out


class Watch:
    """Says each notice once (:meth:`new`): from ``settle`` s after the detector armed, where it
    holds at ``checks`` checks ``every`` s apart (what is learnt settles over tens of seconds:
    a half-learnt sensor looks like a misfit, and says its noise is what it will not be)."""

    def __init__(self, cfg: Config, settle: float = 30.0, every: float = 10.0, checks: int = 3) -> None:
        self.cfg = cfg
        self.settle = settle
        self.every = every
        self.checks = checks
        self.said: set[str] = set()
        self.t_armed = math.nan
        self.t_first = math.nan
        self.t_check = -math.inf
        self.held: dict[str, int] = {}

    def new(self, st: NDArray[np.float64], t: float) -> list[str]:
        """The notices not said before, from state ``st`` at time ``t`` (s); that the detector
        has not armed, once, ``settle`` s after the first call."""
        if self.t_first != self.t_first:
            self.t_first = t
        if st[K.ARMED] == 0.0:
            if t - self.t_first < self.settle or "unarmed" in self.said:
                return []
            self.said.add("unarmed")
            return [notices(learnt(st, self.cfg), self.cfg)["unarmed"]]
        if self.t_armed != self.t_armed:
            self.t_armed = t
        if t - self.t_armed < self.settle or t - self.t_check < self.every:
            return []
        self.t_check = t
        now = notices(learnt(st, self.cfg), self.cfg)
        self.held = {key: self.held.get(key, 0) + 1 for key in now}
        out = [line for key, line in now.items() if self.held[key] >= self.checks and key not in self.said]
        self.said.update(key for key in now if self.held[key] >= self.checks)
        return out
