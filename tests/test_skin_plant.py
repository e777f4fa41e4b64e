"""The multi-patch plant (sim/skin_plant.py) against independent computations.

- one patch, no pipe: the single-patch spatial plant (``SimulatedPlant``), readings and truth;
- a closed loop with no loss to the air: the heat in tank, sink, patches and the water in the
  pipes stays constant while the pump runs and stops (each part's heat counted here from its
  own capacitance and temperatures);
- a connecting pipe: the next patch's inlet is the previous patch's mean outlet, ``D`` samples
  later (``D = L / (v t_s)`` from the pipe's length), cooled by ``exp(-D t_s / tau)``;
- a touch upstream reaches the downstream thermocouple ``D`` samples later and weaker, by the
  pipe's attenuation times the downstream patch's own steady gain from inlet to outlet
  (``spatial_steady_state``, a linear solve);
- the boards read together (``BoardBank``) equal ``Board.read``;
- strokes cross patches where the geometry says; seeded runs repeat exactly.
"""

from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np
import pytest

from thermoskin.params import Config
from thermoskin.physics.convection import R_w
from thermoskin.physics.finger import Touch
from thermoskin.physics.spatial import capacitances, spatial_steady_state
from thermoskin.sim.board_bank import BoardBank
from thermoskin.sim.plant import SimulatedPlant
from thermoskin.sim.scenarios import Scenario
from thermoskin.sim.sensors import Board
from thermoskin.sim.skin_plant import SkinPlant
from thermoskin.sim.skin_scenarios import SkinContact, SkinScenario, contact_arrays, from_single
from thermoskin.skin.layout import parse_skin, single_skin

V_ON = 0.141
QUIET = Config().replace(sensor={"noise_T": 0.0, "quantum_T": 0.0})

THREE: dict[str, Any] = {
    "links": {"arm": {"length": 0.3, "circumference": 0.1}},
    "loops": {"a": {"patches": ["p0", "p1", "p2"],
                    "pipes": [0.01, {"length": 0.02, "tau_loss": 5.0}, 0.0,
                              {"length": 0.015, "tau_loss": 8.0}]}},
    "patches": {"p0": {"link": "arm", "centre": [0.05, 0.05]},
                "p1": {"link": "arm", "centre": [0.09, 0.05], "thermocouples": [0.03, 0.0]},
                "p2": {"link": "arm", "centre": [0.13, 0.05]}},
}


def _scenario(duration: float, contacts: tuple[SkinContact, ...] = (), **kw: Any) -> SkinScenario:
    return SkinScenario("t", "", Scenario("t", "", duration=duration, **kw), contacts)


