"""Command line: ``thermoskin observe | simulate | run | plot | calibrate | export | replay | ...``.

User errors (a bad log, a bad config, an unknown scenario) print one line,
``thermoskin: error: ...``, and exit with code 2; never a traceback.
"""

from __future__ import annotations

import atexit
import contextlib
import errno
import functools
import gc
import math
import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

# isort: off
import thermoskin._blas  # noqa: F401  (one BLAS thread: before numpy is loaded)
# isort: on
import click
import numpy as np
from rich.console import Console
from rich.table import Table

from thermoskin import __version__, startup
from thermoskin.estimation.events import ContactEvent
from thermoskin.params import Config, ConfigError, load_config
from thermoskin.paths import PathError

if TYPE_CHECKING:
    from thermoskin.sim.scenarios import Scenario


def _freeze_at_exit() -> None:
    """At the command's exit, one collection (what is garbage by then is finalised), then every
    object frozen (``gc.freeze``): the interpreter's teardown, which otherwise collects again and
    again while it clears the modules, traversing every object numba and llvmlite made each
    time, took 0.2 s of a 1 s ``observe`` of a short log; now 0.05 s. Exit handlers all still
    run and the OS takes the memory back. What is still reachable at exit and sits in a
    reference cycle is not finalised: the commands close every file they write explicitly (a
    log, events, a recording), so registered only by the command line's :func:`main`, not for
    a program that merely imports this module."""
    gc.collect()
    gc.freeze()


def freeze_at_exit() -> None:
    """Have the interpreter's exit run :func:`_freeze_at_exit` (once, however often asked: a
    program that runs commands in-process registers it again with each)."""
    atexit.unregister(_freeze_at_exit)
    atexit.register(_freeze_at_exit)


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

        try:
            return fn(*args, **kwargs)
        except (ConfigError, LogError, PathError, UserError) as e:
            msg = " ".join(str(e).split())  # one line, whatever the message held
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


def _outputs(*items: tuple[str, Path | None, Any, str], inputs: tuple[Path, ...] = ()) -> None:
    """Check every output path before any work: ``(option, path, suffixes or None, what)``; no
    two at the same path, and none one of the ``inputs`` (writing it would destroy what is read)."""
    from thermoskin.paths import check_output, distinct, not_an_input

    for option, path, suffixes, what in items:
        if path is not None:
            check_output(path, option, suffixes, what)
            not_an_input(path, option, what, inputs)
    distinct(*((option, path) for option, path, _, _ in items))


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


_NO_ARGS: Any = getattr(click.exceptions, "NoArgsIsHelpError", ())  # click >= 8.2


class _Commands(click.Group):
    """The command group, whose usage errors (a missing argument, an unknown option, a value
    that is not a number) are one line and exit 2, as every other user error."""

    def main(self, *args: Any, **kwargs: Any) -> Any:  # type: ignore[override]
        if kwargs.get("standalone_mode", True) is False:  # a caller handling click's errors
            return super().main(*args, **kwargs)
        try:
            rv = super().main(*args, **{**kwargs, "standalone_mode": False})
        except click.UsageError as e:
            if isinstance(e, _NO_ARGS):  # `thermoskin` alone: the help, as click gives it
                e.show()
                sys.exit(e.exit_code)
            where = e.ctx.command_path if e.ctx is not None else "thermoskin"
            msg = " ".join(e.format_message().split())
            click.echo(f"thermoskin: error: {msg} (see {where} --help)", err=True)
            sys.exit(2)
        except click.ClickException as e:
            e.show()
            sys.exit(e.exit_code)
        except click.Abort:
            click.echo("thermoskin: interrupted", err=True)
            sys.exit(130)
        sys.exit(rv if isinstance(rv, int) else 0)


@click.group(cls=_Commands, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="thermoskin")
def main() -> None:
    """Thermoskin: touch sensing on a soft thermal robot skin (thermal exchange observer)."""
    freeze_at_exit()
    ctx = click.get_current_context()
    command = main.get_command(ctx, ctx.invoked_subcommand) if ctx.invoked_subcommand else None
    if not getattr(getattr(command, "callback", None), "starts_itself", False):
        startup.resume()  # the command's start-up ends here (a run or an emulator may last hours)


CONFIG_OPT = click.option("--config", "config_path", type=click.Path(path_type=Path),
                          default=None, help="TOML file overriding the paper's Table I preset.")


@main.command()
@click.argument("input_csv", type=click.Path(path_type=Path))
@click.option("-o", "--output", "output_csv", type=click.Path(path_type=Path), required=True,
              help="Output log (CSV or Parquet): the input columns plus q_i_hat, dq_i_hat (W), "
                   "contact (0/1) and gap; a log that already had them keeps them as *_live.")
@EVENTS_OPT
@CONFIG_OPT
@click.option("--skin", "skin_path", type=click.Path(path_type=Path), default=None,
              help="A skin of many patches (TOML): INPUT is its long-format log (t,patch,T_w,T_p,v,T_a,"
                   "...); every patch is estimated with its inlet water (the cross-talk of shared water "
                   "removed); events gain patch,position,position_sd; the layout with the contacts is "
                   "drawn beside the output (OUTPUT.png).")
@click.option("--groups", "groups_path", type=click.Path(path_type=Path), default=None,
              help="With --skin: also write the body contacts (events on neighbouring patches "
                   "overlapping in time), one row each.")
