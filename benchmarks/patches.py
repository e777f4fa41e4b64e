"""Estimation for many patches: the compiled kernel's tick time and its agreement with one patch.

N patches (each the paper's single patch with its own thermocouple noise: N copies of a
simulated log with independent noise) are stepped one sample at a time by
:class:`~thermoskin.estimation.patches.PatchEstimators` (one compiled loop over state rows).
Prints one JSON line ``{"n", "p50_us", "p99_us", "max_abs_diff_W", ...}``: the tick time (µs,
over many ticks after a warm-up) and the largest difference of ``dq_i_hat`` and ``q_i_hat``
from stepping the plain-Python one-patch reference (``estimation/reference.py``) on the same
data, over ``--check`` patches (the reference is slow).

    python benchmarks/patches.py --n 1000 [--ticks 5000] [--check 3] [--skin-detector]
        [--period-ms P] [--peer DIR] [--json]

``--period-ms P``: each tick starts ``P`` ms after the last began (a busy wait), as a live loop
steps them (default 0: back to back, the worker thread still spinning and the states still in
the caches from the tick before).

``--peer DIR``: another checkout's kernel (``DIR/thermoskin/estimation/kernel.py``, with this
checkout's other modules; its state and parameter layouts must be this one's) steps a copy of
the same patches on the same ticks, in turn with this one (which goes first alternates), so
that the host's load falls on both alike; adds ``"peer"`` (its ``p50_us``, ``p99_us``, ...),
``"ratio_p50"``, ``"ratio_p99"`` (this over the peer) and ``"same_as_peer"`` (the states equal
bit for bit at the end).

``--skin-detector``: the detector of a skin's patch (``observe --skin``, ``run --skin``), whose
onset moves ``q_i`` alone, so the kernel keeps no step signatures, and whose sensors are as
configured (nothing learnt: the ``*_fixed`` loops); adds ``"skin_detector"`` and, stepping a
copy of those patches on the same ticks in turn with them, the full loops (with the learning
code, idle for such patches) as ``"skin_full_loop"`` and ``"skin_ratio_p50"`` (fixed over full).
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import json
import sys
import time
from pathlib import Path
from types import ModuleType

import numpy as np
from _proc import check_package_dir

from thermoskin.estimation import kernel as K  # noqa: N812
from thermoskin.estimation.model import fixed_sensors
from thermoskin.estimation.patches import PatchEstimators
from thermoskin.estimation.reference import ReferenceEstimator
from thermoskin.params import load_config
from thermoskin.sim.run import simulate
from thermoskin.sim.scenarios import SCENARIOS
from thermoskin.skin.observe import SKIN_ONSET_STATE_JUMP


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1000, help="patches")
    ap.add_argument("--ticks", type=int, default=5000, help="samples timed (after 2000 of warm-up)")
    ap.add_argument("--check", type=int, default=3, help="patches checked against the reference")
    ap.add_argument("--threads", choices=("auto", "one", "all"), default="auto",
                    help="one core, every core, or every core from 64 patches on (default)")
    ap.add_argument("--skin-detector", action="store_true",
                    help="also a skin patch's detector (q_i alone jumps at an onset, no step signatures "
                         "kept), stepped in turn with the single patch's on the same ticks")
    ap.add_argument("--period-ms", type=float, default=0.0,
                    help="start a tick every this many ms, as a live loop (default 0: back to back)")
    ap.add_argument("--peer", default=None, metavar="DIR",
                    help="another checkout's src: its kernel on a copy of the patches, in turn")
    ap.add_argument("--json", action="store_true", help="only the JSON line")
    a = ap.parse_args()
    peer = peer_kernel(a.peer) if a.peer else None
    cfg = load_config()
    cfgs = {"single": cfg}
    if a.skin_detector:
        de = dataclasses.replace(cfg.detector, onset_state_jump=SKIN_ONSET_STATE_JUMP)
        # a skin's patch keeps its sensors as configured (skin.observe.patch_config)
        cfgs["skin"] = fixed_sensors(dataclasses.replace(cfg, detector=de))
    warm = 2000
    n_s = warm + a.ticks
    log = simulate(SCENARIOS["one-finger"].with_duration(n_s * cfg.sampling.t_s + 1.0), cfg)
    rng = np.random.default_rng(0)
    noise = rng.normal(0.0, 0.005, (n_s, a.n))  # each patch its own extra noise
    T_w = log["T_w"][:n_s, None] + noise
    T_p = np.repeat(log["T_p"][:n_s, None], a.n, axis=1)
    T_a = np.repeat(log["T_a"][:n_s, None], a.n, axis=1)
    v = np.repeat(log["v"][:n_s, None], a.n, axis=1)
    par = None if a.threads == "auto" else a.threads == "all"
    ests = {k: PatchEstimators(c, n=a.n, parallel=par) for k, c in cfgs.items()}
    refs = {k: [ReferenceEstimator(c, c.sampling.t_s) for _ in range(min(a.check, a.n))]
            for k, c in cfgs.items()}
    one = ests["single"]
    steppers = {name: est.tick for name, est in ests.items()}
    if a.skin_detector:
        sk = ests["skin"]
        f_st, f_codes, f_ev = sk.ST.copy(), sk.codes.copy(), sk.EV.copy()
        if sk._claims is None:
            f_step, f_tail = K.step_many, (f_codes, f_ev)
        else:
            f_step, f_tail = K.step_many_parallel, (f_codes, f_ev, sk._claims.copy())

        def full_tick(t: float, *r: np.ndarray) -> None:
            f_step(f_st, sk.PR, sk.mid, *sk._tabs, t, *r, *f_tail)

        steppers["skin_full"] = full_tick
    if peer is not None:
        p_st, p_codes, p_ev = one.ST.copy(), one.codes.copy(), one.EV.copy()
        p_tail: tuple[np.ndarray, ...] = (p_codes, p_ev)
        if one._claims is None:
            p_step = peer.step_many
        else:
            p_step = peer.step_many_parallel
            if hasattr(peer, "claim_words"):
                p_tail = (*p_tail, peer.claim_words(len(one._claims) // K.CLAIM_STRIDE))

        def peer_tick(t: float, *r: np.ndarray) -> None:
            p_step(p_st, one.PR, one.mid, *one._tabs, t, *r, *p_tail)

        steppers["peer"] = peer_tick
    times = {k: np.empty(n_s) for k in steppers}
    worst = dict.fromkeys(cfgs, 0.0)
    t_s = cfg.sampling.t_s
    iv = ests["single"].index(v[0])
    period_ns = round(a.period_ms * 1e6)
    due = time.perf_counter_ns()
    for k in range(n_s):
        if k and not np.array_equal(v[k], v[k - 1]):
            iv = ests["single"].index(v[k])  # the same tables' rows for both detectors
        t = k * t_s
        if period_ns:
            due += period_ns
            while time.perf_counter_ns() < due:
                pass
        names = list(steppers) if k % 2 == 0 else list(steppers)[::-1]
        for name in names:  # in turn on the same tick, first and last alternately: load falls on all alike
            t0 = time.perf_counter_ns()
            steppers[name](t, T_w[k], T_p[k], T_a[k], est_cmd(a.n), iv, est_drive(a.n), est_fresh(a.n))
            times[name][k] = (time.perf_counter_ns() - t0) * 1e-3
        for name, est in ests.items():
            for i, r in enumerate(refs[name]):
                r.step(t, T_w[k, i], T_p[k, i], v[k, i], T_a[k, i])
                for a_, b_ in ((est.ST[i, K.DQ], r.dq), (est.ST[i, K.QIH], r.q_i_hat)):
                    if a_ == a_ and b_ == b_:
                        worst[name] = max(worst[name], abs(a_ - b_))

    def timing(name: str) -> dict[str, float | int]:
        tt = times[name][warm:]
        return {"p50_us": round(float(np.percentile(tt, 50)), 2),
                "p99_us": round(float(np.percentile(tt, 99)), 2), "max_us": round(float(tt.max()), 1),
                "ticks": len(tt), "ns_per_patch_p50": round(float(np.percentile(tt, 50)) * 1e3 / a.n, 1)}

    def summary(name: str) -> dict[str, float | int | bool]:
        est = ests[name]
        return {**timing(name), "max_abs_diff_W": worst[name], "checked_patches": len(refs[name]),
                "contacts": int(len(est.events) + (est.codes & 1).sum()),
                "parallel": est._claims is not None}

    out: dict[str, object] = {"n": a.n, **summary("single"), "period_ms": a.period_ms}
    if a.skin_detector:
        out["skin_detector"] = summary("skin")
        out["skin_full_loop"] = timing("skin_full")
        out["skin_ratio_p50"] = round(out["skin_detector"]["p50_us"] / out["skin_full_loop"]["p50_us"], 3)
        out["skin_same_as_full"] = bool(np.array_equal(ests["skin"].ST[:, :K.RW], f_st[:, :K.RW],
                                                       equal_nan=True))
    if peer is not None:
        out["peer"] = timing("peer")
        out["ratio_p50"] = round(out["p50_us"] / out["peer"]["p50_us"], 3)
        out["ratio_p99"] = round(out["p99_us"] / out["peer"]["p99_us"], 3)
        out["same_as_peer"] = bool(np.array_equal(one.ST, p_st, equal_nan=True))
    if not a.json:
        print(out)
    print(json.dumps(out))


def peer_kernel(src: str) -> ModuleType:
    """The kernel module of the checkout whose ``src`` is ``src``, loaded beside this one's (its
    imports of the package's other modules get this checkout's); ends the script if its state
    or parameter layout differs from this one's (the tables and states are shared)."""
    check_package_dir("--peer", src)
    path = Path(src) / "thermoskin" / "estimation" / "kernel.py"
    spec = importlib.util.spec_from_file_location("thermoskin.estimation._peer_kernel", path)
    if spec is None or spec.loader is None:
        raise SystemExit(f"--peer {src}: no kernel at {path}")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    try:
        spec.loader.exec_module(mod)
    except ImportError as e:
        raise SystemExit(f"--peer {src}: its kernel needs what this checkout lacks ({e})") from None
    for name in ("NSTATE", "NPARAM"):
        if getattr(mod, name, None) != getattr(K, name):
            raise SystemExit(f"--peer {src}: its kernel's {name} is {getattr(mod, name, None)}, "
                             f"this one's {getattr(K, name)}: not the same layout")
    # the peer compiles apart, without numba's cache: its kernel file may be this checkout's, and
    # its code cached under the module name it has here (``_peer_kernel``, which no other
    # process can import) would be loaded by the next process that looks the kernel up there
    from numba.core.caching import NullCache
    from numba.core.registry import CPUDispatcher

    for obj in vars(mod).values():
        if isinstance(obj, CPUDispatcher):
            obj._cache = NullCache()
    return mod


_CACHE: dict[str, np.ndarray] = {}


def _const(name: str, n: int, value: float, dtype: type) -> np.ndarray:
    key = f"{name}{n}"
    if key not in _CACHE:
        _CACHE[key] = np.full(n, value, dtype=dtype)
    return _CACHE[key]


def est_cmd(n: int) -> np.ndarray:
    return _const("cmd", n, float("nan"), float)


def est_drive(n: int) -> np.ndarray:
    return _const("drive", n, float("nan"), float)


def est_fresh(n: int) -> np.ndarray:
    return _const("fresh", n, 7, np.int64)


if __name__ == "__main__":
    main()
