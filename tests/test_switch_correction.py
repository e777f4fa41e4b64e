"""The pump-cycle correction of T_w (``estimator.switch_bins``): it learns a misfit locked to the
pump's switches, and only that.

The network plant (``sim.run.simulate``) matches the estimator's model, so its no-touch
innovations have zero mean at every phase of the pump's cycle. A known pattern added to the
readings after each switch to more flow (a pipe of many cells lagging the lumped node, in
shape) must then be learned as itself, bin by bin, and nothing after switches the other way.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from thermoskin.estimation import kernel as K  # noqa: N812
from thermoskin.estimation.estimator import TouchEstimator
from thermoskin.estimation.model import fixed_sensors
from thermoskin.params import load_config
from thermoskin.sim.run import simulate
from thermoskin.sim.scenarios import SCENARIOS

NB = 64


def _phases(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Samples since the last change of ``v`` and whether that change was up (computed here)."""
    ph = np.zeros(v.size, dtype=int)
    up = np.zeros(v.size, dtype=bool)
    for k in range(1, v.size):
        if v[k] != v[k - 1]:
            ph[k], up[k] = 0, v[k] > v[k - 1]
        else:
            ph[k], up[k] = ph[k - 1] + 1, up[k - 1]
    return ph, up


def test_correction_learns_an_injected_switch_pattern() -> None:
    base = load_config()
    log = simulate(SCENARIOS["none"].with_duration(30.0), base)
    ph, up = _phases(log["v"])
    pattern = 0.04 * np.sin(np.pi * np.minimum(ph, 50) / 50.0)  # K, 40 mK at mid-phase
    T_w = log["T_w"] + np.where(up, pattern, 0.0)
    # nothing learnt of the sensors: the injected pattern is the correction's to learn alone
    cfg = fixed_sensors(dataclasses.replace(base, estimator=dataclasses.replace(base.estimator,
                                                                                switch_bins=NB)))
    est = TouchEstimator(cfg)
    est.run(log["t"], T_w, log["T_p"], log["v"], log["T_a"], log["T_w_cmd"], log["fresh"])
    tpl = est.st[K.TPL:K.TPL + 2 * NB].reshape(2, NB)
    # bin 0 is the reading the pump switched on (its noise chose the switch: biased, and
    # rightly learned); a constant over the whole cycle is not identifiable from the cycle
    # (the filter's states take part of the pattern's mean), so the comparison is up to one
    bins = np.arange(1, 50)
    truth = 0.04 * np.sin(np.pi * bins / 50.0)
    d = np.concatenate([tpl[0, bins] - truth, tpl[1, bins]])
    # 20 mK noise, one reading per bin per 100 ms cycle, weight 0.02: 2 mK of scatter per bin,
    # plus a few mK of the filter following the pattern within the cycle
    assert np.max(np.abs(d - np.median(d))) < 0.012, d
    assert abs(np.median(d)) < 0.04 * 2 / np.pi  # at most the pattern's mean
    # and the readings so corrected give no false event where the uncorrected model sees some
    assert not est.events
    plain = TouchEstimator(fixed_sensors(base))  # switch_bins 0: no correction (nor learning)
    plain.run(log["t"], T_w, log["T_p"], log["v"], log["T_a"], log["T_w_cmd"], log["fresh"])
    assert len(plain.events) >= 10