@_user_errors
@_starts_itself
def observe(input_csv: Path, output_csv: Path, events_path: Path | None,
            config_path: Path | None, skin_path: Path | None = None, groups_path: Path | None = None) -> None:
    """Estimate the touch heat flow and detect contacts in a recorded log.

    INPUT_CSV (CSV or Parquet) has at least the columns t,T_w,T_p,v,T_a (s, °C, °C, m/s, °C),
    uniformly sampled at 50 Hz to 1 kHz. Each thermocouple's update rate is read from the
    log (its `fresh` column if it has one, else runs of repeated readings); T_w_cmd and drive
    are used if present, as the loop used them, so a log written by `thermoskin run` gives the
    live run's estimates and contacts again. NaN samples are held over (`gap`).
    """
    from thermoskin.analysis.observe import observe_file
    from thermoskin.estimation.freshness import CHANNELS
    from thermoskin.logio import partial_last_line
    from thermoskin.paths import LOG_SUFFIXES

    _outputs(("-o", output_csv, LOG_SUFFIXES, "log"), ("--events", events_path, (".csv",), "events file"),
             ("--groups", groups_path, (".csv",), "groups file"), inputs=(input_csv,))
    cfg = _config(config_path)
    if skin_path is not None:
        _observe_skin(input_csv, output_csv, events_path, groups_path, skin_path, cfg)
        return
    if groups_path is not None:
        raise UserError("--groups needs --skin (a skin of many patches)")
    if partial_last_line(input_csv):
        click.echo(f"thermoskin: warning: {input_csv}: the last line is cut (its writer was stopped "
                   "while writing it): left out", err=True)
    with _progress_bar("observing") as bar:
        task = bar.add_task(f"observing {input_csv.name}", total=None)

        def progress(k: int, n: int | None) -> None:
            startup.resume()  # the kernel is loaded and the first chunk estimated
            bar.update(task, completed=k, total=n)

        note = _compile_note("estimation/kernel.run")

        def compiling() -> None:  # a cold cache: the start-up ends before numba compiles, whose
            startup.resume()      # garbage (millions of objects) must not be frozen
            note()

        res = observe_file(input_csv, output_csv, cfg, progress=progress,
                           characterise=events_path is not None,  # what touched: for the events file
                           compiling=None if note is None else compiling)
    _write_events(events_path, res.events)
    t_s = res.t_s
    for w in res.warnings:
        click.echo(f"thermoskin: warning: {input_csv}: {w}", err=True)
    rates = ", ".join(f"{ch} every {res.periods[ch] * t_s * 1e3:.0f} ms" for ch in CHANNELS)
    show_events(res.events)
    console.print(f"{res.rows} samples at {1 / t_s:.0f} Hz ({rates}), {len(res.events)} contacts, "
                  f"{res.gaps} NaN samples held over; wrote {output_csv}"
                  + (f" and {events_path}" if events_path else ""))
    if res.live_q_max_abs_diff is not None:
        console.print(f"against the log's own estimates: max |q_i_hat difference| "
                      f"{res.live_q_max_abs_diff:.3g} W, {res.live_contact_mismatches or 0} contact "
                      "mismatches")
    if not res.events and res.duration_s < cfg.detector.t_warmup + cfg.detector.t_arm:
        err_console.print(f"thermoskin: warning: the log lasts {res.duration_s:.3g} s, less than "
                          "the detector needs to arm and learn its baseline: no contact can be reported")


def _observe_skin(input_path: Path, output: Path, events_path: Path | None, groups_path: Path | None,
                  skin_path: Path, cfg: Config) -> None:
    """``observe --skin``: every patch of a skin over its long-format log (``skin_observe``),
    streamed (:func:`~thermoskin.skin.observe.observe_skin_file`)."""
    startup.resume()  # a progress of its own (pass 2), after a pass that checks the log
    from thermoskin.skin.layout import load_skin
    from thermoskin.skin.observe import observe_skin_file

    skin = load_skin(skin_path, cfg)
    with _progress_bar("observing") as bar:
        task = bar.add_task(f"observing {input_path.name} on {skin.name}", total=1.0)
        obs = observe_skin_file(input_path, skin, output,  # checked whole before the compile note
                                compiling=_compile_note(skin_kernels(skin, plant=False),
                                                        "the patches' estimators"),
                                progress=lambda f: bar.update(task, completed=f))
    for w in obs.warnings:
        click.echo(f"thermoskin: warning: {input_path}: {w}", err=True)
    _skin_report(skin, obs.events, output.with_suffix(".png"), events_path, groups_path,
                 f"thermoskin observe {input_path.name}")
    console.print(f"{obs.n} samples of {len(skin.patches)} patches at {1 / obs.t_s:.0f} Hz, "
                  f"{len(obs.events)} contacts; wrote {output} and {output.with_suffix('.png')}"
                  + (f", {events_path}" if events_path else "") + (f", {groups_path}" if groups_path else ""))


def _skin_report(skin: Any, events: list[Any], picture: Path, events_path: Path | None,
                 groups_path: Path | None, title: str) -> None:
    """Print a skin's contacts and body contacts; write the events, groups and the layout picture."""
    import math as _m

    from thermoskin.plots.skin import plot_layout
    from thermoskin.skin.groups import group_events, groups_columns, touch_kinds
    from thermoskin.skin.log import write_table
    from thermoskin.skin.observe import events_columns

    groups = group_events(skin, events)
    kinds = touch_kinds(skin, events)
    rows = []
    for e, kind in list(zip(events, kinds, strict=True))[:TABLE_ROWS]:
        ev, pos = e.event, e.position
        rows.append((e.name, f"{ev.onset:.3f}", f"{ev.detected_at:.3f}", f"{ev.release:.3f}", f"{ev.sign:+d}",
                     f"{ev.peak_dq:.3f}", "" if _m.isnan(pos.mean) else f"{pos.mean * 1e3:.1f}",
                     "" if _m.isnan(pos.sd) else f"{pos.sd * 1e3:.1f}", kind))
    show_table(narrow_table("Detected contacts per patch",
                            ("patch", "onset s", "detected s", "release s", "sign", "peak dq W",
                             "position mm", "sd mm", "kind"), rows, text=("kind",)))
    rows = [(str(k), g.link, f"{g.onset:.3f}", f"{g.release:.3f}", "+".join(g.patches),
             f"{g.centre[0] * 1e3:.0f}", f"{g.centre[1] * 1e3:.0f}", f"{g.heat:.3f}")
            for k, g in enumerate(groups[:TABLE_ROWS], 1)]
    show_table(narrow_table("Body contacts (events on neighbouring patches overlapping in time)",
                            ("#", "link", "onset s", "release s", "patches", "x mm", "y mm", "heat W"),
                            rows, text=("link", "patches")))
    try:
        if events_path is not None:
            write_table(events_path, {**events_columns(events), "kind": np.array(kinds, dtype=object)})
        if groups_path is not None:
            write_table(groups_path, groups_columns(groups))
    except OSError as e:
        raise UserError(f"cannot write {e.filename}: {e.strerror or e}") from None
    marks = [{"patch": e.name, "position": e.position.mean, "position_sd": e.position.sd,
              "label": f"{e.event.onset:.1f} s"} for e in events]
    plot_layout(skin, marks, picture, title=f"{title}: {len(events)} contacts on {skin.name}")


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


