"""The closed loop on the simulated skin: plant, loop body and recorder, once per ``t_s``.

From ambient, the loop brings ``T_w`` to its command while the scenario's touches (shifted
by ``t_settle``) come and go; every sample is recorded in the shared schema.

This is the in-process, as-fast-as-possible path (``thermoskin run`` on the simulated skin);
:mod:`thermoskin.runtime.realtime` runs the same loop body at wall-clock speed in a process
of its own, against the simulated skin or a serial device. Both check every sample with
the :class:`~thermoskin.runtime.supervisor.Supervisor`: a fault ends the run in the safe
state (drive 0, pump off) with ``LoopResult.summary["fault"]`` set.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from thermoskin.control.probe import SetpointProbe
from thermoskin.estimation.events import ContactEvent
from thermoskin.logio.plausible import admit, limits
from thermoskin.params import Config, SensorParams
from thermoskin.runtime import supervisor as sv
from thermoskin.runtime.controller import SkinController
from thermoskin.sim.plant import SimulatedPlant
from thermoskin.sim.scenarios import Scenario

#: The simulator's truth columns (a serial device has none).
TRUTH = ("q_i", "T_g", "T_w_true", "T_p_true", "contact_true", "n_fingers")
#: Recorded columns, in order: measured, commands, estimates, then the simulator's truth.
COLUMNS = ("t", "T_w", "T_p", "v", "T_a", "T_w_cmd", "T_p_cmd", "drive", "q_i_hat", "dq_i_hat",
           "contact", "gap", "fresh", *TRUTH)


@dataclass
class LoopResult:
    """The recorded log, the detected contacts, and the loop's own figures."""

    columns: dict[str, NDArray[np.float64]]
    events: list[ContactEvent]
    scenario: Scenario
    wall_s: float
    summary: dict[str, Any] = field(default_factory=dict)
    """``fault`` (supervisor code, 0 = none), ``fault_name``, ``detail``, ``t_fault``."""

    @property
    def fault(self) -> str | None:
        """The fault's name, or ``None`` (a stop on request is no fault)."""
        code = self.summary.get("fault", 0)
        return None if code in (sv.OK, sv.STOPPED) else sv.FAULTS.get(code, str(code))

    @property
    def realtime_factor(self) -> float:
        """Simulated seconds per wall-clock second."""
        return self.scenario.duration / self.wall_s if self.wall_s > 0 else math.inf


