"""The fixed-rate loop: one process of its own, paced at ``t_s`` against absolute deadlines.

The loop process (:func:`_loop_process`) runs, once per sample::

    sleep to (deadline - spin), busy-wait to the deadline       absolute: t0 + k t_s
    s     = dev.read_sample()                                   waits for the device's sample
    code  = supervisor.check(s)                                 bounds, NaN, stuck, stale, link
    if code: dev.safe(); ...; stop                              safe state before anything else
    ctrl.step(s.t, s.T_w, s.T_p, s.T_a, T_w_cmd)                SkinController: the same blocks
    drive, v = supervisor.gate(ctrl.drive, ctrl.v)
    dev.write_command(drive, v)
    ring[k] = (t, T_w, ..., lateness, busy)                     fixed-size float64 row

and nothing else: no logging, no plotting, no JSON, no formatting. The garbage collector
is frozen and disabled after start-up (the loop allocates no reference cycles), the
process asks for ``SCHED_FIFO`` real-time priority and runs without it where that is not
permitted. Rows go into a ring of float64 rows in shared memory (one writer, one reader:
the row first, then the write counter); the parent process (:func:`run_realtime`) drains
it every ~20 ms into the log columns, the recorder and the console. The loop never waits
for the parent: if the parent falls more than the ring behind, rows are lost and counted.

Pacing. With the simulated skin the deadlines are ``t0 + k t_s``. With a serial device
the device's own clock paces the samples: the loop sleeps to ``t0 + t`` with ``t`` the
sample's device time since the first sample and ``t0`` the host time the first sample
arrived; the lateness is the time from a sample's nominal arrival, ``t0_min + t`` with
``t0_min`` the earliest arrival less its device time so far (so never negative), to the
start of its processing (the device's own jitter, transport and host scheduling); the
*lag* is the host's part, from its arrival to the start of processing. The estimator
models each period with the pump velocity and drive the device reports applied over it
(the SAMPLE's ``v``, ``drive``), which are then the log's ``v`` and ``drive``. Samples already
queued (after a late step) are taken at once, so the loop catches up instead of running
behind. (A device clock that drifts against the host's shows as a slow trend of the
lateness; the emulator shares the host's clock.) An *overrun* is a step that ended more
than ``t_s`` after its sample was due and there.

A fault ends the run: the device goes to its safe state first (SAFE frame; the
simulated skin latches drive 0 and pump off), then the fault row is written, and the
summary carries the fault, its device time and the time the safe state was commanded.
"""

from __future__ import annotations

import contextlib
import dataclasses
import gc
import math
import os
import signal
import struct
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from multiprocessing import shared_memory
from typing import Any

import numpy as np
from numpy.typing import NDArray

from thermoskin.devices.base import DeviceError
from thermoskin.estimation.events import ContactEvent
from thermoskin.logio.plausible import admit, limits
from thermoskin.params import Config, SensorParams
from thermoskin.runtime import supervisor as sv
from thermoskin.runtime.closed_loop import COLUMNS, LoopResult
from thermoskin.sim.scenarios import Scenario

#: The fields of a ring row, in order: the log columns of ``closed_loop.COLUMNS`` (truth NaN
#: on hardware), then the device's flags, the loop's timing and the fault code.
ROW = (*COLUMNS,
       "stale", "stuck", "status", "seq", "v_dev", "drive_dev", "late", "lag", "busy", "fault",
       "v_cmd", "drive_cmd")
NF = len(ROW)
_ROW = struct.Struct(f"<{NF}d")
_HDR = struct.Struct("<qqq")  # rows written (loop), stop request (parent), reserved
_COUNT = struct.Struct("<q")
_HDR_BYTES = 64
_I = {k: i for i, k in enumerate(ROW)}


