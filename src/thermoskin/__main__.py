"""The ``thermoskin`` program (also ``python -m thermoskin``): the command line of
:mod:`thermoskin.cli`, with Python's cyclic collector paused while it starts
(:mod:`thermoskin.startup`)."""

from __future__ import annotations


def main() -> None:
    """Run the command line as a program."""
    from thermoskin import startup

    startup.pause()
    try:
        from thermoskin.cli import main as cli

        cli()
    finally:
        startup.cancel()  # a command that exited before its start-up ended (--help, a usage error)


if __name__ == "__main__":
    main()
