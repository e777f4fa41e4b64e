"""``thermoskin reproduce``: the paper's experiments, figures and report.
"""

from __future__ import annotations

from pathlib import Path

import click

from thermoskin.cli.app import main
from thermoskin.cli.common import UserError, _note_compile, _progress_bar, _user_errors, console


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
    _note_compile(("estimation/kernel.step", "estimation/kernel.finish"))
    run_reproduce(out_dir, figs, console=console, progress=_progress_bar)
