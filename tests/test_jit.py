"""The package's numba helpers (``thermoskin._jit``)."""

from __future__ import annotations

import platform

import numpy as np

from thermoskin._jit import njit, prefetch_w


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
