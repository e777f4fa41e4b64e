"""Thermoskin's firmware on a Raspberry Pi Pico: copied to the board's flash as ``main.py``
(with the ``skinfw`` folder) by ``mpremote``, it runs at power-up. docs/hardware.md says how."""

from skinfw.board_rp2 import Board
from skinfw.device import Device

Device(Board()).run()
