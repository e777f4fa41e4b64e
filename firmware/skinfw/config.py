"""The firmware's settings: timing, safety limits, the pump, the converters, the pins.

Integers only (temperatures in 1/128 K counts, as the MAX31856 gives them; times in µs):
nothing on the 1 kHz path needs a float. The pins are those of ``docs/hardware.md`` on a
Raspberry Pi Pico (RP2040); ``board_rp2.py`` reads them from here.
"""

from micropython import const

PROTOCOL_VERSION = const(1)
DEVICE_ID = const(0x7E570002)
"""Reported in HELLO_ACK (the Python emulator is 0x7E570001)."""

T_S_US = const(1000)
"""The sample period, µs (1 kHz)."""
WATCHDOG_US = const(50_000)
"""No COMMAND for this long: Peltier off, pump off, FAULT ``watchdog``, latched until the next HELLO."""
SESSION_TIMEOUT_US = const(1_000_000)
"""The host's silence that ends its session (no more SAMPLEs until a HELLO); until then another
host's HELLO is refused."""
CATCHUP_US = const(1_000_000)
"""Samples owed after a stall are sent at once (each with its own time) up to this far back;
older ones are skipped (counted) and the clock never slips."""
READ_LATE_US = const(10_000)
"""A sample sent later than this (catching up after a stall) reads no converter: what converted
meanwhile is read by the first sample within it, so that no reading is dated more than this
before the instant it was read."""

# the device's own temperature limits (1/128 K counts): wider than the host's [safety] bounds
# (7-37 degC on T_p), a backstop that holds when the host does not
TP_MIN = const(2 * 128)
TP_MAX = const(42 * 128)
TW_MAX = const(43 * 128)
"""The pipe's limit: 43 degC, the long-contact limit of ISO 13732-1 for the surface it feeds."""

PUMP_PWM = True
"""True: the pump's duty follows ``v / V_FULL``; False: on/off (``v > 0`` is on)."""
V_FULL_Q16 = const(13107)
"""The water velocity at full pump duty, m/s times 65536 (0.2 m/s)."""
PWM_HZ = const(20_000)
"""PWM frequency of the Peltier's H-bridge and the pump (above hearing)."""

TC_TYPE = const(0x07)
"""MAX31856 thermocouple type (``CR1``): 0x07 type T (copper-constantan), 0x03 type K."""
FILTER_50HZ = True
"""Mains notch at 50 Hz (conversions every 98 ms typical); False: 60 Hz (82 ms)."""

# Raspberry Pi Pico pins (GP numbers)
PIN_SCK = const(18)
PIN_MOSI = const(19)
PIN_MISO = const(16)
PIN_CS = (17, 20, 21)
"""Chip selects of the T_w, T_p and T_a converters."""
PIN_DRDY = (13, 14, 15)
"""Their data-ready outputs (active low)."""
PIN_PELTIER_PWM = const(2)
PIN_PELTIER_DIR = const(3)
"""High: heating the tank (drive > 0); low: cooling."""
PIN_PUMP = const(6)
PIN_LED = const(25)
"""On while a host's session is on."""
PIN_MAINT = const(22)
"""Held to GND at power-up (a jumper): the firmware does not start, the REPL is free for mpremote."""
CPU_HZ = 200_000_000
"""The RP2040's clock (its datasheet qualifies 200 MHz; MicroPython's default is 125 MHz): the
headroom the 1 kHz loop wants (docs/hardware.md, Timing on the board)."""
SPI_ID = const(0)
SPI_HZ = const(5_000_000)
