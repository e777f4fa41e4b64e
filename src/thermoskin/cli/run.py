"""``thermoskin run``: the closed loop on the simulated skin, in process or paced at
wall-clock speed, or on hardware through the serial protocol; a skin of many patches with
``--skin``.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import click
import numpy as np

from thermoskin.cli.app import main
from thermoskin.cli.common import (
    CONFIG_OPT,
    DURATION_OPT,
    ESTIMATOR_KERNEL,
    EVENTS_OPT,
    IDEAL_SENSORS_OPT,
    SCENARIO_OPT,
    UserError,
    _boards,
    _check_duration,
    _check_loop,
    _config,
    _live_address,
    _live_options,
    _note_compile,
    _outputs,
    _progress_bar,
    _scenario,
    _simple_fingers,
    _start_live,
    _user_errors,
    _write_events,
    console,
    show_events,
    skin_kernels,
)
from thermoskin.cli.observe import _skin_report
from thermoskin.estimation.events import ContactEvent
from thermoskin.params import Config, SensorParams

#: Samples a paced ``run --skin`` steps between two looks at the wall clock (0.1 s at 1 kHz).
PACED_BLOCK = 100

#: Seconds the closed loop gets to bring the skin from ambient to its command before the
#: scenario's touches begin.
SETTLE_S = 10.0


@main.command()
@SCENARIO_OPT
@DURATION_OPT
@click.option("--setpoint", type=float, default=None,
              help="Water-temperature command T_w_cmd, degC (default: the scenario's).")
@CONFIG_OPT
@click.option("--log", "log_path", type=click.Path(path_type=Path), default=Path("run.csv"),
              show_default=True, help="Where to save the log.")
@click.option("--plot", "plot_path", type=click.Path(path_type=Path), default=None,
              help="Where to save the plot (default: beside the log, LOG.png).")
@EVENTS_OPT
@click.option("--device", default="sim", show_default=True,
              help="sim (the simulated skin in this process) or serial://PATH (a device or "
                   "`thermoskin device-emulator` speaking docs/protocol.md).")
@click.option("--realtime/--no-realtime", default=None,
              help="Pace the simulated skin at wall-clock speed (one patch: in the fixed-rate loop "
                   "process); the default with --live, so that a viewer sees the run as it goes. "
                   "--no-realtime: as fast as it computes.")
@click.option("--record", "record_path", type=click.Path(path_type=Path), default=None,
              help="Record every signal, command, event and the parameters to this MCAP file.")
@click.option("--probe", "probe_amp", type=float, default=None, metavar="K",
              help="Active sensing (simulated skin): during a contact the set-point steps by +-K "
                   "(a square wave of 2 s from 0.3 s after the detection, for 6 s at most), so "
                   "that the toucher's conductance and temperature separate (docs/characterise.md).")
@_live_options
@click.option("--skin", "skin_path", type=click.Path(path_type=Path), default=None,
              help="Run a whole skin of many patches (LAYOUT.toml, its layout file: examples/forearm.toml) "
                   "in closed loop on the simulated device "
                   "(scenario default: multi): every patch estimated and its contacts printed as the run "
                   "goes; --live and --record serve / record per-patch topics and a scene (docs/live.md); "
                   "the long-format log, events with patch,position,position_sd, the body contacts "
                   "(--groups) and the layout picture.")
@click.option("--groups", "groups_path", type=click.Path(path_type=Path), default=None,
              help="With --skin: also write the body contacts, one row each.")
@IDEAL_SENSORS_OPT
@_user_errors
def run(scenario: str, duration: float | None, setpoint: float | None,
        config_path: Path | None, log_path: Path, plot_path: Path | None, events_path: Path | None,
        device: str, realtime: bool | None, record_path: Path | None, probe_amp: float | None,
        live_addr: str | None, live_rate: float, live_wait: float, skin_path: Path | None = None,
        groups_path: Path | None = None, live_allow_origin: tuple[str, ...] = (),
        ideal_sensors: bool = False) -> None:
    """Run the whole skin in closed loop: the simulated skin (default) or a serial device.

    From ambient, the MPC and the inner loop bring T_w to its command while the observer
    and the detector run every sample; the scenario's touches start after a settling time.
    Use --scenario none for no touch. With --device serial://PATH or --realtime the loop
    runs at t_s against absolute deadlines in a process of its own. The log is written as
    the run goes (a CSV is flushed at least every second, so a killed run keeps it to
    within a second); the plot is drawn from the log at the end (`thermoskin plot LOG`
    draws it again).

    Exit codes: 0 done; 2 a user error (nothing run, nothing written); 3 a fault (the
    safety supervisor: T_p bounds, touch-safe surface limit, sensor faults, the link lost
    or failing): the device is put in its safe state (Peltier drive 0, pump off), one line
    says why, log, plot and recording are written; start a new run to restart. SIGINT
    (Ctrl-C), SIGTERM and SIGHUP stop the run the same clean way (safe state, log, plot,
    a complete recording) and exit with 130, 143 and 129 (128 + the signal number).
    """
    from thermoskin.paths import LOG_SUFFIXES
    from thermoskin.plots.log import FORMATS, plot_log
    from thermoskin.runtime.closed_loop import COLUMNS, TRUTH, run_closed_loop
    from thermoskin.runtime.digest import RunDigest
    from thermoskin.runtime.runlog import RunLog
    from thermoskin.runtime.stopping import StopRequest

    if live_addr is not None:  # a bad address: its one line, before any compile notice
        _live_address(live_addr, live_rate, live_wait, live_allow_origin)
    if realtime is None:  # a live view watches the run at its own pace; a run alone goes flat out
        realtime = live_addr is not None and device == "sim"
    if skin_path is not None:
        single_only = (device != "sim", setpoint is not None, probe_amp is not None)
        if any(single_only):
            raise UserError("--skin runs the simulated skin in this process: --device, --setpoint and "
                            "--probe are for the single patch")
        _run_skin(skin_path, None if scenario == "fingers" else scenario, duration, config_path, log_path,
                  plot_path, events_path, groups_path, record_path, live_addr, live_rate, live_wait,
                  paced=realtime, live_origins=live_allow_origin)
        return
    if groups_path is not None:
        raise UserError("--groups needs --skin (a skin of many patches)")
    serial = device.startswith("serial://")
    if device != "sim" and not serial:
        raise UserError(f"--device {device!r}: must be sim or serial://PATH")
    if serial and len(device) <= len("serial://"):
        raise UserError("--device serial://PATH: the path is missing")
    port = device[len("serial://"):] if serial else ""
    if port and "://" not in port and not os.path.exists(port):
        # at once, not after the loop process has compiled the estimator (about 10 s on a cold cache)
        raise UserError(f"cannot open {port}: no such device or file")
    if plot_path is None:
        plot_path = log_path.with_suffix(".png")
    _outputs(("--log", log_path, LOG_SUFFIXES, "log"), ("--plot", plot_path, FORMATS, "plot"),
             ("--events", events_path, (".csv",), "events file"),
             ("--record", record_path, (".mcap",), "recording"))
    probe = None
    if probe_amp is not None:
        from thermoskin.control.probe import SetpointProbe

        if serial or realtime:
            raise UserError("--probe: only with the simulated skin in this process (--device sim, "
                            "no --realtime)")
        try:
            probe = SetpointProbe(A=probe_amp)
        except ValueError as e:
            raise UserError(f"--probe {probe_amp}: {str(e).split(': ', 1)[1]}") from None
    cfg = _config(config_path)
    _check_loop(cfg)
    sc = _scenario(scenario, None)
    if not sc.setpoints:
        sc = sc.shifted(SETTLE_S)
    if setpoint is not None:
        lo, hi = cfg.control.T_p_min, cfg.control.T_p_max
        if not lo <= setpoint <= hi:
            raise UserError(f"--setpoint {setpoint} is out of range: T_w_cmd must be within "
                            f"the T_p_cmd bounds [{lo:g}, {hi:g}] degC")
        sc = sc.with_setpoint(setpoint)
    if duration is not None:
        _check_duration(duration, cfg.sampling.t_s)
        sc = sc.with_duration(duration)
    cmd_txt = (", ".join(f"{c:g} degC from {t0:g} s" for t0, c in sc.setpoints)
               if sc.setpoints else f"{sc.T_w_cmd:g} degC")
    where = (f"the device at {device[len('serial://'):]}" if serial else
             "the simulated skin" + (" at wall-clock speed" if realtime else ""))
    # what the configured sensors should give (a short simulation: before the first line, which
    # a caller may take for the loop's start); it runs the estimator first, so a cold cache
    # compiles it here: said before (it was silent for 10 s on a fresh install)
    _note_compile(("estimation/kernel.run", ESTIMATOR_KERNEL))
    watch = _SensorWatch(cfg, sc)
    console.print(f"[bold]thermoskin run[/]: closed loop on {where}, scenario '{sc.name}'"
                  + (", " if serial else f" ({len(sc.touches)} touches), ")
                  + f"T_w_cmd {cmd_txt}, {sc.duration:g} s at {1 / cfg.sampling.t_s:.0f} Hz")
    boards = None
    if not serial:  # the simulated skin's boards (paced or not)
        boards, said = _boards(cfg, ideal_sensors)
        console.print(said, markup=False)
    if watch.start_line:
        console.print(watch.start_line, markup=False)
    names = [k for k in COLUMNS if not serial or k not in TRUTH]
    from thermoskin.logio import has_rows
    from thermoskin.paths import Replaced

    previous = Replaced(log_path, plot_path, events_path, record_path)
    stop = StopRequest().install()
    try:
        recorder = None
        if record_path is not None:
            from thermoskin.runtime.record import LoopRecorder, RecordingError

            try:
                recorder = LoopRecorder(record_path, cfg)
            except RecordingError as e:
                raise UserError(str(e)) from None
        runlog: RunLog | None = None
        res = None
        evstream = None
        digest = RunDigest(cfg)  # the plot, tracking and what touched, as the log is written
        try:
            if live_addr is not None:
                from thermoskin.live import Fanout

                recorder = Fanout(recorder, _start_live(live_addr, live_rate, live_wait, cfg,
                                                        origins=live_allow_origin, stop=stop.is_set))
            if recorder is not None:
                recorder.event(0.0, "run-start", device=device, scenario=sc.name,
                               realtime=bool(realtime or serial),
                               estimator_inputs="device" if serial else "commands")
            try:
                runlog = RunLog(log_path, names)
            except OSError as e:
                raise UserError(f"cannot write {log_path}: {e.strerror or e}") from None
            if events_path is not None:  # each contact as it ends; the whole table at the end
                from thermoskin.estimation.events import EventsStream

                try:
                    evstream = EventsStream(events_path)
                except OSError as e:
                    raise UserError(f"cannot write {events_path}: {e.strerror or e}") from None

            from thermoskin.logio import LogError

            def on_block(block: dict[str, Any]) -> None:
                for line in watch.feed(block):  # what the readings teach of the sensors, once each
                    console.print(f"thermoskin: note: {line}", markup=False)
                try:
                    runlog.write(block)  # type: ignore[union-attr]
                    if recorder is not None:
                        recorder.write_rows(block)
                    digest.feed(block)
                except (LogError, OSError) as e:  # a full disk, a drive gone: stop (safe state)
                    msg = (str(e) if isinstance(e, LogError) else
                           f"cannot write {e.filename or 'the recording'}: {e.strerror or e}")
                    raise UserError(f"{msg}; the run stopped there (a device in its safe state), "
                                    "its outputs keep what was written before") from None

            def on_event(e: ContactEvent) -> None:
                if evstream is not None:
                    evstream.add(e)
                digest.event(e)

            # (the estimator's kernel, which the fixed-rate loop process too loads as it starts, was
            # asked for and said above, before the sensors' watch ran it)
            if serial or realtime:
                res = _run_fixed_rate(sc, cfg, device, on_block, stop, on_event, boards)
            else:
                with _progress_bar("running") as bar:
                    task = bar.add_task("closed loop", total=1.0)

                    def started(t: float) -> None:
                        bar.console.print(f"  t = {t:7.3f} s  contact detected")

                    def ended(e: ContactEvent) -> None:
                        on_event(e)
                        bar.console.print(f"  t = {e.release:7.3f} s  released after {e.duration:.2f} s, "
                                          f"peak dq {e.peak_dq * 1e3:.1f} mW, mean {e.mean_dq * 1e3:.1f} mW")

                    res = run_closed_loop(sc, cfg, on_start=started, on_event=ended,
                                          progress=lambda f: bar.update(task, completed=f),
                                          on_block=on_block, stop=stop, probe=probe, keep=False,
                                          boards=boards)
            if recorder is not None:
                _record_end(recorder, res, digest.t_last if digest.rows else 0.0)
        finally:  # each output closed whatever the others do (a full disk under one of them)
            with contextlib.ExitStack() as closing:
                if runlog is not None:
                    closing.callback(_close_log, runlog, log_path)
                if recorder is not None:
                    closing.callback(recorder.close)
                if evstream is not None:
                    closing.callback(evstream.close)
            if res is None and recorder is not None and getattr(recorder, "rows", 1) == 0:
                record_path.unlink(missing_ok=True)  # type: ignore[union-attr]
        summary = res.summary
        n = runlog.rows if runlog is not None else 0
        if n:
            plot_log(digest.columns(), plot_path, title=f"thermoskin run: {sc.name}, closed loop")
        events = digest.events(res.events)  # what touched
        _write_events(events_path, events)
        if events:
            show_events(events)
            if not serial and any(e.kind for e in events) and _simple_fingers(sc):
                console.print("what: the scenario's fingers are the paper's simple finger (a body held "
                              "at its temperature), which the characteriser, made for people and "
                              "objects as they are, may call an object; --scenario touchers has both "
                              "(docs/characterise.md)")
        stopped = bool(summary.get("interrupted"))
        if n > 1 and not res.fault:
            if serial:
                _tracking(digest.tracking_errors())
            else:
                t_stop = digest.t_last + cfg.sampling.t_s if stopped else math.inf
                _summary(sc, digest.tracking_errors(), res.events, t_stop)
        if serial or realtime:
            _loop_figures(res, n)
        for line in watch.summary():
            console.print(line, markup=False)
        wrote = f"wrote {log_path} and {plot_path}" if n else "no samples"
        if events_path is not None:
            wrote += f", {events_path}"
        if record_path is not None:
            wrote += f" and {record_path}"
        console.print(f"{n * cfg.sampling.t_s:g} s in {res.wall_s:.1f} s "
                      f"({res.realtime_factor:.1f}x real time); {wrote}")
    finally:
        previous.close(wrote=has_rows(log_path))  # no sample on disk: the earlier files back
        stop.restore()
    if res.fault:
        t_f, t_safe = summary.get("t_fault", math.nan), summary.get("t_safe", math.nan)
        safe = (f"safe state (Peltier drive 0, pump off) commanded at t = {t_safe:.3f} s"
                if summary.get("safe_sent", True) else
                "the safe state could not be sent (the link is down): the device's own command "
                "watchdog stops it")
        click.echo(f"thermoskin: fault: {res.fault} at t = {t_f:.3f} s ({summary.get('detail', '')}); "
                   f"{safe}; restart with a new `thermoskin run`", err=True)
        sys.exit(3)
    if stopped:
        why = f"stopped by {stop.name}" if stop.signum else "interrupted"
        outs = ["log", "plot"] + (["events"] if events_path is not None else []) + (
            ["recording"] if record_path is not None else [])
        click.echo(f"thermoskin: {why} at t = {n * cfg.sampling.t_s:.3f} s; the device is in its "
                   f"safe state; {', '.join(outs[:-1])} and {outs[-1]} written", err=True)
        sys.exit(stop.exit_code)


class _SensorWatch:
    """What the run's readings teach of its sensors, said as it goes and summed up at the end.

    At the start, the one-finger SNR the configured sensors should give (``sim.expected``: a
    fingertip below their noise is said at once). Then a second estimator follows the log's rows
    as they are written (the live one's kernel on the same rows: the same state, bit for bit, as
    ``observe`` of the log), and what it learns is said once each (``estimation.learnt.Watch``:
    a fingertip below the readings' noise, readings that do not fit the model, an offset, a lag
    or a noise unlike the configured ones)."""

    def __init__(self, cfg: Config, sc: Any) -> None:
        from thermoskin.estimation.estimator import TouchEstimator
        from thermoskin.estimation.learnt import SNR_MIN, Watch, snr_line
        from thermoskin.sim.expected import expected

        self.est = TouchEstimator(cfg.replace(detector={"redate_readings": 0.0}))
        self.watch = Watch(cfg)
        self.cfg = cfg
        self.t_next = 0.0
        self.rows = 0
        lt = expected(cfg, T_w_cmd=sc.T_w_cmd_at(0.0))
        self.start_line = ""
        if lt.snr == lt.snr and lt.snr < SNR_MIN:
            self.watch.said.add("snr")
            self.start_line = f"thermoskin: note: {snr_line(lt.snr, 'the configured sensors')}"

    def feed(self, block: dict[str, Any]) -> list[str]:
        """A block of the log's rows; the notices to say now."""
        if "T_w" not in block or not len(block["t"]):
            return []
        cols = {k: np.asarray(block[k], dtype=float) for k in ("t", "T_w", "T_p", "v", "T_a")}
        self.est.feed(cols["t"], cols["T_w"], cols["T_p"], cols["v"], cols["T_a"],
                      T_w_cmd=block.get("T_w_cmd"), fresh=block.get("fresh"), drive=block.get("drive"))
        self.rows += len(cols["t"])
        t = float(cols["t"][-1])
        if t < self.t_next:
            return []
        self.t_next = t + 1.0
        return self.watch.new(self.est.st, t)

    def summary(self) -> list[str]:
        """What was learnt by the run's end, and what it says not said before."""
        if not self.rows:
            return []
        lt = self.est.learnt()
        out = list(lt.lines())
        from thermoskin.estimation.learnt import notices

        out += [f"thermoskin: note: {line}" for key, line in notices(lt, self.cfg).items()
                if key not in self.watch.said]
        return out


