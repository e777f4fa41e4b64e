"""The reference firmware (``firmware/``, MicroPython) run on the host against models of its hardware.

``thermoskin device-emulator --firmware --link PATH [--truth TRUTH.csv] [--scenario NAME]
[--fault KIND@S] ...`` runs the firmware's own modules (``skinfw.device``, ``wire``,
``max31856``) under CPython in place of the emulator's device core. Its hardware layer
(:class:`HostBoard`) is register-level models fed by the project's simulated skin:

- :class:`Max31856Model`: the converter's 16 registers (defaults as the datasheet's), SPI
  transactions (address, write bit ``0x80``, auto-increment), continuous conversions every
  98 ms with the 50 Hz filter (82 ms with 60 Hz; ``--tc-period`` overrides), each latching
  the sensing element's temperature (``sim.sensors``: lag, noise and offset of boards as a
  lab buys them, ``sim.boards``, or with ``--ideal-sensors`` of ``[sensor]``)
  quantised to the 19-bit ``LTCB`` registers (1/128 K a count, rounded), ``DRDY`` low until
  ``LTCB`` is read, fault bits in ``SR`` (``OPEN``, ``TCRANGE``);
- :class:`SpiBus` with chip selects, :class:`PwmModel` (``duty_u16``) and :class:`PinModel`;
- :class:`World`: the simulated plant (:class:`~thermoskin.sim.plant.SimulatedPlant`, the
  scenario repeating) stepped once every ``t_s`` of the clock with the drive and pump the PWM
  models hold (H-bridge duty and direction; the pump's duty times its full-duty velocity),
  from the session's start (``board.session_started``: the scenario from zero, the truth file
  again); the faults of ``--fault`` acted out in the hardware (an open thermocouple, three
  converters out of range, the tank's reading at 45 degC, a cut cable, a frozen register);
- :class:`HostUsb`: the pseudo-terminal; every frame the firmware writes is decoded with the
  host's own decoder (:mod:`thermoskin.devices.protocol`), which writes each SAMPLE's truth row
  (``t`` its device time) and counts what does not decode.

:class:`FirmwareBench` runs the same on a virtual clock with an in-memory link, for tests that
must not depend on the wall clock.
"""

from __future__ import annotations

import contextlib
import dataclasses
import gc
import math
import os
import select
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from thermoskin.devices import protocol as proto
from thermoskin.devices.emulator import (
    OVERTEMP_C,
    FaultSpec,
    PtyEmulator,
    TruthWriter,
    serve_until_stopped,
    write_pending,
)
from thermoskin.params import Config
from thermoskin.sim.boards import said, simulated_boards
from thermoskin.sim.plant import SimulatedPlant
from thermoskin.sim.scenarios import Scenario

FIRMWARE_ENV = "THERMOSKIN_FIRMWARE"
"""A folder holding the firmware (``skinfw/``), where it is not beside the package's source."""
TICKS_PERIOD = 1 << 30
"""MicroPython's ``time.ticks_us`` wraps at 2^30 on 32-bit ports: the host's clock does too."""
V_FULL = 0.2
"""The pump's velocity at full duty, m/s (``config.V_FULL_Q16`` of the firmware)."""


class FirmwareNotFoundError(ValueError):
    """The firmware's source is not where it was looked for."""


def firmware_dir() -> Path:
    """The firmware's folder: ``$THERMOSKIN_FIRMWARE``, else ``firmware/`` of the source tree
    this package runs from (a clone of the repository)."""
    env = os.environ.get(FIRMWARE_ENV)
    d = Path(env) if env else Path(__file__).resolve().parents[3] / "firmware"
    if not (d / "skinfw" / "device.py").is_file():
        raise FirmwareNotFoundError(f"no firmware at {d} (skinfw/device.py): --firmware runs the firmware's "
                               f"source from a clone of the repository, or set {FIRMWARE_ENV}=DIR")
    return d


