"""``python -m thermoskin.cli``: the command line (as the ``thermoskin`` program, without its
start-up's pause of the collector)."""

from thermoskin.cli import main

main()
