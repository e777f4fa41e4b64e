"""Where along its pipe a patch was touched (``skin_position``), on readings of a known touch."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg

from thermoskin.physics.convection import FlowResistance
from thermoskin.physics.spatial import contact_cells, spatial_state_space, spatial_steady_state
from thermoskin.skin.layout import load_skin
from thermoskin.skin.position import PatchLocator

ROOT = Path(__file__).resolve().parent.parent
T_S = 1e-3


def _readings(skin, i: int, par: float, k_on: int, n: int, q: float, seed: int, cells: int | None = None,
              offsets: tuple[float, ...] = (), chatter: bool = True):
    """The thermocouples of patch ``i`` (its spatial model through ``physics.spatial``'s own heat
    input ``q_x``, spread on the contact's cells), the pump chattering 50 ms off / 50 ms on,
    ``q`` W into the sheet at ``par`` of the footprint's travel from sample ``k_on``; noise 20 mK.
    ``cells``: the readings' model with this many cells (a second discretisation of the pipe, not
    the locator's own); ``offsets``: each thermocouple's constant error (K, a board's); ``chatter``
    False: the pump running throughout."""
    p, lp = skin.patches[i], skin.loops[skin.patches[i].loop]
    sp, v_on = p.spatial, lp.cfg.pump.v_on
    if cells is not None:
        sp = dataclasses.replace(sp, n_cells=cells)
    # each thermocouple's cell on this grid (cell 0 at the outlet; s from the inlet)
    tc_cells = [min(max(math.floor((1.0 - s / p.length) * sp.n_cells), 0), sp.n_cells - 1)
                for s in p.thermocouples]
    flow = FlowResistance(lp.cfg.skin)
    ends = (p.index == lp.patches[0], p.index == lp.patches[-1])
    w = contact_cells(par, sp.n_cells, sp.footprint)
    E = {}
    for v in (0.0, v_on):
        A, B = spatial_state_space(p.skin, sp, v, flow(v), q_weights=w, still_ends=ends)
        m = A.shape[0]
        M = np.zeros((m + 4, m + 4))
        M[:m, :m], M[:m, m:] = A, B
        X = scipy.linalg.expm(M * T_S)
        E[v] = (X[:m, :m], X[:m, m:])
    v = np.where((np.arange(n) // 50) % 2 == 1, v_on, 0.0) if chatter else np.full(n, v_on)
    T_in = 24.6 + 0.05 * np.sin(np.arange(n) / 300.0)
    x = spatial_steady_state(p.skin, sp, v_on, flow(v_on), np.array([T_in[0], 20.0, 0.0, 0.0]))
    for k in range(3000):  # into the chatter's periodic state before the log begins
        F, G = E[float(v[k % 100])]
        x = F @ x + G @ np.array([T_in[0], 20.0, 0.0, 0.0])
    Y = np.empty((n, len(tc_cells)))
    for k in range(n):
        Y[k] = x[tc_cells]
        F, G = E[float(v[k])]
        x = F @ x + G @ np.array([T_in[k], 20.0, q if k >= k_on else 0.0, 0.0])
    Y += np.random.default_rng(seed).normal(0.0, 0.02, Y.shape)
    for j, c in enumerate(offsets):
        Y[:, j] += c
    s_true = p.length * (1.0 - (0.5 * sp.footprint + par * (1.0 - sp.footprint)))
    return T_in, v, [Y[:, j] for j in range(Y.shape[1])], s_true


@pytest.mark.parametrize("par", [0.2, 0.8])
def test_a_touch_near_either_end_is_placed_where_it_was(par: float) -> None:
    """Two thermocouples (outlet and inlet), the pump chattering, the window opening while the
    pump stands: the position is within 10 % of the pipe of the truth (the model's own start-up,
    0.7 K from a still-water steady state, once took the place of the offset and put a touch
    near the outlet at the inlet)."""
    skin = load_skin(ROOT / "examples" / "forearm.toml")
    i = skin.patch("ventral1").index
    p = skin.patches[i]
    n, k_on, k_off = 5000, 2000, 4200  # the window opens at k_on - 1.5 s = 500: the pump off
    T_in, v, Y, s_true = _readings(skin, i, par, k_on, n, q=1.5, seed=3)
    assert v[k_on - 1500] == 0.0
    pos = PatchLocator(skin, i, T_S).locate(k_on, k_off, T_in, np.full(n, 20.0), v, Y, None,
                                            np.where(np.arange(n) >= k_on, 1.5, 0.0))
    assert np.isfinite(pos.mean), "a position is reported"
    assert abs(pos.mean - s_true) < 0.1 * p.length
    assert pos.heat == pytest.approx(1.0, abs=0.2)  # dq is the heat itself: scale 1


@pytest.mark.parametrize("par", [0.2, 0.8])
def test_board_offsets_and_another_discretisation(par: float) -> None:
    """The readings from a model of the pipe with twice the cells (not the locator's own), each
    thermocouple off by a board's constant error (+0.4 K at the outlet, -0.3 K at the inlet, ten
    times the touch's rise): the touch is still placed within 15 % of the pipe of the truth, its
    scale near 1 (the offsets are fitted before the onset; without that fit the +0.7 K between
    the two thermocouples would read as a touch at the inlet)."""
    skin = load_skin(ROOT / "examples" / "forearm.toml")
    i = skin.patch("ventral1").index
    p = skin.patches[i]
    n, k_on, k_off = 5000, 2000, 4200
    T_in, v, Y, s_true = _readings(skin, i, par, k_on, n, q=1.5, seed=5, cells=2 * p.spatial.n_cells,
                                   offsets=(0.4, -0.3))
    pos = PatchLocator(skin, i, T_S).locate(k_on, k_off, T_in, np.full(n, 20.0), v, Y, None,
                                            np.where(np.arange(n) >= k_on, 1.5, 0.0))
    assert np.isfinite(pos.mean)
    assert abs(pos.mean - s_true) < 0.15 * p.length, (pos.mean, s_true)
    assert pos.heat == pytest.approx(1.0, abs=0.3)


def test_window_from_hand_numbers() -> None:
    """The samples read for a contact (1 ms): 1.5 s before the onset, at most 4 s of the contact,
    the model's start-up 1 s before that; cut at the log's ends and the contact's."""
    from thermoskin.skin.position import window

    assert window(5000, 12000, 20000, 1e-3) == (2500, 3500, 9000)   # 4 s of a 7 s contact
    assert window(5000, 6000, 20000, 1e-3) == (2500, 3500, 6000)    # a 1 s contact, whole
    assert window(5000, 12000, 7000, 1e-3) == (2500, 3500, 7000)    # the log ends first
    assert window(1000, 3000, 20000, 1e-3) == (0, 0, 3000)          # near the log's start
    assert window(2000, 3000, 20000, 1e-3) == (0, 500, 3000)
    assert window(50, 100, 200, 0.01) == (0, 0, 100)                # 100 Hz


def _locate(name: str, par: float = 0.2, dq: bool = True, chatter: bool = True,
            **kw):  # type: ignore[no-untyped-def]
    """Locate a touch of 1.5 W at ``par`` on patch ``name`` from 3 s into a 6 s log (the model's
    start-up from 0.5 s: the samples before it are not read)."""
    skin = load_skin(ROOT / "examples" / "forearm.toml")
    i = skin.patch(name).index
    n, k_on, k_off = 6000, 3000, 5200
    T_in, v, Y, s_true = _readings(skin, i, par, k_on, n, q=1.5, seed=3, chatter=chatter)
    for key, f in kw.items():
        T_in, v, Y = f(T_in, v, Y) if key == "edit" else (T_in, v, Y)
    loc = PatchLocator(skin, i, T_S)
    pos = loc.locate(k_on, k_off, T_in, np.full(n, 20.0), v, Y, kw.get("fresh"),
                     np.where(np.arange(n) >= k_on, 1.5, 0.0) if dq else None)
    return pos, loc, s_true, skin.patches[i]


def test_a_reported_position_carries_its_own_spread() -> None:
    """Reported: sd equals the likelihood's own, positive, below the reporting limit."""
    from thermoskin.skin.position import IDENTIFIABLE

    pos, loc, _, _ = _locate("ventral1")
    prior = float(np.std(loc.positions))
    assert np.isfinite(pos.mean) and pos.sd == pos.sd_fit and 0.0 < pos.sd < IDENTIFIABLE * prior
    assert len(loc.positions) == len(loc.shares) == 25 and loc.positions[0] > loc.positions[-1]


def test_one_thermocouple_with_the_pump_running_is_not_placed() -> None:
    """One thermocouple at the outlet: how much heat, not where. The position and its sd are empty,
    the likelihood's own sd (wider than the limit) and the heat's scale are kept."""
    from thermoskin.skin.position import IDENTIFIABLE

    pos, loc, _, p = _locate("dorsal3", chatter=False)
    assert len(p.thermocouples) == 1
    assert math.isnan(pos.mean) and math.isnan(pos.sd)
    assert pos.sd_fit > IDENTIFIABLE * float(np.std(loc.positions)) and math.isfinite(pos.sd_fit)
    assert pos.heat == pytest.approx(1.0, abs=0.3)


def test_no_flow_or_no_room_gives_no_position() -> None:
    """The pump off through the contact, or a contact of one sample: NAN_POSITION, every field NaN."""
    skin = load_skin(ROOT / "examples" / "forearm.toml")
    i = skin.patch("ventral1").index
    n = 5000
    T_in, v, Y, _ = _readings(skin, i, 0.5, 2000, n, q=1.5, seed=3)
    loc = PatchLocator(skin, i, T_S)
    off = np.where(np.arange(n) >= 1990, 0.0, v)
    for args in ((2000, 4200, off), (2000, 2001, v), (1, 4200, v)):
        pos = loc.locate(args[0], args[1], T_in, np.full(n, 20.0), args[2], Y)
        assert all(math.isnan(x) for x in (pos.mean, pos.sd, pos.sd_fit, pos.heat)), args


def test_a_step_of_one_watt_when_no_heat_course_is_given() -> None:
    """Without the estimator's heat, a step of 1 W from the onset: the scale is the touch's 1.5 W."""
    pos, _, s_true, p = _locate("ventral1", dq=False)
    assert pos.heat == pytest.approx(1.5, rel=0.03)  # the readings' step is 1.5 W
    assert abs(pos.mean - s_true) < 0.1 * p.length


def test_only_fresh_finite_readings_are_used() -> None:
    """Boards at 100 Hz: a reading is new every 10 samples and held between; some new ones lost
    (NaN). Only fresh, finite readings count: the same place as with every reading."""
    n = 6000
    fresh_bits = (np.arange(n) % 10) == 0

    def tenhz(T_in, v, Y):  # type: ignore[no-untyped-def]
        out = []
        for y in Y:
            held = y[np.maximum.accumulate(np.where(fresh_bits, np.arange(n), 0))].copy()
            held[np.arange(n) % 70 == 0] = np.nan  # a lost reading now and then, flagged fresh
            out.append(held)
        return T_in, v, out

    pos, _, s_true, p = _locate("ventral1", edit=tenhz, fresh=[fresh_bits, fresh_bits])
    assert np.isfinite(pos.mean) and abs(pos.mean - s_true) < 0.15 * p.length


def test_a_touch_as_long_as_the_patch_has_one_place() -> None:
    """A footprint the whole patch long: every grid position is the centre, reported as it is."""
    skin = load_skin(ROOT / "examples" / "forearm.toml")
    i = skin.patch("ventral1").index
    p = skin.patches[i]
    whole = dataclasses.replace(p, spatial=dataclasses.replace(p.spatial, contact_length=p.length))
    skin2 = dataclasses.replace(skin, patches=tuple(whole if q.index == i else q for q in skin.patches))
    loc = PatchLocator(skin2, i, T_S)
    assert np.all(loc.positions == 0.5 * p.length) and len(loc.positions) == 25


def test_a_thermocouple_without_readings_before_or_after_the_onset_is_left_out() -> None:
    """One of the two thermocouples with no fresh reading before the onset, or none after it: the
    other alone is fitted (a spread is found: the fit ran), not the contact given up."""
    n = 6000
    none = np.zeros(n, bool)
    every = np.ones(n, bool)
    only_before = np.arange(n) < 3000
    for fresh in ([none, every], [only_before, every]):
        pos, _, _, _ = _locate("ventral1", fresh=fresh)
        assert math.isfinite(pos.sd_fit) and math.isfinite(pos.heat), fresh[0].sum()


def test_the_locators_model_of_a_patch_at_a_loops_ends() -> None:
    """ventral1 opens the ventral loop, palm closes it (examples/forearm.toml): which pipe ends
    reach the tank through still water; a footprint the whole patch long shares its heat evenly
    over the 15 cells. The locator's step at the pump stopped is the zero-order hold of the
    patch's model with ventral1's ends, one column of 1 W per grid place: ``Phi = e^{A t_s}``
    (SciPy) and ``Gamma = A^-1 (Phi - I) B`` (closed form), the heat's columns through the
    model's own heat input ``q_x`` spread as the grid place's shares."""
    skin = load_skin(ROOT / "examples" / "forearm.toml")
    ends = {name: PatchLocator(skin, skin.patch(name).index, T_S).ends
            for name in ("ventral1", "ventral2", "palm")}
    assert ends == {"ventral1": (True, False), "ventral2": (False, False), "palm": (False, True)}
    i = skin.patch("ventral1").index
    p = skin.patches[i]
    loc = PatchLocator(skin, i, T_S)
    Phi, Gu, Gq = loc._matrices(0.0)
    flow = FlowResistance(skin.loops[p.loop].cfg.skin)
    N = p.spatial.n_cells
    for c in (0, 12, 24):
        par = c / 24
        w = contact_cells(par, N, p.spatial.footprint)
        A, B = spatial_state_space(p.skin, p.spatial, 0.0, flow(0.0), q_weights=w, still_ends=(True, False))
        P = scipy.linalg.expm(A * T_S)
        G = np.linalg.solve(A, (P - np.eye(len(A))) @ B)
        np.testing.assert_allclose(Phi, P, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(Gu, G[:, :2], rtol=1e-7, atol=1e-12)
        np.testing.assert_allclose(Gq[:, c], G[:, 2], rtol=1e-7, atol=1e-12)
    whole = dataclasses.replace(p, spatial=dataclasses.replace(p.spatial, contact_length=p.length))
    skin2 = dataclasses.replace(skin, patches=tuple(whole if q.index == i else q for q in skin.patches))
    for sh in PatchLocator(skin2, i, T_S).shares:
        assert sorted(sh) == list(range(N)) and all(abs(x - 1.0 / N) < 1e-12 for x in sh.values())


def test_a_contact_of_one_or_two_samples_and_one_at_the_logs_start() -> None:
    """The pump running at the onset (sample 2050 of the chatter): a contact of one sample gives
    no position (every field NaN), one of two samples is fitted (a spread is found); so is a
    contact from the log's third sample (two samples before it for the offsets, no room for the
    model's start-up)."""
    skin = load_skin(ROOT / "examples" / "forearm.toml")
    i = skin.patch("ventral1").index
    n = 5000
    T_in, v, Y, _ = _readings(skin, i, 0.5, 2050, n, q=1.5, seed=3)
    assert v[2050] > 0.0 and v[2051] > 0.0 and v[2] == 0.0
    loc = PatchLocator(skin, i, T_S)
    one = loc.locate(2050, 2051, T_in, np.full(n, 20.0), v, Y)
    assert all(math.isnan(x) for x in (one.mean, one.sd, one.sd_fit, one.heat))
    for k_on, k_off in ((2050, 2052), (2, 2200)):
        pos = loc.locate(k_on, k_off, T_in, np.full(n, 20.0), v, Y)
        assert math.isfinite(pos.sd_fit) and math.isfinite(pos.heat), (k_on, k_off)


def test_a_contact_of_100_ms_with_the_step_of_one_watt() -> None:
    """A contact of 100 ms (the pump on for its last 50): the step of 1 W from the onset, not
    before it, fits the readings' 1.5 W within 20 % and the place within 5 % of the pipe (the
    heat's rise during the contact is what a short contact shows)."""
    skin = load_skin(ROOT / "examples" / "forearm.toml")
    i = skin.patch("ventral1").index
    p = skin.patches[i]
    n = 6000
    T_in, v, Y, s_true = _readings(skin, i, 0.2, 3000, n, q=1.5, seed=3)
    pos = PatchLocator(skin, i, T_S).locate(3000, 3100, T_in, np.full(n, 20.0), v, Y)
    assert np.isfinite(pos.mean) and abs(pos.mean - s_true) < 0.05 * p.length, (pos.mean, s_true)
    assert pos.heat == pytest.approx(1.5, rel=0.2)


def test_the_samples_before_the_models_start_up_are_not_read() -> None:
    """Only ``[kb, k1)`` of the log is read (``window``): every input NaN before ``kb`` changes
    nothing."""
    from thermoskin.skin.position import window

    skin = load_skin(ROOT / "examples" / "forearm.toml")
    i = skin.patch("ventral1").index
    n, k_on, k_off = 6000, 3000, 5200
    T_in, v, Y, _ = _readings(skin, i, 0.2, k_on, n, q=1.5, seed=3)
    kb = window(k_on, k_off, n, T_S)[0]
    assert kb == 500
    T_a = np.full(n, 20.0)
    loc = PatchLocator(skin, i, T_S)
    want = loc.locate(k_on, k_off, T_in, T_a, v, Y)
    cut = [x.copy() for x in (T_in, T_a, v, *Y)]
    for x in cut:
        x[:kb] = np.nan
    got = loc.locate(k_on, k_off, cut[0], cut[1], cut[2], cut[3:])
    assert got == want


def test_spread_from_the_likelihood_computed_apart() -> None:
    """The likelihood's scale, not only its limit: readings of 1.5 W at the middle of the travel
    (pump running, inputs steady, noise 10 mK, a board's offset on each thermocouple), and the
    position's mean, sd and heat computed apart from the module doc's rule: each grid place's
    response to 1 W from ``scipy.linalg.expm`` of the model with that place's heat input (not the
    locator's augmented matrix), each place's ``RSS`` by ``numpy.linalg.lstsq`` on the readings
    less their mean before the onset, ``sigma^2 = RSS_min / (m - 2)``, the weights
    ``exp(-(RSS - RSS_min) / (2 sigma^2))`` over the grid. A likelihood 1.5 times wider (or a
    degree of freedom off) moves the sd by far more than the 1e-6 held."""
    from thermoskin.skin.position import GRID, IDENTIFIABLE

    skin = load_skin(ROOT / "examples" / "forearm.toml")
    i = skin.patch("ventral1").index
    p, lp = skin.patches[i], skin.loops[skin.patches[i].loop]
    sp, v_on, N = p.spatial, lp.cfg.pump.v_on, p.spatial.n_cells
    tc = [min(max(math.floor((1.0 - s / p.length) * N), 0), N - 1) for s in p.thermocouples]
    flow = FlowResistance(lp.cfg.skin)
    ends = (p.index == lp.patches[0], p.index == lp.patches[-1])
    n, k_on, k_off = 4000, 2000, 3500
    k0 = k_on - 1500  # the window: 1.5 s before the onset, the contact to its end (< 4 s)
    pars = np.linspace(0.0, 1.0, GRID)

    def response(par: float) -> np.ndarray:
        """The thermocouples' rise from 1 W at ``par`` from sample ``k_on`` (from rest)."""
        A, B = spatial_state_space(p.skin, sp, v_on, flow(v_on),
                                   q_weights=contact_cells(float(par), N, sp.footprint), still_ends=ends)
        m = A.shape[0]
        M = np.zeros((m + 4, m + 4))
        M[:m, :m], M[:m, m:] = A, B
        X = scipy.linalg.expm(M * T_S)
        F, g = X[:m, :m], X[:m, m + 2]
        x, out = np.zeros(m), np.empty((n, len(tc)))
        for k in range(n):
            out[k] = x[tc]
            x = F @ x + (g if k >= k_on else 0.0)
        return out

    H = [response(par) for par in pars]
    rng = np.random.default_rng(7)
    Y = np.array([24.3, 24.1]) + 1.5 * H[12] + rng.normal(0.0, 0.01, (n, 2))
    loc = PatchLocator(skin, i, T_S)
    pos = loc.locate(k_on, k_off, np.full(n, 24.6), np.full(n, 20.0), np.full(n, v_on),
                     [Y[:, 0], Y[:, 1]])  # dq None: a step of 1 W, so the heat is the scale

    r = np.concatenate([Y[k_on:k_off, j] - Y[k0:k_on, j].mean() for j in range(2)])
    rss, scale = np.empty(GRID), np.empty(GRID)
    for g, h in enumerate(H):
        hc = np.concatenate([h[k_on:k_off, j] for j in range(2)])[:, None]
        sol, res, _, _ = np.linalg.lstsq(hc, r, rcond=None)
        scale[g], rss[g] = sol[0], res[0]
    s2 = rss.min() / (r.size - 2)
    w = np.exp(-(rss - rss.min()) / (2.0 * s2))
    w /= w.sum()
    s_grid = p.length * (1.0 - (0.5 * sp.footprint + pars * (1.0 - sp.footprint)))
    mean = float(w @ s_grid)
    sd = math.sqrt(float(w @ (s_grid - mean) ** 2))
    # wider than the grid's step (several places weigh), narrow enough to be reported
    assert s_grid[0] - s_grid[1] < sd < IDENTIFIABLE * float(np.std(s_grid))
    assert pos.sd == pos.sd_fit == pytest.approx(sd, rel=1e-6)
    assert pos.mean == pytest.approx(mean, rel=1e-6)
    assert pos.heat == pytest.approx(float(w @ scale), rel=1e-6)
