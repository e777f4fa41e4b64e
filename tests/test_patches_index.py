"""``PatchEstimators.index``: the pump velocity of every row of a long-format block to its table."""

from __future__ import annotations

import numpy as np

from thermoskin.estimation.patches import PatchEstimators
from thermoskin.params import Config


def test_index_of_a_block_is_each_velocity_table_and_nan_none() -> None:
    """A block (looked up per distinct velocity) gives the row whose table is built for that very
    velocity, new velocities included, and -1 for NaN; short arrays (one at a time) agree."""
    pe = PatchEstimators(Config(), n=3)
    rng = np.random.default_rng(5)
    v = rng.choice([0.0, 0.141, 0.07, 0.1, np.nan], size=(400, 3))
    rows = pe.index(v)
    assert rows.shape == v.shape
    assert (rows[np.isnan(v)] == -1).all()
    fin = ~np.isnan(v)
    np.testing.assert_array_equal(np.asarray(pe.v_values)[rows[fin]], v[fin])
    for x in (0.0, 0.07, np.nan):
        assert pe.index(np.array([x]))[0] == rows[(v == x) | (np.isnan(v) & np.isnan(x))][0]
    many = np.linspace(0.01, 0.2, 100)  # more distinct velocities than the block's lookup saves
    r = pe.index(many)
    np.testing.assert_array_equal(np.asarray(pe.v_values)[r], many)


def test_run_rows_reuses_one_scratch_event_row_and_matches_one_patch(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """``run_rows`` hands the kernel the object's own scratch event row on every call (none
    allocated per call) and ``finish`` uses it too; outputs as before: each of two patches fed
    the same log over three calls gives the one-patch estimator's columns and contacts (one
    spanning two calls, one still open at the end, ended by ``finish``)."""
    from thermoskin.estimation import kernel as K  # noqa: N812
    from thermoskin.estimation.estimator import TouchEstimator
    from thermoskin.params import load_config
    from thermoskin.sim.run import simulate
    from thermoskin.sim.scenarios import SCENARIOS

    cfg = load_config()
    log = simulate(SCENARIOS["one-finger"].with_duration(14.0), cfg)  # touches at 5-7 s, 13-15.5 s
    keys = ("T_w", "T_p", "v", "T_a", "T_w_cmd")
    # a skin's patches keep the detector's dates (no re-dating at the contact's end)
    one = TouchEstimator(cfg.replace(detector={"redate_readings": 0.0})).run(
        log["t"], *(log[k] for k in keys), fresh=log["fresh"])
    assert len(one.events) == 2 and one.events[-1].release == log["t"][-1]  # the last: by finish

    seen: list[np.ndarray] = []
    run_rows = K.run_rows

    def spy(*args):  # type: ignore[no-untyped-def]
        seen.append(args[-1])
        return run_rows(*args)

    monkeypatch.setattr(K, "run_rows", spy)
    pe = PatchEstimators(cfg, n=2)
    n = len(log["t"])
    cols: dict[str, list[np.ndarray]] = {}
    for a, b in ((0, 6001), (6001, 9500), (9500, n)):  # the first contact (5.04-7.01 s) spans two
        sl = {k: np.repeat(log[k][a:b], 2) for k in ("t", *keys, "fresh")}
        out, _ = pe.run_rows(np.tile([0, 1], b - a), sl["t"], sl["T_w"], sl["T_p"], sl["v"], sl["T_a"],
                             T_w_cmd=sl["T_w_cmd"], fresh=sl["fresh"])
        for k, x in out.items():
            cols.setdefault(k, []).append(x)
    pe.finish(float(log["t"][-1]))
    assert len(seen) == 3 and all(x is pe._ev for x in seen)
    for k in ("q_i_hat", "dq_i_hat", "sd", "contact", "gap"):
        whole = np.concatenate(cols[k])
        for p in (0, 1):
            np.testing.assert_array_equal(whole[p::2], one.columns[k], err_msg=k)
    for p in (0, 1):
        assert [e for i, e in pe.events if i == p] == one.events
