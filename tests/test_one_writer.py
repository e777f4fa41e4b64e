"""One writer per output (issue 46): every command that writes takes an exclusive lock on each
of its outputs before any work; a second writer of the same path gets one line naming the
holder's pid and exit 2, and nothing of the first's is touched. Two real runs and two real
sweeps on one output; each writing command against a lock held by this test process; the lock
itself against a counter of processes inside it at once."""

from __future__ import annotations

import multiprocessing
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner

from thermoskin.cli import main
from thermoskin.logio import read_log, write_log
from thermoskin.paths import PathError, lock_file, lock_output

ROOT = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "PYTHONUNBUFFERED": "1"}
CMD = [sys.executable, "-c", "from thermoskin.cli import main; main()"]

pytestmark = pytest.mark.usefixtures("compiled_estimator")


def invoke(*args: str) -> tuple[int, str, str]:
    r = CliRunner().invoke(main, list(args))
    return r.exit_code, r.stdout, r.stderr


def _held(out: Path, pid: int) -> bool:
    """Whether process ``pid`` holds the lock on ``out``: its lock file names it, written just
    after the lock was taken (the file alone is made a moment before: a process stopped between
    the two holds nothing, and a second command then takes the lock and runs)."""
    try:
        return lock_file(out).read_text().startswith(f"{pid} ")
    except OSError:
        return False


def test_two_runs_on_one_log(tmp_path: Path) -> None:
    """The issue's case: a second `run --log` on the path of a run under way is refused at once
    (exit 2, one line with the first's pid); the first ends alone and its log reads back whole."""
    first = subprocess.Popen([*CMD, "run", "--duration", "20", "--log", "x.csv"], cwd=tmp_path,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV)
    try:
        t_end = time.monotonic() + 120
        while not _held(tmp_path / "x.csv", first.pid):
            assert first.poll() is None, first.communicate()
            assert time.monotonic() < t_end
            time.sleep(0.02)
        first.send_signal(signal.SIGSTOP)  # held under way, whatever this machine's speed
        try:
            second = subprocess.run([*CMD, "run", "--duration", "20", "--log", "x.csv"], cwd=tmp_path,
                                    capture_output=True, text=True, env=ENV, timeout=120)
        finally:
            first.send_signal(signal.SIGCONT)
        _, err = first.communicate(timeout=600)
    finally:
        if first.poll() is None:
            first.kill()
    assert second.returncode == 2, second.stderr
    assert second.stderr.strip() == (
        f"thermoskin: error: --log x.csv: another process is writing this log: thermoskin run (pid "
        f"{first.pid}); wait for it to end, or give another path")
    assert first.returncode == 0, err
    t = read_log(tmp_path / "x.csv", required=("t",))["t"]
    assert len(t) == 20_000 and np.all(np.diff(t) > 0)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.csv", "x.png"]  # no lock file left


def test_two_sweeps_on_one_output(tmp_path: Path, later_kernels) -> None:  # type: ignore[no-untyped-def]
    """Two sweeps on one output: the second is refused (it crashed with a traceback from the
    parts store); the first's results are whole. The first is held (SIGSTOP) once it has its lock,
    while the second runs: a sweep this small is done in seconds."""
    later_kernels("sweep")  # (compiled once for the suite, not again in each sweep's process)
    spec = tmp_path / "s.toml"
    spec.write_text('[sweep]\nsampler = "grid"\nchunk = 1\nseeds = [0, 1]\n[scenario]\nloop = "open"\n'
                    'duration = 30.0\nsettle = 2.0\ntouches = "one-finger"\n[keys]\n'
                    '"skin.R_g" = [7.0, 8.0, 9.0, 10.0, 11.0, 12.0]\n')
    out = tmp_path / "r.parquet"
    first = subprocess.Popen([*CMD, "sweep", str(spec), "-o", str(out)], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, env=ENV)
    try:
        t_end = time.monotonic() + 120
        while not _held(out, first.pid):
            assert first.poll() is None, first.communicate()
            assert time.monotonic() < t_end
            time.sleep(0.02)
        first.send_signal(signal.SIGSTOP)  # held in the middle of its work (it would be done in seconds)
        try:
            second = subprocess.run([*CMD, "sweep", str(spec), "-o", str(out)], capture_output=True,
                                    text=True, env=ENV, timeout=120)
        finally:
            first.send_signal(signal.SIGCONT)
        _, err = first.communicate(timeout=600)
    finally:
        if first.poll() is None:
            first.kill()
    assert second.returncode == 2, second.stderr
    lines = second.stderr.strip().splitlines()
    assert len(lines) == 1 and f"thermoskin sweep (pid {first.pid})" in lines[0], second.stderr
    assert first.returncode == 0, err
    assert pq.read_table(out).column("point").to_pylist() == list(range(12))


