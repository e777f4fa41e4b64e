"""A skin of many patches on slow thermocouple boards (10 Hz by default), against the same skin at 1 kHz.

Each skin of ``examples/`` (``single.toml``: one patch; ``forearm.toml``: nine patches on two
loops) runs its closed loop (``runtime.skin_loop.run_skin``) for 40 s at 24 °C with four
touches on its first patch (1, 2, 1 and 3 fingers of ``man1`` at 14, 20, 27 and 33 s, 2.5 s
each), then ``observe_skin`` on the log. A touch is found if an event on its patch is detected
within ``[t_on, t_on + duration + 1]`` s (``evaluation.match_events``); every other event is a
false alarm. The boards' rate (every channel, 3 % jitter) is swept with ``--rates``; ``--S-w``
observes each slow-board log again with more noise on the pipe node (the trade it offers between
false alarms and touches). One JSON line::

    python benchmarks/skin_boards.py [--rates 10] [--S-w 3e-3,1e-2] [--json]
    python benchmarks/skin_boards.py --rates 500,200,100,50,20,10 --S-w 3e-3,1e-2,3e-2 --json
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

from thermoskin.analysis.evaluation import match_events
from thermoskin.params import load_config
from thermoskin.physics.finger import Touch
from thermoskin.runtime.skin_loop import run_skin
from thermoskin.sim.scenarios import Scenario
from thermoskin.sim.skin_scenarios import SkinContact, SkinScenario
from thermoskin.skin.layout import load_skin
from thermoskin.skin.log import read_skin_log
from thermoskin.skin.observe import observe_skin

ROOT = Path(__file__).resolve().parents[1]
TOUCHES = ((14.0, 1), (20.0, 2), (27.0, 1), (33.0, 3))


def boards(rate_hz: float) -> dict[str, float]:
    """Thermocouple boards converting ``rate_hz`` times a second (3 % jitter), every channel."""
    p = 1.0 / rate_hz
    return {"period_T_w": p, "period_T_p": p, "period_T_a": p, "jitter": 0.03 * p}


def score(name: str, rate_hz: float | None, tmp: Path, S_w: tuple[float, ...] = ()) -> list[dict[str, Any]]:
    """``rate_hz``: the boards' conversion rate (None: fresh every sample, the loop's 1 kHz). The
    log is observed as the skin's config has it, then with each pipe-node noise ``S_w`` (K²/s, the
    estimator's ``S_w``, kept where above the skin's own) on the same log."""
    cfg = load_config().replace(sensor=boards(rate_hz)) if rate_hz else load_config()
    skin = load_skin(ROOT / "examples" / f"{name}.toml", cfg)
    base = Scenario("touches", "four touches", duration=40.0, T_w_cmd=24.0, T_a=20.0, pump="logic")
    p0 = skin.patches[0].name
    contacts = tuple(SkinContact(Touch(t_on=t, duration=2.5, n_fingers=n, person="man1"), patch=p0,
                                 position=0.015) for t, n in TOUCHES)
    path = tmp / f"{name}-{rate_hz}.parquet"
    run_skin(skin, SkinScenario("touches", "four touches", base, contacts), path)
    log = read_skin_log(path, skin)
    for k in ("q_i", "contact_true", "position_true"):
        log.cols.pop(k)
    rows = []
    for s_w in (None, *S_w):
        sk = skin if s_w is None else load_skin(ROOT / "examples" / f"{name}.toml",
                                                cfg.replace(estimator={"S_w": s_w}))
        row = _score_events(observe_skin(log, sk, locate=False).events, skin, contacts)
        rows.append({"skin": name, "boards": f"{rate_hz:g} Hz" if rate_hz else "1 kHz",
                     **({} if s_w is None else {"S_w": s_w}), **row})
    return rows


def _score_events(events: list[Any], skin: Any, contacts: tuple[SkinContact, ...]) -> dict[str, Any]:
    p0 = skin.patches[0].name
    on_first = [e.event for e in events if e.patch == 0]
    m = match_events([c.touch for c in contacts], on_first)
    elsewhere = [e for e in events if e.patch != 0]
    return {"touches": len(TOUCHES),
            "hits": m.hits, "false_alarms": m.false_alarms + len(elsewhere),
            "latency_median_s": float(np.median(m.latencies)) if m.hits else None,
            "false_alarm_patches": sorted({skin.patches[e.patch].name for e in elsewhere}
                                          | ({p0} if m.false_alarms else set()))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="only the JSON line on stdout")
    ap.add_argument("--rates", default="10", help="comma-separated board rates, Hz, besides 1 kHz "
                    "(default 10)")
    ap.add_argument("--S-w", dest="S_w", default="", help="comma-separated pipe-node noises (K^2/s) to "
                    "observe each slow-board log with too (default: none)")
    a = ap.parse_args()
    S_w = tuple(float(x) for x in a.S_w.split(",") if x)
    rates: list[float | None] = [None, *(float(x) for x in a.rates.split(",") if x)]
    t0 = time.perf_counter()
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for name in ("single", "forearm"):
            for rate in rates:
                for row in score(name, rate, Path(d), S_w if rate else ()):
                    rows.append(row)
                    print(json.dumps(row), file=sys.stderr, flush=True)
    print(json.dumps({"runs": rows, "wall_s": round(time.perf_counter() - t0, 1)}))


if __name__ == "__main__":
    main()
