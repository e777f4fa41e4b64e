"""The interface every device back end shares, and the thermocouple freshness tracker.

A back end (serial hardware, the emulator behind a pseudo-terminal, a replayed
recording) gives the loop one :class:`Sample` per device sample and takes one command
(Peltier drive, pump velocity) per loop step::

    dev.open()
    while running:
        s = dev.read_sample(timeout=0.005)
        if s is None:                 # nothing within the timeout
            if dev.link_lost: dev.safe(); break
            continue
        dev.write_command(drive, v)
    dev.close()                       # safe state first

Thermocouple converters update slower than the 1 kHz loop (about 10 Hz for a
MAX31856 with filtering): most samples repeat the last reading. :class:`ChannelTracker`
marks a channel ``fresh`` only when its update counter moved, ``stale`` when it has not
moved for too long, and ``stuck`` when fresh readings keep exactly the same value
(a frozen converter: noise makes equal consecutive readings rare).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from thermoskin.devices.protocol import CHANNEL_BITS, CHANNELS


class DeviceError(RuntimeError):
    """The device could not be opened or answered wrongly (the message says which and why)."""


@dataclass(slots=True)
class Sample:
    """One device sample as the host sees it.

    ``t`` device clock, s since the session started; ``T_w, T_p, T_a`` °C (NaN = no
    valid reading); ``fresh``, ``stale``, ``stuck`` bit masks over the channels
    (``CH_W | CH_P | CH_A`` of :mod:`~thermoskin.devices.protocol`); ``v`` m/s and
    ``drive`` as applied by the device; ``status`` the device's ``ST_*`` bits; ``seq`` the
    frame number; ``t_recv`` host monotonic time of reception, s.
    """

    t: float
    T_w: float
    T_p: float
    T_a: float
    fresh: int = 0b111
    seq: int = 0
    v: float = 0.0
    drive: float = 0.0
    status: int = 0
    stale: int = 0
    stuck: int = 0
    t_recv: float = 0.0

    def is_fresh(self, channel: str) -> bool:
        """Whether ``channel`` (``"T_w"``, ``"T_p"``, ``"T_a"``) carries a new reading."""
        return bool(self.fresh & CHANNEL_BITS[CHANNELS.index(channel)])

    def as_dict(self) -> dict[str, float | int]:
        """The fields as a flat dict in the shared schema (for recording)."""
        return {"t": self.t, "T_w": self.T_w, "T_p": self.T_p, "T_a": self.T_a, "v": self.v,
                "drive": self.drive, "fresh": self.fresh, "stale": self.stale, "stuck": self.stuck,
                "status": self.status, "seq": self.seq}


@runtime_checkable
class Device(Protocol):
    """A skin device: samples up, Peltier drive and pump commands down."""

    def open(self) -> None:
        """Connect and handshake; raises :class:`DeviceError` on failure."""

    def read_sample(self, timeout: float) -> Sample | None:
        """The next sample, waiting at most ``timeout`` s; ``None`` if none came."""

    def write_command(self, drive: float, v: float) -> None:
        """Peltier drive in [-1, 1] (positive heats the tank), pump velocity ``v`` m/s (0 = off)."""

    def safe(self) -> None:
        """Safe state: Peltier drive 0, pump off."""

    def close(self) -> None:
        """Safe state, then disconnect."""

    @property
    def link_lost(self) -> bool:
        """No sample for longer than the back end's link timeout."""


class ChannelTracker:
    """Fresh / stale / stuck flags of the thermocouple channels from their update counters.

    ``fresh``: the counter moved since the previous sample (or, without counters, the
    device's fresh bit). ``stale``: no update for ``stale_after`` s of device time.
    ``stuck``: ``stuck_after`` consecutive fresh readings with exactly the same value.
    """

    def __init__(self, stale_after: float = 0.5, stuck_after: int = 10) -> None:
        self.stale_after = float(stale_after)
        self.stuck_after = int(stuck_after)
        self.reset()

    def reset(self) -> None:
        self._counter: list[int | None] = [None, None, None]
        self._t_fresh = [math.nan, math.nan, math.nan]
        self._value = [math.nan, math.nan, math.nan]
        self._same = [0, 0, 0]

    def update(self, t: float, values: tuple[float, float, float],
               counters: tuple[int, int, int] | None, fresh_bits: int) -> tuple[int, int, int]:
        """``(fresh, stale, stuck)`` masks for one sample at device time ``t``."""
        fresh = stale = stuck = 0
        for i in range(3):
            bit = CHANNEL_BITS[i]
            if counters is not None:
                prev = self._counter[i]
                is_new = prev is None or counters[i] != prev
                self._counter[i] = counters[i]
            else:
                is_new = bool(fresh_bits & bit)
            x = values[i]
            if is_new:
                fresh |= bit
                if x == self._value[i]:
                    self._same[i] += 1
                else:
                    self._same[i] = 0
                self._value[i] = x
                self._t_fresh[i] = t
            elif not t - self._t_fresh[i] <= self.stale_after:  # also true before the first reading
                stale |= bit
            if self._same[i] >= self.stuck_after - 1 and self.stuck_after > 0:
                stuck |= bit
        return fresh, stale, stuck
