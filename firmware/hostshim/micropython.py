"""The parts of MicroPython's ``micropython`` module the firmware uses, for CPython (the host's
tests put this folder on ``sys.path``; on the board the real module is built in).

``viper`` and ``native`` compile a function to machine code on MicroPython; here they leave
it as it is (the firmware's viper code masks what a machine word would wrap, so both give the
same results). ``const`` marks a compile-time constant there; here it is the value."""


def viper(f):
    return f


def native(f):
    return f


def const(x):
    return x


def kbd_intr(c):
    """MicroPython: the character that raises KeyboardInterrupt on the REPL's stream; nothing here."""