@main.command()
@click.argument("log_path", type=click.Path(path_type=Path))
@click.option("-o", "--output", "output", type=click.Path(path_type=Path), default=None,
              help="The plot (.png, .pdf or .svg; default: beside the log, LOG.png).")
@click.option("--title", default=None, help="Title (default: the log's file name).")
@_user_errors
def plot(log_path: Path, output: Path | None, title: str | None) -> None:
    """Plot a log (`thermoskin run`, `observe` or `simulate`): its temperatures, estimates,
    truth and commands, with the contacts of its `contact` column shaded.

    A log whose writer was stopped (a killed run) is plotted up to where it ends, with a
    warning saying where that is.
    """
    from thermoskin.logio import LogReader, partial_last_line
    from thermoskin.plots.digest import PlotDigest
    from thermoskin.plots.log import FORMATS, plot_log

    output = output if output is not None else log_path.with_suffix(".png")
    _outputs(("-o", output, FORMATS, "plot"))
    digest: PlotDigest | None = None
    t_first = t_last = math.nan
    rows = contacts = 0
    on = False  # in a contact at the end of the last chunk
    with LogReader(log_path, required=("t",), live=True, one_patch=True) as reader:
        for chunk in reader:  # in chunks: the plot's envelope, whatever the log's length
            t = chunk["t"]
            if digest is None:
                digest = PlotDigest(float(np.median(np.diff(t))) if len(t) > 1 else 1e-3)
                t_first = float(t[0])
            digest.feed(chunk)
            if "contact" in chunk:
                c = np.nan_to_num(np.asarray(chunk["contact"], dtype=float)) > 0.5
                contacts += int(np.count_nonzero(c[1:] & ~c[:-1])) + int(bool(c[0]) and not on)
                on = bool(c[-1])
            rows += len(t)
            t_last = float(t[-1])
    if partial_last_line(log_path):
        click.echo(f"thermoskin: warning: {log_path}: the last line is cut (its writer was stopped "
                   f"while writing it): left out; the log ends at t = {t_last:.3f} s", err=True)
    assert digest is not None  # a log has two rows at least (LogReader checks)
    plot_log(digest.columns(), output, title=title or f"thermoskin: {log_path.name}")
    console.print(f"{rows} samples, t = {t_first:.3f} to {t_last:.3f} s, {contacts} contacts; wrote {output}")


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


#: The Peltier identification experiment, a scenario of ``simulate`` only.
EXCITATION = "excitation"


@main.command()
@click.argument("log_csv", type=click.Path(path_type=Path))
@click.option("-o", "--output", "output_toml", type=click.Path(path_type=Path), required=True,
              help="Config file (TOML) for `run --config`: the identified model as [peltier_model].")
@click.option("--t-model", type=float, default=None,
              help="Model sample time, s (default: chosen from the data, 0.1-1 s).")
@_user_errors
def identify(log_csv: Path, output_toml: Path, t_model: float | None) -> None:
    """Fit a discrete ARX model of T_p against the Peltier drive (columns t, T_p, drive).

    Orders chosen by BIC; the fit is the simulation NRMSE on the last 30 % held back. The
    output is a config file (a [peltier_model] table) that `thermoskin run --config` takes:
    the inner loop then adds the model's steady-state drive as a feed-forward.
    """
    from thermoskin.fit.identify import IdentifyError, save_model
    from thermoskin.fit.identify import identify as fit

    _outputs(("-o", output_toml, (".toml",), "config"))
    log = _read_log(log_csv, ("t", "T_p", "drive"))
    try:
        model = fit(log, t_model=t_model)
    except IdentifyError as e:
        raise UserError(f"{log_csv}: {e}") from None
    from thermoskin.params import PeltierModelParams

    use = "feedforward"
    try:
        PeltierModelParams(use=use, t_s=model.t_s, nk=model.nk, a=tuple(model.a), b=tuple(model.b),
                           c=model.c, d=model.d, with_T_a=model.with_T_a)
    except ConfigError as e:
        use = "off"
        click.echo(f"thermoskin: warning: the model cannot drive the controller ({e}); written with "
                   'use = "off"', err=True)
    save_model(model, output_toml, use=use)
    taus = ", ".join(f"{x:.1f}" for x in model.time_constants())
    console.print(f"ARX model at t_s = {model.t_s:g} s: orders na = {model.na}, nb = {model.nb}, "
                  f"delay nk = {model.nk} ({model.criterion.upper()}); time constants {taus} s; "
                  f"static gain {model.steady_state_gain():.1f} K per unit drive")
    console.print(f"fit on held-back data (last 30 %, simulation): NRMSE {model.nrmse:.3f}, "
                  f"RMSE {model.rmse:.3f} K; estimation part NRMSE {model.nrmse_est:.3f}; "
                  f"wrote {output_toml}")
    if use == "feedforward":
        click.echo(f"{output_toml} is a config for `thermoskin run --config {output_toml}`: its "
                   "[peltier_model] gives the inner loop a feed-forward, the drive that holds "
                   "T_p_cmd in the model's steady state")


@main.command()
@click.argument("log_path", type=click.Path(path_type=Path))
@click.option("--config", "--skin", "config_path", type=click.Path(path_type=Path), default=None,
              help="The skin's config (TOML): the starting values and those held. --skin: a "
                   "single patch's skin file.")
@click.option("-o", "--output", "output_toml", type=click.Path(path_type=Path), required=True,
              help="FITTED.toml: the config with the fitted [skin] values (intervals as comments); "
                   "the fit figure goes beside it as FITTED.png.")
@click.option("--params", default=None,
              help="Comma-separated parameters to fit (default: C_g,R_g,R_aw,R_ag,R_w_flowing,"
                   "R_w_stopped; C_w holds the heat scale).")
@click.option("--truth", "truth_path", type=click.Path(path_type=Path), default=None,
              help="The config a simulated log was made with: adds the true values to the table.")
@click.option("--contact-column", default="contact", show_default=True,
              help="Column flagging touches; its rows (padded) are left out if the log has it.")
@click.option("--t-fit", "t_fit", type=float, default=None,
              help="Fit block means of up to this many seconds (faster; biased where the pump "
                   "chatters) instead of every sample (default).")
