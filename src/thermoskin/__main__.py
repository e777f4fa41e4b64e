"""The ``thermoskin`` program (also ``python -m thermoskin``): the command line of
:mod:`thermoskin.cli`, with Python's cyclic collector paused while it starts
(:mod:`thermoskin.startup`)."""

from __future__ import annotations


def main() -> None:
    """Run the command line as a program."""
    from thermoskin import startup

    startup.pause()
    from thermoskin.cli import main as cli

    cli()


if __name__ == "__main__":
    main()
