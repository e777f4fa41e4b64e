"""A skin on 10 Hz thermocouple boards: its loops' pumps count the boards' new readings.

The pump stays stopped for ``pump.still_readings`` (2) new pipe readings (``control/pump.py``):
with 10 Hz boards about 200 ms of still water, which is what lets slow boards see a touch
(``docs/model.md``, What 10 Hz boards allow). The skin's loop passed no fresh bits to its
controllers, so every held 1 kHz sample counted as a reading and the pump stopped for one
board interval (100 ms), as the paper's rule would.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np

from thermoskin.params import load_config
from thermoskin.runtime.skin_loop import run_skin
from thermoskin.sim.scenarios import Scenario
from thermoskin.sim.skin_scenarios import SkinScenario
from thermoskin.skin import load_skin
from thermoskin.skin_log import read_skin_log

ROOT = Path(__file__).resolve().parents[1]
BOARDS_10HZ = {"period_T_w": 0.1, "period_T_p": 0.1, "period_T_a": 0.1, "jitter": 0.003}


def test_the_skins_pump_stays_still_for_two_board_readings(tmp_path: Path) -> None:
    skin = load_skin(ROOT / "examples" / "single.toml", load_config().replace(sensor=BOARDS_10HZ))
    base = Scenario("still", "no touch", duration=6.0, T_w_cmd=24.0, T_a=20.0, pump="logic")
    run_skin(skin, SkinScenario("still", "no touch", base, ()), tmp_path / "s.csv")
    log = read_skin_log(tmp_path / "s.csv", skin)
    on = log.cols["v"][:, 0] > 0.0
    fresh_w = (log.cols["fresh"][:, 0].astype(np.int64) & 1) != 0
    edges = np.flatnonzero(np.diff(on.astype(np.int8))) + 1  # first sample of each new state
    stops = [(a, b) for a, b in itertools.pairwise(edges) if not on[a]]
    assert len(stops) >= 10  # the pump chatters around the command
    for a, b in stops:
        # the readings that came while it stood still, counted from the log's own fresh bits
        assert np.count_nonzero(fresh_w[a:b]) >= 2, (a, b)
    lengths = np.array([b - a for a, b in stops])
    assert lengths.min() >= 190  # two readings 100 +- 3 ms apart (1 ms samples)