@_user_errors
def calibrate(log_path: Path, config_path: Path | None, output_toml: Path, params: str | None,
              truth_path: Path | None, contact_column: str, t_fit: float | None) -> None:
    """Fit the skin's network parameters and R_w to a recorded log (docs/calibration.md).

    LOG_PATH (CSV or Parquet) has t,T_w,T_p,v,T_a, uniformly sampled, no touch (or a
    contact column). Least squares on the network's prediction of T_w from T_p, v, T_a;
    95 % intervals from the Jacobian at the optimum; what the log cannot determine is held
    at the config's value and said so.
    """
    from thermoskin.fit import calibrate as cal_mod
    from thermoskin.logio import read_log
    from thermoskin.plots.calibration import plot_fit

    _outputs(("-o", output_toml, (".toml",), "fitted config"),
             ("-o", output_toml.with_suffix(".png"), (".png",), "fit figure"), inputs=(log_path,))
    if t_fit is not None and not (math.isfinite(t_fit) and t_fit >= 0):
        raise UserError(f"--t-fit {t_fit} must be >= 0 s (0: every sample)")
    cfg = _config(config_path)
    truth = _config(truth_path) if truth_path is not None else None
    names = cal_mod.DEFAULT_PARAMS if params is None else tuple(
        p.strip() for p in params.split(",") if p.strip())
    log = read_log(log_path, required=cal_mod.COLUMNS, one_patch=True,
                   keep=(*cal_mod.COLUMNS, "contact", contact_column))
    if contact_column != "contact" and contact_column not in log:
        raise UserError(f"--contact-column {contact_column}: {log_path} has no such column")
    status = err_console.status("calibrating", spinner="dots") if err_console.is_terminal else None

    def progress(n: int, rms: float) -> None:
        if status is not None and n % 10 == 0:
            status.update(f"calibrating: {n} model runs, residual {rms * 1e3:.2f} mK")

    if status is not None:
        status.start()
    try:
        res = cal_mod.calibrate(log, cfg, names, t_fit=cal_mod.T_FIT if t_fit is None else t_fit,
                                contact=log.get(contact_column), progress=progress)
    except cal_mod.CalibrationError as e:
        raise UserError(f"{log_path}: {e}") from None
    finally:
        if status is not None:
            status.stop()
    v_on = res.blocks.v_modes[res.blocks.v_modes > 0]
    true = cal_mod.prior_values(truth, float(np.median(v_on)) if v_on.size else None) if truth else None
    table = Table(title=f"Skin parameters fitted to {log_path}")
    for col in ("parameter", "prior", "estimate", "95 % interval", *(("true", "in") if true else ()),
                "status"):
        table.add_column(col, justify="left" if col in ("parameter", "status") else "right")
    for p in res.requested:
        lo, hi = res.interval(p)
        ok = math.isfinite(lo) and hi / lo < 1e6
        row = [f"{p} ({cal_mod.UNITS[p]})", f"{res.prior_values[p]:.4g}", f"{res.estimate[p]:.4g}",
               f"[{lo:.4g}, {hi:.4g}]" if ok else "none"]
        if true:
            row += [f"{true[p]:.4g}", ("yes" if lo <= true[p] <= hi else "no") if ok else "-"]
        table.add_row(*row, res.status(p))
    console.print(table)
    if len(res.names) > 1:
        corr = Table(title="Correlation of the fitted ln p")
        corr.add_column("")
        for p in res.names:
            corr.add_column(p, justify="right")
        for p, row in zip(res.names, res.correlation, strict=True):
            corr.add_row(p, *(f"{x:+.2f}" for x in row))
        console.print(corr)
    for line in cal_mod.summary_lines(res):
        console.print(line)
    try:
        cal_mod.save(res, output_toml, source=str(log_path))
        png = plot_fit(res, output_toml.with_suffix(".png"),
                       title=f"thermoskin calibrate {log_path.name}: residual rms "
                             f"{res.rms * 1e3:.2f} mK")
    except OSError as e:
        raise UserError(f"cannot write {e.filename or output_toml}: {e.strerror or e}") from None
    console.print(f"wrote {output_toml} and {png}")


@main.command()
def scenarios() -> None:
    """List the named simulation scenarios."""
    from thermoskin.sim.scenarios import SCENARIOS

    table = Table(title="Scenarios")
    for col in ("name", "duration s", "touches", "pump", "description"):
        table.add_column(col)
    for sc in SCENARIOS.values():
        table.add_row(sc.name, f"{sc.duration:g}", str(len(sc.touches)), sc.pump, sc.description)
    table.add_row(EXCITATION, "600", "0", "off", "the Peltier tank under a rich drive, for "
                  "`thermoskin identify` (simulate only)")
    console.print(table)


@main.command()
@click.option("--scenario", default=None,
              help="Named scenario (see `thermoskin scenarios`; default: fingers, with --skin: multi).")
@DURATION_OPT
@CONFIG_OPT
@click.option("-o", "--output", "output_csv", type=click.Path(path_type=Path), required=True,
              help="Log CSV (measured columns and the simulator's truth q_i, T_g).")
@click.option("--skin", "skin_path", type=click.Path(path_type=Path), default=None,
              help="A skin of many patches (TOML, see examples/forearm.toml): simulated in closed loop, "
                   "one controller per water loop; the log has one row per sample and patch: "
                   "t,patch,T_w,T_p,v,T_a[,T_w2..],q_i,contact_true,position_true,fresh.")
@_user_errors
def simulate(scenario: str | None, duration: float | None, config_path: Path | None,
             output_csv: Path, skin_path: Path | None) -> None:
    """Simulate the skin under a named scenario and write its log."""
    from thermoskin.logio import write_blocks, write_log
    from thermoskin.paths import LOG_SUFFIXES
    from thermoskin.sim.run import simulate_blocks

    _outputs(("-o", output_csv, LOG_SUFFIXES, "log"))
    cfg = _config(config_path)
    if skin_path is not None:
        _simulate_skin(skin_path, "multi" if scenario is None else scenario, duration, cfg, output_csv)
        return
    scenario = "fingers" if scenario is None else scenario
    if scenario == EXCITATION:
        from thermoskin.sim.excitation import simulate_excitation

        dur = 600.0 if duration is None else duration
        _check_duration(dur, cfg.sampling.t_s)
        with _progress_bar("excitation") as bar:
            task = bar.add_task("simulating the Peltier under excitation", total=1.0)
            log = simulate_excitation(cfg, dur, seed=cfg.sensor.seed,
                                      progress=lambda f: bar.update(task, completed=f))
        write_log(output_csv, log)
        console.print(f"simulated {dur:g} s of the Peltier tank under a rich drive "
                      f"({len(log['t'])} samples); wrote {output_csv}")
        return
    sc = _scenario(scenario, duration, cfg.sampling.t_s)
    if duration is None:
        _check_duration(sc.duration, cfg.sampling.t_s, "the scenario's duration")
    with _progress_bar(f"simulating {sc.name}") as bar:
        task = bar.add_task(f"simulating {sc.name}", total=1.0)
        # written block by block (whole or not at all): memory does not follow the length
        blocks = simulate_blocks(sc, cfg, progress=lambda f: bar.update(task, completed=f))
        rows = write_blocks(output_csv, blocks)
    console.print(f"simulated {sc.duration:g} s of '{sc.name}' ({len(sc.touches)} touches, "
                  f"{rows} samples); wrote {output_csv}")


