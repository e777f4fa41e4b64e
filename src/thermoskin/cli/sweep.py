"""``thermoskin sweep`` and ``thermoskin sweep-plot``: designs simulated in batches, and
their picture.
"""

from __future__ import annotations

from pathlib import Path

import click

from thermoskin.cli.app import main
from thermoskin.cli.common import UserError, _note_compile, _outputs, _user_errors, console, err_console


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
    from thermoskin.sweep.run import run_sweep
    from thermoskin.sweep.spec import load_sweep

    _outputs(("-o", output, (".parquet",), "results file"))  # locked: its parts are this sweep's
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
    from thermoskin.plots.sweep import plot_results

    _outputs(("-o", output, (".png", ".pdf", ".svg"), "plot"))
    for line in plot_results(results, output, list(metrics) or None):
        err_console.print(f"thermoskin: note: {line}")
    console.print(f"plot written to {output}")
