"""The runs behind the figures, as picklable jobs (so that a process pool can share them out).

Every contact and set-point run is the closed loop (:func:`run_closed_loop`: plant with the
Peltier tank, pump logic, MPC, inner loop, observer and detector) from ambient. Fig. 19 has
two more kinds, both on the spatial skin with the pump logic on the measured ``T_w`` and the
tank held at ``T_w_cmd + 0.3 K`` (open loop in ``T_p``, as ``thermoskin simulate``):
``"stopped"`` stops the pump while a finger is on (what Sec. V's rule does whenever the
touch heats the pipe above its command), ``"inlet-near"`` lets the water enter at the
thermocouple end. :func:`open_loop_spatial` says why.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from thermoskin.control.pump import PumpLogic
from thermoskin.estimation.estimator import TouchEstimator
from thermoskin.estimation.events import ContactEvent
from thermoskin.estimation.observer import ThermalExchangeObserver
from thermoskin.experiments.analysis import aligned_response, contact_stats, setpoint_stats
from thermoskin.experiments.scenarios import T_A, contact_scenario, setpoint_scenario
from thermoskin.fit.identify import decimate_blocks
from thermoskin.params import Config, load_config
from thermoskin.physics.spatial import SpatialParams
from thermoskin.runtime.closed_loop import run_closed_loop
from thermoskin.sim.plant import SimulatedPlant
from thermoskin.sim.scenarios import Scenario

Array = NDArray[np.float64]

PLOT_EVERY = 10
"""Logs returned for plotting are means over blocks of 10 samples (100 Hz)."""
PLOT_KEYS = ("t", "T_w", "T_p", "v", "T_w_cmd", "T_p_cmd", "q_i_hat", "dq_i_hat", "q_i", "T_g",
             "T_w_true", "contact_true")
T_P_OFFSET = 0.3
"""Tank above the command in the open-loop spatial runs, K (``Scenario.T_p_offset``)."""


@dataclass(frozen=True)
class Job:
    """One run: ``kind`` is ``setpoint``, ``contacts`` (closed loop), ``stopped`` or ``inlet-near``."""

    key: str
    kind: str
    T_w_cmd: float = 24.0
    n_fingers: int = 1
    person: str = "man1"
    position: float = 0.0
    skin_model: str = "network"
    n_contacts: int = 15
    duration: float = 60.0

    def scenario(self) -> Scenario:
        if self.kind == "setpoint":
            return setpoint_scenario(self.T_w_cmd, self.duration)
        return contact_scenario(self.n_fingers, self.person, self.position, self.n_contacts, name=self.key)


def open_loop_spatial(sc: Scenario, cfg: Config, *, stop_in_contact: bool, inlet: str = "far"
                      ) -> tuple[list[ContactEvent], dict[str, Array]]:
    """The spatial skin (the simulated plant, prescribed tank) with the pump logic and a held
    tank; observer and detector over the log.

    Why not the closed loop: with thermocouple noise of 0.02 K and no hysteresis the pump
    switches at its 50 ms dwell whatever a touch does (a finger moves ``T_w`` by about
    0.01 K while the pump runs), so in the closed loop the pump runs half the time during
    every contact. With the water flowing from the far end past the thermocouple
    (``inlet = "far"``) the outlet collects every cell's heat and a touch reads the same
    wherever it is; only the stopped phases, too short here, let distance matter. The paper
    explains Fig. 19 by conduction ("thermal attenuation ... depending on the distance")
    and its pump rule stops the water whenever the pipe is above its command, which a
    finger at 34 °C does on the prototype (Sec. VI-B: the pipe was held at 24 °C "other
    than the time that human contacted"). ``stop_in_contact`` runs that case: the pump
    logic holds ``T_w`` between contacts and the pump is stopped while a finger is on.
    The command and the tank are not changed, so the loss of the pump's heat during a
    contact cools the pipe by about 2 K; the observer's model knows ``v = 0`` and takes it
    out of ``dq_i_hat``.
    """
    t_s = cfg.sampling.t_s
    sc = dataclasses.replace(sc, T_p_offset=T_P_OFFSET, T_p_drift=0.0, setpoints=())
    plant = SimulatedPlant(cfg, sc, skin_model="spatial", tank="prescribed",
                           spatial=SpatialParams(inlet=inlet))
    n = plant.n
    cmd = float(sc.T_w_cmd)
    plant.reset("command", T_w0=cmd)
    pump = PumpLogic(cfg.pump, t_s)
    prof = plant.profile()
    G_l = prof["G_c"].tolist()
    T_w, T_p_m, T_a_m, T_w_true, T_g, v = (np.zeros(n) for _ in range(6))
    fresh = np.zeros(n, dtype=np.int64)
    skin = plant.skin
    for k in range(n):
        T_w_true[k] = skin.T_w
        T_g[k] = skin.T_g
        m, T_p_m[k], T_a_m[k] = plant.measure()
        T_w[k] = m
        fresh[k] = plant.fresh
        vk = pump.step(m, cmd)
        if stop_in_contact and G_l[k] > 0.0:
            vk = 0.0
        v[k] = vk
        plant.apply(0.0, vk)
    t = np.arange(n) * t_s
    out = TouchEstimator(cfg, t_s=t_s).run(t, T_w, T_p_m, v, T_a_m, fresh=fresh)
    G, T_f = prof["G_c"], prof["T_f"]
    return out.events, {"t": t, "T_w": T_w, "T_p": T_p_m, "v": v, "T_a": T_a_m, "T_w_cmd": np.full(n, cmd),
            "T_p_cmd": prof["T_p"], "q_i_hat": out.columns["q_i_hat"],
            "dq_i_hat": out.columns["dq_i_hat"],
            "q_i": G * (T_f - T_g), "T_g": T_g, "T_w_true": T_w_true, "contact_true": (G > 0).astype(float)}


def run_job(job: Job, cfg: Config | None = None) -> dict[str, Any]:
    """Run one job; return its key numbers, aligned responses and a decimated log for plots."""
    cfg = cfg or load_config()
    sc = job.scenario()
    wall0 = time.perf_counter()
    events: list[Any] = []
    if job.kind in ("setpoint", "contacts"):
        res = run_closed_loop(sc, cfg, skin_model=job.skin_model)
        cols, events = res.columns, res.events
    elif job.kind in ("stopped", "inlet-near"):
        events, cols = open_loop_spatial(sc, cfg, stop_in_contact=job.kind == "stopped",
                                 inlet="near" if job.kind == "inlet-near" else "far")
    else:
        raise ValueError(f"unknown job kind {job.kind!r}")
    # The figures show the paper's observer: its dq_i_hat is the change of the eq. 8 estimate
    # from what eq. 8 gives with no touch (the detector's events come from the estimator).
    cols = dict(cols)
    cols["dq_i_hat"] = ThermalExchangeObserver(cfg.skin, cfg.observer, cfg.sampling.t_s).run(
        cols["T_w"], cols["T_p"], cols["v"], cols["T_a"]).dq_i_hat
    out: dict[str, Any] = {"job": job, "scenario": sc, "wall_s": time.perf_counter() - wall0,
                           "n_events": len(events),
                           "events": [(e.onset, e.release) for e in events]}
    if job.kind == "setpoint":
        out["stats"] = setpoint_stats(cols, cfg.sampling.t_s)
    else:
        st = contact_stats(cols, sc.touches, events)
        out["stats"] = st.summary()
        out["per_contact"] = {"mean_dq": st.mean_dq, "peak_dq": st.peak_dq, "rise": st.rise}
        out["aligned"] = aligned_response(cols, sc.touches, baseline=st.baseline)
        out["aligned_q"] = aligned_response(cols, sc.touches, key="q_i", baseline=0.0)
        touched = np.asarray(cols["contact_true"]) > 0
        out["pump_on_in_contact"] = float(np.mean(np.asarray(cols["v"])[touched] > 0))
    out["cols"] = {k: decimate_blocks(np.asarray(cols[k], dtype=float), PLOT_EVERY)
                   for k in PLOT_KEYS if k in cols}
    out["T_a"] = T_A
    return out
