"""What the commands share: one-line user errors (exit 2), the console and its tables,
checks made before any work (outputs, duration, memory), compile notices, options.
"""

from __future__ import annotations

import errno
import functools
import math
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import click
from rich.console import Console
from rich.table import Table

from thermoskin.estimation.events import ContactEvent
from thermoskin.params import Config, ConfigError, load_config
from thermoskin.paths import PathError

if TYPE_CHECKING:
    from thermoskin.sim.scenarios import Scenario



F = TypeVar("F", bound=Callable[..., Any])


console = Console(highlight=False, soft_wrap=True)


err_console = Console(stderr=True, highlight=False, soft_wrap=True)


#: The file system refusing a write (full, over quota, read-only, a drive gone): the user's to fix.
STORAGE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EIO, errno.EFBIG})


class UserError(Exception):
    """Any other user error with a one-line message."""


def _user_errors(fn: F) -> F:
    """Turn user errors into one line on stderr and exit code 2."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        from thermoskin.logio import LogError

        held = len(_LOCKS)
        try:
            return fn(*args, **kwargs)
        except (ConfigError, LogError, PathError, UserError) as e:
            from thermoskin.cli.terminal import one_line

            msg = one_line(str(e))  # one line of at most 400 characters, whatever the message held
            click.echo(f"thermoskin: error: {msg}", err=True)
            sys.exit(2)
        except KeyboardInterrupt:
            click.echo("thermoskin: interrupted", err=True)
            sys.exit(130)
        except OSError as e:
            if e.errno not in STORAGE_ERRNOS:
                raise
            where = f"{e.filename}: " if e.filename else ""
            click.echo(f"thermoskin: error: {where}{e.strerror} (the file system); what was "
                       "written before is kept", err=True)
            sys.exit(2)
        finally:  # the command's outputs are free again (its lock files gone)
            while len(_LOCKS) > held:
                _LOCKS.pop().release()

    return wrapper  # type: ignore[return-value]


def _starts_itself(fn: F) -> F:
    """Mark a command that ends its start-up (:func:`thermoskin.startup.resume`) itself, at
    its first progress, after it has imported and loaded what it needs; every other command's
    ends before it runs (:func:`main`)."""
    fn.starts_itself = True  # type: ignore[attr-defined]
    return fn


def _config(path: Path | None, preset: str = "paper") -> Config:
    return load_config(path, preset=preset)


#: More contacts than this are printed as the first and last few (the rest: --events).
TABLE_ROWS = 40


#: The output locks the command running now holds (:func:`_outputs`), released as it ends.
_LOCKS: list[Any] = []


def _outputs(*items: tuple[str, Path | None, Any, str], inputs: tuple[Path, ...] = ()) -> None:
    """Check every output path before any work: ``(option, path, suffixes or None, what)``; no
    two at the same path, and none one of the ``inputs`` (writing it would destroy what is read);
    then lock each (:func:`thermoskin.paths.lock_output`: one writer per output, a second
    command on the same path refused with the holder's pid) until the command ends."""
    from thermoskin.paths import check_output, distinct, lock_output, not_an_input

    for option, path, suffixes, what in items:
        if path is not None:
            check_output(path, option, suffixes, what)
            not_an_input(path, option, what, inputs)
    distinct(*((option, path) for option, path, _, _ in items))
    ctx = click.get_current_context(silent=True)
    command = f"thermoskin {ctx.info_name}" if ctx is not None else "thermoskin"
    for option, path, _, what in items:
        if path is not None:
            lock = lock_output(path, option, what, command)
            if lock is not None:
                _LOCKS.append(lock)


def _check_loop(cfg: Config) -> None:
    """Refuse, with one line, a configuration the loop's blocks cannot run at (before any output)."""
    from thermoskin.control.mpc import check_step
    from thermoskin.physics.convection import R_w

    check_step(cfg.skin, R_w(cfg.pump.v_on, cfg.skin), cfg.sampling.t_s)


#: Memory a simulated or logged sample takes while a command holds a whole run, bytes (measured:
#: about 430 for `simulate`, 250 for `run`; rounded up).
BYTES_PER_SAMPLE = 500


def _available_memory() -> int:
    """Bytes of memory available to a new allocation (``MemAvailable``), or 4 GiB if unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return 4 << 30


def _size(n: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"):
        if n < 1024 or unit == "EiB":
            return f"{n:.3g} {unit}"
        n /= 1024
    return f"{n:.3g} EiB"


def _check_duration(duration: float, t_s: float, option: str = "--duration") -> None:
    """A finite duration > 0 whose samples fit in this machine's memory, else one line."""
    if not (math.isfinite(duration) and duration > 0):
        raise UserError(f"{option} {duration:g}: must be a finite number of seconds > 0")
    n = duration / t_s
    need = n * BYTES_PER_SAMPLE
    avail = _available_memory()
    if need > 0.8 * avail:
        most = 0.8 * avail / BYTES_PER_SAMPLE * t_s
        raise UserError(f"{option} {duration:g} s is {n:.3g} samples at {1 / t_s:g} Hz, about "
                        f"{_size(need)} in memory: more than this machine has free ({_size(avail)}); "
                        f"at most about {most:.3g} s here")


def _note_compile(where: str | tuple[str, ...], what: str = "the estimator",
                  how_long: str = "about 10 s") -> None:
    """Say so, once, when compiled code (``package/module.function``, or several: any of them)
    is not in numba's cache yet (the first run after an install or an update): compiling takes
    a while, with nothing else to show meanwhile."""
    note = _compile_note(where, what, how_long)
    if note is not None:
        note()


def _compile_note(where: str | tuple[str, ...], what: str = "the estimator",
                  how_long: str = "about 10 s") -> Callable[[], None] | None:
    """What :func:`_note_compile` would print, to print later (once the input has passed its
    checks); None when the code is in the cache."""
    from thermoskin._numba_cache import has_compiled

    if all(has_compiled(w) for w in ((where,) if isinstance(where, str) else where)):
        return None
    return lambda: err_console.print(f"thermoskin: compiling {what} (once after an install or an "
                                     f"update: {how_long}; cached for the next runs)")


def _shown(events: list[ContactEvent], title: str) -> tuple[str, list[tuple[int, ContactEvent]]]:
    """The rows a table shows (a long list: its first and last rows) and its title."""
    if len(events) > TABLE_ROWS:
        half = TABLE_ROWS // 2
        title = f"{title} (the first and last {half} of {len(events)}; all with --events)"
        tail = list(enumerate(events[-half:], len(events) - half + 1))
        return title, list(enumerate(events[:half], 1)) + tail
    return title, list(enumerate(events, 1))


def _what(e: ContactEvent) -> str:
    """What touched, in words: kind, toucher, material (where it says more than the toucher),
    surface temperature; ``?`` where not identifiable."""
    words = [e.kind, e.toucher or "?"]
    if e.material != e.toucher:
        words.append(e.material or "?")
    if math.isfinite(e.T_f_hat):
        words.append(f"{e.T_f_hat:.1f}C")
    return " ".join(words)


def events_table(events: list[ContactEvent], title: str = "Detected contacts",
                 what: bool | None = None) -> Table:
    """The events as a rich table (heat flows signed: negative for heat out, a cold object);
    a long list shows its first and last rows. ``what``: a column of what touched (default:
    where the events are characterised, :mod:`thermoskin.touch.characterise`)."""
    title, shown = _shown(events, title)
    if what is None:
        what = any(e.kind for e in events)
    rows = []
    for i, e in shown:
        rows.append((str(i), f"{e.onset:.3f}", f"{e.detected_at:.3f}", f"{e.release:.3f}",
                     f"{e.duration:.2f}", "+" if e.sign > 0 else "-", f"{e.peak_dq:.3f}",
                     f"{e.mean_dq:.3f}", f"{e.energy:.3f}", *((_what(e),) if what else ())))
    names = ("#", "onset s", "detected s", "release s", "duration s", "sign", "peak dq W", "mean dq W",
             "energy J", *(("what",) if what else ()))
    return narrow_table(title, names, rows, text=("what",))


def show_events(events: list[ContactEvent], title: str = "Detected contacts") -> None:
    """Print the events' table; where they are characterised, what touched in its column if the
    terminal is wide enough for it unbroken, else in a table of its own below (an 80-column
    terminal left it six characters: "glass-ceramic" came out "glass-" and "eramic")."""
    if not any(e.kind for e in events):
        show_table(events_table(events, title, what=False))
        return
    from rich.measure import Measurement

    full = events_table(events, title, what=True)
    wide = console.options.update_width(10_000)  # measured unclamped: the width it needs unbroken
    if Measurement.get(console, wide, full).maximum <= console.width:
        show_table(full)
        return
    show_table(events_table(events, title, what=False))
    show_table(narrow_table("What touched (docs/characterise.md)", ("#", "what"),
                            [(str(i), _what(e)) for i, e in _shown(events, title)[1]], text=("what",)))


def _simple_fingers(sc: Scenario) -> bool:
    """Does the scenario touch the skin with the paper's simple finger (no physical toucher)?"""
    return any(tc.toucher is None for tc in sc.touches)


def show_table(table: Table) -> None:
    """Print a table within the terminal's width (the console soft-wraps long lines otherwise)."""
    console.print(table, soft_wrap=False)


def narrow_table(title: str, names: tuple[str, ...], rows: list[tuple[str, ...]],
                 text: tuple[str, ...] = ()) -> Table:
    """A rich table that keeps its numbers whole in a narrow terminal (80 columns): no rules
    between the columns, each column but those named in ``text`` as wide as its widest cell
    (its header wraps at its spaces), the ``text`` columns wrapping in what is left. Print it
    with :func:`show_table`."""
    from rich import box

    table = Table(title=title, box=box.SIMPLE_HEAD, pad_edge=False, collapse_padding=True)
    for c, name in enumerate(names):
        if name in text:
            table.add_column(name, justify="left", overflow="fold")
        else:
            width = max([len(r[c]) for r in rows] + [len(w) for w in name.split()])
            table.add_column(name, justify="right", min_width=width)
    for r in rows:
        table.add_row(*r)
    return table


EVENTS_OPT = click.option("--events", "events_path", type=click.Path(path_type=Path), default=None,
                          help="Also write the contacts, one row each: onset,detected,release,"
                               "duration,sign,peak_dq,mean_dq,energy (s, s, s, s, +1/-1, W, W, J) "
                               "and what touched: kind,toucher,material,p_human,G_hat,G_sd,T_f_hat,"
                               "T_f_sd,effusivity_hat (empty where not identifiable; "
                               "docs/characterise.md). `observe` characterises the contacts only "
                               "for this file (about 14 ms a contact).")


def _write_events(path: Path | None, events: list[ContactEvent]) -> None:
    if path is None:
        return
    from thermoskin.estimation.events import write_events

    try:
        write_events(path, events)
    except OSError as e:
        raise UserError(f"cannot write {path}: {e.strerror or e}") from None


def _units_options(fn: F) -> F:
    """``--time-unit s|ms|us`` and ``--temp-unit C|K``: the units of a log read (default: seconds
    and °C, a log that looks like another unit refused; :mod:`thermoskin.logio.units`)."""
    fn = click.option("--temp-unit", "temp_unit", type=click.Choice(["C", "K"]), default=None,
                      help="The log's temperatures are in C (degrees Celsius) or K (kelvin, converted). "
                           "Default: C, and a log whose T columns look like kelvin is refused.")(fn)
    return click.option("--time-unit", "time_unit", type=click.Choice(["s", "ms", "us"]), default=None,
                        help="The log's t is in s, ms or us (converted to s). Default: s, and a log "
                             "whose t looks like ms or us (a step of 0.1-10 whole tenths, ...) is "
                             "refused.")(fn)  # type: ignore[return-value]


def _units(time_unit: str | None, temp_unit: str | None) -> Any:
    """:class:`~thermoskin.logio.units.Units` of the two options."""
    from thermoskin.logio.units import Units

    return Units(time_unit, temp_unit)


CONFIG_OPT = click.option("--config", "config_path", type=click.Path(path_type=Path),
                          default=None, help="PARAMS.toml, a parameter file: its tables override the "
                                            "paper's Table I preset (examples/params.toml).")


def _read_log(path: Path, required: Any) -> dict[str, Any]:
    """The columns ``required`` of a whole log (the others read and checked, not held), also
    of one whose writer was stopped mid-line (a killed run): its cut last line is left out
    with one warning line saying where the log ends."""
    from thermoskin.logio import partial_last_line, read_log

    log = read_log(path, required=required, live=True, one_patch=True, keep=required)
    if partial_last_line(path):
        click.echo(f"thermoskin: warning: {path}: the last line is cut (its writer was stopped "
                   f"while writing it): left out; the log ends at t = {float(log['t'][-1]):.3f} s",
                   err=True)
    return log


def _scenario(name: str, duration: float | None, t_s: float = 1e-3) -> Any:
    from thermoskin.sim.scenarios import SCENARIOS

    if name not in SCENARIOS:
        known = ", ".join([*SCENARIOS, EXCITATION])
        raise UserError(f"unknown scenario {name!r} (known: {known})")
    sc = SCENARIOS[name]
    if duration is not None:
        _check_duration(duration, t_s)
        sc = sc.with_duration(duration)
    return sc


def _progress_bar(description: str) -> Any:
    from rich.progress import BarColumn, Progress, TaskProgressColumn, TimeRemainingColumn

    return Progress("[progress.description]{task.description}", BarColumn(),
                    TaskProgressColumn(), TimeRemainingColumn(), console=err_console,
                    transient=True, disable=not err_console.is_terminal)


SCENARIO_OPT = click.option("--scenario", default="fingers", show_default=True,
                            help="Named scenario (see `thermoskin scenarios`).")


DURATION_OPT = click.option("--duration", type=float, default=None,
                            help="Seconds to simulate (default: the scenario's).")

IDEAL_SENSORS_OPT = click.option(
    "--ideal-sensors", "ideal_sensors", is_flag=True,
    help="Simulate the thermocouple boards exactly as [sensor] says (what the estimator is told). "
         "Default: boards as a lab buys them, drawn from [sensor] seed: offsets within +-0.3 K, "
         "noise 0.02-0.05 K, a 1/128 K step, beads lagging 5-30 ms in water and 0.5-1.5 s in air "
         "(sim/boards.py, docs/model.md).")


def _boards(cfg: Any, ideal: bool) -> Any:
    """The simulated boards: ``[sensor]`` itself (``--ideal-sensors``) or a lab's, drawn from its
    seed (``sim.boards.lab_boards``); and a line saying which."""
    from thermoskin.sim.boards import describe, simulated_boards

    b = simulated_boards(cfg.sensor, ideal)
    if ideal:
        return b, "boards: as configured (--ideal-sensors)"
    return b, f"boards as a lab buys them (seed {b.seed}; --ideal-sensors for the configured): {describe(b)}"


#: The Peltier identification experiment, a scenario of ``simulate`` only.
EXCITATION = "excitation"


def _live_options(fn: F) -> F:
    """``--live [HOST:]PORT``, ``--live-rate HZ``, ``--live-wait S`` (see docs/live.md)."""
    from thermoskin.live.address import DEFAULT_ADDRESS

    fn = click.option("--live-wait", "live_wait", type=float, default=0.0, show_default=True,
                      help="With --live: wait up to this many seconds for a viewer to subscribe "
                           "before starting.")(fn)
    fn = click.option("--live-rate", "live_rate", type=float, default=100.0, show_default=True,
                      help="With --live: signals decimated to this rate, Hz of the loop clock.")(fn)
    fn = click.option("--live-allow-origin", "live_allow_origin", multiple=True, metavar="ORIGIN",
                      help="With --live: also serve web pages of this origin (a hosted viewer, e.g. "
                           "https://app.foxglove.dev; * for any). Without it only the live page and "
                           "clients that send no Origin (Foxglove desktop, Lichtblick, scripts) are "
                           "served; other pages get 403.")(fn)
    return click.option("--live", "live_addr", is_flag=False, flag_value=DEFAULT_ADDRESS, default=None,
                        metavar="[HOST:]PORT",
                        help=f"Serve the topics live over the Foxglove WebSocket protocol (default "
                             f"{DEFAULT_ADDRESS}) and a live page on PORT+1.")(fn)  # type: ignore[return-value]


def _live_address(addr: str, rate: float, wait: float, origins: tuple[str, ...] = ()) -> tuple[str, int]:
    """``--live``'s ``(host, port)``, and ``--live-rate``, ``--live-wait``, ``--live-allow-origin``
    checked: a user error of one line, before the command compiles or starts anything (``run``
    checks them at once)."""
    from thermoskin.live import LiveError, parse_address
    from thermoskin.live.gate import allowed_origins

    try:
        allowed_origins(origins)
    except ValueError as e:
        raise UserError(str(e)) from None
    if not (rate > 0 and math.isfinite(rate)):
        raise UserError(f"--live-rate {rate}: must be > 0 Hz")
    if not (wait >= 0 and math.isfinite(wait)):
        raise UserError(f"--live-wait {wait}: must be >= 0 s")
    try:
        return parse_address(addr)
    except LiveError as e:
        raise UserError(str(e)) from None


def _start_live(addr: str, rate: float, wait: float, cfg: Any,
                view: str = "layout docs/foxglove-layout.json", *, origins: tuple[str, ...] = (),
                stop: Callable[[], bool] | None = None, **kw: Any) -> Any:
    """The live server at ``addr`` (one-line errors), its addresses printed; waits for a viewer
    (a wait that ``stop``, a signal's stop request, ends). ``view``: how to look at it in
    Foxglove; ``origins``: ``--live-allow-origin``; ``kw``: a skin's ``topics`` and ``params``
    (``LiveServer``)."""
    from thermoskin.live import LiveError, LiveServer

    try:
        live = LiveServer(*_live_address(addr, rate, wait, origins), config=cfg, rate=rate,
                          allow_origins=origins, stop=stop, **kw)
    except LiveError as e:
        raise UserError(str(e)) from None
    console.print(f"[bold]live[/]: Foxglove WebSocket {live.ws_url} (Foxglove or Lichtblick: open "
                  f"connection, Foxglove WebSocket; {view}); page "
                  f"{live.page_url}; signals at {rate:g} Hz")
    if wait > 0:
        console.print(f"[bold]live[/]: waiting up to {wait:g} s for a viewer")
        if not live.wait_for_client(wait, stop):
            console.print("[bold]live[/]: no viewer yet; starting")
    return live


#: The compiled code a single patch's `run` waits for (in this process, or in the fixed-rate loop
#: process): the estimator's sample step.
ESTIMATOR_KERNEL = "estimation/kernel.step"


#: The compiled functions the skin's plant calls (``package/module.function``), each with its own
#: entry in numba's cache (``_advance`` compiles its ``_push`` and ``_out`` with it). Alone
#: (`simulate --skin`) they compile in about 2 s: nothing to say.
SKIN_PLANT_KERNELS = ("sim/skin_plant._advance", "sim/skin_plant._gather", "sim/skin_plant._scatter",
                      "sim/board_bank._read")


#: The patches' estimators' (``run_rows_fixed``, the sample step inlined; a skin's patches learn
#: nothing of their sensors): what `observe --skin` compiles (about 10 s on a cold cache).
SKIN_ESTIMATOR_KERNELS = ("estimation/kernel.new_state", "estimation/kernel.run_rows_fixed",
                          "estimation/kernel.finish")


#: What `run --skin` compiles: the plant and the estimators.
SKIN_KERNELS = SKIN_PLANT_KERNELS + SKIN_ESTIMATOR_KERNELS


#: What the estimators compile besides when a patch is fed through a pipe (its transport correction).
PIPE_KERNEL = "skin/transport._run"


def skin_kernels(skin: Any, plant: bool = True, estimators: bool = True) -> tuple[str, ...]:
    """The compiled code a command on ``skin`` compiles: the plant's
    (:data:`SKIN_PLANT_KERNELS`), the estimators' (:data:`SKIN_ESTIMATOR_KERNELS`, and
    :data:`PIPE_KERNEL` unless every patch is fed straight from its tank), or both (`run
    --skin`): a skin whose run never compiles the transport correction must not wait for it in
    the cache. (Measured by running each command on an empty ``NUMBA_CACHE_DIR`` and listing it.)"""
    from thermoskin.skin.observe import tank_fed

    out = SKIN_PLANT_KERNELS if plant else ()
    if estimators:
        piped = any(not tank_fed(skin, i) for i in range(len(skin.patches)))
        out += SKIN_ESTIMATOR_KERNELS + ((PIPE_KERNEL,) if piped else ())
    return out
