"""Named simulation scenarios: touches, commands, the prescribed Peltier temperature, the pump mode.

The Peltier/tank temperature is prescribed here (no MPC, no Peltier model)::

    T_p(t) = T_w_cmd + T_p_offset + T_p_drift sin(2 pi t / T_p_period)

With the pump logic around ``T_w_cmd`` (Sec. V) an offset of a few tenths of a kelvin
heats the pipe while the pump runs and the pipe cools by natural loss while it is stopped:
the chattering of Fig. 8. The touch scenarios follow Sec. VI (one, two, three fingers;
three persons), with touches 1.5-3 s long and 5-9 s of quiet between them ("gap":
from the release of one touch to the onset of the next).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from thermoskin.physics.finger import PERSONS, Touch

PUMP_MODES = ("logic", "on", "off")


@dataclass(frozen=True)
class Scenario:
    """One simulated experiment: ``duration`` s, ``T_w_cmd`` and ``T_a`` (°C), ``T_p(t)``, touches, pump."""

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
    """Command schedule ``((t_start, T_w_cmd), ...)`` for the closed loop; empty: ``T_w_cmd``."""

    def __post_init__(self) -> None:
        if self.pump not in PUMP_MODES:
            raise ValueError(f"Scenario {self.name!r}: pump = {self.pump!r} must be one of {PUMP_MODES}")
        if not (math.isfinite(self.duration) and self.duration > 0):
            raise ValueError(f"Scenario {self.name!r}: duration = {self.duration} s must be > 0")
        if not self.T_p_period > 0:
            raise ValueError(f"Scenario {self.name!r}: T_p_period = {self.T_p_period} s must be > 0")
        object.__setattr__(self, "touches", tuple(sorted(self.touches, key=lambda tc: tc.t_on)))

    def T_p(self, t: float | NDArray[np.float64]) -> float | NDArray[np.float64]:
        """Prescribed Peltier/tank temperature, °C (scalar or array ``t``)."""
        tt = np.asarray(t, dtype=float)
        out = self.T_w_cmd + self.T_p_offset + self.T_p_drift * np.sin(2.0 * np.pi * tt / self.T_p_period)
        return float(out) if out.ndim == 0 else out

    def T_w_cmd_at(self, t: float) -> float:
        """The water-temperature command at ``t`` (s), °C."""
        cmd = self.T_w_cmd
        for t0, c in self.setpoints:
            if t >= t0:
                cmd = c
        return cmd

    def shifted(self, dt: float) -> Scenario:
        """The same touches and command changes ``dt`` s later, the run ``dt`` s longer."""
        touches = tuple(dataclasses.replace(tc, t_on=tc.t_on + dt) for tc in self.touches)
        setpoints = tuple((t0 + dt, c) for t0, c in self.setpoints)
        return dataclasses.replace(self, duration=self.duration + dt, touches=touches,
                                   setpoints=setpoints)

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
    "none": Scenario("none", "no touch: noise and pump chattering only", duration=60.0),
    "setpoints": Scenario(
        "setpoints", "commands 24, 26, 28 degC, 120 s each, no touch (Fig. 8)", duration=360.0,
        setpoints=((0.0, 24.0), (120.0, 26.0), (240.0, 28.0))),
    "realistic": random_scenario(2024, 120.0, name="realistic"),
}
"""The named scenarios; ``fingers`` is the default."""

DEFAULT_SCENARIO = "fingers"


def get_scenario(name: str) -> Scenario:
    """A named scenario, with a clear error for an unknown name."""
    try:
        return SCENARIOS[name]
    except KeyError:
        raise KeyError(f"unknown scenario {name!r} (known: {', '.join(SCENARIOS)})") from None
