"""Touch estimation as one block: the observer (eq. 8) feeding the contact detector.

In a loop that holds the skin at a command, the detector is armed only once ``T_w`` has
stayed within ``detector.arm_band`` of ``T_w_cmd`` for ``detector.t_arm`` seconds: while
the skin warms from ambient the observer's start-up transient would otherwise become the
detector's no-touch baseline. Without a command (``T_w_cmd`` NaN, offline logs) it is
armed from the first sample. The live loop, the streaming path and replay all step this
block, so they agree sample for sample.
"""

from __future__ import annotations

import math

from thermoskin.detector import ContactDetector
from thermoskin.observer import ThermalExchangeObserver
from thermoskin.params import Config


class TouchEstimator:
    """Observer and detector, stepped together; ``contact`` and the observer's outputs."""

    __slots__ = ("_band", "_n_arm", "_n_in", "armed", "contact", "detector", "observer")

    def __init__(self, cfg: Config) -> None:
        t_s = cfg.sampling.t_s
        self.observer = ThermalExchangeObserver(cfg.skin, cfg.observer, t_s)
        self.detector = ContactDetector(cfg.detector, t_s)
        self._band = cfg.detector.arm_band
        self._n_arm = max(1, round(cfg.detector.t_arm / t_s))
        self.reset()

    def reset(self) -> None:
        """Both blocks afresh; disarmed until the set-point is held (if there is one)."""
        self.observer.reset()
        self.detector.reset()
        self.armed = False
        self._n_in = 0
        self.contact = 0

    def step(self, t: float, T_w: float, T_p: float, v: float, T_a: float,
             T_w_cmd: float = math.nan) -> int:
        """One sample (``v`` the pump command applied from ``t`` on); returns ``contact``."""
        obs = self.observer
        obs.step(T_w, T_p, v, T_a)
        if not self.armed:
            if T_w_cmd != T_w_cmd:  # no command: nothing to wait for
                self.armed = True
            elif abs(T_w - T_w_cmd) <= self._band:
                self._n_in += 1
                self.armed = self._n_in >= self._n_arm
            else:
                self._n_in = 0
        self.contact = self.detector.step(t, obs.r, obs.dq_i_hat,
                                          obs.gap or not obs.ready or not self.armed)
        return self.contact
