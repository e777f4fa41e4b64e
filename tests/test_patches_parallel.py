"""Many patches stepped in parallel: each core claims chunks of them, and every patch is
stepped exactly once a tick."""

from __future__ import annotations

import numpy as np
import pytest

from thermoskin._jit import njit, prange
from thermoskin.estimation import kernel as K  # noqa: N812


@njit(cache=False, parallel=True)
def _visit(claims: np.ndarray, visits: np.ndarray, thread: np.ndarray) -> None:
    """The claim loop of :func:`kernel.step_many_parallel`, each patch's step a visit count."""
    n = visits.shape[0]
    nw = K._claims_open(claims, n)
    for w in prange(nw):
        s = 0
        while True:
            lo, hi, s = K._claim(claims, w, s, n)
            if lo < 0:
                break
            for i in range(lo, hi):
                visits[i] += 1
                thread[i] = w


@pytest.mark.parametrize("ranges", [1, 2, 3, 7])
def test_every_patch_is_claimed_exactly_once(ranges: int) -> None:
    """However the claims fall between the threads, each patch is stepped once a tick, never
    twice nor skipped: patch counts below, at and around a chunk and many chunks, over many
    ticks (the claim words reopened each time). With more ranges than threads a thread takes
    what is left of the others' ranges from their backs: some patches are then stepped by a
    thread other than their range's owner."""
    claims = K.claim_words(ranges)
    stolen = 0
    for n in (1, K.CHUNK - 1, K.CHUNK, K.CHUNK + 1, 4 * K.CHUNK + 5, 1000):
        nch = -(-n // K.CHUNK)
        owner = np.repeat([next(r for r in range(ranges) if c < (r + 1) * nch // ranges)
                           for c in range(nch)], K.CHUNK)[:n]
        for _ in range(50):
            visits = np.zeros(n, dtype=np.int64)
            thread = np.full(n, -1, dtype=np.int64)
            _visit(claims, visits, thread)
            np.testing.assert_array_equal(visits, 1)
            stolen += int((thread != owner).sum())
    if ranges == 7:
        assert stolen > 0


def test_parallel_kernel_steps_each_patch_as_the_serial_one() -> None:
    """``step_many_parallel`` (every core, chunks claimed) against ``step_many`` (one loop, in
    patch order) on the same ticks: 150 patches (ten chunks, so a core may take some of the
    other's range), each with its own noise, two in three touched and one in three not,
    through warm-up, onset and release. The states, contact bits and ended contacts are equal
    bit for bit every tick, and one patch's state to the one-patch estimator's. Compiling the
    parallel kernel here is part of the test: it once failed in numba's parfor pass, and no
    test saw it."""
    from thermoskin.estimation.estimator import TouchEstimator
    from thermoskin.estimation.patches import PatchEstimators
    from thermoskin.params import load_config
    from thermoskin.sim.run import simulate
    from thermoskin.sim.scenarios import SCENARIOS

    cfg = load_config()
    n, n_s = 150, 9000
    dur = n_s * cfg.sampling.t_s + 0.5
    touched = simulate(SCENARIOS["one-finger"].with_duration(dur), cfg)
    quiet = simulate(SCENARIOS["none"].with_duration(dur), cfg)
    src = [quiet if i % 3 == 0 else touched for i in range(n)]
    rng = np.random.default_rng(7)
    cols = {c: np.stack([s[c][:n_s] for s in src], axis=1) for c in ("T_w", "T_p", "T_a", "v")}
    cols["T_w"] += rng.normal(0.0, 0.005, (n_s, n))  # each patch its own noise
    par, ser = PatchEstimators(cfg, n=n, parallel=True), PatchEstimators(cfg, n=n, parallel=False)
    assert par._claims is not None and ser._claims is None
    one = TouchEstimator(cfg)  # patch 1 alone, through the one-patch entry point
    nan, fresh = np.full(n, np.nan), np.full(n, 7, dtype=np.int64)
    ended = np.zeros(n, dtype=np.int64)
    for k in range(n_s):
        t = k * cfg.sampling.t_s
        rest = (cols["T_w"][k], cols["T_p"][k], cols["T_a"][k], nan)
        par.tick(t, *rest, par.index(cols["v"][k]), nan, fresh)
        ser.tick(t, *rest, ser.index(cols["v"][k]), nan, fresh)
        one.step(t, cols["T_w"][k, 1], cols["T_p"][k, 1], cols["v"][k, 1], cols["T_a"][k, 1])
        np.testing.assert_array_equal(par.codes, ser.codes)
        done = np.flatnonzero(ser.codes & K.C_ENDED)
        np.testing.assert_array_equal(par.EV[done], ser.EV[done])
        ended[done] += 1
    np.testing.assert_array_equal(par.ST, ser.ST)
    np.testing.assert_array_equal(ser.ST[1], one.st)
    # the touched patches' contacts ended, the others' never began
    assert (ended[1::3] >= 1).all() and (ended[2::3] >= 1).all() and (ended[::3] == 0).all()


def _two_models(n: int, n_s: int, seed: int):  # type: ignore[no-untyped-def]
    """Two models (the default; a sheet half as thick and another detector design), a
    one-finger log of ``n_s`` samples, and each of ``n`` patches its own noise on its T_w."""
    import dataclasses

    from thermoskin.params import load_config
    from thermoskin.sim.run import simulate
    from thermoskin.sim.scenarios import SCENARIOS

    a = load_config()
    b = dataclasses.replace(a, skin=dataclasses.replace(a.skin, C_g=0.5 * a.skin.C_g),
                            detector=dataclasses.replace(a.detector, dq_design=2.0 * a.detector.dq_design))
    log = simulate(SCENARIOS["one-finger"].with_duration(n_s * a.sampling.t_s + 0.5), a)
    rng = np.random.default_rng(seed)
    T_w = log["T_w"][:n_s, None] + rng.normal(0.0, 0.005, (n_s, n))
    return a, b, log, T_w, rng


def _assert_each_as_alone(mixed, cfgs, log, T_w, step_mixed=None) -> None:  # type: ignore[no-untyped-def]
    """Patches of each model alone (one estimator a model, every patch of it), stepped a sample
    at a time on the same readings (and ``step_mixed(k, rest, v)`` with them): each patch of
    ``mixed`` equals the same patch among its model's alone, bit for bit."""
    from thermoskin.estimation.patches import PatchEstimators

    n, n_s = T_w.shape[1], T_w.shape[0]
    t_s = cfgs[0].sampling.t_s
    alone = {c: PatchEstimators(c, n=n, parallel=False) for c in set(cfgs)}
    nan, fresh = np.full(n, np.nan), np.full(n, 7, dtype=np.int64)
    for k in range(n_s):
        rest = (T_w[k], np.full(n, log["T_p"][k]), np.full(n, log["T_a"][k]), nan)
        v = np.full(n, log["v"][k])
        if step_mixed is not None:
            step_mixed(k * t_s, rest, v)
        for est in alone.values():
            est.tick(k * t_s, *rest, est.index(v), nan, fresh)
    for i, c in enumerate(cfgs):
        np.testing.assert_array_equal(mixed.ST[i], alone[c].ST[i], err_msg=f"patch {i}")
    first = [alone[c].ST[0] for c in alone]
    assert not np.array_equal(first[0], first[1])  # the two models do differ


@pytest.mark.parametrize("parallel", [False, True])
def test_patches_of_two_models_each_step_with_their_own(parallel: bool) -> None:
    """Patches of two models, in runs of eight, so that the model changes within a claimed
    chunk (of 16) and at the chunks' boundaries: the loops take a model's rows again only where
    it changes, so each patch must still be stepped with its own. Every patch's state equals,
    bit for bit, that of the same patch among patches of its model alone, stepped on the same
    readings."""
    from thermoskin.estimation.patches import PatchEstimators

    n, n_s = 70, 3000
    a, b, log, T_w, _ = _two_models(n, n_s, seed=11)
    cfgs = [b if (i // 8) % 2 else a for i in range(n)]
    mixed = PatchEstimators(cfgs, parallel=parallel)
    assert len(mixed.PR) == 2 and not np.array_equal(mixed._tabs[0][0], mixed._tabs[0][1])
    nan, fresh = np.full(n, np.nan), np.full(n, 7, dtype=np.int64)
    _assert_each_as_alone(mixed, cfgs, log, T_w,
                          lambda t, rest, v: mixed.tick(t, *rest, mixed.index(v), nan, fresh))


def test_rows_of_two_models_in_any_order_each_step_with_their_own() -> None:
    """``run_rows`` (a long-format log: one row a patch and sample) with patches of two models,
    the patches' order within each sample shuffled: each patch's state equals, bit for bit, the
    same patch's among patches of its model alone, stepped a sample at a time."""
    from thermoskin.estimation.patches import PatchEstimators

    n, n_s = 6, 2500
    a, b, log, T_w, rng = _two_models(n, n_s, seed=5)
    cfgs = [a, b, b, a, b, a]
    order = np.concatenate([rng.permutation(n) for _ in range(n_s)])
    k = np.repeat(np.arange(n_s), n)
    mixed = PatchEstimators(cfgs, parallel=False)
    mixed.run_rows(order, k * a.sampling.t_s, T_w[k, order], log["T_p"][:n_s][k], log["v"][:n_s][k],
                   log["T_a"][:n_s][k])
    _assert_each_as_alone(mixed, cfgs, log, T_w)


def test_patches_with_nothing_learnt_step_in_the_loops_without_it() -> None:
    """Patches whose sensors are as configured (``fixed_sensors``, a skin's) are stepped by the
    ``*_fixed`` loops, whose step has no learning code: on the same readings (a touched and an
    untouched log, each patch its own noise) their filter and detector (the state before the
    learnt fields), contact bits and ended contacts equal, bit for bit, those of the full loops
    stepping the same patches, serial, parallel and long-format alike; and one patch's contact
    estimate the plain-Python reference's (``estimation/reference.py``, written apart) to
    1e-9 W. A patch that learns is stepped by the full loops."""
    from thermoskin.estimation.model import fixed_sensors
    from thermoskin.estimation.patches import PatchEstimators
    from thermoskin.estimation.reference import ReferenceEstimator
    from thermoskin.params import load_config
    from thermoskin.sim.run import simulate
    from thermoskin.sim.scenarios import SCENARIOS

    learning = load_config()
    cfg = fixed_sensors(learning)
    assert not K.fixed(PatchEstimators(learning, n=2).PR)
    n, n_s = 40, 9000
    dur = n_s * cfg.sampling.t_s + 0.5
    touched = simulate(SCENARIOS["one-finger"].with_duration(dur), cfg)
    quiet = simulate(SCENARIOS["none"].with_duration(dur), cfg)
    src = [quiet if i % 2 == 0 else touched for i in range(n)]
    rng = np.random.default_rng(3)
    cols = {c: np.stack([s[c][:n_s] for s in src], axis=1) for c in ("T_w", "T_p", "T_a", "v")}
    cols["T_w"] += rng.normal(0.0, 0.005, (n_s, n))
    ser, par = PatchEstimators(cfg, n=n, parallel=False), PatchEstimators(cfg, n=n, parallel=True)
    assert K.fixed(ser.PR) and ser._step_many is K.step_many_fixed
    assert par._step_many_parallel is K.step_many_parallel_fixed
    full_st, full_codes, full_ev = ser.ST.copy(), ser.codes.copy(), ser.EV.copy()
    ref = ReferenceEstimator(cfg, cfg.sampling.t_s)
    nan, fresh = np.full(n, np.nan), np.full(n, 7, dtype=np.int64)
    worst, ended = 0.0, 0
    for k in range(n_s):
        t = k * cfg.sampling.t_s
        rest = (cols["T_w"][k], cols["T_p"][k], cols["T_a"][k], nan)
        iv = ser.index(cols["v"][k])
        ser.tick(t, *rest, iv, nan, fresh)
        par.tick(t, *rest, iv, nan, fresh)
        K.step_many(full_st, ser.PR, ser.mid, *ser._tabs, t, *rest, iv, nan, fresh, full_codes, full_ev)
        np.testing.assert_array_equal(ser.codes, full_codes)
        np.testing.assert_array_equal(par.codes, full_codes)
        done = np.flatnonzero(full_codes & K.C_ENDED)
        np.testing.assert_array_equal(ser.EV[done], full_ev[done])
        ended += len(done)
        ref.step(t, cols["T_w"][k, 1], cols["T_p"][k, 1], cols["v"][k, 1], cols["T_a"][k, 1])
        if ref.dq == ref.dq:
            worst = max(worst, abs(ser.ST[1, K.DQ] - ref.dq))
    np.testing.assert_array_equal(ser.ST[:, :K.RW], full_st[:, :K.RW])
    np.testing.assert_array_equal(par.ST[:, :K.RW], full_st[:, :K.RW])
    assert ended >= n // 2 and worst < 1e-9
    # the long-format loop: each patch's rows in turn within a sample
    rows = PatchEstimators(cfg, n=n, parallel=False)
    assert rows._run_rows is K.run_rows_fixed
    k = np.repeat(np.arange(n_s), n)
    p = np.tile(np.arange(n), n_s)
    out, _ = rows.run_rows(p, k * cfg.sampling.t_s, cols["T_w"][k, p], cols["T_p"][k, p],
                           cols["v"][k, p], cols["T_a"][k, p])
    np.testing.assert_array_equal(rows.ST[:, :K.RW], full_st[:, :K.RW])
    assert out["contact"].sum() > 0
