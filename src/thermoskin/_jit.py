"""numba, as the package's compiled modules import it: ``from thermoskin._jit import njit, prange``.

Importing numba through here loads its array registry without the BLAS probe
(:func:`thermoskin._numba_cache.skip_blas_probe`, which keeps ``scipy.linalg`` out of a short
``observe``) before any compiled call, so that no compiled module can forget it.
"""

from __future__ import annotations

from numba import njit, prange

from thermoskin._numba_cache import skip_blas_probe

skip_blas_probe()

__all__ = ["njit", "prange"]
