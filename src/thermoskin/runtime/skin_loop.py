"""A whole skin in closed loop: one temperature controller per water loop, a long-format log.

Each loop of the skin (``skin.py``) has its own tank, Peltier and pump, and its own
:class:`~thermoskin.runtime.controller.SkinController` (pump logic, MPC of eqs. 9-11, inner PI
on the drive; no estimator: the patches are estimated from the log, per patch). The
controlled temperature is the ``T_w`` reading of the loop's **feedback** patch, by default
the last patch the water passes before it returns to the tank: as on the paper's single
patch, the thermocouple sits where the water leaves, so the pump's rule (stop while the
pipe is above its command) stops the water once the whole loop is warm enough, and the
patches upstream (warmer, the water cools along the loop) are never colder than the command.

The MPC's model is the one-node pipe of eq. 10. For a loop it is the **lumped loop**: the
capacitance of all its patches' pipes (``sum C_w``), the sheet's ``C_g``, ``R_g``, ``R_ag``
of all patches in parallel, and a loss to the air (``R_aw``) such that the model's steady
gain from ``T_p`` to the controlled ``T_w``, ``W / (W + G)``, is the loop's own (its patches
and pipes in series with the pump running, ``SkinPlant``'s equilibrium chain); ``R_w(v)`` is the
loop's (eq. 1). The transport delays are not in the model; the pump's switching absorbs them.

The log (``LogWriter``, CSV or Parquet, written every ``block`` samples: memory does not
grow with the duration) has one row per sample and patch, patches in the description's order
(``patch`` is the index into ``skin.patches``)::

    t, patch, T_w, T_p, v, T_a, [T_w2, ...], q_i, contact_true, position_true, fresh

``T_w`` (``T_w2``, ...) the patch's thermocouples (NaN where a patch has fewer), ``T_p``, ``v``,
``T_a`` its loop's tank, pump and air readings, the truth ``q_i`` (W), ``contact_true``,
``position_true`` (m from the patch's inlet, NaN without contact), and ``fresh`` (bits:
``T_w`` 1, the loop's ``T_p`` 2 and ``T_a`` 4, ``T_w2`` 8, ``T_w3`` 16, ...).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from thermoskin.params import Config
from thermoskin.runtime.controller import SkinController
from thermoskin.runtime.runlog import FLUSH_S
from thermoskin.sim.skin_plant import SkinPlant
from thermoskin.sim.skin_scenarios import SkinScenario
from thermoskin.skin.layout import Skin

Array = NDArray[np.float64]


def lumped_loop(skin: Skin, j: int, gain: float) -> Config:
    """The config of loop ``j``'s controller: the lumped loop (module doc) with steady ``gain``
    (``(T_w - T_a) / (T_p - T_a)`` at the feedback thermocouple, pump running)."""
    from thermoskin.physics.convection import R_w

    lp = skin.loops[j]
    ps = [skin.patches[i].skin for i in lp.patches]
    cfg = lp.cfg
    W = 1.0 / R_w(cfg.pump.v_on, cfg.skin)
    R_g = 1.0 / sum(1.0 / p.R_g for p in ps)
    R_ag = 1.0 / sum(1.0 / p.R_ag for p in ps)
    G = W * (1.0 / gain - 1.0)  # W / (W + G) = gain
    g_aw = G - 1.0 / (R_g + R_ag)
    R_aw = 1.0 / g_aw if g_aw > 0.0 else 1.0 / sum(1.0 / p.R_aw for p in ps)
    net = {"C_w": sum(p.C_w for p in ps), "C_g": sum(p.C_g for p in ps), "R_g": R_g, "R_ag": R_ag,
           "R_aw": R_aw}
    return dataclasses.replace(cfg, skin=dataclasses.replace(cfg.skin, **net))


@dataclass
class SkinRun:
    """What a run did: samples, wall time, per loop the tracking, per patch the contact time."""

    skin: Skin
    scenario: SkinScenario
    n: int
    wall_s: float
    path: Path | None
    tracking: list[float] = field(default_factory=list)
    """Per loop: mean |T_w - T_w_cmd| of the feedback reading over the second half, K (NaN
    if the run stopped before it)."""
    contact_s: list[float] = field(default_factory=list)
    """Per patch: seconds in contact."""
    q_peak: list[float] = field(default_factory=list)
    """Per patch: the largest true heat flow, W."""
    stopped: bool = False
    """The run was asked to stop (``stop``) before its end: ``n`` samples ran."""

    @property
    def realtime_factor(self) -> float:
        """Simulated seconds per wall-clock second."""
        return self.n * self.skin.cfg.sampling.t_s / self.wall_s if self.wall_s > 0 else math.inf


def run_skin(skin: Skin, scenario: SkinScenario, path: str | Path | None = None, *,
             tank: str = "peltier", start: str = "equilibrium", block: int = 1000,
             progress: Callable[[float], None] | None = None,
             on_block: Callable[[dict[str, Array]], None] | None = None,
             step_times: NDArray[np.int64] | None = None, stop: Any = None) -> SkinRun:
    """Run ``scenario`` on ``skin`` in closed loop; write the log to ``path`` (if given).

    ``start``: ``"equilibrium"`` (every loop warm at its command, pump running, the drive that
    holds its tank) or ``"ambient"`` (everything at the air). ``on_block(columns)`` gets every
    block of rows as written (long format). ``tank="prescribed"``: the scenario's ``T_p(t)``,
    the controllers' pumps only. ``step_times`` (an int64 array of at least the run's samples):
    each sample's wall time, ns (a benchmark's; ``time.perf_counter_ns``). ``stop``: anything
    with ``is_set()`` (a :class:`~thermoskin.runtime.stopping.StopRequest`), polled every
    sample: the run ends after the sample under way, its rows written (``SkinRun.stopped``).

    The log is written as the run goes (a CSV handed to the OS every
    :data:`~thermoskin.runtime.runlog.FLUSH_S` s), and closed, not discarded, when the run
    fails: what ran is kept.
    """
    from thermoskin.logio import LogWriter
    from thermoskin.skin.log import block_samples

    cfg = skin.cfg
    t_s = cfg.sampling.t_s
    block = block_samples(len(skin.patches), block)  # rows a block: bounded whatever the skin's size
    plant = SkinPlant(skin, scenario, tank=tank, block=block)
    plant.reset(start)
    P, L, n = plant.P, plant.L, plant.n
    T_a0 = float(scenario.base.T_a_at(0.0))
    ctrls = []
    for j, lp in enumerate(skin.loops):
        xs, _, _ = plant._chain(j, T_a0 + 1.0, T_a0)
        fb = skin.patches[lp.feedback]
        gain = float(xs[lp.patches.index(fb.index)][fb.tc_cells[0]]) - T_a0
        c = SkinController(lumped_loop(skin, j, gain), estimate=False)
        c.reset(plant.T_p_true[j])
        c.inner.reset(plant.drive0[j])
        ctrls.append(c)
    fb_idx = [lp.feedback for lp in skin.loops]
    names = skin.log_columns()
    B = min(block, n)
    buf = np.empty((B, *plant.rec.shape))
    patch_col = np.tile(np.arange(P, dtype=np.int64), B)
    half = n // 2
    err_sum = [0.0] * L
    err_n = [0] * L
    contact_n = np.zeros(P)
    q_peak = np.zeros(P)
    writer = LogWriter(path, names, flush_s=FLUSH_S) if path is not None else None
    setpoints = sorted({0.0, *(t0 for t0, _ in scenario.base.setpoints)})
    cmd_at = scenario.base.T_w_cmd_at
    cmd = cmd_at(0.0)
    drives, vs = [0.0] * L, [0.0] * L
    every = max(1, n // 200)
    k0 = 0
    rec = plant.rec
    Tw0 = plant.T_w_read[0]
    Tp, Ta = plant.T_p_read, plant.T_a_read
    fresh = plant.fresh  # per patch, updated in place by measure()
    clock = time.perf_counter_ns
    ns0 = clock()
    wall0 = time.perf_counter()
    stopped = False

    def flush(m: int) -> None:
        """The ``m`` buffered samples from ``k0`` on: to the log and ``on_block``."""
        nonlocal k0
        cols = _long(names, k0, m, t_s, patch_col, buf, plant.n_tc)
        np.add(contact_n, cols["contact_true"].reshape(m, P).sum(axis=0), out=contact_n)
        np.maximum(q_peak, np.abs(cols["q_i"]).reshape(m, P).max(axis=0), out=q_peak)
        if writer is not None:
            writer.write(cols)
        if on_block is not None:
            on_block(cols)
        k0 += m

    try:
        for k in range(n):
            if stop is not None and stop.is_set():
                stopped = True
                break
            t = k * t_s
            if setpoints and t >= setpoints[0]:
                cmd = cmd_at(t)
                setpoints.pop(0)
            plant.measure()
            tw, tp, ta, fr = Tw0.tolist(), Tp.tolist(), Ta.tolist(), fresh.tolist()
            for j in range(L):
                c = ctrls[j]
                T_w = tw[fb_idx[j]]
                # the feedback patch's fresh bits: the pump's still window counts new readings
                c.step(t, T_w, tp[j], ta[j], cmd, int(fr[fb_idx[j]]))
                drives[j] = c.drive
                vs[j] = c.v
                if k >= half:
                    err_sum[j] += abs(T_w - cmd)
                    err_n[j] += 1
            plant.apply(drives, vs)
            r = k - k0
            buf[r] = rec  # the readings and truth at t_k, the pump over [t_k, t_k+1)
            if r + 1 == B or k + 1 == n:
                flush(r + 1)
            if progress is not None and k % every == 0:
                progress(k / n)
            if step_times is not None:
                ns1 = clock()
                step_times[k] = ns1 - ns0
                ns0 = ns1
        if stopped and k > k0:  # the samples before the stop
            flush(k - k0)
    finally:
        if writer is not None:
            writer.close()  # what ran is kept, whatever ended the run
    done = k0  # samples written (every one before a stop or the end)
    wall = time.perf_counter() - wall0
    if progress is not None and not stopped:
        progress(1.0)
    return SkinRun(skin, scenario, done, wall, Path(path) if path is not None else None,
                   tracking=[e / m if m else math.nan for e, m in zip(err_sum, err_n, strict=True)],
                   contact_s=(contact_n * t_s).tolist(), q_peak=q_peak.tolist(), stopped=stopped)


def _long(names: list[str], k0: int, m: int, t_s: float, patch_col: NDArray[np.int64], buf: Array,
          n_tc: int) -> dict[str, Any]:
    """The first ``m`` buffered samples as long-format columns (sample-major, patches in order)."""
    from thermoskin.sim.skin_plant import REC_ROWS

    P = buf.shape[2]
    cols: dict[str, Any] = {"t": np.repeat((k0 + np.arange(m)) * t_s, P), "patch": patch_col[:m * P],
                            "T_w": buf[:m, 0].ravel()}
    for j in range(1, n_tc):
        cols[f"T_w{j + 1}"] = buf[:m, j].ravel()
    for r, name in enumerate(REC_ROWS):
        x = buf[:m, n_tc + r].ravel()
        cols[name] = x.astype(np.int64) if name in ("contact_true", "fresh") else x
    return {k: cols[k] for k in names}