def _simulate_skin(skin_path: Path, scenario: str, duration: float | None, cfg: Config,
                   output: Path) -> None:
    """``simulate --skin``: the skin of many patches in closed loop, its long-format log."""
    from thermoskin.logio import log_format
    from thermoskin.runtime.skin_loop import run_skin
    from thermoskin.sim.skin_scenarios import skin_scenario
    from thermoskin.skin.layout import load_skin

    skin = load_skin(skin_path, cfg)
    log_format(output)
    if duration is not None and not (duration > 0 and math.isfinite(duration)):
        raise UserError(f"--duration {duration} must be > 0 s")
    try:
        sc = skin_scenario(scenario, skin, duration)
    except (KeyError, ValueError) as e:
        raise UserError(str(e).strip("'\"")) from None
    with _progress_bar(f"simulating {sc.name} on {skin.name}") as bar:
        task = bar.add_task(f"simulating {sc.name} on {skin.name}", total=1.0)
        try:
            res = run_skin(skin, sc, output, progress=lambda f: bar.update(task, completed=f))
        except ValueError as e:
            raise UserError(str(e)) from None
        except OSError as e:
            raise UserError(f"cannot write {output}: {e.strerror or e}") from None
    names = ", ".join(f"{p.index} {p.name}" for p in skin.patches)
    console.print(f"simulated {sc.duration:g} s of '{sc.name}' on {skin.name} ({len(skin.patches)} patches "
                  f"on {len(skin.loops)} loops, {len(sc.contacts)} contacts) at "
                  f"{res.realtime_factor:.0f}x real time; {res.n * len(skin.patches)} rows; patch: {names}; "
                  f"wrote {output}")


def _live_options(fn: F) -> F:
    """``--live [HOST:]PORT``, ``--live-rate HZ``, ``--live-wait S`` (see docs/live.md)."""
    from thermoskin.live.address import DEFAULT_ADDRESS

    fn = click.option("--live-wait", "live_wait", type=float, default=0.0, show_default=True,
                      help="With --live: wait up to this many seconds for a viewer to subscribe "
                           "before starting.")(fn)
    fn = click.option("--live-rate", "live_rate", type=float, default=100.0, show_default=True,
                      help="With --live: signals decimated to this rate, Hz of the loop clock.")(fn)
    return click.option("--live", "live_addr", is_flag=False, flag_value=DEFAULT_ADDRESS, default=None,
                        metavar="[HOST:]PORT",
                        help=f"Serve the topics live over the Foxglove WebSocket protocol (default "
                             f"{DEFAULT_ADDRESS}) and a live page on PORT+1.")(fn)  # type: ignore[return-value]


def _live_address(addr: str, rate: float, wait: float) -> tuple[str, int]:
    """``--live``'s ``(host, port)``, and ``--live-rate``, ``--live-wait`` checked: a user error of
    one line, before the command compiles or starts anything (``run`` checks them at once)."""
    from thermoskin.live import LiveError, parse_address

    if not (rate > 0 and math.isfinite(rate)):
        raise UserError(f"--live-rate {rate}: must be > 0 Hz")
    if not (wait >= 0 and math.isfinite(wait)):
        raise UserError(f"--live-wait {wait}: must be >= 0 s")
    try:
        return parse_address(addr)
    except LiveError as e:
        raise UserError(str(e)) from None


def _start_live(addr: str, rate: float, wait: float, cfg: Any,
                view: str = "layout docs/foxglove-layout.json", **kw: Any) -> Any:
    """The live server at ``addr`` (one-line errors), its addresses printed; waits for a viewer.
    ``view``: how to look at it in Foxglove; ``kw``: a skin's ``topics`` and ``params`` (``LiveServer``)."""
    from thermoskin.live import LiveError, LiveServer

    try:
        live = LiveServer(*_live_address(addr, rate, wait), config=cfg, rate=rate, **kw)
    except LiveError as e:
        raise UserError(str(e)) from None
    console.print(f"[bold]live[/]: Foxglove WebSocket {live.ws_url} (Foxglove or Lichtblick: open "
                  f"connection, Foxglove WebSocket; {view}); page "
                  f"{live.page_url}; signals at {rate:g} Hz")
    if wait > 0:
        console.print(f"[bold]live[/]: waiting up to {wait:g} s for a viewer")
        if not live.wait_for_client(wait):
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

