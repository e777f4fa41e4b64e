"""The loop's row blocks as topic messages, decimated for a live view.

The topics and their fields are those of the recording (:data:`~thermoskin.runtime.record.
TOPIC_SCHEMAS`): a field is filled from the loop column of the same name, or from the
column the recorder takes it from (``/skin/sample`` ``v`` and ``drive`` are the device's
``v_dev`` and ``drive_dev`` when the row has them; ``/control`` ``v_cmd`` is ``v``). A
field without a column in the block is left out. ``/skin/estimate`` is not sent on the
row a fault tripped (the blocks did not run on it), ``/sim/truth`` only when the block
has a finite ``q_i``, ``/loop/timing`` only when it has ``late``.

Signals (every topic but ``/events`` and ``/params``) are decimated to ``rate`` Hz of the
loop clock: the first row of each bin ``floor(t * rate)`` is kept. Contact onsets and
releases (a change of ``contact`` on a row without fault) become ``/events`` messages
``contact-on`` / ``contact-off`` on every row, never decimated.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np

from thermoskin.runtime.record import TOPIC_SCHEMAS

#: Topics sent whole (never decimated).
EVENT_TOPICS = ("/events", "/params")
#: Topics decimated to the live rate.
SIGNAL_TOPICS = tuple(k for k in TOPIC_SCHEMAS if k not in EVENT_TOPICS)
#: Loop columns a field is read from when they differ from its name, first present wins.
SOURCES: dict[tuple[str, str], tuple[str, ...]] = {
    ("/skin/sample", "v"): ("v_dev", "v"),
    ("/skin/sample", "drive"): ("drive_dev", "drive"),
    ("/control", "v_cmd"): ("v",),
}
#: A topic sent only when the block has this column (with a finite value, for the truth).
REQUIRES = {"/sim/truth": "q_i", "/loop/timing": "late"}
#: Bins are taken a millionth of a bin early, so that ``t = k t_s`` on a bin edge
#: (``0.03 * 100 = 2.9999999999999996``) falls in its own bin.
_EPS = 1e-6


def clean(value: Any) -> Any:
    """NaN and infinities to ``None``, through dicts and lists (JSON has neither)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [clean(v) for v in value]
    if isinstance(value, np.generic):
        return clean(value.item())
    return value


class Decimator:
    """Keeps the first sample of each ``1/rate`` bin of ``t`` (the loop clock, s)."""

    def __init__(self, rate: float) -> None:
        if not (rate > 0 and math.isfinite(rate)):
            raise ValueError(f"decimation rate {rate} Hz must be > 0 and finite")
        self.rate = float(rate)
        self._bin = -math.inf

    def select(self, t: np.ndarray) -> np.ndarray:
        """Indices of ``t`` (one block, in order) to keep."""
        if not len(t):
            return np.zeros(0, dtype=np.intp)
        b = np.floor(np.asarray(t, dtype=float) * self.rate + _EPS)
        prev = np.empty_like(b)
        prev[0] = self._bin
        prev[1:] = b[:-1]
        self._bin = float(b[-1])
        return np.flatnonzero(b != prev)

    def keep(self, t: float) -> bool:
        """Whether one sample at ``t`` is kept."""
        b = math.floor(t * self.rate + _EPS)
        if b == self._bin:
            return False
        self._bin = b
        return True


def _fields(topic: str) -> list[tuple[str, bool]]:
    props = TOPIC_SCHEMAS[topic].get("properties", {})
    return [(k, props[k].get("type") == "integer") for k in props if k != "t"]


class RowMessages:
    """Turns the loop's row blocks into ``(topic, t, message)``, signals decimated to ``rate`` Hz."""

    def __init__(self, rate: float = 100.0) -> None:
        self.rate = rate
        self._dec = Decimator(rate)
        self._contact = 0
        self._fields = {topic: _fields(topic) for topic in SIGNAL_TOPICS}

    def messages(self, block: Mapping[str, Any]) -> Iterator[tuple[str, float, dict[str, Any]]]:
        """Every contact change on ``/events`` and the decimated signals of one block."""
        t = np.asarray(block["t"], dtype=float)
        n = len(t)
        if not n:
            return
        fault = np.asarray(block["fault"]) if "fault" in block else np.zeros(n)
        ok_rows = np.flatnonzero(fault == 0)
        if "contact" in block and len(ok_rows):
            c = np.nan_to_num(np.asarray(block["contact"], dtype=float)[ok_rows]).astype(np.int64)
            prev = np.empty_like(c)
            prev[0] = self._contact
            prev[1:] = c[:-1]
            for j in np.flatnonzero(c != prev):
                yield "/events", float(t[ok_rows[j]]), {"kind": "contact-on" if c[j] else "contact-off"}
            self._contact = int(c[-1])
        keep = self._dec.select(t)
        if not len(keep):
            return
        plans = []
        for topic, fields in self._fields.items():
            need = REQUIRES.get(topic)
            if need is not None and (need not in block or (
                    topic == "/sim/truth" and not np.isfinite(np.asarray(block[need], dtype=float)).any())):
                continue
            cols = []
            for name, is_int in fields:
                src = next((s for s in SOURCES.get((topic, name), (name,)) if s in block), None)
                if src is not None:
                    cols.append((name, np.asarray(block[src])[keep].tolist(), is_int))
            if cols:
                plans.append((topic, cols))
        ts = t[keep].tolist()
        ok = (fault[keep] == 0).tolist()
        for j, tj in enumerate(ts):
            for topic, cols in plans:
                if topic == "/skin/estimate" and not ok[j]:
                    continue
                msg: dict[str, Any] = {}
                for name, vals, is_int in cols:
                    x = vals[j]
                    if is_int:
                        msg[name] = int(x) if math.isfinite(x) else 0
                    else:
                        msg[name] = float(x) if math.isfinite(x) else None
                yield topic, tj, msg
