"""Points of a sweep as rows of one batched simulation, and the metrics of each point.

:func:`run_chunk` takes points (a config and a seed each) that share a structure (the
same scenario length, sampling interval and MPC horizon), builds each row's parameters,
tables and input profiles in numpy, runs them all in :func:`thermoskin.sweep.kernel.run_rows`
and scores each row. The same point through the one-point path
(:func:`~thermoskin.runtime.closed_loop.run_closed_loop`, or
:func:`~thermoskin.sim.run.simulate` then :func:`~thermoskin.analysis.observe.observe`) is the
reference ``tests/test_sweep.py`` holds the batch to.

Metrics of a point (a row of ``RESULTS.parquet``):

- ``detection_rate``: touches detected / touches scored (``evaluation.match_events``, a
  touch is detected by the first contact detected within ``[t_on, t_off + late]``);
- ``false_alarms_per_h``: the other contacts per hour from ``settle`` on;
- ``latency_median_s``, ``latency_p90_s``: ``detected_at - t_on`` of the detected touches;
- ``snr_one_finger``: ``(mean dq_i_hat over one-finger contact - mean over quiet) / sd over
  quiet``, quiet = from ``settle`` on, no contact now nor in the last ``T_QUIET`` s;
- ``tracking_rms_K``: ``sqrt(mean (T_w_true - T_w_cmd)^2)`` from ``settle`` s on;
- ``energy_J``: the Peltier modules' electric energy ``sum P_elec t_s`` (closed loop).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from thermoskin.analysis.evaluation import match_events
from thermoskin.control.inner import model_feedforward
from thermoskin.control.mpc import Mpc
from thermoskin.estimation.estimator import TouchEstimator
from thermoskin.estimation.events import NEV, ContactEvent
from thermoskin.params import Config
from thermoskin.physics.convection import FlowResistance
from thermoskin.physics.finger import contact_profile
from thermoskin.physics.peltier import PeltierTank
from thermoskin.sim.scenarios import Scenario, get_scenario, random_scenario
from thermoskin.sim.sensors import Sensors
from thermoskin.sweep import kernel as SK  # noqa: N812

Array = NDArray[np.float64]

LOOPS = ("closed", "open")
T_QUIET = 3.0
"""s after a contact's end before ``dq_i_hat`` counts as quiet again (the estimate settles)."""
EVENT_CAP = 256

METRICS = ("detection_rate", "false_alarms_per_h", "latency_median_s", "latency_p90_s",
           "snr_one_finger", "tracking_rms_K", "energy_J")
"""The metrics a sweep can keep (all by default)."""
EXTRA = ("touches", "hits", "misses", "false_alarms", "observed_s", "qp_solves")
"""Counts kept with every point."""


@dataclass(frozen=True)
class ScenarioSpec:
    """What each point runs: the loop, the touches, the length, the set-point and the air."""

    loop: str = "closed"
    """``closed`` (from ambient under MPC and Peltier) or ``open`` (prescribed tank, pump logic)."""
    touches: str = "random"
    """``random`` (seeded by the point's seed), ``none``, or a named scenario's touches."""
    duration: float = 60.0
    T_w_cmd: float = 24.0
    T_a: float = 20.0
    settle: float = 10.0
    """s: touches start after it (closed loop: the named scenario's are shifted by it), and
    the tracking error is taken from it on."""
    late: float = 1.0
    """s: a detection this long after a touch's end still counts for it."""


def build_scenario(spec: ScenarioSpec, seed: int) -> Scenario:
    """The point's scenario (``seed`` draws the random touches)."""
    if spec.touches == "random":
        sc = random_scenario(seed, spec.duration, t_first=spec.settle, T_w_cmd=spec.T_w_cmd, T_a=spec.T_a)
        return sc
    if spec.touches == "none":
        return Scenario("none", "no touch", duration=spec.duration, T_w_cmd=spec.T_w_cmd, T_a=spec.T_a)
    sc = get_scenario(spec.touches)
    sc = dataclasses.replace(sc, T_w_cmd=spec.T_w_cmd, T_a=spec.T_a, setpoints=(), ambient=(), pump="logic")
    first = min((tc.t_on for tc in sc.touches), default=0.0)
    sc = sc.shifted(max(0.0, spec.settle - first))
    return sc.with_duration(spec.duration)


# ------------------------------------------------------------------------- one row's inputs
@dataclass
class Row:
    """Everything the kernel needs of one point, and what scoring needs."""

    ps: Array
    profiles: dict[str, Array]
    noise: Array
    conv: NDArray[np.uint8]
    est_key: Any
    mpc_key: Any
    scenario: Scenario


