"""The simulated plant: skin, tank, sensors, touches and ambient, stepped one ``t_s`` at a time.

One plant serves every simulated path: ``sim.run.simulate`` (open loop, prescribed
``T_p``, pump logic), ``runtime.closed_loop`` (Peltier tank under the loop body),
``devices.sim_device.SimDevice`` (the realtime loop's device), the device emulator's
``DeviceCore`` (touches and ambient repeating every scenario duration) and the spatial
runs of ``experiments.runs``. A fix to the plant is a fix to all of them.

Per sample ``k`` (``t_k = k t_s``)::

    T_w, T_p, T_a = plant.measure()   # the boards' readings of the state at t_k; plant.fresh
    plant.apply(drive, v)             # hold drive and v over [t_k, t_k+1), advance (ZOH)

- **skin**: ``"network"``, the two-node network of Fig. 3 (``sim.skin.SimulatedSkin``,
  what the observer assumes), or ``"spatial"``, cells along the pipe
  (``sim.spatial_skin.SpatialSkin``), each touch at its ``position``;
- **tank**: ``"peltier"``, the Peltier tank (``physics.peltier.PeltierTank``) driven by
  ``drive`` and losing ``q_p = (T_p - T_w)/R_w(v)`` to the skin's water (the spatial skin:
  exactly the heat its water brought over the sample, ``SpatialSkin.q_water``); or
  ``"prescribed"``, ``T_p = scenario.T_p(t)`` (``drive`` ignored);
- **touches** ``G_c, T_f`` (``physics.finger.contact_profile``) and the **true ambient**
  ``scenario.T_a_at(t)`` drive the skin (and the tank's loss to the air); with
  ``repeat=True`` both repeat every ``scenario.duration`` and the plant runs for ever;
- **sensors** (``sim.sensors.Sensors``) read ``T_w``, ``T_p`` and the true ambient once per
  sample: the boards ``boards`` (their true offsets, noise, lags: ``sim.boards``), by default
  the config's ``[sensor]`` (what the lab believes its boards are);
- **touchers** (a touch naming ``toucher``, :mod:`thermoskin.physics.contact`): a body of
  its own behind the touch's ramped conductance ``G_j(t)``, stepped against the sheet every
  sample. Over sample ``k`` toucher ``j`` is exactly a conductance ``G_eff,j`` to a source
  at ``T_eff,j`` (``Toucher.begin``); with the fixed touches ``(G_x, T_x)`` the skin steps
  with ``G_c = G_x + sum_j G_eff,j`` and ``T_f = (G_x T_x + sum_j G_eff,j T_eff,j)/G_c``, then
  each toucher completes its step with the sheet's mean over the sample
  ``(T_g[k] + T_g[k+1])/2`` (``Toucher.end``). Each toucher starts from its preset's rest
  (the touch's ``T_body``) at its touch, so a repeating plant replays it; a scenario without
  touchers takes the fixed-touch path unchanged.

Truth at sample ``k`` (:meth:`truth`): ``q_i = G_c(t_k) (T_f(t_k) - T_g(t_k))`` with the
contact applied from ``t_k`` on (as the open-loop log), ``T_g``, ``T_w``, ``T_p``; a toucher
adds ``G_j(t_k) (T_s,j(t_k) - T_g(t_k))`` with its surface temperature now.
:meth:`contact_truth` names the current contact (the latest begun): ``toucher_true``
(``human``/``object``, ``""`` for a fixed touch without fingers), ``material_true`` (its
class, :data:`thermoskin.physics.contact.CLASSES`), ``T_f_true`` (its surface temperature
at the onset, °C) and ``G_true`` (its conductance once pressed, W/K); in a log
(:meth:`truth_columns`) as numbers: ``toucher_true`` 1/0/-1 (human, object, no contact),
``material_true`` the class's index (-1 no contact).

Starts (:meth:`reset`): ``"ambient"`` (tank, heat sink, pipe and sheet at the air, the
closed loop's start), ``"command"`` (the pipe at ``T_w0``, the sheet in its equilibrium
for it) or ``"equilibrium"`` (the network's equilibrium for ``T_p(0)`` and a held ``v``;
a Peltier tank at ``T_p(0)``, its sink at the air).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from thermoskin.params import Config, SensorParams
from thermoskin.physics.convection import FlowResistance
from thermoskin.physics.finger import T_F_IDLE, Touch, body_temperature, contact_profile, full_conductance
from thermoskin.physics.peltier import PeltierTank
from thermoskin.physics.spatial import SpatialParams
from thermoskin.sim.scenarios import Scenario
from thermoskin.sim.sensors import Sensors
from thermoskin.sim.skin import SimulatedSkin

if TYPE_CHECKING:
    from thermoskin.physics.contact import Toucher

SKIN_MODELS = ("network", "spatial")
TANKS = ("peltier", "prescribed")
STARTS = ("ambient", "command", "equilibrium")
WINDOW = 16_384
"""Samples of the scenario's profiles the plant holds at a time (:meth:`SimulatedPlant._window`)."""


