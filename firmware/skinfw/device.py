"""The skin device: sessions, the 1 kHz sample loop, the host's commands and its own safety.

Plain Python over a small hardware layer (``board``: the SPI bus with three MAX31856
converters, PWM and pins for the Peltier's H-bridge and the pump, the USB serial link, the
microsecond clock; ``board_rp2.py`` on a Raspberry Pi Pico, register-level models on the
host, ``thermoskin device-emulator --firmware``). It speaks docs/protocol.md, version 1.

**Per sample** (every ``T_S_US`` against absolute deadlines, :meth:`Device.tick`):

1. the host's COMMAND that came since the last sample is applied now, at the sample's start
   (H-bridge duty and direction, pump duty), so that the SAMPLE can say what holds over the
   period to come; a sample sent late (catching up after a stall) keeps the outputs as they
   were, and says so;
2. each converter whose ``DRDY`` is low is read (one 5-byte SPI transaction: the reading and
   its fault bits): a new reading, its counter moved, its ``fresh`` bit set. A sample sent
   more than ``READ_LATE_US`` late reads none: what converted during the stall is read by
   the first sample back on time, not dated into the samples owed before it. An open
   thermocouple or a range fault is a NaN reading, a FAULT frame and the safe state, as is a
   reading beyond the device's own limits (``config.TP_MIN/TP_MAX/TW_MAX``);
3. one SAMPLE (50 bytes on the wire) goes out: its fields live in a preallocated packet and
   are updated in place (device time += ``T_S_US``, ``seq`` += 1, CRC-16 by table, COBS):
   nothing is allocated.

**Its own safety**, whatever the host does: no COMMAND for ``WATCHDOG_US`` (50 ms), an
over-temperature or a converter fault: Peltier off and pump off at once, a FAULT frame,
latched until the next session. SAFE from the host does the same.

**Sessions.** A HELLO whose ``seq`` (the host's session id) is new starts a session: the
device clock at zero, no command yet (outputs off), the converters read afresh, the first
SAMPLE at once. The session's own HELLO repeated is answered again and restarts nothing.
Another id while a session is on (not ended by SAFE, its host heard within
``SESSION_TIMEOUT_US``) is refused: HELLO_ACK status 2 (busy). A session whose host fell
silent for ``SESSION_TIMEOUT_US`` ends: outputs off, no more SAMPLEs until a HELLO.
"""

import struct

from micropython import const

from skinfw import config as C  # noqa: N812
from skinfw import wire
from skinfw.max31856 import MAX31856, SR_OPEN, SR_RANGE

T_HELLO = const(0x01)
T_HELLO_ACK = const(0x02)
T_SAMPLE = const(0x10)
T_COMMAND = const(0x20)
T_SAFE = const(0x21)
T_FAULT = const(0x30)

ST_SAFE = const(0x0010)
ST_WATCHDOG = const(0x0020)
ST_OVERRUN = const(0x0040)
ST_NO_COMMAND = const(0x0080)

F_TC_OPEN = const(1)
F_OVERTEMP = const(2)
F_TC_RANGE = const(4)
F_WATCHDOG = const(5)

STATUS_OK = const(0)
STATUS_BAD_VERSION = const(1)
STATUS_BUSY = const(2)

# the SAMPLE packet (type | seq | body | crc): offsets
_P_SEQ = const(1)
_P_T = const(5)
_P_TW = const(13)
_P_FRESH = const(25)
_P_STATUS = const(26)
_P_COUNT = const(28)
_P_V = const(34)
_P_DRIVE = const(38)
_P_CMDSEQ = const(42)
_P_CRC = const(46)
SAMPLE_PACKET = const(48)
SAMPLE_FRAME = const(50)
"""A SAMPLE on the wire: COBS adds one byte to the 48, the delimiter another."""

_PLUS_ONE = b"\x00\x00\x80\x3f"
_MINUS_ONE = b"\x00\x00\x80\xbf"


