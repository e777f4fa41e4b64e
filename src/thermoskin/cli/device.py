"""``thermoskin device-emulator``: the simulated skin behind a pseudo-terminal speaking the
serial protocol.
"""

from __future__ import annotations

import sys
from pathlib import Path

import click

from thermoskin.cli.app import main
from thermoskin.cli.common import CONFIG_OPT, IDEAL_SENSORS_OPT, SCENARIO_OPT, _config
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
@IDEAL_SENSORS_OPT
def device_emulator(link: Path, scenario: str, faults: tuple[str, ...], tc_period: float | None,
                    jitter: float | None, truth_path: Path | None, firmware: bool, watchdog: float | None,
                    config_path: Path | None, ideal_sensors: bool = False) -> None:
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
        sys.exit(firmware_main(str(link), cfg, sc, specs, tc_period, jitter, truth_path, watchdog,
                               ideal_sensors=ideal_sensors))
    sys.exit(emulator_main(str(link), scenario, list(faults), tc_period, cfg, jitter=jitter,
                           truth=truth_path, watchdog=watchdog, ideal_sensors=ideal_sensors))


@main.command("device-hello")
@click.option("--device", "device", required=True, metavar="serial://PATH",
              help="The device: serial://PATH (a board's USB serial port, or an emulator's link).")
@click.option("--seconds", type=float, default=2.0, show_default=True,
              help="Seconds of samples to look at.")
def device_hello(device: str, seconds: float) -> None:
    """Check that a device answers, with its outputs off: its HELLO_ACK, then SECONDS of
    samples without any COMMAND (the device holds the Peltier and the pump off), and per
    thermocouple its conversions per second, mean, spread and faults.

    The first step of a bench's bring-up (docs/hardware.md). Exit codes: 0 every channel
    converting with valid readings; 2 no device, or a device that does not answer (one line);
    3 it answered, but a channel gave no valid reading or reported a fault.
    """
    import math

    import numpy as np

    from thermoskin.devices import protocol as proto
    from thermoskin.devices.base import DeviceError
    from thermoskin.devices.serial_device import SerialDevice

    if not device.startswith("serial://") or len(device) <= len("serial://"):
        click.echo(f"thermoskin: error: --device {device!r}: must be serial://PATH", err=True)
        sys.exit(2)
    if not (0.1 <= seconds <= 600.0):
        click.echo(f"thermoskin: error: --seconds {seconds}: must be within [0.1, 600] s", err=True)
        sys.exit(2)
    port = device[len("serial://"):]
    dev = SerialDevice(port, link_timeout=0.5)
    try:
        dev.open()
    except DeviceError as e:
        click.echo(f"thermoskin: error: {e}", err=True)
        sys.exit(2)
    got = []
    try:
        t_end = None
        t_keep = 0.0
        while True:
            s = dev.read_sample(0.5)
            if s is None:
                break
            got.append(s)
            if t_end is None:
                t_end = s.t + seconds
            if s.t >= t_end:
                break
            if s.t >= t_keep:  # no COMMAND is sent: the session's HELLO keeps it on
                dev.keepalive()
                t_keep = s.t + 0.3
    finally:
        dev.close()
    ack = dev.ack
    assert ack is not None
    click.echo(f"device: {device}, protocol {ack.version}, id 0x{ack.device_id:08X}, sample period "
               f"{ack.t_s_us} µs, thermocouples every {ack.tc_period_us / 1000:g} ms")
    st = dev.decoder.stats
    if not got:
        click.echo("thermoskin: fault: the device answered but sent no sample", err=True)
        sys.exit(3)
    t = np.array([s.t for s in got])
    span = t[-1] - t[0]
    steps = np.diff(t)
    regular = bool(len(steps)) and bool(np.allclose(steps, ack.t_s_us * 1e-6))
    click.echo(f"samples: {len(got)} over {span:.3f} s of device time, "
               f"{f'every {ack.t_s_us} µs' if regular else 'with gaps'}; "
               f"{st.corrupted} frames corrupted, {st.lost} lost")
    ok = True
    for i, (name, bit) in enumerate(zip(proto.CHANNELS, proto.CHANNEL_BITS, strict=True)):
        fresh = [s for s in got if s.fresh & bit]
        x = np.array([(s.T_w, s.T_p, s.T_a)[i] for s in fresh], dtype=float)
        valid = x[np.isfinite(x)]
        open_ = any(s.status & (proto.ST_OPEN_W << i) for s in got)
        rate = (len(fresh) - 1) / span if span > 0 and len(fresh) > 1 else math.nan
        if not valid.size or open_:
            ok = False
            why = "open thermocouple" if open_ else "no valid reading"
            click.echo(f"{name}: {why} ({len(fresh)} conversions)")
            continue
        click.echo(f"{name}: {len(fresh)} conversions ({rate:.1f}/s), mean {valid.mean():.3f} degC, "
                   f"spread (sd) {valid.std():.4f} K, range {valid.min():.3f} to {valid.max():.3f} degC")
    faults = [f.name for _, f in dev.faults]
    last = got[-1].status
    bits = [n for b, n in ((proto.ST_SAFE, "safe state"), (proto.ST_WATCHDOG, "watchdog"),
                           (proto.ST_NO_COMMAND, "no command yet: outputs off"),
                           (proto.ST_OVERRUN, "late samples")) if last & b]
    click.echo(f"status: {', '.join(bits) or 'ok'}"
               + (f"; faults reported: {', '.join(faults)}" if faults else ""))
    if faults or not ok:
        sys.exit(3)
