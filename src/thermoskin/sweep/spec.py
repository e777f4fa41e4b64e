"""A sweep's description (``SWEEP.toml``): the keys and their values, the sampler, the seeds,
the scenario and the metrics; and its points, each with a hash that names it::

    [sweep]
    config = "base.toml"        # optional: the config every point starts from (relative to this file)
    sampler = "lhs"             # grid (every combination) | random | lhs (scipy.stats.qmc)
    points = 1000               # random / lhs: how many
    seed = 0                    # the sampler's seed
    seeds = [0]                 # every point runs once per seed: sensor.seed and the random touches
    chunk = 25                  # points per batch (a task on a cluster)
    metrics = ["detection_rate", "tracking_rms_K"]   # optional: keep only these

    [scenario]                  # engine.ScenarioSpec
    loop = "closed"             # closed | open
    touches = "random"          # random | none | a named scenario (thermoskin scenarios)
    duration = 60.0             # s
    T_w_cmd = 24.0
    T_a = 20.0
    settle = 10.0               # s: touches start after it; tracking and quiet time counted from it

    [keys]                      # any config key section.name, or a skin description key
    "skin.R_g" = [8.0, 10.0, 12.0]            # a list: grid values (random / lhs: choices)
    "pump.v_on" = {lo = 0.05, hi = 0.3}       # a range: random / lhs (grid: add n = ...)
    "detector.h_on" = {lo = 4.0, hi = 8.0, n = 5, log = false}
    "patch.length" = {lo = 0.02, hi = 0.05}   # the patch's pipe length, m (skin.py scaling)

Skin description keys are the single patch's ``patch.length`` and ``patch.width`` (m): the
network of ``[skin]`` scaled to that patch as ``skin.py`` scales it (``C_w, 1/R_g, 1/R_aw``
with the length, ``C_g, 1/R_ag`` with the area), after the point's ``skin.*`` keys.

Every mistake is a :class:`SweepError` (a ``ConfigError``): one line naming the file and
the key.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from thermoskin.params import Config, ConfigError, check_kind, load_config, read_toml, to_toml
from thermoskin.sim.scenarios import SCENARIOS
from thermoskin.skin.layout import REF_LENGTH, REF_WIDTH, _scaled_skin
from thermoskin.sweep.engine import EXTRA, LOOPS, METRICS, ScenarioSpec

SAMPLERS = ("grid", "random", "lhs")
SKIN_KEYS = ("patch.length", "patch.width")
SWEEP_KEYS = ("config", "sampler", "points", "seed", "seeds", "chunk", "metrics")
MAX_POINTS = 1_000_000


class SweepError(ConfigError):
    """A bad sweep description (one line naming the file and the key)."""


@dataclass(frozen=True)
class Axis:
    """One swept key: a list of ``values``, or a range ``lo..hi`` (``n`` grid steps, ``log``)."""

    key: str
    values: tuple[Any, ...] = ()
    lo: float = math.nan
    hi: float = math.nan
    n: int = 0
    log: bool = False

    def grid(self) -> list[Any]:
        if self.values:
            return list(self.values)
        if self.log:
            return [float(x) for x in np.geomspace(self.lo, self.hi, self.n)]
        return [float(x) for x in np.linspace(self.lo, self.hi, self.n)]

    def at(self, u: float) -> Any:
        """The value at ``u`` in ``[0, 1)`` (a list: its ``floor(u len)``-th element)."""
        if self.values:
            return self.values[min(int(u * len(self.values)), len(self.values) - 1)]
        if self.log:
            return float(math.exp(math.log(self.lo) + u * (math.log(self.hi) - math.log(self.lo))))
        return float(self.lo + u * (self.hi - self.lo))


@dataclass(frozen=True)
class Point:
    """One point: its index, values (key -> value), seed, config and hash."""

    index: int
    values: dict[str, Any]
    seed: int
    cfg: Config
    hash: str


@dataclass
class Sweep:
    """A parsed ``SWEEP.toml``."""

    source: str
    base: Config
    axes: list[Axis]
    sampler: str
    n_points: int
    sampler_seed: int
    seeds: tuple[int, ...]
    chunk: int
    scenario: ScenarioSpec
    metrics: tuple[str, ...]
    points: list[Point] = field(default_factory=list)

    @property
    def keys(self) -> list[str]:
        return [a.key for a in self.axes]

    def columns(self) -> list[str]:
        """The columns of a result row, in order."""
        return ["point", "hash", "seed", *self.keys, *self.metrics, *EXTRA]


def _err(src: str, key: str, msg: str) -> SweepError:
    return SweepError(f"{src}: {key}: {msg}")


def _number(src: str, key: str, x: Any) -> float:
    if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(float(x)):
        raise _err(src, key, f"{x!r} is not a finite number")
    return float(x)


def _int(src: str, key: str, x: Any, lo: int, hi: int) -> int:
    if isinstance(x, bool) or not isinstance(x, int) or not lo <= x <= hi:
        raise _err(src, key, f"{x!r} must be an integer from {lo} to {hi}")
    return int(x)


def _section_field(key: str) -> tuple[str, str, Any] | None:
    """``(section, name, field)`` of a config key ``section.name``, or None."""
    from thermoskin.params import _SECTION_TYPES

    if key.count(".") != 1:
        return None
    sec, name = key.split(".")
    cls = _SECTION_TYPES.get(sec)
    if cls is None:
        return None
    f = {x.name: x for x in dataclasses.fields(cls)}.get(name)
    return (sec, name, f) if f is not None else None


def _axis(src: str, key: str, val: Any, sampler: str) -> Axis:
    where = f"keys.{key}"
    if key not in SKIN_KEYS and _section_field(key) is None:
        raise _err(src, where, "unknown key (a config key section.name, e.g. skin.R_g, or "
                               f"{', '.join(SKIN_KEYS)})")
    if isinstance(val, list):
        if not val:
            raise _err(src, where, "an empty list of values")
        for x in val:
            if not isinstance(x, int | float | str) or isinstance(x, bool):
                raise _err(src, where, f"value {x!r} is neither a number nor a word")
        return Axis(key, values=tuple(val))
    if isinstance(val, dict):
        unknown = set(val) - {"lo", "hi", "n", "log"}
        if unknown:
            raise _err(src, where, f"unknown field {sorted(unknown)[0]!r} (a range has lo, hi, n, log)")
        if "lo" not in val or "hi" not in val:
            raise _err(src, where, "a range needs lo and hi")
        lo, hi = _number(src, f"{where}.lo", val["lo"]), _number(src, f"{where}.hi", val["hi"])
        if not lo < hi:
            raise _err(src, where, f"lo = {lo:g} must be below hi = {hi:g}")
        log = val.get("log", False)
        if not isinstance(log, bool):
            raise _err(src, f"{where}.log", f"{log!r} must be true or false")
        if log and lo <= 0:
            raise _err(src, where, "a log range needs lo > 0")
        n = 0
        if sampler == "grid":
            if "n" not in val:
                raise _err(src, where, "a range on a grid needs n (the number of values)")
            n = _int(src, f"{where}.n", val["n"], 1, 10_000)
        return Axis(key, lo=lo, hi=hi, n=n, log=log)
    raise _err(src, where, f"{val!r} must be a list of values or a range {{lo = ..., hi = ...}}")


def _scenario(src: str, data: Any) -> ScenarioSpec:
    if not isinstance(data, dict):
        raise _err(src, "scenario", "must be a table")
    known = {f.name: f for f in dataclasses.fields(ScenarioSpec)}
    kw: dict[str, Any] = {}
    for k, v in data.items():
        where = f"scenario.{k}"
        if k not in known:
            raise _err(src, where, f"unknown key (known: {', '.join(known)})")
        if k in ("loop", "touches"):
            if not isinstance(v, str):
                raise _err(src, where, f"{v!r} must be a word")
            ok = LOOPS if k == "loop" else ("random", "none", *SCENARIOS)
            if v not in ok:
                raise _err(src, where, f"{v!r} must be one of {', '.join(ok)}")
            kw[k] = v
        else:
            kw[k] = _number(src, where, v)
    spec = ScenarioSpec(**kw)
    if not 1.0 <= spec.duration <= 86400.0:
        raise _err(src, "scenario.duration", f"{spec.duration:g} s must be from 1 s to a day")
    if not 0.0 <= spec.settle < spec.duration:
        raise _err(src, "scenario.settle", f"{spec.settle:g} s must be >= 0 and below the duration")
    if not 0.0 <= spec.late <= 60.0:
        raise _err(src, "scenario.late", f"{spec.late:g} s must be from 0 to 60 s")
    for k in ("T_w_cmd", "T_a"):
        if not -20.0 <= getattr(spec, k) <= 80.0:
            raise _err(src, f"scenario.{k}", f"{getattr(spec, k):g} °C must be from -20 to 80 °C")
    return spec


def point_config(base: Config, values: dict[str, Any]) -> Config:
    """``base`` with the point's config keys, then its skin description keys."""
    sections: dict[str, dict[str, Any]] = {}
    for key, v in values.items():
        if key in SKIN_KEYS:
            continue
        sec, name, f = _section_field(key)  # type: ignore[misc]
        if f.type in ("int", int) and isinstance(v, float):
            if v != round(v):
                raise ConfigError(f"{key} = {v!r} must be a whole number")
            v = int(v)
        sections.setdefault(sec, {})[name] = v
    cfg = base.replace(**sections) if sections else base
    if any(k in values for k in SKIN_KEYS):
        length = float(values.get("patch.length", REF_LENGTH))
        width = float(values.get("patch.width", REF_WIDTH))
        if not (1e-3 <= length <= 10.0 and 1e-3 <= width <= 10.0):
            raise ConfigError(f"patch.length = {length:g} m and patch.width = {width:g} m must be "
                              "from 1 mm to 10 m")
        own = {k.split(".")[1] for k in values if k.startswith("skin.")}
        cfg = dataclasses.replace(cfg, skin=_scaled_skin(cfg.skin, length, width, own))
    return cfg


