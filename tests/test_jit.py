"""The package's numba helpers (``thermoskin._jit``)."""

from __future__ import annotations

import platform

import numpy as np

from thermoskin._jit import fetch_add, njit, prange, prefetch_w


@njit(cache=False)
def _write_after_hint(a: np.ndarray, i: int) -> float:
    prefetch_w(a, i)
    prefetch_w(a, a.shape[0] - 1)
    a[i] = 2.5
    return a.sum()


def test_prefetch_is_a_hint_only() -> None:
    a = np.arange(100.0)
    expected = a.sum() - a[7] + 2.5
    assert _write_after_hint(a, 7) == expected
    assert a[7] == 2.5
    if platform.machine() in ("x86_64", "AMD64"):  # the instruction itself, where we know its name
        asm = _write_after_hint.inspect_asm(_write_after_hint.signatures[0])
        assert "prefetchw" in asm


@njit(cache=False, parallel=True)
def _claim_all(counter: np.ndarray, old: np.ndarray) -> None:
    for i in prange(old.shape[0]):
        old[i] = fetch_add(counter, 0, 1)


@njit(cache=False)
def _fetch_sub(c: np.ndarray) -> int:
    return fetch_add(c, 0, -(1 << 32))


def test_fetch_add_is_atomic_across_threads() -> None:
    """Every thread's add counts and each sees a value of its own: the values returned are
    0 .. n-1, each once (a plain read-then-write on two cores would lose adds and return
    some values twice), and the word ends at n. Also a negative add."""
    n = 200_000
    counter = np.zeros(3, dtype=np.int64)
    old = np.full(n, -1, dtype=np.int64)
    _claim_all(counter, old)
    assert counter[0] == n and counter[1] == 0
    np.testing.assert_array_equal(np.sort(old), np.arange(n))
    c = np.array([5], dtype=np.int64)
    assert _fetch_sub(c) == 5 and c[0] == 5 - (1 << 32)