def test_one_patch_no_pipe_is_the_single_spatial_plant() -> None:
    """Peltier tank, the pump switching, the drive moving, two touches: equal to rounding."""
    cfg = Config()
    sc = Scenario("t", "", duration=4.0, touches=(Touch(0.5, 1.2, 2, position=0.5),
                                                  Touch(2.2, 1.0, 1, position=0.25)))
    skin = single_skin(cfg)
    a = SimulatedPlant(cfg, sc, skin_model="spatial")
    b = SkinPlant(skin, from_single(sc, skin))
    a.reset()
    b.reset()
    worst = worst_read = 0.0
    for k in range(a.n):
        T_w, T_p, T_a = a.measure()
        b.measure()
        q, _, T_w_true, T_p_true = a.truth()
        worst = max(worst, abs(T_w_true - b.state(0)[0]), abs(T_p_true - b.tanks[0].T_p), abs(q - b.q_i[0]))
        worst_read = max(worst_read, abs(T_w - b.T_w_read[0, 0]), abs(T_p - b.T_p_read[0]),
                         abs(T_a - b.T_a_read[0]))
        assert a.fresh == int(b.fresh[0])
        assert bool(a.contact()[0]) == bool(b.contact_true[0])
        drive = 0.3 * math.sin(k * 0.002)
        v = V_ON if (k // 70) % 3 else 0.0
        a.apply(drive, v)
        b.apply([drive], [v])
    assert worst < 1e-9
    assert worst_read == 0.0  # the same boards, the same streams
    np.testing.assert_allclose(b.state(0), a.skin.x, rtol=0, atol=1e-9)


def _parse_closed(data: dict[str, Any], cfg: Config) -> Any:
    """:func:`parse_skin`, then no loss to the air anywhere: every patch's and tank's loss set to
    1e15 K/W, a physical limit beyond the parameters' bounds, so set past their validation
    (safe: each parsed skin and loop holds its own parameter objects)."""
    skin = parse_skin(data, "three.toml", cfg)
    objs = [p.skin for p in skin.patches] + [lp.cfg.skin for lp in skin.loops]
    for o in objs:
        for k in ("R_aw", "R_ag"):
            object.__setattr__(o, k, 1e15)
    for lp in skin.loops:
        for k in ("R_tank_air", "R_sink"):
            object.__setattr__(lp.cfg.peltier, k, 1e15)
    return skin


def _heat(plant: SkinPlant, W: float) -> float:
    """Heat in the loop, J (from 0 °C): tank and sink, every patch's nodes, the water in the pipes."""
    skin = plant.skin
    E = 0.0
    for j, lp in enumerate(skin.loops):
        tank = plant.tanks[j]
        E += lp.cfg.peltier.C_tank * tank.T_p + lp.cfg.peltier.C_sink * tank.T_sink
        E += sum(W * plant.t_s * T for pipe in plant.pipe_parcels(j) for T in pipe)
    for p in skin.patches:
        E += float(capacitances(p.skin, p.spatial) @ plant.state(p.index))
    return E


def test_energy_balance_of_a_loop() -> None:
    """With no loss to the air and no drive, the loop's heat is constant to rounding while the
    water runs and stands (a tank warmer than its skin, patches at different temperatures)."""
    data = copy.deepcopy(THREE)
    data["pipe"] = {"tau_loss": math.inf}
    for p in data["loops"]["a"]["pipes"]:
        if isinstance(p, dict):
            p["tau_loss"] = math.inf
    cfg = Config()
    skin = _parse_closed(data, cfg)
    plant = SkinPlant(skin, _scenario(1.5, T_a=20.0))
    plant.reset("ambient")
    plant.tanks[0].reset(30.0, 25.0, 20.0)
    rng = np.random.default_rng(4)
    for p in skin.patches:
        plant.state(p.index)[:] = 20.0 + 4.0 * rng.random(p.spatial.n_states)
    W = 1.0 / R_w(V_ON, cfg.skin)
    E0 = _heat(plant, W)
    moved = 0.0
    for k in range(plant.n):
        v = V_ON if (k // 150) % 2 == 0 else 0.0
        plant.apply([0.0], [v])
        moved = max(moved, abs(plant.q_out[0]))
        assert _heat(plant, W) == pytest.approx(E0, rel=1e-12, abs=1e-9)
    assert moved > 1.0  # heat did flow (W), and back into the pipes and patches


def test_outlet_is_next_inlet_after_the_pipe() -> None:
    skin = parse_skin(copy.deepcopy(THREE), "three.toml", QUIET)
    plant = SkinPlant(skin, _scenario(1.0, T_a=20.0, T_w_cmd=24.0, T_p_offset=0.5, T_p_drift=0.5,
                                      T_p_period=0.3), tank="prescribed")
    plant.reset("equilibrium")
    t_s = plant.t_s
    D01 = round(0.02 / (V_ON * t_s))  # the pipe from p0 to p1: 142 samples
    D12 = 1  # no pipe from p1 to p2: the patches are stepped together
    D_sup = round(0.01 / (V_ON * t_s))
    outs, ins = [], []
    nm = plant.nmax
    for _ in range(plant.n):
        plant.apply([0.0], [V_ON])
        outs.append(plant.last_outlet_means())
        ins.append(plant.Z[:, nm].copy())  # the inlet each patch had over the sample
    outs, ins = np.array(outs), np.array(ins)
    T_a = 20.0
    a01 = math.exp(-D01 * t_s / 5.0)
    k = np.arange(D01 + 10, plant.n)
    np.testing.assert_allclose(ins[k, 1], T_a + (outs[k - D01, 0] - T_a) * a01, rtol=0, atol=1e-12)
    k = np.arange(5, plant.n)  # a pipe of no length: still one sample, cooling (tau 100 s) for it
    np.testing.assert_allclose(ins[k, 2], T_a + (outs[k - D12, 1] - T_a) * math.exp(-D12 * t_s / 100.0),
                               rtol=0, atol=1e-12)
    # the supply: the tank's T_p(t) D_sup samples back (no loss given: the default tau 100 s)
    T_p = np.array(plant.scenario.base.T_p(np.arange(plant.n) * t_s))
    k = np.arange(D_sup + 1, plant.n)
    np.testing.assert_allclose(ins[k, 0], T_a + (T_p[k - D_sup] - T_a) * math.exp(-D_sup * t_s / 100.0),
                               rtol=0, atol=1e-12)
    assert np.ptp(outs[:, 0]) > 0.05  # the tank's swing passed through


def test_upstream_touch_reaches_downstream_later_and_weaker() -> None:
    """Pump running, prescribed tank: the touch's effect (run with minus run without, the model
    being linear) at p1's outlet thermocouple is zero until the pipe's delay has passed, then
    tends to a(pipe) * g(p1) times the effect at p0's outlet."""
    skin = parse_skin(copy.deepcopy(THREE), "three.toml", QUIET)
    touch = SkinContact(Touch(0.2, 3.0, 0, G=0.15, T_body=34.0), patch="p0", position=0.015)
    runs = []
    for contacts in ((touch,), ()):
        plant = SkinPlant(skin, _scenario(3.1, contacts, T_a=20.0, T_w_cmd=24.0, T_p_offset=0.4),
                          tank="prescribed")
        plant.reset("equilibrium")
        rows = []
        for _ in range(plant.n):
            plant.measure()
            rows.append(plant.T_w_read[0, :2].copy())
            plant.apply([0.0], [V_ON])
        runs.append(np.array(rows))
    d = runs[0] - runs[1]
    t_s = plant.t_s
    k_on = round(0.2 / t_s)
    D = round(0.02 / (V_ON * t_s))
    first0 = int(np.argmax(np.abs(d[:, 0]) > 0))
    first1 = int(np.argmax(np.abs(d[:, 1]) > 0))
    # the press ramps from G = 0 at t_on: the touch acts from sample k_on + 1 and p0's outlet
    # cell (under the footprint's edge? no: 5 mm away, through the sheet) moves the next sample
    assert first0 == k_on + 2
    # p0's mean outlet over sample first0 - 1 enters p1 D samples later; before that, p1 is untouched
    assert np.all(d[:first0 + D, 1] == 0.0)
    # then it shows within the water's transit through p1 (C_w / W, about 27 ms)
    assert first0 + D <= first1 <= first0 + D + 30
    # steady: the pipe's attenuation and p1's gain from its inlet to its outlet, pump running
    p1 = skin.patch("p1")
    a = math.exp(-D * t_s / 5.0)
    R = R_w(V_ON, skin.loops[0].cfg.skin)
    x1 = spatial_steady_state(p1.skin, p1.spatial, V_ON, R, np.array([1.0, 0.0, 0.0, 0.0]))
    g = x1[0]
    assert 0.9 < a * g < 1.0
    assert d[-1, 1] / d[-1, 0] == pytest.approx(a * g, rel=1e-4)
    assert 0.0 < d[-1, 1] < d[-1, 0]


def test_still_water_reaches_the_tank_at_the_loop_ends_only() -> None:
    """Pump stopped: only p0's inlet and p2's outlet exchange with the tank (W(0)/2 each)."""
    cfg = Config()
    skin = _parse_closed(copy.deepcopy(THREE), cfg)
    plant = SkinPlant(skin, _scenario(0.2, T_a=20.0))
    plant.reset("ambient")
    plant.tanks[0].reset(30.0, 20.0, 20.0)
    start = [plant.state(i).copy() for i in range(3)]
    for _ in range(100):
        T_p = plant.tanks[0].T_p  # over the sample to come
        plant.apply([0.0], [0.0])
    np.testing.assert_allclose(plant.state(1), start[1], rtol=0, atol=1e-12)  # a middle patch: nothing
    assert plant.state(0)[14] > 20.0 + 1e-3 and plant.state(2)[0] > 20.0 + 1e-3
    W0 = 1.0 / R_w(0.0, cfg.skin)
    y_out = plant.last_outlet_means()[2]  # p2's outlet cell, mean over the last sample
    y_in = plant.Y[0, plant.nmax + 1]  # p0's inlet cell
    assert plant.q_out[0] == pytest.approx(0.5 * W0 * ((T_p - y_in) + (T_p - y_out)), rel=1e-6)


def test_board_bank_equals_boards() -> None:
    ss = np.random.SeedSequence

    def boards() -> list[Board]:
        return [Board("T_w", noise_T=0.02, quantum_T=1 / 128, t_s=1e-3, noise_seed=ss(1, spawn_key=(0,)),
                      jitter_seed=ss(1, spawn_key=(3,))),
                Board("T_p", period=0.1, jitter=0.003, lag=0.5, noise_T=0.02, quantum_T=1 / 128, t_s=1e-3,
                      noise_seed=ss(1, spawn_key=(1,)), jitter_seed=ss(1, spawn_key=(4,))),
                Board("T_a", period=0.013, jitter=0.006, lag=1.0, noise_T=0.05, t_s=1e-3,
                      noise_seed=ss(1, spawn_key=(2,)), jitter_seed=ss(1, spawn_key=(5,)))]

    ref, bank = boards(), BoardBank(boards())
    rng = np.random.default_rng(0)
    for _ in range(6000):  # several noise blocks and jitter refills
        x = 20.0 + rng.random(3)
        r = [b.read(float(xi)) for b, xi in zip(ref, x, strict=True)]
        bank.read(x)
        assert r == bank.value.tolist()
        assert [bool(b.fresh) for b in ref] == bank.fresh.tolist()


def test_stroke_crosses_patches_where_they_are() -> None:
    skin = parse_skin(copy.deepcopy(THREE), "three.toml")
    # along the row at 0.04 m/s from x = 0.03 to 0.15: p0 spans [0.035, 0.065], p1 [0.075, 0.105], ...
    c = SkinContact(Touch(1.0, 3.0, 2), link="arm", path=((0.0, 0.03, 0.05), (3.0, 0.15, 0.05)))
    t = np.arange(0.0, 4.5, 0.001)
    patch, G, s, _ = contact_arrays(skin, (c,), t)
    x = 0.03 + 0.04 * (t - 1.0)
    on = (t > 1.0 + 0.03) & (t < 4.0 - 0.03)  # pressed (past the ramps)
    for i, (lo, hi) in enumerate(((0.035, 0.065), (0.075, 0.105), (0.115, 0.145))):
        inside = on & (x > lo + 1e-9) & (x < hi - 1e-9)
        assert np.all(patch[0, inside] == i)
        np.testing.assert_allclose(s[0, inside], x[inside] - lo, atol=1e-12)
    gap = on & (x > 0.066) & (x < 0.074)
    assert gap.any() and np.all(patch[0, gap] == -1) and np.all(G[0, gap] == 0.0)
    # the plant's truth: position on a grid of 1/(8 N) of the footprint's travel (20 mm / 120)
    plant = SkinPlant(skin, _scenario(4.5, (c,)), tank="prescribed")
    plant.reset("equilibrium")
    seen = []
    for k in range(plant.n):
        plant.measure()
        if plant.contact_true.any():
            i = int(np.argmax(plant.contact_true))
            seen.append((i, plant.position_true[i], s[0, k]))
        plant.apply([0.0], [V_ON])
    assert {i for i, _, _ in seen} == {0, 1, 2}
    err = [abs(pt - max(min(st, 0.025), 0.005)) for _, pt, st in seen]  # the footprint stays on the pipe
    assert max(err) <= 0.5 * 0.02 / 120 + 1e-12


def test_seeded_runs_repeat() -> None:
    skin = parse_skin(copy.deepcopy(THREE), "three.toml",
                      Config().replace(sensor={"period_T_w": 0.1, "jitter": 0.002, "lag_T_a": 1.0}))
    touch = SkinContact(Touch(0.1, 0.5, 1), patch="p1", position=0.01)

    def run(seed_skin: Any) -> np.ndarray:
        plant = SkinPlant(seed_skin, _scenario(0.8, (touch,)))
        plant.reset("equilibrium")
        rows = []
        for k in range(plant.n):
            plant.measure()
            rows.append(plant.rec.copy())
            plant.apply([0.05], [V_ON if k % 200 < 120 else 0.0])
        return np.array(rows)

    a, b = run(skin), run(skin)
    np.testing.assert_array_equal(a, b)
    boards = {"period_T_w": 0.1, "jitter": 0.002, "lag_T_a": 1.0, "seed": 7}
    other = parse_skin(copy.deepcopy(THREE), "three.toml", Config().replace(sensor=boards))
    c = run(other)
    assert not np.array_equal(a[:, 0], c[:, 0])
