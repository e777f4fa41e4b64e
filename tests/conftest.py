"""Fixtures shared by tests: the compiled estimator for `thermoskin` processes, Python's peak
allocation of a call."""

from __future__ import annotations

from collections.abc import Callable

import pytest


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
