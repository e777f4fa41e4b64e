"""The onset CUSUMs' step signature ``mu`` against the filter itself, run twice.

At an onset the state takes ``jump * mu``, ``mu`` what remains in the filter's error of a
unit step of ``q_i`` at the CUSUM's last zero (``estimation.kernel``). The filter is linear
in its readings with gains that do not depend on them, so the estimates of two runs whose
readings differ by a step's response ``delta * H s`` (``s`` the step carried by the model,
``s <- Phi s`` from ``e_q``) differ by ``delta (s - mu)``: an independent computation of
``mu`` from two ordinary runs, here with 10 Hz boards (readings held, updates sparse).
"""

from __future__ import annotations

import numpy as np
import pytest

from thermoskin.estimation import kernel as K  # noqa: N812
from thermoskin.estimation.model import I_Q, I_TP, I_TW
from thermoskin.estimation.reference import ReferenceEstimator
from thermoskin.estimator import TouchEstimator
from thermoskin.params import load_config
from thermoskin.sim.conditions import get_condition
from thermoskin.sim.run import simulate

DELTA = 1e-3  # W: small, so that neither run sees a tank manoeuvre the other does not


def _case():  # type: ignore[no-untyped-def]
    cond = get_condition("boards-10hz", 77)
    cfg = cond.config(load_config())
    log = simulate(cond.scenario.with_duration(6.0), cfg)
    return cfg, log


@pytest.mark.parametrize("impl", ["kernel", "reference"])
def test_signature_is_the_difference_of_two_runs(impl: str) -> None:
    cfg, log = _case()
    t_s = cfg.sampling.t_s
    tables = ReferenceEstimator(cfg, t_s).tables
    e_q = np.eye(5)[I_Q]
    k0, n = 3000, 4500  # the step: in the prior of sample k0 + 1 on
    runs = []
    for stepped in (False, True):
        est = TouchEstimator(cfg) if impl == "kernel" else ReferenceEstimator(cfg, t_s)
        if impl == "kernel":  # idle (the kernel carries signatures only then), never warming up
            est.st[K.MODE] = K.IDLE
        s = np.zeros(5)  # the step carried by the model: s <- Phi s
        xs, mus, ss = [], [], []
        for k in range(n):
            v = float(log["v"][k])
            T_w, T_p = float(log["T_w"][k]), float(log["T_p"][k])
            if stepped:
                T_w += DELTA * s[I_TW]
                T_p += DELTA * s[I_TP]
            # a constant command far from T_w: never armed, so no CUSUM restarts but ours
            est.step(float(log["t"][k]), T_w, T_p, v, float(log["T_a"][k]), 90.0,
                     int(log["fresh"][k]))
            s = tables.Phi[tables.index(v)] @ s
            if k == k0:  # the step, and every CUSUM's signature, start here
                s = e_q.copy()
                if impl == "kernel":
                    K._mu_reset_all(est.st)
                else:
                    for c in est.cusums:
                        c.mu = e_q.copy()
            if impl == "kernel":
                xs.append(est.st[K.X:K.X + 5].copy())
                mus.append(K.signature(est.st, 0))
            else:
                xs.append(est.x.copy())
                mus.append(est.cusums[0].mu.copy())
            ss.append(s.copy())
        runs.append((np.array(xs), np.array(mus), np.array(ss)))
    (x1, _, _), (x2, mu, s_all) = runs
    ks = slice(k0, n)
    expected = DELTA * (s_all[ks] - mu[ks])
    assert np.abs((x2[ks] - x1[ks]) - expected).max() <= 1e-10  # rounding only (DELTA 1e-3)
    assert np.abs(expected).max() > 1e-5  # the step did show
    # the filter has learnt part of the step over 1.5 s of 10 Hz readings, not none nor all
    assert 0.05 < 1.0 - mu[-1][I_Q] < 0.95
