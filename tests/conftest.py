"""Fixtures shared by tests: the compiled estimator for `thermoskin` processes, Python's peak
allocation of a call. And the suite's setting for two cores shared by three workers."""

from __future__ import annotations

import compileall
import fcntl
import os
import subprocess
import sys
import tempfile
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

_WARM_PROC = pytest.StashKey[subprocess.Popen]()  # type: ignore[type-arg]
_WARM = ("from thermoskin.estimation.estimator import warm_up; from thermoskin.params import "
         "load_config; warm_up(load_config())")


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
      (``_estimator_compiled_once``)."""
    if hasattr(config, "workerinput"):  # an xdist worker: the controller has done it
        return
    import thermoskin

    compileall.compile_dir(Path(thermoskin.__file__).parent, quiet=1)
    if not config.getoption("numprocesses", None):  # one process: it compiles as it goes
        return
    lock = Path(tempfile.mkdtemp(prefix="thermoskin-tests-")) / "warm.lock"
    fd = os.open(lock, os.O_CREAT | os.O_RDWR, 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)  # the child's from here: the same open file
        proc = subprocess.Popen([sys.executable, "-c", _WARM], pass_fds=(fd,),
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    finally:
        os.close(fd)
    os.environ[WARM_LOCK] = str(lock)  # the workers, started after this, inherit it
    config.stash[_WARM_PROC] = proc


def pytest_unconfigure(config: pytest.Config) -> None:
    proc = config.stash.get(_WARM_PROC, None)
    if proc is not None:
        if proc.poll() is None:
            proc.kill()
        proc.wait()
        lock = Path(os.environ.pop(WARM_LOCK))
        lock.unlink(missing_ok=True)
        lock.parent.rmdir()


@pytest.fixture(scope="session", autouse=True)
def _estimator_compiled_once() -> Iterator[None]:
    """A worker's first test waits until the controller's compile of the estimator has ended
    (:func:`pytest_configure`); after that, the code loads from numba's cache. Whether the
    compile succeeded does not matter here: a test that needs the code compiles what is not
    there."""
    path = os.environ.get(WARM_LOCK)
    if path and os.path.exists(path):
        with open(path) as fh:
            fcntl.flock(fh, fcntl.LOCK_SH)
    yield


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