def run_closed_loop(scenario: Scenario, cfg: Config, *, skin_model: str = "network",
                    on_start: Callable[[float], None] | None = None,
                    on_event: Callable[[ContactEvent], None] | None = None,
                    progress: Callable[[float], None] | None = None,
                    on_block: Callable[[dict[str, Any]], None] | None = None,
                    block: int = 1000, stop: Any = None,
                    probe: SetpointProbe | None = None, keep: bool = True,
                    boards: SensorParams | None = None) -> LoopResult:
    """Run ``scenario`` (its touches at their times) in closed loop from ambient.

    ``skin_model``: ``"network"`` (two-node, as the observer assumes) or ``"spatial"``.
    ``on_block(columns)`` (a recorder) gets every ``block`` rows as column arrays of its own,
    with a ``fault`` column (the supervisor's code, non-zero on the row that tripped).
    ``stop`` (anything with ``is_set()``, e.g. a
    :class:`~thermoskin.runtime.stopping.StopRequest`) is polled every sample: once set, the
    loop commands the safe state and ends with the rows so far (``summary["interrupted"]``).
    ``probe``: active sensing during contacts (:class:`~thermoskin.control.probe.SetpointProbe`).
    ``keep``: the result holds every row (``LoopResult.columns``); False holds only the
    current block (``columns`` empty), so memory does not grow with the run's length
    (``thermoskin run``, whose ``on_block`` writes them). ``summary["rows"]`` counts the rows.
    ``boards``: the simulated thermocouple boards as they truly are (``sim.boards``); by default
    the config's ``[sensor]``, which the estimator takes them to be.
    """
    plant = SimulatedPlant(cfg, scenario, skin_model=skin_model, boards=boards)
    ctrl = SkinController(cfg, probe)
    ctrl.reset(scenario.T_a)
    n, t_s = plant.n, cfg.sampling.t_s
    block = max(1, int(block))
    est = ctrl.estimator
    sup = sv.Supervisor(cfg)
    check = sup.check
    lim = limits(cfg.plausible)
    truth = plant.truth
    k_sent = 0
    kept: list[dict[str, Any]] = []
    rec: dict[str, NDArray[np.float64]] = {}
    recorded = COLUMNS[:-2]  # the plant's contact truth comes from its profile

    def new_block() -> list[NDArray[np.float64]]:
        """The columns of the next ``block`` rows (each block arrays of its own)."""
        rec.update({k: np.zeros(min(block, n - k_sent)) for k in recorded})
        return [rec[k] for k in recorded]

    def send(k1: int, code: int = 0) -> None:
        nonlocal k_sent
        if k1 <= k_sent:
            return
        part = {k: rec[k][:k1 - k_sent] for k in recorded}
        part.update(plant.contact_columns(k_sent, k1))
        if keep:
            kept.append(part)
        if on_block is not None:
            f = np.zeros(k1 - k_sent)
            if code:
                f[-1] = code
            on_block({**part, "fault": f})
        k_sent = k1

    (c_t, c_Tw, c_Tp, c_v, c_Ta, c_cmd, c_Tpc, c_drv, c_qi, c_dq, c_con, c_gap, c_fr, c_q, c_Tg,
     c_Twt, c_Tpt) = new_block()
    n_run = n
    cmd_at = scenario.T_w_cmd_at
    setpoint_changes = sorted({0.0, *(t0 for t0, _ in scenario.setpoints)})
    cmd = cmd_at(0.0)
    every = max(1, n // 200)
    stopped = stop.is_set if stop is not None else None
    wall0 = time.perf_counter()
    j = 0  # the row in the block
    for k in range(n):
        t = k * t_s
        if stopped is not None and stopped():
            sup.stop(t)
            ctrl.safe()
            plant.apply(0.0, 0.0)  # the safe state: Peltier drive 0, pump off
            n_run = k
            break
        if setpoint_changes and t >= setpoint_changes[0]:
            cmd = cmd_at(t)
            setpoint_changes.pop(0)
        T_w, T_p, T_a = plant.measure()
        fresh = plant.fresh
        w, p, a = admit(lim, T_w, T_p, T_a)  # implausible readings are no readings
        if check(t, w, p, a):
            ctrl.safe()  # safe outputs first; the plant gets them below
        else:
            ctrl.step(t, w, p, a, cmd, fresh)
        q_i, T_g, T_w_true, T_p_true = truth()
        c_t[j] = t
        c_Tw[j] = T_w
        c_Tp[j] = T_p
        c_Ta[j] = T_a
        c_v[j] = ctrl.v
        c_cmd[j] = cmd
        c_Tpc[j] = ctrl.T_p_cmd
        c_drv[j] = ctrl.drive
        c_qi[j] = est.q_i_hat
        c_dq[j] = est.dq_i_hat
        c_con[j] = ctrl.contact
        c_gap[j] = est.gap
        c_fr[j] = fresh
        c_q[j] = q_i
        c_Tg[j] = T_g
        c_Twt[j] = T_w_true
        c_Tpt[j] = T_p_true
        if est.started and on_start is not None:
            on_start(t)
        if est.written and on_event is not None:
            for e in est.written:
                on_event(e)
        plant.apply(ctrl.drive, ctrl.v)
        if sup.code:
            n_run = k + 1
            break
        if progress is not None and k % every == 0:
            progress(k / n)
        j += 1
        if j == block and k + 1 < n:
            send(k + 1)
            (c_t, c_Tw, c_Tp, c_v, c_Ta, c_cmd, c_Tpc, c_drv, c_qi, c_dq, c_con, c_gap, c_fr, c_q, c_Tg,
             c_Twt, c_Tpt) = new_block()
            j = 0
    fault_code = sup.code if sup.code != sv.STOPPED else 0
    send(n_run, fault_code)
    n_events = len(est.events)
    est.finish((n_run - 1) * t_s)
    if on_event is not None:
        for e in est.events[n_events:]:
            on_event(e)
    wall = time.perf_counter() - wall0
    if progress is not None:
        progress(1.0)
    columns: dict[str, NDArray[Any]] = {}
    if keep:
        columns = {k: (np.concatenate([b[k] for b in kept]) if kept else np.zeros(0)) for k in COLUMNS}
        for k in ("contact", "gap", "fresh", "contact_true", "n_fingers"):
            columns[k] = columns[k].astype(np.int8)
    summary = {"fault": sup.code, "fault_name": sv.FAULTS[sup.code], "detail": sup.detail,
               "t_fault": sup.t_fault, "fault_value": sup.value, "t_safe": sup.t_fault,
               "interrupted": sup.code == sv.STOPPED, "rows": n_run}
    return LoopResult(columns=columns, events=est.events, scenario=scenario, wall_s=wall, summary=summary)
