"""``thermoskin device-emulator``: the simulated skin behind a pseudo-terminal speaking the
serial protocol.
"""

from __future__ import annotations

import sys
from pathlib import Path

import click

from thermoskin.cli.app import main
from thermoskin.cli.common import CONFIG_OPT, SCENARIO_OPT, _config
from thermoskin.params import ConfigError
from thermoskin.paths import PathError


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
@click.option("--firmware", is_flag=True,
              help="Run the reference firmware (firmware/, MicroPython) under CPython in place of "
                   "the emulator's device core, on register-level models of its MAX31856 converters "
                   "and PWM outputs fed by the simulated skin (docs/hardware.md).")
@click.option("--watchdog", type=float, default=None,
              help="The device's command watchdog, s [default: 0.5; the firmware's 0.05].")
@CONFIG_OPT
def device_emulator(link: Path, scenario: str, faults: tuple[str, ...], tc_period: float | None,
                    jitter: float | None, truth_path: Path | None, firmware: bool, watchdog: float | None,
                    config_path: Path | None) -> None:
    """Run the simulated skin behind a pseudo-terminal speaking docs/protocol.md.

    Makes LINK a symbolic link to the pty and runs until stopped (Ctrl-C, SIGTERM); the link
    is removed on exit. Each host's HELLO starts a fresh session (the scenario, the device
    clock and the truth file from zero); a second host is refused while one is connected.
    Connect with `thermoskin run --device serial://LINK`. With --truth, the truth file holds
    every sample of the session sent up to the stop. --firmware: the same with the reference
    firmware's own code as the device.
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
    if firmware:
        from thermoskin.devices.emulator import check_options
        from thermoskin.devices.firmware_host import main as firmware_main

        try:
            sc, specs = check_options(scenario, faults, tc_period, jitter, watchdog)
        except (KeyError, ValueError) as e:
            click.echo(f"thermoskin: error: {e.args[0] if isinstance(e, KeyError) else e}", err=True)
            sys.exit(2)
        sys.exit(firmware_main(str(link), cfg, sc, specs, tc_period, jitter, truth_path, watchdog))
    sys.exit(emulator_main(str(link), scenario, list(faults), tc_period, cfg, jitter=jitter,
                           truth=truth_path, watchdog=watchdog))