def _close_log(runlog: Any, path: Path) -> None:
    """Close a run's log (a :class:`~thermoskin.runtime.runlog.RunLog`); a log that got no sample
    goes (no header alone)."""
    runlog.close()
    if runlog.rows == 0:
        path.unlink(missing_ok=True)


def _run_skin(skin_path: Path, scenario: str | None, duration: float | None, config_path: Path | None,
              log_path: Path, plot_path: Path | None, events_path: Path | None,
              groups_path: Path | None, record_path: Path | None = None, live_addr: str | None = None,
              live_rate: float = 100.0, live_wait: float = 0.0, paced: bool = False,
              live_origins: tuple[str, ...] = ()) -> None:
    """``run --skin``: the whole skin in closed loop (one controller per water loop,
    ``runtime/skin_loop.py``), every patch estimated and its contacts detected block by block as
    the loop goes (``skin_observe.SkinEstimator``), printed as they come and served live / recorded
    (``runtime/skin_topics.py``); at the end the positions and body contacts from the log
    (``observe_skin_file``, streamed, which gives the live contacts again), the layout picture
    beside the log. ``paced``: at wall-clock speed (``--realtime``, the default with ``--live``)."""
    from thermoskin.paths import LOG_SUFFIXES
    from thermoskin.sim.skin_scenarios import skin_scenario
    from thermoskin.skin.layout import load_skin
    from thermoskin.skin.observe import SkinEstimator, board_warnings

    if plot_path is None:
        plot_path = log_path.with_suffix(".png")
    _outputs(("--log", log_path, LOG_SUFFIXES, "log"), ("--plot", plot_path, (".png",), "picture"),
             ("--events", events_path, (".csv",), "events file"),
             ("--groups", groups_path, (".csv",), "groups file"),
             ("--record", record_path, (".mcap",), "recording"))
    cfg = _config(config_path)
    skin = load_skin(skin_path, cfg)
    if duration is not None:
        _check_duration(duration, cfg.sampling.t_s)
    try:
        sc = skin_scenario(scenario or "multi", skin, duration)
    except (KeyError, ValueError) as e:
        raise UserError(str(e).strip("'\"")) from None
    console.print(f"[bold]thermoskin run --skin[/]: {skin.name} ({len(skin.patches)} patches on "
                  f"{len(skin.loops)} loops) in closed loop on the simulated skin, scenario '{sc.name}' "
                  f"({len(sc.contacts)} contacts), {sc.duration:g} s"
                  + (" at wall-clock speed" if paced else "") + "; every patch estimated as it goes")
    from thermoskin.runtime.stopping import StopRequest

    period = skin.cfg.sensor.period_T_w  # the simulated boards'
    for w in board_warnings(skin, 1.0 / max(period, cfg.sampling.t_s)):
        click.echo(f"thermoskin: warning: {w}", err=True)
    _note_compile(skin_kernels(skin), "the skin's plant and the estimator")
    est = SkinEstimator(skin, cfg.sampling.t_s)
    from thermoskin.logio import has_rows
    from thermoskin.paths import Replaced

    previous = Replaced(log_path, plot_path, events_path, groups_path, record_path)
    stop = StopRequest().install()
    try:
        _run_skin_loop(skin, sc, cfg, est, stop, log_path, plot_path, events_path, groups_path,
                       record_path, live_addr, live_rate, live_wait, paced, live_origins)
    finally:
        previous.close(wrote=has_rows(log_path))  # no sample on disk: the earlier files back
        stop.restore()
    if stop.is_set():
        why = f"stopped by {stop.name}" if stop.signum else "interrupted"
        click.echo(f"thermoskin: {why}; log, events, picture and recording written up to the stop", err=True)
        sys.exit(stop.exit_code)


