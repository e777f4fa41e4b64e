"""``thermoskin identify`` (the Peltier's ARX model) and ``thermoskin calibrate`` (the
network's parameters fitted to a no-touch log).
"""

from __future__ import annotations

import math
from pathlib import Path

import click
import numpy as np
from rich.table import Table

from thermoskin.cli.app import main
from thermoskin.cli.common import UserError, _config, _outputs, _read_log, _user_errors, console, err_console
from thermoskin.params import ConfigError


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
@click.option("--config", "config_path", type=click.Path(path_type=Path), default=None,
              help="PARAMS.toml, a parameter file: its [skin] values start the fit and hold what is "
                   "not fitted (default: the paper's Table I).")
@click.option("--skin", "layout_path", type=click.Path(path_type=Path), default=None, hidden=True)
@click.option("-o", "--output", "output_toml", type=click.Path(path_type=Path), required=True,
              help="FITTED.toml: the config with the fitted [skin] and [sensor] values (intervals as "
                   "comments); "
                   "the fit figure goes beside it as FITTED.png.")
@click.option("--params", default=None,
              help="Comma-separated parameters to fit (default: C_g,R_g,R_aw,R_ag,R_w_flowing,"
                   "R_w_stopped and the offsets of the two channels other than the reference; C_w "
                   "holds the heat scale). Also: offset_T_w, offset_T_p, offset_T_a, lag_T_w, lag_T_a.")
@click.option("--lags", default=None,
              help="Also fit these sensors' lags: T_w, T_a or T_w,T_a (a pipe sensor's lag shows at "
                   "the pump's switching, an air sensor's only where the air changes).")
@click.option("--reference", type=click.Choice(["T_w", "T_p", "T_a"]), default="T_w", show_default=True,
              help="The channel whose offset is held at its config value: only the differences "
                   "between the channels' offsets reach the readings.")
@click.option("--truth", "truth_path", type=click.Path(path_type=Path), default=None,
              help="The config a simulated log was made with: adds the true values to the table.")
@click.option("--contact-column", default="contact", show_default=True,
              help="Column flagging touches; its rows (padded) are left out if the log has it.")
@click.option("--t-fit", "t_fit", type=float, default=None,
              help="Fit block means of up to this many seconds (default 0.01; the reading the pump "
                   "switched on a block of its own); 0: every sample.")
@_user_errors
def calibrate(log_path: Path, config_path: Path | None, output_toml: Path, params: str | None,
              lags: str | None, reference: str, truth_path: Path | None, contact_column: str,
              t_fit: float | None, layout_path: Path | None = None) -> None:
    """Fit the skin's network parameters, R_w and the sensors' offsets (and lags, --lags) to a
    recorded log (docs/calibration.md).

    LOG_PATH (CSV or Parquet) has t,T_w,T_p,v,T_a, uniformly sampled, no touch (or a
    contact column; a fresh column gives the boards' conversions). Least squares on the
    network's prediction of the T_w reading from the T_p, v, T_a readings; 95 % intervals
    from the Jacobian at the optimum; what the log cannot determine is held at the config's
    value and said so, and a parameter that runs to a bound is a finding in the table.
    """
    from thermoskin.fit import calibrate as cal_mod
    from thermoskin.logio import read_log
    from thermoskin.plots.calibration import plot_fit

    if layout_path is not None:  # --skin was once another name of --config here
        raise UserError("calibrate fits one patch's parameters: give its parameter file with --config "
                        "(--skin names a skin's layout file, which calibrate does not take)")

    _outputs(("-o", output_toml, (".toml",), "fitted config"),
             ("-o", output_toml.with_suffix(".png"), (".png",), "fit figure"), inputs=(log_path,))
    if t_fit is not None and not (math.isfinite(t_fit) and t_fit >= 0):
        raise UserError(f"--t-fit {t_fit} must be >= 0 s (0: every sample)")
    cfg = _config(config_path)
    truth = _config(truth_path) if truth_path is not None else None
    names = cal_mod.default_params(reference) if params is None else tuple(
        p.strip() for p in params.split(",") if p.strip())
    if lags is not None:
        chans = [c.strip() for c in lags.split(",") if c.strip()]
        bad = [c for c in chans if f"lag_{c}" not in cal_mod.LAGS]
        if bad or not chans:
            raise UserError(f"--lags {lags}: give T_w, T_a or T_w,T_a (the tank sensor's lag is not "
                            "in the model)")
        names = (*names, *(f"lag_{c}" for c in chans))
    log = read_log(log_path, required=cal_mod.COLUMNS, one_patch=True,
                   keep=(*cal_mod.COLUMNS, "contact", "fresh", contact_column))
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
                                contact=log.get(contact_column), reference=reference, progress=progress)
    except cal_mod.CalibrationError as e:
        raise UserError(f"{log_path}: {e}") from None
    finally:
        if status is not None:
            status.stop()
    v_on = res.blocks.v_modes[res.blocks.v_modes > 0]
    true = cal_mod.prior_values(truth, float(np.median(v_on)) if v_on.size else None) if truth else None
    table = Table(title=f"Skin and sensor parameters fitted to {log_path}")
    for col in ("parameter", "prior", "estimate", "95 % interval", *(("true", "in") if true else ()),
                "status"):
        table.add_column(col, justify="left" if col in ("parameter", "status") else "right")
    for p in res.requested:
        lo, hi = res.interval(p)
        ok = math.isfinite(lo) and math.isfinite(hi) and (cal_mod.kind(p) == "offset"
                                                          or hi / max(lo, 1e-300) < 1e6)
        row = [f"{p} ({cal_mod.UNITS[p]})", f"{res.prior_values[p]:.4g}", f"{res.estimate[p]:.4g}",
               f"[{lo:.4g}, {hi:.4g}]" if ok else "none"]
        if true:
            row += [f"{true[p]:.4g}", ("yes" if lo <= true[p] <= hi else "no") if ok else "-"]
        table.add_row(*row, res.status(p))
    console.print(table)
    for p, why in res.findings.items():
        console.print(f"finding: {p} {why}", markup=False)
    if len(res.names) > 1:
        corr = Table(title="Correlation of the fitted ln p (offsets: b)")
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
