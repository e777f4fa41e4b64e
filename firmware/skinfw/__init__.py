"""Thermoskin's reference firmware (MicroPython): docs/protocol.md on a microcontroller.

``device`` (sessions, the 1 kHz loop, safety), ``wire`` (CRC-16, COBS, fixed-point views of
the f32 fields), ``max31856`` (the converter's driver), ``config`` (timing, limits, pins),
``board_rp2`` (the hardware layer on a Raspberry Pi Pico). Nothing here imports ``thermoskin``:
it runs on the microcontroller; ``thermoskin device-emulator --firmware`` runs the same
modules under CPython against register-level models of the hardware."""