#: The patches' estimators' (``run_rows``, the sample step inlined): what `observe --skin`
#: compiles (about 10 s on a cold cache).
SKIN_ESTIMATOR_KERNELS = ("estimation/kernel.new_state", "estimation/kernel.run_rows",
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
@click.option("--realtime", is_flag=True,
              help="Pace the simulated skin at wall-clock speed in the fixed-rate loop process.")
@click.option("--record", "record_path", type=click.Path(path_type=Path), default=None,
              help="Record every signal, command, event and the parameters to this MCAP file.")
@click.option("--probe", "probe_amp", type=float, default=None, metavar="K",
              help="Active sensing (simulated skin): during a contact the set-point steps by +-K "
                   "(a square wave of 2 s from 0.3 s after the detection, for 6 s at most), so "
                   "that the toucher's conductance and temperature separate (docs/characterise.md).")
@_live_options
@click.option("--skin", "skin_path", type=click.Path(path_type=Path), default=None,
              help="Run a whole skin of many patches (TOML) in closed loop on the simulated device "
                   "(scenario default: multi): every patch estimated and its contacts printed as the run "
                   "goes; --live and --record serve / record per-patch topics and a scene (docs/live.md); "
                   "the long-format log, events with patch,position,position_sd, the body contacts "
                   "(--groups) and the layout picture.")
@click.option("--groups", "groups_path", type=click.Path(path_type=Path), default=None,
              help="With --skin: also write the body contacts, one row each.")
@_user_errors
def run(scenario: str, duration: float | None, setpoint: float | None,
        config_path: Path | None, log_path: Path, plot_path: Path | None, events_path: Path | None,
        device: str, realtime: bool, record_path: Path | None, probe_amp: float | None,
        live_addr: str | None, live_rate: float, live_wait: float, skin_path: Path | None = None,
        groups_path: Path | None = None) -> None:
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
        _live_address(live_addr, live_rate, live_wait)
    if skin_path is not None:
        single_only = (device != "sim", realtime, setpoint is not None, probe_amp is not None)
        if any(single_only):
            raise UserError("--skin runs the simulated skin in this process: --device, --realtime, "
                            "--setpoint and --probe are for the single patch")
        _run_skin(skin_path, None if scenario == "fingers" else scenario, duration, config_path, log_path,
                  plot_path, events_path, groups_path, record_path, live_addr, live_rate, live_wait)
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
    console.print(f"[bold]thermoskin run[/]: closed loop on {where}, scenario '{sc.name}'"
                  + (", " if serial else f" ({len(sc.touches)} touches), ")
                  + f"T_w_cmd {cmd_txt}, {sc.duration:g} s at {1 / cfg.sampling.t_s:.0f} Hz")
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

                recorder = Fanout(recorder, _start_live(live_addr, live_rate, live_wait, cfg))
            if recorder is not None:
                recorder.event(0.0, "run-start", device=device, scenario=sc.name,
                               realtime=bool(realtime or serial))
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

            # the same kernel either way: the fixed-rate loop process compiles it as it starts
            # (before it opens the device)
            _note_compile(ESTIMATOR_KERNEL)
            if serial or realtime:
                res = _run_fixed_rate(sc, cfg, device, on_block, stop, on_event)
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
                                          on_block=on_block, stop=stop, probe=probe, keep=False)
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
                              "(README: What touched the skin)")
        stopped = bool(summary.get("interrupted"))
        if n > 1 and not res.fault:
            if serial:
                _tracking(digest.tracking_errors())
            else:
                t_stop = digest.t_last + cfg.sampling.t_s if stopped else math.inf
                _summary(sc, digest.tracking_errors(), res.events, t_stop)
        if serial or realtime:
            _loop_figures(res, n)
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


def _close_log(runlog: Any, path: Path) -> None:
    """Close a run's log (a :class:`~thermoskin.runtime.runlog.RunLog`); a log that got no sample
    goes (no header alone)."""
    runlog.close()
    if runlog.rows == 0:
        path.unlink(missing_ok=True)


def _run_skin(skin_path: Path, scenario: str | None, duration: float | None, config_path: Path | None,
              log_path: Path, plot_path: Path | None, events_path: Path | None,
              groups_path: Path | None, record_path: Path | None = None, live_addr: str | None = None,
              live_rate: float = 100.0, live_wait: float = 0.0) -> None:
    """``run --skin``: the whole skin in closed loop (one controller per water loop,
    ``runtime/skin_loop.py``), every patch estimated and its contacts detected block by block as
    the loop goes (``skin_observe.SkinEstimator``), printed as they come and served live / recorded
    (``runtime/skin_topics.py``); at the end the positions and body contacts from the log
    (``observe_skin_file``, streamed, which gives the live contacts again), the layout picture
    beside the log."""
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
                  f"({len(sc.contacts)} contacts), {sc.duration:g} s; every patch estimated as it goes")
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
                       record_path, live_addr, live_rate, live_wait)
    finally:
        previous.close(wrote=has_rows(log_path))  # no sample on disk: the earlier files back
        stop.restore()
    if stop.is_set():
        why = f"stopped by {stop.name}" if stop.signum else "interrupted"
        click.echo(f"thermoskin: {why}; log, events, picture and recording written up to the stop", err=True)
        sys.exit(stop.exit_code)


def _run_skin_loop(skin: Any, sc: Any, cfg: Config, est: Any, stop: Any, log_path: Path, plot_path: Path,
                   events_path: Path | None, groups_path: Path | None, record_path: Path | None,
                   live_addr: str | None, live_rate: float, live_wait: float) -> None:
    """The body of ``run --skin`` (:func:`_run_skin`) under its stop request."""
    from thermoskin.estimation.events import EventsStream
    from thermoskin.live.skin_topics import figures
    from thermoskin.runtime.skin_loop import run_skin
    from thermoskin.skin.observe import SKIN_EVENT_COLUMNS, SkinEvent, observe_skin_file

    sinks = _skin_sinks(skin, cfg, record_path, live_addr, live_rate, live_wait)
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

            try:
                res = run_skin(skin, sc, log_path, progress=lambda f: bar.update(task, completed=f),
                               on_block=on_block, stop=stop)
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
                live_wait: float) -> list[tuple[Any, Any]]:
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
                               view="a 3D panel on /skin/scene, plots of /patch/NAME/estimate.dq_i_hat")
        except BaseException:
            for s, _ in sinks:
                s.close()
            raise
        sinks.append((live, SkinMessages(skin, live_rate)))
    return sinks


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
        console.print(f"[bold]link[/]: {ln['frames']} frames, {ln['corrupted']} corrupted, "
                      f"{ln['lost']} lost, {ln['repeated']} repeated")


def _run_fixed_rate(sc: Any, cfg: Config, device: str, on_block: Callable[[dict[str, Any]], None],
                    stop: Any, on_event: Callable[[ContactEvent], None] | None = None) -> Any:
    """The fixed-rate loop process; contacts and faults printed as they come."""
    from thermoskin.runtime.realtime import LoopSpec, run_realtime

    state = {"contact": 0, "t_prev": -math.inf}

    def on_rows(block: dict[str, Any]) -> None:
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

    spec = LoopSpec(cfg, sc, device=device, duration=sc.duration)
    res = run_realtime(spec, on_rows=on_rows, stop=stop, on_event=on_event, keep=False)
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


@main.command("device-emulator")
@click.option("--link", "link", type=click.Path(path_type=Path), required=True,
              help="Symbolic link to create, pointing at the emulator's pseudo-terminal.")
@SCENARIO_OPT
@click.option("--fault", "faults", multiple=True, metavar="KIND@SECONDS",
              help="Inject a fault at a device time: tc-open, nan-burst, overtemp, serial-drop, "
                   "tc-stuck (repeatable).")