def load_firmware(folder: Path | None = None) -> Any:
    """The firmware's ``skinfw`` package, imported under CPython (with ``micropython`` from the
    firmware's ``hostshim``); its modules, fresh (a previous import is dropped)."""
    d = folder or firmware_dir()
    for name in [m for m in sys.modules if m == "skinfw" or m.startswith("skinfw.")]:
        del sys.modules[name]
    for p in (str(d / "hostshim"), str(d)):
        if p not in sys.path:
            sys.path.insert(0, p)
    import importlib

    importlib.invalidate_caches()
    return importlib.import_module("skinfw.device")


# ----------------------------------------------------------------------------- clocks

class WallClock:
    """The host's monotonic clock, µs."""

    def now(self) -> int:
        return time.monotonic_ns() // 1000


class VirtualClock:
    """A clock that moves only when told (tests that must not depend on the wall clock)."""

    def __init__(self, t_us: int = 1_000_000_000) -> None:
        self.t = int(t_us)

    def now(self) -> int:
        return self.t

    def advance(self, us: int) -> None:
        self.t += max(0, int(us))


# ----------------------------------------------------------------------------- converter

REG_DEFAULTS = bytes([0x00, 0x03, 0xFF, 0x7F, 0xC0, 0x7F, 0xFF, 0x80, 0x00, 0x00, 0x00, 0x00,
                      0x00, 0x00, 0x00, 0x00])
"""The MAX31856's registers at power-up (CR0, CR1, MASK, CJHF, CJLF, LTHFTH, LTHFTL, LTLFTH,
LTLFTL, CJTO, CJTH, CJTL, LTCBH, LTCBM, LTCBL, SR)."""
SR_OPEN, SR_OVUV, SR_TCRANGE = 0x01, 0x02, 0x40


class Max31856Model:
    """One MAX31856 at register level (module doc), converting on the world's clock.

    ``period_s``: its conversion period (``None``: the datasheet's typical 98 ms with the
    50 Hz filter, 82 ms with 60 Hz, plus 40 / 33.3 ms per averaged sample); ``jitter_s``:
    uniform jitter of each conversion's instant. Faults (set by the world): ``open`` (the
    thermocouple open: ``SR.OPEN`` at each conversion), ``out_of_range`` (``SR.TCRANGE``),
    ``stuck`` (``LTCB`` frozen while conversions go on), ``dead`` (the chip does not answer:
    every byte reads 0xFF, ``DRDY`` never low).
    """

    def __init__(self, t_s: float, period_s: float | None = None, jitter_s: float = 0.0,
                 seed: int = 0) -> None:
        self.t_s = t_s
        self.period_s = period_s
        self.jitter_s = jitter_s
        self._rng = np.random.default_rng(seed)
        self.open = self.out_of_range = self.stuck = self.dead = False
        self.reset()

    def reset(self) -> None:
        """Power-up: registers at their defaults, no conversion going."""
        self.regs = bytearray(REG_DEFAULTS)
        self.drdy_low = False
        self.next_conv = -1  # the world step of the next conversion (-1: not converting)
        self.conversions = 0

    def restart_conversions(self, step: int) -> None:
        """Conversions from ``step`` on (continuous mode set), the first one period later."""
        self.next_conv = step + self._period_steps()

    def _period_steps(self) -> int:
        if self.period_s is not None:
            p = self.period_s
        else:
            hz50 = bool(self.regs[0] & 0x01)
            avg = 1 << min(4, (self.regs[1] >> 4) & 0x07)
            p = (0.098 if hz50 else 0.082) + (avg - 1) * (0.040 if hz50 else 1 / 30)
        if self.jitter_s > 0:
            p += self._rng.uniform(-self.jitter_s, self.jitter_s)
        return max(1, round(p / self.t_s))

    def transaction(self, tx: bytes, step: int) -> bytes:
        """One chip-select-low transaction at world step ``step``: the bytes it shifts out."""
        if self.dead:
            return b"\xff" * len(tx)
        if not tx:
            return b""
        addr = tx[0]
        out = bytearray(len(tx))
        if addr & 0x80:  # write, auto-incrementing
            for i, b in enumerate(tx[1:]):
                reg = ((addr & 0x0F) + i) & 0x0F
                if reg == 0:
                    was = self.regs[0] & 0x80
                    if b & 0x02:  # FAULTCLR (self-clearing)
                        self.regs[15] = 0
                    self.regs[0] = b & ~0x02 & 0xFF
                    if b & 0x80 and not was:
                        self.restart_conversions(step)
                    elif not b & 0x80:
                        self.next_conv = -1
                elif reg < 12:  # 12-15 (LTCB, SR) are read-only
                    self.regs[reg] = b
            return bytes(out)
        for i in range(1, len(tx)):
            reg = ((addr & 0x0F) + i - 1) & 0x0F
            out[i] = self.regs[reg]
            if 12 <= reg <= 14:
                self.drdy_low = False
        return bytes(out)

    def at_step(self, step: int, T: float) -> None:
        """World step ``step`` with the sensing element at ``T`` (°C): a conversion if one is due."""
        if self.next_conv < 0 or step < self.next_conv or self.dead:
            return
        self.next_conv = step + self._period_steps()
        self.conversions += 1
        sr = 0
        if self.open:
            sr |= SR_OPEN
        elif self.out_of_range or not math.isfinite(T):
            sr |= SR_TCRANGE
        elif not self.stuck:
            code = math.floor(T * 128.0 + 0.5)
            code = max(-(1 << 18), min((1 << 18) - 1, code)) & 0x7FFFF
            w = code << 5
            self.regs[12], self.regs[13], self.regs[14] = (w >> 16) & 0xFF, (w >> 8) & 0xFF, w & 0xFF
        self.regs[15] = sr
        self.drdy_low = True


