"""The safety supervisor: between the blocks and the device, once per sample.

The loop calls, in this order::

    code = sup.check(t, T_w, T_p, T_a, stale, stuck, status)   # before the blocks
    if code: dev.safe(); ...                                    # safe state first, then report
    ctrl.step(...)
    drive, v = sup.gate(ctrl.drive, ctrl.v)                     # after the blocks

and ``sup.link_lost(age)`` while no sample comes. A fault **latches**: ``gate`` returns
``(0, 0)`` from then on, and only :meth:`reset` (a new run: ``thermoskin run`` again)
clears it. What trips (``[safety]`` in the config; codes in :data:`FAULTS`):

- ``tc-open``: the device flags an open thermocouple (``ST_OPEN_*``) or sent a FAULT.
- ``overtemp``: a ``T_p`` reading outside ``[T_p_min, T_p_max]``.
- ``touch-temp``: the estimated surface temperature above ``T_touch_max`` (default 40 °C,
  3 K under the 43 °C of ISO 13732-1 / IEC 60601-1 Table 24 for long contact). With
  ``surface = "pipe"`` the estimate is ``T_w``: the sheet lies between the water and the
  air, so while the water is the warmer it bounds the sheet from above. With
  ``"network"`` it is the network's steady no-touch sheet temperature
  ``(R_ag T_w + R_g T_a) / (R_g + R_ag)``.
- ``nan``: a NaN reading on any channel lasting longer than ``max_nan_s`` (device time).
  Shorter gaps pass through as NaN: the observer freezes and holds (as offline), the pump
  logic, the MPC and the inner loop hold their last output.
- ``stuck``: ``stuck_readings`` equal new readings in a row (``ChannelTracker``).
- ``stale``: no new reading on a channel for ``stale_s``.
- ``link``: no sample for ``link_timeout_s`` (host clock), or any error on the link (a
  closed port, an unplugged device, an I/O error, a failed write: :meth:`link_error`).
- ``device``: the device reports its own safe state or watchdog while the host is running.

Plain floats and ints, no allocation: it runs in the 1 kHz process.
"""

from __future__ import annotations

from thermoskin.devices import protocol as proto
from thermoskin.params import Config

OK = 0
TC_OPEN = 1
OVERTEMP = 2
TOUCH_TEMP = 3
NAN = 4
STUCK = 5
STALE = 6
LINK = 7
DEVICE = 8
STOPPED = 9
"""Not a fault: the run was stopped (Ctrl-C); the device is put in its safe state too."""

FAULTS = {OK: "ok", TC_OPEN: "tc-open", OVERTEMP: "overtemp", TOUCH_TEMP: "touch-temp",
          NAN: "nan", STUCK: "stuck", STALE: "stale", LINK: "link", DEVICE: "device",
          STOPPED: "stopped"}

_OPEN = proto.ST_OPEN_W | proto.ST_OPEN_P | proto.ST_OPEN_A
_DEV_SAFE = proto.ST_SAFE | proto.ST_WATCHDOG