def _run_skin_loop(skin: Any, sc: Any, cfg: Config, est: Any, stop: Any, log_path: Path, plot_path: Path,
                   events_path: Path | None, groups_path: Path | None, record_path: Path | None,
                   live_addr: str | None, live_rate: float, live_wait: float, paced: bool = False,
                   live_origins: tuple[str, ...] = ()) -> None:
    """The body of ``run --skin`` (:func:`_run_skin`) under its stop request; ``paced``: each
    block of :data:`PACED_BLOCK` samples waits for its end on the wall clock."""
    from thermoskin.estimation.events import EventsStream
    from thermoskin.live.skin_topics import figures
    from thermoskin.runtime.skin_loop import run_skin
    from thermoskin.skin.observe import SKIN_EVENT_COLUMNS, SkinEvent, observe_skin_file

    sinks = _skin_sinks(skin, cfg, record_path, live_addr, live_rate, live_wait, live_origins, stop)
    P = len(skin.patches)
    names = [p.name for p in skin.patches]
    width = max(len(n) for n in names)
    evstream = None
    try:
        if events_path is not None:  # each contact as it ends (no position yet); the table at the end
            try:
                evstream = EventsStream(events_path, (*SKIN_EVENT_COLUMNS, "kind"), fill_kind=False)
            except OSError as e:
                raise UserError(f"cannot write {events_path}: {e.strerror or e}") from None
        for sink, msgs in sinks:
            sink.event(0.0, "run-start", device="sim", scenario=sc.name, skin=skin.name)
            for topic, t, m in msgs.start():
                sink.publish(topic, t, m)
        with _progress_bar("running") as bar:
            task = bar.add_task("closed loop", total=1.0)
            wall0 = time.monotonic()

            def on_block(block: dict[str, Any]) -> None:
                m = len(block["t"]) // P
                cols = {k: np.asarray(v).reshape(m, P) for k, v in block.items() if k not in ("t", "patch")}
                t = np.asarray(block["t"])[::P]
                b = est.block(t, cols)
                for c in b.changes:
                    if c.on:
                        bar.console.print(f"  t = {c.t:7.3f} s  {names[c.patch]:<{width}}  contact detected "
                                          f"({c.sign:+d})")
                    elif c.event is not None:
                        e = c.event
                        if evstream is not None:
                            evstream.add_row(SkinEvent(c.patch, names[c.patch], e).row())
                        bar.console.print(f"  t = {c.t:7.3f} s  {names[c.patch]:<{width}}  released after "
                                          f"{e.duration:.2f} s (onset {e.onset:.3f} s), peak dq "
                                          f"{e.peak_dq * 1e3:.0f} mW")
                    else:
                        bar.console.print(f"  t = {c.t:7.3f} s  {names[c.patch]:<{width}}  withdrawn "
                                          "(over at once, no reading confirmed it: noise, no event)")
                for sink, msgs in sinks:
                    for topic, tt, msg in msgs.messages(t, cols, b):
                        sink.publish(topic, tt, msg)
                if paced:  # the block's last sample is due at its time on the wall clock
                    ahead = wall0 + float(t[-1]) - time.monotonic()
                    if ahead > 0.0 and not stop.is_set():
                        time.sleep(ahead)  # a block's worth at most: a signal's stop waits no longer

            try:
                res = run_skin(skin, sc, log_path, progress=lambda f: bar.update(task, completed=f),
                               on_block=on_block, stop=stop, **({"block": PACED_BLOCK} if paced else {}))
            except OSError as e:
                raise UserError(f"cannot write {log_path}: {e.strerror or e}") from None
        t_end = max(res.n - 1, 0) * cfg.sampling.t_s
        est.finish(t_end)
        for sink, _ in sinks:
            for i, e in sorted(est.events, key=lambda x: (x[1].onset, x[0])):
                sink.event(e.onset, "contact", patch=names[i], **figures(e))
            sink.event(t_end, "run-end", wall_s=res.wall_s)
    finally:
        if evstream is not None:
            evstream.close()
        for sink, _ in sinks:
            sink.close()
    if res.n < 2:  # stopped before two samples: nothing to estimate from
        console.print(f"{res.n} samples; wrote {log_path}" if res.n else
                      "no sample: an earlier run's files at these paths are kept as they were")
        return
    obs = observe_skin_file(log_path, skin, None)  # streamed: an hour's run is read back in blocks
    live = sorted(((i, e) for i, e in est.events), key=lambda x: (x[1].onset, x[0]))
    if live != [(e.patch, e.event) for e in obs.events]:  # one estimator: never, unless a bug
        click.echo(f"thermoskin: warning: the contacts estimated from {log_path} differ from the live ones "
                   f"({len(obs.events)} against {len(live)})", err=True)
    _skin_report(skin, obs.events, plot_path, events_path, groups_path, f"thermoskin run --skin {sc.name}")
    track = ", ".join(f"{lp.name} {e:.3f} K" for lp, e in zip(skin.loops, res.tracking, strict=True))
    console.print(f"{res.n * cfg.sampling.t_s:g} s in {res.wall_s:.1f} s ({res.realtime_factor:.1f}x "
                  f"real time, the closed loop and the live estimation); mean |T_w - T_w_cmd| over the "
                  f"second half: {track}; "
                  f"{len(obs.events)} contacts; "
                  f"wrote {log_path} and {plot_path}" + (f", {events_path}" if events_path else "")
                  + (f", {groups_path}" if groups_path else "") + (f", {record_path}" if record_path else ""))


