"""Many patches stepped in parallel, each core claiming chunks of them, are each the patch alone."""

from __future__ import annotations

import numpy as np
import pytest

from thermoskin.estimation import kernel as K  # noqa: N812
from thermoskin.params import load_config
from thermoskin.patches import PatchEstimators
from thermoskin.sim.run import simulate
from thermoskin.sim.scenarios import SCENARIOS


@pytest.mark.parametrize("ranges", [1, 2, 3, 7])
def test_parallel_step_is_the_serial_step_bit_for_bit(ranges: int) -> None:
    """:func:`kernel.step_many_parallel` gives every patch the state the serial loop gives it,
    bit for bit, through a touch: so each patch is stepped exactly once a tick (twice or never
    would move its clock, counters and estimate). With one claim range, with one a thread,
    and with more ranges than threads (a thread then takes what is left of the others' from
    their backs), and a patch count that is no multiple of the chunk."""
    cfg = load_config()
    n = 4 * K.CHUNK + 5
    m = 6500  # the touch begins at 5 s
    log = simulate(SCENARIOS["one-finger"].with_duration(m * 1e-3 + 0.5), cfg)
    rng = np.random.default_rng(7)
    T_w = log["T_w"][:m, None] + rng.normal(0.0, 0.005, (m, n))
    T_p = np.repeat(log["T_p"][:m, None], n, axis=1)
    T_a = np.repeat(log["T_a"][:m, None], n, axis=1)
    serial = PatchEstimators(cfg, n=n, parallel=False)
    par = PatchEstimators(cfg, n=n, parallel=True)
    par._claims = K.claim_words(ranges)
    nan = np.full(n, np.nan)
    fresh = np.full(n, 7, dtype=np.int64)
    iv = serial.index(np.full(n, log["v"][0]))
    started = 0
    for k in range(m):
        if k and log["v"][k] != log["v"][k - 1]:
            iv = serial.index(np.full(n, log["v"][k]))
        for pe in (serial, par):
            pe.tick(k * 1e-3, T_w[k], T_p[k], T_a[k], nan, iv, nan, fresh)
        np.testing.assert_array_equal(par.codes, serial.codes)
        started += int((serial.codes & K.C_STARTED).astype(bool).sum())
    assert started >= n // 2  # the touch was seen
    np.testing.assert_array_equal(par.ST, serial.ST)
