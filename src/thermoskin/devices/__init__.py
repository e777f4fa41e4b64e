"""Device back ends behind one interface (:class:`~thermoskin.devices.base.Device`).

- :mod:`.protocol`: the binary link protocol (COBS frames, CRC-16, HELLO/SAMPLE/COMMAND/...).
- :mod:`.serial_device`: the host side over pyserial (hardware, or the emulator's pty).
- :mod:`.emulator`: the simulated skin behind a pseudo-terminal speaking the protocol.
- :class:`thermoskin.runtime.record.ReplayDevice`: a recording played back.
"""

from thermoskin.devices.base import ChannelTracker, Device, DeviceError, Sample

__all__ = ["ChannelTracker", "Device", "DeviceError", "Sample"]
