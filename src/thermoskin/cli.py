"""Command line: ``thermoskin observe | simulate | run``.

User errors (a bad log, a bad config, an unknown scenario) print one line,
``thermoskin: error: ...``, and exit with code 2; never a traceback.
"""

from __future__ import annotations

import functools
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import click
import numpy as np
from rich.console import Console
from rich.table import Table

from thermoskin import __version__
from thermoskin.detector import ContactEvent
from thermoskin.params import Config, ConfigError, load_config

F = TypeVar("F", bound=Callable[..., Any])
console = Console(highlight=False)
err_console = Console(stderr=True, highlight=False)


class UserError(Exception):
    """Any other user error with a one-line message."""


def _user_errors(fn: F) -> F:
    """Turn user errors into one line on stderr and exit code 2."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        from thermoskin.logio import LogError

        try:
            return fn(*args, **kwargs)
        except (ConfigError, LogError, UserError) as e:
            err_console.print(f"thermoskin: error: {e}", markup=False)
            sys.exit(2)
        except KeyboardInterrupt:
            err_console.print("thermoskin: interrupted", markup=False)
            sys.exit(130)

    return wrapper  # type: ignore[return-value]


def _config(path: Path | None, preset: str = "paper") -> Config:
    return load_config(path, preset=preset)


def events_table(events: list[ContactEvent], title: str = "Detected contacts") -> Table:
    """The events as a rich table."""
    table = Table(title=title)
    for name in ("#", "onset s", "detected s", "release s", "duration s", "peak dq W",
                 "mean dq W", "energy J"):
        table.add_column(name, justify="right")
    for i, e in enumerate(events, 1):
        table.add_row(str(i), f"{e.onset:.3f}", f"{e.detected_at:.3f}", f"{e.release:.3f}",
                      f"{e.duration:.2f}", f"{e.peak_dq:.4f}", f"{e.mean_dq:.4f}",
                      f"{e.energy:.4f}")
    return table


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="thermoskin")
def main() -> None:
    """Thermoskin: touch sensing on a soft thermal robot skin (thermal exchange observer)."""


CONFIG_OPT = click.option("--config", "config_path", type=click.Path(path_type=Path),
                          default=None, help="TOML file overriding the paper's Table I preset.")


@main.command()
@click.argument("input_csv", type=click.Path(path_type=Path))
@click.option("-o", "--output", "output_csv", type=click.Path(path_type=Path), required=True,
              help="Output CSV: the input columns plus q_i_hat (W) and contact (0/1).")
@CONFIG_OPT
@_user_errors
def observe(input_csv: Path, output_csv: Path, config_path: Path | None) -> None:
    """Estimate the touch heat flow and detect contacts in a recorded log.

    INPUT_CSV has a header and at least the columns t,T_w,T_p,v,T_a (s, °C, °C, m/s, °C),
    uniformly sampled. NaN samples (a loose thermocouple) are held over and flagged in the
    output's ``gap`` column.
    """
    from thermoskin.logio import read_log, sample_time, write_log
    from thermoskin.pipeline import INPUT_COLUMNS, observe as run_observe

    cfg = _config(config_path)
    log = read_log(input_csv, required=INPUT_COLUMNS)
    t_s = sample_time(log["t"])
    res = run_observe(log, cfg, t_s=t_s)
    out = dict(log)
    out.update(res.columns)
    write_log(output_csv, out)
    n_gap = int(np.sum(res.columns["gap"]))
    console.print(events_table(res.events))
    console.print(f"{len(log['t'])} samples at {1 / t_s:.0f} Hz, {len(res.events)} contacts, "
                  f"{n_gap} NaN samples held over; wrote {output_csv}")
