"""Fixtures shared by tests: the compiled estimator for `thermoskin` processes, Python's peak
allocation of a call. And the suite's setting for two cores shared by three workers."""

from __future__ import annotations

import compileall
import fcntl
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

# The parallel kernels' threads (OpenMP) wait for work at a barrier by spinning, by default. On
# two cores shared by three workers the spinning threads take the core from the other workers'
# tests, and a thread descheduled mid-barrier makes the others spin longer: the parallel tests
# took 37 s of CPU in the suite, 11 s alone. Waiting passively (a futex) costs some latency per
# tick and none of the other tests' CPU. Set before any worker or `thermoskin` process that the
# tests start loads the OpenMP runtime; a value already set is kept.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")


WARM_LOCK = "THERMOSKIN_TESTS_WARM_LOCK"
"""The environment variable naming the lock the estimator's first compile holds (below)."""

LATER_LOCKS = "THERMOSKIN_TESTS_LATER_LOCKS"
"""The environment variable naming the locks of the later compiles (:data:`LATER`):
``group=path`` pairs joined by ``;``."""

_WARM_PROCS = pytest.StashKey[list]()  # type: ignore[type-arg]
_WARM = ("from thermoskin.estimation.estimator import warm_up; from thermoskin.params import "
         "load_config; warm_up(load_config())")

LATER: dict[str, tuple[str, ...]] = {
    "patches-fixed": ("thermoskin.estimation.kernel.run_rows_fixed",
                      "thermoskin.estimation.kernel.step_many_fixed", "thermoskin.estimation.kernel.finish"),
    "patches": ("thermoskin.estimation.kernel.step_many", "thermoskin.estimation.kernel.run_rows"),
    "parallel": ("thermoskin.estimation.kernel.step_many_parallel",
                 "thermoskin.estimation.kernel.step_many_parallel_fixed"),
    "sweep": ("thermoskin.sweep.kernel.run_rows", "thermoskin.sweep.qp.box_qp"),
}
"""The other entry points that inline the estimator's sample step (the patches' loops, the
sweep's batch), by group, in the order a second process of the controller's compiles them
while the workers run (:data:`_LATER`). In one process they take about 45 s of one core on a
fresh clone (the step's parts typed once); compiled by the first tests that call them, in
three workers and the `thermoskin` processes of the tests, they took about 95 s, one of them
twice at the same time. A worker's first compile of one of them waits for its group's lock
(:func:`_wait_for_later_compiles`), then loads it from numba's cache; a test that starts a
`thermoskin` process needing them waits with :func:`later_kernels`."""

_LATER = """
import os, sys
import numpy as np
from thermoskin.estimation.model import fixed_sensors
from thermoskin.estimation.patches import PatchEstimators
from thermoskin.params import load_config

fds = dict(kv.split("=") for kv in sys.argv[1].split(","))
cfg = load_config()
x2, x4 = np.full(2, 24.0), np.full(4, 24.0)


def patches(c, parallel):
    PatchEstimators(c, n=2, parallel=parallel).step(0.0, x2, x2, np.zeros(2), x2)


def rows(c):
    pe = PatchEstimators(c, n=2)
    pe.run_rows(np.array([0, 1, 0, 1]), np.array([0.0, 0.0, 1e-3, 1e-3]), x4, x4, np.zeros(4), x4)
    pe.finish(1e-3)


def done(group):
    os.close(int(fds[group]))


rows(fixed_sensors(cfg)); patches(fixed_sensors(cfg), False); done("patches-fixed")
patches(cfg, False); rows(cfg); done("patches")
patches(cfg, True); patches(fixed_sensors(cfg), True); done("parallel")
from thermoskin.sweep.engine import ScenarioSpec, run_chunk
run_chunk([(cfg, 1)], ScenarioSpec(duration=1.0, settle=0.5)); done("sweep")
"""


def _locked(path: Path) -> int:
    """A new lock file at ``path``, held (exclusively) by the open file returned."""
    fd = os.open(path, os.O_CREAT | os.O_RDWR, 0o600)
    fcntl.flock(fd, fcntl.LOCK_EX)
    return fd


