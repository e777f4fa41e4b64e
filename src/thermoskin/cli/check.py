"""``thermoskin check``: a sensor and model check of a log (:mod:`thermoskin.fit.check`)."""

from __future__ import annotations

from pathlib import Path

import click

from thermoskin.cli.app import main
from thermoskin.cli.common import (
    UserError,
    _config,
    _outputs,
    _user_errors,
    console,
    narrow_table,
    show_table,
)


@main.command()
@click.argument("log_path", type=click.Path(path_type=Path))
@click.option("--config", "config_path", type=click.Path(path_type=Path), default=None,
              help="The configuration to check against (TOML; default: the paper's Table I preset).")
@click.option("--write-config", "write_path", type=click.Path(path_type=Path), default=None,
              help="OUT.toml: the configuration with the [sensor] section found in the log "
                   "(offsets, lags, noise, quantum, periods), what was found as comments.")
@click.option("--contact-column", default="contact", show_default=True,
              help="Column flagging touches; its rows (padded) are left out if the log has it.")
@_user_errors
def check(log_path: Path, config_path: Path | None, write_path: Path | None, contact_column: str) -> None:
    """Check a log's sensors and the configured skin against it, in seconds (docs/calibration.md).

    LOG_PATH (CSV or Parquet) has t,T_w,T_p,v,T_a (a fresh column gives the boards' conversions;
    no touch, or a contact column). Per channel: update period, quantum, noise, offset (relative
    to T_w's) and lag; how well the configured skin fits; the SNR a one-finger touch would have;
    and what to do next: calibrate, set a value, or nothing.
    """
    from thermoskin.fit import calibrate as cal
    from thermoskin.fit import check as chk
    from thermoskin.logio import read_log

    _outputs(("--write-config", write_path, (".toml",), "config"), inputs=(log_path,))
    cfg = _config(config_path)
    log = read_log(log_path, required=cal.COLUMNS, one_patch=True,
                   keep=(*cal.COLUMNS, "fresh", "T_w_cmd", "contact", contact_column))
    if contact_column != "contact" and contact_column not in log:
        raise UserError(f"--contact-column {contact_column}: {log_path} has no such column")
    try:
        rep = chk.check(log, cfg, contact=log.get(contact_column))
    except chk.CheckError as e:
        raise UserError(f"{log_path}: {e}") from None
    show_table(narrow_table(f"Sensors in {log_path} (95 % half-widths; * kept as configured)",
                            chk.TABLE, chk.table_rows(rep)))
    for line in (*chk.notes(rep), *chk.summary_lines(rep)):
        console.print(line, markup=False)
    console.print("Next:", style="bold")
    for line in rep.advice:
        console.print(f"- {line}", markup=False)
    if write_path is not None:
        try:
            chk.save(rep, cfg, write_path, source=str(log_path))
        except OSError as e:
            raise UserError(f"cannot write {e.filename or write_path}: {e.strerror or e}") from None
        console.print(f"wrote {write_path}")