@pytest.fixture
def work(tmp_path: Path) -> Path:
    n = 3000
    t = np.arange(n) * 1e-3
    write_log(tmp_path / "in.csv", {"t": t, "T_w": np.full(n, 24.0), "T_p": np.full(n, 25.0),
                                    "v": np.full(n, 0.141), "T_a": np.full(n, 20.0)})
    from thermoskin.params import Config
    from thermoskin.runtime.closed_loop import COLUMNS
    from thermoskin.runtime.record import LoopRecorder

    rec = LoopRecorder(tmp_path / "in.mcap", Config())
    block = {c: np.zeros(1000) for c in COLUMNS}
    block["t"] = np.arange(1000) * 1e-3
    block["T_w"] = np.full(1000, 24.0)
    rec.write_rows(block)
    rec.close()
    cwd = Path.cwd()
    os.chdir(tmp_path)
    try:
        yield tmp_path
    finally:
        os.chdir(cwd)


COMMANDS = [
    (["run", "--duration", "1", "--log", "out.csv"], "--log", "out.csv"),
    (["run", "--duration", "1", "--log", "r.csv", "--record", "out.mcap"], "--record", "out.mcap"),
    (["run", "--duration", "1", "--log", "r.csv", "--events", "out.csv"], "--events", "out.csv"),
    (["observe", "in.csv", "-o", "out.csv"], "-o", "out.csv"),
    (["simulate", "--duration", "1", "-o", "out.csv"], "-o", "out.csv"),
    (["export", "in.mcap", "-o", "out.csv"], "-o", "out.csv"),
    (["replay", "in.mcap", "-o", "out.csv"], "-o", "out.csv"),
    (["plot", "in.csv", "-o", "out.png"], "-o", "out.png"),
    (["sweep", str(ROOT / "examples" / "sweep-small.toml"), "-o", "out.parquet"], "-o", "out.parquet"),
    (["identify", "in.csv", "-o", "out.toml"], "-o", "out.toml"),
]


@pytest.mark.parametrize(("args", "option", "held"), COMMANDS, ids=[f"{a[0]} {o}" for a, o, _ in COMMANDS])
def test_every_writer_is_refused_on_a_held_output(work: Path, args: list[str], option: str,
                                                  held: str) -> None:
    """Each writing command, its output locked by another writer (this process): one line naming
    it, exit 2, nothing written, the lock still held after."""
    (work / held).write_bytes(b"the other writer's\n")
    lock = lock_output(work / held, "-o", "file", "thermoskin other")
    assert lock is not None
    try:
        before = {p.name: p.read_bytes() for p in work.iterdir() if p.is_file()}
        code, _, err = invoke(*args)
        assert code == 2, err
        assert err.strip() == (f"thermoskin: error: {option} {held}: another process is writing this "
                               f"{_what(err)}: thermoskin other (pid {os.getpid()}); wait for it to end, "
                               "or give another path")
        assert {p.name: p.read_bytes() for p in work.iterdir() if p.is_file()} == before
    finally:
        lock.release()
    assert not lock_file(work / held).exists()


def _what(err: str) -> str:
    return err.split("another process is writing this ", 1)[1].split(": thermoskin other", 1)[0]


def test_a_lock_frees_a_folder_it_made_and_a_stale_lock_file_is_taken_over(tmp_path: Path) -> None:
    out = tmp_path / "new" / "deeper" / "x.csv"
    lock = lock_output(out, "-o")
    assert lock is not None and lock_file(out).read_text() == f"{os.getpid()} thermoskin\n"
    with pytest.raises(PathError, match=rf"-o {out}: another process is writing this file: thermoskin "
                                        rf"\(pid {os.getpid()}\)"):
        lock_output(out, "-o")
    lock.release()
    assert list(tmp_path.iterdir()) == []  # the folders it made, empty, are gone
    stale = tmp_path / ".y.csv.lock"
    stale.write_text("99999999 thermoskin run\n")  # left by a killed writer: no lock on it
    lock = lock_output(tmp_path / "y.csv", "-o")
    assert lock is not None
    lock.release()
    assert list(tmp_path.iterdir()) == []


def _worker(path: str, inside: str, rounds: int, q: multiprocessing.Queue) -> None:
    taken = clashes = 0
    for _ in range(rounds):
        try:
            lock = lock_output(Path(path), "-o")
        except PathError:
            continue
        try:  # inside: a file that only one process may hold at a time
            fd = os.open(inside, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            clashes += 1
        else:
            os.close(fd)
            os.unlink(inside)
        taken += 1
        lock.release()
    q.put((taken, clashes))


def test_the_lock_excludes_under_contention(tmp_path: Path) -> None:
    """Four processes take, hold and release the lock of one output 300 times each, the lock file
    removed at every release: never two inside at once (an O_EXCL file counts them)."""
    ctx = multiprocessing.get_context("fork")
    q: multiprocessing.Queue = ctx.Queue()
    procs = [ctx.Process(target=_worker, args=(str(tmp_path / "x.csv"), str(tmp_path / "inside"), 300, q))
             for _ in range(4)]
    for p in procs:
        p.start()
    got = [q.get(timeout=120) for _ in procs]
    for p in procs:
        p.join(60)
    assert sum(c for _, c in got) == 0
    assert sum(t for t, _ in got) > 0