class _RecorderSink:
    """A :class:`~thermoskin.runtime.record.Recorder` with the live server's ``publish``."""

    def __init__(self, rec: Any) -> None:
        self.rec = rec

    def publish(self, topic: str, t: float, data: Any) -> None:
        self.rec.write(topic, t, data)

    def event(self, t: float, kind: str, **detail: Any) -> None:
        self.rec.event(t, kind, **detail)

    def close(self) -> None:
        self.rec.close()


def _skin_sinks(skin: Any, cfg: Config, record_path: Path | None, live_addr: str | None, live_rate: float,
                live_wait: float, live_origins: tuple[str, ...] = (),
                stop: Any = None) -> list[tuple[Any, Any]]:
    """The recording (every sample) and the live server (decimated) of a skin's run, each with its
    :class:`~thermoskin.live.skin_topics.SkinMessages`."""
    from thermoskin.live.skin_topics import SkinMessages, layout, skin_topics

    sinks: list[tuple[Any, Any]] = []
    topics = skin_topics(skin)
    params = {"skin": layout(skin)}
    if record_path is not None:
        from thermoskin.runtime.record import Recorder, RecordingError

        try:
            rec = Recorder(record_path, cfg, schemas=topics, params=params)
        except RecordingError as e:
            raise UserError(str(e)) from None
        sinks.append((_RecorderSink(rec), SkinMessages(skin)))
    if live_addr is not None:
        try:
            live = _start_live(live_addr, live_rate, live_wait, cfg, topics=topics, params=params,
                               origins=live_origins, stop=None if stop is None else stop.is_set,
                               view="a 3D panel on /skin/scene, plots of /patch/NAME/estimate.dq_i_hat")
        except BaseException:
            for s, _ in sinks:
                s.close()
            raise
        sinks.append((live, SkinMessages(skin, live_rate)))
    return sinks


