"""The device emulator over a real pseudo-terminal, seen from the serial host side."""

from __future__ import annotations

import itertools
import math
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest
import serial

from thermoskin.devices import protocol as proto
from thermoskin.devices.base import ChannelTracker, Device, DeviceError, Sample
from thermoskin.devices.emulator import TRUTH_COLUMNS, DeviceCore, FaultSpec, PtyEmulator, TruthWriter, main
from thermoskin.devices.serial_device import SerialDevice
from thermoskin.params import Config
from thermoskin.physics.finger import contact_profile
from thermoskin.sim.scenarios import SCENARIOS

pytestmark = pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs pseudo-terminals")

Start = Callable[..., tuple[PtyEmulator, Path]]


@pytest.fixture
def start_emulator(tmp_path: Path) -> Iterator[Start]:
    """Start emulators in threads; stop them and check that their links are gone."""
    running: list[tuple[PtyEmulator, threading.Thread]] = []

    def start(faults: tuple[str, ...] = (), tc_period: float = 0.1, scenario: str = "fingers",
              command_timeout: float = 0.5, name: str = "skin") -> tuple[PtyEmulator, Path]:
        # this test's thread is the host: a loaded machine may hold it up past the second
        # after which a silent host's session ends, which is not under test here
        core = DeviceCore(Config(), SCENARIOS[scenario], [FaultSpec.parse(f) for f in faults],
                          tc_period=tc_period, command_timeout=command_timeout, session_timeout=10.0)
        link = tmp_path / name
        emu = PtyEmulator(link, core)
        th = threading.Thread(target=emu.run, daemon=True)
        th.start()
        assert emu.ready.wait(5.0)
        running.append((emu, th))
        return emu, link

    yield start
    for emu, th in running:
        emu.stop()
        th.join(5.0)
        assert not th.is_alive()
        assert not emu.link.is_symlink(), "the link must be removed on exit"


def collect(dev: SerialDevice, seconds: float, command: tuple[float, float] | None = None,
            stop_on_loss: bool = False) -> list[Sample]:
    out: list[Sample] = []
    t_end = time.monotonic() + seconds
    while time.monotonic() < t_end:
        s = dev.read_sample(0.01)
        if s is None:
            if stop_on_loss and dev.link_lost:
                break
            continue
        out.append(s)
        if command is not None:
            dev.write_command(*command)
    return out


