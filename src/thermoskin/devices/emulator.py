"""The device emulator: the simulated skin behind a pseudo-terminal speaking the link protocol.

``thermoskin device-emulator --link PATH [--scenario NAME] [--fault KIND@SECONDS]
[--tc-period S] [--jitter S] [--truth TRUTH.csv]`` (or ``python -m
thermoskin.devices.emulator``) opens a pty pair, makes ``PATH`` a symbolic link to the
slave side (a stale link is replaced, the link is removed on exit; a link another emulator
serves, known by the lock it holds on the file ``.LINK.lock`` beside it, is refused) and waits
for a HELLO. Each host's HELLO (a new session id in its ``seq``) starts a fresh session: the
scenario, the device clock and the truth file from zero; the session's own HELLO repeated
restarts nothing; another host's is refused (``STATUS_BUSY``) while a session is on, until its
host's SAFE or a second of its silence (``SESSION_TIMEOUT``). In a session, every ``t_s``
(1 ms, paced by the wall clock with absolute deadlines from the HELLO) it

1. measures: the thermocouple boards of the simulated plant read ``T_w, T_p, T_a``
   (``sim.sensors``: each converts every ``tc_period``, default 0.1 s, a MAX31856-class
   board, with the configured jitter and lag); between conversions the last reading is
   repeated with its fresh bit clear and its update counter unchanged;
2. sends a SAMPLE (and a FAULT when a fault it can detect appears);
3. advances the simulated plant (:class:`~thermoskin.sim.plant.SimulatedPlant`: the skin,
   exact ZOH, and the Peltier tank, :class:`~thermoskin.physics.peltier.PeltierTank` with
   the configured drive limits, losing ``q_out = (T_p - T_w)/R_w(v)`` to the skin's water)
   one step with the last COMMAND (drive, pump velocity), the scenario's touches and
   ambient repeating every ``scenario.duration``. It starts in the network's equilibrium
   for ``scenario.T_p(0)`` with the pump running.

``--truth TRUTH.csv`` writes the simulator's truth, one row per sample sent,
``t,contact_true,q_i,n_fingers,T_g`` with ``t`` the sample's device time (as the host
logs it), flushed every half second and complete when the emulator stops (SIGINT,
SIGTERM). ``--tc-period`` sets the three boards' conversion periods (default 0.1 s, or
the config's ``[sensor]`` periods if it sets any), ``--jitter`` their jitter.

Until the first COMMAND after a HELLO, and while no COMMAND came for ``command_timeout``
s (the watchdog), the device holds drive 0 and the pump off. SAFE latches the same
until the next HELLO.

Faults, ``KIND@SECONDS`` since the session's start (again in each session):

- ``tc-open``: ``T_w`` reads NaN with ``ST_OPEN_W`` set; one FAULT(F_TC_OPEN) is sent.
- ``nan-burst``: every channel reads NaN from then on (no flag: the host must notice).
- ``overtemp``: ``T_p`` reads :data:`OVERTEMP_C` (beyond the 7-37 °C bound).
- ``serial-drop``: the device stops sending and stops listening (a cut cable).
- ``tc-stuck``: ``T_w`` freezes at its last reading while still flagged fresh.

``tc-open``, ``nan-burst`` and ``overtemp`` force a reading of their channels at their
onset, so they show in the very sample at their time (the host's fault-to-safe delay is measured from there);
``tc-stuck`` shows at the regular conversions. :attr:`DeviceCore.t_safe` is the device
time at which the first SAFE of the session took effect (NaN if none).
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import math
import os
import select
import signal
import sys
import threading
import time
import tty
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from thermoskin.devices import protocol as proto
from thermoskin.params import Config
from thermoskin.sim.boards import said, simulated_boards
from thermoskin.sim.plant import SimulatedPlant
from thermoskin.sim.scenarios import DEFAULT_SCENARIO, SCENARIOS, Scenario, get_scenario

FAULT_KINDS = ("tc-open", "nan-burst", "overtemp", "serial-drop", "tc-stuck")
SESSION_TIMEOUT = 1.0
"""The host's silence (s) that ends its session; until then another host's HELLO is refused."""
OVERTEMP_C = 45.0
"""``T_p`` reading under the ``overtemp`` fault, °C."""
_FORCED = {"tc-open": proto.CH_W, "nan-burst": proto.CH_W | proto.CH_P | proto.CH_A,
           "overtemp": proto.CH_P}
"""Faults that force a reading of their channels at their onset (seen in that very sample)."""
DEVICE_ID = 0x7E57_0001
"""Device id the emulator reports in HELLO_ACK."""



def write_pending(fd: int, out: bytearray) -> None:
    """Write what the pseudo-terminal takes of ``out`` now, never waiting, and drop it from ``out``;
    a link whose other end is gone (``OSError``) drops everything pending."""
    if not out:
        return
    try:
        n = os.write(fd, out)
    except (BlockingIOError, InterruptedError):
        return
    except OSError:
        out.clear()
        return
    del out[:n]


@dataclass(frozen=True)
class FaultSpec:
    """A fault ``kind`` injected ``t`` seconds after the host connected."""

    kind: str
    t: float

    @classmethod
    def parse(cls, text: str) -> FaultSpec:
        """``"tc-open@12.5"`` -> ``FaultSpec("tc-open", 12.5)``; ValueError naming the problem."""
        kind, sep, when = text.partition("@")
        kind = kind.strip()
        if not sep or kind not in FAULT_KINDS:
            raise ValueError(f"fault {text!r}: must be KIND@SECONDS with KIND one of "
                             f"{', '.join(FAULT_KINDS)}")
        try:
            t = float(when)
        except ValueError:
            raise ValueError(f"fault {text!r}: {when!r} is not a number of seconds") from None
        if not (math.isfinite(t) and t >= 0):
            raise ValueError(f"fault {text!r}: the time must be >= 0 s")
        return cls(kind, t)


class DeviceCore:
    """What the device does, without I/O or wall clock: messages in, one step per ``t_s``.

    The physics and the thermocouple boards are the simulated plant
    (:class:`~thermoskin.sim.plant.SimulatedPlant`: Peltier tank, the scenario's touches and
    ambient repeating every ``scenario.duration``, the ``[sensor]`` boards, or with
    ``lab_boards`` boards as a lab buys them drawn from its seed, ``sim.boards``); ``tc_period``
    (s) sets the three boards' conversion periods and ``jitter`` (s) their jitter (``None``:
    the configuration's). The faults are the device's own, applied to the plant's readings.
    """

    def __init__(self, cfg: Config, scenario: Scenario, faults: Sequence[FaultSpec] = (),
                 tc_period: float | None = 0.1, command_timeout: float = 0.5,
                 device_id: int = DEVICE_ID, jitter: float | None = None,
                 session_timeout: float = SESSION_TIMEOUT, lab_boards: bool = False) -> None:
        sensor: dict[str, float] = {}
        if tc_period is not None:
            sensor.update(period_T_w=tc_period, period_T_p=tc_period, period_T_a=tc_period)
        if jitter is not None:
            sensor["jitter"] = jitter
        cfg = cfg.replace(sensor=sensor) if sensor else cfg
        self.cfg = cfg
        self.t_s = cfg.sampling.t_s
        self.scenario = scenario
        self.faults = sorted(faults, key=lambda f: f.t)
        s = cfg.sensor
        self.tc_period = max(s.period_T_w, s.period_T_p, s.period_T_a) or self.t_s
        """The longest conversion period of the boards (reported in HELLO_ACK), s."""
        self.command_timeout = float(command_timeout)
        self.session_timeout = float(session_timeout)
        """The host's silence (s) after which its session is over (the device idles until a HELLO)."""
        self.device_id = device_id
        self.boards = simulated_boards(cfg.sensor, ideal=not lab_boards)
        """The boards the plant reads through (their true offsets, noise, lags)."""
        self.plant = SimulatedPlant(cfg, scenario, repeat=True, boards=self.boards)
        self.skin = self.plant.skin
        self.tank = self.plant.tank
        self.sensors = self.plant.sensors
        self.connected = False
        """A session is on: SAMPLEs go out every ``t_s``."""
        self.session_id: int | None = None
        """The host's session id (its HELLO's ``seq``) while a session is on."""
        self.sessions = 0
        """Sessions started (each a HELLO of a new id): the caller restarts its clock and truth."""
        self.refused = 0
        """HELLOs refused because another host's session was on."""
        self.k = 0
        self.k_host = 0
        """``k`` at the host's last message of this session."""
        self.seq = 0
        self.t_safe = math.nan
        """Device time (s) from which a SAFE held drive 0 and pump off; NaN before any."""
        self._reset_physics()

    def _reset_physics(self) -> None:
        self.plant.reset("equilibrium", v=self.cfg.pump.v_on)
        self.drive = 0.0
        self.v = 0.0
        self.cmd_drive = 0.0
        self.cmd_v = 0.0
        self.cmd_seq = 0
        self.k_cmd = -1
        self.safe_latched = False
        self.active: set[str] = set()
        self.readings = [math.nan, math.nan, math.nan]
        self.counters = [0, 0, 0]
        self.truth = (0.0, 0, 0.0, 0, math.nan)
        """``(t, contact_true, q_i, n_fingers, T_g)`` of the last sample sent."""
        self._overrun = False

    # -- messages --------------------------------------------------------------------------
    def _next_seq(self) -> int:
        self.seq = (self.seq + 1) % proto.SEQ_MOD
        return self.seq

    def on_message(self, msg: proto.Message) -> list[proto.Message]:
        """Apply one host message; return the replies."""
        t = msg.TYPE
        if self.connected and t != proto.T_HELLO:
            self.k_host = self.k
        if t == proto.T_COMMAND:
            if self.connected and not self.safe_latched:
                d = msg.drive  # type: ignore[union-attr]
                v = msg.v  # type: ignore[union-attr]
                self.cmd_drive = min(1.0, max(-1.0, d)) if d == d else 0.0
                self.cmd_v = min(10.0, v) if v == v and v > 0.0 else 0.0
                self.cmd_seq = msg.seq
                self.k_cmd = self.k
            return []
        if t == proto.T_SAFE:
            if self.connected:
                if not self.safe_latched and self.t_safe != self.t_safe:
                    self.t_safe = self.t
                self.safe_latched = True
            return []
        if t == proto.T_HELLO:
            return [self._hello(msg)]  # type: ignore[arg-type]
        return []

    def _hello(self, msg: proto.Hello) -> proto.HelloAck:
        """A HELLO: the session's own repeated (answered again, nothing restarts), another
        host's while a session is on (refused: ``STATUS_BUSY``), or a new session (the
        scenario, the device clock and the caller's truth restart at zero)."""
        status = proto.STATUS_OK
        if msg.version != proto.PROTOCOL_VERSION:
            status = proto.STATUS_BAD_VERSION
        elif self.connected and msg.seq == self.session_id:
            self.k_host = self.k
        elif self.live:
            status = proto.STATUS_BUSY
            self.refused += 1
        else:
            self.start_session(msg.seq)
        return proto.HelloAck(self._next_seq(), proto.PROTOCOL_VERSION, status, self.device_id,
                              round(self.t_s * 1e6), round(self.tc_period * 1e6))

    @property
    def live(self) -> bool:
        """A session that another host's HELLO may not take over: on, not ended by a SAFE, its
        host heard from within ``session_timeout``."""
        return (self.connected and not self.safe_latched
                and (self.k - self.k_host) * self.t_s <= self.session_timeout)

    def start_session(self, session_id: int) -> None:
        """A fresh session: the scenario from its start (the plant in its initial state), the
        device clock at zero, no command yet, faults again from their times."""
        self._reset_physics()
        self.k = self.k_host = 0
        self.t_safe = math.nan
        self.session_id = session_id
        self.connected = True
        self.sessions += 1

    def end_session(self) -> None:
        """The host is gone: outputs off, no more SAMPLEs until a HELLO."""
        self.connected = False
        self.session_id = None
        self.drive = self.v = 0.0

    @property
    def host_silent(self) -> bool:
        """The session's host has said nothing for ``session_timeout``: its session is over."""
        return self.connected and (self.k - self.k_host) * self.t_s > self.session_timeout

    @property
    def t(self) -> float:
        """Device time, s since the host first connected."""
        return self.k * self.t_s

    def fault_active(self, kind: str) -> bool:
        return kind in self.active

    def mark_overrun(self) -> None:
        self._overrun = True

    # -- one sample ------------------------------------------------------------------------
    def step(self) -> list[proto.Message]:
        """Measure, report (SAMPLE and new FAULTs), then advance the physics by ``t_s``."""
        t = self.k * self.t_s
        out: list[proto.Message] = []
        force = 0
        for f in self.faults:
            if f.t <= t + 1e-12 and f.kind not in self.active:
                self.active.add(f.kind)
                force |= _FORCED.get(f.kind, 0)
                if f.kind == "tc-open":
                    out.append(proto.Fault(0, proto.F_TC_OPEN, 0, math.nan))
        active = self.active
        plant = self.plant
        T_w, T_p, T_a = plant.measure()
        fresh = plant.fresh | force
        q_i, T_g, _, _ = plant.truth()
        contact, n_fingers = plant.contact()
        self.truth = (t, contact, q_i, n_fingers, T_g)
        if fresh:
            if active:
                if "tc-stuck" in active:
                    T_w = self.readings[0]
                if "tc-open" in active:
                    T_w = math.nan
                if "overtemp" in active:
                    T_p = self.sensors.quantise(OVERTEMP_C + (T_p - plant.T_p_true))
                if "nan-burst" in active:
                    T_w = T_p = T_a = math.nan
            r, c = self.readings, self.counters
            if fresh & proto.CH_W:
                r[0] = T_w
                c[0] = (c[0] + 1) & 0xFFFF
            if fresh & proto.CH_P:
                r[1] = T_p
                c[1] = (c[1] + 1) & 0xFFFF
            if fresh & proto.CH_A:
                r[2] = T_a
                c[2] = (c[2] + 1) & 0xFFFF

        # commands in force over the next step
        status = 0
        if self.safe_latched:
            status |= proto.ST_SAFE
            drive = v = 0.0
        elif self.k_cmd < 0:
            status |= proto.ST_NO_COMMAND
            drive = v = 0.0
        elif (self.k - self.k_cmd) * self.t_s > self.command_timeout:
            status |= proto.ST_WATCHDOG
            drive = v = 0.0
        else:
            drive, v = self.cmd_drive, self.cmd_v
        if "tc-open" in active:
            status |= proto.ST_OPEN_W
        if self._overrun:
            status |= proto.ST_OVERRUN
            self._overrun = False
        self.drive, self.v = drive, v
        r = self.readings
        for i, m in enumerate(out):
            out[i] = proto.Fault(self._next_seq(), m.code, m.channel, m.value)  # type: ignore[union-attr]
        out.append(proto.SampleMsg(self._next_seq(), round(t * 1e6), r[0], r[1], r[2], fresh, status,
                               (self.counters[0], self.counters[1], self.counters[2]), v, drive,
                               self.cmd_seq))

        # physics over [t, t + t_s)
        plant.apply(drive, v)
        self.k += 1
        return out


