"""The hardware layer on a Raspberry Pi Pico (RP2040), MicroPython 1.23 or newer.

What :class:`skinfw.device.Device` uses, and nothing more: the SPI bus with the three
MAX31856 chip selects and data-ready pins, the Peltier H-bridge's PWM and direction pins,
the pump's PWM (a MOSFET switch), the on-board LED, a USB CDC serial interface of its own
for the link (``usb-device-cdc`` from micropython-lib: ``mpremote mip install
usb-device-cdc``; the REPL keeps the board's first serial port, the link is the second),
the microsecond clock and the hardware watchdog. Pins: ``skinfw.config`` and
docs/hardware.md.

Not run on hardware by the project's tests (they run the device on register-level models,
``thermoskin device-emulator --firmware``); docs/hardware.md's bring-up checks it on a bench.
"""

import time

import machine
import micropython
from machine import PWM, SPI, Pin

from skinfw import config as C  # noqa: N812


class Board:
    def __init__(self):
        micropython.alloc_emergency_exception_buf(128)
        micropython.kbd_intr(-1)  # no KeyboardInterrupt from a byte on the REPL's port
        # outputs first: off, whatever happens next
        self.peltier_pwm = PWM(Pin(C.PIN_PELTIER_PWM), freq=C.PWM_HZ, duty_u16=0)
        self.peltier_dir = Pin(C.PIN_PELTIER_DIR, Pin.OUT, value=0)
        self.pump = PWM(Pin(C.PIN_PUMP), freq=C.PWM_HZ, duty_u16=0)
        self.led = Pin(C.PIN_LED, Pin.OUT, value=0)
        machine.freq(C.CPU_HZ)  # then the PWM frequencies again, the bus after it
        self.peltier_pwm.freq(C.PWM_HZ)
        self.pump.freq(C.PWM_HZ)
        self.spi = SPI(C.SPI_ID, baudrate=C.SPI_HZ, polarity=0, phase=1, bits=8, firstbit=SPI.MSB,
                       sck=Pin(C.PIN_SCK), mosi=Pin(C.PIN_MOSI), miso=Pin(C.PIN_MISO))
        self.cs = [Pin(p, Pin.OUT, value=1) for p in C.PIN_CS]
        self.drdy = [Pin(p, Pin.IN, Pin.PULL_UP) for p in C.PIN_DRDY]
        import usb.device
        from usb.device.cdc import CDCInterface

        self.cdc = CDCInterface(timeout=0)  # non-blocking: a host that does not read costs frames
        usb.device.get().init(self.cdc, builtin_driver=True)
        self.ticks_us = time.ticks_us
        self.ticks_diff = time.ticks_diff
        self.ticks_add = time.ticks_add
        # a hung loop resets the chip: its pins float back to inputs, the drivers' pull-downs
        # hold the H-bridge and the pump off
        self.wdt = machine.WDT(timeout=100)
        self._t_gc = time.ticks_ms()

    def usb_read(self, buf):
        """Bytes the host sent, into ``buf`` (non-blocking); how many."""
        n = self.cdc.readinto(buf)
        return n or 0

    def usb_write(self, mv):
        """Queue a frame for the host (non-blocking); how many bytes were taken."""
        if not self.cdc.is_open():
            return 0
        n = self.cdc.write(mv)
        return n or 0

    def wait(self, us):
        """Until the next sample (``us``): collect garbage once a second where there is time for
        it (the 1 kHz path allocates nothing; replies to HELLO and FAULT frames do)."""
        import gc

        if us > 700 and time.ticks_diff(time.ticks_ms(), self._t_gc) > 1000:
            self._t_gc = time.ticks_ms()
            gc.collect()

    def alive(self):
        return True

    def feed(self):
        self.wdt.feed()

    def session_started(self):
        self.led.value(1)

    def session_ended(self):
        self.led.value(0)
