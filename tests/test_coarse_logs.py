"""Logs written slower than the loop ran: a logger keeping every n-th row of a run whose
thermocouples sit on 10 Hz boards.

Such a log loses the ``fresh`` bits of the readings that came between its rows (their values
still show), and a board's reading that made the controller switch the pump shows in the same
row as the switch, though it was taken before it. Before these were handled, a 10 Hz-board
run logged at 100 Hz lost 64 of 74 touches with its ``fresh`` column, and 10 without it.
"""

from __future__ import annotations

import numpy as np
import pytest

from thermoskin.analysis.evaluation import match_events
from thermoskin.analysis.observe import observe
from thermoskin.estimation.freshness import FreshInference, infer_fresh
from thermoskin.params import load_config
from thermoskin.sim.conditions import decimate, get_condition
from thermoskin.sim.run import simulate


def test_a_changed_value_is_fresh_whatever_the_column_says() -> None:
    t = np.arange(6) * 0.01
    T_w = np.array([20.0, 20.0, 20.5, 20.5, 20.5, 21.0])
    T_p = np.full(6, 24.0)
    T_a = np.array([19.0, np.nan, np.nan, 19.0, 19.0, 19.0])
    fresh = np.array([7, 0, 0, 0, 2, 0], dtype=float)  # the bits of rows 2, 3 and 5 were lost
    log = {"t": t, "T_w": T_w, "T_p": T_p, "T_a": T_a, "fresh": fresh}
    f, _ = infer_fresh(log)
    # by hand: T_w changed at rows 2 and 5, T_a at 1 (to NaN) and 3 (from NaN); row 4's T_p bit kept
    np.testing.assert_array_equal(f, [7, 4, 1, 4, 2, 1])
    # chunk by chunk, a change across the chunks' border counts
    inf = FreshInference()
    parts = [inf.feed({k: v[a:b] for k, v in log.items()}) for a, b in ((0, 2), (2, 5), (5, 6))]
    np.testing.assert_array_equal(np.concatenate(parts), f)


def test_a_log_as_the_loop_wrote_it_keeps_its_own_bits() -> None:
    cond = get_condition("boards-10hz", 31)
    log = simulate(cond.scenario.with_duration(5.0), cond.config())
    f, periods = infer_fresh(log)
    np.testing.assert_array_equal(f, log["fresh"].astype(np.int64))  # nothing added
    assert 95 <= periods["T_w"] <= 105


@pytest.mark.parametrize("keep_fresh", [True, False])
def test_boards_logged_at_100_hz_find_every_touch(keep_fresh: bool) -> None:
    """Every touch of a 10 Hz-board run logged at 100 Hz (seeds 4250-4251, not the bench's),
    with or without its ``fresh`` column, and no false alarm."""
    n = misses = fas = 0
    lat: list[float] = []
    for seed in (4250, 4251):
        cond = get_condition("boards-10hz", seed)
        cfg = cond.config(load_config())
        log = decimate(simulate(cond.scenario, cfg), 10)
        if not keep_fresh:
            del log["fresh"]
        m = match_events(cond.scenario.touches, observe(log, cfg).events)
        n += len(cond.scenario.touches)
        misses += m.misses
        fas += m.false_alarms
        lat += m.latencies.tolist()
    assert n >= 20 and misses == 0 and fas == 0, (n, misses, fas)
    assert np.median(lat) <= 0.45


def test_a_skin_logs_changed_values_are_fresh_too() -> None:
    """The skin's path (``observe --skin``, ``run --skin``) sets a thermocouple's bit where its
    value changed, per patch, block by block as on the whole log."""
    from types import SimpleNamespace

    from thermoskin.skin.layout import tc_fresh_bit
    from thermoskin.skin.observe import SkinFreshInference

    skin = SimpleNamespace(n_thermocouples=2)
    T_w = np.array([[20.0, 21.0], [20.0, 21.5], [20.5, 21.5], [20.5, 21.5]])
    T_w2 = np.array([[22.0, 23.0], [22.0, 23.0], [22.0, 23.0], [22.25, 23.0]])
    T_p = np.full((4, 2), 24.0)
    T_a = np.full((4, 2), 19.0)
    fresh = np.zeros((4, 2), dtype=np.int64)
    fresh[1, 0] = 2  # a tank reading the column kept
    cols = {"T_w": T_w, "T_w2": T_w2, "T_p": T_p, "T_a": T_a}
    b2 = tc_fresh_bit(1)
    expect = np.array([[7 | b2, 7 | b2], [2, 1], [1, 0], [b2, 0]])  # row 0: no row before it
    whole = SkinFreshInference(skin).feed({**cols, "fresh": fresh})  # type: ignore[arg-type]
    np.testing.assert_array_equal(whole, expect)
    inf = SkinFreshInference(skin)  # type: ignore[arg-type]
    parts = [inf.feed({**{k: v[a:b] for k, v in cols.items()}, "fresh": fresh[a:b]})
             for a, b in ((0, 1), (1, 4))]
    np.testing.assert_array_equal(np.vstack(parts), expect)