class Device:
    """The device on a ``board`` (the hardware layer: see the module doc)."""

    def __init__(self, board):
        self.board = board
        self.tab = wire.crc_table()
        self.tc = [MAX31856(board.spi, board.cs[i], board.drdy[i], C.TC_TYPE, C.FILTER_50HZ)
                   for i in range(3)]
        self.tc_period_us = 98_000 if C.FILTER_50HZ else 82_000
        self.spkt = bytearray(SAMPLE_PACKET)
        self.spkt[0] = T_SAMPLE
        self.sout = bytearray(SAMPLE_FRAME + 2)
        self.sout_mv = memoryview(self.sout)[:SAMPLE_FRAME]
        self.xpkt = bytearray(32)
        self.xout = bytearray(40)
        self.rx = bytearray(256)
        self.fill = 0
        self.chunk = bytearray(64)
        self.pkt = bytearray(48)
        self.cmd = bytearray(8)
        self.cmd_seq = bytearray(4)
        self.sid = bytearray(4)
        self.host_seq = bytearray(4)
        self.session = False
        self.starting = False
        self.safe = False
        self.watchdog = False
        self.have_cmd = False
        self.pending = False
        self.open_mask = 0
        self.faults_sent = 0
        self.t_host = 0
        self.t_cmd = 0
        self.next_tick = 0
        # counts
        self.sessions = 0
        self.refused = 0
        self.samples = 0
        self.late = 0
        """Samples sent more than one period late (catching up after a stall)."""
        self.skipped = 0
        """Samples owed for longer than ``CATCHUP_US``: never sent (the clock went on)."""
        self.dropped = 0
        """Frames the USB link had no room for."""
        self.bad_frames = 0
        self.tc_ok = [False, False, False]
        self.outputs_off()

    # -- start ------------------------------------------------------------------------------
    def begin(self):
        """Outputs off, the converters configured; whether each answers (``tc_ok``)."""
        self.outputs_off()
        for i in range(3):
            self.tc_ok[i] = bool(self.tc[i].begin())
        self.next_tick = self.board.ticks_us()

    def run(self):
        """The main loop, for as long as the board lives (for ever on a microcontroller)."""
        b = self.board
        self.begin()
        while b.alive():
            b.feed()
            d = self.step()
            if d > 0:
                b.wait(d)

    def step(self):
        """One pass of the loop: the host's bytes, then the sample if it is due; the µs to the
        next sample (> 0: nothing due)."""
        b = self.board
        now = b.ticks_us()
        self.read_host(now)
        late = b.ticks_diff(now, self.next_tick)
        if late < 0:
            return -late
        self.tick(now, late)
        self.next_tick = b.ticks_add(self.next_tick, C.T_S_US)
        return 0

    # -- outputs ----------------------------------------------------------------------------
    def outputs_off(self):
        b = self.board
        b.peltier_pwm.duty_u16(0)
        b.peltier_dir.value(0)
        b.pump.duty_u16(0)

    def go_safe(self):
        """Peltier off, pump off, now; latched until the next session."""
        self.outputs_off()
        self.safe = True
        self.pending = False
        self._report_outputs(0, 0)

    def _report_outputs(self, drive, v):
        """The SAMPLE's applied ``drive`` and ``v`` fields: 0 (off), 1 (the command's own
        bytes), 2 (+/-1: the command's drive clamped)."""
        p = self.spkt
        if drive == 0:
            wire.put_u16(p, _P_DRIVE, 0)
            wire.put_u16(p, _P_DRIVE + 2, 0)
        elif drive == 1:
            wire.copy(self.cmd, 0, p, _P_DRIVE, 4)
        else:
            wire.copy(_MINUS_ONE if self.cmd[3] & 0x80 else _PLUS_ONE, 0, p, _P_DRIVE, 4)
        if v == 0:
            wire.put_u16(p, _P_V, 0)
            wire.put_u16(p, _P_V + 2, 0)
        else:
            wire.copy(self.cmd, 4, p, _P_V, 4)

    def apply(self):
        """The pending COMMAND to the H-bridge and the pump (and to the SAMPLE's fields)."""
        b, cmd = self.board, self.cmd
        q = wire.f32_fixed(cmd, 0, 16)  # |drive| in 1/65536; NaN: 0
        clamped = q > 65535
        duty = 65535 if clamped else q
        b.peltier_dir.value(0 if cmd[3] & 0x80 else 1)
        b.peltier_pwm.duty_u16(duty)
        qv = 0 if cmd[7] & 0x80 else wire.f32_fixed(cmd, 4, 16)
        if qv == 0:
            b.pump.duty_u16(0)
        elif C.PUMP_PWM:
            b.pump.duty_u16(wire.scale_duty(qv, C.V_FULL_Q16))
        else:
            b.pump.duty_u16(65535)
        self._report_outputs(0 if duty == 0 else (2 if clamped else 1), 0 if qv == 0 else 1)
        wire.copy(self.cmd_seq, 0, self.spkt, _P_CMDSEQ, 4)

    # -- the sample -------------------------------------------------------------------------
    def tick(self, now, late):
        """The sample due ``late`` µs ago (see the module doc)."""
        if not self.session:
            for tc in self.tc:  # the converters serviced, nothing sent
                if tc.ready():
                    tc.read()
            return
        b = self.board
        status = 0
        if late >= C.CATCHUP_US:  # owed too long: skipped (but this one), the clock goes on
            n = late // C.T_S_US
            self.skipped += n
            for _ in range(n):
                wire.add_le(self.spkt, _P_T, 8, C.T_S_US)
            self.next_tick = b.ticks_add(self.next_tick, n * C.T_S_US)
            late -= n * C.T_S_US
            status |= ST_OVERRUN
        if late >= C.T_S_US:
            status |= ST_OVERRUN
            self.late += 1
        force = 0
        if self.starting:
            self.starting = False
            b.session_started()
            force = 1
        if self.have_cmd and not self.safe and b.ticks_diff(now, self.t_cmd) > C.WATCHDOG_US:
            self.watchdog = True
            self._fault(F_WATCHDOG, 0, 0, True)
            self.go_safe()
        if self.pending and late < C.T_S_US and not self.safe:
            self.pending = False
            self.apply()
        fresh = 0
        read = late < C.READ_LATE_US  # a sample owed since a stall reads none (module doc)
        for i in range(3):
            tc = self.tc[i]
            if force or (read and tc.ready()):
                tc.read()
                self._reading(i)
                fresh |= 1 << i
        p = self.spkt
        p[_P_FRESH] = fresh
        status |= self.open_mask
        if self.safe:
            status |= ST_SAFE
        if self.watchdog:
            status |= ST_WATCHDOG
        if not self.have_cmd:
            status |= ST_NO_COMMAND
        wire.put_u16(p, _P_STATUS, status)
        self._send_sample()
        wire.add_le(p, _P_T, 8, C.T_S_US)
        if b.ticks_diff(now, self.t_host) > C.SESSION_TIMEOUT_US:
            self.end_session()

    def _reading(self, i):
        """The reading of converter ``i`` into the SAMPLE, its faults and limits checked."""
        tc, p = self.tc[i], self.spkt
        off = _P_TW + 4 * i
        sr = tc.sr
        wire.add_le(p, _P_COUNT + 2 * i, 2, 1)
        if sr & SR_OPEN:
            wire.put_nan(p, off)
            self.open_mask |= 1 << i
            self._fault(F_TC_OPEN, i, 0, True)
            self.go_safe()
            return
        if sr & SR_RANGE:
            wire.put_nan(p, off)
            self._fault(F_TC_RANGE, i, 0, True)
            self.go_safe()
            return
        raw = tc.raw
        wire.q7_to_f32(raw, p, off)
        if (i == 1 and (raw > C.TP_MAX or raw < C.TP_MIN)) or (i == 0 and raw > C.TW_MAX):
            self._fault(F_OVERTEMP, i, raw, False)
            self.go_safe()

    def _send_sample(self):
        p, out = self.spkt, self.sout
        wire.add_le(p, _P_SEQ, 4, 1)
        wire.put_u16(p, _P_CRC, wire.crc16(p, 0, _P_CRC, self.tab))
        n = wire.cobs_encode(p, SAMPLE_PACKET, out)
        out[n] = 0
        self.samples += 1
        if self.board.usb_write(self.sout_mv) < SAMPLE_FRAME:
            self.dropped += 1

    def _send(self, typ, body):
        """A frame other than SAMPLE (rare: allocation allowed), numbered by the same counter."""
        p = self.xpkt
        wire.add_le(self.spkt, _P_SEQ, 4, 1)
        p[0] = typ
        wire.copy(self.spkt, _P_SEQ, p, 1, 4)
        n = len(body)
        wire.copy(body, 0, p, 5, n)
        wire.put_u16(p, 5 + n, wire.crc16(p, 0, 5 + n, self.tab))
        m = wire.cobs_encode(p, 7 + n, self.xout)
        self.xout[m] = 0
        if self.board.usb_write(memoryview(self.xout)[:m + 1]) < m + 1:
            self.dropped += 1

    def _fault(self, code, channel, raw, nan):
        """One FAULT frame per fault and channel in a session (``raw``: the offending reading,
        1/128 K counts; ``nan``: no value)."""
        bit = 1 << (3 * code + channel)
        if self.faults_sent & bit:
            return
        self.faults_sent |= bit
        body = bytearray(7)
        body[0] = code
        body[2] = channel
        if nan:
            wire.put_nan(body, 3)
        else:
            wire.q7_to_f32(raw, body, 3)
        self._send(T_FAULT, body)

    # -- the host ---------------------------------------------------------------------------
    def read_host(self, now):
        """Take the bytes that came, decode whole frames, act on them."""
        b, rx, chunk = self.board, self.rx, self.chunk
        for _ in range(8):  # at most 512 bytes a pass
            n = b.usb_read(chunk)
            if n <= 0:
                return
            if self.fill + n > len(rx):  # no delimiter in 256 bytes: garbage, dropped
                self.fill = 0
                self.bad_frames += 1
            wire.copy(chunk, 0, rx, self.fill, n)
            self.fill += n
            start = 0
            while True:
                z = wire.find_zero(rx, start, self.fill)
                if z < 0:
                    break
                ln = z - start
                if 0 < ln <= 44:
                    m = wire.cobs_decode(rx, start, ln, self.pkt, 44)
                    if m >= 7 and wire.crc16(self.pkt, 0, m - 2, self.tab) == (
                            self.pkt[m - 2] | (self.pkt[m - 1] << 8)):
                        self.on_frame(m, now)
                    else:
                        self.bad_frames += 1
                elif ln:
                    self.bad_frames += 1
                start = z + 1
            rest = self.fill - start
            if rest and start:
                wire.move(rx, start, 0, rest)
            self.fill = rest
            if n < len(chunk):
                return

    def on_frame(self, m, now):
        """One whole host frame (``self.pkt[:m]``, its CRC checked)."""
        p = self.pkt
        typ = p[0]
        if typ == T_COMMAND and m == 15:
            if not self.session or wire.seq_newer(p, 1, self.host_seq, 0) <= 0:
                return
            wire.copy(p, 1, self.host_seq, 0, 4)
            self.t_host = now
            if self.safe:
                return
            wire.copy(p, 5, self.cmd, 0, 8)
            wire.copy(p, 1, self.cmd_seq, 0, 4)
            self.pending = True
            self.have_cmd = True
            self.t_cmd = now
        elif typ == T_SAFE and m == 9:
            if not self.session or wire.seq_newer(p, 1, self.host_seq, 0) <= 0:
                return
            wire.copy(p, 1, self.host_seq, 0, 4)
            self.t_host = now
            self.go_safe()
        elif typ == T_HELLO and m == 13:
            self.hello(now)
        else:
            self.bad_frames += 1

    def live(self, now):
        """A session another host may not take over: on, not ended by SAFE, heard from lately."""
        return (self.session and not self.safe
                and self.board.ticks_diff(now, self.t_host) <= C.SESSION_TIMEOUT_US)

    def hello(self, now):
        p = self.pkt
        version = p[5] | (p[6] << 8)
        same = self.session and wire.seq_newer(p, 1, self.sid, 0) == 0
        if version != C.PROTOCOL_VERSION:
            status = STATUS_BAD_VERSION
        elif same:
            status = STATUS_OK
            self.t_host = now
        elif self.live(now):
            status = STATUS_BUSY
            self.refused += 1
        else:
            status = STATUS_OK
            self.start_session(now)
        self._send(T_HELLO_ACK, struct.pack("<HHIII", C.PROTOCOL_VERSION, status, C.DEVICE_ID,
                                            C.T_S_US, self.tc_period_us))

    def start_session(self, now):
        """A fresh session for the HELLO in ``pkt``: clock at zero, outputs off, no command,
        faults cleared, the converters read afresh at its first sample (right away)."""
        p, s = self.pkt, self.spkt
        wire.copy(p, 1, self.sid, 0, 4)
        wire.copy(p, 1, self.host_seq, 0, 4)
        self.outputs_off()
        self.session = True
        self.starting = True
        self.safe = self.watchdog = self.have_cmd = self.pending = False
        self.open_mask = 0
        self.faults_sent = 0
        for i in range(_P_T, _P_T + 8):
            s[i] = 0
        self._report_outputs(0, 0)
        for i in range(_P_CMDSEQ, _P_CMDSEQ + 4):
            s[i] = 0
        self.t_host = now
        self.next_tick = now  # the session's first sample at once
        self.sessions += 1
        for tc in self.tc:  # faults latched in the converters from before
            tc.clear_faults()

    def end_session(self):
        """The host is gone: outputs off, no more SAMPLEs until a HELLO."""
        self.outputs_off()
        self.session = False
        self.board.session_ended()
