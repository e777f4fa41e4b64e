"""Fixtures shared by the tests that start `thermoskin` in processes of their own."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def compiled_estimator() -> None:
    """The estimator's compiled code (its kernel and the fit that dates a contact again) in
    numba's cache before a test starts `thermoskin run` processes and waits on them as on a
    run. On a cold cache (a fresh clone) each such process would first compile for 20-60 s,
    and a test that a worker happens to run first would wait past its limits."""
    import numpy as np

    from thermoskin.estimator import TouchEstimator, warm_up
    from thermoskin.params import load_config

    cfg = load_config()
    warm_up(cfg)  # new_state, run, the re-dating fit
    est = TouchEstimator(cfg)
    est.step(0.0, 24.0, 24.0, 0.0, 24.0)  # step
    x = np.full(3, 24.0)
    est.run(np.arange(3) * cfg.sampling.t_s, x, x, np.zeros(3), x)  # and finish


@pytest.fixture(scope="session")
def compiled_skin(tmp_path_factory: pytest.TempPathFactory) -> None:
    """What `run --skin` compiles (the skin's plant, the patches' estimators, the transport
    correction) in numba's cache, by a run of 50 ms: as :func:`compiled_estimator`, for the
    tests that wait on a skin's run (on a cold cache it would first compile for about a
    minute)."""
    import subprocess
    import sys
    from pathlib import Path

    forearm = Path(__file__).resolve().parents[1] / "examples" / "forearm.toml"
    log = tmp_path_factory.mktemp("compiled_skin") / "run.csv"
    subprocess.run([sys.executable, "-c", "from thermoskin.cli import main; main()", "run", "--skin",
                    str(forearm), "--duration", "0.05", "--log", str(log)],
                   check=True, capture_output=True, timeout=600)
