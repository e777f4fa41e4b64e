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
