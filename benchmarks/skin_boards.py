"""A skin of many patches on 10 Hz thermocouple boards, against the same skin on 1 kHz ones.

Each skin of ``examples/`` (``single.toml``: one patch; ``forearm.toml``: nine patches on two
loops) runs its closed loop (``runtime.skin_loop.run_skin``) for 40 s at 24 °C with four
touches on its first patch (1, 2, 1 and 3 fingers of ``man1`` at 14, 20, 27 and 33 s, 2.5 s
each), then ``observe_skin`` on the log. A touch is found if an event on its patch is detected
within ``[t_on, t_on + duration + 1]`` s (``evaluation.match_events``); every other event is a
false alarm. One JSON line::

    python benchmarks/skin_boards.py [--json]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from thermoskin.evaluation import match_events
from thermoskin.params import load_config
from thermoskin.physics.finger import Touch
from thermoskin.runtime.skin_loop import run_skin
from thermoskin.sim.scenarios import Scenario
from thermoskin.sim.skin_scenarios import SkinContact, SkinScenario
from thermoskin.skin import load_skin
from thermoskin.skin_log import read_skin_log
from thermoskin.skin_observe import observe_skin

ROOT = Path(__file__).resolve().parents[1]
BOARDS_10HZ = {"period_T_w": 0.1, "period_T_p": 0.1, "period_T_a": 0.1, "jitter": 0.003}
TOUCHES = ((14.0, 1), (20.0, 2), (27.0, 1), (33.0, 3))


def score(name: str, boards: bool, tmp: Path) -> dict[str, Any]:
    cfg = load_config().replace(sensor=BOARDS_10HZ) if boards else load_config()
    skin = load_skin(ROOT / "examples" / f"{name}.toml", cfg)
    base = Scenario("touches", "four touches", duration=40.0, T_w_cmd=24.0, T_a=20.0, pump="logic")
    p0 = skin.patches[0].name
    contacts = tuple(SkinContact(Touch(t_on=t, duration=2.5, n_fingers=n, person="man1"), patch=p0,
                                 position=0.015) for t, n in TOUCHES)
    path = tmp / f"{name}-{boards}.parquet"
    run_skin(skin, SkinScenario("touches", "four touches", base, contacts), path)
    log = read_skin_log(path, skin)
    for k in ("q_i", "contact_true", "position_true"):
        log.cols.pop(k)
    events = observe_skin(log, skin, locate=False).events
    on_first = [e.event for e in events if e.patch == 0]
    m = match_events([c.touch for c in contacts], on_first)
    elsewhere = [e for e in events if e.patch != 0]
    return {"skin": name, "boards": "10 Hz" if boards else "1 kHz", "touches": len(TOUCHES),
            "hits": m.hits, "false_alarms": m.false_alarms + len(elsewhere),
            "latency_median_s": float(np.median(m.latencies)) if m.hits else None,
            "false_alarm_patches": sorted({skin.patches[e.patch].name for e in elsewhere}
                                          | ({p0} if m.false_alarms else set()))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="only the JSON line on stdout")
    ap.parse_args()
    t0 = time.perf_counter()
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for name in ("single", "forearm"):
            for boards in (False, True):
                rows.append(score(name, boards, Path(d)))
                print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
    print(json.dumps({"runs": rows, "wall_s": round(time.perf_counter() - t0, 1)}))


if __name__ == "__main__":
    main()