@dataclass
class LoopSpec:
    """What the loop process needs (picklable: it crosses into a new process)."""

    cfg: Config
    scenario: Scenario
    device: str = "sim"
    """``"sim"`` (the simulated skin, paced at wall-clock speed) or ``"serial://PATH"``."""
    duration: float | None = None
    """Seconds of device time (default: the scenario's)."""
    skin_model: str = "network"
    spin_s: float = 2.0e-4
    """Busy-wait before each deadline, s (the sleep before it ends this early)."""
    rt_priority: int = 50
    """``SCHED_FIFO`` priority asked for (0: do not ask)."""
    first_sample_timeout: float = 3.0
    """The longest wait for the session's first sample after its HELLO_ACK, s (the device's
    handshake time: a device answers, then samples at once)."""
    parent_pid: int = 0
    """The process the loop serves (set by :func:`run_realtime`); the loop stops, in the safe
    state, as soon as that process is gone (0: the parent at start-up)."""
    boards: SensorParams | None = None
    """The simulated skin's thermocouple boards as they truly are (``sim.boards``; default: the
    config's ``[sensor]``)."""


class RealtimeResult(LoopResult):
    """A :class:`LoopResult` with the fixed-rate loop's timing (``late``, ``lag``, ``busy``)."""

    @property
    def realtime_factor(self) -> float:
        hist = self.summary.get("timing_hist")
        n = hist.rows if hist is not None else len(self.columns.get("t", ()))
        dur = n * self.summary.get("t_s", 1e-3)
        return dur / self.wall_s if self.wall_s > 0 else math.inf

    def timing(self) -> dict[str, float]:
        """p50/p99/max (µs) of the lateness, the lag (start after the sample was there) and the
        step time; overruns, rows. From the kept columns, or (a run that kept none) from the
        loop's :class:`TimingHistogram`."""
        out: dict[str, float] = {"overruns": float(self.summary.get("overruns", 0)),
                                 "lost_rows": float(self.summary.get("lost_rows", 0))}
        hist = self.summary.get("timing_hist")
        if hist is not None:
            return {"rows": float(hist.rows), **out, **hist.figures()}
        late = self.columns.get("late", np.zeros(0))
        out = {"rows": float(len(late)), **out}
        for name in TIMING:
            x = self.columns.get(name, np.zeros(0))
            x = x[np.isfinite(x)] * 1e6
            if x.size:
                out[f"{name}_p50_us"] = float(np.percentile(x, 50))
                out[f"{name}_p99_us"] = float(np.percentile(x, 99))
                out[f"{name}_max_us"] = float(x.max())
        return out


#: The loop's timing columns (s).
TIMING = ("late", "lag", "busy")


class TimingHistogram:
    """The timing columns of every row, in memory that does not grow with the run: a
    histogram of each over :data:`DECADES` decades of magnitude from 0.1 µs, :data:`PER_DECADE`
    bins a decade, on both sides of zero (a lateness can be negative), and one bin for
    magnitudes of 0.1 µs and below (read as 0); a quantile is within 0.12 % of its value;
    each column's maximum exact."""

    LO = 1e-7
    DECADES = 9
    PER_DECADE = 1000

    def __init__(self) -> None:
        self.half = self.DECADES * self.PER_DECADE  # bins a side; bin ``half`` is zero
        self.counts = {k: np.zeros(2 * self.half + 1, dtype=np.int64) for k in TIMING}
        self.max = dict.fromkeys(TIMING, -math.inf)
        self.rows = 0

    def add(self, rows: NDArray[np.float64]) -> None:
        """Rows of the ring (``ROW`` fields)."""
        self.rows += len(rows)
        h = self.half
        for k in TIMING:
            x = rows[:, _I[k]]
            x = x[np.isfinite(x)]
            if not x.size:
                continue
            a = np.abs(x)
            with np.errstate(divide="ignore", invalid="ignore"):
                m = np.floor(np.log10(np.maximum(a, self.LO) / self.LO) * self.PER_DECADE) + 1
            m = np.where(a <= self.LO, 0, np.minimum(m, h))
            b = (h + np.sign(x) * m).astype(np.int64)
            self.counts[k] += np.bincount(b, minlength=2 * h + 1)
            self.max[k] = max(self.max[k], float(x.max()))

    def quantile(self, name: str, q: float) -> float:
        """The ``q`` quantile (0-1) of column ``name``, s: its bin's geometric centre (0 for the
        zero bin)."""
        c = np.cumsum(self.counts[name])
        if not c[-1]:
            return math.nan
        m = int(np.searchsorted(c, q * c[-1])) - self.half
        if m == 0:
            return 0.0
        return math.copysign(self.LO * 10 ** ((abs(m) - 0.5) / self.PER_DECADE), m)

    def figures(self) -> dict[str, float]:
        """``{name}_p50_us``, ``_p99_us``, ``_max_us`` of each column with samples."""
        out = {}
        for k in TIMING:
            if self.counts[k].any():
                out[f"{k}_p50_us"] = self.quantile(k, 0.5) * 1e6
                out[f"{k}_p99_us"] = self.quantile(k, 0.99) * 1e6
                out[f"{k}_max_us"] = self.max[k] * 1e6
        return out