def test_a_log_without_bits_is_read_the_same_whole_or_in_chunks() -> None:
    """Without a ``fresh`` column each channel's rate is decided on its first 64 rows, so
    ``observe`` (the whole log) and ``observe`` of a file (chunks of any size) read the same
    bits, and a skin's patch reads them as a one-patch log does. By hand: a channel that moves
    on most rows is fresh everywhere from row 64 on (before, only where it changed); one held
    for 10 rows only where it changed; of rows 1-63 (row 0 is new by definition, not counted),
    one that changes on 32 is every sample from row 64, one that changes on 31 is not (were
    row 0 counted, 32 of 64 would tip it)."""
    from types import SimpleNamespace

    from thermoskin.skin.observe import SkinFreshInference

    n = 300
    rng = np.random.default_rng(5)
    fast = 20.0 + np.round(rng.normal(0.0, 0.02, n) * 128) / 128  # 1 kHz: equal values are common
    fast[63] = fast[62]  # the last row before the decision is not a change ...
    fast[64] = fast[63]  # ... nor the first after it
    held = np.repeat(20.0 + np.arange(n // 10) / 64, 10)
    steps = np.zeros(n)
    steps[1:64:2] = 1.0 / 64  # rows 1, 3, ..., 63: 32 changes of 63
    half = 20.0 + np.cumsum(steps) + np.where(np.arange(n) >= 64, np.arange(n) % 2 / 64, 0.0)
    steps[63] = 0.0  # 31 changes of 63 ...
    below = 20.0 + np.cumsum(steps) + np.where(np.arange(n) >= 64, np.arange(n) % 2 / 64, 0.0)
    below[64:] = below[64]  # ... and none later, so "where it changed" shows as no bit
    log = {"t": np.arange(n) * 1e-3, "T_w": fast, "T_p": held, "T_a": half, "T_w2": below}
    chans = [("T_w", 1), ("T_p", 2), ("T_a", 4), ("T_w2", 8)]

    def changes(x: np.ndarray) -> np.ndarray:
        return np.concatenate(([True], x[1:] != x[:-1]))

    assert changes(half)[1:64].sum() == 32 and changes(below)[1:64].sum() == 31
    assert not changes(fast)[63] and not changes(fast)[64]  # the border rows below are tested
    inf = FreshInference(chans)
    f = inf.feed(log)
    np.testing.assert_array_equal((f[:64] & 1) != 0, changes(fast)[:64])
    assert (f[64:] & 1).all()
    np.testing.assert_array_equal((f & 2) != 0, np.arange(n) % 10 == 0)
    np.testing.assert_array_equal((f[:64] & 4) != 0, changes(half)[:64])
    assert (f[64:] & 4).all()
    np.testing.assert_array_equal((f & 8) != 0, changes(below))  # where it changed, all along
    assert inf.periods == {"T_w": 1.0, "T_p": 10.0, "T_a": 1.0, "T_w2": 2.0}
    f3, periods = infer_fresh(log)  # the one-patch channels, whole
    assert periods == {"T_w": 1.0, "T_p": 10.0, "T_a": 1.0}
    np.testing.assert_array_equal(f3, f & 7)
    for cuts in ([0, 1, 2, 30], [63, 1], [64], [10, 90], [299]):
        inf, parts, k = FreshInference(chans), [], 0
        for m in [*cuts, n]:
            parts.append(inf.feed({c: v[k:k + m] for c, v in log.items()}))
            k += m
        np.testing.assert_array_equal(np.concatenate(parts), f)
    skin = SimpleNamespace(n_thermocouples=2)  # T_w2: a patch's second thermocouple, bit 8
    two = {c: np.column_stack([v, v[::-1]]) for c, v in log.items() if c != "t"}
    skin_bits = SkinFreshInference(skin).feed(two)  # type: ignore[arg-type]
    np.testing.assert_array_equal(skin_bits[:, 0], f)
    rev = FreshInference(chans).feed({c: v[::-1] for c, v in log.items()})
    np.testing.assert_array_equal(skin_bits[:, 1], rev)
