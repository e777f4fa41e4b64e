"""What the estimator should learn of a configuration's sensors, before any reading comes.

``thermoskin run`` says at its start whether a fingertip's touch would be below the noise of
the sensors it is told of (``[sensor]``: their noise, step and periods): :func:`expected`
simulates the skin with exactly those boards and no touch, at the run's command, for a few
seconds, runs the estimator over it and reads what it learnt (``estimation.learnt``), its
one-finger SNR included. Once the run's own readings have taught it more, the run says again
where they differ (``estimation.learnt.Watch``).
"""

from __future__ import annotations

import dataclasses

from thermoskin.estimation.estimator import TouchEstimator
from thermoskin.estimation.learnt import Learnt, learnt
from thermoskin.params import Config, SensorParams
from thermoskin.sim.run import simulate
from thermoskin.sim.scenarios import SCENARIOS


def expected(cfg: Config, T_w_cmd: float | None = None, seconds: float = 8.0,
             boards: SensorParams | None = None) -> Learnt:
    """What the estimator learns of ``boards`` (default: the configured ``[sensor]``, as the lab
    believes them) in ``seconds`` of no touch at ``T_w_cmd`` (default: the preset scenario's)
    on the simulated skin, the pump switching as it does in a loop."""
    sc = SCENARIOS["none"].with_duration(seconds)
    if T_w_cmd is not None:
        sc = dataclasses.replace(sc, T_w_cmd=float(T_w_cmd))
    log = simulate(sc, cfg, boards=boards)
    est = TouchEstimator(cfg.replace(detector={"redate_readings": 0.0}))
    est.run(log["t"], log["T_w"], log["T_p"], log["v"], log["T_a"], T_w_cmd=log["T_w_cmd"],
            fresh=log["fresh"])
    return learnt(est.st, cfg)
