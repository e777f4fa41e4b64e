"""The matrix exponential by scaling and squaring with Padé approximants, in numpy alone.

Higham's algorithm (N. J. Higham, "The scaling and squaring method for the matrix exponential
revisited", SIAM J. Matrix Anal. Appl. 26(4), 2005, Algorithm 2.3); scipy's ``expm`` has since
moved to Al-Mohy and Higham's refinement (2009), which scales less on some non-normal
matrices of large norm. The estimator's matrices have small norms (``|A| t_s`` below 2), where
neither scales. It is here, and not taken from scipy, because ``import scipy.linalg``
costs about 0.15 s, more than the rest of ``thermoskin observe`` on a short log; the
estimator's tables (:func:`thermoskin.physics.network.discretize`,
:func:`thermoskin.estimation.model.van_loan`) need one exponential of a small matrix each.
The tests hold it to scipy's on the model's matrices and on random ones of every norm.
Estimation uses it (the tables, a skin's position fit); the simulator keeps scipy's, which
it imports anyway for its larger spatial models.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

# Padé [m/m] numerator coefficients b_0..b_m and the largest 1-norm for which degree m
# reaches double precision (Higham 2005, Table 2.3)
_B = {
    3: (120.0, 60.0, 12.0, 1.0),
    5: (30240.0, 15120.0, 3360.0, 420.0, 30.0, 1.0),
    7: (17297280.0, 8648640.0, 1995840.0, 277200.0, 25200.0, 1512.0, 56.0, 1.0),
    9: (17643225600.0, 8821612800.0, 2075673600.0, 302702400.0, 30270240.0, 2162160.0,
        110880.0, 3960.0, 90.0, 1.0),
    13: (64764752532480000.0, 32382376266240000.0, 7771770303897600.0, 1187353796428800.0,
         129060195264000.0, 10559470521600.0, 670442572800.0, 33522128640.0, 1323241920.0,
         40840800.0, 960960.0, 16380.0, 182.0, 1.0),
}
_THETA = {3: 1.495585217958292e-2, 5: 2.539398330063230e-1, 7: 9.504178996162932e-1,
          9: 2.097847961257068e0, 13: 5.371920351148152e0}


def expm(A: Array) -> Array:
    """``exp(A)`` of a real square matrix (Higham 2005, Algorithm 2.3)."""
    if np.iscomplexobj(A):
        raise ValueError("expm here is for real matrices")
    A = np.asarray(A, dtype=float)
    if A.ndim != 2 or A.shape[0] != A.shape[1]:
        raise ValueError(f"expm needs a square matrix, not shape {A.shape}")
    n = A.shape[0]
    if not np.all(np.isfinite(A)):
        raise ValueError("expm of a matrix with a NaN or infinite entry")
    norm = float(np.abs(A).sum(axis=0).max()) if n else 0.0
    eye = np.eye(n)
    for m in (3, 5, 7, 9):
        if norm <= _THETA[m]:
            b = _B[m]
            A2 = A @ A
            powers = [eye, A2]
            while len(powers) <= m // 2:
                powers.append(powers[-1] @ A2)
            U = A @ sum(b[2 * j + 1] * powers[j] for j in range(m // 2 + 1))
            V = sum(b[2 * j] * powers[j] for j in range(m // 2 + 1))
            return np.linalg.solve(V - U, V + U)
    s = max(0, math.ceil(math.log2(norm / _THETA[13])))
    A = A / 2.0**s
    b = _B[13]
    A2 = A @ A
    A4 = A2 @ A2
    A6 = A4 @ A2
    U = A @ (A6 @ (b[13] * A6 + b[11] * A4 + b[9] * A2)
             + b[7] * A6 + b[5] * A4 + b[3] * A2 + b[1] * eye)
    V = A6 @ (b[12] * A6 + b[10] * A4 + b[8] * A2) + b[6] * A6 + b[4] * A4 + b[2] * A2 + b[0] * eye
    R = np.linalg.solve(V - U, V + U)
    for _ in range(s):
        R = R @ R
    return R