def test_a_write_that_went_out_is_no_link_fault(start_emulator: Start,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """A write whose bytes all went out, its thread then held up past the write timeout (a
    stalled process; a cold compile in another thread took the CI's handshake down this way), is
    no link fault: pyserial's own write raised "Write timeout" after writing everything."""
    _, link = start_emulator()
    dev = SerialDevice(str(link))
    real_write, slow = os.write, []

    def write_then_stall(fd: int, data: bytes) -> int:  # type: ignore[no-untyped-def]
        n = real_write(fd, data)
        if fd == dev._fd and threading.current_thread() is threading.main_thread():
            slow.append(n)
            time.sleep(0.6)
        return n

    monkeypatch.setattr(os, "write", write_then_stall)
    dev.open()
    try:
        assert slow and dev.ack is not None  # the HELLO went out slowly, and was answered
        dev.write_command(0.3, 0.141)
        assert collect(dev, 0.2)
    finally:
        monkeypatch.setattr(os, "write", real_write)
        dev.close()


def test_a_port_that_takes_nothing_is_a_link_fault() -> None:
    """No room in the port for the write timeout: a write fails (then a link fault), in about
    that time, not sooner and not never."""
    import tty

    from thermoskin.devices.serial_device import WRITE_TIMEOUT_S

    master, slave = os.openpty()
    tty.setraw(slave)
    os.set_blocking(slave, False)
    try:
        dev = SerialDevice(os.ttyname(slave))
        dev._fd = slave  # nobody reads the other side: the pty's queue fills
        t0 = time.monotonic()
        with pytest.raises(serial.SerialTimeoutException):
            dev._write(None, b"x" * (1 << 20))  # type: ignore[arg-type]
        assert WRITE_TIMEOUT_S - 0.01 <= time.monotonic() - t0 < WRITE_TIMEOUT_S + 1.0
    finally:
        os.close(master)
        os.close(slave)


def test_end_to_end_handshake_samples_commands(start_emulator: Start) -> None:
    emu, link = start_emulator(command_timeout=10.0)  # the watchdog is tested below
    dev = SerialDevice(str(link))
    assert isinstance(dev, Device)
    dev.open()
    try:
        assert dev.ack is not None and dev.ack.version == proto.PROTOCOL_VERSION
        assert dev.device_id == emu.core.device_id
        assert dev.tc_period == pytest.approx(0.1)
        before = collect(dev, 0.3)
        assert before and all(s.v == 0.0 and s.status & proto.ST_NO_COMMAND for s in before)
        got = collect(dev, 1.0, command=(0.3, 0.141))
        v_core = emu.core.v  # before close(): its SAFE switches the pump off
    finally:
        dev.close()
    samples = before + got
    # 1.3 s of wall clock (judged by the device's clock, not the wall's: a loaded machine
    # delivers them late or in a burst): contiguous device clock and sequence numbers
    assert len(samples) >= 300
    # sequence numbers: +1 a sample, +2 where the device answered a repeated HELLO in between
    # (the host repeats it every 0.2 s until the first answer; a loaded machine may answer late)
    steps = [b.seq - a.seq for a, b in itertools.pairwise(samples)]
    assert set(steps) <= {1, 2} and steps.count(2) <= 2
    t = [s.t for s in samples]
    assert t[0] == 0.0
    assert all(abs(b - a - 1e-3) < 1e-9 for a, b in itertools.pairwise(t))
    assert dev.decoder.stats.corrupted == 0
    # thermocouple boards at 10 Hz: fresh on every 100th sample, repeated values between
    fresh = [s for s in samples if s.fresh]
    assert [round(s.t, 3) for s in fresh] == [round(0.1 * i, 3) for i in range(len(fresh))]
    assert all(s.fresh == proto.CH_W | proto.CH_P | proto.CH_A for s in fresh)
    for a, b in itertools.pairwise(samples):
        if not b.fresh:
            assert (b.T_w, b.T_p, b.T_a) == (a.T_w, a.T_p, a.T_a)
    assert not any(s.stale or s.stuck for s in samples)
    # the pump command reached the device: applied v reported, and in the emulator's state
    last = got[-1]
    assert last.v == pytest.approx(0.141, rel=1e-6) and last.drive == pytest.approx(0.3, rel=1e-6)
    assert v_core == pytest.approx(0.141, rel=1e-6)
    assert last.status & (proto.ST_NO_COMMAND | proto.ST_SAFE | proto.ST_WATCHDOG) == 0
    # heating drive: the tank (T_p) warms
    assert fresh[-1].T_p > fresh[len(before) // 100].T_p + 0.05
    # close() sent SAFE
    time.sleep(0.05)
    assert emu.core.safe_latched and emu.core.v == 0.0 and emu.core.drive == 0.0


def test_a_repeated_hello_drops_no_sample(start_emulator: Start) -> None:
    """The host repeats HELLO every 0.2 s until answered; on a loaded machine the repeat can
    reach the device after its first answer, mid-stream: it is answered again, and no sample
    already queued is lost (the device clock stays contiguous)."""
    _emu, link = start_emulator()
    with SerialDevice(str(link)) as dev:
        first = collect(dev, 0.2, command=(0.0, 0.141))
        time.sleep(0.8)  # a busy host: the samples back up in the link and the device's queue
        # the late repeat of this session's HELLO (its id in its seq)
        dev._send(proto.Hello(dev.session_id, proto.PROTOCOL_VERSION, 1000), leading_zero=True)
        later = collect(dev, 0.6, command=(0.0, 0.141))
    samples = first + later
    t = [s.t for s in samples]
    assert all(abs(b - a - 1e-3) < 1e-9 for a, b in itertools.pairwise(t))
    steps = [b.seq - a.seq for a, b in itertools.pairwise(samples)]
    assert steps.count(2) == 1 and set(steps) == {1, 2}  # the second HELLO_ACK's number


def test_watchdog_safe_and_rehandshake(start_emulator: Start) -> None:
    _emu, link = start_emulator(command_timeout=0.2)
    with SerialDevice(str(link)) as dev:
        collect(dev, 0.2, command=(0.0, 0.141))
        quiet = collect(dev, 0.4)  # no commands: the watchdog stops the pump
        assert quiet[0].v > 0
        assert quiet[-1].v == 0.0 and quiet[-1].status & proto.ST_WATCHDOG
        resumed = collect(dev, 0.1, command=(0.0, 0.141))
        assert resumed[-1].v > 0 and not resumed[-1].status & proto.ST_WATCHDOG
        dev.safe()
        latched = collect(dev, 0.2, command=(0.5, 0.141))  # commands are ignored once SAFE
        assert latched[-1].status & proto.ST_SAFE and latched[-1].v == 0.0
        assert latched[-1].t > 0.5
        dev.open()  # a new session: the latch cleared, the device clock from zero again
        again = collect(dev, 0.1, command=(0.0, 0.141))
        assert again[0].t == 0.0 and again[-1].v > 0 and not again[-1].status & proto.ST_SAFE


@pytest.mark.parametrize("kind", ["tc-open", "nan-burst", "overtemp", "serial-drop", "tc-stuck"])
def test_fault_observed_by_host(start_emulator: Start, kind: str) -> None:
    t_f = 0.3
    for attempt in range(3):
        _emu, link = start_emulator(faults=(f"{kind}@{t_f}",), tc_period=0.05, name=f"skin{attempt}")
        dev = SerialDevice(str(link), link_timeout=0.05, stuck_after=5)
        dev.open()
        try:
            samples = collect(dev, 1.2 if kind != "serial-drop" else 0.8, command=(0.0, 0.141),
                              stop_on_loss=kind == "serial-drop")
            lost_at = time.monotonic() if kind == "serial-drop" else math.nan
        finally:
            dev.close()
        # the 50 ms link timeout taken before the fault: this loaded machine held the host (or
        # the emulator) past it, which is no fault under test; tried again (at most twice)
        if not (dev.link_lost and samples and samples[-1].t < t_f - 2e-3):
            break
    before = [s for s in samples if s.t < t_f - 1e-9]
    assert len(before) >= 250
    assert all(math.isfinite(s.T_w) and math.isfinite(s.T_p) and s.T_p < 40 for s in before)
    assert not any(s.stuck or s.status & proto.ST_OPEN_W for s in before)
    after = [s for s in samples if s.t >= t_f - 1e-9]
    if kind == "serial-drop":
        assert after == [] and dev.link_lost
        assert samples[-1].t == pytest.approx(t_f - 1e-3)
        assert lost_at - samples[-1].t_recv < 0.3  # detected within about link_timeout
        return
    first = after[0]
    assert first.t == pytest.approx(t_f) and first.fresh  # 0.3 s is a thermocouple update
    if kind == "tc-open":
        assert math.isnan(first.T_w) and first.status & proto.ST_OPEN_W
        assert [f.code for _, f in dev.faults] == [proto.F_TC_OPEN]
    elif kind == "nan-burst":
        assert all(math.isnan(x) for s in after for x in (s.T_w, s.T_p, s.T_a))
    elif kind == "overtemp":
        assert all(s.T_p > 44.0 for s in after) and all(math.isfinite(s.T_w) for s in after)
    elif kind == "tc-stuck":
        assert {s.T_w for s in after} == {before[-1].T_w}
        assert all(s.fresh & proto.CH_W for s in after if s.fresh)
        stuck = [s for s in after if s.stuck & proto.CH_W]
        # 5 equal fresh readings, the last good one (0.25 s) included: 3 updates after the onset
        assert stuck and stuck[0].t == pytest.approx(t_f + 3 * 0.05)
        assert not any(s.stuck & (proto.CH_P | proto.CH_A) for s in samples)


def test_bad_version_refused(start_emulator: Start) -> None:
    _, link = start_emulator()
    with serial.serial_for_url(str(link), timeout=0.5) as ser:
        ser.reset_input_buffer()
        ser.write(b"\x00" + proto.encode(proto.Hello(0, 99, 1000)))
        dec = proto.Decoder()
        acks: list[proto.Message] = []
        t_end = time.monotonic() + 2.0
        while not acks and time.monotonic() < t_end:
            acks = [m for m in dec.feed(ser.read(64)) if m.TYPE == proto.T_HELLO_ACK]
    assert acks and acks[0].status == proto.STATUS_BAD_VERSION  # type: ignore[union-attr]


def test_no_device_times_out(tmp_path: Path) -> None:
    with pytest.raises(DeviceError, match="cannot open"):
        SerialDevice(str(tmp_path / "nothing")).open()
    master, slave = os.openpty()
    try:  # a silent pty: no HELLO_ACK
        dev = SerialDevice(os.ttyname(slave), handshake_timeout=0.3)
        with pytest.raises(DeviceError, match="no HELLO_ACK"):
            dev.open()
    finally:
        os.close(master)
        os.close(slave)


def test_stale_link_replaced_and_file_refused(tmp_path: Path) -> None:
    link = tmp_path / "dev"
    link.symlink_to("/dev/pts/does-not-exist")
    emu = PtyEmulator(link, DeviceCore(Config(), SCENARIOS["none"]))
    emu.open_link()
    try:
        assert os.readlink(link) == emu.slave_name
    finally:
        emu.close_link()
    assert not link.is_symlink()
    link.write_text("not a link")
    assert main(str(link), "none", verbose=False) == 2
    assert link.read_text() == "not a link"


def test_link_in_use_is_not_taken_over(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A second emulator on the link of a running one refuses (exit 2, one line) and leaves the
    first one reachable; once the first is gone, its stale link is taken, even where its pty's
    number now belongs to another terminal."""
    link = tmp_path / "dev"
    first = PtyEmulator(link, DeviceCore(Config(), SCENARIOS["none"]))
    first.open_link()
    try:
        assert main(str(link), "none", verbose=False) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "is served by another emulator" in err[0]
        assert os.readlink(link) == first.slave_name
    finally:
        first.close_link()
    assert sorted(p.name for p in tmp_path.iterdir()) == [".dev.lock"]  # the link gone, the lock free
    # as a killed emulator leaves it: its link, its lock file (no longer held), and its pty
    # number perhaps taken by another terminal meanwhile
    other_master, other_slave = os.openpty()
    link.symlink_to(os.ttyname(other_slave))
    (tmp_path / ".dev.lock").write_text("")
    second = PtyEmulator(link, DeviceCore(Config(), SCENARIOS["none"]))
    second.open_link()
    try:
        assert os.readlink(link) == second.slave_name
    finally:
        second.close_link()
        os.close(other_master)
        os.close(other_slave)


def test_main_rejects_bad_arguments(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(str(tmp_path / "l"), "no-such-scenario") == 2
    assert "unknown scenario" in capsys.readouterr().err
    assert main(str(tmp_path / "l"), "none", ["melt@3"]) == 2
    assert "KIND@SECONDS" in capsys.readouterr().err
    assert main(str(tmp_path / "l"), "none", ["overtemp@soon"]) == 2
    assert not (tmp_path / "l").exists()


def test_core_thermocouple_period_and_faults() -> None:
    """Without I/O: fresh flags, counters, repeated values, fault onsets to the sample."""
    core = DeviceCore(Config(), SCENARIOS["one-finger"],
                      [FaultSpec("tc-stuck", 0.25), FaultSpec("overtemp", 0.5)], tc_period=0.1)
    core.on_message(proto.Hello(0))
    core.on_message(proto.Command(1, 0.0, 0.141))
    tracker = ChannelTracker(stale_after=0.15, stuck_after=3)
    msgs = [m for _ in range(800) for m in core.step()]
    samples = [m for m in msgs if isinstance(m, proto.SampleMsg)]
    assert len(samples) == 800 and [m.t_us for m in samples[:3]] == [0, 1000, 2000]
    fresh = [m for m in samples if m.fresh]
    assert [m.t_us for m in fresh] == [100_000 * i for i in range(8)]
    assert [m.counters[0] for m in fresh] == list(range(1, 9))
    flags = [tracker.update(m.t_us * 1e-6, (m.T_w, m.T_p, m.T_a), m.counters, m.fresh) for m in samples]
    assert [f[0] != 0 for f in flags] == [m.fresh != 0 for m in samples]
    assert not any(f[1] for f in flags)
    stuck_t = [m.t_us for m, f in zip(samples, flags, strict=True) if f[2]]
    assert stuck_t[0] == 400_000  # frozen at the 0.2 s reading: the 3rd equal one is at 0.4 s
    assert all(m.T_p > 44 for m in fresh if m.t_us >= 500_000)
    assert all(m.T_p < 30 for m in fresh if m.t_us < 500_000)


def test_tracker_marks_stale_channel() -> None:
    tr = ChannelTracker(stale_after=0.2)
    assert tr.update(0.0, (1.0, 2.0, 3.0), (1, 1, 1), 0) == (0b111, 0, 0)
    assert tr.update(0.1, (1.0, 2.0, 3.0), (1, 2, 2), 0) == (0b110, 0, 0)
    assert tr.update(0.25, (1.0, 2.0, 3.0), (1, 2, 2), 0) == (0, 0b001, 0)


def test_cli_process_links_and_stops_on_sigterm(tmp_path: Path) -> None:
    link = tmp_path / "skin"
    proc = subprocess.Popen([sys.executable, "-m", "thermoskin.devices.emulator", "--link", str(link),
                             "--scenario", "none", "--tc-period", "0.001"],
                            stderr=subprocess.PIPE, text=True)
    try:
        t_end = time.monotonic() + 30.0
        while not link.is_symlink() and time.monotonic() < t_end and proc.poll() is None:
            time.sleep(0.02)
        assert link.is_symlink()
        with SerialDevice(str(link)) as dev:
            got = collect(dev, 0.5, command=(0.0, 0.141))
        assert len(got) > 300
        assert all(s.fresh == 0b111 for s in got)  # a 1 kHz thermocouple board
    finally:
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    assert "stopped after" in err and "lateness" in err
    assert not link.is_symlink()


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_truth_file_from_a_real_emulator_process(tmp_path: Path, sig: signal.Signals) -> None:
    """--truth: one row per sample sent, t as the host logs it, flushed while running,
    complete at the stop, and the simulator's values (no command: drive 0, pump off)."""
    link, truth = tmp_path / "skin", tmp_path / "truth.csv"
    proc = subprocess.Popen([sys.executable, "-c", "from thermoskin.cli import main; main()",
                             "device-emulator", "--link", str(link), "--scenario", "fingers",
                             "--truth", str(truth)], stderr=subprocess.PIPE, text=True)
    try:
        t_end = time.monotonic() + 30.0
        while not link.is_symlink() and time.monotonic() < t_end and proc.poll() is None:
            time.sleep(0.02)
        assert link.is_symlink()
        with SerialDevice(str(link)) as dev:
            got = collect(dev, 0.8)  # no COMMAND: the device holds drive 0 and the pump off
        assert len(got) > 300
        time.sleep(1.1)
        mid = np.loadtxt(truth, delimiter=",", skiprows=1, ndmin=2)
        assert mid[-1, 0] >= got[-1].t  # flushed within a second of sending
    finally:
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    lines = truth.read_text().splitlines()
    assert lines[0] == "t,contact_true,q_i,n_fingers,T_g" == ",".join(TRUTH_COLUMNS)
    rows = np.loadtxt(truth, delimiter=",", skiprows=1, ndmin=2)
    n = rows.shape[0]
    assert f"stopped after {n} samples" in err and f"{n} truth rows" in err  # every sample sent
    np.testing.assert_array_equal(np.round(rows[:, 0] * 1e6), np.arange(n) * 1000)  # 0, 1 ms, ...
    assert n >= mid.shape[0] and {round(s.t * 1e6) for s in got} <= set(np.round(rows[:, 0] * 1e6))
    # the same values as the device core stepped here without commands
    core = DeviceCore(Config(), SCENARIOS["fingers"])
    core.on_message(proto.Hello(0))
    ref = []
    for _ in range(n):
        core.step()
        ref.append(core.truth)
    ref_a = np.array(ref)
    np.testing.assert_array_equal(rows[:, [1, 3]], ref_a[:, [1, 3]])
    np.testing.assert_allclose(rows[:, [2, 4]], ref_a[:, [2, 4]], rtol=1e-8, atol=1e-12)


def test_truth_rows_follow_the_touches_and_bad_truth_path(tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    core = DeviceCore(Config(), SCENARIOS["fingers"], command_timeout=100.0)
    core.on_message(proto.Hello(0))
    core.on_message(proto.Command(1, 0.1, 0.141))
    w = TruthWriter(tmp_path / "t.csv")
    for _ in range(6000):
        core.step()
        w.add(*core.truth)
    w.close()
    rows = np.loadtxt(tmp_path / "t.csv", delimiter=",", skiprows=1)
    G, T_f, n_f = contact_profile(SCENARIOS["fingers"].touches, np.arange(6000) * 1e-3)
    np.testing.assert_array_equal(rows[:, 1], G > 0)
    np.testing.assert_array_equal(rows[:, 3], n_f)
    np.testing.assert_allclose(rows[:, 2], G * (T_f - rows[:, 4]), rtol=1e-7, atol=1e-12)
    assert rows[5500, 2] > 0.1  # the first touch (5.0-7.0 s) brings heat
    assert main(str(tmp_path / "l"), "none", truth=tmp_path / "no" / "dir" / "t.csv", verbose=False) == 2
    assert "cannot write the truth file" in capsys.readouterr().err
    assert main(str(tmp_path / "l"), "none", jitter=-1.0, verbose=False) == 2
    assert main(str(tmp_path / "l"), "none", tc_period=0.1, jitter=0.06, verbose=False) == 2
    assert "jitter" in capsys.readouterr().err
    assert not (tmp_path / "l").exists()


def test_sessions_on_the_core_fresh_repeated_busy_and_ended() -> None:
    """A HELLO of a new id starts a fresh session (clock at zero, the plant from its start: the
    same readings as a new device's for the same commands); the session's own HELLO repeated
    restarts nothing; another id while the session is on is refused (STATUS_BUSY) and changes
    nothing; after a SAFE, or a second of the host's silence, a new id is taken."""

    def run(core: DeviceCore, n: int, seq0: int) -> list[proto.SampleMsg]:
        out = []
        for i in range(n):
            core.on_message(proto.Command(seq0 + i, 0.2, 0.141 if i < n // 2 else 0.0))
            out += [m for m in core.step() if isinstance(m, proto.SampleMsg)]
        return out

    fresh = DeviceCore(Config(), SCENARIOS["fingers"])
    assert fresh.on_message(proto.Hello(77))[0].status == proto.STATUS_OK  # type: ignore[union-attr]
    ref = run(fresh, 600, 78)

    core = DeviceCore(Config(), SCENARIOS["fingers"])
    assert core.on_message(proto.Hello(5))[0].status == proto.STATUS_OK  # type: ignore[union-attr]
    first = run(core, 900, 6)
    assert first[-1].t_us == 899_000
    # the session's HELLO again (answered late): answered, nothing restarts
    assert core.on_message(proto.Hello(5))[0].status == proto.STATUS_OK  # type: ignore[union-attr]
    assert core.sessions == 1 and core.step()[-1].t_us == 900_000  # type: ignore[union-attr]
    # another host while the session is on: refused, nothing changes
    ack = core.on_message(proto.Hello(99))[0]
    assert ack.status == proto.STATUS_BUSY and core.refused == 1  # type: ignore[union-attr]
    assert core.sessions == 1 and core.session_id == 5 and core.step()[-1].t_us == 901_000  # type: ignore[union-attr]
    # the host ends its session (SAFE): the next id is a fresh session from zero
    core.on_message(proto.Safe(1000))
    assert core.on_message(proto.Hello(99))[0].status == proto.STATUS_OK  # type: ignore[union-attr]
    assert core.sessions == 2 and core.session_id == 99 and not core.safe_latched
    second = run(core, 600, 100)
    assert [m.t_us for m in second] == [m.t_us for m in ref] == [1000 * i for i in range(600)]
    assert [(m.T_w, m.T_p, m.T_a, m.fresh, m.counters, m.v, m.drive) for m in second] == \
           [(m.T_w, m.T_p, m.T_a, m.fresh, m.counters, m.v, m.drive) for m in ref]
    # a host that falls silent (killed, unplugged): its session ends a second later
    for _ in range(round(core.session_timeout / core.t_s) - 2):
        core.step()
    assert core.live and not core.host_silent
    for _ in range(3):
        core.step()
    assert core.host_silent and not core.live
    assert core.on_message(proto.Hello(123))[0].status == proto.STATUS_OK  # type: ignore[union-attr]
    assert core.sessions == 3 and core.k == 0


def test_a_second_host_is_refused_while_a_session_is_on(start_emulator: Start) -> None:
    """Another `thermoskin run` on the port is told at once that the port is in use (the host
    locks it); another program that does not lock it gets HELLO_ACK status BUSY; the first
    host's session goes on undisturbed (its device clock continues)."""
    emu, link = start_emulator()
    with SerialDevice(str(link)) as dev:
        first = collect(dev, 0.3, command=(0.0, 0.141))
        with pytest.raises(DeviceError, match="in use by another program"):
            SerialDevice(str(link)).open()
        with serial.serial_for_url(str(link), timeout=0.05) as other:  # no lock
            other.write(b"\x00" + proto.encode(proto.Hello(424242, proto.PROTOCOL_VERSION, 1000)))
            dec, acks = proto.Decoder(), []
            t_end = time.monotonic() + 2.0
            while not acks and time.monotonic() < t_end:
                acks = [m for m in dec.feed(other.read(4096)) if m.TYPE == proto.T_HELLO_ACK]
                dev.write_command(0.0, 0.141)  # the first host keeps its session on
        assert acks and acks[0].status == proto.STATUS_BUSY  # type: ignore[union-attr]
        later = collect(dev, 0.3, command=(0.0, 0.141))
    assert emu.core.sessions == 1 and emu.core.refused == 1
    assert later and later[0].t > first[-1].t and later[-1].v > 0  # the same session, on


def test_truth_writer_restarts() -> None:
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        w = TruthWriter(Path(d) / "t.csv")
        w.add(0.0, 0, 0.0, 0, 24.0)
        w.add(0.001, 1, 0.1, 1, 24.1)
        w.flush()
        w.restart()
        w.add(0.0, 0, 0.0, 0, 23.0)
        w.close()
        assert (Path(d) / "t.csv").read_text().splitlines() == [",".join(TRUTH_COLUMNS),
                                                                 "0.000000,0,0,0,23"]
