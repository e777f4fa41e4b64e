"""``thermoskin reproduce``: the paper's Figs. 8 and 12-19 on the simulated skin, summary.json, report.md.

Each figure needs some runs (:data:`NEEDS`); the runs are shared out over a process pool
(two workers), then the figures, ``summary.json`` and ``report.md`` are written. See
:mod:`thermoskin.experiments.scenarios` for the reading of Sec. VI and
:mod:`thermoskin.experiments.analysis` for the numbers.
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from contextlib import AbstractContextManager
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.progress import Progress

from thermoskin.experiments import figures
from thermoskin.experiments.report import write_report
from thermoskin.experiments.runs import Job, run_job
from thermoskin.experiments.scenarios import N_CONTACTS, POSITIONS, SETPOINT_S, SETPOINTS
from thermoskin.physics.finger import PERSONS

FIGURES: tuple[str, ...] = ("fig8", "fig12", "fig13", "fig14", "fig15", "fig16", "fig17", "fig18", "fig19")
"""The reproduced figures, in order."""

WORKERS = 2
"""Processes running the jobs (the reproduction is sized for two cores)."""


class ReproductionError(ValueError):
    """An impossible state of the reproduction (a job missing for a figure)."""


def jobs_for(n_contacts: int = N_CONTACTS, setpoint_s: float = SETPOINT_S) -> dict[str, Job]:
    """Every job of the full reproduction, by key."""
    jobs: dict[str, Job] = {}
    for c in SETPOINTS:
        jobs[f"sp{c:g}"] = Job(f"sp{c:g}", "setpoint", T_w_cmd=c, duration=setpoint_s)
    for n in (1, 2, 3):
        jobs[f"f{n}"] = Job(f"f{n}", "contacts", n_fingers=n, n_contacts=n_contacts)
    for who in PERSONS:
        if who != "man1":  # man1's one-finger run is f1
            jobs[f"p-{who}"] = Job(f"p-{who}", "contacts", person=who, n_contacts=n_contacts)
    for name, x in POSITIONS.items():
        jobs[f"pos-{name}"] = Job(f"pos-{name}", "contacts", position=x, skin_model="spatial",
                                  n_contacts=n_contacts)
        jobs[f"stop-{name}"] = Job(f"stop-{name}", "stopped", position=x, n_contacts=n_contacts)
        jobs[f"inlet-{name}"] = Job(f"inlet-{name}", "inlet-near", position=x, n_contacts=n_contacts)
    return jobs


def person_key(who: str) -> str:
    return "f1" if who == "man1" else f"p-{who}"


NEEDS: dict[str, tuple[str, ...]] = {
    "fig8": tuple(f"sp{c:g}" for c in SETPOINTS),
    "fig12": ("f1",), "fig13": ("f2",), "fig14": ("f3",),
    "fig15": ("f1",), "fig16": ("f2",), "fig17": ("f3",),
    "fig18": tuple(person_key(w) for w in PERSONS),
    "fig19": ("f1", *(f"{k}-{p}" for k in ("pos", "stop", "inlet") for p in POSITIONS)),
}
"""The jobs each figure needs."""

_COST = {"setpoint": 1.0, "contacts": 1.0, "stopped": 0.3, "inlet-near": 0.3}


def _cost(job: Job) -> float:
    """Rough relative cost, to start the longest jobs first."""
    dur = job.duration if job.kind == "setpoint" else 12.0 + 3.0 * job.n_contacts
    return dur * _COST[job.kind] * (1.8 if job.skin_model == "spatial" else 1.0)


def run_jobs(jobs: Sequence[Job], workers: int = WORKERS,
             on_done: Callable[[str], None] | None = None) -> dict[str, dict[str, Any]]:
    """Run ``jobs`` (in a process pool when more than one worker and job) and return results by key."""
    ordered = sorted(jobs, key=_cost, reverse=True)
    out: dict[str, dict[str, Any]] = {}
    workers = max(1, min(workers, os.cpu_count() or 1, len(ordered)))
    if workers == 1:
        for job in ordered:
            out[job.key] = run_job(job)
            if on_done is not None:
                on_done(job.key)
        return out
    with ProcessPoolExecutor(max_workers=workers) as pool:
        futures = {pool.submit(run_job, job): job.key for job in ordered}
        for fut in as_completed(futures):
            key = futures[fut]
            out[key] = fut.result()
            if on_done is not None:
                on_done(key)
    return out


def _clean(x: Any) -> Any:
    """JSON-safe: NaN and inf become None, tuples lists."""
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_clean(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def _pair(st: dict[str, Any]) -> dict[str, Any]:
    """The summary's ``{mean_dq_W, peak_dq_W}`` first, then the other numbers."""
    return {"mean_dq_W": st["mean_dq_W"], "peak_dq_W": st["peak_dq_W"],
            **{k: v for k, v in st.items() if k not in ("mean_dq_W", "peak_dq_W")}}


