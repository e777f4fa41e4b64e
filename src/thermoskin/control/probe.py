"""Active sensing: the set-point modulated a little during a hold, to tell conductance from temperature.

A toucher's heat ``q_i = G' (T_0 - T_x)`` (:mod:`thermoskin.touch.characterise`) shows only the
product of its conductance and its temperature difference while the sheet's no-touch
temperature ``T_x`` stands still. Moving ``T_x`` separates them (the trick of the
two-temperature sensors of Bhattacharjee et al., 2020): the flow changes by ``-G' ΔT_x``.
The skin's temperature is controlled through the pipe, so during a contact the probe
adds a square wave to the command::

    T_w_cmd' = T_w_cmd + A sign(sin(2 pi (t - t_det - delay)/period))    delay <= t - t_det < max_s

from ``delay`` s after the detection (a tap is over by then) for at most ``max_s`` s, while
the contact lasts; ``period = 0`` is one step of ``+A``. The sheet follows the pipe by
``R_par/R_g`` (1/11 with Table I, where the air holds the sheet; 10/11 with a sheet
bonded to the pipe). The estimator keeps the unmodulated command (its arming and its
reset on a new set-point must not see the probe); the pump logic and the MPC get the
modulated one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class SetpointProbe:
    """The probe's square wave: amplitude ``A`` (K), ``period`` (s; 0: one step), ``delay``
    after the detection (s), at most ``max_s`` s after it."""

    A: float = 0.3
    period: float = 2.0
    delay: float = 0.3
    max_s: float = 6.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.A) and 0.0 <= self.A <= 2.0):
            raise ValueError(f"SetpointProbe: A = {self.A} K must be in [0, 2]")
        for what, v in (("period", self.period), ("delay", self.delay), ("max_s", self.max_s)):
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"SetpointProbe: {what} = {v} s must be >= 0")

    def offset(self, since: float) -> float:
        """The command's offset (K) ``since`` s after the detection of a contact still on."""
        s = since - self.delay
        if s < 0.0 or since >= self.max_s:
            return 0.0
        if self.period <= 0.0:
            return self.A
        return self.A if (s % self.period) < 0.5 * self.period else -self.A
