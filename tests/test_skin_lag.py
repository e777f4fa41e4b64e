"""The lumped model's inlet lag (``skin_lag``) and the lagged inlet of ``InletStream``.

Independent references: the advection through ``N`` well-mixed cells is an Erlang-``N``
distribution of residence times (``scipy.stats.gamma``), and the lumped node a first-order lag;
the lagged inlet is the plain inlet of a skin whose pipes are longer by the lag.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import scipy.stats

from thermoskin.physics.convection import R_w
from thermoskin.skin import load_skin
from thermoskin.skin_inlet import InletStream, inlet_inputs
from thermoskin.skin_lag import best_delay, lumped_lag
from thermoskin.skin_observe import patch_config

ROOT = Path(__file__).resolve().parents[1]
FOREARM = ROOT / "examples" / "forearm.toml"


def test_best_delay_recovers_a_known_shift() -> None:
    t = np.linspace(0.0, 1.0, 1001)
    y = 1.0 - np.exp(-t / 0.1)
    shifted = np.where(t >= 0.037, 1.0 - np.exp(-(t - 0.037) / 0.1), 0.0)
    assert best_delay(shifted, y) == 37


def test_lag_is_the_erlang_versus_exponential_delay() -> None:
    """The spatial pipe (15 cells) against the lumped node: the least-squares delay between an
    Erlang-15 and an exponential of the same mean (scipy's gamma, a fine grid), in units of the
    pipe's residence time ``C_w R_w``; the sheet and the pipe's conduction shift it a little."""
    tau = 1.0
    t = np.linspace(0.0, 10.0 * tau, 20001)
    ys = scipy.stats.gamma.cdf(t, 15, scale=tau / 15)
    ds = np.arange(0.0, 1.0, 1e-3)
    err = [np.sum((ys - np.where(t >= d, 1.0 - np.exp(-(t - d) / tau), 0.0)) ** 2) for d in ds]
    d_ref = float(ds[int(np.argmin(err))])
    skin = load_skin(FOREARM)
    for i in (0, 8):  # a 30 mm patch, the palm (40 mm, its own network)
        cfg = patch_config(skin, i)
        lc = skin.loops[skin.patches[i].loop].cfg
        v = lc.pump.v_on
        res = cfg.skin.C_w * R_w(v, lc.skin)
        assert abs(lumped_lag(skin, i, cfg.skin) / (v * res) - d_ref) < 0.03


def test_lagged_inlet_is_the_inlet_of_longer_pipes_block_by_block() -> None:
    skin = load_skin(FOREARM)
    P, n, t_s = len(skin.patches), 3000, 1e-3
    rng = np.random.default_rng(3)
    T_w = [24.0 + rng.normal(0.0, 0.1, (n, P)), np.full((n, P), np.nan)]
    T_p = np.repeat(25.0 + 0.1 * np.sin(np.arange(n) * 0.01)[:, None], P, axis=1)
    v = np.repeat(np.where((np.arange(n) // 50) % 2 == 0, 0.141, 0.0)[:, None], P, axis=1)
    T_a = np.full((n, P), 20.0)
    lag = [0.001 * (1 + i % 3) for i in range(P)]
    st = InletStream(skin, t_s, lag=lag)
    parts = []
    for a in range(0, n, 700):
        b = min(a + 700, n)
        plain, _ = st.push([x[a:b] for x in T_w], T_p[a:b], v[a:b], T_a[a:b], None)
        assert st.lagged is not None
        parts.append((plain, *st.lagged))
    plain = np.vstack([p[0] for p in parts])
    lagged = np.vstack([p[1] for p in parts])
    lag_fr = np.vstack([p[2] for p in parts])
    ref_plain, _ = inlet_inputs(skin, t_s, T_w, T_p, v, T_a, None)
    np.testing.assert_array_equal(plain, ref_plain)
    assert np.abs(lagged - plain).max() > 0.05  # the lag moves the inlet
    for i, p in enumerate(skin.patches):
        lp = skin.loops[p.loop]
        q = lp.patches.index(i)
        pipes = list(lp.pipes)
        if q == 0 and pipes[0].length == 0.0:
            continue
        pipes[q] = dataclasses.replace(pipes[q], length=pipes[q].length + lag[i])
        loops = list(skin.loops)
        loops[p.loop] = dataclasses.replace(lp, pipes=tuple(pipes))
        longer = dataclasses.replace(skin, loops=tuple(loops))
        ref, ref_fr = inlet_inputs(longer, t_s, T_w, T_p, v, T_a, None)
        np.testing.assert_array_equal(lagged[:, i], ref[:, i])
        np.testing.assert_array_equal(lag_fr[:, i], ref_fr[:, i])
