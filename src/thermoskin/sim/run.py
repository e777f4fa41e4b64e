"""Run a scenario on the simulated skin: sample by sample, the pump logic on the *measured* ``T_w``.

Open loop on the simulated plant (``sim.plant.SimulatedPlant``, prescribed tank): the
tank temperature ``T_p`` is the scenario's (``Scenario.T_p``: the command plus an offset,
rate-limited after a command change); the pump logic runs on the measured ``T_w``
against the scenario's command schedule.

Row ``k`` of the result holds the state at ``t_k = k t_s`` and the inputs applied over
``[t_k, t_k+1)`` (zero-order hold). Columns (docs/model.md names and units):

- measured: ``t`` (s, from 0), ``T_w``, ``T_p``, ``T_a`` (°C, the thermocouple boards'
  readings: lag, noise, quantum, held between conversions; ``sim.sensors``), ``v`` (m/s,
  the pump command applied from ``t_k`` on), ``T_w_cmd`` (°C), ``fresh`` (bit mask of the
  channels converted at ``t_k``: ``T_w`` 1, ``T_p`` 2, ``T_a`` 4);
- truth: ``T_w_true``, ``T_g`` (°C), ``q_i`` (W, ``G_c (T_f - T_g)`` at ``t_k`` with the
  contact applied from ``t_k``), ``contact_true`` (1 while ``G_c > 0``), ``n_fingers``,
  ``T_a_true`` (°C, the ambient that drives the physics); with touchers (touches naming
  one, :mod:`thermoskin.physics.contact`) also the current contact's
  ``toucher_true, material_true, T_f_true, G_true`` (1 human, 0 object; the index of its
  material class in ``physics.contact.CLASSES``; its surface temperature at the onset °C;
  its conductance W/K; -1, -1, NaN, 0 outside contacts: ``SimulatedPlant.truth_columns``).

The state starts in equilibrium, so there is no start-up transient: with the pump logic
at ``T_w = T_w_cmd`` and the sheet's equilibrium for it; with the pump always on or off
in the network's equilibrium for the initial inputs.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

import numpy as np

from thermoskin.control.pump import PumpLogic
from thermoskin.params import Config, SensorParams
from thermoskin.sim.plant import SimulatedPlant
from thermoskin.sim.scenarios import Scenario, get_scenario

COLUMNS = ("t", "T_w", "T_p", "v", "T_a", "T_w_cmd", "T_w_true", "T_g", "q_i", "contact_true", "n_fingers",
           "fresh", "T_a_true")


BLOCK = 65_536
"""Samples per block of :func:`simulate_blocks`."""


def simulate(scenario: Scenario | str, cfg: Config, duration: float | None = None,
             progress: Callable[[float], None] | None = None,
             boards: SensorParams | None = None) -> dict[str, np.ndarray]:
    """Simulate ``scenario`` (or its name) for its duration (or ``duration`` s); see the module doc.
    The whole log in memory: :func:`simulate_blocks` joined."""
    blocks = list(simulate_blocks(scenario, cfg, duration, progress, boards=boards))
    return {k: np.concatenate([b[k] for b in blocks]) for k in blocks[0]}


def simulate_blocks(scenario: Scenario | str, cfg: Config, duration: float | None = None,
                    progress: Callable[[float], None] | None = None,
                    block: int = BLOCK, boards: SensorParams | None = None
                    ) -> Iterator[dict[str, np.ndarray]]:
    """:func:`simulate`, its log given ``block`` samples at a time (``thermoskin simulate`` writes
    each as it comes): the same samples, and only a block's columns held at once (the plant
    holds a window of its scenario's profiles), so memory does not grow with the duration.
    ``boards``: the thermocouple boards as they truly are (default: the config's ``[sensor]``)."""
    sc = get_scenario(scenario) if isinstance(scenario, str) else scenario
    if duration is not None:
        sc = sc.with_duration(duration)
    t_s = cfg.sampling.t_s
    plant = SimulatedPlant(cfg, sc, tank="prescribed", boards=boards)
    n = plant.n
    pump = PumpLogic(cfg.pump, t_s)
    v_const = cfg.pump.v_on if sc.pump == "on" else 0.0
    logic = sc.pump == "logic"
    if logic:
        plant.reset("command", T_w0=float(sc.T_w_cmd_at(0.0)))
        pump.reset(on=True)
    else:
        plant.reset("equilibrium", v=v_const)

    skin = plant.skin
    touchers = bool(plant.touchers)
    truth = plant.truth
    measure, apply, pump_step = plant.measure, plant.apply, pump.step
    every = max(1, n // 100)
    next_report = every if progress is not None else n + 1
    block = max(1, block)
    for k0 in range(0, n, block):
        k1 = min(n, k0 + block)
        m = k1 - k0
        prof = plant.profile(k0, k1)
        t = prof["t"]
        cmd = sc.T_w_cmd_profile(t)
        cmd_l = cmd.tolist()
        cols = [[0.0] * m for _ in range(6)]
        T_w_true, T_g, T_w_m, T_p_m, T_a_m, v_col = cols
        fresh = [0] * m
        q_col = [0.0] * m if touchers else []
        for j in range(m):
            T_w_true[j] = skin.T_w
            T_g[j] = skin.T_g
            mw, T_p_m[j], T_a_m[j] = measure()
            T_w_m[j] = mw
            fresh[j] = plant.fresh
            v = pump_step(mw, cmd_l[j], bool(fresh[j] & 1)) if logic else v_const
            v_col[j] = v
            if touchers:
                q_col[j] = truth()[0]
            apply(0.0, v)
            if k0 + j + 1 >= next_report:
                progress((k0 + j + 1) / n)  # type: ignore[misc]
                next_report += every
        if progress is not None and k1 == n and next_report - every < n:
            progress(1.0)
        G_b, T_f_b = prof["G_c"], prof["T_f"]
        T_g_arr = np.asarray(T_g)
        out = {
            "t": t,
            "T_w": np.asarray(T_w_m),
            "T_p": np.asarray(T_p_m),
            "v": np.asarray(v_col),
            "T_a": np.asarray(T_a_m),
            "T_w_cmd": cmd,
            "T_w_true": np.asarray(T_w_true),
            "T_g": T_g_arr,
            "q_i": np.asarray(q_col) if touchers else G_b * (T_f_b - T_g_arr),
            "contact_true": (G_b > 0.0).astype(np.int8),
            "n_fingers": prof["n_fingers"].astype(np.int8),
            "fresh": np.asarray(fresh, dtype=np.int8),
            "T_a_true": prof["T_a_true"],
        }
        if touchers:
            out.update(plant.truth_columns(k0, k1))
        yield out
