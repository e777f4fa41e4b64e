"""Excitation log of the Peltier tank: schema, drive limits, noise, truth, speed."""

from __future__ import annotations

import numpy as np
import pytest

from thermoskin.params import Config
from thermoskin.physics.peltier import PeltierTank
from thermoskin.sim.excitation import COLUMNS, simulate_excitation


@pytest.fixture(scope="module")
def log():
    return simulate_excitation(Config(), duration=120.0, seed=1)


def test_schema_and_limits(log):
    assert set(COLUMNS) <= set(log)
    n = log["t"].size
    assert n == 120_000
    assert all(v.size == n for v in log.values())
    d = log["drive"]
    assert d.min() >= -1.0 and d.max() <= 1.0
    assert np.unique(d).size >= 4 and (np.diff(d) != 0).sum() >= 5
    assert np.all(log["v"] == 0.0)


def test_noise_and_truth(log):
    err = log["T_p"] - log["T_p_true"]
    assert 0.01 < err.std() < 0.04
    assert abs(err.mean()) < 0.005
    assert np.all(np.abs(log["T_a"] - 20.0) < 0.2)


def test_truth_matches_tank():
    cfg = Config()
    L = simulate_excitation(cfg, duration=5.0, seed=0, couple_skin=False)
    tank = PeltierTank(cfg.peltier, cfg.sampling.t_s)
    tank.reset(L["T_p_true"][0], L["T_sink"][0])
    for d in L["drive"][:-1]:
        tank.step(d, 20.0)
    assert tank.T_p == pytest.approx(L["T_p_true"][-1], abs=1e-12)


def test_drive_limits_from_config():
    cfg = Config().replace(control={"drive_min": -0.2, "drive_max": 0.3})
    L = simulate_excitation(cfg, duration=60.0, seed=0, large=0.9)
    assert L["drive"].min() >= -0.2 and L["drive"].max() <= 0.3


def test_progress_and_errors():
    seen = []
    simulate_excitation(Config(), duration=2.0, progress=seen.append)
    assert seen[-1] == 1.0 and len(seen) >= 10
    with pytest.raises(ValueError, match="duration"):
        simulate_excitation(Config(), duration=0.0)