def build_summary(res: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """summary.json from the results present (a section only if all of its runs are there)."""
    s: dict[str, Any] = {}
    if all(f"sp{c:g}" in res for c in SETPOINTS):
        s["setpoints"] = {f"{c:g}": res[f"sp{c:g}"]["stats"] for c in SETPOINTS}
    if all(f"f{n}" in res for n in (1, 2, 3)):
        s["fingers"] = {str(n): _pair(res[f"f{n}"]["stats"]) for n in (1, 2, 3)}
    if all(person_key(w) in res for w in PERSONS):
        s["persons"] = {w: {**_pair(res[person_key(w)]["stats"]), "T_body_degC": PERSONS[w].T_body,
                            "G_finger_W_per_K": PERSONS[w].G_finger} for w in PERSONS}
    groups = {"positions": "stop", "positions_closed_loop": "pos", "positions_inlet_near": "inlet"}
    for section, prefix in groups.items():
        if all(f"{prefix}-{p}" in res for p in POSITIONS):
            s[section] = {p: {**_pair(res[f"{prefix}-{p}"]["stats"]), "position": x,
                              "pump_on_in_contact": res[f"{prefix}-{p}"]["pump_on_in_contact"]}
                          for p, x in POSITIONS.items()}
    if "positions" in s:
        s["positions_note"] = ("'positions' is the spatial skin with the pump stopped while the finger is "
                               "on (Fig. 19b); 'positions_closed_loop' the closed loop with the pump "
                               "switching (Fig. 19a); 'positions_inlet_near' the water entering at the "
                               "thermocouple end. See report.md.")
    if "f1" in res and "pos-near" in res:
        a, b = res["f1"]["stats"], res["pos-near"]["stats"]
        s["spatial_vs_network"] = {
            "network_mean_dq_W": a["mean_dq_W"], "spatial_near_mean_dq_W": b["mean_dq_W"],
            "network_peak_dq_W": a["peak_dq_W"], "spatial_near_peak_dq_W": b["peak_dq_W"],
            "ratio_mean": b["mean_dq_W"] / a["mean_dq_W"], "ratio_peak": b["peak_dq_W"] / a["peak_dq_W"]}
    return _clean(s)


def make_figures(figs: Sequence[str], res: dict[str, dict[str, Any]], out_dir: Path) -> dict[str, Path]:
    """Write the PNGs of ``figs``; return their paths."""
    paths: dict[str, Path] = {}
    q_max = max((res[k]["stats"]["peak_dq_W"] for k in ("f1", "f2", "f3") if k in res), default=None)
    for fig in figs:
        missing = [k for k in NEEDS[fig] if k not in res]
        if missing:
            raise ReproductionError(f"{fig}: runs {missing} missing")
        path = out_dir / f"{fig}.png"
        num = int(fig[3:])
        if fig == "fig8":
            figures.fig8([res[k] for k in NEEDS[fig]], path)
        elif num in (12, 13, 14):
            figures.fig_temperatures(res[f"f{num - 11}"], path, num, num - 11)
        elif num in (15, 16, 17):
            figures.fig_heat_flow(res[f"f{num - 14}"], path, num, num - 14, q_max=q_max)
        elif fig == "fig18":
            figures.fig18([(w, res[person_key(w)]) for w in PERSONS], path)
        elif fig == "fig19":
            figures.fig19([(p, res[f"pos-{p}"]) for p in POSITIONS],
                          [(p, res[f"stop-{p}"]) for p in POSITIONS], res["f1"], path)
        paths[fig] = path
    return paths


def reproduce(out_dir: Path, only: list[str] | None, console: Console,
              progress: Callable[[str], AbstractContextManager[Progress]], *,
              n_contacts: int = N_CONTACTS, setpoint_s: float = SETPOINT_S, workers: int = WORKERS) -> None:
    """Run the experiments of ``only`` (default: all of :data:`FIGURES`) and write figures, summary, report.

    ``n_contacts`` and ``setpoint_s`` shorten the runs (tests); the full reproduction uses
    the defaults.
    """
    figs = [f for f in FIGURES if only is None or f in only]
    unknown = sorted(set(only or ()) - set(FIGURES))
    if unknown:
        raise ReproductionError(f"unknown figures {unknown}")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    all_jobs = jobs_for(n_contacts, setpoint_s)
    keys = sorted({k for f in figs for k in NEEDS[f]})
    jobs = [all_jobs[k] for k in keys]
    wall0 = time.perf_counter()
    with progress("simulating the experiments") as bar:
        task = bar.add_task("simulating the experiments", total=len(jobs))
        res = run_jobs(jobs, workers,
                       on_done=lambda key: bar.update(task, advance=1, description=f"done {key}"))
    sim_wall = time.perf_counter() - wall0
    paths = make_figures(figs, res, out_dir)
    summary = build_summary(res)
    summary["run"] = {"figures": figs, "n_contacts": n_contacts, "setpoint_s": setpoint_s,
                      "simulated_s": sum(r["scenario"].duration for r in res.values()),
                      "wall_s": round(time.perf_counter() - wall0, 2),
                      "simulation_wall_s": round(sim_wall, 2)}
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    write_report(out_dir / "report.md", figs, paths, summary, res)
    for fig in figs:
        console.print(f"wrote {paths[fig]}")
    console.print(f"wrote {out_dir / 'summary.json'} and {out_dir / 'report.md'} "
                  f"({len(jobs)} runs, {summary['run']['simulated_s']:.0f} s simulated, "
                  f"{summary['run']['wall_s']:.0f} s wall)")
