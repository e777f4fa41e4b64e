"""The units of a log's time and temperatures: seconds and degrees Celsius, said otherwise or refused.

Logs of this project hold ``t`` in seconds and every ``T_*`` column in °C. Exports of other
loggers often hold ``t`` in milliseconds (or microseconds) and temperatures in kelvin. Read as
seconds, a 1 kHz log in milliseconds is a 1 Hz log: the estimator warned, then reported 155
contacts on a log with no touch and exited 0. Read as °C, temperatures in kelvin are all
implausible.

:class:`Units` says what a log's columns are in (``--time-unit s|ms|us``, ``--temp-unit C|K``);
each chunk is converted to seconds and °C as it is read (``t * factor``, ``T - 273.15``), so
what a command writes and prints is in seconds and °C. Where a unit is not said, the first
chunk is checked (:func:`check`) and a log that looks like another unit is refused, with
that unit and the option that says it:

- **time**: a step of ``t`` (the median, per sample) of 0.1 to 10 that is a whole number of
  tenths reads as 0.1-10 ms in milliseconds (a skin's log has rows every 0.1 to 10 ms): a
  step of exactly 1 is a 1 kHz log in milliseconds far more often than a 1 Hz log in seconds;
  a step above 10 that is 0.1-10 ms in microseconds reads as microseconds (as seconds it is
  slower than the estimator can take anyway). A log whose rows really are 0.1 s or more apart
  in seconds is read with ``--time-unit s``.
- **temperature**: a ``T_*`` column whose median is 200 to 400 reads as kelvin (-73 to 127
  °C; no skin is at 200 °C, and the plausible range ends at 150 °C).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from thermoskin.logio.common import LogError

#: ``--time-unit``: seconds a unit of the log's ``t``.
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6}
#: ``--temp-unit``: what is added to a ``T_*`` value for °C.
TEMP_UNITS = {"C": 0.0, "K": -273.15}
#: Medians of a ``T_*`` column read as kelvin, K.
KELVIN_RANGE = (200.0, 400.0)


def is_temperature(name: str) -> bool:
    """Whether the column ``name`` holds a temperature (``T_w``, ``T_w2``, ``T_p``, ``T_a``,
    ``T_w_cmd``, ...)."""
    return name.startswith("T_")


def suspected_time_unit(step: float) -> str | None:
    """The unit ``t`` looks like from its step (module doc), None if seconds: a whole number of
    tenths from 1 to 100 (0.1 to 10 ms in milliseconds, to a millionth of a tenth), or 100 to
    10 000 (0.1 to 10 ms in microseconds)."""
    if not math.isfinite(step):
        return None
    tenths = step * 10.0
    if 1 <= round(tenths) <= 100 and abs(tenths - round(tenths)) <= 1e-6 * tenths:
        return "ms"
    if 100.0 <= step <= 10_000.0:
        return "us"
    return None


@dataclass(frozen=True)
class Units:
    """The units of a log's ``t`` (``time``: a key of :data:`TIME_UNITS`) and ``T_*`` columns
    (``temperature``: of :data:`TEMP_UNITS`); None: seconds and °C, checked (module doc)."""

    time: str | None = None
    temperature: str | None = None

    def __post_init__(self) -> None:
        if self.time is not None and self.time not in TIME_UNITS:
            raise ValueError(f"--time-unit {self.time}: one of {', '.join(TIME_UNITS)}")
        if self.temperature is not None and self.temperature not in TEMP_UNITS:
            raise ValueError(f"--temp-unit {self.temperature}: one of {', '.join(TEMP_UNITS)}")

    def convert(self, names: Iterable[str], cols: list[NDArray[np.float64]]) -> list[NDArray[np.float64]]:
        """A chunk's columns (in ``names``' order) in seconds and °C."""
        f = TIME_UNITS[self.time or "s"]
        d = TEMP_UNITS[self.temperature or "C"]
        if f == 1.0 and d == 0.0:
            return cols
        out = []
        for n, c in zip(names, cols, strict=True):
            if n == "t" and f != 1.0:
                c = c * f
            elif d != 0.0 and is_temperature(n):
                c = c + d
            out.append(c)
        return out

    def check(self, path: Path, names: list[str], cols: list[NDArray[np.float64]],
              rows_per_sample: int = 1) -> None:
        """Refuse the first chunk (its columns in ``names``' order) where a unit not said looks like
        another (module doc): :class:`LogError` naming it and the option."""
        if self.time is None:
            t = cols[names.index("t")][::rows_per_sample]
            if len(t) >= 2:
                step = float(np.median(np.diff(t)))
                unit = suspected_time_unit(step)
                if unit is not None:
                    rate = f"{1 / step:.3g} Hz"  # a step of 0.1 at least (suspected_time_unit)
                    ms = step * TIME_UNITS[unit] * 1e3
                    raise LogError(f"{path}: t steps by {step:g} a row: read as seconds the log is sampled "
                                   f"at {rate}, which a skin's log never is (rows every 0.1 to 10 ms); read "
                                   f"as {_UNIT_NAME[unit]} it is every {ms:g} ms: give --time-unit {unit} "
                                   "(or --time-unit s if t is in seconds)")
        if self.temperature is None:
            warm: list[tuple[str, float]] = []
            for n, c in zip(names, cols, strict=True):
                if is_temperature(n):
                    finite = c[np.isfinite(c)]
                    if finite.size:
                        med = float(np.median(finite))
                        if KELVIN_RANGE[0] <= med <= KELVIN_RANGE[1]:
                            warm.append((n, med))
            if warm:
                which = ", ".join(f"{n} about {m:.1f}" for n, m in warm[:4])
                raise LogError(f"{path}: {which}: no skin is that warm in degrees Celsius; read as kelvin "
                               f"that is {warm[0][1] - 273.15:.1f} degC: give --temp-unit K (or "
                               "--temp-unit C if they are in degrees Celsius)")


_UNIT_NAME = {"ms": "milliseconds", "us": "microseconds"}