def _samples(cfg: Config, spec: ScenarioSpec) -> int:
    return max(1, math.floor(spec.duration / cfg.sampling.t_s + 1e-9))


def structure(cfg: Config, spec: ScenarioSpec) -> tuple[int, int]:
    """Rows run together when they have the same samples and MPC horizon."""
    return _samples(cfg, spec), (int(cfg.control.H) if spec.loop == "closed" else 1)


def _class(G: Array, n_f: NDArray[np.int64], t_s: float) -> NDArray[np.int8]:
    """Per sample: ``CLS_ONE`` (one finger touching), ``CLS_QUIET`` or ``CLS_OTHER``."""
    n = len(G)
    on = G > 0.0
    idx = np.where(on, np.arange(n), -(10 ** 12))
    last = np.maximum.accumulate(idx)
    quiet = ~on & ((np.arange(n) - last) * t_s > T_QUIET)
    cls = np.full(n, SK.CLS_OTHER, dtype=np.int8)
    cls[quiet] = SK.CLS_QUIET
    cls[on & (n_f == 1)] = SK.CLS_ONE
    return cls


def _cmd_profile(sc: Scenario, t: Array) -> Array:
    """The command the closed loop holds at each sample (``run_closed_loop``'s schedule)."""
    cmd = np.full(len(t), sc.T_w_cmd_at(0.0))
    for t0 in sorted({0.0, *(t0 for t0, _ in sc.setpoints)}):
        k = int(np.searchsorted(t, t0, side="left"))
        if k < len(t):
            cmd[k:] = sc.T_w_cmd_at(float(t[k]))
    return cmd


def prepare(cfg: Config, spec: ScenarioSpec, seed: int) -> Row:
    """One point's row: parameters (``kernel.S_*``), profiles, sensor noise and conversions."""
    t_s = cfg.sampling.t_s
    closed = spec.loop == "closed"
    sc = build_scenario(spec, seed)
    n = _samples(cfg, spec)
    t = np.arange(n) * t_s
    G, T_f, n_f = contact_profile(sc.touches, t)
    T_a = np.asarray(sc.T_a_at(t), dtype=float)
    cmd = _cmd_profile(sc, t) if closed else sc.T_w_cmd_profile(t)
    T_p = np.zeros(n) if closed else np.asarray(sc.T_p(t), dtype=float)
    sens = Sensors(cfg.sensor, t_s)
    noise = np.empty((3, n))
    conv = np.empty((3, n), dtype=np.uint8)
    for j, ch in enumerate(("T_w", "T_p", "T_a")):
        b = sens.boards[ch]
        b.reset()
        noise[j] = b._noise_rng.standard_normal(n)
        conv[j] = b.conversions(n)
    ps = np.zeros(SK.NS)
    s = cfg.skin
    R_w = FlowResistance(s)
    v_on = cfg.pump.v_on
    ps[SK.S_TS] = t_s
    ps[SK.S_CW], ps[SK.S_CG], ps[SK.S_RG], ps[SK.S_RAW], ps[SK.S_RAG] = s.C_w, s.C_g, s.R_g, s.R_aw, s.R_ag
    ps[SK.S_RWON], ps[SK.S_RWOFF] = R_w(v_on), R_w(0.0)
    ps[SK.S_VON] = v_on
    ps[SK.S_HALF] = 0.5 * float(cfg.pump.hysteresis)
    ps[SK.S_NDWELL] = max(0, math.ceil(float(cfg.pump.min_dwell) / t_s - 1e-9))
    ps[SK.S_NSTILL] = cfg.pump.still_readings
    p, c = cfg.peltier, cfg.control
    tank = PeltierTank(p, t_s, (c.drive_min, c.drive_max))
    ps[SK.S_NMOD], ps[SK.S_SM], ps[SK.S_RM] = p.n_modules, p.S_m, p.R_m
    ps[SK.S_KM], ps[SK.S_IMAX] = p.K_m, p.I_max
    ps[SK.S_CT], ps[SK.S_RTA], ps[SK.S_CS], ps[SK.S_RS] = p.C_tank, p.R_tank_air, p.C_sink, p.R_sink
    ps[SK.S_NSUB] = tank.n_sub
    ps[SK.S_DMIN], ps[SK.S_DMAX] = c.drive_min, c.drive_max
    ps[SK.S_KP], ps[SK.S_KITS] = c.Kp, c.Ki * t_s
    ps[SK.S_SPAN] = c.drive_max - c.drive_min
    ff = model_feedforward(cfg.peltier_model)
    if ff is None:
        ps[SK.S_FFMODE] = 0.0
    elif not callable(ff):
        ps[SK.S_FFMODE], ps[SK.S_FF0] = 1.0, float(ff)
    else:
        m = cfg.peltier_model
        ps[SK.S_FFMODE] = 2.0
        ps[SK.S_FF0], ps[SK.S_FF1], ps[SK.S_FF2], ps[SK.S_FF3] = 1.0 + sum(m.a), m.d, m.c, sum(m.b)
    ps[SK.S_TPMIN], ps[SK.S_TPMAX] = c.T_p_min, c.T_p_max
    ps[SK.S_NOISE], ps[SK.S_QUANT] = cfg.sensor.noise_T, cfg.sensor.quantum_T
    ps[SK.S_LAGW], ps[SK.S_LAGP], ps[SK.S_LAGA] = cfg.sensor.lag_T_w, cfg.sensor.lag_T_p, cfg.sensor.lag_T_a
    ps[SK.S_TTRACK] = spec.settle
    ps[SK.S_CLOSED] = 1.0 if closed else 0.0
    if closed:  # from ambient (SimulatedPlant.reset("ambient"), SkinController.reset(T_a))
        a0 = float(T_a[0])
        ps[SK.S_W0] = ps[SK.S_G0] = ps[SK.S_P0] = ps[SK.S_SINK0] = a0
        ps[SK.S_TPPREV0] = min(max(float(sc.T_a), c.T_p_min), c.T_p_max)
    else:  # the pipe at its command, the sheet in equilibrium (SimulatedPlant.reset("command"))
        w0 = float(cmd[0])
        ps[SK.S_W0] = w0
        ps[SK.S_G0] = ((w0 / s.R_g + T_a[0] / s.R_ag + G[0] * T_f[0])
                       / (1.0 / s.R_g + 1.0 / s.R_ag + G[0]))
        ps[SK.S_P0] = float(T_p[0])
    mpc_key = (s, c, t_s, v_on) if closed else None
    return Row(ps=ps, profiles={"G_c": G, "T_f": T_f, "T_a": T_a, "cmd": cmd, "T_p": T_p,
                                "cls": _class(G, n_f, t_s)},
               noise=noise, conv=conv, est_key=_est_key(cfg), mpc_key=mpc_key, scenario=sc)


