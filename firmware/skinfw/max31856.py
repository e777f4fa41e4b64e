"""MAX31856 thermocouple-to-digital converter over SPI (Maxim/Analog Devices datasheet, rev. 0+).

Registers (read at the address, write at ``0x80 | address``; a multi-byte access
auto-increments): ``CR0`` 0x00 (bit 7 ``CMODE`` continuous conversions, bits 5:4 ``OCFAULT``
open-circuit detection, bit 1 ``FAULTCLR``, bit 0 50 Hz filter), ``CR1`` 0x01 (bits 6:4
``AVGSEL``, bits 3:0 thermocouple type), ``MASK`` 0x02, ``LTCBH/M/L`` 0x0C-0x0E (the
linearised thermocouple temperature: 19 bits two's complement, left-justified, 1/128 K a
count), ``SR`` 0x0F (fault status: 7 ``CJRANGE``, 6 ``TCRANGE``, 5 ``CJHIGH``, 4 ``CJLOW``,
3 ``TCHIGH``, 2 ``TCLOW``, 1 ``OVUV``, 0 ``OPEN``). ``DRDY`` goes low when a conversion is
in ``LTCB`` and high again when it is read. SPI mode 1 or 3, up to 5 MHz.

One :meth:`read` is one SPI transaction of 5 bytes (address, ``LTCBH``, ``LTCBM``, ``LTCBL``,
``SR``): the reading and its fault bits together, 8 µs at 5 MHz. It leaves them in ``raw``
and ``sr`` (no tuple is made on the 1 kHz path).
"""

import sys

import micropython
from micropython import const

if sys.implementation.name != "micropython":  # viper's cast, for CPython
    def ptr8(x):
        return x

CR0 = const(0x00)
CR1 = const(0x01)
MASK = const(0x02)
LTCBH = const(0x0C)
SR = const(0x0F)
WRITE = const(0x80)

CMODE = const(0x80)
OCFAULT_01 = const(0x10)
"""Open-circuit detection, mode 1 (the datasheet's choice for thermocouple leads under 5 kΩ)."""
FAULTCLR = const(0x02)
FILTER_50HZ = const(0x01)

SR_OPEN = const(0x01)
SR_OVUV = const(0x02)
SR_TCRANGE = const(0x40)
SR_CJRANGE = const(0x80)
SR_RANGE = const(0xC2)
"""The fault bits that make a reading invalid besides ``OPEN``: range and over/under-voltage."""

TYPE_K = const(0x03)
TYPE_T = const(0x07)


class MAX31856:
    """One converter: chip select ``cs`` and data-ready ``drdy`` pins (``machine.Pin``-like),
    on the shared ``spi`` bus (``machine.SPI``-like: ``write``, ``write_readinto``)."""

    def __init__(self, spi, cs, drdy, tc_type=TYPE_T, filter_50hz=True, avgsel=0):
        self.spi = spi
        self.cs = cs
        self.drdy = drdy
        self.tc_type = tc_type
        self.filter_50hz = filter_50hz
        self.avgsel = avgsel
        self._tx = bytearray(5)
        self._tx[0] = LTCBH
        self._rx = bytearray(5)
        self._w = bytearray(2)
        self.raw = 0
        """The last reading, counts of 1/128 K (signed)."""
        self.sr = 0
        """The fault status register read with it."""

    def write_reg(self, reg, value):
        w = self._w
        w[0] = WRITE | reg
        w[1] = value
        self.cs.value(0)
        self.spi.write(w)
        self.cs.value(1)

    def read_reg(self, reg):
        tx, rx = self._tx, self._rx
        tx[0] = reg
        self.cs.value(0)
        self.spi.write_readinto(memoryview(tx)[:2], memoryview(rx)[:2])
        self.cs.value(1)
        tx[0] = LTCBH
        return rx[1]

    def begin(self):
        """Configure (thermocouple type, averaging, mains filter, open-circuit detection, every
        fault reported in ``SR``), clear old faults and start continuous conversions. Whether
        the chip answers: ``CR1`` reads back as written."""
        self.write_reg(CR0, 0)  # stop: the next CMODE starts a fresh conversion cycle
        cr1 = ((self.avgsel & 0x07) << 4) | (self.tc_type & 0x0F)
        self.write_reg(CR1, cr1)
        self.write_reg(MASK, 0x00)
        cr0 = CMODE | OCFAULT_01 | (FILTER_50HZ if self.filter_50hz else 0)
        self.write_reg(CR0, cr0 | FAULTCLR)
        return self.read_reg(CR1) == cr1

    def ready(self):
        """A new conversion is waiting (``DRDY`` low)."""
        return self.drdy.value() == 0

    def read(self):
        """Read the conversion and the fault status (one transaction; ``DRDY`` goes high)."""
        rx = self._rx
        self.cs.value(0)
        self.spi.write_readinto(self._tx, rx)
        self.cs.value(1)
        self.sr = rx[4]
        self.raw = _ltcb(rx)

    def clear_faults(self):
        """Clear latched fault bits (``FAULTCLR``), conversions going on."""
        cr0 = CMODE | OCFAULT_01 | (FILTER_50HZ if self.filter_50hz else 0)
        self.write_reg(CR0, cr0 | FAULTCLR)


@micropython.viper
def _ltcb(rx: ptr8) -> int:
    """The signed 19-bit reading in ``rx[1:4]`` (``LTCBH, LTCBM, LTCBL``), counts of 1/128 K."""
    v = (int(rx[1]) << 11) | (int(rx[2]) << 3) | (int(rx[3]) >> 5)
    if v & 0x40000:
        v -= 0x80000
    return v