# ----------------------------------------------------------------------------- the world

class World:
    """The simulated skin behind the models (module doc), stepped on the clock's time."""

    def __init__(self, cfg: Config, scenario: Scenario, faults: Sequence[FaultSpec] = (),
                 tc_period: float | None = None, jitter: float | None = None,
                 truth: TruthWriter | None = None, lab_boards: bool = False) -> None:
        s = cfg.sensor
        self.boards = simulated_boards(s, ideal=not lab_boards)
        """The sensing elements' offsets, noise and lags: a lab's drawn from ``[sensor]`` seed
        (``sim.boards``) with ``lab_boards``, else ``[sensor]``'s."""
        # the sensing elements (lag, noise, offsets) read every sample: the converters'
        # conversions and quantum (1/128 K) are the models'
        analog = dataclasses.replace(self.boards, period_T_w=0.0, period_T_p=0.0, period_T_a=0.0,
                                     quantum_T=0.0)
        self.cfg = cfg
        self.t_s = cfg.sampling.t_s
        self.t_s_us = round(self.t_s * 1e6)
        self.plant = SimulatedPlant(cfg, scenario, repeat=True, boards=analog)
        j = s.jitter if jitter is None else jitter
        self.models = [Max31856Model(self.t_s, tc_period, j, seed=int(s.seed) + i) for i in range(3)]
        self.faults = sorted(faults, key=lambda f: f.t)
        self.truth = truth
        self.origin: int | None = None  # clock µs of the session's t = 0
        self.w = 0
        self.peltier_duty = 0
        self.peltier_dir = 0
        self.pump_duty = 0
        self.active: set[str] = set()
        self.link_cut = False
        self.sessions = 0
        self.t_fault = math.nan
        """Device time of the first injected fault's onset (s)."""
        self._ring = [(0, 0.0, 0, math.nan)] * 4096
        self.bad_frames = 0

    # -- sessions ----------------------------------------------------------------------------
    def start_session(self, now: int) -> None:
        """The firmware starts a session: the scenario from its start, t = 0 now, the truth file
        again; the converters' last conversion is of the plant as it starts."""
        self.origin = now
        self.w = 0
        self.sessions += 1
        self.plant.reset("equilibrium", v=self.cfg.pump.v_on)
        self.active.clear()
        self.link_cut = False
        self.t_fault = math.nan
        for m in self.models:
            m.open = m.out_of_range = m.stuck = False
        for m in self.models:  # the last conversion: of this plant, now
            if m.next_conv >= 0:
                m.next_conv = 0
        self._arrive()
        if self.truth is not None:
            self.truth.restart()

    def end_session(self) -> None:
        self.origin = None
        if self.truth is not None:
            self.truth.flush()

    # -- time ------------------------------------------------------------------------------
    @property
    def drive(self) -> float:
        """The Peltier drive the H-bridge applies, [-1, 1]."""
        return (1.0 if self.peltier_dir else -1.0) * self.peltier_duty / 65535.0

    @property
    def v(self) -> float:
        """The water velocity the pump gives, m/s."""
        return V_FULL * self.pump_duty / 65535.0

    def sync(self, now: int) -> None:
        """Step the plant up to the clock's ``now`` (µs) with the outputs as they are."""
        if self.origin is None:
            return
        target = (now - self.origin) // self.t_s_us
        while self.w < target:
            self._step()

    def _step(self) -> None:
        """From step ``w`` to ``w + 1``: the plant over one ``t_s`` with the outputs as they are."""
        self.plant.apply(self.drive, self.v)
        self.w += 1
        self._arrive()

    def _arrive(self) -> None:
        """The plant at step ``w``: faults due, the converters' conversions due, its truth."""
        w = self.w
        t = w * self.t_s
        plant = self.plant
        for f in self.faults:
            if f.t <= t + 1e-12 and f.kind not in self.active:
                self._activate(f.kind, t)
        T = list(plant.measure())
        if "overtemp" in self.active:
            T[1] = OVERTEMP_C + (T[1] - plant.T_p_true)
        for m, x in zip(self.models, T, strict=True):
            m.at_step(w, x)
        q_i, T_g, _, _ = plant.truth()
        c, n_f = plant.contact()
        self._ring[w % len(self._ring)] = (c, q_i, n_f, T_g)

    def _activate(self, kind: str, t: float) -> None:
        self.active.add(kind)
        if self.t_fault != self.t_fault:
            self.t_fault = t
        mw = self.models[0]
        if kind == "tc-open":
            mw.open = True
        elif kind == "nan-burst":  # every converter out of range: the firmware's NaN readings
            for m in self.models:
                m.out_of_range = True
        elif kind == "tc-stuck":
            mw.stuck = True
        elif kind == "serial-drop":
            self.link_cut = True

    def truth_at(self, t_us: int) -> tuple[int, float, int, float]:
        """``(contact_true, q_i, n_fingers, T_g)`` at device time ``t_us`` of the session (the
        last 4096 steps are kept)."""
        k = t_us // self.t_s_us
        if self.w < k and self.origin is not None:
            self.sync(self.origin + k * self.t_s_us)
        return self._ring[k % len(self._ring)]