LATE_S = 0.05
"""A sample handled later than this after its nominal arrival counts as late (the link timeout)."""


def _loop_figures(res: Any, n: int) -> None:
    """The fixed-rate loop's timing and the link's figures."""
    summary = res.summary
    tm = res.timing()
    g = dict.fromkeys(("late_p50_us", "late_p99_us", "late_max_us", "busy_p99_us", "lag_p50_us",
                       "lag_p99_us", "lag_max_us"), math.nan) | tm
    console.print(f"[bold]loop[/]: {n} steps; lateness p50 {g['late_p50_us']:.0f} µs, "
                  f"p99 {g['late_p99_us']:.0f} µs, max {g['late_max_us']:.0f} µs (host lag p50 "
                  f"{g['lag_p50_us']:.0f}, p99 {g['lag_p99_us']:.0f}, max {g['lag_max_us']:.0f} µs); "
                  f"step p99 {g['busy_p99_us']:.0f} µs; {tm['overruns']:.0f} overruns, "
                  f"{tm['lost_rows']:.0f} rows lost; priority {summary.get('priority', '?')}")
    if "link" in summary:
        ln = summary["link"]
        late = summary.get("late_counts", {})
        console.print(f"[bold]link[/]: {ln['frames']} frames, {ln['corrupted']} corrupted, "
                      f"{ln['lost']} lost, {ln['repeated']} repeated; {late.get('device', 0)} frames "
                      f"late from the device, {late.get('host', 0)} samples handled more than "
                      f"{LATE_S * 1e3:g} ms late")
        if (late.get("host", 0) or ln["lost"]) and not res.fault:  # a fault: its own line says
            click.echo(f"thermoskin: warning: the link fell behind: {late.get('device', 0)} frames the "
                       f"device sent late, {late.get('host', 0)} samples this host handled more than "
                       f"{LATE_S * 1e3:g} ms late (longest {g['late_max_us'] / 1e3:.0f} ms), "
                       f"{ln['lost']} frames lost, {tm['overruns']:.0f} loop overruns: the estimates "
                       "and contacts follow the device's clock and the outputs it applied, the control "
                       "acted late; a busy host (give the loop real-time priority: docs/runtime.md)",
                       err=True)


