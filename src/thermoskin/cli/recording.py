"""``thermoskin export`` and ``thermoskin replay``: a recording (MCAP) as a table or ROS 2
messages, and the estimator run again on it.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any

import click
import numpy as np

from thermoskin.cli.app import main
from thermoskin.cli.common import (
    UserError,
    _config,
    _live_address,
    _live_options,
    _note_compile,
    _outputs,
    _start_live,
    _user_errors,
    console,
    show_events,
)


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
           live_rate: float, live_wait: float, speed: float | None,
           live_allow_origin: tuple[str, ...] = ()) -> None:
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
        _live_address(live_addr, live_rate, live_wait, live_allow_origin)
    from thermoskin.paths import LOG_SUFFIXES

    _outputs(("-o", output, LOG_SUFFIXES, "log"))
    _recording(recording)
    if output is None:
        _replay_live(recording, live_addr, live_rate, live_wait, speed or 1.0, live_allow_origin)
        return
    cfg = _config(config_path) if config_path is not None else None
    _note_compile("estimation/kernel.run")  # the estimator over each block (TouchEstimator.feed)
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
        _replay_live(recording, live_addr, live_rate, live_wait, speed or 1.0, live_allow_origin)
    if not cmp["agrees"] and cfg is None:
        sys.exit(1)


def _replay_live(recording: Path, addr: str, rate: float, wait: float, speed: float,
                 origins: tuple[str, ...] = ()) -> None:
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
    from thermoskin.runtime.stopping import StopRequest

    stop = StopRequest().install()  # SIGINT, SIGTERM, SIGHUP: the play ends, the server closes
    try:
        live = _start_live(addr, rate, wait, None, topics=topics, origins=origins, stop=stop.is_set)
        try:
            console.print(f"[bold]live[/]: playing {recording} at {speed:g}x")
            res = play(recording, live, speed, stop=stop.is_set)
        except RecordingError as e:
            raise UserError(str(e)) from None
        finally:
            live.close()
    finally:
        stop.restore()
    cut = "" if res["complete"] else " (the recording was cut short: played what it holds)"
    console.print(f"played {res['sent']} messages ({res['skipped']} signal samples decimated away) "
                  f"from t = {res['t_first']:.3f} to {res['t_last']:.3f} s in {res['wall_s']:.1f} s{cut}")
    if stop.is_set():
        click.echo(f"thermoskin: {'stopped by ' + stop.name if stop.signum else 'interrupted'}: the "
                   "replay into the live server ended", err=True)
        sys.exit(stop.exit_code)
