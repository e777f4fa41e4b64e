"""No traceback under an ASCII-only locale (issue 46): ``LC_ALL=C`` with Python's locale coercion
and UTF-8 mode off, as some service managers and containers start programs. Realtime and serial
runs used to end with ``UnicodeEncodeError`` at the summary's "µs" (a fault: exit 1 instead of
3), ``scenarios`` at its first "°". Every command's output now degrades to ASCII words there;
file names whose bytes the locale cannot decode are written and read (pyarrow takes them as an
open file) and shown in plot titles."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from thermoskin.cli.terminal import to_ascii
from thermoskin.logio import read_log

pytestmark = pytest.mark.usefixtures("compiled_estimator")

C_LOCALE = {**os.environ, "LC_ALL": "C", "LANG": "C", "PYTHONCOERCECLOCALE": "0", "PYTHONUTF8": "0",
            "PYTHONIOENCODING": "", "PYTHONUNBUFFERED": "1"}
C_LOCALE.pop("PYTHONIOENCODING")
CMD = [sys.executable, "-c", "from thermoskin.cli import main; main()"]
#: "bñ" in UTF-8: bytes an ASCII locale cannot decode
NAME = b"b\xc3\xb1"


def ascii_run(*args: str | bytes, cwd: Path, timeout: float = 300) -> subprocess.CompletedProcess[bytes]:
    p = subprocess.run([*CMD, *args], cwd=cwd, env=C_LOCALE, capture_output=True, timeout=timeout)
    for stream in (p.stdout, p.stderr):
        assert b"Traceback" not in stream, stream.decode("utf-8", "replace")
        stream.decode("ascii")  # every byte ASCII: the terminal gets what it can show
    return p


def test_the_interpreter_really_is_ascii(tmp_path: Path) -> None:
    p = subprocess.run([sys.executable, "-c", "import sys; print(sys.stdout.encoding, sys.flags.utf8_mode)"],
                       env=C_LOCALE, capture_output=True, text=True)
    assert p.stdout.split() == ["ascii", "0"] or p.stdout.split()[0].lower().startswith("ansi_x3.4")


def test_scenarios_and_help(tmp_path: Path) -> None:
    p = ascii_run("scenarios", cwd=tmp_path)
    assert p.returncode == 0
    assert b"degC" in p.stdout or b"deg" in p.stdout
    assert ascii_run("run", "--help", cwd=tmp_path).returncode == 0


def test_realtime_run_ends_with_its_summary(tmp_path: Path) -> None:
    p = ascii_run("run", "--realtime", "--duration", "1", "--log", "x.csv", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert b"lateness p50 " in p.stdout and b" us, p99 " in p.stdout
    assert len(read_log(tmp_path / "x.csv", required=("t",))["t"]) == 1000


def test_serial_run_with_a_fault_exits_3(tmp_path: Path) -> None:
    """A serial run over the emulator, a thermocouple opening at 1.5 s: the fault's one line and
    exit 3 (a traceback and 1 before), the loop's figures printed in ASCII."""
    link = tmp_path / "skin"
    emu = subprocess.Popen([*CMD, "device-emulator", "--link", str(link), "--fault", "tc-open@1.5"],
                           env=C_LOCALE, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        t_end = time.monotonic() + 60
        while not link.is_symlink():
            assert emu.poll() is None, emu.stderr.read() if emu.stderr else b""
            assert time.monotonic() < t_end
            time.sleep(0.02)
        cfg = tmp_path / "tolerant.toml"
        cfg.write_text("[safety]\nlink_timeout_s = 0.5\n")
        p = ascii_run("run", "--device", f"serial://{link}", "--duration", "10", "--log", "x.csv",
                      "--config", str(cfg), cwd=tmp_path)
    finally:
        emu.terminate()
        emu.wait(30)
    assert p.returncode == 3, p.stderr
    assert p.stderr.decode().strip().splitlines()[-1].startswith("thermoskin: fault: tc-open at t = ")
    assert b" us" in p.stdout


def test_names_the_locale_cannot_decode(tmp_path: Path) -> None:
    """simulate, observe (to Parquet), plot and a missing file, each named with bytes the locale
    cannot decode: written, read, plotted; the error one line."""
    assert ascii_run("simulate", "--duration", "2", "-o", NAME + b".csv", cwd=tmp_path).returncode == 0
    p = ascii_run("observe", NAME + b".csv", "-o", NAME + b".parquet", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert ascii_run("plot", NAME + b".parquet", cwd=tmp_path).returncode == 0
    assert (tmp_path / os.fsdecode(NAME + b".png")).stat().st_size > 10_000
    assert len(read_log(tmp_path / os.fsdecode(NAME + b".parquet"), required=("t", "q_i_hat"))["t"]) == 2000
    p = ascii_run("observe", b"no" + NAME + b".csv", "-o", b"o.csv", cwd=tmp_path)
    assert p.returncode == 2 and len(p.stderr.splitlines()) == 1


def test_ascii_words() -> None:
    """The words written by hand for each character; accents dropped; the rest '?'."""
    assert to_ascii("lateness p50 7 µs, 24 °C ± 0.1 K → ok") == "lateness p50 7 us, 24 degC +- 0.1 K -> ok"
    assert to_ascii("Müller, naïve, “quoted”, 1–2 …") == 'Muller, naive, "quoted", 1-2 ...'
    assert to_ascii("日本 \udcc3") == "?? ?"
