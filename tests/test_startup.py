"""The program's start-up: the cyclic collector paused while it loads, resumed for the work."""

from __future__ import annotations

import gc
import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import CliRunner

from thermoskin import startup
from thermoskin.cli import main
from thermoskin.logio import write_log
from thermoskin.params import load_config
from thermoskin.sim.run import simulate
from thermoskin.sim.scenarios import SCENARIOS


@pytest.fixture
def restored_gc() -> Iterator[None]:
    """The test process's collector as it was (enabled, nothing frozen) after the test."""
    was = gc.isenabled()
    yield
    startup._paused = False
    gc.unfreeze()
    gc.enable() if was else gc.disable()


def test_pause_and_resume(restored_gc: None) -> None:
    gc.enable()
    startup.pause()
    assert not gc.isenabled() and startup.paused()
    startup.resume()
    assert gc.isenabled() and not startup.paused()
    assert gc.get_freeze_count() > 0  # what the start-up made is kept out of collections
    frozen = gc.get_freeze_count()
    startup.resume()  # a second end changes nothing
    assert gc.get_freeze_count() == frozen


def test_a_collector_switched_off_by_the_caller_stays_off(restored_gc: None) -> None:
    gc.disable()
    startup.pause()
    assert not startup.paused()
    startup.resume()
    assert not gc.isenabled() and gc.get_freeze_count() == 0


def test_a_command_ends_the_start_up_as_it_begins(restored_gc: None) -> None:
    """Every command but ``observe`` resumes the collector before its own work (a device
    emulator or a run may last hours), whether it handles user errors or not."""
    startup.pause()
    res = CliRunner().invoke(main, ["scenarios"])
    assert res.exit_code == 0, res.output
    assert gc.isenabled() and not startup.paused()


PROBE = """
import gc, json, sys
made = []  # collections (any generation) before the exit's own, the command line's handler
exiting = []
gc.callbacks.append(lambda phase, info: phase == "start" and not exiting and made.append(1))
entry = sys.argv.pop(1)
import atexit
from thermoskin import startup
@atexit.register
def report():  # registered first: runs last, after the command's own exit handlers
    print(json.dumps({"collections": len(made), "enabled": gc.isenabled(), "frozen": gc.get_freeze_count(),
                      "paused": startup.paused()}), file=sys.stderr)
if entry == "program":
    from thermoskin.__main__ import main
else:
    from thermoskin.cli import main
try:
    main()
finally:
    exiting.append(1)
"""


def _probe(entry: str, *args: str) -> dict[str, object]:
    r = subprocess.run([sys.executable, "-c", PROBE, entry, *args], capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stderr.strip().splitlines()[-1])


def test_observe_starts_without_collections(tmp_path: Path, compiled_estimator: None) -> None:
    """The program pauses the collector: an ``observe`` of a short log makes no collection
    while it imports and loads its compiled code (the command line imported as a module,
    unpaused, makes over two hundred: about 60 ms), then runs its work with the collector on
    and what the start-up made frozen."""
    log = tmp_path / "short.csv"
    write_log(log, simulate(SCENARIOS["one-finger"].with_duration(2.0), load_config()))
    program = _probe("program", "observe", str(log), "-o", str(tmp_path / "program.csv"))
    module = _probe("module", "observe", str(log), "-o", str(tmp_path / "module.csv"))
    assert module["collections"] >= 100, module  # what the pause takes out
    assert program["collections"] <= 20, program  # those of the work after the start-up
    assert program["enabled"] and not program["paused"] and program["frozen"] > 100_000, program
    assert (tmp_path / "program.csv").read_bytes() == (tmp_path / "module.csv").read_bytes()


def test_a_cold_cache_ends_the_start_up_before_compiling(tmp_path: Path, restored_gc: None,
                                                         monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """On a cold cache ``observe`` compiles its kernel after the first chunk: the collector is
    on by then, so the compiler's garbage (millions of objects) is collected, not frozen."""
    from thermoskin import _numba_cache
    from thermoskin.analysis import observe as pipeline

    log = tmp_path / "short.csv"
    write_log(log, simulate(SCENARIOS["one-finger"].with_duration(2.0), load_config()))
    seen: list[tuple[bool, bool]] = []
    warm_up = pipeline.warm_up

    def watched(cfg):  # type: ignore[no-untyped-def]
        seen.append((gc.isenabled(), startup.paused()))
        warm_up(cfg)

    monkeypatch.setattr(_numba_cache, "has_compiled", lambda stem: False)
    monkeypatch.setattr(pipeline, "warm_up", watched)
    startup.pause()
    res = CliRunner().invoke(main, ["observe", str(log), "-o", str(tmp_path / "o.csv")])
    assert res.exit_code == 0, res.output
    assert seen == [(True, False)]
    assert "compiling the estimator" in res.stderr


def test_an_early_exit_turns_the_collector_back_on(restored_gc: None, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """``--help`` (or a usage error) ends before any command's start-up does; the program's
    entry still turns the collector back on, unfrozen, for a caller that goes on, and has the
    exit freeze what is left (as every command does: ``cli.app._freeze_at_exit``), so that the
    interpreter's teardown does not traverse the start-up's objects, all still young."""
    import atexit

    from thermoskin import cli
    from thermoskin.__main__ import main as program

    gc.enable()
    for args in (["--help"], ["observe", "--help"], ["nonsense"]):
        registered: list[object] = []  # the exit's handlers, as atexit keeps them (in order, twice if twice)

        def unregister(fn, reg=registered):  # type: ignore[no-untyped-def]
            reg[:] = [f for f in reg if f != fn]

        monkeypatch.setattr(atexit, "register", registered.append)
        monkeypatch.setattr(atexit, "unregister", unregister)
        monkeypatch.setattr(sys, "argv", ["thermoskin", *args])
        with pytest.raises(SystemExit):
            program()
        assert gc.isenabled() and not startup.paused() and gc.get_freeze_count() == 0, args
        assert registered == [cli.app._freeze_at_exit], args  # once, though observe --help asks twice


def test_a_failing_command_still_exits_cleanly(tmp_path: Path) -> None:
    """A user error during the start-up (the pause still on) is one line and exit 2."""
    r = subprocess.run([sys.executable, "-m", "thermoskin", "observe", str(tmp_path / "none.csv"),
                        "-o", str(tmp_path / "o.csv")], capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and r.stderr.startswith("thermoskin: error:") and "Traceback" not in r.stderr


WARM_UP = """
import sys
from thermoskin.estimation import redate
from thermoskin.estimation.estimator import warm_up
from thermoskin.params import load_config
warm_up(load_config(), fits=sys.argv[1] == "fits")
print(len(redate.trace.overloads), len(redate.pulse_sums.overloads))
"""


@pytest.mark.parametrize("fits", [True, False])
def test_warm_up_loads_the_fit_only_when_asked(fits: bool, compiled_estimator: None) -> None:
    """A live loop's warm-up loads the compiled fit that dates a contact again at its end (its
    sample must not wait for it); ``observe``'s (``fits=False``) leaves it to the first contact's
    end, which numba's dispatch then loads from the cache. In a process of its own: the test
    process has loaded it already."""
    r = subprocess.run([sys.executable, "-c", WARM_UP, "fits" if fits else "none"], capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    loaded = [int(x) for x in r.stdout.split()]
    assert loaded == ([1, 1] if fits else [0, 0]), loaded
