"""Thermoskin's firmware on a Raspberry Pi Pico: copied to the board's flash as ``main.py``
(with the ``skinfw`` folder) by ``mpremote``, it runs at power-up. docs/hardware.md says how.

GP22 held to GND at power-up (a jumper): the firmware does not start (no watchdog, outputs
left off), so that ``mpremote`` has the REPL for an update."""

from machine import Pin
from skinfw import config

if Pin(config.PIN_MAINT, Pin.IN, Pin.PULL_UP).value() == 0:
    print("thermoskin firmware: maintenance jumper on GP22: not started")
else:
    from skinfw.board_rp2 import Board
    from skinfw.device import Device

    Device(Board()).run()
