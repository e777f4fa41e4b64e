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
from thermoskin.estimation.estimator import TouchEstimator
from thermoskin.estimation.model import I_Q, I_TP, I_TW, fixed_sensors
from thermoskin.estimation.reference import ReferenceEstimator
from thermoskin.params import load_config
from thermoskin.sim.conditions import get_condition
from thermoskin.sim.run import simulate

DELTA = 1e-3  # W: small, so that neither run sees a tank manoeuvre the other does not


def _case():  # type: ignore[no-untyped-def]
    cond = get_condition("boards-10hz", 77)
    cfg = cond.config(load_config())
    log = simulate(cond.scenario.with_duration(6.0), cfg)
    return fixed_sensors(cfg), log  # the filter linear in its readings: nothing learnt


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
                        c.mu = np.eye(6)[I_Q]  # (six states: the bead's too)
            if impl == "kernel":
                xs.append(est.st[K.X:K.X + 5].copy())
                mus.append(K.signature(est.st, 0))
            else:
                xs.append(est.x[:5].copy())
                mus.append(est.cusums[0].mu[:5].copy())  # (its sixth: the pipe thermocouple's bead)
            ss.append(s.copy())
        runs.append((np.array(xs), np.array(mus), np.array(ss)))
    (x1, _, _), (x2, mu, s_all) = runs
    ks = slice(k0, n)
    expected = DELTA * (s_all[ks] - mu[ks])
    assert np.abs((x2[ks] - x1[ks]) - expected).max() <= 1e-10  # rounding only (DELTA 1e-3)
    assert np.abs(expected).max() > 1e-5  # the step did show
    # the filter has learnt part of the step over 1.5 s of 10 Hz readings, not none nor all
    assert 0.05 < 1.0 - mu[-1][I_Q] < 0.95


def test_carry_against_matrix_products() -> None:
    """One sample's carry of the six signatures (:func:`kernel._mu_carry`, one vector of them)
    against numpy's ``Phi (I - K_p H_p)(I - K_w H_w) mu``: a reading not made leaves its stale
    gain unused, and a signature restarted in the sample (a unit step of ``q_i``) becomes
    ``Phi``'s column exactly, though the carry applies the updates to it."""
    rng = np.random.default_rng(3)
    F = rng.normal(size=(5, 5))
    F[I_Q] = np.eye(5)[I_Q]  # q_i and dT_p are random walks: unit rows (as build_tables makes them)
    F[4] = np.eye(5)[4]
    kw, kp = rng.normal(size=5), rng.normal(size=5)
    H_w, H_p = np.eye(5)[I_TW], np.eye(5)[I_TP]
    for pipe_made in (True, False):
        st = K.new_state()
        mus = rng.normal(size=(K.NCU, 5))
        for j in range(K.NCU):
            st[K.MU + K.NCU * np.arange(5) + j] = mus[j]
        st[K.KUP], st[K.KUP + 1:K.KUP + 6] = (1.0 if pipe_made else 0.0), kw
        st[K.KUP + 6], st[K.KUP + 7:K.KUP + 12] = 1.0, kp
        K._mu_reset(st, 2)
        K._mu_carry(st, F)
        Aw = np.eye(5) - np.outer(kw, H_w) if pipe_made else np.eye(5)
        A = F @ (np.eye(5) - np.outer(kp, H_p)) @ Aw
        for j in range(K.NCU):
            if j == 2:
                assert np.array_equal(K.signature(st, j), F[:, I_Q])
            else:
                np.testing.assert_allclose(K.signature(st, j), A @ mus[j], rtol=1e-12, atol=1e-12)
