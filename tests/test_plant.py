"""One simulated plant behind every simulated path: the open loop, the closed loop, SimDevice,
the emulator's DeviceCore and the spatial runs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from thermoskin.devices import protocol as proto
from thermoskin.devices.emulator import DeviceCore
from thermoskin.devices.sim_device import SimDevice
from thermoskin.params import Config
from thermoskin.physics.finger import Touch
from thermoskin.runtime.closed_loop import run_closed_loop
from thermoskin.sim.plant import SimulatedPlant
from thermoskin.sim.run import simulate
from thermoskin.sim.scenarios import SCENARIOS, Scenario

CFG = Config()


def test_open_loop_log_is_the_plant_stepped_by_the_pump_logic() -> None:
    """simulate() = a prescribed-tank plant with the pump logic on its T_w reading."""
    from thermoskin.control.pump import PumpLogic

    sc = SCENARIOS["one-finger"].with_duration(8.0)
    cfg = CFG.replace(sensor={"period_T_a": 0.05, "lag_T_a": 1.0, "seed": 4})
    log = simulate(sc, cfg)
    plant = SimulatedPlant(cfg, sc, tank="prescribed")
    plant.reset("command", T_w0=24.0)
    pump = PumpLogic(cfg.pump, cfg.sampling.t_s)
    rows = []
    for _ in range(plant.n):
        q_i, T_g, T_w, T_p = plant.truth()
        m = plant.measure()
        v = pump.step(m[0], 24.0)
        rows.append((*m, v, plant.fresh, q_i, T_g, T_w, T_p, *plant.contact()))
        plant.apply(0.0, v)
    r = np.array(rows)
    for i, k in enumerate(("T_w", "T_p", "T_a", "v", "fresh", "q_i", "T_g", "T_w_true")):
        np.testing.assert_array_equal(r[:, i], log[k], err_msg=k)
    np.testing.assert_array_equal(r[:, 8], sc.T_p(log["t"]))
    np.testing.assert_array_equal(r[:, 9], log["contact_true"])
    np.testing.assert_array_equal(r[:, 10], log["n_fingers"])


def test_closed_loop_and_sim_device_share_the_plants_truth() -> None:
    sc = SCENARIOS["one-finger"].with_duration(7.0)
    c = run_closed_loop(sc, CFG).columns
    G = SimulatedPlant(CFG, sc).profile()["G_c"]
    from thermoskin.physics.finger import contact_profile

    G2, T_f, _ = contact_profile(sc.touches, c["t"])
    np.testing.assert_array_equal(G, G2)
    # q_i with the contact applied from t_k on, as the open-loop log
    np.testing.assert_allclose(c["q_i"], G2 * (T_f - c["T_g"]), rtol=0, atol=1e-15)
    assert c["q_i"].max() > 0.2
    dev = SimDevice(CFG, sc)
    dev.open()
    for k in range(5200):
        s = dev.read_sample()
        assert s is not None
        q_i, T_g, _, _ = dev.truth()
        if k == 5100:
            assert q_i == pytest.approx(G2[k] * (T_f[k] - T_g), abs=1e-15) and q_i > 0
        dev.write_command(0.0, 0.141)


def test_the_true_ambient_drives_the_tanks_loss() -> None:
    """One step of the tank from the air's 20 °C with the air at 30 °C: the loss term by hand."""
    sc = Scenario("amb", "", 2.0, ambient=((0.0, 30.0), (1.0, 30.0)), T_a=20.0)
    plant = SimulatedPlant(CFG, sc)
    assert plant.profile(0, 1)["T_a_true"][0] == 30.0
    # start the tank, its sink and the skin at 20 °C against air at 30 °C
    plant.tank.reset(20.0, 20.0)
    plant.skin.reset(20.0, 20.0)
    p = CFG.peltier
    plant.apply(0.0, 0.0)
    t_s = CFG.sampling.t_s
    rate = (plant.tank.T_p - 20.0) / t_s
    assert rate == pytest.approx((30.0 - 20.0) / (p.R_tank_air * p.C_tank), rel=1e-3)