# ----------------------------------------------------------------------------- the layer

class SpiBus:
    """The SPI bus: the transaction goes to the converter whose chip select is low."""

    def __init__(self, world: World, clock: Any) -> None:
        self.world, self.clock = world, clock
        self.selected: int | None = None

    def write(self, buf: Any) -> None:
        self.write_readinto(buf, bytearray(len(buf)))

    def write_readinto(self, tx: Any, rx: Any) -> None:
        n = len(tx)
        if self.selected is None:
            rx[:n] = b"\xff" * n  # nobody drives MISO: the pull-up
            return
        w = self.world
        w.sync(self.clock.now())
        rx[:n] = w.models[self.selected].transaction(bytes(tx), w.w)


class CsPin:
    """A chip-select output."""

    def __init__(self, bus: SpiBus, index: int) -> None:
        self.bus, self.index = bus, index
        self.level = 1

    def value(self, v: int | None = None) -> int:
        if v is not None:
            self.level = int(bool(v))
            if self.level == 0:
                self.bus.selected = self.index
            elif self.bus.selected == self.index:
                self.bus.selected = None
        return self.level


class DrdyPin:
    """A converter's data-ready output (active low), as the firmware reads it now."""

    def __init__(self, world: World, clock: Any, index: int) -> None:
        self.world, self.clock, self.index = world, clock, index

    def value(self) -> int:
        self.world.sync(self.clock.now())
        m = self.world.models[self.index]
        return 0 if m.drdy_low and not m.dead else 1