# ----------------------------------------------------------------------------- loop process

def _set_priority(prio: int) -> str:
    from thermoskin.devices.sched import set_fifo

    return set_fifo(prio)


def _make_device(spec: LoopSpec) -> Any:
    if spec.device == "sim":
        from thermoskin.devices.sim_device import SimDevice

        return SimDevice(spec.cfg, spec.scenario, skin_model=spec.skin_model, boards=spec.boards)
    if spec.device.startswith("serial://"):
        from thermoskin.devices.serial_device import SerialDevice

        s = spec.cfg.safety
        return SerialDevice(spec.device[len("serial://"):], t_s=spec.cfg.sampling.t_s,
                            link_timeout=s.link_timeout_s, stale_after=s.stale_s,
                            stuck_after=max(1, s.stuck_readings))
    raise ValueError(f"unknown device {spec.device!r} (sim or serial://PATH)")


def _warm_up(cfg: Config, T: float) -> None:
    """Step a throw-away loop body so that first-call costs (imports, caches) are paid now."""
    from thermoskin.estimation.estimator import warm_up
    from thermoskin.runtime.controller import SkinController

    c = SkinController(cfg)
    c.reset(T)
    for k in range(20):
        c.step(k * cfg.sampling.t_s, T, T, T, T)
    warm_up(cfg)  # and the fit that dates a contact again at its end


