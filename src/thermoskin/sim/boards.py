"""Thermocouple boards as a lab buys them: the simulated skin's default sensors.

A configuration's ``[sensor]`` section says what the lab believes its boards are; the boards
themselves differ from that, and from each other. :func:`lab_boards` draws a set of boards as
they come out of the box, one set per seed (:data:`LAB`, with the sources of each range):

- **offset** (reading minus truth) ``U(-0.3, 0.3)`` K per channel: a type K thermocouple's
  cold-junction compensation on its board is accurate to about ±0.3 K over a small range of
  board temperature (MAX31856 data sheet: cold-junction accuracy ±0.7 °C over -20 to 85 °C,
  typically much less near room temperature), and special-limits type K wire adds ±1.1 K
  absolute (IEC 60584-1 class 1: ±1.5 K) that a lab trims by a one-point check to a few
  tenths; two boards of one batch then disagree by tenths of a kelvin;
- **noise** ``U(0.02, 0.05)`` K rms per channel: the MAX31856's effective resolution at its
  slowest filter is about 0.02 K, and a thermocouple lead picking up a pump's motor and a
  Peltier's PWM in a lab adds as much again (a shielded, twisted lead: the lower end);
- **quantum** 1/128 K (0.0078125 K): the MAX31856's 19-bit thermocouple register (the
  MAX31855's is 0.25 K: ``quantum_T = 0.25`` in the mismatch benchmark);
- **lag** (time constant of the bead): the pipe's and the tank's beads in water
  ``U(0.005, 0.03)`` s (a 0.25 mm exposed junction in moving water: tens of ms, Omega's
  response-time table for bare wire), the air's ``U(0.5, 1.5)`` s (the same bead in still air);
- **period** and **jitter**: as configured (the emulator's boards convert every 0.1 s, a
  MAX31856 at its 50/60 Hz filter and one-sample averaging).

:func:`simulated_boards` picks them or the configuration itself (``--ideal-sensors``: every
reading exactly as the estimator assumes, what the simulator did before boards were drawn).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from thermoskin.params import SensorParams

#: The ranges boards are drawn from (module doc): per channel offset (K), noise (K), lag (s).
LAB = {
    "offset": (-0.3, 0.3),
    "noise": (0.02, 0.05),
    "quantum": 1.0 / 128.0,
    "lag_T_w": (0.005, 0.03),
    "lag_T_p": (0.005, 0.03),
    "lag_T_a": (0.5, 1.5),
}

CHANNELS = ("T_w", "T_p", "T_a")
_STREAM = 0x1AB
"""The boards' draw is its own stream of the seed (``SeedSequence(seed, spawn_key=(_STREAM,))``):
the readings' noise and jitter streams (``sim.sensors``) are unchanged by it."""


def lab_boards(sensor: SensorParams, seed: int | None = None) -> SensorParams:
    """Boards as a lab buys them (module doc), drawn from ``seed`` (default ``sensor.seed``):
    ``sensor`` with each channel's offset, noise and lag drawn and the quantum 1/128 K; its
    periods, jitter and seed kept. The same seed gives the same boards."""
    s = int(sensor.seed if seed is None else seed)
    rng = np.random.default_rng(np.random.SeedSequence(s, spawn_key=(_STREAM,)))
    kw: dict[str, float] = {}
    for ch in CHANNELS:
        kw[f"offset_{ch}"] = float(rng.uniform(*LAB["offset"]))
        kw[f"noise_{ch}"] = float(rng.uniform(*LAB["noise"]))
        kw[f"lag_{ch}"] = float(rng.uniform(*LAB[f"lag_{ch}"]))
    return dataclasses.replace(sensor, quantum_T=float(LAB["quantum"]), seed=s, **kw)


def simulated_boards(sensor: SensorParams, ideal: bool) -> SensorParams:
    """The boards a simulated skin reads through: exactly as configured (``ideal``,
    ``--ideal-sensors``) or a lab's, drawn from ``sensor.seed`` (:func:`lab_boards`)."""
    return sensor if ideal else lab_boards(sensor)


def said(boards: SensorParams, ideal: bool) -> str:
    """Which boards, in a device's banner: ``boards as configured`` or a lab's, described."""
    return "boards as configured" if ideal else f"boards as a lab buys them: {describe(boards)}"


def describe(boards: SensorParams) -> str:
    """One line: each channel's offset, noise and lag, and the quantum."""
    parts = [f"{ch} offset {getattr(boards, f'offset_{ch}'):+.3f} K, noise {boards.noise(ch):.3f} K, "
             f"lag {getattr(boards, f'lag_{ch}'):.3g} s" for ch in CHANNELS]
    return "; ".join(parts) + f"; quantum {boards.quantum_T:g} K"