def _compiling(code: str, locks: dict[str, Path]) -> subprocess.Popen:  # type: ignore[type-arg]
    """A process running ``code`` (its argument: ``group=fd`` pairs joined by ``,``) that holds
    each lock of ``locks`` from now on, until it closes that file or ends (the same open file:
    the lock is the child's once the parent has closed its copy)."""
    fds = {group: _locked(path) for group, path in locks.items()}
    try:
        arg = ",".join(f"{g}={fd}" for g, fd in fds.items())
        return subprocess.Popen([sys.executable, "-c", code, arg], pass_fds=tuple(fds.values()),
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    finally:
        for fd in fds.values():
            os.close(fd)


def _later_locks() -> dict[str, str]:
    """:data:`LATER_LOCKS` as ``{group: path}`` (empty where it is not set)."""
    return dict(kv.split("=", 1) for kv in os.environ.get(LATER_LOCKS, "").split(";") if kv)


def _wait(path: str, limit: float = 900.0) -> None:
    """Until the lock at ``path`` is free (at once if there is none), at most ``limit`` seconds:
    a compile that never ends must not hang the suite (the test then compiles for itself)."""
    try:
        with open(path) as fh:
            end = time.monotonic() + limit
            while True:
                try:
                    fcntl.flock(fh, fcntl.LOCK_SH | fcntl.LOCK_NB)
                    return
                except BlockingIOError:
                    if time.monotonic() > end:
                        return
                    time.sleep(0.05)
    except FileNotFoundError:
        pass


def pytest_configure(config: pytest.Config) -> None:
    """Before the workers start, in the controller:

    - the package's bytecode, compiled once. Where ``PYTHONDONTWRITEBYTECODE`` is set (some
      machines set it), every worker and every `thermoskin` process a test starts would
      otherwise compile the package's sources again (0.1-0.2 s each, a few hundred of them);
      Python reads bytecode already there whatever the setting;
    - the estimator's compiled code (about 17 s of one core on a fresh clone), compiled once
      by a process of its own while the workers collect, into numba's cache: otherwise each
      worker, on its first test of the estimator, compiles the same code at the same time.
      The process holds a lock until it ends; each worker waits for it before its first test
      (``_estimator_compiled_once``);
    - the other entry points of the sample step (:data:`LATER`), compiled by a second process
      meanwhile, on the core the waiting workers leave, and after, group by group.

    In a worker: its first compile of one of :data:`LATER` waits for that group."""
    if hasattr(config, "workerinput"):  # an xdist worker: the controller has done the rest
        locks = _later_locks()
        if locks:
            _wait_for_later_compiles(locks)
        return
    import thermoskin

    compileall.compile_dir(Path(thermoskin.__file__).parent, quiet=1)
    if not config.getoption("numprocesses", None):  # one process: it compiles as it goes
        return
    tmp = Path(tempfile.mkdtemp(prefix="thermoskin-tests-"))
    later = {group: tmp / f"{group}.lock" for group in LATER}
    procs = [_compiling(_WARM, {"warm": tmp / "warm.lock"}), _compiling(_LATER, later)]
    # the workers, started after this, inherit them
    os.environ[WARM_LOCK] = str(tmp / "warm.lock")
    os.environ[LATER_LOCKS] = ";".join(f"{g}={path}" for g, path in later.items())
    config.stash[_WARM_PROCS] = procs


def _wait_for_later_compiles(locks: dict[str, str]) -> None:
    """Make this worker's first compile of each of :data:`LATER` wait until the controller's
    second process has put it in numba's cache (or has ended): then it loads from there."""
    from numba.core.dispatcher import Dispatcher

    waits = {name: locks[group] for group, names in LATER.items() if group in locks for name in names}
    compile_ = Dispatcher.compile

    def compile(self, sig):  # type: ignore[no-untyped-def]
        path = waits.pop(f"{self.py_func.__module__}.{self.py_func.__qualname__}", None)
        if path is not None:
            _wait(path)
        return compile_(self, sig)

    Dispatcher.compile = compile  # type: ignore[method-assign]


def pytest_unconfigure(config: pytest.Config) -> None:
    procs = config.stash.get(_WARM_PROCS, None)
    if procs is None:
        return
    for proc in procs:
        if proc.poll() is None:
            proc.kill()
        proc.wait()
    tmp = Path(os.environ.pop(WARM_LOCK)).parent
    os.environ.pop(LATER_LOCKS, None)
    shutil.rmtree(tmp, ignore_errors=True)


@pytest.fixture(scope="session", autouse=True)
def _estimator_compiled_once() -> Iterator[None]:
    """A worker's first test waits until the controller's compile of the estimator has ended
    (:func:`pytest_configure`); after that, the code loads from numba's cache. Whether the
    compile succeeded does not matter here: a test that needs the code compiles what is not
    there."""
    path = os.environ.get(WARM_LOCK)
    if path:
        _wait(path)
    yield


@pytest.fixture(scope="session")
def later_kernels() -> Callable[..., None]:
    """``later_kernels(group, ...)``: wait until the controller's second process has compiled
    those groups of :data:`LATER` (at once where it has, or under ``-n 0``): for a test that
    starts `thermoskin` processes which run them (they would compile them again meanwhile)."""
    locks = _later_locks()

    def wait(*groups: str) -> None:
        for group in groups:
            if group not in LATER:
                raise KeyError(group)
            if group in locks:
                _wait(locks[group])

    return wait


@pytest.fixture(scope="session")
def compiled_estimator() -> None:
    """The estimator's compiled code (its kernel and the fit that dates a contact again) in
    numba's cache before a test starts `thermoskin run` processes and waits on them as on a
    run. On a cold cache (a fresh clone) each such process would first compile (about 10 s),
    and a test that a worker happens to run first would wait past its limits."""
    import numpy as np

    from thermoskin.estimation.estimator import TouchEstimator, warm_up
    from thermoskin.params import load_config

    cfg = load_config()
    warm_up(cfg)  # new_state, run, the re-dating fit
    est = TouchEstimator(cfg)
    est.step(0.0, 24.0, 24.0, 0.0, 24.0)  # step
    x = np.full(3, 24.0)
    est.run(np.arange(3) * cfg.sampling.t_s, x, x, np.zeros(3), x)  # and finish


@pytest.fixture
def peak_memory() -> Callable[[Callable[[], object]], int]:
    """``peak_memory(fn)``: Python's peak allocation (bytes, ``tracemalloc``) while ``fn()`` runs."""
    import tracemalloc

    def peak(fn: Callable[[], object]) -> int:
        tracemalloc.start()
        try:
            fn()
            return tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()

    return peak


@pytest.fixture(scope="session")
def serial_session() -> Callable[[str], tuple[dict, list]]:
    """``serial_session(name)``: a serial session recorded in ``tests/data/NAME.parquet`` (its
    readings and commands, 75 s of scenario ``fingers``) and the eight touches of that scenario
    that end in it."""
    from thermoskin.logio import read_log
    from thermoskin.sim.scenarios import SCENARIOS

    def load(name: str) -> tuple[dict, list]:
        log = read_log(Path(__file__).parent / "data" / f"{name}.parquet")
        touches = [t for t in SCENARIOS["fingers"].touches if t.t_off < log["t"][-1]]
        assert len(touches) == 8 and log["t"][-1] > 74.9
        return log, touches

    return load
