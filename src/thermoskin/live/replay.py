"""``thermoskin replay RUN.mcap --live``: a recording played into the live server.

The server advertises the recording's own channels and schemas (:func:`recorded_topics`),
so a single patch's and a skin's recordings (per-patch topics, the protobuf scene) replay
alike. Messages go out in file order, their recorded payloads as they are, paced so that
a message at loop time ``t`` leaves at ``(t - t_first) / speed`` s of wall-clock time
after the first; signals are decimated to the server's rate per topic (as a live run's),
events, ``/params`` and the scene all sent.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from os import PathLike
from pathlib import Path
from typing import Any

from thermoskin.live.messages import EVENT_TOPICS, Decimator
from thermoskin.live.server import LATCHED, LiveServer
from thermoskin.runtime.record import RecordingError, recording_channels, scan_messages

_MAGIC = b"\x89MCAP0\r\n"


def recorded_topics(path: str | PathLike[str]) -> dict[str, tuple[str, Any]]:
    """The recording's channels as :class:`LiveServer` ``topics`` (``(message encoding,
    foxglove.Schema)`` each): a replay serves exactly the recorded topics and schemas, a
    single patch's or a skin's (its per-patch topics and the protobuf scene)."""
    import foxglove

    out: dict[str, tuple[str, Any]] = {}
    for topic, (enc, name, s_enc, data) in recording_channels(path).items():
        out[topic] = (enc, foxglove.Schema(name=name or topic, encoding=s_enc, data=data))
    return out


#: Longest sleep between two looks at the stop request, s.
STOP_POLL_S = 0.05


def play(path: str | PathLike[str], live: LiveServer, speed: float = 1.0, *,
         clock: Callable[[], float] = time.monotonic,
         sleep: Callable[[float], None] = time.sleep,
         stop: Callable[[], bool] | None = None) -> dict[str, Any]:
    """Play ``path`` into ``live`` at ``speed`` times real time; figures of what was sent.

    The recorded payloads go out as they are (JSON or protobuf), at their log time (the loop
    clock). Returns ``sent`` (messages), ``skipped`` (signals dropped by decimation),
    ``t_first``, ``t_last`` (loop clock, s), ``wall_s``, ``complete`` (the file's footer
    was read and nothing was damaged) and ``stopped`` (``stop()`` turned true: looked at
    before every message and at least every :data:`STOP_POLL_S` s of a wait).
    """
    if not (speed > 0 and math.isfinite(speed)):
        raise ValueError(f"--speed {speed}: must be > 0 and finite")
    p = Path(path)
    if not p.is_file():
        raise RecordingError(f"recording {p} does not exist")
    with open(p, "rb") as fh:
        if fh.read(len(_MAGIC)) != _MAGIC:
            raise RecordingError(f"{p} is not an MCAP file (bad magic)")
    rate = live.rows.rate
    decimators: dict[str, Decimator] = {}
    sent = skipped = 0
    t_first = t_last = math.nan
    wall0 = math.nan
    stopped = False
    sc = scan_messages(p)
    for batch in sc.batches():
        if stopped:
            break
        for topic, _, log_ns, payload in batch:
            if stop is not None and stop():
                stopped = True
                break
            if topic not in live.channels:
                continue
            t = log_ns * 1e-9
            if topic not in EVENT_TOPICS and topic not in LATCHED:
                dec = decimators.get(topic)
                if dec is None:
                    dec = decimators[topic] = Decimator(rate)
                if not dec.keep(t):
                    skipped += 1
                    continue
            if math.isnan(wall0):
                wall0, t_first = clock(), t
            due = wall0 + (t - t_first) / speed
            while (delay := due - clock()) > 0.001:
                if stop is not None and stop():
                    stopped = True
                    break
                sleep(min(delay, STOP_POLL_S) if stop is not None else delay)
            if stopped:
                break
            live.publish(topic, t, bytes(payload))
            sent += 1
            t_last = t
    wall = clock() - wall0 if sent else 0.0
    return {"sent": sent, "skipped": skipped, "t_first": t_first, "t_last": t_last, "wall_s": wall,
            "complete": bool(sc.report.complete), "stopped": stopped}
