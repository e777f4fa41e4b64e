"""Inner loop: a PI controller on the Peltier drive making ``T_p`` follow ``T_p_cmd`` (Sec. V).

The MPC (eqs. 9-11) commands the Peltier / tank temperature ``T_p_cmd``; this loop turns
the error into the normalised drive of the Peltier modules (``+1`` full heating, ``-1``
full cooling). Gains are Table I's ``Kp = 0.1 /K`` and ``Ki = 0.03 /(K s)``.

Discrete PI (backward Euler on the integral, position form), with ``e(k) = T_p_cmd(k) - T_p(k)``::

    I_c      = I(k-1) + Ki t_s e(k)                  candidate integrator
    v(k)     = ff(k) + Kp e(k) + I_c                 unsaturated output
    drive(k) = clip(v(k), drive_min, drive_max)

Anti-windup by conditional integration (clamping): the candidate is rejected,
``I(k) = I(k-1)`` and ``v(k) = ff(k) + Kp e(k) + I(k-1)``, when ``v(k)`` lies above
``drive_max`` with ``e(k) > 0`` or below ``drive_min`` with ``e(k) < 0``, i.e. when
integrating would push further into saturation; otherwise ``I(k) = I_c``. As a second
guard (a large feed-forward can hold ``v`` inside the range while ``I`` drifts) the
integrator is kept within ``|I| <= drive_max - drive_min``, the whole drive range.

Feed-forward ``ff(k) = drive_ff(T_p_cmd(k), T_a(k))`` (default none): a callable, or a
gain ``k_ff`` read as ``drive_ff = k_ff (T_p_cmd - T_a)`` (the drive that holds the tank
against its loss to air grows with its excess over ambient). The integrator then carries
only the correction on top of it.

A NaN ``T_p`` or ``T_p_cmd`` (lost reading) holds the previous drive and does not
integrate; a NaN ``T_a`` holds the previous feed-forward. Plain Python floats throughout;
no arrays are allocated per step.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from thermoskin.params import ControlParams, PeltierModelParams

FeedForward = Callable[[float, float], float]


def model_feedforward(model: PeltierModelParams) -> FeedForward | float | None:
    """The feed-forward of an identified Peltier model (``[peltier_model]``, ``use = "feedforward"``).

    The drive that holds ``T_p_cmd`` in the ARX model's steady state (``A(1) T_p = B(1) u +
    d T_a + c``): without the ``T_a`` input the gain ``k_ff = A(1)/B(1)`` on ``T_p_cmd - T_a``
    (the tank at zero drive sits at the air; the model's ``c/A(1)`` is the air of the
    identification run), with it ``(A(1) T_p_cmd - d T_a - c)/B(1)``. ``None`` when unused.
    """
    if model.use != "feedforward":
        return None
    A1 = 1.0 + sum(model.a)
    B1 = sum(model.b)
    if not model.with_T_a:
        return A1 / B1
    d, c = model.d, model.c

    def ff(T_p_cmd: float, T_a: float) -> float:
        return (A1 * T_p_cmd - d * T_a - c) / B1

    return ff


class InnerLoop:
    """PI with conditional-integration anti-windup and optional feed-forward on the drive.

    After each ``step``: ``drive`` (the output), ``integral`` (``I(k)``), ``saturated``
    (``True`` when the output was clipped), ``ff`` (the feed-forward term used).
    """

    __slots__ = ("Ki", "Kp", "_ff_fn", "_ff_gain", "_ki_ts", "_span", "drive", "drive_max",
                 "drive_min", "ff", "integral", "saturated", "t_s")

    def __init__(self, control: ControlParams, t_s: float = 1.0e-3, *,
                 feedforward: FeedForward | float | None = None) -> None:
        if not (t_s > 0 and math.isfinite(t_s)):
            raise ValueError(f"InnerLoop: t_s = {t_s} s must be > 0")
        if not control.drive_min < control.drive_max:
            raise ValueError(f"InnerLoop: drive_min = {control.drive_min} must be below "
                             f"drive_max = {control.drive_max}")
        self.t_s = float(t_s)
        self.Kp = float(control.Kp)
        self.Ki = float(control.Ki)
        self._ki_ts = self.Ki * self.t_s
        self.drive_min = float(control.drive_min)
        self.drive_max = float(control.drive_max)
        self._span = self.drive_max - self.drive_min
        self._ff_fn: FeedForward | None = None
        self._ff_gain = 0.0
        if callable(feedforward):
            self._ff_fn = feedforward
        elif feedforward is not None:
            self._ff_gain = float(feedforward)
        self.integral = 0.0
        self.drive = 0.0
        self.ff = 0.0
        self.saturated = False
        self.reset()

    def reset(self, drive0: float = 0.0) -> None:
        """Start with the integrator at ``drive0`` (clipped): zero error then gives ``drive0 + ff``."""
        d = min(max(float(drive0), self.drive_min), self.drive_max)
        self.integral = d
        self.drive = d
        self.ff = 0.0
        self.saturated = False

    def step(self, T_p: float, T_p_cmd: float, T_a: float = 20.0) -> float:
        """One sample: the drive in ``[drive_min, drive_max]`` to apply until the next sample."""
        e = T_p_cmd - T_p
        if e != e:  # NaN reading: hold
            return self.drive
        if self._ff_fn is not None:
            ff = float(self._ff_fn(T_p_cmd, T_a))
        else:
            ff = self._ff_gain * (T_p_cmd - T_a) if self._ff_gain != 0.0 else 0.0
        if ff != ff:  # a NaN air reading: hold the last feed-forward
            ff = self.ff
        i_c = self.integral + self._ki_ts * e
        if i_c > self._span:
            i_c = self._span
        elif i_c < -self._span:
            i_c = -self._span
        p = ff + self.Kp * e
        v = p + i_c
        if (v > self.drive_max and e > 0.0) or (v < self.drive_min and e < 0.0):
            v = p + self.integral          # reject the integration step
        else:
            self.integral = i_c
        if v > self.drive_max:
            d, sat = self.drive_max, True
        elif v < self.drive_min:
            d, sat = self.drive_min, True
        else:
            d, sat = v, False
        self.drive = d
        self.ff = ff
        self.saturated = sat
        return d
