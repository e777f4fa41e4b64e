"""``thermoskin observe`` (one patch or ``--skin``) and ``thermoskin plot``: a recorded log
estimated, its contacts detected and characterised; a log drawn.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import click
import numpy as np

from thermoskin import startup
from thermoskin.cli.app import main
from thermoskin.cli.common import (
    CONFIG_OPT,
    EVENTS_OPT,
    TABLE_ROWS,
    UserError,
    _compile_note,
    _config,
    _outputs,
    _progress_bar,
    _starts_itself,
    _units,
    _units_options,
    _user_errors,
    _write_events,
    console,
    err_console,
    narrow_table,
    show_events,
    show_table,
    skin_kernels,
)
from thermoskin.params import Config


@main.command()
@click.argument("input_csv", type=click.Path(path_type=Path))
@click.option("-o", "--output", "output_csv", type=click.Path(path_type=Path), required=True,
              help="Output log (CSV or Parquet): the input columns plus q_i_hat, dq_i_hat (W), "
                   "contact (0/1) and gap; a log that already had them keeps them as *_live.")
@EVENTS_OPT
@CONFIG_OPT
@click.option("--skin", "skin_path", type=click.Path(path_type=Path), default=None,
              help="LAYOUT.toml, a skin of many patches' layout file (examples/forearm.toml): INPUT "
                   "is its long-format log (t,patch,T_w,T_p,v,T_a,...); every patch is estimated "
                   "with its inlet water (the cross-talk of shared water removed); events gain "
                   "patch,position,position_sd; the layout with the contacts is "
                   "drawn beside the output (OUTPUT.png).")
@click.option("--groups", "groups_path", type=click.Path(path_type=Path), default=None,
              help="With --skin: also write the body contacts (events on neighbouring patches "
                   "overlapping in time), one row each.")
@_units_options
@_user_errors
@_starts_itself
def observe(input_csv: Path, output_csv: Path, events_path: Path | None,
            config_path: Path | None, skin_path: Path | None = None, groups_path: Path | None = None,
            time_unit: str | None = None, temp_unit: str | None = None) -> None:
    """Estimate the touch heat flow and detect contacts in a recorded log.

    INPUT_CSV (CSV or Parquet) has at least the columns t,T_w,T_p,v,T_a (s, °C, °C, m/s, °C),
    uniformly sampled at 50 Hz to 1 kHz. Each thermocouple's update rate is read from the
    log (its `fresh` column if it has one, else runs of repeated readings); T_w_cmd and drive
    are used if present, as the loop used them, so a log written by `thermoskin run` gives the
    live run's estimates and contacts again. NaN samples are held over (`gap`). A log in
    milliseconds or kelvin is read with --time-unit ms, --temp-unit K (the output in s and °C);
    one that looks like them without is refused.
    """
    from thermoskin.analysis.observe import observe_file
    from thermoskin.estimation.freshness import CHANNELS
    from thermoskin.logio import partial_last_line
    from thermoskin.paths import LOG_SUFFIXES

    _outputs(("-o", output_csv, LOG_SUFFIXES, "log"), ("--events", events_path, (".csv",), "events file"),
             ("--groups", groups_path, (".csv",), "groups file"), inputs=(input_csv,))
    cfg = _config(config_path)
    units = _units(time_unit, temp_unit)
    if skin_path is not None:
        _observe_skin(input_csv, output_csv, events_path, groups_path, skin_path, cfg, units)
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

        said: set[str] = set()

        def first(lt: Any) -> None:  # the start: a fingertip below the noise is said at once
            from thermoskin.estimation.learnt import SNR_MIN, snr_line

            if lt.snr == lt.snr and lt.snr < SNR_MIN:
                said.add("snr")
                bar.console.print(f"thermoskin: note: {snr_line(lt.snr, 'this log')}", markup=False)

        res = observe_file(input_csv, output_csv, cfg, progress=progress,
                           characterise=events_path is not None,  # what touched: for the events file
                           compiling=None if note is None else compiling, units=units,
                           on_first=first)
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
    if res.learnt is not None:
        for line in res.learnt.lines():
            console.print(line)
        for key, line in res.notices.items():
            if key not in said:
                console.print(f"thermoskin: note: {line}", markup=False)
    if not res.events and res.duration_s < cfg.detector.t_warmup + cfg.detector.t_arm:
        err_console.print(f"thermoskin: warning: the log lasts {res.duration_s:.3g} s, less than "
                          "the detector needs to arm and learn its baseline: no contact can be reported")


def _observe_skin(input_path: Path, output: Path, events_path: Path | None, groups_path: Path | None,
                  skin_path: Path, cfg: Config, units: Any = None) -> None:
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
                                progress=lambda f: bar.update(task, completed=f), units=units)
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


@main.command()
@click.argument("log_path", type=click.Path(path_type=Path))
@click.option("-o", "--output", "output", type=click.Path(path_type=Path), default=None,
              help="The plot (.png, .pdf or .svg; default: beside the log, LOG.png).")
@click.option("--title", default=None, help="Title (default: the log's file name).")
@_units_options
@_user_errors
def plot(log_path: Path, output: Path | None, title: str | None, time_unit: str | None = None,
         temp_unit: str | None = None) -> None:
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
    with LogReader(log_path, required=("t",), live=True, one_patch=True,
                   units=_units(time_unit, temp_unit)) as reader:
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
