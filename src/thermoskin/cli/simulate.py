"""``thermoskin scenarios`` and ``thermoskin simulate`` (one patch or ``--skin``): the
simulated skin's log, truth included.
"""

from __future__ import annotations

import math
from pathlib import Path

import click
from rich.table import Table

from thermoskin.cli.app import main
from thermoskin.cli.common import (
    CONFIG_OPT,
    DURATION_OPT,
    EXCITATION,
    IDEAL_SENSORS_OPT,
    UserError,
    _boards,
    _check_duration,
    _config,
    _outputs,
    _progress_bar,
    _scenario,
    _user_errors,
    console,
)
from thermoskin.params import Config


@main.command()
def scenarios() -> None:
    """List the named simulation scenarios: a patch's (`run`, `simulate`; on a skin of many
    patches, `--skin`, they touch its first patch) and a skin's (`--skin` only)."""
    from thermoskin.sim.scenarios import SCENARIOS
    from thermoskin.sim.skin_scenarios import SKIN_SCENARIOS

    table = Table(title="Scenarios")
    for col in ("name", "for", "duration s", "touches", "pump", "description"):
        table.add_column(col)
    for sc in SCENARIOS.values():
        table.add_row(sc.name, "patch, skin", f"{sc.duration:g}", str(len(sc.touches)), sc.pump,
                      sc.description)
    table.add_row(EXCITATION, "patch", "600", "0", "off", "the Peltier tank under a rich drive, for "
                  "`thermoskin identify` (simulate only)")
    for name, description in SKIN_SCENARIOS.items():
        table.add_row(name, "skin", "per skin", "per skin", "logic", f"{description} (--skin only)")
    console.print(table)


@main.command()
@click.option("--scenario", default=None,
              help="Named scenario (see `thermoskin scenarios`; default: fingers, with --skin: multi).")
@DURATION_OPT
@CONFIG_OPT
@click.option("-o", "--output", "output_csv", type=click.Path(path_type=Path), required=True,
              help="Log CSV (measured columns and the simulator's truth q_i, T_g).")
@click.option("--skin", "skin_path", type=click.Path(path_type=Path), default=None,
              help="LAYOUT.toml, a skin of many patches' layout file (examples/forearm.toml): simulated "
                   "in closed loop, "
                   "one controller per water loop; the log has one row per sample and patch: "
                   "t,patch,T_w,T_p,v,T_a[,T_w2..],q_i,contact_true,position_true,fresh.")
@IDEAL_SENSORS_OPT
@_user_errors
def simulate(scenario: str | None, duration: float | None, config_path: Path | None,
             output_csv: Path, skin_path: Path | None, ideal_sensors: bool = False) -> None:
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
    boards, said = _boards(cfg, ideal_sensors)
    console.print(said)
    with _progress_bar(f"simulating {sc.name}") as bar:
        task = bar.add_task(f"simulating {sc.name}", total=1.0)
        # written block by block (whole or not at all): memory does not follow the length
        blocks = simulate_blocks(sc, cfg, progress=lambda f: bar.update(task, completed=f),
                                 boards=boards)
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
    from thermoskin.logio.common import listing

    names = listing([f"{p.index} {p.name}" for p in skin.patches], 20)  # 10 000 names are not read
    console.print(f"simulated {sc.duration:g} s of '{sc.name}' on {skin.name} ({len(skin.patches)} patches "
                  f"on {len(skin.loops)} loops, {len(sc.contacts)} contacts) at "
                  f"{res.realtime_factor:.0f}x real time; {res.n * len(skin.patches)} rows; patch: {names}; "
                  f"wrote {output}")