class PwmModel:
    """A PWM output: its ``duty_u16`` drives the world's Peltier or pump from now on."""

    def __init__(self, world: World, clock: Any, attr: str) -> None:
        self.world, self.clock, self.attr = world, clock, attr
        self.duty = 0

    def duty_u16(self, d: int | None = None) -> int:
        if d is not None:
            self.world.sync(self.clock.now())
            self.duty = max(0, min(65535, int(d)))
            setattr(self.world, self.attr, self.duty)
        return self.duty


class PinModel:
    """An output pin (the H-bridge's direction)."""

    def __init__(self, world: World, clock: Any, attr: str) -> None:
        self.world, self.clock, self.attr = world, clock, attr
        self.level = 0

    def value(self, v: int | None = None) -> int:
        if v is not None:
            self.world.sync(self.clock.now())
            self.level = int(bool(v))
            setattr(self.world, self.attr, self.level)
        return self.level


class HostBoard:
    """The firmware's hardware layer on the host: the models above, a clock, a link.

    ``link``: an object with ``read(buf) -> n``, ``write(data) -> n`` and ``wait(us)``
    (:class:`HostUsb` over the pty, or :class:`MemoryLink`)."""

    def __init__(self, world: World, clock: Any, link: Any) -> None:
        self.world, self.clock, self.link = world, clock, link
        self.spi = SpiBus(world, clock)
        self.cs = [CsPin(self.spi, i) for i in range(3)]
        self.drdy = [DrdyPin(world, clock, i) for i in range(3)]
        self.peltier_pwm = PwmModel(world, clock, "peltier_duty")
        self.peltier_dir = PinModel(world, clock, "peltier_dir")
        self.pump = PwmModel(world, clock, "pump_duty")
        self.running = True

    def ticks_us(self) -> int:
        return self.clock.now() % TICKS_PERIOD

    @staticmethod
    def ticks_diff(a: int, b: int) -> int:
        return (a - b + TICKS_PERIOD // 2) % TICKS_PERIOD - TICKS_PERIOD // 2

    @staticmethod
    def ticks_add(a: int, d: int) -> int:
        return (a + d) % TICKS_PERIOD

    def usb_read(self, buf: bytearray) -> int:
        return self.link.read(buf)

    def usb_write(self, data: Any) -> int:
        return self.link.write(data)

    def wait(self, us: int) -> None:
        self.link.wait(us)

    def alive(self) -> bool:
        return self.running

    def feed(self) -> None:
        pass

    def session_started(self) -> None:
        self.world.start_session(self.clock.now())

    def session_ended(self) -> None:
        self.world.end_session()


class _Frames:
    """What the firmware sends, decoded by the host's decoder: each SAMPLE's truth row, and the
    device time of its first SAMPLE in the safe state after an injected fault (``t_safe``, s;
    NaN before: the firmware's own clock, as on a board)."""

    def __init__(self, world: World) -> None:
        self.world = world
        self.decoder = proto.Decoder(check_seq=False)
        self.t_safe = math.nan

    def feed(self, data: bytes, delivered: bool = True) -> list[proto.Message]:
        msgs = self.decoder.feed(data)
        w = self.world
        if self.t_safe != self.t_safe and w.t_fault == w.t_fault:
            for m in msgs:
                if m.TYPE == proto.T_SAMPLE and m.status & proto.ST_SAFE:  # type: ignore[union-attr]
                    self.t_safe = m.t_us * 1e-6  # type: ignore[union-attr]
                    break
        if delivered and w.truth is not None and w.origin is not None:
            for m in msgs:
                if m.TYPE == proto.T_SAMPLE:
                    t_us = m.t_us  # type: ignore[union-attr]
                    c, q_i, n_f, T_g = w.truth_at(t_us)
                    w.truth.add(t_us * 1e-6, c, q_i, n_f, T_g)
            w.truth.maybe_flush(time.monotonic())  # handed to its writer every flush_s, as the emulator's
        return msgs


class HostUsb:
    """The USB link as the pty's master side: the host's bytes in, the firmware's frames out
    (queued up to ``max_out`` bytes, as the host's USB serial driver buffers them); a cut cable
    (``serial-drop``) passes nothing either way."""

    def __init__(self, fd: int, world: World, max_out: int = 64 * 1024) -> None:
        self.fd, self.world = fd, world
        self.frames = _Frames(world)
        self.out = bytearray()
        self.max_out = max_out
        self.dropped = 0

    def read(self, buf: bytearray) -> int:
        try:
            n = os.readv(self.fd, [buf])
        except (BlockingIOError, InterruptedError, OSError):
            return 0
        if self.world.link_cut:
            return 0
        return n

    def write(self, data: Any) -> int:
        n = len(data)
        if self.world.link_cut:
            self.frames.feed(bytes(data), delivered=False)
            return n  # into the cut cable
        if len(self.out) + n > self.max_out:
            self.dropped += 1
            return 0
        b = bytes(data)
        self.frames.feed(b)
        self.out += b
        self.flush()
        return n

    def flush(self) -> None:
        write_pending(self.fd, self.out)

    def wait(self, us: int) -> None:
        self.flush()
        with contextlib.suppress(InterruptedError, OSError, ValueError):
            select.select([self.fd], [self.fd] if self.out else [], [], us * 1e-6)


class MemoryLink:
    """An in-memory link (tests): the host's bytes queued in ``to_device``, the firmware's
    frames decoded into ``messages``; ``wait`` moves the virtual clock."""

    def __init__(self, world: World, clock: VirtualClock) -> None:
        self.world, self.clock = world, clock
        self.frames = _Frames(world)
        self.to_device = bytearray()
        self.messages: list[proto.Message] = []

    def send(self, msg: proto.Message) -> None:
        self.to_device += proto.encode(msg)

    def read(self, buf: bytearray) -> int:
        if self.world.link_cut:
            self.to_device.clear()
            return 0
        n = min(len(buf), len(self.to_device))
        buf[:n] = self.to_device[:n]
        del self.to_device[:n]
        return n

    def write(self, data: Any) -> int:
        if not self.world.link_cut:
            self.messages += self.frames.feed(bytes(data))
        return len(data)

    def wait(self, us: int) -> None:
        self.clock.advance(us)


class FirmwareBench:
    """The firmware on the models with a virtual clock and a :class:`MemoryLink` (tests)."""

    def __init__(self, cfg: Config, scenario: Scenario, faults: Sequence[FaultSpec] = (),
                 tc_period: float | None = None, truth: TruthWriter | None = None,
                 settings: dict[str, Any] | None = None, lab_boards: bool = False) -> None:
        fw = load_firmware()
        import skinfw.config as fwc

        for k, v in (settings or {}).items():
            setattr(fwc, k, v)
        self.clock = VirtualClock()
        self.world = World(cfg, scenario, faults, tc_period, truth=truth, lab_boards=lab_boards)
        self.link = MemoryLink(self.world, self.clock)
        self.board = HostBoard(self.world, self.clock, self.link)
        self.device = fw.Device(self.board)
        self.device.begin()

    def run_for(self, us: int, each_sample: Any = None) -> None:
        """Run the firmware's loop for ``us`` of virtual time; ``each_sample(msg)`` may answer
        each SAMPLE (a host's COMMAND) as it comes."""
        end = self.clock.now() + us
        seen = len(self.link.messages)
        while self.clock.now() < end:
            d = self.device.step()
            if each_sample is not None:
                for m in self.link.messages[seen:]:
                    if m.TYPE == proto.T_SAMPLE:
                        each_sample(m)
                seen = len(self.link.messages)
            if d > 0:
                self.clock.advance(min(d, end - self.clock.now()))


# ----------------------------------------------------------------------------- the pty

class FirmwarePty(PtyEmulator):
    """The firmware's :class:`HostBoard` behind the emulator's pseudo-terminal and link."""

    def __init__(self, link: str | os.PathLike[str], world: World, truth: TruthWriter | None = None,
                 *, settings: dict[str, Any] | None = None) -> None:
        super().__init__(link, None, truth)  # type: ignore[arg-type]
        self.world = world
        self.settings = settings or {}
        self.device: Any = None
        self.board: HostBoard | None = None
        self.t_safe = math.nan
        """Device time (s) of the firmware's first SAMPLE in its safe state after the first
        injected fault (its own clock)."""

    def serve(self) -> None:
        fw = load_firmware()
        import skinfw.config as fwc

        for k, v in self.settings.items():
            setattr(fwc, k, v)
        clock = WallClock()
        usb = HostUsb(self._master, self.world)
        board = HostBoard(self.world, clock, usb)
        self.board = board
        dev = fw.Device(board)
        self.device = dev
        dev.begin()
        gc.collect()
        gc.freeze()
        gc.disable()  # as the emulator's: no collection pauses a session
        stop = self._stop
        try:
            while not stop.is_set():
                d = dev.step()
                if d > 0:
                    usb.wait(d)
        finally:
            gc.enable()
        self.t_safe = usb.frames.t_safe
        self.ready.clear()

    def timing(self) -> dict[str, float]:
        dev = self.device
        if dev is None:
            return {"samples": 0}
        return {"samples": float(dev.samples), "late": float(dev.late), "skipped": float(dev.skipped),
                "dropped_frames": float(dev.dropped), "sessions": float(dev.sessions),
                "refused": float(dev.refused)}


def main(link: str, cfg: Config, scenario: Scenario, faults: Sequence[FaultSpec], tc_period: float | None,
         jitter: float | None, truth: str | os.PathLike[str] | None, watchdog: float | None,
         verbose: bool = True, rt_priority: int = 40, ideal_sensors: bool = False) -> int:
    """``device-emulator --firmware``: until SIGINT/SIGTERM; 0 on a clean stop, 2 on a bad
    argument or link (one line). The sensing elements are a lab's, drawn from ``[sensor]`` seed
    (``sim.boards``), unless ``ideal_sensors`` (then exactly ``[sensor]``)."""
    try:
        firmware_dir()
    except FirmwareNotFoundError as e:
        print(f"device-emulator: {e}", file=sys.stderr)
        return 2
    settings: dict[str, Any] = {}
    if watchdog is not None:
        settings["WATCHDOG_US"] = round(watchdog * 1e6)
    writer = None
    if truth is not None:
        try:
            writer = TruthWriter(truth)
        except OSError as e:
            print(f"device-emulator: cannot write the truth file {truth}: {e.strerror or e}", file=sys.stderr)
            return 2
    world = World(cfg, scenario, faults, tc_period, jitter, writer, lab_boards=not ideal_sensors)
    emu = FirmwarePty(link, world, writer, settings=settings)

    def started() -> None:
        period = f"{tc_period * 1e3:g} ms" if tc_period else "98 ms (MAX31856, 50 Hz filter)"
        print(f"device-emulator: {link} -> {emu.slave_name} (the firmware from {firmware_dir()} on "
              f"models of its hardware; scenario {scenario.name}, conversions every {period}"
              + (f", faults {', '.join(f'{f.kind}@{f.t:g}' for f in faults)}" if faults else "")
              + (f", truth to {truth}" if truth is not None else "")
              + f"; {said(world.boards, ideal_sensors)}"
              + "); waiting for the host",
              file=sys.stderr, flush=True)

    def stopped() -> None:
        tm = emu.timing()
        usb = emu.board.link if emu.board is not None else None
        line = ("device-emulator: firmware stopped after {samples:.0f} samples in {sessions:.0f} "
                "sessions ({refused:.0f} HELLOs of a second host refused); {late:.0f} samples sent "
                "late, {skipped:.0f} skipped, {dropped_frames:.0f} frames dropped; priority {p}")
        print(line.format(**tm, p=emu.priority) if tm.get("samples") else
              "device-emulator: stopped (no host connected)", file=sys.stderr)
        if usb is not None and usb.frames.decoder.stats.corrupted:
            print(f"device-emulator: {usb.frames.decoder.stats.corrupted} frames of the firmware did not "
                  "decode", file=sys.stderr)
        if emu.t_safe == emu.t_safe:
            print(f"device-emulator: the firmware's safe state from t = {emu.t_safe:.3f} s (fault at "
                  f"t = {world.t_fault:.3f} s)", file=sys.stderr)
        if writer is not None:
            print(f"device-emulator: {writer.rows} truth rows in {truth}", file=sys.stderr)

    return serve_until_stopped(emu, link, writer, rt_priority, started if verbose else None,
                               stopped if verbose else None)
