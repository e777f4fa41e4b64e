"""Pump logic (Sec. V): run the water while the pipe is below its command, stop it above.

The paper (Sec. V): "In the case where the temperature response is larger than its
temperature command, the velocity of water flow turns to 0 m/s for stopping heat
transfer from the Peltier pump"; the water then cools by natural loss. Sec. VI: the
pump keeps ``v = 0.141 m/s`` except while ``T_w`` is above its command. This on/off rule
is the chattering of Fig. 8.

With a hysteresis band ``h = params.hysteresis`` (K)::

    running and T_w > T_w_cmd + h/2  ->  stop      (v = 0)
    stopped and T_w < T_w_cmd - h/2  ->  run       (v = v_on)

``h = 0`` is the paper's plain rule (equality keeps the current state). A real DC pump
does not switch faster than tens of milliseconds: a state is held at least
``min_dwell`` seconds (``ceil(min_dwell / t_s)`` samples) before the next switch.
A NaN ``T_w`` (a lost thermocouple reading) keeps the current state.
"""

from __future__ import annotations

import math

from thermoskin.params import PumpParams


class PumpLogic:
    """On/off pump command ``v`` from ``T_w`` and ``T_w_cmd`` (Sec. V), with hysteresis and dwell."""

    __slots__ = ("_half", "_held", "_n_dwell", "_n_still", "_still", "_v_on", "min_dwell", "on", "params",
                 "t_s")

    def __init__(self, params: PumpParams, t_s: float = 1.0e-3, *,
                 min_dwell: float | None = None) -> None:
        """``min_dwell`` (s) defaults to ``params.min_dwell``."""
        if min_dwell is None:
            min_dwell = params.min_dwell
        if not (t_s > 0 and math.isfinite(t_s)):
            raise ValueError(f"PumpLogic: t_s = {t_s} s must be > 0")
        if not (min_dwell >= 0 and math.isfinite(min_dwell)):
            raise ValueError(f"PumpLogic: min_dwell = {min_dwell} s must be >= 0")
        self.params = params
        self.t_s = float(t_s)
        self.min_dwell = float(min_dwell)
        self._v_on = float(params.v_on)
        self._half = 0.5 * float(params.hysteresis)
        # samples a state must be held; the 1e-9 guards min_dwell/t_s landing just above an integer
        self._n_dwell = max(0, math.ceil(self.min_dwell / self.t_s - 1e-9))
        self._n_still = int(params.still_readings)
        self._still = self._n_still
        self.on = True
        self._held = self._n_dwell
        self.reset()

    def reset(self, on: bool = True) -> None:
        """Start running (or stopped), as if held for long: the first switch may come at once."""
        self.on = bool(on)
        self._held = self._n_dwell
        self._still = self._n_still

    @property
    def v(self) -> float:
        """The current velocity command, m/s."""
        return self._v_on if self.on else 0.0

    def step(self, T_w: float, T_w_cmd: float, fresh: bool = True) -> float:
        """One sample: the velocity ``v`` (m/s) to apply from now to the next sample.

        ``fresh``: this ``T_w`` is a new reading (not a held one)."""
        if fresh and not self.on:
            self._still += 1
        if self._held >= self._n_dwell:
            if self.on:
                if T_w > T_w_cmd + self._half:
                    self.on = False
                    self._held = 0
                    self._still = 0
            elif T_w < T_w_cmd - self._half and self._still >= self._n_still:
                self.on = True
                self._held = 0
        if self._held < self._n_dwell:
            self._held += 1
        return self._v_on if self.on else 0.0