def point_hash(values: dict[str, Any], seed: int, spec: ScenarioSpec, base: Config) -> str:
    """What a point is, hashed: its values and seed, the scenario, the base config."""
    text = json.dumps({"values": {k: values[k] for k in sorted(values)}, "seed": seed,
                       "scenario": dataclasses.asdict(spec), "base": to_toml(base)},
                      sort_keys=True, default=repr)
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def _unit_samples(axes: list[Axis], sampler: str, n: int, seed: int) -> np.ndarray:
    d = len(axes)
    if sampler == "random":
        return np.random.default_rng(seed).random((n, d))
    from scipy.stats import qmc

    return qmc.LatinHypercube(d=d, seed=np.random.default_rng(seed)).random(n)


def load_sweep(path: str | Path) -> Sweep:
    """Parse and check ``SWEEP.toml``; every point's config is built (and so checked) here."""
    p = Path(path)
    src = str(p)
    data = read_toml(p, "sweep file", SweepError)
    check_kind(p, data, "sweep", SweepError)
    for k in data:
        if k not in ("sweep", "scenario", "keys"):
            raise _err(src, k, "unknown table (known: sweep, scenario, keys)")
    sw = data.get("sweep", {})
    if not isinstance(sw, dict):
        raise _err(src, "sweep", "must be a table")
    for k in sw:
        if k not in SWEEP_KEYS:
            raise _err(src, f"sweep.{k}", f"unknown key (known: {', '.join(SWEEP_KEYS)})")
    sampler = sw.get("sampler", "grid")
    if sampler not in SAMPLERS:
        raise _err(src, "sweep.sampler", f"{sampler!r} must be one of {', '.join(SAMPLERS)}")
    base_path = sw.get("config")
    if base_path is not None:
        if not isinstance(base_path, str):
            raise _err(src, "sweep.config", f"{base_path!r} must be a path")
        bp = Path(base_path)
        base = load_config(bp if bp.is_absolute() else p.parent / bp)
    else:
        base = load_config()
    seeds = sw.get("seeds", [0])
    if not isinstance(seeds, list) or not seeds:
        raise _err(src, "sweep.seeds", f"{seeds!r} must be a non-empty list of integers")
    seeds_t = tuple(_int(src, "sweep.seeds", s, 0, 2**32 - 1) for s in seeds)
    if len(set(seeds_t)) != len(seeds_t):
        raise _err(src, "sweep.seeds", "a seed is repeated")
    chunk = _int(src, "sweep.chunk", sw.get("chunk", 25), 1, 10_000)
    seed = _int(src, "sweep.seed", sw.get("seed", 0), 0, 2**32 - 1)
    metrics = sw.get("metrics", list(METRICS))
    if not isinstance(metrics, list) or not metrics:
        raise _err(src, "sweep.metrics", "must be a non-empty list")
    for m in metrics:
        if m not in METRICS:
            raise _err(src, "sweep.metrics", f"unknown metric {m!r} (known: {', '.join(METRICS)})")
    keys = data.get("keys", {})
    if not isinstance(keys, dict):
        raise _err(src, "keys", "must be a table of key = values")
    axes = [_axis(src, k, v, sampler) for k, v in keys.items()]
    if sampler != "grid":
        n = _int(src, "sweep.points", sw.get("points", 0), 1, MAX_POINTS)
        if not axes:
            raise _err(src, "keys", f"a {sampler} sweep needs at least one key")
    else:
        if "points" in sw:
            raise _err(src, "sweep.points", "a grid has every combination; points is for random and lhs")
        n = math.prod(len(a.grid()) for a in axes) if axes else 1
        if n > MAX_POINTS:
            raise _err(src, "keys", f"the grid has {n} points (at most {MAX_POINTS})")
    sweep = Sweep(source=src, base=base, axes=axes, sampler=sampler, n_points=n, sampler_seed=seed,
                  seeds=seeds_t, chunk=chunk, scenario=_scenario(src, data.get("scenario", {})),
                  metrics=tuple(metrics))
    if len(seeds_t) * n > MAX_POINTS:
        raise _err(src, "sweep.seeds", f"{len(seeds_t)} seeds x {n} points is too many")
    sweep.points = _points(sweep)
    return sweep


def _points(sw: Sweep) -> list[Point]:
    if sw.sampler == "grid":
        combos = [dict(zip(sw.keys, c, strict=True)) for c in itertools.product(*(a.grid() for a in sw.axes))]
    else:
        U = _unit_samples(sw.axes, sw.sampler, sw.n_points, sw.sampler_seed)
        combos = [{a.key: a.at(float(u[j])) for j, a in enumerate(sw.axes)} for u in U]
    points: list[Point] = []
    for values in combos:
        for seed in sw.seeds:
            v = dict(values)
            where = ", ".join(f"{k} = {x!r}" for k, x in v.items()) or "the base config"
            try:
                cfg = point_config(sw.base, {**v, "sensor.seed": seed} if "sensor.seed" not in v else v)
            except ConfigError as e:
                raise SweepError(f"{sw.source}: point {where}: {' '.join(str(e).split())}") from None
            s = int(v.get("sensor.seed", seed))
            points.append(Point(index=len(points), values=v, seed=s, cfg=cfg,
                                hash=point_hash(v, s, sw.scenario, sw.base)))
    return points
