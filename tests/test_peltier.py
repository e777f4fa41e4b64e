"""Peltier tank: energy balance, steady state vs solve_ivp, asymmetry, COP, integration."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import fsolve

from thermoskin.params import PeltierParams
from thermoskin.physics.peltier import KELVIN, PeltierTank, cop, module_heats

P = PeltierParams()


def ode(p: PeltierParams, cur: float, T_a: float, q_out: float = 0.0):
    """The two-node ODE written out again from the textbook equations (cold/hot faces)."""
    def f(_t, x):
        Tt, Ts = x
        th_t, th_s = Tt + KELVIN, Ts + KELVIN
        # tank face: hot junction for cur > 0 (Peltier heat S cur θ released), cold for cur < 0
        q_tank = p.S_m * cur * th_t + 0.5 * cur**2 * p.R_m - p.K_m * (Tt - Ts)
        q_sink = -p.S_m * cur * th_s + 0.5 * cur**2 * p.R_m + p.K_m * (Tt - Ts)
        n = p.n_modules
        return [(n * q_tank - (Tt - T_a) / p.R_tank_air - q_out) / p.C_tank,
                (n * q_sink - (Ts - T_a) / p.R_sink) / p.C_sink]
    return f


@pytest.mark.parametrize("cur", [-6.0, -2.0, 0.5, 3.0, 6.0])
def test_energy_balance(cur):
    Tt, Ts = 18.0, 31.0
    Q_t, Q_s, P_el = module_heats(cur, Tt, Ts, P)
    # electric power from the terminal voltage: V = S (θ_t - θ_s) + cur R
    V = P.S_m * ((Tt + KELVIN) - (Ts + KELVIN)) + cur * P.R_m
    assert Q_t + Q_s == pytest.approx(V * cur, rel=1e-12)
    assert P_el == pytest.approx(V * cur, rel=1e-12)


def test_signs():
    # heating: tank face gets heat, sink face loses some (module pumps from the sink)
    Q_t, Q_s, _ = module_heats(3.0, 20.0, 20.0, P)
    assert Q_t > 0 and Q_s < 0
    # cooling: tank face loses heat, sink gets more than the electric power
    Q_t, Q_s, P_el = module_heats(-3.0, 20.0, 20.0, P)
    assert Q_t < 0 and Q_s > P_el > 0


def test_asymmetry():
    tank = PeltierTank(P, 1e-3)
    up = tank.steady_state(0.1)[0] - 20.0
    down = 20.0 - tank.steady_state(-0.1)[0]
    assert up > down > 0  # Joule heat helps heating and opposes cooling
    Qp = module_heats(4.0, 20.0, 25.0, P)[0]
    Qm = module_heats(-4.0, 20.0, 25.0, P)[0]
    assert Qp + Qm == pytest.approx(16.0 * P.R_m - 2 * P.K_m * (20.0 - 25.0))


def test_cop_limits():
    Tt, Ts = 10.0, 30.0  # cooling the tank below the sink
    Tc, Th = Tt + KELVIN, Ts + KELVIN
    for cur in np.linspace(0.5, 6.0, 12):
        c = cop(-cur, Tt, Ts, P)
        assert c < Tc / (Th - Tc)  # Carnot limit of a refrigerator
    # heating with the tank hotter than the sink: COP below the heat-pump Carnot limit, above 0
    Tt, Ts = 35.0, 20.0
    for cur in np.linspace(1.0, 6.0, 6):
        c = cop(cur, Tt, Ts, P)
        assert 0 < c < (Tt + KELVIN) / (Tt - Ts)
    # at zero temperature difference, heating COP > 1 (Peltier heat adds to Joule heat)
    assert cop(3.0, 20.0, 20.0, P) > 1.0


@pytest.mark.parametrize("drive", [-0.5, -0.1, 0.0, 0.07, 0.3])
def test_steady_state_vs_independent(drive):
    tank = PeltierTank(P, 1e-3)
    Tt, Ts = tank.steady_state(drive, 22.0, q_out=0.3)
    f = ode(P, drive * P.I_max, 22.0, 0.3)
    root = fsolve(lambda x: f(0, x), [20.0, 20.0], xtol=1e-10)
    assert (Tt, Ts) == pytest.approx(tuple(root), abs=1e-8)
    sol = solve_ivp(f, (0, 6000.0), [22.0, 22.0], method="LSODA", rtol=1e-10, atol=1e-10)
    assert (Tt, Ts) == pytest.approx(tuple(sol.y[:, -1]), abs=1e-4)


def test_step_vs_solve_ivp():
    tank = PeltierTank(P, 1e-3)
    tank.reset(24.0, 21.0, T_a=20.0)
    rng = np.random.default_rng(0)
    drives = rng.uniform(-0.4, 0.4, 6)
    x = np.array([24.0, 21.0])
    for d in drives:  # 6 segments of 1 s
        for _ in range(1000):
            tank.step(d, 20.0, 0.1)
        sol = solve_ivp(ode(P, d * P.I_max, 20.0, 0.1), (0, 1.0), x, rtol=1e-11, atol=1e-11)
        x = sol.y[:, -1]
        assert (tank.T_p, tank.T_sink) == pytest.approx(tuple(x), abs=1e-8)


def test_coarse_step_uses_substeps():
    tank = PeltierTank(P, 1.0)
    assert tank.n_sub > 1
    tank.reset(24.0, 21.0)
    for _ in range(30):
        tank.step(0.2, 20.0)
    sol = solve_ivp(ode(P, 0.2 * P.I_max, 20.0), (0, 30.0), [24.0, 21.0], rtol=1e-11, atol=1e-11)
    assert (tank.T_p, tank.T_sink) == pytest.approx(tuple(sol.y[:, -1]), abs=1e-6)


def test_clipping_and_power():
    tank = PeltierTank(P, 1e-3, drive_limits=(-0.5, 0.8))
    tank.reset(20.0)
    tank.step(5.0, 20.0)
    assert tank.i_module == pytest.approx(0.8 * P.I_max)
    assert tank.P_elec == pytest.approx(P.n_modules * tank.i_module**2 * P.R_m)
    tank.step(-5.0, 20.0)
    assert tank.i_module == pytest.approx(-0.5 * P.I_max)
    assert tank.Q_tank + tank.Q_sink == pytest.approx(tank.P_elec)


def test_drive_for_and_errors():
    tank = PeltierTank(P, 1e-3)
    d = tank.drive_for(30.0, 20.0)
    assert tank.steady_state(d, 20.0)[0] == pytest.approx(30.0, abs=1e-9)
    with pytest.raises(ValueError, match="out of reach"):
        PeltierTank(P, 1e-3, (-0.01, 0.01)).drive_for(60.0)
    with pytest.raises(ValueError, match="drive_limits"):
        PeltierTank(P, 1e-3, (0.2, 1.0))
    with pytest.raises(ValueError, match="t_s"):
        PeltierTank(P, 0.0)