TRUTH_COLUMNS = ("t", "contact_true", "q_i", "n_fingers", "T_g")
"""Columns of the emulator's truth file (``--truth``)."""


class TruthWriter:
    """The emulator's truth, one CSV row per sample sent: ``t,contact_true,q_i,n_fingers,T_g``.

    ``t`` is the sample's device time (``t_us`` of its SAMPLE, s since the HELLO), which the
    host logs as its ``t``; ``contact_true`` 0/1, ``q_i`` W (the touch's heat into the
    sheet, contact applied from ``t`` on), ``n_fingers``, ``T_g`` °C. Rows are formatted as
    they come and handed every ``flush_s`` (wall clock, :meth:`maybe_flush`) to a thread of
    their own, which writes and flushes them: a write the disk holds up (a machine writing
    much else) never holds up the device's samples. :meth:`flush`, :meth:`restart` and
    :meth:`close` wait for what was handed over; ``rows`` counts the rows written.
    """

    def __init__(self, path: str | os.PathLike[str], flush_s: float = 0.5) -> None:
        import queue

        self.path = Path(path)
        self._f = self.path.open("w", encoding="ascii", newline="\n")
        self._f.write(",".join(TRUTH_COLUMNS) + "\n")
        self._f.flush()
        self._rows: list[str] = []
        self.flush_s = float(flush_s)
        self._t_flush = time.monotonic()
        self.rows = 0
        self._q: queue.SimpleQueue[tuple[str, int] | None] = queue.SimpleQueue()
        self._done = threading.Condition()
        self._handed = 0
        self._written = 0
        self._thread: threading.Thread | None = None

    def _write_loop(self) -> None:
        while (item := self._q.get()) is not None:
            text, n = item
            self._f.write(text)
            self._f.flush()
            with self._done:
                self.rows += n
                self._written += 1
                self._done.notify_all()

    def _hand_off(self, now: float | None) -> None:
        if self._rows:
            if self._thread is None:
                self._thread = threading.Thread(target=self._write_loop, name="truth-writer", daemon=True)
                self._thread.start()
            self._handed += 1
            self._q.put(("".join(self._rows), len(self._rows)))
            self._rows.clear()
        self._t_flush = time.monotonic() if now is None else now

    def _wait(self) -> None:
        with self._done:
            self._done.wait_for(lambda: self._written >= self._handed)

    def restart(self) -> None:
        """A new session: the file holds its header alone again (the rows of the session before
        are dropped, as its host's log is another file)."""
        self._rows.clear()
        self._wait()
        self._f.seek(0)
        self._f.truncate()
        self._f.write(",".join(TRUTH_COLUMNS) + "\n")
        self._f.flush()
        self.rows = 0

    def add(self, t: float, contact: int, q_i: float, n_fingers: int, T_g: float) -> None:
        """One sample's row (formatted now, written at the next flush)."""
        self._rows.append(f"{t:.6f},{contact},{q_i:.9g},{n_fingers},{T_g:.9g}\n")

    def maybe_flush(self, now: float) -> None:
        """Hand the rows to the writer if ``flush_s`` passed since the last time (``now``:
        monotonic, s)."""
        if now - self._t_flush >= self.flush_s:
            self._hand_off(now)

    def flush(self, now: float | None = None) -> None:
        """Every row so far written and flushed (waits for the writer)."""
        self._hand_off(now)
        self._wait()
        self._f.flush()

    def close(self) -> None:
        """Every row so far to the file, then close it."""
        if not self._f.closed:
            self.flush()
            if self._thread is not None:
                self._q.put(None)
                self._thread.join()
                self._thread = None
            self._f.close()