def test_emulator_core_is_the_plant_with_the_devices_boards_and_repeating_touches() -> None:
    sc = Scenario("rep", "", 3.0, touches=(Touch(0.5, 1.0, 2),))
    core = DeviceCore(CFG, sc, tc_period=0.1, command_timeout=100.0)
    core.on_message(proto.Hello(0))
    core.on_message(proto.Command(1, 0.2, 0.141))
    samples = [m for _ in range(7000) for m in core.step() if isinstance(m, proto.SampleMsg)]
    truths = []
    core2 = DeviceCore(CFG, sc, tc_period=0.1)
    core2.on_message(proto.Hello(0))
    core2.on_message(proto.Command(1, 0.2, 0.141))
    for _ in range(7000):
        core2.step()
        truths.append(core2.truth)
    tr = np.array(truths)
    # touches repeat every scenario duration (3000 samples)
    np.testing.assert_array_equal(tr[:3000, 1], tr[3000:6000, 1])
    t_in = (np.arange(7000) % 3000) * 1e-3
    np.testing.assert_array_equal(tr[:, 1], (t_in > 0.5) & (t_in < 1.5))
    assert set(tr[:, 3]) == {0.0, 2.0}
    # the same plant stepped by hand with the same commands reads the same
    cfg = CFG.replace(sensor={"period_T_w": 0.1, "period_T_p": 0.1, "period_T_a": 0.1})
    plant = SimulatedPlant(cfg, sc, repeat=True)
    plant.reset("equilibrium", v=cfg.pump.v_on)
    for k, m in enumerate(samples):
        T_w, T_p, T_a = plant.measure()
        if m.fresh:
            assert (m.T_w, m.T_p, m.T_a) == (T_w, T_p, T_a), k
        assert m.fresh == plant.fresh
        plant.apply(0.2, 0.141)
    assert [m.t_us for m in samples if m.fresh][:3] == [0, 100_000, 200_000]


def test_emulator_jitter_and_fault_on_plant_readings() -> None:
    core = DeviceCore(CFG, SCENARIOS["none"], [], tc_period=0.1, jitter=0.004)
    core.on_message(proto.Hello(0))
    msgs = [m for _ in range(3000) for m in core.step() if isinstance(m, proto.SampleMsg)]
    fresh_t = np.array([m.t_us for m in msgs if m.fresh & proto.CH_W]) * 1e-6
    off = fresh_t[1:] - 0.1 * np.round(fresh_t[1:] / 0.1)
    assert np.all(np.abs(off) <= 0.0045) and np.any(off != 0.0)
    assert core.cfg.sensor.jitter == 0.004 and core.tc_period == pytest.approx(0.1)
    with pytest.raises(ValueError, match="jitter"):
        DeviceCore(CFG, SCENARIOS["none"], tc_period=0.01, jitter=0.006)
    assert math.isnan(DeviceCore(CFG, SCENARIOS["none"]).t_safe)


def test_plant_bad_arguments() -> None:
    with pytest.raises(ValueError, match="skin_model"):
        SimulatedPlant(CFG, SCENARIOS["none"], skin_model="foam")
    with pytest.raises(ValueError, match="tank"):
        SimulatedPlant(CFG, SCENARIOS["none"], tank="kettle")
    with pytest.raises(ValueError, match="start"):
        SimulatedPlant(CFG, SCENARIOS["none"]).reset("somewhere")


