"""The ``thermoskin`` program (also ``python -m thermoskin``): the command line of
:mod:`thermoskin.cli`, with Python's cyclic collector paused while it starts
(:mod:`thermoskin.startup`)."""

from __future__ import annotations

import sys


def main() -> None:
    """Run the command line as a program."""
    from thermoskin import startup

    startup.pause()
    try:
        from thermoskin.cli import main as cli

        cli()
    finally:
        if startup.paused():  # a command that exited before its start-up ended (--help, a usage error)
            startup.cancel()  # the collector back on, nothing frozen, for a caller that goes on
            cli_module = sys.modules.get("thermoskin.cli")
            if cli_module is not None:  # and the exit's teardown as quick as a command's
                cli_module.freeze_at_exit()


if __name__ == "__main__":
    main()