class PtyEmulator:
    """:class:`DeviceCore` behind a pseudo-terminal, paced at ``t_s`` by the wall clock.

    ``run()`` blocks until :meth:`stop` (or SIGINT/SIGTERM through :func:`main`). Timing
    statistics (lateness of each sample against its absolute deadline) are kept in
    :attr:`lateness` (the last 100 000 samples, s).

    **After a stall** (the emulator's process not scheduled for a while) it catches up the
    way a board's sample buffer would: the samples it owes are measured and sent at once,
    each with its own device time, so the host receives every sample, late; the device
    clock never slips against the wall clock. Samples owed for longer than ``buffer_s``
    (the buffer's depth) are lost (not sent; the physics still advances; counted in
    ``lost_samples``), and a sample sent more than :data:`MAX_LAG` late carries the
    ``ST_OVERRUN`` status bit. ``rt_priority`` > 0 asks for ``SCHED_FIFO`` in :meth:`serve`
    (:attr:`priority` says what was granted).
    """

    MAX_OUT = 64 * 1024
    MAX_LAG = 0.05
    """A sample sent later than this (s) is flagged ``ST_OVERRUN``."""

    def __init__(self, link: str | os.PathLike[str], core: DeviceCore,
                 truth: TruthWriter | None = None, *, rt_priority: int = 0,
                 buffer_s: float = 1.0) -> None:
        self.link = Path(link)
        self.core = core
        self.truth = truth
        """Where each sample sent also writes its truth row (``None``: nowhere)."""
        self.decoder = proto.Decoder()
        self._stop = threading.Event()
        self.ready = threading.Event()
        """Set once the link exists."""
        self.connected = threading.Event()
        """Set at the first session's HELLO."""
        self.overruns = 0
        self.dropped_frames = 0
        self.lost_samples = 0
        self.rt_priority = int(rt_priority)
        self.priority = "normal"
        self.buffer_s = float(buffer_s)
        self.lateness = np.zeros(100_000)
        self.n_late = 0
        self._out = bytearray()
        self._t0 = 0.0
        self._master = -1
        self._slave = -1
        self._lock = -1  # held on .LINK.lock while the link is ours
        self.slave_name = ""

    def stop(self) -> None:
        self._stop.set()

    # -- link ------------------------------------------------------------------------------
    def open_link(self) -> None:
        """Open the pty pair (raw mode) and point the link at its slave side."""
        link = self.link
        if link.exists() and not link.is_symlink():
            raise FileExistsError(f"{link} exists and is not a symbolic link; not replacing it")
        # one emulator per link: a lock on a file beside it, held while it serves (the OS lets
        # it go when the emulator dies, however: a killed one's link is then stale and taken
        # over). The file stays: removed, a second emulator could lock the removed one while a
        # third locks a new one
        import fcntl

        lock = os.open(link.with_name(f".{link.name}.lock"), os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(lock)
            raise FileExistsError(f"{link} is served by another emulator; not taking it over: stop "
                                  "that one or choose another --link") from None
        self._lock = lock
        try:
            self._open_pty()
        except BaseException:
            self.close_link()
            raise

    def _open_pty(self) -> None:
        """The pty pair (raw mode) and the link pointed at its slave side."""
        link = self.link
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        os.set_blocking(self._master, False)
        self.slave_name = os.ttyname(self._slave)
        tmp = link.with_name(f".{link.name}.{os.getpid()}.tmp")
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        os.symlink(self.slave_name, tmp)
        os.replace(tmp, link)  # atomically replaces a stale link
        self.ready.set()

    def close_link(self) -> None:
        """Remove the link (if it is still ours) and close the pty."""
        with contextlib.suppress(OSError):
            if self.link.is_symlink() and os.readlink(self.link) == self.slave_name:
                self.link.unlink()
        for fd in (self._master, self._slave, self._lock):
            if fd >= 0:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self._master = self._slave = self._lock = -1

    # -- I/O -------------------------------------------------------------------------------
    def _read(self) -> None:
        try:
            data = os.read(self._master, 65536)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            return
        if not data:
            return
        core = self.core
        silent = "serial-drop" in core.active
        for msg in self.decoder.feed(data):
            if silent:
                continue
            n = core.sessions
            replies = core.on_message(msg)
            if core.sessions != n:  # a new session: its clock starts now; what the session
                self._t0 = time.monotonic()  # before left unsent is not this host's
                self._out.clear()
                self.connected.set()
            # a HELLO repeated by the session's host (its first answered late) restarts
            # nothing and drops nothing: the host ignores samples before its HELLO_ACK
            for reply in replies:
                self._send(reply)
        self._flush()

    def _send(self, msg: proto.Message) -> None:
        frame = proto.encode(msg)
        if len(self._out) + len(frame) > self.MAX_OUT:
            self.dropped_frames += 1
            return
        self._out += frame

    def _flush(self) -> None:
        write_pending(self._master, self._out)

    # -- loop ------------------------------------------------------------------------------
    def run(self) -> None:
        """Create the link, wait for the host, run until stopped; the link is removed on exit."""
        self.open_link()
        try:
            self.serve()
        finally:
            self.close_link()

    def serve(self) -> None:
        """Run until :meth:`stop`: idle until a HELLO starts a session, then one SAMPLE every
        ``t_s`` against absolute deadlines from the HELLO; a new session (another HELLO, once
        the one before has ended) restarts the clock and the truth; a session whose host fell
        silent for ``core.session_timeout`` ends, and the emulator idles again."""
        gc.collect()
        gc.freeze()  # the start-up heap is never traversed again
        # and no collection pauses a session: what a sample allocates (messages, frames, rows)
        # holds no reference cycle, so reference counting frees it
        gc.disable()
        try:
            self._serve()
        finally:
            gc.enable()

    def _serve(self) -> None:
        core = self.core
        t_s = core.t_s
        master = self._master
        stop = self._stop
        truth = self.truth
        lat = self.lateness
        n_lat = lat.size
        session = core.sessions
        t0 = 0.0
        k = 0
        fifo = False
        while not stop.is_set():
            if core.sessions != session:  # a HELLO started a session: clock and truth from zero
                session = core.sessions
                t0 = self._t0
                k = 0
                if truth is not None:
                    truth.restart()
                if not fifo and self.rt_priority > 0:
                    from thermoskin.devices.sched import set_fifo

                    self.priority = set_fifo(self.rt_priority)
                    fifo = True
            if not core.connected:  # no session: wait for a HELLO
                r, _, _ = select.select([master], [], [], 0.05)
                if r:
                    self._read()
                continue
            deadline = t0 + k * t_s
            while True:
                now = time.monotonic()
                left = deadline - now
                if left <= 0.0:
                    break
                r, _, _ = select.select([master], [], [], left)
                if r:
                    self._read()
                    if core.sessions != session or not core.connected:
                        break
            if core.sessions != session or not core.connected:
                continue
            late = now - deadline
            lat[self.n_late % n_lat] = late
            self.n_late += 1
            if late > self.buffer_s:  # beyond the buffer's depth: measured, never sent
                core.step()
                self.lost_samples += 1
                k += 1
                continue
            if late > self.MAX_LAG:
                self.overruns += 1
                core.mark_overrun()
            msgs = core.step()
            if "serial-drop" not in core.active:
                for m in msgs:
                    self._send(m)
                self._flush()
                if truth is not None:
                    truth.add(*core.truth)
                    truth.maybe_flush(now)
            k += 1
            self._read()
            if core.host_silent:  # its host is gone (killed, unplugged): the session ends
                core.end_session()
                self._out.clear()
                if truth is not None:
                    truth.flush()

    def timing(self) -> dict[str, float]:
        """Lateness of the samples against their deadlines (the last 100 000): mean, p50, p99,
        max (µs; the max is the longest stall); counts of late (overrun), lost and dropped."""
        n = min(self.n_late, self.lateness.size)
        if n == 0:
            return {"samples": 0}
        x = self.lateness[:n] * 1e6
        return {"samples": float(self.n_late), "mean_us": float(x.mean()),
                "p50_us": float(np.percentile(x, 50)), "p99_us": float(np.percentile(x, 99)),
                "max_us": float(x.max()), "overruns": float(self.overruns),
                "lost_samples": float(self.lost_samples),
                "dropped_frames": float(self.dropped_frames)}


def check_options(scenario: str, faults: Sequence[str], tc_period: float | None, jitter: float | None,
                  watchdog: float | None = None) -> tuple[Scenario, list[FaultSpec]]:
    """The scenario and the faults of the emulator's options; ValueError (KeyError for the
    scenario) naming the option and the problem."""
    sc = get_scenario(scenario)
    specs = [FaultSpec.parse(f) for f in faults]
    if tc_period is not None and not (tc_period > 0 and math.isfinite(tc_period)):
        raise ValueError(f"--tc-period {tc_period} s must be > 0")
    if jitter is not None and not (jitter >= 0 and math.isfinite(jitter)):
        raise ValueError(f"--jitter {jitter} s must be >= 0")
    if watchdog is not None and not (0.002 <= watchdog <= 60.0):
        raise ValueError(f"--watchdog {watchdog} s must be within [0.002, 60] s")
    return sc, specs


def serve_until_stopped(emu: PtyEmulator, link: str | os.PathLike[str], writer: TruthWriter | None,
                        rt_priority: int, started: Callable[[], None] | None = None,
                        stopped: Callable[[], None] | None = None) -> int:
    """Serve ``emu`` (the emulator's core or the firmware's) on ``link`` until SIGINT/SIGTERM (or
    :meth:`PtyEmulator.stop`): the link made (exit 2 in one line if it cannot be), ``SCHED_FIFO``
    at ``rt_priority`` asked for, ``started()`` (the banner), the sessions served, the link
    removed and the truth file closed, then ``stopped()`` (the report); 0 on a clean stop. The
    signal handlers are put back, and the truth file closed, whatever happens."""
    from thermoskin.devices.sched import set_fifo

    old: dict[int, object] = {}
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            old[sig] = signal.signal(sig, lambda signum, frame: emu.stop())
    try:
        try:
            emu.open_link()
        except OSError as e:
            print(f"device-emulator: cannot create the link {link}: {e}", file=sys.stderr)
            return 2
        emu.priority = set_fifo(rt_priority)
        if started is not None:
            started()
        try:
            emu.serve()
        finally:
            emu.close_link()
            if writer is not None:
                writer.close()
        if stopped is not None:
            stopped()
        return 0
    finally:
        if writer is not None:
            writer.close()
        for sig, handler in old.items():
            signal.signal(sig, handler)  # type: ignore[arg-type]


def main(link: str, scenario: str = DEFAULT_SCENARIO, faults: Sequence[str] = (),
         tc_period: float | None = None, cfg: Config | None = None, verbose: bool = True,
         jitter: float | None = None, truth: str | os.PathLike[str] | None = None,
         rt_priority: int = 40, watchdog: float | None = None, ideal_sensors: bool = False) -> int:
    """Run the emulator until SIGINT/SIGTERM; 0 on a clean stop, 2 on bad arguments or link.

    ``rt_priority``: the ``SCHED_FIFO`` priority asked for once the host connects (0: none;
    the loop process asks for 50, so the host's loop comes first on a busy core).

    ``tc_period`` (s) sets the three boards' conversion periods; ``None``: the config's
    ``[sensor]`` periods if any is set, else 0.1 s. ``jitter`` (s): their jitter (``None``:
    the config's). ``truth``: a CSV file for the truth (:class:`TruthWriter`), complete up
    to the last sample sent when the emulator stops. ``watchdog`` (s): the command watchdog
    (default 0.5 s). The boards are a lab's, drawn from ``[sensor]`` seed (``sim.boards``),
    unless ``ideal_sensors`` (then exactly ``[sensor]``).
    """
    cfg = cfg or Config()
    s = cfg.sensor
    if tc_period is None and not (s.period_T_w or s.period_T_p or s.period_T_a):
        tc_period = 0.1
    try:
        sc, specs = check_options(scenario, faults, tc_period, jitter, watchdog)
        core = DeviceCore(cfg, sc, specs, tc_period=tc_period, jitter=jitter,
                          command_timeout=0.5 if watchdog is None else watchdog,
                          lab_boards=not ideal_sensors)
    except (KeyError, ValueError) as e:
        print(f"device-emulator: {e.args[0] if isinstance(e, KeyError) else e}", file=sys.stderr)
        return 2
    writer = None
    if truth is not None:
        try:
            writer = TruthWriter(truth)
        except OSError as e:
            print(f"device-emulator: cannot write the truth file {truth}: {e.strerror or e}", file=sys.stderr)
            return 2
    emu = PtyEmulator(link, core, writer)

    def started() -> None:
        j = core.cfg.sensor.jitter
        if rt_priority > 0 and not emu.priority.startswith("SCHED_FIFO"):
            print(f"device-emulator: running at {emu.priority}: a busy machine may stall the "
                  "emulator (its samples then come late, in a burst)", file=sys.stderr, flush=True)
        print(f"device-emulator: {link} -> {emu.slave_name} (scenario {sc.name}, "
              f"thermocouples every {core.tc_period * 1e3:g} ms"
              + (f" +- {j * 1e3:g} ms" if j else "")
              + (f", faults {', '.join(faults)}" if faults else "")
              + (f", truth to {truth}" if truth is not None else "")
              + f"; {said(core.boards, ideal_sensors)}"
              + "); waiting for the host",
              file=sys.stderr, flush=True)

    def stopped() -> None:
        tm = emu.timing()
        if not tm.get("samples"):
            print("device-emulator: stopped (no host connected)", file=sys.stderr)
            return
        print("device-emulator: stopped after {samples:.0f} samples; lateness mean {mean_us:.0f} µs, "
              "p99 {p99_us:.0f} µs, max (longest stall) {max_us:.0f} µs; {overruns:.0f} samples "
              "sent late (> 50 ms), {lost_samples:.0f} lost, {dropped_frames:.0f} frames "
              "dropped; priority {priority}".format(**tm, priority=emu.priority), file=sys.stderr)
        if core.sessions > 1 or core.refused:
            print(f"device-emulator: {core.sessions} sessions; {core.refused} HELLOs of a second "
                  "host refused while a session was on", file=sys.stderr)
        if core.t_safe == core.t_safe:
            print(f"device-emulator: SAFE from the host took effect at t = {core.t_safe:.3f} s",
                  file=sys.stderr)
        if writer is not None:
            print(f"device-emulator: {writer.rows} truth rows in {truth}", file=sys.stderr)

    return serve_until_stopped(emu, link, writer, rt_priority, started if verbose else None,
                               stopped if verbose else None)


def _cli(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m thermoskin.devices.emulator",
                                 description="simulated skin behind a pseudo-terminal")
    ap.add_argument("--link", required=True, help="symbolic link to create for the pty")
    ap.add_argument("--scenario", default=DEFAULT_SCENARIO, help=f"one of {', '.join(SCENARIOS)}")
    ap.add_argument("--fault", action="append", default=[], metavar="KIND@SECONDS",
                    help=f"inject a fault; KIND one of {', '.join(FAULT_KINDS)}")
    ap.add_argument("--tc-period", type=float, default=None,
                    help="conversion period of the three thermocouple boards, s (default 0.1)")
    ap.add_argument("--jitter", type=float, default=None, help="conversion-instant jitter, s (default 0)")
    ap.add_argument("--ideal-sensors", action="store_true",
                    help="the boards exactly as [sensor] says (default: a lab's, drawn from its seed)")
    ap.add_argument("--truth", default=None, metavar="TRUTH.csv",
                    help="write the truth: t,contact_true,q_i,n_fingers,T_g per sample")
    a = ap.parse_args(argv)
    return main(a.link, a.scenario, a.fault, a.tc_period, jitter=a.jitter, truth=a.truth,
                ideal_sensors=a.ideal_sensors)


if __name__ == "__main__":
    sys.exit(_cli())