#: ``toucher_true`` in a log: the toucher as a number.
TOUCHER_CODES = {"human": 1, "object": 0}


class SimulatedPlant:
    """One scenario on the simulated skin, sample by sample (see the module doc).

    ``n`` samples (default: the scenario's duration); with ``repeat`` the profiles span one
    scenario duration and repeat. The scenario's profiles over those samples (contacts,
    positions, ambient, a prescribed tank: :meth:`profile`) are computed :data:`WINDOW`
    samples at a time as the plant reaches them, so its memory does not grow with ``n``.
    """

    def __init__(self, cfg: Config, scenario: Scenario, n: int | None = None,
                 skin_model: str = "network", *, tank: str = "peltier", repeat: bool = False,
                 spatial: SpatialParams | None = None, boards: SensorParams | None = None) -> None:
        if skin_model not in SKIN_MODELS:
            raise ValueError(f"unknown skin_model {skin_model!r} (network or spatial)")
        if tank not in TANKS:
            raise ValueError(f"unknown tank {tank!r} (peltier or prescribed)")
        t_s = cfg.sampling.t_s
        self.cfg = cfg
        self.scenario = scenario
        self.t_s = t_s
        self.repeat = bool(repeat)
        self.n = n if n is not None else max(1, math.floor(scenario.duration / t_s + 1e-9))
        self.spatial = skin_model == "spatial"
        if self.spatial:
            from thermoskin.sim.spatial_skin import SpatialSkin

            self.skin: SimulatedSkin = SpatialSkin(cfg, spatial)  # type: ignore[assignment]
            self.skin.track_exchange = tank == "peltier"  # type: ignore[attr-defined]
        else:
            self.skin = SimulatedSkin(cfg)
        self.prescribed = tank == "prescribed"
        self.tank = PeltierTank(cfg.peltier, t_s, (cfg.control.drive_min, cfg.control.drive_max))
        self.R_w = FlowResistance(cfg.skin)
        self.boards = cfg.sensor if boards is None else boards
        self.sensors = Sensors(self.boards, t_s)
        self._init_touchers(scenario)
        self._w0, self._w1 = 0, 0  # the profiles' window: samples [w0, w1) (``_window``)
        self.k = 0
        self.reset()

    # -- profiles ------------------------------------------------------------------------
    def profile(self, k0: int = 0, k1: int | None = None) -> dict[str, NDArray[np.generic]]:
        """The scenario's profiles over samples ``[k0, k1)`` of the profile (default: all
        ``n``), computed afresh (nothing is held): ``t`` (s), ``G_c`` (W/K), ``T_f`` (°C) and
        ``n_fingers`` of the fixed touches and touchers' ramps together
        (:func:`~thermoskin.physics.finger.contact_profile`), ``position`` (m, the touch's
        on the spatial skin, 0 elsewhere), ``T_a_true`` (°C, the true ambient), ``T_p`` (°C,
        the prescribed tank, NaN for a Peltier tank) and ``current`` (the index in
        ``scenario.touches`` of the contact, -1 none). Each is a function of ``t_k = k t_s``
        alone, so any cut of the samples gives the same values."""
        k0, k1 = self._span(k0, k1)
        sc = self.scenario
        t = np.arange(k0, k1) * self.t_s
        G_c, T_f, n_f = contact_profile(sc.touches, t)
        pos = np.zeros(t.size)
        cur = np.full(t.size, -1, dtype=np.int64)
        for j, tc in enumerate(sc.touches):
            on = (t >= tc.t_on) & (t < tc.t_off)
            pos[on] = tc.position
            cur[(t > tc.t_on) & (t < tc.t_off)] = j
        T_p = (np.asarray(sc.T_p(t), dtype=float) if self.prescribed else np.full(t.size, math.nan))
        return {"t": t, "G_c": G_c, "T_f": T_f, "n_fingers": n_f, "position": pos,
                "T_a_true": np.asarray(sc.T_a_at(t), dtype=float), "T_p": T_p, "current": cur}

    def contact_columns(self, k0: int = 0, k1: int | None = None) -> dict[str, NDArray[np.generic]]:
        """The contact truth a log holds over samples ``[k0, k1)`` of the profile (default: all):
        ``contact_true`` (int8, 1 while ``G_c > 0``) and ``n_fingers``, as :meth:`profile` and
        :meth:`contact` give them, without the profile's other columns (the closed loop asks
        for them every block)."""
        k0, k1 = self._span(k0, k1)
        G_c, _, n_f = contact_profile(self.scenario.touches, np.arange(k0, k1) * self.t_s)
        return {"contact_true": (G_c > 0.0).astype(np.int8), "n_fingers": n_f}

    def _span(self, k0: int, k1: int | None) -> tuple[int, int]:
        """Samples ``[k0, k1)`` of the profile, within ``[0, n]`` (``k1`` None: to ``n``)."""
        k1 = self.n if k1 is None else min(int(k1), self.n)
        return min(max(0, int(k0)), k1), k1

    def _window(self, i: int) -> int:
        """Sample ``i``'s place in the profiles' window, which is moved to hold it if it does
        not: :data:`WINDOW` samples from a multiple of it, as plain lists for the per-sample
        path. The plant holds only this window, so its memory does not grow with ``n``."""
        if self._w0 <= i < self._w1:
            return i - self._w0
        w0 = i - i % WINDOW
        w1 = min(self.n, w0 + WINDOW)
        p = self.profile(w0, w1)
        self._G_c: list[float] = p["G_c"].tolist()
        self._T_f: list[float] = p["T_f"].tolist()
        self._n_f: list[int] = p["n_fingers"].tolist()
        self._pos: list[float] = p["position"].tolist()
        self._T_a: list[float] = p["T_a_true"].tolist()
        self._T_p: list[float] = p["T_p"].tolist()
        self._cur: list[int] = p["current"].tolist()
        if self.touchers:
            t = p["t"]
            fixed = [tc for tc, tch in zip(self.scenario.touches, self._has_toucher, strict=True) if not tch]
            G_x, T_x, _ = contact_profile(fixed, t)
            self._G_x: list[float] = G_x.tolist()
            self._T_x: list[float] = T_x.tolist()
            self._wt: list[tuple[int, int, list[float], Toucher]] = []
            """``(lo, hi, G_j over [lo, hi), Toucher)`` of each toucher in contact within the
            window, ``lo, hi`` window places, in the scenario's order."""
            for tc, tch in self.touchers:
                lo, hi = (int(x) for x in np.searchsorted(t, [tc.t_on, tc.t_off], side="right"))
                if lo < hi:
                    g, _, _ = contact_profile([tc], t[lo:hi])
                    self._wt.append((lo, hi, g.tolist(), tch))
        self._w0, self._w1 = w0, w1
        return i - w0

    # -- state ---------------------------------------------------------------------------
    def reset(self, start: str = "ambient", *, T_w0: float | None = None, v: float = 0.0) -> None:
        """Back to sample 0, sensors from their seed; ``start`` one of :data:`STARTS` (module doc).

        ``T_w0`` (°C) is the pipe of a ``"command"`` start (default ``scenario.T_w_cmd_at(0)``),
        ``v`` (m/s) the pump held for an ``"equilibrium"`` start.
        """
        if start not in STARTS:
            raise ValueError(f"SimulatedPlant.reset: start = {start!r} must be one of {STARTS}")
        self.k = 0
        self._k_read = -1
        self._reading = (math.nan, math.nan, math.nan)
        self.fresh = 0
        self.sensors.reset()
        self._rest_touchers()
        j = self._window(0)
        T_a, G0, T_f0 = self._T_a[j], self._G_c[j], self._T_f[j]
        skin, tank = self.skin, self.tank
        if start == "ambient":
            tank.reset(T_a, T_a, T_a)
            skin.reset(T_a, T_a=T_a, G_c=G0, T_f=T_f0)
            return
        T_p0 = float(self.scenario.T_p(0.0))
        tank.reset(T_p0, None, T_a)
        if start == "command":
            w0 = self.scenario.T_w_cmd_at(0.0) if T_w0 is None else float(T_w0)
            skin.reset(w0, T_a=T_a, G_c=G0, T_f=T_f0)
        else:
            skin.reset_equilibrium(T_p0, v, T_a, G0, T_f0)

    # -- touchers ------------------------------------------------------------------------
    def _init_touchers(self, scenario: Scenario) -> None:
        """The touchers of the touches that name one, and each touch's contact truth."""
        touches = scenario.touches
        self.touchers: list[tuple[Touch, Toucher]] = []
        """``(touch, its Toucher)`` per touch naming a toucher, in the scenario's order."""
        self._has_toucher = [tc.toucher is not None for tc in touches]
        self._rest: list[list[float]] = []
        rows = []
        for tc in touches:
            if tc.toucher is None:
                who = "human" if tc.n_fingers > 0 else ""
                rows.append((who, "human" if who else "", body_temperature(tc), full_conductance(tc)))
                continue
            from thermoskin.physics.contact import toucher

            tch = toucher(tc.toucher, body_temperature(tc), tc.area, tc.pressure, t_s=self.t_s,
                          T_env=float(scenario.T_a_at(tc.t_on)))
            self.touchers.append((tc, tch))
            self._rest.append(list(tch.T))
            tr = tch.truth
            rows.append((tr["toucher_true"], tr["class_true"], tr["T_f_true"], tr["G_true"]))
        self.touch_truth: list[tuple[str, str, float, float]] = rows
        """``(toucher_true, material_true, T_f_true, G_true)`` per touch (``material_true``: the
        class, one of ``contact.CLASSES``)."""

    def _rest_touchers(self) -> None:
        """Every toucher back to its rest before its touch."""
        for (_, tch), T0 in zip(self.touchers, self._rest, strict=True):
            tch.set_state(T0)

    def contact_truth(self) -> tuple[str, str, float, float]:
        """``(toucher_true, material_true, T_f_true, G_true)`` of the contact now (module doc);
        ``("", "", nan, nan)`` outside contacts."""
        j = self._cur[self._window(self.index())]
        return self.touch_truth[j] if j >= 0 else ("", "", math.nan, math.nan)

    def truth_columns(self, k0: int = 0, k1: int | None = None) -> dict[str, NDArray[np.generic]]:
        """:meth:`contact_truth` over samples ``[k0, k1)`` of the profile (default: all) as
        numbers a log holds (the log schema is numeric): ``toucher_true``
        (:data:`TOUCHER_CODES`: 1 human, 0 object, -1 no contact), ``material_true`` (the
        index of the class in :data:`thermoskin.physics.contact.CLASSES`, -1 no contact),
        ``T_f_true`` (°C, NaN outside contacts), ``G_true`` (W/K, 0 outside contacts)."""
        from thermoskin.physics.contact import CLASSES

        cur = self.profile(k0, k1)["current"]
        rows = [*self.touch_truth, ("", "", math.nan, 0.0)]  # index -1: no contact
        who = np.array([TOUCHER_CODES.get(r[0], -1) for r in rows], dtype=np.int8)
        mat = np.array([CLASSES.index(r[1]) if r[1] in CLASSES else -1 for r in rows], dtype=np.int8)
        T_f = np.array([r[2] for r in rows])
        G = np.array([r[3] for r in rows])
        return {"toucher_true": who[cur], "material_true": mat[cur], "T_f_true": T_f[cur], "G_true": G[cur]}

    def index(self) -> int:
        """Index of the current sample in the profiles (``k``, or ``k mod n`` when repeating)."""
        return self.k % self.n if self.repeat else self.k

    @property
    def T_p_true(self) -> float:
        """The tank's true temperature now, °C."""
        return self._T_p[self._window(self.index())] if self.prescribed else self.tank.T_p

    def measure(self) -> tuple[float, float, float]:
        """``(T_w, T_p, T_a)`` as the thermocouples read them now (°C); ``fresh`` their bit mask.

        The sensors advance once per sample: a second call in the same sample repeats the first.
        """
        k = self.k
        if self._k_read != k:
            i = k % self.n if self.repeat else k
            j = i - self._w0
            if j < 0 or i >= self._w1:
                j = self._window(i)
            sens = self.sensors
            T_p = self._T_p[j] if self.prescribed else self.tank.T_p
            self._reading = r = sens.read(self.skin.T_w, T_p, self._T_a[j])
            self.fresh = sens.fresh
            self._k_read = k
            return r
        return self._reading

    def truth(self) -> tuple[float, float, float, float]:
        """``(q_i, T_g, T_w, T_p)`` now (W, °C): ``q_i`` with the contact applied from now on."""
        i = self.k % self.n if self.repeat else self.k
        j = i - self._w0
        if j < 0 or i >= self._w1:
            j = self._window(i)
        skin = self.skin
        T_g = skin.T_g
        T_p = self._T_p[j] if self.prescribed else self.tank.T_p
        if self.touchers:
            G = self._G_x[j]
            q_i = G * (self._T_x[j] - T_g) if G > 0.0 else 0.0
            for lo, hi, g, tch in self._wt:
                if lo <= j < hi and g[j - lo] > 0.0:
                    q_i += g[j - lo] * (tch.T_s - T_g)
            return q_i, T_g, skin.T_w, T_p
        G = self._G_c[j]
        q_i = G * (self._T_f[j] - T_g) if G > 0.0 else 0.0
        return q_i, T_g, skin.T_w, T_p

    def contact(self) -> tuple[int, int]:
        """``(contact_true, n_fingers)`` now: 1 while ``G_c > 0``, and the fingers touching."""
        j = self._window(self.index())
        return (1 if self._G_c[j] > 0.0 else 0), self._n_f[j]

    def apply(self, drive: float, v: float) -> None:
        """Hold ``drive`` and ``v`` over one sample and advance."""
        k = self.k
        if self._k_read != k:
            self.measure()  # the sensors see every sample
        i = k % self.n if self.repeat else k
        j = i - self._w0
        if j < 0 or i >= self._w1:
            j = self._window(i)
        skin = self.skin
        T_a = self._T_a[j]
        if self.prescribed:
            T_p = self._T_p[j]
        else:
            tank = self.tank
            T_p = tank.T_p
            if not self.spatial:
                tank.step(drive, T_a, (T_p - skin.T_w) / self.R_w(v))
        if self.touchers:
            self._step_touchers(j, T_p, v, T_a)
        elif self.spatial:
            skin.step(T_p, v, T_a, self._G_c[j], self._T_f[j],
                      position=self._pos[j])  # type: ignore[call-arg]
        else:
            skin.step(T_p, v, T_a, self._G_c[j], self._T_f[j])
        if self.spatial and not self.prescribed:  # the heat the water brought to the skin over the sample
            self.tank.step(drive, T_a, skin.q_water)  # type: ignore[attr-defined]
        self.k = k + 1
        if self.repeat and self.touchers and self.k % self.n == 0:
            self._rest_touchers()

    def _step_touchers(self, j: int, T_p: float, v: float, T_a: float) -> None:
        """The skin's step with the touchers at window place ``j`` (module doc), then theirs."""
        skin = self.skin
        G = self._G_x[j]
        GT = G * self._T_x[j] if G > 0.0 else 0.0
        for lo, hi, g, tch in self._wt:
            if lo <= j < hi:
                tch.begin(g[j - lo])
                ge = tch.G_eff
                if ge > 0.0:
                    G += ge
                    GT += ge * tch.T_eff
        T_f = GT / G if G > 0.0 else T_F_IDLE
        T_g0 = skin.T_g
        if self.spatial:
            skin.step(T_p, v, T_a, G, T_f, position=self._pos[j])  # type: ignore[call-arg]
        else:
            skin.step(T_p, v, T_a, G, T_f)
        T_gm = 0.5 * (T_g0 + skin.T_g)
        for lo, hi, _, tch in self._wt:  # the same touchers, without a list per sample
            if lo <= j < hi:
                tch.end(T_gm)
