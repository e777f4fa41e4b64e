"""Discrete SISO filters from continuous transfer functions, streamed or over arrays.

``Iir`` discretises ``num(s)/den(s)`` with the bilinear (Tustin) transform
(:func:`bilinear`, ``s = 2 f_s (z - 1)/(z + 1)``) and runs it in transposed direct form II, the form
``scipy.signal.lfilter`` uses, so that the per-sample ``step`` and the array path
``run`` share one state layout and agree to rounding. The filter runs on the deviation
from the value it was reset at (``x - x0``, output ``dc x0 +``), so that large absolute
temperatures do not cost digits.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


def bilinear(num: Array, den: Array, fs: float) -> tuple[Array, Array]:
    """Tustin's map of ``num(s)/den(s)`` (coefficients highest power first) to ``b(z)/a(z)``.

    With ``n`` the order of ``den`` and ``k = 2 fs``, each ``c_j s^j`` becomes
    ``c_j k^j (z - 1)^j (z + 1)^(n - j)``; both polynomials are divided by ``a``'s leading
    coefficient (as ``scipy.signal.bilinear``, without importing ``scipy.signal``).
    """
    num = np.atleast_1d(np.asarray(num, dtype=float))
    den = np.atleast_1d(np.asarray(den, dtype=float))
    n = len(den) - 1
    k = 2.0 * fs

    def mapped(c: Array) -> Array:
        out = np.zeros(n + 1)
        for i, cj in enumerate(c[::-1]):  # cj multiplies s^i
            term = np.array([cj * k**i])
            for _ in range(i):
                term = np.convolve(term, [1.0, -1.0])
            for _ in range(n - i):
                term = np.convolve(term, [1.0, 1.0])
            out += term
        return out

    b, a = mapped(num), mapped(den)
    return b / a[0], a / a[0]


class Iir:
    """A proper SISO filter ``num(s)/den(s)`` discretised at ``t_s`` (Tustin)."""

    __slots__ = ("_a1", "_a2", "_a3", "_b0", "_b1", "_b2", "_b3", "_step", "_x0", "_y0",
                 "a", "b", "dc", "order", "z")

    def __init__(self, num: Array, den: Array, t_s: float) -> None:
        num = np.atleast_1d(np.asarray(num, dtype=float))
        den = np.atleast_1d(np.asarray(den, dtype=float))
        if len(num) > len(den):
            raise ValueError("improper transfer function")
        b, a = bilinear(num, den, fs=1.0 / t_s)
        n = len(a) - 1
        b = np.concatenate([np.zeros(n + 1 - len(b)), b]) if len(b) < n + 1 else b
        b, a = b / a[0], a / a[0]
        self.b: Array = b
        self.a: Array = a
        self.order = n
        self.dc = float(num[-1] / den[-1]) if den[-1] != 0 else float("inf")
        self.z: list[float] = [0.0] * n
        self._x0 = self._y0 = 0.0
        self._step = {0: self._step0, 1: self._step1, 2: self._step2, 3: self._step3}[n]
        self._coeffs()

    def _coeffs(self) -> None:
        b, a = self.b.tolist(), self.a.tolist()
        b += [0.0] * (4 - len(b))
        a += [0.0] * (4 - len(a))
        self._b0, self._b1, self._b2, self._b3 = b[:4]
        self._a1, self._a2, self._a3 = a[1:4]

    def reset(self, x0: float) -> None:
        """Steady state for a constant input ``x0`` (output ``dc * x0``)."""
        self.z = [0.0] * self.order
        self._x0 = x0
        self._y0 = self.dc * x0 if self.order else self._b0 * x0

    def step(self, x: float) -> float:
        """One sample."""
        return self._y0 + self._step(x - self._x0)

    def _step0(self, x: float) -> float:
        return self._b0 * x

    def _step1(self, x: float) -> float:
        z = self.z
        y = self._b0 * x + z[0]
        z[0] = self._b1 * x - self._a1 * y
        return y

    def _step2(self, x: float) -> float:
        z = self.z
        y = self._b0 * x + z[0]
        z[0] = self._b1 * x - self._a1 * y + z[1]
        z[1] = self._b2 * x - self._a2 * y
        return y

    def _step3(self, x: float) -> float:
        z = self.z
        y = self._b0 * x + z[0]
        z[0] = self._b1 * x - self._a1 * y + z[1]
        z[1] = self._b2 * x - self._a2 * y + z[2]
        z[2] = self._b3 * x - self._a3 * y
        return y

    def run(self, x: Array, x0: float) -> Array:
        """Filter a whole array, starting in steady state for ``x0``; leaves ``z`` at the end."""
        self.reset(x0)
        if self.order == 0:
            return self._b0 * np.asarray(x, dtype=float)
        from scipy.signal import lfilter  # 1 s of import: only where arrays are filtered

        y, zf = lfilter(self.b, self.a, np.asarray(x, dtype=float) - x0, zi=np.zeros(self.order))
        self.z = zf.tolist()
        return y + self._y0
