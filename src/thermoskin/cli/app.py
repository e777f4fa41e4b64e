"""The ``thermoskin`` command group: one-line usage errors (exit 2) and the start-up's end.
"""

from __future__ import annotations

import atexit
import gc
import sys
from typing import Any

import click

from thermoskin import __version__, startup


def _freeze_at_exit() -> None:
    """At the command's exit, one collection (what is garbage by then is finalised), then every
    object frozen (``gc.freeze``): the interpreter's teardown, which otherwise collects again and
    again while it clears the modules, traversing every object numba and llvmlite made each
    time, took 0.2 s of a 1 s ``observe`` of a short log; now 0.05 s. Exit handlers all still
    run and the OS takes the memory back. What is still reachable at exit and sits in a
    reference cycle is not finalised: the commands close every file they write explicitly (a
    log, events, a recording), so registered only by the command line's :func:`main`, not for
    a program that merely imports this module."""
    gc.collect()
    gc.freeze()


def freeze_at_exit() -> None:
    """Have the interpreter's exit run :func:`_freeze_at_exit` (once, however often asked: a
    program that runs commands in-process registers it again with each)."""
    atexit.unregister(_freeze_at_exit)
    atexit.register(_freeze_at_exit)


_NO_ARGS: Any = getattr(click.exceptions, "NoArgsIsHelpError", ())  # click >= 8.2


class _Commands(click.Group):
    """The command group, whose usage errors (a missing argument, an unknown option, a value
    that is not a number) are one line and exit 2, as every other user error."""

    def main(self, *args: Any, **kwargs: Any) -> Any:  # type: ignore[override]
        from thermoskin.cli.terminal import degrade_to_ascii

        degrade_to_ascii()  # an ASCII-only locale: "µs" written "us", never an encoding error
        if kwargs.get("standalone_mode", True) is False:  # a caller handling click's errors
            return super().main(*args, **kwargs)
        try:
            rv = super().main(*args, **{**kwargs, "standalone_mode": False})
        except click.UsageError as e:
            if isinstance(e, _NO_ARGS):  # `thermoskin` alone: the help, as click gives it
                e.show()
                sys.exit(e.exit_code)
            from thermoskin.cli.terminal import one_line

            where = e.ctx.command_path if e.ctx is not None else "thermoskin"
            msg = one_line(e.format_message())
            click.echo(f"thermoskin: error: {msg} (see {where} --help)", err=True)
            sys.exit(2)
        except click.ClickException as e:
            e.show()
            sys.exit(e.exit_code)
        except click.Abort:
            click.echo("thermoskin: interrupted", err=True)
            sys.exit(130)
        sys.exit(rv if isinstance(rv, int) else 0)


@click.group(cls=_Commands, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="thermoskin")
def main() -> None:
    """Thermoskin: touch sensing on a soft thermal robot skin (thermal exchange observer)."""
    freeze_at_exit()
    ctx = click.get_current_context()
    command = main.get_command(ctx, ctx.invoked_subcommand) if ctx.invoked_subcommand else None
    if not getattr(getattr(command, "callback", None), "starts_itself", False):
        startup.resume()  # the command's start-up ends here (a run or an emulator may last hours)