@pytest.mark.parametrize("path", ["open", "closed", "spatial", "device"])
def test_the_profiles_window_changes_nothing(monkeypatch: pytest.MonkeyPatch, path: str) -> None:
    """The plant holds its scenario's profiles a window at a time (``plant.WINDOW`` samples):
    windows of 1009 samples, cut mid-touch and mid-toucher, give every sample of one window the
    length of the run (the profiles whole, as the plant held them before), on the open loop
    (prescribed tank, touchers), the closed loop, the spatial skin and the emulator's repeating
    plant across its wrap."""
    import thermoskin.sim.plant as plant_mod

    def go() -> dict[str, np.ndarray]:
        if path == "open":
            return simulate("touchers", CFG, 24.0)
        if path == "closed":
            return run_closed_loop(SCENARIOS["touchers"].with_duration(24.0), CFG).columns
        if path == "spatial":
            sc = SCENARIOS["mixed"].with_duration(12.0)
            return run_closed_loop(sc, CFG, skin_model="spatial").columns
        core = DeviceCore(CFG, SCENARIOS["touchers"].with_duration(8.0))  # a cold can at 6.7 s
        rows = []
        for k in range(20_000):  # 2.5 scenario durations
            rows.append(core.plant.measure() + core.plant.truth() + core.plant.contact())
            core.plant.apply(0.3, 0.141 if k % 700 < 400 else 0.0)
        return {"rows": np.array(rows)}

    monkeypatch.setattr(plant_mod, "WINDOW", 10**9)
    whole = go()
    monkeypatch.setattr(plant_mod, "WINDOW", 1009)
    cut = go()
    for k, a in whole.items():
        assert np.array_equal(cut[k], a, equal_nan=True), k
    if path != "device":
        assert whole["contact_true"].sum() > 2000  # touches cross the windows' edges
    else:
        assert np.abs(whole["rows"][:, 3]).max() > 1.0  # q_i: the cold can in each repeat


def test_profile_is_the_touches_and_ambient_at_each_sample() -> None:
    """:meth:`SimulatedPlant.profile` by hand: a two-finger touch's ramp (``RAMP_S``) and its
    position, the ambient's interpolation, a prescribed tank's command, over any cut."""
    from thermoskin.physics.finger import RAMP_S, full_conductance

    tc = Touch(t_on=1.0, duration=2.0, n_fingers=2, position=0.12)
    sc = Scenario("p", "", 4.0, touches=(tc,), ambient=((0.0, 20.0), (4.0, 24.0)), T_a=20.0)
    plant = SimulatedPlant(CFG, sc, tank="prescribed")
    t_s = CFG.sampling.t_s
    p = plant.profile(900, 3100)
    t = np.arange(900, 3100) * t_s
    G = full_conductance(tc) * np.clip(np.minimum(t - 1.0, 3.0 - t) / RAMP_S, 0.0, 1.0)
    G[(t <= 1.0) | (t > 3.0)] = 0.0
    np.testing.assert_allclose(p["G_c"], G, rtol=1e-12, atol=0)
    assert np.array_equal(p["n_fingers"], np.where(G > 0, 2, 0))
    assert np.array_equal(p["position"], np.where((t >= 1.0) & (t < 3.0), 0.12, 0.0))
    np.testing.assert_allclose(p["T_a_true"], 20.0 + t, rtol=1e-12)
    np.testing.assert_array_equal(p["T_p"], sc.T_p(t))
    assert np.array_equal(p["current"], np.where((t > 1.0) & (t < 3.0), 0, -1))
    whole = plant.profile()
    for k, x in p.items():
        np.testing.assert_array_equal(whole[k][900:3100], x, err_msg=k)
    # the contact truth alone (the closed loop's per block): the same by hand, and sample by
    # sample what the plant says while it runs
    cc = plant.contact_columns(900, 3100)
    assert cc["contact_true"].dtype == np.int8 and np.array_equal(cc["contact_true"], G > 0)
    assert np.array_equal(cc["n_fingers"], np.where(G > 0, 2, 0))
    live = []
    for _ in range(3100):
        live.append(plant.contact())
        plant.apply(0.0, 0.0)
    assert np.array_equal(np.array(live[900:]), np.column_stack([cc["contact_true"], cc["n_fingers"]]))
