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

``--sessions N`` runs N sessions per delay, the i-th with the scenario's touches ``0.1 i / N`` s
later (over serial their phase against the boards' conversions moves with when the host
connected) and, with ``--lab-boards``, the device's boards as a lab buys them drawn from seed i
(``sim.boards``); ``--config F``: the host's configuration (e.g. ``[detector] rho_window = 0``
to see what the dispersion does). Many 10 Hz sessions in a minute, where the pty takes their
length each (``serial_load.py``); ``total`` sums them per delay.

    python benchmarks/command_delay.py [--delays 1,2,5] [--duration 20] [--scenario none]
                                       [--sessions N] [--lab-boards] [--config F]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math

import numpy as np

from thermoskin.analysis.evaluation import match_events, touches_from_truth
from thermoskin.devices import protocol as proto
from thermoskin.devices.emulator import DeviceCore
from thermoskin.params import load_config
from thermoskin.runtime.controller import SkinController
from thermoskin.sim.scenarios import get_scenario


def session(delay: int, duration: float, scenario: str, tp_every_sample: bool = False, shift: float = 0.0,
            lab_seed: int | None = None, host_config: str | None = None) -> dict[str, object]:
    """One session of ``duration`` s with every command ``delay`` (>= 1) samples late; the
    scenario's touches ``shift`` s later; ``lab_seed``: the device's boards as a lab buys them,
    of that seed; ``host_config``: the host's configuration file (None: the default)."""
    cfg = load_config()
    if tp_every_sample:
        cfg = cfg.replace(sensor={"period_T_w": 0.1, "period_T_p": 0.0, "period_T_a": 0.1})
    if lab_seed is not None:
        cfg = cfg.replace(sensor={"seed": lab_seed})
    sc = get_scenario(scenario)
    if shift:
        sc = dataclasses.replace(sc, touches=tuple(dataclasses.replace(tc, t_on=tc.t_on + shift)
                                                   for tc in sc.touches))
    core = DeviceCore(cfg, sc, tc_period=None if tp_every_sample else 0.1, lab_boards=lab_seed is not None)
    core.on_message(proto.Hello(1, proto.PROTOCOL_VERSION, 1000))
    ctrl = SkinController(load_config(host_config))
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
                 "latency_s": None if x is None else round(x, 3)}
                for tc, x in zip(touches, m.latency_by_touch(), strict=True) if tc.t_on < duration]
    return {"delay_samples": delay, "tp_every_sample": tp_every_sample, "shift_s": round(shift, 4),
            "lab_seed": lab_seed, "dispersion": round(float(lt.rho), 2),
            "snr_one_finger": round(float(lt.snr), 2), "hits": m.hits, "false_alarms": m.false_alarms,
            "false_alarms_at_s": [round(float(e.detected_at), 2) for e in m.spurious],
            "latency_by_touch": by_touch}


def totals(rows: list[dict[str, object]]) -> list[dict[str, object]]:
    """Per delay (the tank's every-sample run apart): touches, detected, false alarms, latency
    median and p90, the dispersion's median over the sessions."""
    out = []
    for key in sorted({(r["delay_samples"], r["tp_every_sample"]) for r in rows}, key=str):
        rs = [r for r in rows if (r["delay_samples"], r["tp_every_sample"]) == key]
        lat = [x["latency_s"] for r in rs for x in r["latency_by_touch"]]  # type: ignore[attr-defined]
        hit = [x for x in lat if x is not None]
        out.append({"delay_samples": key[0], "tp_every_sample": key[1], "sessions": len(rs),
                    "touches": len(lat), "detected": len(hit),
                    "false_alarms": sum(int(r["false_alarms"]) for r in rs),  # type: ignore[call-overload]
                    "latency_median_s": round(float(np.median(hit)), 3) if hit else None,
                    "latency_p90_s": round(float(np.percentile(hit, 90)), 3) if hit else None,
                    "dispersion_median": round(float(np.median([r["dispersion"] for r in rs])), 2)})
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--delays", default="1,2,5", help="command delays, samples (>= 1)")
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--scenario", default="none")
    ap.add_argument("--sessions", type=int, default=1,
                    help="sessions per delay, the i-th with the touches 0.1 i / N s later")
    ap.add_argument("--lab-boards", action="store_true",
                    help="the device's boards as a lab buys them, seed i for the i-th session")
    ap.add_argument("--config", default=None, metavar="F", help="the host's configuration (TOML)")
    ap.add_argument("--json", action="store_true", help="print JSON (the only output format)")
    a = ap.parse_args()
    try:
        delays = [int(x) for x in a.delays.split(",")]
    except ValueError:
        ap.error(f"--delays {a.delays!r}: integers >= 1, comma-separated")
    if any(d < 1 for d in delays) or not math.isfinite(a.duration) or a.duration <= 0 or a.sessions < 1:
        ap.error("--delays: integers >= 1; --duration: > 0; --sessions: >= 1")
    try:
        load_config(a.config)
        get_scenario(a.scenario)
    except (OSError, ValueError, KeyError) as e:
        ap.error(str(e))
    rows = []
    for i in range(a.sessions):
        kw = {"shift": 0.1 * i / a.sessions, "lab_seed": i if a.lab_boards else None, "host_config": a.config}
        rows += [session(d, a.duration, a.scenario, **kw) for d in delays]  # type: ignore[arg-type]
        rows.append(session(2, a.duration, a.scenario, tp_every_sample=True, **kw))  # type: ignore[arg-type]
    print(json.dumps({"scenario": a.scenario, "duration_s": a.duration, "sessions": a.sessions,
                      "lab_boards": a.lab_boards, "config": a.config, "runs": rows,
                      "total": totals(rows)}))


if __name__ == "__main__":
    main()
