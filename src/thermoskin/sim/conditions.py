"""Conditions for the detection test bench: one seeded generator per condition.

``CONDITIONS[name](seed)`` returns a :class:`Condition`: the :class:`Scenario` to simulate
(touches, ambient profile, commands), the config overrides it needs (sensor settings;
the sensor seed is the condition's seed) and a log decimation factor.
:func:`simulate_condition` runs it open loop (:func:`thermoskin.sim.run.simulate`).
Times, durations and strengths are drawn from the ranges below with
``numpy.random.default_rng(seed)``; the same seed gives the same condition and log.

Default touch population (where a condition says nothing else): 1-3 fingers of one of
:data:`~thermoskin.physics.finger.PERSONS`, body ``U(32, 35)`` °C, ``U(1.5, 3)`` s long,
``U(5, 9)`` s from one release to the next onset, the first onset ``t_first + U(0, 2)`` s,
none ending later than 1 s before the end; pushed past any window a condition keeps
clear of touches (the gap then grows). The tank drifts as in ``random_scenario``.

============  =============================================================================
name          what
============  =============================================================================
ambient-step  the air steps by +-1 K within ``U(0.3, 1)`` s (a door), 3-4 times 40-70 s
              apart; air sensor lag 1 s; no touch within 5 s after a door event
ambient-ramp  the air drifts ``U(2, 3)`` K up (or down) over 10 min and back; lag 1 s
holds         touches held ``U(20, 60)`` s
taps          taps ``U(0.2, 0.5)`` s, ``U(3, 8)`` s from one release to the next onset
tap-burst     bursts of five taps 1 s apart (onset to onset), each ``U(0.2, 0.5)`` s;
              8 s from a burst's last release to the next burst
weak          one-finger-like touches of ``G = 0.02`` W/K
palm          palms, ``G = 0.3`` W/K (``n_fingers = 0``)
cold          objects at ``U(12, 18)`` °C, ``G = U(0.05, 0.3)`` W/K, ``U(1, 5)`` s long
              (``n_fingers = 0``)
noisy         thermocouple noise 0.05 K
boards-10hz   the three channels on 10 Hz boards with 3 ms of jitter
log-100hz     a 1 kHz simulation whose log is decimated to 100 Hz (:func:`decimate`)
log-50hz      the same decimated to 50 Hz, the slowest log rate ``observe`` is made for
setpoints     commands from 24 °C changing 3 times (``U(22, 28)`` °C in 0.5 K steps,
              1-4 K apart) every ``U(60, 90)`` s; no touch within 10 s after a change
quiet-hour    an hour with no touch, the pump switching, the air drifting by up to
              +-1 K per 10 min (piecewise linear); lag 1 s
============  =============================================================================

**log-100hz and the pump.** The pump holds each state at least ``pump.min_dwell``
(50 ms, five rows at 100 Hz), so the on/off wave of ``v`` is not aliased: every switch
of the 1 kHz log shows in the 100 Hz log (tested), each seen up to 9 ms late. What
decimation loses is the timing inside a row: a row carries ``v`` of its first sample for
the whole 10 ms, so in a row that holds a switch the heat the water brought is wrong by
up to 9 ms of ``q_p``. With the chattering of Fig. 8 (about 16 switches a second at the
defaults) that is about one row in seven (15 % of the rows of a 120 s log).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from thermoskin.params import Config, SkinParams, load_config
from thermoskin.physics.finger import PERSONS, Touch
from thermoskin.sim.scenarios import Scenario

Window = tuple[float, float]
TouchMaker = Callable[[np.random.Generator, float, float], Touch]

T_A0 = 20.0
"""Ambient at the start of every condition, °C."""
AIR_LAG = 1.0
"""Time constant of the air sensor where a condition lags it (a bead in still air), s."""


@dataclass(frozen=True)
class Condition:
    """What to simulate for one condition and seed: scenario, config overrides, log decimation."""

    name: str
    seed: int
    scenario: Scenario
    overrides: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    """``Config.replace`` arguments, e.g. ``{"sensor": {"lag_T_a": 1.0, "seed": 3}}``."""
    decimate: int = 1
    """Keep every ``decimate``-th row of the log (1: all)."""
    description: str = ""

    def config(self, base: Config | None = None) -> Config:
        """``base`` (default: the paper's preset) with this condition's overrides."""
        base = base if base is not None else load_config()
        return base.replace(**{k: dict(v) for k, v in self.overrides.items()})


# -- building blocks --------------------------------------------------------------------------

def finger_touch(rng: np.random.Generator, t_on: float, duration: float) -> Touch:
    """1-3 fingers of a random person, body ``U(32, 35)`` °C (the default population)."""
    names = sorted(PERSONS)
    n = int(rng.integers(1, 4))
    who = names[int(rng.integers(len(names)))]
    return Touch(t_on=t_on, duration=duration, n_fingers=n, person=who, T_body=float(rng.uniform(32.0, 35.0)))


def _clear(t: float, d: float, avoid: tuple[Window, ...]) -> float:
    """The earliest onset ``>= t`` whose touch ``[onset, onset + d]`` misses every window."""
    moved = True
    while moved:
        moved = False
        for a, b in avoid:
            if t < b and t + d > a:
                t = b
                moved = True
    return t


def touch_train(rng: np.random.Generator, t_end: float, *, t_first: float = 5.0,
                durations: tuple[float, float] = (1.5, 3.0), gaps: tuple[float, float] = (5.0, 9.0),
                avoid: tuple[Window, ...] = (), make: TouchMaker = finger_touch) -> tuple[Touch, ...]:
    """Touches one after another: onset ``t_first + U(0, 2)``, durations and release-to-onset
    gaps uniform in their ranges, kept out of the ``avoid`` windows, ending by ``t_end - 1``."""
    touches = []
    t = t_first + rng.uniform(0.0, 2.0)
    while True:
        d = float(rng.uniform(*durations))
        g = float(rng.uniform(*gaps))
        t = _clear(t, d, avoid)
        if t + d > t_end - 1.0:
            break
        touches.append(make(rng, float(t), d))
        t += d + g
    return tuple(touches)


def finger_train(seed: int, duration: float, *, train_s: float | None = None) -> Scenario:
    """Touches of 1-3 fingers every 5-9 s (:func:`touch_train`), the tank drifting: the touch
    logs of the mismatch benchmark. The touches are drawn for ``train_s`` s (default
    ``duration``) before the tank's drift, so that a log shorter than ``train_s`` is the start of
    the longer one, touch for touch."""
    rng = np.random.default_rng(seed)
    touches = touch_train(rng, duration if train_s is None else train_s)
    return _scenario("fingers", seed, duration, touches, rng, "touches of 1-3 fingers every 5-9 s")


def mis_sized_skin(skin: SkinParams, f: float) -> dict[str, float]:
    """``skin``'s network as a lab's may truly be before it calibrates (``[skin]`` changes):
    ``C_w, C_g`` by ``1 + f``, ``R_g, R_ag`` by ``1 - f`` (``f`` -0.3: 30 % lighter and less
    conductive than configured)."""
    return {"C_w": skin.C_w * (1 + f), "C_g": skin.C_g * (1 + f), "R_g": skin.R_g * (1 - f),
            "R_ag": skin.R_ag * (1 - f)}


def _drift(rng: np.random.Generator) -> dict[str, float]:
    return {"T_p_drift": float(rng.uniform(0.01, 0.04)), "T_p_period": float(rng.uniform(30.0, 90.0))}


def _scenario(name: str, seed: int, duration: float, touches: tuple[Touch, ...],
              rng: np.random.Generator, description: str, **kw: Any) -> Scenario:
    return Scenario(name=f"{name}-{seed}", description=description, duration=float(duration),
                    T_a=T_A0, touches=touches, pump="logic", **_drift(rng), **kw)


def _sensor(seed: int, **kw: float) -> dict[str, dict[str, Any]]:
    return {"sensor": {"seed": seed, **kw}}


# -- the conditions ---------------------------------------------------------------------------

def ambient_step(seed: int, duration: float = 240.0) -> Condition:
    """Doors: the air steps by +-1 K within ``U(0.3, 1)`` s, 3-4 times; air sensor lag 1 s."""
    rng = np.random.default_rng(seed)
    n_events = int(rng.integers(3, 5))
    t = rng.uniform(20.0, 40.0)
    T = T_A0
    points: list[tuple[float, float]] = []
    avoid: list[Window] = []
    for _ in range(n_events):
        rise = float(rng.uniform(0.3, 1.0))
        step = 1.0 if rng.uniform() < 0.5 else -1.0
        points += [(float(t), T), (float(t) + rise, T + step)]
        avoid.append((float(t), float(t) + rise + 5.0))
        T += step
        t += rng.uniform(40.0, 70.0)
    touches = touch_train(rng, duration, avoid=tuple(avoid))
    sc = _scenario("ambient-step", seed, duration, touches, rng,
                   "the air steps by 1 K within 1 s a few times (a door); touches in between",
                   ambient=tuple(points))
    return Condition("ambient-step", seed, sc, _sensor(seed, lag_T_a=AIR_LAG), description=sc.description)


def ambient_ramp(seed: int, duration: float = 1200.0) -> Condition:
    """Slow drift: ``U(2, 3)`` K up (or down) over 10 min and back; air sensor lag 1 s."""
    rng = np.random.default_rng(seed)
    amp = float(rng.uniform(2.0, 3.0)) * (1.0 if rng.uniform() < 0.5 else -1.0)
    t0 = float(rng.uniform(10.0, 30.0))
    points = ((t0, T_A0), (t0 + 600.0, T_A0 + amp), (t0 + 1200.0, T_A0))
    touches = touch_train(rng, duration)
    sc = _scenario("ambient-ramp", seed, duration, touches, rng,
                   "the air drifts 2-3 K over 10 min and back; touches throughout", ambient=points)
    return Condition("ambient-ramp", seed, sc, _sensor(seed, lag_T_a=AIR_LAG), description=sc.description)


def holds(seed: int, duration: float = 300.0) -> Condition:
    """Touches held ``U(20, 60)`` s."""
    rng = np.random.default_rng(seed)
    touches = touch_train(rng, duration, durations=(20.0, 60.0))
    sc = _scenario("holds", seed, duration, touches, rng, "touches held 20-60 s")
    return Condition("holds", seed, sc, _sensor(seed), description=sc.description)


def taps(seed: int, duration: float = 120.0) -> Condition:
    """Isolated taps ``U(0.2, 0.5)`` s, ``U(3, 8)`` s from one release to the next onset."""
    rng = np.random.default_rng(seed)
    touches = touch_train(rng, duration, durations=(0.2, 0.5), gaps=(3.0, 8.0))
    sc = _scenario("taps", seed, duration, touches, rng, "isolated taps of 0.2-0.5 s, 3-8 s apart")
    return Condition("taps", seed, sc, _sensor(seed), description=sc.description)


def tap_burst(seed: int, duration: float = 150.0) -> Condition:
    """Bursts of five taps 1 s apart (onset to onset), ``U(0.2, 0.5)`` s each; 8 s between bursts."""
    rng = np.random.default_rng(seed)
    touches: list[Touch] = []
    t = 5.0 + rng.uniform(0.0, 2.0)
    while True:
        durs = rng.uniform(0.2, 0.5, size=5)
        if t + 4.0 + durs[-1] > duration - 1.0:
            break
        proto_touch = finger_touch(rng, t, float(durs[0]))  # one hand per burst
        touches += [Touch(t_on=float(t + i), duration=float(durs[i]), n_fingers=proto_touch.n_fingers,
                          person=proto_touch.person, T_body=proto_touch.T_body) for i in range(5)]
        t += 4.0 + float(durs[-1]) + 8.0
    sc = _scenario("tap-burst", seed, duration, tuple(touches), rng,
                   "bursts of five taps 1 s apart (0.2-0.5 s each), 8 s between bursts")
    return Condition("tap-burst", seed, sc, _sensor(seed), description=sc.description)


def _fixed_G(G: float, n_fingers: int) -> TouchMaker:
    def make(rng: np.random.Generator, t_on: float, duration: float) -> Touch:
        who = sorted(PERSONS)[int(rng.integers(len(PERSONS)))]
        return Touch(t_on=t_on, duration=duration, n_fingers=n_fingers, person=who,
                     T_body=float(rng.uniform(32.0, 35.0)), G=G)
    return make


def weak(seed: int, duration: float = 120.0, G: float = 0.02) -> Condition:
    """One-finger-like touches of ``G = 0.02`` W/K (or the ``G`` given)."""
    rng = np.random.default_rng(seed)
    touches = touch_train(rng, duration, make=_fixed_G(G, 1))
    sc = _scenario("weak", seed, duration, touches, rng, f"weak one-finger touches, G = {G:g} W/K")
    return Condition("weak", seed, sc, _sensor(seed), description=sc.description)


def palm(seed: int, duration: float = 120.0) -> Condition:
    """Palms: ``G = 0.3`` W/K."""
    rng = np.random.default_rng(seed)
    touches = touch_train(rng, duration, make=_fixed_G(0.3, 0))
    sc = _scenario("palm", seed, duration, touches, rng, "palms, G = 0.3 W/K")
    return Condition("palm", seed, sc, _sensor(seed), description=sc.description)


def _cold_object(rng: np.random.Generator, t_on: float, duration: float) -> Touch:
    return Touch(t_on=t_on, duration=duration, n_fingers=0, T_body=float(rng.uniform(12.0, 18.0)),
                 G=float(rng.uniform(0.05, 0.3)))


def cold(seed: int, duration: float = 120.0) -> Condition:
    """Cold objects: ``U(12, 18)`` °C, ``G = U(0.05, 0.3)`` W/K, ``U(1, 5)`` s long."""
    rng = np.random.default_rng(seed)
    touches = touch_train(rng, duration, durations=(1.0, 5.0), make=_cold_object)
    sc = _scenario("cold", seed, duration, touches, rng, "cold objects at 12-18 degC, G 0.05-0.3 W/K, 1-5 s")
    return Condition("cold", seed, sc, _sensor(seed), description=sc.description)


def _default(name: str, description: str, sensor: dict[str, float] | None = None,
             factor: int = 1) -> Callable[[int], Condition]:
    def make(seed: int, duration: float = 120.0) -> Condition:
        rng = np.random.default_rng(seed)
        touches = touch_train(rng, duration)
        sc = _scenario(name, seed, duration, touches, rng, description)
        return Condition(name, seed, sc, _sensor(seed, **(sensor or {})), decimate=factor,
                         description=description)
    make.__name__ = name.replace("-", "_")
    make.__doc__ = description
    return make


noisy = _default("noisy", "thermocouple noise 0.05 K", {"noise_T": 0.05})
boards_10hz = _default("boards-10hz", "all three channels on 10 Hz boards with 3 ms of jitter",
                       {"period_T_w": 0.1, "period_T_p": 0.1, "period_T_a": 0.1, "jitter": 0.003})
log_100hz = _default("log-100hz", "a 1 kHz simulation, its log decimated to 100 Hz", factor=10)
log_50hz = _default("log-50hz", "a 1 kHz simulation, its log decimated to 50 Hz", factor=20)


def setpoints(seed: int, duration: float = 300.0) -> Condition:
    """Command changes from 24 °C (``U(22, 28)``, 1-4 K apart) every ``U(60, 90)`` s; no touch
    within 10 s after a change."""
    rng = np.random.default_rng(seed)
    cmds = [(0.0, 24.0)]
    t = 0.0
    while True:
        t += float(rng.uniform(60.0, 90.0))
        prev = cmds[-1][1]
        while True:
            c = float(np.round(rng.uniform(22.0, 28.0) * 2.0) / 2.0)
            if 1.0 <= abs(c - prev) <= 4.0:
                break
        if t > duration - 20.0 or len(cmds) > 3:
            break
        cmds.append((t, c))
    avoid = tuple((t0, t0 + 10.0) for t0, _ in cmds[1:])
    touches = touch_train(rng, duration, avoid=avoid)
    sc = _scenario("setpoints", seed, duration, touches, rng,
                   "set-point changes with touches between (none within 10 s after a change)",
                   setpoints=tuple(cmds))
    return Condition("setpoints", seed, sc, _sensor(seed), description=sc.description)


def quiet_hour(seed: int, duration: float = 3600.0) -> Condition:
    """An hour with no touch, the pump switching, the air drifting slowly; air sensor lag 1 s."""
    rng = np.random.default_rng(seed)
    knots = np.arange(0.0, duration + 600.0, 600.0)
    T = T_A0 + np.concatenate([[0.0], np.cumsum(rng.uniform(-1.0, 1.0, size=knots.size - 1))])
    sc = _scenario("quiet-hour", seed, duration, (), rng,
                   "an hour with no touch: pump switching, slow ambient drift",
                   ambient=tuple((float(a), float(b)) for a, b in zip(knots, T, strict=True)))
    return Condition("quiet-hour", seed, sc, _sensor(seed, lag_T_a=AIR_LAG), description=sc.description)


CONDITIONS: dict[str, Callable[[int], Condition]] = {
    "ambient-step": ambient_step,
    "ambient-ramp": ambient_ramp,
    "holds": holds,
    "taps": taps,
    "tap-burst": tap_burst,
    "weak": weak,
    "palm": palm,
    "cold": cold,
    "noisy": noisy,
    "boards-10hz": boards_10hz,
    "log-100hz": log_100hz,
    "log-50hz": log_50hz,
    "setpoints": setpoints,
    "quiet-hour": quiet_hour,
}
"""Every condition's generator: ``CONDITIONS[name](seed)`` (each also takes ``duration=``)."""


def get_condition(name: str, seed: int, **kw: Any) -> Condition:
    """``CONDITIONS[name](seed, **kw)`` with a clear error for an unknown name."""
    try:
        make = CONDITIONS[name]
    except KeyError:
        raise KeyError(f"unknown condition {name!r} (known: {', '.join(CONDITIONS)})") from None
    return make(seed, **kw)


def decimate(log: Mapping[str, np.ndarray], factor: int) -> dict[str, np.ndarray]:
    """Every ``factor``-th row of a log (rows 0, factor, 2 factor, ...): a slower logger."""
    if isinstance(factor, bool) or not isinstance(factor, int) or factor < 1:
        raise ValueError(f"decimate: factor = {factor!r} must be a whole number >= 1")
    return {k: np.asarray(v)[::factor].copy() for k, v in log.items()}


def simulate_condition(name: str, seed: int, *, cfg: Config | None = None,
                       duration: float | None = None) -> dict[str, np.ndarray]:
    """Simulate one condition open loop (``sim.run.simulate``) and decimate its log as it says.

    ``cfg`` is the base configuration (default: the paper's preset), ``duration`` cuts the
    run short (s; touches starting later are dropped).
    """
    from thermoskin.sim.run import simulate

    cond = get_condition(name, seed)
    sc = cond.scenario if duration is None else cond.scenario.with_duration(duration)
    log = simulate(sc, cond.config(cfg))
    return decimate(log, cond.decimate) if cond.decimate > 1 else log


__all__ = ["CONDITIONS", "Condition", "decimate", "finger_touch", "get_condition", "simulate_condition",
           "touch_train"]