def _run_fixed_rate(sc: Any, cfg: Config, device: str, on_block: Callable[[dict[str, Any]], None],
                    stop: Any, on_event: Callable[[ContactEvent], None] | None = None,
                    boards: SensorParams | None = None) -> Any:
    """The fixed-rate loop process; contacts and faults printed as they come."""
    from thermoskin.devices.protocol import ST_OVERRUN
    from thermoskin.runtime.realtime import LoopSpec, run_realtime

    state = {"contact": 0, "t_prev": -math.inf}
    late = {"device": 0, "host": 0}

    def on_rows(block: dict[str, Any]) -> None:
        late["device"] += int(np.count_nonzero(block["status"].astype(np.int64) & ST_OVERRUN))
        late["host"] += int(np.count_nonzero(block["late"] > LATE_S))
        c = block["contact"]
        f = block["fault"]
        t = block["t"]
        for i in np.flatnonzero(np.diff(np.concatenate([[state["contact"]], c])) != 0):
            if not f[i]:
                console.print(f"  t = {t[i]:7.3f} s  contact " + ("detected" if c[i] else "released"))
        if len(c):
            ok = f == 0
            if ok.any():
                state["contact"] = int(c[ok][-1])
        on_block(block)

    spec = LoopSpec(cfg, sc, device=device, duration=sc.duration, boards=boards)
    res = run_realtime(spec, on_rows=on_rows, stop=stop, on_event=on_event, keep=False)
    res.summary["late_counts"] = late
    err = res.summary.get("error")
    if err:
        if res.summary.get("device_error"):
            raise UserError(err.removeprefix("DeviceError: "))
        raise UserError(f"the loop process failed: {err}")
    return res