def run_loop(spec: LoopSpec, buf: Any, cap: int,
             on_event: Callable[[ContactEvent], None] | None = None) -> dict[str, Any]:
    """The fixed-rate loop over ``spec.device``; rows into the ring in ``buf``; the summary.
    ``on_event``: each contact as it ends (a few times a minute: not the per-sample path)."""
    from thermoskin.runtime.controller import SkinController

    cfg, sc = spec.cfg, spec.scenario
    t_s = cfg.sampling.t_s
    duration = spec.duration if spec.duration is not None else sc.duration
    n_max = max(1, math.floor(duration / t_s + 1e-9))
    summary: dict[str, Any] = {"t_s": t_s, "fault": sv.OK, "overruns": 0, "rows": 0,
                               "device": spec.device}
    dev = _make_device(spec)
    is_sim = spec.device == "sim"
    ctrl = SkinController(cfg, background_fits=True)  # a contact's re-dating fit in a worker
    sup = sv.Supervisor(cfg)
    lim = limits(cfg.plausible)
    _warm_up(cfg, sc.T_a)
    summary["priority"] = _set_priority(spec.rt_priority)
    cmd_at = sc.T_w_cmd_at
    changes = sorted({0.0, *(t0 for t0, _ in sc.setpoints)})
    pack = _ROW.pack_into
    count_pack = _COUNT.pack_into
    hdr_unpack = _HDR.unpack_from
    mono = time.monotonic
    sleep = time.sleep
    spin = spec.spin_s
    row_bytes = _ROW.size
    nan = math.nan
    truth = getattr(dev, "truth", None)
    plant = getattr(dev, "plant", None)
    pending = getattr(dev, "pending", None)
    faults_seen = 0
    dev_faults = getattr(dev, "faults", None)
    ppid = spec.parent_pid or os.getppid()

    gc.collect()
    if hasattr(gc, "freeze"):
        gc.freeze()
    gc.disable()
    dev.open()  # DeviceError propagates: the parent reports it
    # the re-dating worker's Python between its compiled parts holds the interpreter at most
    # this long while the loop waits for it (the default, 5 ms, is five samples)
    switch = sys.getswitchinterval()
    sys.setswitchinterval(1e-4)
    try:
        s = dev.read_sample(spec.first_sample_timeout)
        if s is None:
            summary.update(fault=sv.LINK, fault_name="link", t_fault=0.0,
                           detail=f"no first sample within {spec.first_sample_timeout:g} s")
            dev.safe()
            return summary
        t_first = s.t
        t0 = mono() if is_sim else s.t_recv  # the host time of device time t_first
        t0_min = t0
        ctrl.reset(s.T_p if (not is_sim and s.T_p == s.T_p) else sc.T_a)
        cmd = cmd_at(0.0)
        k = 0
        overruns = 0
        t_last_arrival = mono()
        code = sv.OK
        t_safe_host = nan
        next_deadline = t0
        try:  # any error on the link (a pulled cable, EIO, a failed write) is a link fault
            while True:
                # ---- the sample of this step (s) is in hand; its nominal arrival, from the
                # earliest arrival so far (t0_min, this sample's included): lateness >= 0
                t_dev = s.t - t_first
                start = mono()
                # the simulated skin's sample is there at its deadline; a device's when it came
                t_avail = t0 + t_dev if is_sim else s.t_recv
                late = start - (t0 + t_dev if is_sim else t0_min + t_dev)
                if changes and t_dev >= changes[0]:
                    cmd = cmd_at(t_dev)
                    changes.pop(0)
                T_w, T_p, T_a = admit(lim, s.T_w, s.T_p, s.T_a)  # implausible readings are no readings
                code = sup.check(s.t, T_w, T_p, T_a, s.stale, s.stuck, s.status)
                if dev_faults is not None and len(dev_faults) > faults_seen:
                    f = dev_faults[faults_seen][1]
                    faults_seen = len(dev_faults)
                    code = sup.device_fault(s.t, f.name, f.value)
                if code:
                    dev.safe()  # safe state before anything else
                    t_safe_host = mono()
                    drive = v = 0.0
                    est = ctrl.estimator
                    q_i_hat, dq, contact, gap = est.q_i_hat, est.dq_i_hat, 0, 1
                    T_p_cmd = ctrl.T_p_cmd
                else:
                    if is_sim:
                        ctrl.step(s.t, T_w, T_p, T_a, cmd, s.fresh)
                    else:  # the estimator models the interval to come with what the device applies
                        ctrl.step(s.t, T_w, T_p, T_a, cmd, s.fresh, s.v, s.drive)
                    drive, v = sup.gate(ctrl.drive, ctrl.v)
                    est = ctrl.estimator
                    if est.written and on_event is not None:
                        for e in est.written:
                            on_event(e)
                    q_i_hat, dq, contact, gap = est.q_i_hat, est.dq_i_hat, ctrl.contact, est.gap
                    T_p_cmd = ctrl.T_p_cmd
                if truth is not None:
                    q_i, T_g, T_wt, T_pt = truth()
                    c_on, n_on = plant.contact()
                    c_true, n_f = float(c_on), float(n_on)
                else:
                    q_i = T_g = T_wt = T_pt = c_true = n_f = nan
                if not code:
                    dev.write_command(drive, v)
                end = mono()
                if end > t_avail + t_s:
                    overruns += 1
                # the log's v and drive: what the estimator modelled (a serial device's applied
                # ones, which observe then reads back); the commands beside them
                v_log, drive_log = (v, drive) if is_sim or code else (s.v, s.drive)
                pack(buf, _HDR_BYTES + (k % cap) * row_bytes, s.t, s.T_w, s.T_p, v_log, s.T_a, cmd, T_p_cmd,
                     drive_log, q_i_hat, dq, contact, gap, s.fresh, q_i, T_g, T_wt, T_pt, c_true, n_f,
                     s.stale, s.stuck, s.status, s.seq, s.v, s.drive, late, start - t_avail, end - start,
                     code, v, drive)
                k += 1
                count_pack(buf, 0, k)
                if code or k >= n_max:
                    break
                # ---- wait for the next deadline, then take the next sample
                if hdr_unpack(buf, 0)[1] or (k & 127 == 0 and os.getppid() != ppid):
                    code = sup.stop(s.t)
                    dev.safe()
                    t_safe_host = mono()
                    break
                next_deadline = t0 + t_dev + t_s
                if pending is None or not pending():
                    rest = next_deadline - mono() - spin
                    if rest > 0.0:
                        sleep(rest)
                    while mono() < next_deadline:
                        pass
                if is_sim:
                    s = dev.read_sample(0.0)
                    if s is None:
                        break
                    continue
                s = dev.read_sample(0.0)
                while s is None:
                    age = mono() - t_last_arrival
                    code = sup.link_lost(next_deadline - t0 + t_first, age)
                    if code:
                        break
                    s = dev.read_sample(min(0.002, sup.link_timeout - age + 1e-4))
                if code:
                    dev.safe()
                    t_safe_host = mono()
                    break
                t_last_arrival = s.t_recv
                # the host time of device time t_first as the earliest arrival allows (the first
                # sample may have come late, from a backlog, as after a second session's HELLO):
                # for the lateness and the reported safe time; pacing keeps t0 (deadlines set by
                # the earliest arrival made the loop wait on the link instead of sleeping to its
                # deadline: more overruns, measured)
                off = s.t_recv - (s.t - t_first)
                if off < t0_min:
                    t0_min = off
        except (OSError, DeviceError) as e:
            why = str(e) if isinstance(e, DeviceError) else f"{type(e).__name__}: {e}"
            code = sup.link_error(mono() - t0 + t_first, why)
            summary["safe_sent"] = _try_safe(dev)  # as far as the link allows
            t_safe_host = mono()
        summary.update(overruns=overruns, rows=k, fault=sup.code, fault_name=sv.FAULTS[sup.code],
                       detail=sup.detail, t_fault=sup.t_fault, fault_value=sup.value,
                       t_safe=(t_safe_host - t0_min + t_first) if t_safe_host == t_safe_host else nan,
                       t_end=s.t if s is not None else nan)
        est = ctrl.estimator
        est.finish(summary["t_end"] if math.isfinite(summary["t_end"]) else (k - 1) * t_s)
        summary["events"] = list(est.events)
        dec = getattr(dev, "decoder", None)
        if dec is not None:
            st = dec.stats
            summary["link"] = {"frames": st.frames, "corrupted": st.corrupted, "lost": st.lost,
                               "repeated": st.repeated, "out_of_order": st.out_of_order}
        return summary
    finally:
        gc.enable()
        sys.setswitchinterval(switch)
        with contextlib.suppress(Exception):
            dev.close()  # safe state, then disconnect


