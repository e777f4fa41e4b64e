"""Fixtures shared by tests: the compiled estimator for `thermoskin` processes, Python's peak
allocation of a call. And the suite's setting for two cores shared by three workers."""

from __future__ import annotations

import compileall
import os
from collections.abc import Callable
from pathlib import Path

import pytest

# The parallel kernels' threads (OpenMP) wait for work at a barrier by spinning, by default. On
# two cores shared by three workers the spinning threads take the core from the other workers'
# tests, and a thread descheduled mid-barrier makes the others spin longer: the parallel tests
# took 37 s of CPU in the suite, 11 s alone. Waiting passively (a futex) costs some latency per
# tick and none of the other tests' CPU. Set before any worker or `thermoskin` process that the
# tests start loads the OpenMP runtime; a value already set is kept.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")


def pytest_configure(config: pytest.Config) -> None:
    """The package's bytecode, compiled once before the workers start. Where
    ``PYTHONDONTWRITEBYTECODE`` is set (some machines set it), every worker and every
    `thermoskin` process a test starts would otherwise compile the package's sources again
    (0.1-0.2 s each, a few hundred of them); Python reads bytecode already there whatever the
    setting."""
    if hasattr(config, "workerinput"):  # an xdist worker: the controller has done it
        return
    import thermoskin

    compileall.compile_dir(Path(thermoskin.__file__).parent, quiet=1)


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
