"""Thermoskin: touch sensing and temperature control for soft thermal robot skins.

The objects a lab composes in its own code (``docs/api.md`` shows each with examples)::

    import thermoskin as ts

    cfg = ts.load_config()                        # the paper's Table I, or ts.load_config("my.toml")
    est = ts.TouchEstimator(cfg)                  # eq. 8, the Kalman filter, the detector: one patch
    contact = est.step(t, T_w, T_p, v, T_a)       # one sample (floats), in a loop of your own
    res = est.run(t, T_w, T_p, v, T_a)            # or numpy arrays: res.columns, res.events
    obs = ts.observe(log, cfg)                    # a log as a dict of arrays (its own rate, fresh flags)
    many = ts.PatchEstimators(cfg, n=100)         # many patches, one compiled loop
    log = ts.read_log("run.csv")                  # CSV or Parquet; ts.write_log, ts.LogReader, ts.LogWriter
    ts.write_events("events.csv", res.events)     # one row per contact
    skin = ts.load_skin("examples/forearm.toml")  # a skin of many patches (its layout file)
    sc = ts.skin_scenario("multi", skin)          # its scenario (or ts.SkinScenario of ts.SkinContact);
                                                  # ts.run_skin, ts.read_skin_log, ts.observe_skin,
                                                  # ts.group_events
    ts.characterise_events(events, columns, cfg)  # what touched; thermoskin.fit.calibrate.calibrate (a fit);
                                                  # ts.load_sweep / ts.run_sweep (design sweeps)

Names are imported on first use, so ``import thermoskin`` stays light.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from thermoskin import _numba_cache

_numba_cache.configure()  # before numba is imported (a cache per version of the compiled code)

__version__ = "0.1.0"

#: Public name -> module that defines it.
_EXPORTS = {
    "Config": "thermoskin.params",
    "ConfigError": "thermoskin.params",
    "load_config": "thermoskin.params",
    "save_config": "thermoskin.params",
    "TouchEstimator": "thermoskin.estimation.estimator",
    "Observation": "thermoskin.estimation.estimator",
    "PatchEstimators": "thermoskin.estimation.patches",
    "ThermalExchangeObserver": "thermoskin.estimation.observer",
    "ContactEvent": "thermoskin.estimation.events",
    "EVENT_COLUMNS": "thermoskin.estimation.events",
    "write_events": "thermoskin.estimation.events",
    "observe": "thermoskin.analysis.observe",
    "observe_file": "thermoskin.analysis.observe",
    "read_log": "thermoskin.logio",
    "write_log": "thermoskin.logio",
    "LogReader": "thermoskin.logio",
    "LogWriter": "thermoskin.logio",
    "LogError": "thermoskin.logio",
    "simulate": "thermoskin.sim.run",
    "Scenario": "thermoskin.sim.scenarios",
    "SCENARIOS": "thermoskin.sim.scenarios",
    "Touch": "thermoskin.physics.finger",
    "run_closed_loop": "thermoskin.runtime.closed_loop",
    "SkinController": "thermoskin.runtime.controller",
    "match_events": "thermoskin.analysis.evaluation",
    "Skin": "thermoskin.skin.layout",
    "load_skin": "thermoskin.skin.layout",
    "read_skin_log": "thermoskin.skin.log",
    "observe_skin": "thermoskin.skin.observe",
    "group_events": "thermoskin.skin.groups",
    "run_skin": "thermoskin.runtime.skin_loop",
    "skin_scenario": "thermoskin.sim.skin_scenarios",
    "SkinScenario": "thermoskin.sim.skin_scenarios",
    "SkinContact": "thermoskin.sim.skin_scenarios",
    "characterise_events": "thermoskin.touch.characterise",
    "load_sweep": "thermoskin.sweep.spec",
    "run_sweep": "thermoskin.sweep.run",
}

__all__ = [
    "EVENT_COLUMNS",
    "SCENARIOS",
    "Config",
    "ConfigError",
    "ContactEvent",
    "LogError",
    "LogReader",
    "LogWriter",
    "Observation",
    "PatchEstimators",
    "Scenario",
    "Skin",
    "SkinContact",
    "SkinController",
    "SkinScenario",
    "ThermalExchangeObserver",
    "Touch",
    "TouchEstimator",
    "__version__",
    "characterise_events",
    "group_events",
    "load_config",
    "load_skin",
    "load_sweep",
    "match_events",
    "observe",
    "observe_file",
    "observe_skin",
    "read_log",
    "read_skin_log",
    "run_closed_loop",
    "run_skin",
    "run_sweep",
    "save_config",
    "simulate",
    "skin_scenario",
    "write_events",
    "write_log",
]


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'thermoskin' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)


if TYPE_CHECKING:  # for type checkers and IDEs
    from thermoskin.analysis.evaluation import match_events
    from thermoskin.analysis.observe import observe, observe_file
    from thermoskin.estimation.estimator import Observation, TouchEstimator
    from thermoskin.estimation.events import EVENT_COLUMNS, ContactEvent, write_events
    from thermoskin.estimation.observer import ThermalExchangeObserver
    from thermoskin.estimation.patches import PatchEstimators
    from thermoskin.logio import LogError, LogReader, LogWriter, read_log, write_log
    from thermoskin.params import Config, ConfigError, load_config, save_config
    from thermoskin.physics.finger import Touch
    from thermoskin.runtime.closed_loop import run_closed_loop
    from thermoskin.runtime.controller import SkinController
    from thermoskin.runtime.skin_loop import run_skin
    from thermoskin.sim.run import simulate
    from thermoskin.sim.scenarios import SCENARIOS, Scenario
    from thermoskin.sim.skin_scenarios import SkinContact, SkinScenario, skin_scenario
    from thermoskin.skin.groups import group_events
    from thermoskin.skin.layout import Skin, load_skin
    from thermoskin.skin.log import read_skin_log
    from thermoskin.skin.observe import observe_skin
    from thermoskin.sweep.run import run_sweep
    from thermoskin.sweep.spec import load_sweep
    from thermoskin.touch.characterise import characterise_events