def _try_safe(dev: Any) -> bool:
    """Command the safe state as far as the link allows; whether the command went out."""
    try:
        dev.safe()
    except Exception:
        return False
    return True


_PR_SET_PDEATHSIG = 1


def _die_with_parent(sig: int = signal.SIGTERM) -> None:
    """Ask the kernel to send ``sig`` to this process when its parent dies (Linux prctl)."""
    import ctypes
    import ctypes.util

    with contextlib.suppress(Exception):
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, int(sig), 0, 0, 0)


def _loop_process(spec: LoopSpec, shm_name: str, cap: int, conn: Any) -> None:
    """Entry point of the loop process: run, then send the summary down ``conn``.

    The loop must not outlive the run it serves: the kernel sends it SIGTERM when its
    parent dies (``PR_SET_PDEATHSIG``), SIGTERM and SIGHUP set the stop word (the loop
    then commands the safe state and ends), and the parent's pid, passed in, is checked
    once at start (a parent that died before the ``prctl``) and every 128 samples. SIGINT
    is ignored: a Ctrl-C reaches the whole process group and the parent asks for the stop.
    If the parent is gone at the end, the loop releases the shared memory itself.
    """
    _die_with_parent()
    shm = shared_memory.SharedMemory(name=shm_name)
    views = [shm.buf]  # emptied before the memory is closed

    def stop(signum: int, frame: Any) -> None:
        if views:
            _COUNT.pack_into(views[0], 8, 1)  # the stop word, as the parent sets it

    with contextlib.suppress(ValueError, OSError):
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, stop)
        signal.signal(signal.SIGHUP, stop)
    if spec.parent_pid and os.getppid() != spec.parent_pid:
        stop(0, None)

    def on_event(e: ContactEvent) -> None:  # to the parent, which writes it at once
        with contextlib.suppress(OSError):
            conn.send(("event", e))

    try:
        try:
            summary = run_loop(spec, views[0], cap, on_event)
        except Exception as e:  # reported by the parent as one line
            summary = {"error": f"{type(e).__name__}: {e}",
                       "device_error": isinstance(e, DeviceError)}
        with contextlib.suppress(OSError):  # the parent may be gone (killed)
            conn.send(summary)
            conn.close()
    finally:
        views.clear()
        shm.close()
        if spec.parent_pid and os.getppid() != spec.parent_pid:
            _release(shm)


