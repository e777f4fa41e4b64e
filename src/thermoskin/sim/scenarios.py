"""Named simulation scenarios: touches, commands, ambient, the prescribed Peltier temperature, the pump.

The Peltier/tank temperature is prescribed here for the open loop (no MPC, no Peltier
model)::

    T_p(t) = c(t) + T_p_drift sin(2 pi t / T_p_period)

where ``c(t)`` follows ``T_w_cmd(t) + T_p_offset`` at no more than ``T_p_rate`` K/s (a
tank cannot step): with one command ``c = T_w_cmd + T_p_offset``; with a set-point
schedule, from the start of each command segment ``[s_i, s_i+1)`` with target ``c_i``::

    c(t) = c_i + sign(c(s_i) - c_i) max(|c(s_i) - c_i| - T_p_rate (t - s_i), 0)

With the pump logic around ``T_w_cmd`` (Sec. V) an offset of a few tenths of a kelvin
heats the pipe while the pump runs and the pipe cools by natural loss while it is stopped:
the chattering of Fig. 8.

The ambient air is ``T_a`` (constant) or, with ``ambient = ((t_0, T_a0), (t_1, T_a1), ...)``,
piecewise linear through those points and constant before the first and after the last;
``T_a`` is then the profile's value at ``t = 0``. The true ambient drives the physics (the
skin's and the tank's losses to the air); the air sensor sees it through its lag.

The touch scenarios follow Sec. VI (one, two, three fingers; three persons), with touches
1.5-3 s long and 5-9 s of quiet between them ("gap": from the release of one touch to the
onset of the next).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from thermoskin.physics import world as W  # noqa: N812
from thermoskin.physics.finger import PERSONS, Touch

PUMP_MODES = ("logic", "on", "off")


@dataclass(frozen=True)
class Scenario:
    """One simulated experiment: ``duration`` s, command(s), ambient, ``T_p(t)``, touches, pump."""

    name: str
    description: str
    duration: float
    T_w_cmd: float = 24.0
    T_a: float = 20.0
    touches: tuple[Touch, ...] = ()
    pump: str = "logic"
    T_p_offset: float = 0.3
    T_p_drift: float = 0.0
    T_p_period: float = 60.0
    setpoints: tuple[tuple[float, float], ...] = ()
    """Command schedule ``((t_start, T_w_cmd), ...)``; empty: ``T_w_cmd`` throughout."""
    ambient: tuple[tuple[float, float], ...] = ()
    """Ambient profile ``((t, T_a), ...)``, piecewise linear (s, °C); empty: ``T_a`` throughout."""
    T_p_rate: float = 0.3
    """Fastest change of the prescribed ``T_p`` after a command change, K/s."""

    def __post_init__(self) -> None:
        if self.pump not in PUMP_MODES:
            raise ValueError(f"Scenario {self.name!r}: pump = {self.pump!r} must be one of {PUMP_MODES}")
        if not (math.isfinite(self.duration) and self.duration > 0):
            raise ValueError(f"Scenario {self.name!r}: duration = {self.duration} s must be > 0")
        if not self.T_p_period > 0:
            raise ValueError(f"Scenario {self.name!r}: T_p_period = {self.T_p_period} s must be > 0")
        if not (math.isfinite(self.T_p_rate) and self.T_p_rate > 0):
            raise ValueError(f"Scenario {self.name!r}: T_p_rate = {self.T_p_rate} K/s must be > 0")
        for what, pts in (("setpoints", self.setpoints), ("ambient", self.ambient)):
            pts = tuple((float(a), float(b)) for a, b in pts)
            if not all(math.isfinite(a) and math.isfinite(b) for a, b in pts):
                raise ValueError(f"Scenario {self.name!r}: {what} must hold finite (s, °C) pairs")
            times = [a for a, _ in pts]
            if any(b <= a for a, b in itertools.pairwise(times)):
                raise ValueError(f"Scenario {self.name!r}: the times of {what} must increase")
            object.__setattr__(self, what, pts)
        if self.ambient:
            object.__setattr__(self, "T_a", float(self.T_a_at(0.0)))
        object.__setattr__(self, "touches", tuple(sorted(self.touches, key=lambda tc: tc.t_on)))

    def T_a_at(self, t: float | NDArray[np.float64]) -> float | NDArray[np.float64]:
        """The true ambient at ``t`` (s), °C (scalar or array ``t``)."""
        tt = np.asarray(t, dtype=float)
        if not self.ambient:
            out = np.full(tt.shape, float(self.T_a))
        else:
            xp, fp = zip(*self.ambient, strict=True)
            out = np.interp(tt, xp, fp)
        return float(out) if out.ndim == 0 else out

    def T_p(self, t: float | NDArray[np.float64]) -> float | NDArray[np.float64]:
        """Prescribed Peltier/tank temperature, °C (scalar or array ``t``); see the module doc."""
        tt = np.asarray(t, dtype=float)
        drift = self.T_p_drift * np.sin(2.0 * np.pi * tt / self.T_p_period)
        base = self._T_p_limited(tt) if self.setpoints else self.T_w_cmd + self.T_p_offset
        out = base + drift
        return float(out) if out.ndim == 0 else out

    def _T_p_limited(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """``c(t)``: the command plus offset, followed at ``T_p_rate`` K/s from ``c(0)``."""
        starts = sorted({0.0, *(t0 for t0, _ in self.setpoints if t0 > 0.0)})
        out = np.empty(t.shape)
        c_start = self.T_w_cmd_at(0.0) + self.T_p_offset
        rate = self.T_p_rate
        for i, s0 in enumerate(starts):
            s1 = starts[i + 1] if i + 1 < len(starts) else math.inf
            target = self.T_w_cmd_at(s0) + self.T_p_offset
            gap = c_start - target  # 0 in the first segment
            m = t < s1 if i == 0 else (t >= s0) & (t < s1)
            out[m] = target + np.sign(gap) * np.maximum(abs(gap) - rate * (t[m] - s0), 0.0)
            if math.isfinite(s1):
                c_start = target + float(np.sign(gap)) * max(abs(gap) - rate * (s1 - s0), 0.0)
        return out

    def T_w_cmd_at(self, t: float) -> float:
        """The water-temperature command at ``t`` (s), °C."""
        cmd = self.T_w_cmd
        for t0, c in self.setpoints:
            if t >= t0:
                cmd = c
        return cmd

    def T_w_cmd_profile(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """:meth:`T_w_cmd_at` over an array of times, °C."""
        t = np.asarray(t, dtype=float)
        out = np.full(t.shape, float(self.T_w_cmd))
        for t0, c in self.setpoints:
            out[t >= t0] = c
        return out

    def shifted(self, dt: float) -> Scenario:
        """The same touches, command and ambient changes ``dt`` s later, the run ``dt`` s longer."""
        touches = tuple(dataclasses.replace(tc, t_on=tc.t_on + dt) for tc in self.touches)
        setpoints = tuple((t0 + dt, c) for t0, c in self.setpoints)
        ambient = tuple((t0 + dt, T) for t0, T in self.ambient)
        return dataclasses.replace(self, duration=self.duration + dt, touches=touches,
                                   setpoints=setpoints, ambient=ambient)

    def with_setpoint(self, T_w_cmd: float) -> Scenario:
        """The same scenario held at one command."""
        return dataclasses.replace(self, T_w_cmd=float(T_w_cmd), setpoints=())

    def with_duration(self, duration: float) -> Scenario:
        """The same scenario over ``duration`` s (touches starting later are dropped)."""
        touches = tuple(tc for tc in self.touches if tc.t_on < duration)
        return dataclasses.replace(self, duration=float(duration), touches=touches)


def _sequence(t_first: float, durations: list[float], gaps: list[float], fingers: list[int],
              persons: list[str]) -> tuple[Touch, ...]:
    """Touches one after another: ``gaps[i]`` s from the release of touch ``i`` to the next onset."""
    touches = []
    t = t_first
    for i, (dur, n, who) in enumerate(zip(durations, fingers, persons, strict=True)):
        touches.append(Touch(t_on=t, duration=dur, n_fingers=n, person=who))
        if i < len(gaps):
            t += dur + gaps[i]
    return tuple(touches)


def random_scenario(seed: int, duration: float = 120.0, *, name: str | None = None,
                    t_first: float = 5.0, T_w_cmd: float = 24.0, T_a: float = 20.0) -> Scenario:
    """A randomised but seeded touch sequence.

    Each touch: ``n_fingers`` uniform in 1..3, a random person of :data:`PERSONS` (their
    ``G_finger``), a body temperature ``U(32, 35)`` °C, a duration ``U(1.5, 3)`` s; the
    gap from one release to the next onset ``U(5, 9)`` s; the first onset in
    ``t_first + U(0, 2)`` s; no touch ends later than 1 s before the end. ``T_p`` drifts
    by ``U(0.01, 0.04)`` K with a period ``U(30, 90)`` s.
    """
    rng = np.random.default_rng(seed)
    names = sorted(PERSONS)
    touches = []
    t = t_first + rng.uniform(0.0, 2.0)
    while True:
        n = int(rng.integers(1, 4))
        who = names[int(rng.integers(len(names)))]
        T_body = float(rng.uniform(32.0, 35.0))
        dur = float(rng.uniform(1.5, 3.0))
        gap = float(rng.uniform(5.0, 9.0))
        if t + dur > duration - 1.0:
            break
        touches.append(Touch(t_on=t, duration=dur, n_fingers=n, person=who, T_body=T_body))
        t += dur + gap
    return Scenario(
        name=name or f"random-{seed}",
        description=f"randomised touches (seed {seed}): 1-3 fingers, random person, body 32-35 °C, "
                    "durations U(1.5, 3) s, gaps U(5, 9) s, slow T_p drift",
        duration=float(duration), T_w_cmd=T_w_cmd, T_a=T_a, touches=tuple(touches), pump="logic",
        T_p_drift=float(rng.uniform(0.01, 0.04)), T_p_period=float(rng.uniform(30.0, 90.0)))


def step_schedule(duration: float, every: float = 5.0, lo: float = 22.0, hi: float = 26.0,
                  seed: int = 0) -> tuple[tuple[float, float], ...]:
    """Commands ``U(lo, hi)`` °C rounded to 0.5 K, a new one every ``every`` s (seeded).

    Stepping the command up runs the pump for seconds; stepping it down stops it for
    seconds: the long pump-on and pump-off stretches that identify ``R_w`` (``calibrate``).
    """
    rng = np.random.default_rng(seed)
    times = np.arange(0.0, duration, every)
    return tuple((float(t), float(np.round(rng.uniform(lo, hi) * 2.0) / 2.0)) for t in times)


def toucher_scenario(seed: int, duration: float = 180.0, *, name: str | None = None,
                     t_first: float = 5.0, T_w_cmd: float = 24.0, T_a: float = 20.0,
                     p_human: float = W.P_HUMAN, p_tap: float = W.P_TAP) -> Scenario:
    """Persons and objects touching the skin, seeded (touchers of :mod:`thermoskin.physics.contact`,
    drawn from :mod:`thermoskin.physics.world`).

    Each touch: a person with probability ``p_human`` (a part of ``world.HUMAN_PARTS``, its
    area and pressure uniform in the part's ranges, skin at ``U(*world.T_SKIN_RANGE)`` °C),
    else one of ``world.OBJECT_TEMPS`` at its temperature (``room``: relative to ``T_a``),
    its preset area times ``U(*world.OBJECT_AREA_SCALE)``, pressed at
    ``U(*world.OBJECT_PRESSURE)`` Pa. A tap (probability ``p_tap``) lasts
    ``U(*world.TAP_S)`` s, a hold ``U(*world.HOLD_S)`` s; ``U(6, 10)`` s from one release to
    the next onset; the first onset in ``t_first + U(0, 2)`` s; no touch ends later than
    1 s before the end.
    """
    HUMAN_PARTS, OBJECT_TEMPS = W.HUMAN_PARTS, W.OBJECT_TEMPS
    rng = np.random.default_rng(seed)
    parts = list(HUMAN_PARTS)
    shares = np.array([HUMAN_PARTS[p][0] for p in parts])
    objects = list(OBJECT_TEMPS)
    touches = []
    t = t_first + rng.uniform(0.0, 2.0)
    while True:
        if rng.uniform() < p_human:
            part = parts[int(rng.choice(len(parts), p=shares / shares.sum()))]
            _, (a0, a1), (p0, p1) = HUMAN_PARTS[part]
            tc = dict(toucher=part, n_fingers=1 if part == "finger" else 0,
                      T_body=float(rng.uniform(*W.T_SKIN_RANGE)), area=float(rng.uniform(a0, a1)),
                      pressure=float(rng.uniform(p0, p1)))
        else:
            from thermoskin.physics.contact import OBJECTS

            kind = objects[int(rng.integers(len(objects)))]
            opts = OBJECT_TEMPS[kind]
            w = np.array([o[0] for o in opts])
            _, how, lo, hi = opts[int(rng.choice(len(opts), p=w / w.sum()))]
            T0 = float(rng.uniform(lo, hi)) + (T_a if how == "room" else 0.0)
            tc = dict(toucher=kind, n_fingers=0, T_body=T0,
                      area=float(OBJECTS[kind].area * rng.uniform(*W.OBJECT_AREA_SCALE)),
                      pressure=float(rng.uniform(*W.OBJECT_PRESSURE)))
        dur = float(rng.uniform(*W.TAP_S) if rng.uniform() < p_tap else rng.uniform(*W.HOLD_S))
        gap = float(rng.uniform(6.0, 10.0))
        if t + dur > duration - 1.0:
            break
        touches.append(Touch(t_on=t, duration=dur, **tc))  # type: ignore[arg-type]
        t += dur + gap
    return Scenario(
        name=name or f"touchers-{seed}",
        description=f"persons (30-36 °C skin) and objects (cold drinks, hot mugs, tools at room "
                    f"temperature) touching, seed {seed}: taps 0.2-0.6 s, holds 1.5-6 s, 6-10 s apart",
        duration=float(duration), T_w_cmd=T_w_cmd, T_a=T_a, touches=tuple(touches), pump="logic")


_FINGERS_DUR = [2.0, 2.5, 1.8, 2.2, 2.8, 1.6, 2.4, 3.0, 2.0]
_FINGERS_GAP = [7.0, 6.0, 8.0, 5.5, 7.5, 6.5, 8.5, 6.0]

SCENARIOS: dict[str, Scenario] = {
    "fingers": Scenario(
        "fingers", "three touches each of one, two and three fingers (man1), Figs. 9-17",
        duration=90.0,
        touches=_sequence(5.0, _FINGERS_DUR, _FINGERS_GAP, [1, 1, 1, 2, 2, 2, 3, 3, 3], ["man1"] * 9)),
    "one-finger": Scenario(
        "one-finger", "six one-finger touches (man1)", duration=60.0,
        touches=_sequence(5.0, [2.0, 2.5, 1.8, 2.2, 2.8, 1.6], [6.0, 7.0, 5.5, 8.0, 6.5], [1] * 6,
                          ["man1"] * 6)),
    "persons": Scenario(
        "persons", "three persons, three one-finger touches each, Fig. 18", duration=90.0,
        touches=_sequence(5.0, [2.0, 2.4, 1.8] * 3, [6.0, 7.0, 6.5, 8.0, 5.5, 7.5, 6.0, 7.0],
                          [1] * 9, ["man1"] * 3 + ["woman1"] * 3 + ["woman2"] * 3)),
    "long-touch": Scenario(
        "long-touch", "one finger held for 30 s (a detector must not swallow it)", duration=60.0,
        touches=(Touch(t_on=10.0, duration=30.0, n_fingers=1, person="man1"),)),
    "pump-on": Scenario(
        "pump-on", "pump always running (no chattering); one, two and three fingers", duration=60.0,
        touches=_sequence(5.0, [2.0, 2.5, 2.2, 1.8, 2.8, 2.4], [6.0, 7.0, 5.5, 8.0, 6.5],
                          [1, 1, 2, 2, 3, 3], ["man1"] * 6),
        pump="on"),
    "mixed": Scenario(
        "mixed", "two, three, one and two fingers (man1), 6 s apart: a short mixed test", duration=30.0,
        touches=_sequence(5.0, [2.0, 1.8, 2.5, 2.2], [4.0, 4.2, 3.5], [2, 3, 1, 2], ["man1"] * 4)),
    "none": Scenario("none", "no touch: noise and pump chattering only", duration=60.0),
    "setpoints": Scenario(
        "setpoints", "commands 24, 26, 28 degC, 120 s each, no touch (Fig. 8)", duration=360.0,
        setpoints=((0.0, 24.0), (120.0, 26.0), (240.0, 28.0))),
    "realistic": random_scenario(2024, 120.0, name="realistic"),
    "touchers": toucher_scenario(13, 180.0, name="touchers"),
    "calibration": Scenario(
        "calibration", "no touch; commands stepping every 5 s within 22-26 degC: long pump-on and "
        "pump-off stretches, for `thermoskin calibrate`", duration=120.0,
        setpoints=step_schedule(120.0, seed=15)),
}
"""The named scenarios; ``fingers`` is the default."""

DEFAULT_SCENARIO = "fingers"


def get_scenario(name: str) -> Scenario:
    """A named scenario, with a clear error for an unknown name."""
    try:
        return SCENARIOS[name]
    except KeyError:
        raise KeyError(f"unknown scenario {name!r} (known: {', '.join(SCENARIOS)})") from None