def _est_key(cfg: Config) -> Config:
    """The estimator's tables do not depend on the noise seed: rows that differ only there share them."""
    return cfg.replace(sensor={"seed": 0})


class Models:
    """Estimator and MPC models built once per distinct configuration (shared by rows)."""

    def __init__(self) -> None:
        self.est: dict[Any, tuple[Array, tuple[Array, ...]]] = {}
        self.mpc: dict[Any, tuple[Array, ...]] = {}

    def estimator(self, key: Config) -> tuple[Array, tuple[Array, ...]]:
        got = self.est.get(key)
        if got is None:
            est = TouchEstimator(key)
            if est._iv.get(0.0) != 0 or est._iv.get(key.pump.v_on) != 1:
                raise RuntimeError("estimator tables: rows 0 and 1 must be v = 0 and v_on")
            tabs = tuple(np.ascontiguousarray(x[:2]) for x in est.tabs)
            got = self.est[key] = (est.pr.copy(), tabs)
        return got

    def controller(self, key: Any, H: int) -> tuple[Array, ...]:
        if key is None:
            z = np.zeros((H, 4))
            return z, z, np.eye(H), np.eye(H), np.zeros(4), np.zeros(8)
        got = self.mpc.get(key)
        if got is None:
            skin, control, t_s, v_on = key
            m = Mpc(skin, control, t_s, v_on=v_on)
            got = self.mpc[key] = (np.ascontiguousarray(m._K_unc), np.ascontiguousarray(m.F),
                                   np.ascontiguousarray(m.P), np.ascontiguousarray(np.linalg.inv(m.P)),
                                   np.array(m._k0), np.array(m._interval))
        return got


# ------------------------------------------------------------------------- the batch
def run_chunk(points: Sequence[tuple[Config, int]], spec: ScenarioSpec,
              models: Models | None = None) -> list[dict[str, Any]]:
    """Run points ``(config, seed)`` of one structure (:func:`structure`) as one batch;
    one metrics dict per point, in order."""
    from thermoskin.sim.skin_plant import _one_blas_thread

    with _one_blas_thread():  # the same rounding on every machine and worker, whatever its BLAS threads
        return _run_chunk(points, spec, models or Models())


