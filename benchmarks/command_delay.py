"""The hardware path without its pty and clock: the emulator's device and the host's loop in one
process, the host's commands reaching the device a fixed number of samples late.

Over serial the device applies a COMMAND at the sample after it came, one or more samples after
the reading the host computed it from (many on a busy host); in the simulated loop it applies
at once. With 10 Hz boards the pump's switches then fall that many samples after a reading.
This steps the emulator's :class:`~thermoskin.devices.emulator.DeviceCore` (its plant, boards
and scenario) with the host's :class:`~thermoskin.runtime.controller.SkinController` (the MPC,
the pump and the estimator, fed the device's applied ``v`` and ``drive`` as ``thermoskin run``
does), each command delivered ``d`` samples after its sample, and prints per delay the
dispersion the estimator learnt (``observe``'s "dispersion": about 1 where the model fits the
readings; above 1.5 the detector weighs its evidence by ``1.5 / rho``), its one-finger SNR, and
each touch's latency scored against the device's truth. A last run has the tank's board
converting every sample (the others at 10 Hz), delay 2.

    python benchmarks/command_delay.py [--delays 1,2,5] [--duration 20] [--scenario none]
"""

from __future__ import annotations

import argparse
import json
import math

import numpy as np

from thermoskin.analysis.evaluation import match_events, touches_from_truth
from thermoskin.devices import protocol as proto
from thermoskin.devices.emulator import DeviceCore
from thermoskin.params import load_config
from thermoskin.runtime.controller import SkinController
from thermoskin.sim.scenarios import get_scenario


def session(delay: int, duration: float, scenario: str, tp_every_sample: bool = False) -> dict[str, object]:
    """One session of ``duration`` s with every command ``delay`` (>= 1) samples late."""
    cfg = load_config()
    if tp_every_sample:
        cfg = cfg.replace(sensor={"period_T_w": 0.1, "period_T_p": 0.0, "period_T_a": 0.1})
    sc = get_scenario(scenario)
    core = DeviceCore(cfg, sc, tc_period=None if tp_every_sample else 0.1)
    core.on_message(proto.Hello(1, proto.PROTOCOL_VERSION, 1000))
    ctrl = SkinController(load_config())
    est = ctrl.estimator
    assert est is not None
    n = round(duration / core.t_s)
    due: dict[int, proto.Command] = {}
    truth = np.zeros((n, 3))
    for k in range(n):
        cmd = due.pop(k, None)
        if cmd is not None:
            core.on_message(cmd)
        s = next(m for m in core.step() if isinstance(m, proto.SampleMsg))
        t = s.t_us * 1e-6  # the scenario's command, as `thermoskin run` takes it
        ctrl.step(t, s.T_w, s.T_p, s.T_a, sc.T_w_cmd_at(t), s.fresh, s.v, s.drive)
        due[k + delay] = proto.Command(k + 2, ctrl.drive, ctrl.v)
        _, contact, _, n_fingers, _ = core.truth
        truth[k] = (t, contact, n_fingers)
    est.finish(truth[-1, 0])  # a contact still on ends with the session, as `run` ends it
    touches = touches_from_truth(truth[:, 0], truth[:, 1], truth[:, 2])
    m = match_events(touches, est.events, t_end=duration)
    lt = est.learnt()
    by_touch = [{"t_on_s": round(tc.t_on, 3), "n_fingers": tc.n_fingers,
                 "latency_s": None if j is None else round(est.events[j].detected_at - tc.t_on, 3)}
                for tc, j in zip(touches, m.pairs, strict=True) if tc.t_on < duration]
    return {"delay_samples": delay, "tp_every_sample": tp_every_sample,
            "dispersion": round(float(lt.rho), 2), "snr_one_finger": round(float(lt.snr), 2),
            "hits": m.hits, "false_alarms": m.false_alarms, "latency_by_touch": by_touch}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--delays", default="1,2,5", help="command delays, samples (>= 1)")
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--scenario", default="none")
    ap.add_argument("--json", action="store_true", help="print JSON (the only output format)")
    a = ap.parse_args()
    try:
        delays = [int(x) for x in a.delays.split(",")]
    except ValueError:
        ap.error(f"--delays {a.delays!r}: integers >= 1, comma-separated")
    if any(d < 1 for d in delays) or not math.isfinite(a.duration) or a.duration <= 0:
        ap.error("--delays: integers >= 1; --duration: > 0")
    rows = [session(d, a.duration, a.scenario) for d in delays]
    rows.append(session(2, a.duration, a.scenario, tp_every_sample=True))
    print(json.dumps({"scenario": a.scenario, "duration_s": a.duration, "runs": rows}))


if __name__ == "__main__":
    main()