def _release(shm: shared_memory.SharedMemory) -> None:
    """Unlink the shared memory of a parent that died (``unlink`` also takes it off the
    resource tracker, which would otherwise warn of a leak)."""
    with contextlib.suppress(Exception):
        shm.unlink()


# ----------------------------------------------------------------------------- parent side

class _Columns:
    """Growing float64 columns of the ring's rows."""

    def __init__(self, n_hint: int) -> None:
        self.data = np.empty((max(16, n_hint), NF))
        self.n = 0

    def add(self, rows: NDArray[np.float64]) -> None:
        m = len(rows)
        if self.n + m > len(self.data):
            new = np.empty((max(2 * len(self.data), self.n + m), NF))
            new[: self.n] = self.data[: self.n]
            self.data = new
        self.data[self.n: self.n + m] = rows
        self.n += m

    def columns(self) -> dict[str, NDArray[np.float64]]:
        d = self.data[: self.n]
        return {k: d[:, i].copy() for k, i in _I.items()}


def run_realtime(spec: LoopSpec, *, on_rows: Callable[[dict[str, NDArray[np.float64]]], None] | None = None,
                 ring_rows: int = 1 << 16, poll_s: float = 0.02,
                 stop: Any = None, on_event: Callable[[ContactEvent], None] | None = None,
                 keep: bool = True) -> RealtimeResult:
    """Run the fixed-rate loop in a new process; drain its rows; return the log and summary.

    ``on_rows(block)`` gets each drained block as columns (for the console and the
    recorder); ``on_event(e)`` each contact as it ends (the loop sends it at once, so a
    caller that writes it keeps it even if it is killed later). Ctrl-C (or ``stop``:
    anything with ``is_set()``, polled every drain, e.g. a
    :class:`~thermoskin.runtime.stopping.StopRequest` set by SIGINT, SIGTERM or SIGHUP) asks
    the loop to stop: the device goes to its safe state and the run ends with the rows so
    far (``summary["fault"] == STOPPED``, ``summary["interrupted"]``). ``keep``: the result
    holds every row; False keeps none (``columns`` empty; the timing in a
    :class:`TimingHistogram`), so memory does not grow with the run (``thermoskin run``).
    """
    import multiprocessing as mp

    t_s = spec.cfg.sampling.t_s
    duration = spec.duration if spec.duration is not None else spec.scenario.duration
    n_hint = math.floor(duration / t_s + 1e-9) + 1
    # fork is fast; a process with other threads (an emulator thread in the tests) spawns
    method = "fork" if threading.active_count() == 1 and "fork" in mp.get_all_start_methods() else "spawn"
    ctx = mp.get_context(method)
    shm = shared_memory.SharedMemory(create=True, size=_HDR_BYTES + ring_rows * _ROW.size)
    views = {"hdr": np.ndarray((3,), dtype=np.int64, buffer=shm.buf),
             "ring": np.ndarray((ring_rows, NF), dtype=np.float64, buffer=shm.buf, offset=_HDR_BYTES)}
    hdr = views["hdr"]
    hdr[:] = 0
    recv, send = ctx.Pipe(duplex=False)
    spec = dataclasses.replace(spec, parent_pid=os.getpid())
    proc = ctx.Process(target=_loop_process, args=(spec, shm.name, ring_rows, send),
                       name="thermoskin-loop", daemon=True)
    cols: _Columns | TimingHistogram = _Columns(n_hint) if keep else TimingHistogram()
    read = 0
    lost = 0
    summary: dict[str, Any] | None = None
    wall0 = time.perf_counter()
    interrupted = False

    def drain() -> None:
        nonlocal read, lost
        ring = views["ring"]
        w = int(views["hdr"][0])
        if w <= read:
            return
        if w - read > ring_rows:
            lost += w - read - ring_rows
            read = w - ring_rows
        i0, i1 = read % ring_rows, w % ring_rows
        block = (ring[i0:i1] if i0 < i1 or w - read == 0 else
                 np.concatenate([ring[i0:], ring[:i1]]))
        block = np.array(block)  # copy before the writer comes round
        read = w
        cols.add(block)
        if on_rows is not None:
            on_rows({k: block[:, i] for k, i in _I.items()})

    try:
        proc.start()
        send.close()
        while summary is None:
            try:
                if stop is not None and stop.is_set():
                    hdr[1] = 1
                if recv.poll(poll_s):
                    try:
                        msg = recv.recv()
                    except EOFError:
                        msg = {"error": "the loop process ended without a summary"}
                    if isinstance(msg, tuple):  # ("event", a contact that ended)
                        drain()  # its rows first
                        if on_event is not None:
                            on_event(msg[1])
                        continue
                    summary = msg
                drain()
                if summary is None and not proc.is_alive() and not recv.poll(0):
                    summary = {"error": f"the loop process died (exit code {proc.exitcode})"}
            except KeyboardInterrupt:
                interrupted = True
                hdr[1] = 1
        drain()
    finally:
        if summary is None:  # left on an error here (a log that cannot be written): the loop
            hdr[1] = 1       # stops at once, the device in its safe state, not at its duration
        if proc.pid is not None:
            proc.join(5.0)
        if proc.pid is not None and proc.is_alive():
            proc.terminate()
            proc.join(2.0)
        del hdr
        views.clear()  # no view may outlive the shared memory
        shm.close()
        shm.unlink()
    summary["lost_rows"] = lost
    summary["interrupted"] = interrupted or summary.get("fault") == sv.STOPPED
    wall = time.perf_counter() - wall0
    if isinstance(cols, TimingHistogram):
        summary["timing_hist"] = cols
    return RealtimeResult(columns=cols.columns() if isinstance(cols, _Columns) else {},
                          events=summary.get("events", []),
                          scenario=spec.scenario, wall_s=wall, summary=summary)