@click.option("--tc-period", type=float, default=None,
              help="Conversion period of the three thermocouple boards, s [default: 0.1, or the "
                   "config's [sensor] periods if it sets any].")
@click.option("--jitter", type=float, default=None,
              help="Jitter of the boards' conversion instants, s [default: the config's, 0].")
@click.option("--truth", "truth_path", type=click.Path(path_type=Path), default=None,
              help="Write the simulator's truth to this CSV: t,contact_true,q_i,n_fingers,T_g per "
                   "sample, t as in the host's log.")
@CONFIG_OPT
def device_emulator(link: Path, scenario: str, faults: tuple[str, ...], tc_period: float | None,
                    jitter: float | None, truth_path: Path | None, config_path: Path | None) -> None:
    """Run the simulated skin behind a pseudo-terminal speaking docs/protocol.md.

    Makes LINK a symbolic link to the pty, starts its clock when the host first connects,
    and runs until stopped (Ctrl-C, SIGTERM); the link is removed on exit. Connect with
    `thermoskin run --device serial://LINK`. With --truth, the truth file holds every
    sample sent up to the stop.
    """
    from thermoskin.devices.emulator import main as emulator_main
    from thermoskin.paths import check_output

    try:
        cfg = _config(config_path)
        check_output(link, "--link", None, "link")
        if truth_path is not None:
            check_output(truth_path, "--truth", (".csv",), "truth file")
    except (ConfigError, PathError) as e:
        click.echo(f"thermoskin: error: {' '.join(str(e).split())}", err=True)
        sys.exit(2)
    sys.exit(emulator_main(str(link), scenario, list(faults), tc_period, cfg, jitter=jitter,
                           truth=truth_path))


@main.command()
@click.argument("recording", type=click.Path(path_type=Path))
@click.option("-o", "--output", "output", type=click.Path(path_type=Path), required=True,
              help="RUN.parquet or RUN.csv: one row per sample, every signal as a column; "
                   "with --ros2, OUT.mcap.")
@click.option("--ros2", "ros2", is_flag=True,
              help="Write OUT.mcap: every message as a ROS 2 message (CDR, ros2msg schemas), for "
                   "ros2 bag, Foxglove and Lichtblick.")
@_user_errors
def export(recording: Path, output: Path, ros2: bool) -> None:
    """Export an MCAP recording (`thermoskin run --record`) to Parquet or CSV, or (--ros2)
    to an MCAP file of ROS 2 messages.

    Fields that are not numbers become text columns. A damaged recording is exported
    from every intact part, with one warning line per damaged part saying what was lost,
    and the exit code is 4 (0 otherwise; 2 for a user error). A cut-off recording (the
    recorder was killed) is exported up to where it ends, with a warning saying where.
    """
    from thermoskin.runtime.record import RecordingError
    from thermoskin.runtime.record import export as do_export

    if ros2:
        from thermoskin.runtime.ros2 import export_ros2 as do_export
    elif output.suffix.lower() == ".mcap":
        raise UserError(f"cannot export to {output}: an .mcap output needs --ros2 (ROS 2 messages)")
    _outputs(("-o", output, (".mcap",) if ros2 else (".csv", ".parquet"), "output"))
    _recording(recording)
    info: dict[str, Any] = {}
    try:
        out = do_export(recording, output, info=info)
    except RecordingError as e:
        raise UserError(str(e)) from None
    except OSError as e:
        raise UserError(f"cannot write {output}: {e.strerror or e}") from None
    console.print(f"wrote {out}")
    for line in info.get("warnings", ()):
        click.echo(f"thermoskin: warning: {recording}: {line}", err=True)
    _recording_warnings(info["report"])


def _recording(path: Path) -> None:
    """A recording to read: it exists and is a file (one line otherwise)."""
    from thermoskin.paths import check_input

    check_input(path, "recording")


def _recording_warnings(report: Any) -> None:
    """One warning line per damaged part and for a cut-off end; exit 4 if damage cost data."""
    for line in report.lines():
        click.echo(f"thermoskin: warning: {report.path}: {line}", err=True)
    if report.data_lost:
        click.echo(f"thermoskin: {report.path} is damaged: {report.lost_messages} messages lost "
                   f"in {len(report.spans)} damaged part(s); every intact part was used", err=True)
        sys.exit(4)


@main.command()
@click.argument("recording", type=click.Path(path_type=Path))
@click.option("-o", "--output", "output", type=click.Path(path_type=Path), default=None,
              help="CSV: the observer's inputs, the replayed q_i_hat, dq_i_hat, contact, gap and "
                   "the live q_i_hat_live, contact_live (required unless --live).")
@click.option("--config", "config_path", type=click.Path(path_type=Path), default=None,
              help="TOML file to replay with instead of the recorded configuration.")
@_live_options
@click.option("--speed", type=float, default=None,
              help="With --live: play at this factor of real time (default 1).")
@_user_errors
def replay(recording: Path, output: Path | None, config_path: Path | None, live_addr: str | None,
           live_rate: float, live_wait: float, speed: float | None) -> None:
    """Re-run the observer and the detector on a recording; compare with the live estimates.

    Exits with code 1 if the replayed q_i_hat or contact differ from the recorded ones
    (with the recorded configuration they must be identical), and with code 4 if the
    recording is damaged (replayed over its intact parts; one warning line per damaged
    part; the estimates after a lost part cannot be reproduced exactly). With --live, plays
    the recording into the live server (Foxglove WebSocket and page) at real speed or --speed.
    """
    from thermoskin.logio import write_blocks
    from thermoskin.runtime.record import RecordingError, SchemaChangeError, replay_blocks

    if output is None and live_addr is None:
        raise UserError("replay: give -o OUT.csv, --live [HOST:]PORT, or both")
    if speed is not None and live_addr is None:
        raise UserError("--speed plays into the live server: give --live too")
    if speed is not None and not (speed > 0 and math.isfinite(speed)):
        raise UserError(f"--speed {speed}: must be > 0")
    if live_addr is not None:  # a bad address: its one line, before the replay writes anything
        _live_address(live_addr, live_rate, live_wait)
    from thermoskin.paths import LOG_SUFFIXES

    _outputs(("-o", output, LOG_SUFFIXES, "log"))
    _recording(recording)
    if output is None:
        _replay_live(recording, live_addr, live_rate, live_wait, speed or 1.0)
        return
    cfg = _config(config_path) if config_path is not None else None
    info: dict[str, Any] = {}
    cmp: dict[str, Any] = {}

    def blocks(whole: bool) -> Any:
        for b in replay_blocks(recording, cfg, info, cmp, whole=whole):
            out = {k: np.asarray(v, dtype=float) for k, v in b.items()}
            for k in ("contact", "gap", "contact_live"):
                out[k] = out[k].astype(np.int8)
            yield out

    try:
        try:  # block by block: memory does not grow with the recording (whole if its columns change)
            write_blocks(output, blocks(whole=False))
        except SchemaChangeError:
            write_blocks(output, blocks(whole=True))
    except RecordingError as e:
        raise UserError(str(e)) from None
    except OSError as e:
        raise UserError(f"cannot write {output}: {e.strerror or e}") from None
    if cmp["events"]:
        show_events(cmp["events"], title="Replayed contacts")
    same = ("identical to" if cmp["exact"] else
            "equal within 1e-9 W to" if cmp["agrees"] else "DIFFERENT from")
    console.print(f"replayed {cmp['samples']} samples: q_i_hat and contact {same} the live run "
                  f"(max |q_i_hat difference| {cmp['q_i_hat_max_abs_diff']:.3g} W, "
                  f"{cmp['contact_mismatches']} contact mismatches); wrote {output}")
    _recording_warnings(info["report"])
    if live_addr is not None:
        _replay_live(recording, live_addr, live_rate, live_wait, speed or 1.0)
    if not cmp["agrees"] and cfg is None:
        sys.exit(1)