def _run_chunk(points: Sequence[tuple[Config, int]], spec: ScenarioSpec,
               models: Models) -> list[dict[str, Any]]:
    rows = [prepare(cfg, spec, seed) for cfg, seed in points]
    shapes = {structure(cfg, spec) for cfg, _ in points}
    if len(shapes) != 1:
        raise ValueError(f"run_chunk: points of different structures {sorted(shapes)}")
    ((n, H),) = shapes
    N = len(rows)
    est_ids: dict[Any, int] = {}
    mpc_ids: dict[Any, int] = {}
    mid = np.array([est_ids.setdefault(r.est_key, len(est_ids)) for r in rows], dtype=np.int64)
    cid = np.array([mpc_ids.setdefault(r.mpc_key, len(mpc_ids)) for r in rows], dtype=np.int64)
    ests = [models.estimator(k) for k in est_ids]
    PR = np.ascontiguousarray(np.stack([e[0] for e in ests]))
    tabs = [np.ascontiguousarray(np.stack([e[1][j] for e in ests])) for j in range(7)]
    ctrls = [models.controller(k, H) for k in mpc_ids]
    Kmat, Fmat, Pm, Pinv = (np.ascontiguousarray(np.stack([c[j] for c in ctrls])) for j in range(4))
    for r in rows:
        if r.mpc_key is not None:
            k0, iv = models.mpc[r.mpc_key][4], models.mpc[r.mpc_key][5]
            r.ps[SK.S_K0:SK.S_K3 + 1] = k0
            r.ps[SK.S_IV0:SK.S_IV7 + 1] = iv
    PS = np.ascontiguousarray(np.stack([r.ps for r in rows]))

    def prof(name: str, dtype: Any = float) -> np.ndarray:
        return np.ascontiguousarray(np.stack([r.profiles[name] for r in rows]).astype(dtype, copy=False))

    NOISE = np.ascontiguousarray(np.stack([r.noise for r in rows]))
    CONV = np.ascontiguousarray(np.stack([r.conv for r in rows]))
    RES = np.zeros((N, SK.NR))
    EVENTS = np.zeros((N, EVENT_CAP, NEV))
    SK.run_rows(PS, prof("G_c"), prof("T_f"), prof("T_a"), prof("cmd"), prof("T_p"), prof("cls", np.int8),
                NOISE, CONV, mid, PR, *tabs, cid, Kmat, Fmat, Pm, Pinv, RES, EVENTS)
    out = []
    for i, r in enumerate(rows):
        ne = int(RES[i, SK.R_NEV])
        events = [ContactEvent.from_kernel(EVENTS[i, j]) for j in range(min(ne, EVENT_CAP))]
        out.append(score(r.scenario, events, RES[i], spec, n * points[i][0].sampling.t_s,
                         points[i][0].sampling.t_s))
    return out


def score(sc: Scenario, events: Sequence[ContactEvent], res: Array, spec: ScenarioSpec,
          t_end: float, t_s: float) -> dict[str, Any]:
    """The metrics of one point (module doc) from its contacts and the kernel's sums."""
    m = match_events(sc.touches, events, late=spec.late, t_end=t_end)
    scored = m.hits + m.misses
    observed_h = res[SK.R_NARMED] * t_s / 3600.0
    lat = m.latencies
    n1, nq = res[SK.R_N1], res[SK.R_NQ]
    if n1 > 0 and nq > 1:
        mq = res[SK.R_SUMQ] / nq
        var = max(res[SK.R_SUMQ2] / nq - mq * mq, 0.0)
        snr = (res[SK.R_SUM1] / n1 - mq) / math.sqrt(var) if var > 0 else math.nan
    else:
        snr = math.nan
    return {
        "detection_rate": m.hits / scored if scored else math.nan,
        "false_alarms_per_h": m.false_alarms / observed_h if observed_h > 0 else math.nan,
        "latency_median_s": float(np.median(lat)) if len(lat) else math.nan,
        "latency_p90_s": float(np.percentile(lat, 90)) if len(lat) else math.nan,
        "snr_one_finger": float(snr),
        "tracking_rms_K": math.sqrt(res[SK.R_SSE] / res[SK.R_NTRACK]) if res[SK.R_NTRACK] else math.nan,
        "energy_J": float(res[SK.R_ENERGY]),
        "touches": len(sc.touches), "hits": m.hits, "misses": m.misses, "false_alarms": m.false_alarms,
        "observed_s": float(res[SK.R_NARMED] * t_s), "qp_solves": int(res[SK.R_QPS]),
    }
