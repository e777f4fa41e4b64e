"""A compiled solver of the MPC's box-constrained QP (eqs. 9-11), for the batched sweep.

The QP of :mod:`thermoskin.control.mpc`::

    min_u  0.5 u'P u + q'u     subject to   lb <= u_i <= ub           (eqs. 9, 11)

with ``P`` positive definite, so its minimiser is unique: any exact method gives daqp's
answer up to rounding. Here a primal-dual active-set iteration (Hintermüller, Ito and
Kunisch 2002), warm started from the previous sample's active set as the live MPC's
daqp is. For an active set ``A`` (each ``u_i``, ``i in A``, at its bound ``b_i``) the
minimiser over the rest and its multipliers are, with ``u* = -P^-1 q`` (the
unconstrained optimum) and ``Pinv = P^-1``::

    A small:  Pinv[A, A] lam = b_A - u*_A,   u = u* + Pinv[:, A] lam,   grad_A = lam
    F small:  P[F, F] u_F = -(q_F + P[F, A] b_A),               grad_A = (P u + q)_A

(whichever of ``A`` and its complement ``F`` is smaller is factored, Cholesky). The set
is then corrected: a free ``u_i`` beyond a bound joins it, a bound whose multiplier pulls
inwards (``grad_i > 0`` at the upper bound, ``< 0`` at the lower) is released. No change:
the KKT conditions hold, ``u`` is the optimum. If the iteration has not settled after
``MAXIT`` rounds (it can cycle on a non-M-matrix ``P``), projected Gauss-Seidel, which
converges for any positive definite ``P``, finishes the job; ``fallbacks`` counts those.
"""

from __future__ import annotations

import math

import numpy as np

from thermoskin._jit import njit

MAXIT = 60
TOL = 1e-12


@njit(cache=True, forceinline=True)
def _chol_solve(M, r, m):
    """Solve ``M[:m, :m] x = r[:m]`` in place (``M`` symmetric positive definite; overwritten)."""
    for j in range(m):
        s = M[j, j]
        for k in range(j):
            s -= M[j, k] * M[j, k]
        d = math.sqrt(s) if s > 0.0 else 1e-300
        M[j, j] = d
        for i in range(j + 1, m):
            s = M[i, j]
            for k in range(j):
                s -= M[i, k] * M[j, k]
            M[i, j] = s / d
    for i in range(m):
        s = r[i]
        for k in range(i):
            s -= M[i, k] * r[k]
        r[i] = s / M[i, i]
    for i in range(m - 1, -1, -1):
        s = r[i]
        for k in range(i + 1, m):
            s -= M[k, i] * r[k]
        r[i] = s / M[i, i]


@njit(cache=True)
def box_qp(P, Pinv, q, ustar, lb, ub, W, u, M, r, idx, g):
    """Minimise ``0.5 u'Pu + q'u`` over ``lb <= u <= ub`` into ``u``; ``ustar = -P^-1 q``.

    ``W`` (int8, length H): the active set to start from (+1 upper, -1 lower, 0 free), left
    as the final one. ``M`` (H x H), ``r``, ``g`` (H), ``idx`` (int64, H): scratch.
    Returns the number of rounds, or ``-1`` when projected Gauss-Seidel had to finish.
    """
    H = q.shape[0]
    for it in range(MAXIT):
        na = 0
        for i in range(H):
            if W[i] != 0:
                na += 1
        if na == 0:
            for i in range(H):
                u[i] = ustar[i]
                g[i] = 0.0
        elif na <= H - na:
            m = 0
            for i in range(H):
                if W[i] != 0:
                    idx[m] = i
                    m += 1
            for a in range(m):
                ia = idx[a]
                r[a] = (ub if W[ia] > 0 else lb) - ustar[ia]
                for b in range(m):
                    M[a, b] = Pinv[ia, idx[b]]
            _chol_solve(M, r, m)
            for i in range(H):
                s = ustar[i]
                for a in range(m):
                    s += Pinv[i, idx[a]] * r[a]
                u[i] = s
                g[i] = 0.0
            for a in range(m):
                g[idx[a]] = r[a]
        else:
            m = 0
            for i in range(H):
                if W[i] == 0:
                    idx[m] = i
                    m += 1
            for i in range(H):
                if W[i] != 0:
                    u[i] = ub if W[i] > 0 else lb
            for a in range(m):
                ia = idx[a]
                s = -q[ia]
                for j in range(H):
                    if W[j] != 0:
                        s -= P[ia, j] * u[j]
                r[a] = s
                for b in range(m):
                    M[a, b] = P[ia, idx[b]]
            _chol_solve(M, r, m)
            for a in range(m):
                u[idx[a]] = r[a]
            for i in range(H):
                if W[i] != 0:
                    s = q[i]
                    for j in range(H):
                        s += P[i, j] * u[j]
                    g[i] = s
                else:
                    g[i] = 0.0
        changed = False
        for i in range(H):
            if W[i] == 0:
                if u[i] > ub + TOL:
                    W[i] = 1
                    changed = True
                elif u[i] < lb - TOL:
                    W[i] = -1
                    changed = True
            elif (W[i] > 0 and g[i] > TOL) or (W[i] < 0 and g[i] < -TOL):
                W[i] = 0
                changed = True
        if not changed:
            return it + 1
    # projected Gauss-Seidel from the clipped unconstrained optimum
    for i in range(H):
        u[i] = min(max(ustar[i], lb), ub)
    for _sweep in range(100000):
        delta = 0.0
        for i in range(H):
            s = q[i]
            for j in range(H):
                s += P[i, j] * u[j]
            x = min(max(u[i] - s / P[i, i], lb), ub)
            d = abs(x - u[i])
            if d > delta:
                delta = d
            u[i] = x
        if delta < 1e-14:
            break
    for i in range(H):
        W[i] = 1 if u[i] >= ub else (-1 if u[i] <= lb else 0)
    return -1


def solve(P: np.ndarray, q: np.ndarray, lb: float, ub: float,
          W: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    """:func:`box_qp` from Python (tests): ``(u, rounds)``."""
    H = len(q)
    Pinv = np.linalg.inv(P)
    ustar = -Pinv @ q
    W = np.zeros(H, dtype=np.int8) if W is None else W
    u = np.zeros(H)
    rounds = box_qp(P, Pinv, q, ustar, lb, ub, W, u, np.zeros((H, H)), np.zeros(H),
                    np.zeros(H, dtype=np.int64), np.zeros(H))
    return u, int(rounds)