def _replay_live(recording: Path, addr: str, rate: float, wait: float, speed: float) -> None:
    """Play ``recording`` into a live server at ``speed`` times real time."""
    from thermoskin.live import play
    from thermoskin.live.replay import recorded_topics
    from thermoskin.runtime.record import RecordingError

    if not recording.is_file():
        raise UserError(f"recording {recording} does not exist")
    try:
        topics = recorded_topics(recording)
    except RecordingError as e:
        raise UserError(str(e)) from None
    if not topics:
        raise UserError(f"{recording}: no channel recorded (nothing to play)")
    live = _start_live(addr, rate, wait, None, topics=topics)
    try:
        console.print(f"[bold]live[/]: playing {recording} at {speed:g}x")
        res = play(recording, live, speed)
    except RecordingError as e:
        raise UserError(str(e)) from None
    finally:
        live.close()
    cut = "" if res["complete"] else " (the recording was cut short: played what it holds)"
    console.print(f"played {res['sent']} messages ({res['skipped']} signal samples decimated away) "
                  f"from t = {res['t_first']:.3f} to {res['t_last']:.3f} s in {res['wall_s']:.1f} s{cut}")


@main.command()
@click.option("--out", "out_dir", type=click.Path(path_type=Path), default=Path("reproduction"),
              show_default=True, help="Folder for the figures, summary.json and report.md.")
@click.option("--only", default=None,
              help="Comma-separated figures to reproduce, e.g. fig8,fig15 (default: all).")
@_user_errors
def reproduce(out_dir: Path, only: str | None) -> None:
    """Reproduce the paper's Figs. 8 and 12-19 on the simulated skin, with a report."""
    from thermoskin.experiments.reproduce import FIGURES
    from thermoskin.experiments.reproduce import reproduce as run_reproduce
    from thermoskin.paths import check_output_dir

    check_output_dir(out_dir, "--out")
    figs = None
    if only is not None:
        figs = [f.strip() for f in only.split(",") if f.strip()]
        unknown = [f for f in figs if f not in FIGURES]
        if unknown or not figs:
            raise UserError(f"--only {only!r}: unknown figure(s) {', '.join(unknown) or '(none)'}"
                            f" (known: {', '.join(FIGURES)})")
    run_reproduce(out_dir, figs, console=console, progress=_progress_bar)



@main.command()
@click.argument("sweep_toml", type=click.Path(path_type=Path))
@click.option("-o", "--output", "output", type=click.Path(path_type=Path), required=True,
              help="RESULTS.parquet: one row per point (resumed if it exists; refused if it holds other "
                   "points or columns than this sweep's).")
@click.option("--dask", "dask_address", default=None,
              help="Run the chunks on a Dask cluster: its scheduler ADDRESS (tcp://host:8786), "
                   "or 'local' for a local cluster (pip install 'thermoskin[dask]').")
@_user_errors
def sweep(sweep_toml: Path, output: Path, dask_address: str | None) -> None:
    """Run a parameter sweep (docs/sweep.md): every point of SWEEP_TOML, batched.

    Rows are written as chunks finish; a rerun skips the points already written.
    """
    from thermoskin.paths import check_output
    from thermoskin.sweep.run import run_sweep
    from thermoskin.sweep.spec import load_sweep

    check_output(output, "-o", (".parquet",), "results file")
    if dask_address is not None and not dask_address.strip():
        raise UserError("--dask: give a scheduler address (tcp://host:8786) or 'local'")
    sw = load_sweep(sweep_toml)
    _note_compile("sweep/kernel.run_rows", "the sweep's batched simulation", "about 20 s")
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    with Progress(TextColumn("sweep"), BarColumn(), MofNCompleteColumn(), TextColumn("points, left"),
                  TimeRemainingColumn(), console=err_console, transient=True,
                  disable=not err_console.is_terminal) as bar:
        task = bar.add_task("sweep", total=len(sw.points))
        res = run_sweep(sw, output, dask=dask_address,
                        progress=lambda done, total: bar.update(task, completed=done))
    console.print(f"{res.rows} points in {output} ({res.ran} run now in {res.wall_s:.1f} s, "
                  f"{res.skipped} already done)")


@main.command(name="sweep-plot")
@click.argument("results", type=click.Path(path_type=Path))
@click.option("-o", "--output", "output", type=click.Path(path_type=Path), required=True,
              help="PLOT.png")
@click.option("--metric", "metrics", multiple=True,
              help="Metric(s) to draw (repeat; default: every metric in the file).")
@_user_errors
def sweep_plot(results: Path, output: Path, metrics: tuple[str, ...]) -> None:
    """Heat maps (two keys) or parallel coordinates of metrics against a sweep's keys."""
    from thermoskin.paths import check_output
    from thermoskin.plots.sweep import plot_results

    check_output(output, "-o", (".png", ".pdf", ".svg"), "plot")
    plot_results(results, output, list(metrics) or None)
    console.print(f"plot written to {output}")


if __name__ == "__main__":
    main()
