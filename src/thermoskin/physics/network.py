"""The two-node thermal network of Fig. 3 (eqs. 3-7): state space and transfer functions.

State ``x = [T_w, T_g]`` (°C), input ``u = [T_p, T_a, q_x, T_f]``::

    C_w dT_w/dt = (T_p - T_w)/R_w - (T_w - T_a)/R_aw - (T_w - T_g)/R_g
    C_g dT_g/dt = (T_w - T_g)/R_g + q_i - (T_g - T_a)/R_ag
    q_i = q_x + G_c (T_f - T_g)

``q_x`` is a heat flow imposed on the sheet (W); ``G_c`` (W/K) is a contact conductance to
a body at ``T_f`` (the finger model). ``q_aw`` and ``q_ag`` are eqs. 3-4; ``q_p = (T_p -
T_w)/R_w`` with ``R_w`` from eq. 1.

Transfer functions are ``(num, den)`` coefficient arrays, highest power of ``s`` first
(the convention of ``scipy.signal``). With ``D(s) = R_g C_w C_g s^2 + (C_w + C_g) s``:

- eq. 5: ``T_w / (q_p - q_aw) = (R_g C_g s + 1) / D(s)``
- network ``q_i`` path: ``T_w / (q_i - q_ag) = 1 / D(s)``
- eq. 6 as printed: ``T_w / q_i = (R_g C_w s + 1)(R_g C_g s + 1) / D(s)``
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from thermoskin.params import SkinParams
from thermoskin.physics.expm import expm

Array = NDArray[np.float64]
TF = tuple[Array, Array]


def state_space(skin: SkinParams, R_w: float, G_c: float = 0.0) -> tuple[Array, Array]:
    """``(A, B)`` of the network for ``x = [T_w, T_g]``, ``u = [T_p, T_a, q_x, T_f]``."""
    Cw, Cg, Rg, Raw, Rag = skin.C_w, skin.C_g, skin.R_g, skin.R_aw, skin.R_ag
    A = np.array([
        [-(1 / R_w + 1 / Raw + 1 / Rg) / Cw, 1 / (Rg * Cw)],
        [1 / (Rg * Cg), -(1 / Rg + 1 / Rag + G_c) / Cg],
    ])
    B = np.array([
        [1 / (R_w * Cw), 1 / (Raw * Cw), 0.0, 0.0],
        [0.0, 1 / (Rag * Cg), 1 / Cg, G_c / Cg],
    ])
    return A, B


def discretize(A: Array, B: Array, t_s: float) -> tuple[Array, Array]:
    """Exact zero-order-hold discretisation ``x[k+1] = Phi x[k] + Gamma u[k]``.

    ``[[Phi, Gamma], [0, I]] = exp([[A, B], [0, 0]] t_s)`` (one matrix exponential).
    """
    A = np.atleast_2d(np.asarray(A, dtype=float))
    B2 = np.asarray(B, dtype=float).reshape(A.shape[0], -1)
    n, m = B2.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n] = A
    M[:n, n:] = B2
    E = expm(M * t_s)
    return E[:n, :n].copy(), E[:n, n:].copy()  # contiguous: the compiled kernel takes one layout


def steady_state(skin: SkinParams, R_w: float, u: Array, G_c: float = 0.0) -> Array:
    """Equilibrium ``x`` for a constant input ``u`` (solves ``A x + B u = 0``)."""
    A, B = state_space(skin, R_w, G_c)
    return np.linalg.solve(A, -B @ np.asarray(u, dtype=float))


def D_poly(skin: SkinParams) -> Array:
    """``D(s) = R_g C_w C_g s^2 + (C_w + C_g) s``."""
    return np.array([skin.R_g * skin.C_w * skin.C_g, skin.C_w + skin.C_g, 0.0])


def tf_pump_path(skin: SkinParams) -> TF:
    """Eq. 5: ``T_w / (q_p - q_aw) = (R_g C_g s + 1) / D(s)``."""
    return np.array([skin.R_g * skin.C_g, 1.0]), D_poly(skin)


def tf_touch_path(skin: SkinParams) -> TF:
    """The network's ``q_i`` path: ``T_w / (q_i - q_ag) = 1 / D(s)`` (docs/model.md)."""
    return np.array([1.0]), D_poly(skin)


def tf_touch_path_eq6(skin: SkinParams) -> TF:
    """Eq. 6 as printed: ``(R_g C_w s + 1)(R_g C_g s + 1) / D(s)``."""
    return np.polymul([skin.R_g * skin.C_w, 1.0], [skin.R_g * skin.C_g, 1.0]), D_poly(skin)


def Q_den(skin: SkinParams) -> Array:
    """``(R_g C_w s + 1)(R_g C_g s + 1)``, the observer's denominator (eq. 8)."""
    return np.polymul([skin.R_g * skin.C_w, 1.0], [skin.R_g * skin.C_g, 1.0])


def tf_Q(skin: SkinParams) -> TF:
    """The observer's unit-DC-gain low-pass ``Q(s) = 1 / ((R_g C_w s+1)(R_g C_g s+1))``."""
    return np.array([1.0]), Q_den(skin)
