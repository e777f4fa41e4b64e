"""The simulated skin as a device: skin network, Peltier tank, sensors and scripted touches.

``measure()`` returns the thermocouple readings at the current sample; ``apply(drive, v)``
holds the Peltier drive and the pump command over one ``t_s`` and advances the physics
(zero-order hold). The tank gives the skin's water ``T_p`` and loses ``q_p`` to it.

``skin_model="network"`` is the two-node network of Fig. 3 (what the observer assumes);
``"spatial"`` is the cell model along the pipe (``physics.spatial``), where each touch acts at
its ``position`` (0 = at the thermocouple, 1 = the far end).
"""

from __future__ import annotations

import math

import numpy as np

from thermoskin.params import Config
from thermoskin.physics.convection import FlowResistance
from thermoskin.physics.finger import contact_profile
from thermoskin.physics.peltier import PeltierTank
from thermoskin.sim.scenarios import Scenario
from thermoskin.sim.sensors import Sensors
from thermoskin.sim.skin import SimulatedSkin


class SimulatedPlant:
    """One scenario on the simulated skin, sample by sample."""

    def __init__(self, cfg: Config, scenario: Scenario, n: int | None = None,
                 skin_model: str = "network") -> None:
        t_s = cfg.sampling.t_s
        self.cfg = cfg
        self.scenario = scenario
        self.t_s = t_s
        self.n = n if n is not None else max(1, math.floor(scenario.duration / t_s + 1e-9))
        t = np.arange(self.n) * t_s
        G_c, T_f, n_f = contact_profile(scenario.touches, t)
        self.G_c, self.T_f = G_c.tolist(), T_f.tolist()
        self.n_fingers = n_f
        self.position = [0.0] * self.n
        if skin_model == "spatial":
            from thermoskin.sim.spatial_skin import SpatialSkin

            pos = np.zeros(self.n)
            for tc in scenario.touches:
                pos[(t >= tc.t_on) & (t < tc.t_off)] = tc.position
            self.position = pos.tolist()
            self.skin: SimulatedSkin = SpatialSkin(cfg)  # type: ignore[assignment]
        elif skin_model == "network":
            self.skin = SimulatedSkin(cfg)
        else:
            raise ValueError(f"unknown skin_model {skin_model!r} (network or spatial)")
        self.spatial = skin_model == "spatial"
        self.tank = PeltierTank(cfg.peltier, t_s,
                                (cfg.control.drive_min, cfg.control.drive_max))
        self.R_w = FlowResistance(cfg.skin)
        self.sensors = Sensors(cfg.sensor, t_s)
        self.T_a_true = np.asarray(scenario.T_a_at(t), dtype=float)
        """The true ambient at each sample (the scenario's profile), °C."""
        self._T_a = self.T_a_true.tolist()
        self.k = 0
        self.reset()

    def reset(self) -> None:
        """Everything at ambient: the tank, the sink, the pipe and the sheet; sensors from their seed."""
        T_a = self._T_a[0]
        self.k = 0
        self._k_read = -1
        self._reading = (math.nan, math.nan, math.nan)
        self.fresh = 0
        self.sensors.reset()
        self.tank.reset(T_a, T_a, T_a)
        self.skin.reset(T_a, T_a=T_a, G_c=self.G_c[0], T_f=self.T_f[0])

    def measure(self) -> tuple[float, float, float]:
        """``(T_w, T_p, T_a)`` as the thermocouples read them now (°C); ``fresh`` their bit mask.

        The sensors advance once per sample: a second call in the same sample repeats the first.
        """
        if self._k_read != self.k:
            sens = self.sensors
            self._reading = sens.read(self.skin.T_w, self.tank.T_p, self._T_a[self.k])
            self.fresh = sens.fresh
            self._k_read = self.k
        return self._reading

    def apply(self, drive: float, v: float) -> None:
        """Hold ``drive`` and ``v`` over one sample and advance."""
        k = self.k
        if self._k_read != k:
            self.measure()  # the sensors see every sample
        skin, tank = self.skin, self.tank
        T_a = self._T_a[k]
        q_p = (tank.T_p - skin.T_w) / self.R_w(v)
        if self.spatial:
            skin.step(tank.T_p, v, T_a, self.G_c[k], self.T_f[k],
                      position=self.position[k])  # type: ignore[call-arg]
        else:
            skin.step(tank.T_p, v, T_a, self.G_c[k], self.T_f[k])
        tank.step(drive, T_a, q_p)
        self.k = k + 1