class Supervisor:
    """Checks every sample against the ``[safety]`` limits; latches the first fault."""

    __slots__ = ("T_p_max", "T_p_min", "T_touch_max", "_nan_since", "_w_a", "_w_w", "check_device",
                 "code", "detail", "link_timeout", "max_nan", "stale_on", "stuck_on", "t_fault",
                 "value")

    def __init__(self, cfg: Config, *, check_device: bool = True) -> None:
        s = cfg.safety
        self.T_p_min, self.T_p_max = s.T_p_min, s.T_p_max
        self.T_touch_max = s.T_touch_max
        if s.surface == "network":
            Rg, Rag = cfg.skin.R_g, cfg.skin.R_ag
            self._w_w, self._w_a = Rag / (Rg + Rag), Rg / (Rg + Rag)
        else:
            self._w_w, self._w_a = 1.0, 0.0
        self.max_nan = s.max_nan_s
        self.link_timeout = s.link_timeout_s
        self.stuck_on = s.stuck_readings > 0
        self.stale_on = True
        self.check_device = check_device
        self.reset()

    def reset(self) -> None:
        """Clear a latched fault: the explicit restart."""
        self.code = OK
        self.t_fault = float("nan")
        self.value = float("nan")
        self.detail = ""
        self._nan_since = float("nan")

    @property
    def tripped(self) -> bool:
        return self.code != OK

    def surface(self, T_w: float, T_a: float) -> float:
        """Estimated surface temperature, °C."""
        return self._w_w * T_w + self._w_a * T_a if self._w_a else T_w

    def _trip(self, code: int, t: float, value: float, detail: str) -> int:
        if self.code == OK:
            self.code, self.t_fault, self.value, self.detail = code, t, value, detail
        return self.code

    def check(self, t: float, T_w: float, T_p: float, T_a: float, stale: int = 0, stuck: int = 0,
              status: int = 0) -> int:
        """One sample at device time ``t``; the (latched) fault code, 0 if none."""
        if self.code:
            return self.code
        if status & _OPEN:
            return self._trip(TC_OPEN, t, T_w, "open thermocouple flagged by the device")
        if T_p > self.T_p_max or T_p < self.T_p_min:
            return self._trip(OVERTEMP, t, T_p, f"T_p = {T_p:.2f} degC outside "
                              f"[{self.T_p_min:g}, {self.T_p_max:g}] degC")
        if T_w != T_w or T_p != T_p or T_a != T_a:
            if self._nan_since != self._nan_since:
                self._nan_since = t
            elif t - self._nan_since > self.max_nan:
                return self._trip(NAN, t, float("nan"),
                                  f"NaN readings for more than {self.max_nan:g} s")
        else:
            self._nan_since = float("nan")
            Ts = self.surface(T_w, T_a)
            if Ts > self.T_touch_max:
                return self._trip(TOUCH_TEMP, t, Ts, f"estimated surface {Ts:.2f} degC above "
                                  f"the touch-safe limit {self.T_touch_max:g} degC")
        if stuck and self.stuck_on:
            return self._trip(STUCK, t, float(stuck), "thermocouple reading frozen "
                              f"(channels {_channels(stuck)})")
        if stale and self.stale_on:
            return self._trip(STALE, t, float(stale), "no new thermocouple reading "
                              f"(channels {_channels(stale)})")
        if status & _DEV_SAFE and self.check_device:
            return self._trip(DEVICE, t, float(status), f"device in its safe state (status 0x{status:04x})")
        return OK

    def device_fault(self, t: float, name: str, value: float) -> int:
        """A FAULT frame from the device."""
        code = TC_OPEN if name == "tc-open" else (OVERTEMP if name == "overtemp" else DEVICE)
        return self._trip(code, t, value, f"device reported {name}")

    def link_lost(self, t: float, age: float) -> int:
        """No sample for ``age`` s; trips past ``link_timeout``."""
        if self.code:
            return self.code
        if age > self.link_timeout:
            return self._trip(LINK, t, age, f"no sample from the device for {age * 1e3:.0f} ms")
        return OK

    def link_error(self, t: float, detail: str) -> int:
        """The link failed outright (closed port, unplugged device, I/O error, failed write):
        a ``link`` fault at once, as a silent line is after ``link_timeout``."""
        return self._trip(LINK, t, float("nan"), f"link lost: {detail}")

    def stop(self, t: float) -> int:
        """A requested stop (not a fault): latches the safe outputs too."""
        return self._trip(STOPPED, t, float("nan"), "stopped on request")

    def gate(self, drive: float, v: float) -> tuple[float, float]:
        """The outputs to send: the blocks' own, or ``(0, 0)`` once tripped."""
        if self.code:
            return 0.0, 0.0
        return drive, v


def _channels(mask: int) -> str:
    return ",".join(n for n, b in zip(proto.CHANNELS, proto.CHANNEL_BITS, strict=True) if mask & b)
