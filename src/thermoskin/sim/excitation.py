"""Excitation log of the Peltier tank, for identifying the ``T_p`` response (Sec. V's ARMA model).

The drive (``[-1, 1]``, positive heats, see :mod:`thermoskin.physics.peltier`) is a
random multi-level signal:

- levels drawn uniformly from ``[-A_cool, A_heat]``, 9 levels, where ``A_heat`` and
  ``A_cool`` are ``amplitude`` times the steady-state drives that hold ``T_p`` at the band
  edges ``T_band`` (the default tank is so strong that ±0.1 already spans 4–40 °C);
- dwell times log-uniform between ``0.5 s`` and ``60 s``, so that the excitation covers
  the sink (~15 s) and the tank (~180 s) time constants and faster ones;
- while the true ``T_p`` is outside ``T_band`` the next level is drawn on the side that
  brings it back (the choice uses the true state, never the noisy readings, so the
  drive is independent of the measurement noise);
- a few large steps both ways (``±large`` for 8 s) at fixed fractions of the run,
  clipped to the drive limits ``cfg.control.drive_min/max``.

The skin is simulated with the pump off (``v = 0``): ``T_w`` follows the tank through the
still-water resistance ``R_w(0)`` (about 57 K/W, ``thermoskin.physics.convection``), and the
tank gives up ``q_p = (T_p - T_w)/R_w(0)`` to it (a few tenths of a watt at most,
against the watts of the tank's own loss; ``couple_skin=False`` neglects it).

Columns (``sim.run`` conventions; row ``k`` holds the state at ``t_k`` and the drive applied
over ``[t_k, t_k+1)``): measured ``t, T_w, T_p, v, T_a, drive`` (thermocouple noise and
quantisation from ``cfg.sensor`` on the temperatures); truth ``T_p_true, T_sink,
T_w_true, P_elec`` (W).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from thermoskin.params import Config
from thermoskin.physics.finger import T_F_IDLE
from thermoskin.physics.peltier import PeltierTank
from thermoskin.sim.skin import Sensors, SimulatedSkin

COLUMNS = ("t", "T_w", "T_p", "v", "T_a", "drive", "T_p_true", "T_sink", "T_w_true", "P_elec")


def drive_signal(n: int, t_s: float, rng: np.random.Generator, A_heat: float, A_cool: float,
                 dwell: tuple[float, float] = (0.5, 60.0), n_levels: int = 9
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Open-loop part of the excitation: switch sample indices and proposed levels.

    Returns ``(starts, levels)``: segment ``i`` starts at sample ``starts[i]`` with the
    level ``levels[i]``, a value of the ``n_levels`` grid on ``[-A_cool, A_heat]``; the sign
    is decided online by the band guard (see the module doc).
    """
    grid = np.linspace(-A_cool, A_heat, n_levels)
    starts = [0]
    while starts[-1] < n:
        d = math.exp(rng.uniform(math.log(dwell[0]), math.log(dwell[1])))
        starts.append(starts[-1] + max(1, round(d / t_s)))
    starts_a = np.asarray(starts[:-1], dtype=np.int64)
    return starts_a, rng.choice(grid, size=starts_a.size)


def simulate_excitation(cfg: Config, duration: float = 600.0, seed: int = 0,
                        progress: Callable[[float], None] | None = None, *, T_a: float = 20.0,
                        T_p0: float = 24.0, T_band: tuple[float, float] = (12.0, 36.0),
                        amplitude: float = 2.5, large: float = 0.4,
                        couple_skin: bool = True) -> dict[str, np.ndarray]:
    """Log the Peltier tank under a rich drive for ``duration`` s at ``cfg.sampling.t_s``.

    Starts in steady state at ``T_p0`` (the drive that holds it, sink in equilibrium).
    ``seed`` sets the drive; the sensor noise comes from ``cfg.sensor.seed``.
    """
    if not duration > 0.0:
        raise ValueError(f"simulate_excitation: duration = {duration} s must be > 0")
    t_s = cfg.sampling.t_s
    n = max(2, math.floor(duration / t_s + 1e-9))
    t = np.arange(n) * t_s
    lo, hi = cfg.control.drive_min, cfg.control.drive_max
    tank = PeltierTank(cfg.peltier, t_s, (lo, hi))
    skin = SimulatedSkin(cfg)
    R_w0 = skin.R_w(0.0)

    d0 = tank.drive_for(T_p0, T_a)
    A_heat = min(hi, amplitude * max(tank.drive_for(T_band[1], T_a), 1e-3))
    A_cool = min(-lo, amplitude * max(-tank.drive_for(T_band[0], T_a), 1e-3))
    rng = np.random.default_rng(seed)
    starts, levels = drive_signal(n, t_s, rng, A_heat, A_cool)
    # large steps both ways: (fraction of the run, level), 8 s each
    big = [(0.15, large), (0.35, -large), (0.6, -large), (0.8, large)]
    n_big = max(1, round(8.0 / t_s))
    big_at = {round(f * n): min(max(lvl, lo), hi) for f, lvl in big}
    seg_at = dict(zip(starts.tolist(), levels.tolist(), strict=True))

    skin.reset_equilibrium(T_p0, 0.0, T_a)  # tank, sink and skin start together in steady state
    q0 = (T_p0 - skin.T_w) / R_w0 if couple_skin else 0.0
    d0 = tank.drive_for(T_p0, T_a, q0)
    tank.reset_steady(d0, T_a, q0)

    drive = np.empty(n)
    T_p = [0.0] * n
    T_sink = [0.0] * n
    T_w = [0.0] * n
    P = [0.0] * n
    level = d0
    big_left = 0
    band_lo, band_hi = T_band
    step, skin_step = tank.step, skin.step
    every = max(1, n // 100)
    next_report = every if progress is not None else n + 1
    for k in range(n):
        x = tank.T_p
        T_p[k] = x
        T_sink[k] = tank.T_sink
        Tw = skin.T_w
        T_w[k] = Tw
        if k in big_at:
            level, big_left = big_at[k], n_big
        elif big_left > 0:
            big_left -= 1
            if big_left == 0:
                level = 0.0
        elif k in seg_at:
            level = seg_at[k]
            if (x > band_hi and level > 0.0) or (x < band_lo and level < 0.0):
                level = -level * (A_cool / A_heat if level > 0.0 else A_heat / A_cool)
        drive[k] = level
        q_p = (x - Tw) / R_w0 if couple_skin else 0.0
        step(level, T_a, q_p)
        P[k] = tank.P_elec
        skin_step(x, 0.0, T_a, 0.0, T_F_IDLE)
        if k + 1 >= next_report:
            progress((k + 1) / n)  # type: ignore[misc]
            next_report += every
    if progress is not None and next_report - every < n:
        progress(1.0)

    sensors = Sensors(cfg.sensor, cfg.sampling.t_s)
    T_p_true = np.asarray(T_p)
    T_w_true = np.asarray(T_w)
    return {
        "t": t,
        "T_w": sensors.measure("T_w", T_w_true),
        "T_p": sensors.measure("T_p", T_p_true),
        "v": np.zeros(n),
        "T_a": sensors.measure("T_a", np.full(n, float(T_a))),
        "drive": np.clip(drive, lo, hi),
        "T_p_true": T_p_true,
        "T_sink": np.asarray(T_sink),
        "T_w_true": T_w_true,
        "P_elec": np.asarray(P),
    }
