"""The closed loop on the simulated skin: plant, loop body and recorder, once per ``t_s``.

From ambient, the loop brings ``T_w`` to its command while the scenario's touches (shifted
by ``t_settle``) come and go; every sample is recorded in the shared schema.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from thermoskin.detector import ContactEvent
from thermoskin.params import Config
from thermoskin.runtime.controller import SkinController
from thermoskin.sim.plant import SimulatedPlant
from thermoskin.sim.scenarios import Scenario

#: Recorded columns, in order: measured, commands, estimates, then the simulator's truth.
COLUMNS = ("t", "T_w", "T_p", "v", "T_a", "T_w_cmd", "T_p_cmd", "drive", "q_i_hat", "dq_i_hat",
           "contact", "gap", "q_i", "T_g", "T_w_true", "T_p_true", "contact_true", "n_fingers")


@dataclass
class LoopResult:
    """The recorded log, the detected contacts, and the loop's own figures."""

    columns: dict[str, NDArray[np.float64]]
    events: list[ContactEvent]
    scenario: Scenario
    wall_s: float

    @property
    def realtime_factor(self) -> float:
        """Simulated seconds per wall-clock second."""
        return self.scenario.duration / self.wall_s if self.wall_s > 0 else math.inf


def run_closed_loop(scenario: Scenario, cfg: Config, *, skin_model: str = "network",
                    on_start: Callable[[float], None] | None = None,
                    on_event: Callable[[ContactEvent], None] | None = None,
                    progress: Callable[[float], None] | None = None) -> LoopResult:
    """Run ``scenario`` (its touches at their times) in closed loop from ambient.

    ``skin_model``: ``"network"`` (two-node, as the observer assumes) or ``"spatial"``.
    """
    plant = SimulatedPlant(cfg, scenario, skin_model=skin_model)
    ctrl = SkinController(cfg)
    ctrl.reset(scenario.T_a)
    n, t_s = plant.n, cfg.sampling.t_s
    rec = {k: np.zeros(n) for k in COLUMNS}
    cols = [rec[k] for k in COLUMNS]
    (c_t, c_Tw, c_Tp, c_v, c_Ta, c_cmd, c_Tpc, c_drv, c_qi, c_dq, c_con, c_gap, c_q, c_Tg,
     c_Twt, c_Tpt, _, _) = cols
    obs, det = ctrl.observer, ctrl.detector
    cmd_at = scenario.T_w_cmd_at
    setpoint_changes = sorted({0.0, *(t0 for t0, _ in scenario.setpoints)})
    cmd = cmd_at(0.0)
    every = max(1, n // 200)
    wall0 = time.perf_counter()
    for k in range(n):
        t = k * t_s
        if setpoint_changes and t >= setpoint_changes[0]:
            cmd = cmd_at(t)
            setpoint_changes.pop(0)
        T_w, T_p, T_a = plant.measure()
        ctrl.step(t, T_w, T_p, T_a, cmd)
        skin = plant.skin
        c_t[k] = t
        c_Tw[k] = T_w
        c_Tp[k] = T_p
        c_Ta[k] = T_a
        c_v[k] = ctrl.v
        c_cmd[k] = cmd
        c_Tpc[k] = ctrl.T_p_cmd
        c_drv[k] = ctrl.drive
        c_qi[k] = obs.q_i_hat
        c_dq[k] = obs.dq_i_hat
        c_con[k] = ctrl.contact
        c_gap[k] = obs.gap
        c_q[k] = skin.G_c * (skin.T_f - skin.T_g) if skin.G_c else 0.0
        c_Tg[k] = skin.T_g
        c_Twt[k] = skin.T_w
        c_Tpt[k] = plant.tank.T_p
        if det.started and on_start is not None:
            on_start(t)
        if det.ended and on_event is not None:
            on_event(det.events[-1])
        plant.apply(ctrl.drive, ctrl.v)
        if progress is not None and k % every == 0:
            progress(k / n)
    n_events = len(det.events)
    det.finish((n - 1) * t_s)
    if on_event is not None and len(det.events) > n_events:
        on_event(det.events[-1])
    wall = time.perf_counter() - wall0
    if progress is not None:
        progress(1.0)
    rec["contact_true"] = (np.asarray(plant.G_c) > 0).astype(np.int8)
    rec["n_fingers"] = np.asarray(plant.n_fingers, dtype=np.int8)
    for k in ("contact", "gap"):
        rec[k] = rec[k].astype(np.int8)
    return LoopResult(columns=rec, events=det.events, scenario=scenario, wall_s=wall)