def _record_end(recorder: Any, res: Any, t_end: float) -> None:
    """Contacts, the fault and the loop's figures on /events (``t_end``: the last row's ``t``)."""
    import dataclasses

    for e in res.events:
        detail = dataclasses.asdict(e)
        detail["touch_kind"] = detail.pop("kind")  # ``kind`` names the record's kind
        recorder.event(e.onset, "contact", **detail)
    s = res.summary
    if res.fault:
        recorder.event(s.get("t_fault", t_end), "fault", name=res.fault, detail=s.get("detail", ""),
                       value=s.get("fault_value", math.nan), t_safe=s.get("t_safe", math.nan))
    timing = res.timing() if hasattr(res, "timing") else {}
    recorder.event(t_end, "run-end", wall_s=res.wall_s,
                   priority=s.get("priority", ""), **timing)


def _tracking(segments: Sequence[Any], with_T_p_cmd: bool = False) -> None:
    """Tracking over the last minute (or half) of each command
    (:class:`~thermoskin.analysis.evaluation.Tracking` each)."""
    for seg in segments:
        bounds = (f"; T_p_cmd within [{seg.T_p_cmd_min:.2f}, {seg.T_p_cmd_max:.2f}] degC"
                  if with_T_p_cmd else "")
        console.print(f"[bold]tracking[/] T_w_cmd {seg.T_w_cmd:g} degC: mean |error| "
                      f"{seg.mean_abs_error:.3f} K, mean error {seg.mean_error:+.3f} K over "
                      f"{seg.t0:.1f}-{seg.t1:.1f} s{bounds}")


def _summary(sc: Any, segments: Sequence[Any], events: list[ContactEvent], t_stop: float = math.inf) -> None:
    """Tracking of each command (with T_p_cmd's range); touches vs detections (a run stopped
    at ``t_stop`` scores only the touches it could tell)."""
    from thermoskin.analysis.evaluation import match_events

    _tracking(segments, with_T_p_cmd=True)
    m = match_events(sc.touches, events, t_end=t_stop)
    lat = m.latencies
    lat_txt = (f"onset latency median {np.median(lat) * 1e3:.0f} ms, max {np.max(lat) * 1e3:.0f} ms"
               if len(lat) else "no latency (nothing detected)")
    n_scored = len(sc.touches) - m.not_scored
    cut = (f" before the stop at t = {t_stop:.3f} s ({m.not_scored} more after it or cut by it, not "
           "counted)" if math.isfinite(t_stop) else "")
    console.print(f"[bold]summary[/]: {n_scored} touches scripted{cut}, {m.hits} detected, "
                  f"{m.misses} missed, {m.false_alarms} false alarms; {lat_txt}")
