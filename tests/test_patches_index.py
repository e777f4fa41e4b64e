"""``PatchEstimators.index``: the pump velocity of every row of a long-format block to its table."""

from __future__ import annotations

import numpy as np

from thermoskin.params import Config
from thermoskin.patches import PatchEstimators


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
