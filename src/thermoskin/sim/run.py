"""Run a scenario on the simulated skin: sample by sample, the pump logic on the *measured* ``T_w``.

Open loop: the tank temperature ``T_p`` is prescribed by the scenario (``Scenario.T_p``:
the command plus an offset, rate-limited after a command change); the pump logic runs on
the measured ``T_w`` against the scenario's command schedule.

Row ``k`` of the result holds the state at ``t_k = k t_s`` and the inputs applied over
``[t_k, t_k+1)`` (zero-order hold). Columns (MODEL.md names and units):

- measured: ``t`` (s, from 0), ``T_w``, ``T_p``, ``T_a`` (°C, the thermocouple boards'
  readings: lag, noise, quantum, held between conversions; ``sim.sensors``), ``v`` (m/s,
  the pump command applied from ``t_k`` on), ``T_w_cmd`` (°C), ``fresh`` (bit mask of the
  channels converted at ``t_k``: ``T_w`` 1, ``T_p`` 2, ``T_a`` 4);
- truth: ``T_w_true``, ``T_g`` (°C), ``q_i`` (W, ``G_c (T_f - T_g)`` at ``t_k`` with the
  contact applied from ``t_k``), ``contact_true`` (1 while ``G_c > 0``), ``n_fingers``,
  ``T_a_true`` (°C, the ambient that drives the physics).

The state starts in equilibrium, so there is no start-up transient: with the pump logic
at ``T_w = T_w_cmd`` and the sheet's equilibrium for it; with the pump always on or off
in the network's equilibrium for the initial inputs.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from thermoskin.control.pump import PumpLogic
from thermoskin.params import Config
from thermoskin.physics.finger import contact_profile
from thermoskin.sim.scenarios import Scenario, get_scenario
from thermoskin.sim.sensors import FRESH_A, FRESH_P, Sensors
from thermoskin.sim.skin import SimulatedSkin

COLUMNS = ("t", "T_w", "T_p", "v", "T_a", "T_w_cmd", "T_w_true", "T_g", "q_i", "contact_true", "n_fingers",
           "fresh", "T_a_true")


def simulate(scenario: Scenario | str, cfg: Config, duration: float | None = None,
             progress: Callable[[float], None] | None = None) -> dict[str, np.ndarray]:
    """Simulate ``scenario`` (or its name) for its duration (or ``duration`` s); see the module doc."""
    sc = get_scenario(scenario) if isinstance(scenario, str) else scenario
    if duration is not None:
        sc = sc.with_duration(duration)
    t_s = cfg.sampling.t_s
    n = max(1, math.floor(sc.duration / t_s + 1e-9))
    t = np.arange(n) * t_s
    T_p = np.asarray(sc.T_p(t), dtype=float)
    T_a = np.asarray(sc.T_a_at(t), dtype=float)
    cmd = sc.T_w_cmd_profile(t)
    G_c, T_f, n_fingers = contact_profile(sc.touches, t)

    skin = SimulatedSkin(cfg)
    sensors = Sensors(cfg.sensor, t_s)
    pump = PumpLogic(cfg.pump, t_s)
    v_const = cfg.pump.v_on if sc.pump == "on" else 0.0
    logic = sc.pump == "logic"
    if logic:
        skin.reset(float(cmd[0]), T_a=T_a[0], G_c=G_c[0], T_f=T_f[0])
        pump.reset(on=True)
    else:
        skin.reset_equilibrium(T_p[0], v_const, T_a[0], G_c[0], T_f[0])

    T_p_l, T_a_l, G_l, T_f_l, cmd_l = T_p.tolist(), T_a.tolist(), G_c.tolist(), T_f.tolist(), cmd.tolist()
    T_w_true = [0.0] * n
    T_g = [0.0] * n
    T_w_meas = [0.0] * n
    fresh_w = [0] * n
    v_col = [0.0] * n
    board_w = sensors.board("T_w")
    step, pump_step, read_w = skin.step, pump.step, board_w.read
    every = max(1, n // 100)
    next_report = every if progress is not None else n + 1
    for k in range(n):
        Tw = skin.T_w
        T_w_true[k] = Tw
        T_g[k] = skin.T_g
        m = read_w(Tw)
        T_w_meas[k] = m
        fresh_w[k] = board_w.fresh
        v = pump_step(m, cmd_l[k]) if logic else v_const
        v_col[k] = v
        step(T_p_l[k], v, T_a_l[k], G_l[k], T_f_l[k])
        if k + 1 >= next_report:
            progress((k + 1) / n)  # type: ignore[misc]
            next_report += every
    if progress is not None and next_report - every < n:
        progress(1.0)

    T_p_m, conv_p = sensors.board("T_p").read_array(T_p)
    T_a_m, conv_a = sensors.board("T_a").read_array(T_a)
    fresh = (np.asarray(fresh_w) + conv_p * FRESH_P + conv_a * FRESH_A).astype(np.int8)
    T_g_arr = np.asarray(T_g)
    return {
        "t": t,
        "T_w": np.asarray(T_w_meas),
        "T_p": T_p_m,
        "v": np.asarray(v_col),
        "T_a": T_a_m,
        "T_w_cmd": cmd,
        "T_w_true": np.asarray(T_w_true),
        "T_g": T_g_arr,
        "q_i": G_c * (T_f - T_g_arr),
        "contact_true": (G_c > 0.0).astype(np.int8),
        "n_fingers": n_fingers.astype(np.int8),
        "fresh": fresh,
        "T_a_true": T_a,
    }
