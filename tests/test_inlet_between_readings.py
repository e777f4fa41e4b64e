"""The inlet water between two readings of an upstream outlet (``skin_inlet``, slow boards).

Readings every few samples leave the water between them unread. Where that water is short
(``INTERP_M``) the inlet is the linear interpolation of the two readings, fresh; longer gaps,
and the tank's own readings, are held and not fresh, as before. Checked against the source's
true values on a ramp, where linear interpolation is exact (block by block: test_skin_live.py).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from thermoskin.skin.inlet import FRESH_T_P, INTERP_M, inlet_inputs
from thermoskin.skin.layout import load_skin

FOREARM = Path(__file__).resolve().parents[1] / "examples" / "forearm.toml"
T_S = 1e-3
V = 0.141


def _ramp_loop(every: int, n: int = 3000):
    """dorsal1's outlet reads a ramp, fresh every ``every`` samples and held between; the tank
    likewise; the pump runs at ``V`` throughout."""
    skin = load_skin(FOREARM)
    P = len(skin.patches)
    t = np.arange(n) * T_S
    f = 24.0 + 0.5 * t                        # the outlet water's true temperature, K
    held = f[(np.arange(n) // every) * every]
    T_w = [np.repeat(held[:, None], P, axis=1), np.full((n, P), math.nan)]
    T_p = np.repeat((25.0 + 0.2 * t)[(np.arange(n) // every) * every, None], P, axis=1)
    T_a = np.full((n, P), 20.0)
    v = np.full((n, P), V)
    bit = np.where(np.arange(n) % every == 0, 1 | FRESH_T_P | 4, 0)
    fresh = np.repeat(bit[:, None], P, axis=1).astype(np.int64)
    return skin, f, T_w, T_p, v, T_a, fresh


def test_short_gaps_are_interpolated_exactly_on_a_ramp() -> None:
    every = 5  # 200 Hz boards: 0.7 mm of water between readings
    assert V * every * T_S < INTERP_M
    skin, f, T_w, T_p, v, T_a, fresh = _ramp_loop(every)
    T_in, fr = inlet_inputs(skin, T_S, T_w, T_p, v, T_a, fresh)
    i = [p.name for p in skin.patches].index("dorsal2")  # fed by dorsal1 through 0.02 m
    pipe = skin.loops[skin.patches[i].loop].pipes[1]
    lag = pipe.length / (V * T_S)                        # samples the water takes through it
    k = np.arange(len(f))
    src_k = np.floor(k - lag + 1e-9).astype(int)         # the sample whose water arrives at k
    ok = (src_k >= 1) & (src_k + every < k)              # that water's next reading has come
    age = (k - src_k) * T_S
    decay = np.exp(-age / pipe.tau_loss) if pipe.tau_loss > 0 else np.ones(len(k))
    want = 20.0 + (f[np.maximum(src_k, 0)] - 20.0) * decay
    assert np.abs(T_in[ok, i] - want[ok]).max() < 1e-9
    assert (fr[ok, i] & FRESH_T_P).all()                 # every sample brings new, known water
    # the loop's first patch is fed by the tank, whose readings are held, fresh only when read
    j = [p.name for p in skin.patches].index("dorsal1")
    steady = k > 2000
    assert np.unique(T_in[steady, j]).size < steady.sum() / (every - 1)
    assert 0 < (fr[steady, j] & FRESH_T_P).astype(bool).mean() <= 1.0 / every + 0.01


def test_long_gaps_are_held_and_not_fresh() -> None:
    every = 10  # 100 Hz boards: 1.4 mm
    assert V * every * T_S > INTERP_M
    skin, f, T_w, T_p, v, T_a, fresh = _ramp_loop(every)
    T_in, fr = inlet_inputs(skin, T_S, T_w, T_p, v, T_a, fresh)
    i = [p.name for p in skin.patches].index("dorsal2")
    k = np.arange(len(f))
    steady = k > 1000
    assert 0 < (fr[steady, i] & FRESH_T_P).astype(bool).mean() <= 1.0 / every + 0.01
    # held: the value changes at most at the fresh samples (and by the pipe's slow cooling)
    jumps = np.abs(np.diff(T_in[steady, i])) > 1e-3
    assert np.all((fr[steady, i][1:] & FRESH_T_P)[jumps] != 0)
