"""The in-process simulated skin (:class:`~thermoskin.sim.plant.SimulatedPlant`) as a device.

``read_sample`` measures the plant at the current sample (``fresh``: the channels whose
simulated board converted; every channel every sample with the default ``[sensor]``);
``write_command`` holds the drive and the pump command over one ``t_s`` and advances the
physics. ``safe()`` latches drive 0 and pump off for every later step. The simulator's
truth of the sample just read is in :meth:`truth`.
"""

from __future__ import annotations

from thermoskin.devices.base import Sample
from thermoskin.params import Config, SensorParams
from thermoskin.sim.plant import SimulatedPlant
from thermoskin.sim.scenarios import Scenario


class SimDevice:
    """A :class:`~thermoskin.devices.base.Device` backed by the simulated skin."""

    def __init__(self, cfg: Config, scenario: Scenario, skin_model: str = "network",
                 boards: SensorParams | None = None) -> None:
        self.plant = SimulatedPlant(cfg, scenario, skin_model=skin_model, boards=boards)
        self.t_s = cfg.sampling.t_s
        self.n = self.plant.n
        self._safe = False
        self._drive = 0.0
        self._v = 0.0

    def open(self) -> None:
        self.plant.reset()
        self._safe = False

    @property
    def done(self) -> bool:
        """The scenario has no more samples."""
        return self.plant.k >= self.n

    def read_sample(self, timeout: float = 0.0) -> Sample | None:
        """The sample at the plant's current step; ``None`` past the scenario's end."""
        k = self.plant.k
        if k >= self.n:
            return None
        T_w, T_p, T_a = self.plant.measure()
        return Sample(k * self.t_s, T_w, T_p, T_a, self.plant.fresh, k, self._v, self._drive)

    def truth(self) -> tuple[float, float, float, float]:
        """``(q_i, T_g, T_w, T_p)`` of the simulator at the current step (W, °C)."""
        return self.plant.truth()

    def write_command(self, drive: float, v: float) -> None:
        """Hold ``drive``, ``v`` (or the safe outputs) over one sample and advance."""
        if self._safe:
            drive = v = 0.0
        self._drive, self._v = drive, v
        if self.plant.k < self.n:
            self.plant.apply(drive, v)

    def safe(self) -> None:
        self._safe = True
        self._drive = self._v = 0.0

    def close(self) -> None:
        self.safe()

    @property
    def link_lost(self) -> bool:
        return False
