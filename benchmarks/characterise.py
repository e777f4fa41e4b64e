"""What touched the skin: accuracy against time since onset, confusion, estimate errors, probe cost.

Closed-loop runs of ``toucher_scenario`` (persons at 30-36 °C, cold drinks, hot mugs, tools
at room temperature; :mod:`thermoskin.physics.world`) on seeds never used in tuning
(``SEED0`` and up; seeds below 1000 were used while the characteriser was written), each
contact characterised from its onset to ``τ`` s later (what a live call then would know)
and at its release:

- detection per toucher (a contact not detected cannot be characterised);
- person/object (``p_human >= 0.5``) and material class (the most probable) correct, against
  ``τ`` in 0.25-3 s, over the detected contacts lasting at least ``τ``; the share decided
  (``toucher`` / ``material`` not empty) and the accuracy among those;
- the confusion matrix of the material class at 1.5 s and at the release;
- the estimates against the truth: ``T_f`` (holds of 3 s and more: called identifiable,
  within ±1.5 K), ``G``, effusivity (ratio), with their z-scores;
- active sensing (``--probe``): the same seeds with and without the set-point square wave,
  detection (hits, false alarms, latency, release error) and regulation (``|T_w - T_w_cmd|``
  during contacts and outside) compared.

Skins: ``table1`` (the paper's: the sheet held by the air, ``R_ag`` = 1 K/W, ``R_g`` = 10 K/W)
and ``bonded`` (a sheet bonded to the pipe and insulated from the air: ``R_g`` = 1 K/W,
``R_ag`` = 10 K/W), each without and with the probe.

    python benchmarks/characterise.py [--seeds 12] [--duration 300] [--json]
        [--figure docs/img/characterise.png]
    python benchmarks/characterise.py --from-json OUT.json --figure docs/img/characterise.png

The machine is shared: wall times are indicative.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np

from thermoskin.analysis.evaluation import match_events
from thermoskin.control.probe import SetpointProbe
from thermoskin.params import Config
from thermoskin.physics import contact as ct
from thermoskin.runtime.closed_loop import run_closed_loop
from thermoskin.sim.scenarios import toucher_scenario
from thermoskin.touch.characterise import Characteriser

SEED0 = 13000
SETTLE_S = 10.0
TAUS = (0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0)
SKINS: dict[str, dict[str, float]] = {"table1": {}, "bonded": {"R_g": 1.0, "R_ag": 10.0}}
PROBES: dict[str, SetpointProbe | None] = {"none": None, "square": SetpointProbe()}
CLASSES = ct.CLASSES
ANCHORS = {0.5: 0.84, 1.5: 0.98}
"""Bhattacharjee, Wade & Kemp (RSS 2015): 11 materials, 84 % after 0.5 s, 98 % after 1.5 s."""


def truth_of(tc: Any) -> dict[str, Any]:
    """The toucher's truth (``physics.contact.toucher``)."""
    t = ct.toucher(tc.toucher, tc.T_body, tc.area, tc.pressure).truth
    return {"kind": tc.toucher, "human": t["toucher_true"] == "human", "cls": t["class_true"],
            "T_f": t["T_f_true"], "G": t["G_true"], "e": t["effusivity_true"], "duration": tc.duration}


def run_one(args: tuple[int, str, str, float]) -> dict[str, Any]:
    seed, skin, probe, duration = args
    cfg = Config().replace(skin=SKINS[skin], sensor={"seed": seed}) if SKINS[skin] else \
        Config().replace(sensor={"seed": seed})
    sc = toucher_scenario(seed, duration).shifted(SETTLE_S)
    res = run_closed_loop(sc, cfg, probe=PROBES[probe])
    c = res.columns
    ch = Characteriser(cfg)
    ch.feed(c["t"], c["dq_i_hat"], c["T_w"], c["T_a"])
    ch.finish()
    m = match_events(sc.touches, res.events)
    rows = []
    for tc, hit in zip(sc.touches, m.pairs, strict=True):
        row: dict[str, Any] = {"truth": truth_of(tc), "detected": hit is not None}
        if hit is not None:
            e = res.events[hit]
            row["latency"] = e.detected_at - tc.t_on
            row["release_err"] = e.release - tc.t_off
            out = {}
            for tau in (*TAUS, None):
                if tau is not None and tau > tc.duration:
                    continue
                r = ch.characterise(e, tau)
                out["end" if tau is None else f"{tau:g}"] = {
                    "p_human": r.p_human, "toucher": r.toucher, "material": r.material,
                    "cls": max(r.p_class.items(), key=lambda kv: kv[1])[0],
                    "G": r.G_hat, "G_sd": r.G_sd, "T_f": r.T_f_hat, "T_f_sd": r.T_f_sd,
                    "e": r.effusivity_hat, "post_T": r.post["T_0"], "post_T_sd": r.post["T_0_sd"]}
            row["at"] = out
        rows.append(row)
    # regulation after the settle: |T_w - T_w_cmd|, in contacts and outside
    k0 = int(SETTLE_S / cfg.sampling.t_s)
    err = np.abs(c["T_w"] - c["T_w_cmd"])[k0:]
    inc = c["contact_true"][k0:] > 0
    reg = {"in_p50": float(np.median(err[inc])) if inc.any() else math.nan,
           "in_p99": float(np.percentile(err[inc], 99)) if inc.any() else math.nan,
           "in_max": float(err[inc].max()) if inc.any() else math.nan,
           "out_p50": float(np.median(err[~inc])), "out_p99": float(np.percentile(err[~inc], 99)),
           "out_max": float(err[~inc].max())}
    return {"seed": seed, "skin": skin, "probe": probe, "rows": rows,
            "false_alarms": m.false_alarms, "regulation": reg, "wall_s": res.wall_s}


def _share(x: list[bool]) -> float:
    return float(np.mean(x)) if x else math.nan


def summarise(runs: list[dict[str, Any]]) -> dict[str, Any]:
    rows = [r for run in runs for r in run["rows"]]
    det = [r for r in rows if r["detected"]]
    out: dict[str, Any] = {"touches": len(rows), "detected": len(det),
                           "false_alarms": sum(run["false_alarms"] for run in runs)}
    kinds = sorted({r["truth"]["kind"] for r in rows})
    out["detection_by_kind"] = {k: f"{sum(r['detected'] for r in rows if r['truth']['kind'] == k)}/"
                                   f"{sum(r['truth']['kind'] == k for r in rows)}" for k in kinds}
    lat = [r["latency"] for r in det]
    rel = [abs(r["release_err"]) for r in det]
    out["latency_p50_s"] = float(np.median(lat)) if lat else math.nan
    out["release_abs_err_p50_s"] = float(np.median(rel)) if rel else math.nan
    curve = {}
    for tau in TAUS:
        key = f"{tau:g}"
        rr = [r for r in det if key in r["at"]]
        hum = [(r["at"][key]["p_human"] >= 0.5) == r["truth"]["human"] for r in rr]
        dec = [r for r in rr if r["at"][key]["toucher"]]
        hum_dec = [(r["at"][key]["toucher"] == "human") == r["truth"]["human"] for r in dec]
        mat = [r["at"][key]["cls"] == r["truth"]["cls"] for r in rr]
        mdec = [r for r in rr if r["at"][key]["material"]]
        mat_dec = [r["at"][key]["material"] == r["truth"]["cls"] for r in mdec]
        curve[key] = {"n": len(rr), "person_object": _share(hum), "person_object_decided": _share([
            True] * len(dec) + [False] * (len(rr) - len(dec))), "person_object_acc_decided": _share(hum_dec),
            "material": _share(mat), "material_decided": len(mdec) / len(rr) if rr else math.nan,
            "material_acc_decided": _share(mat_dec)}
    out["accuracy_vs_time"] = curve
    for key in ("1.5", "end"):
        conf = {a: dict.fromkeys(CLASSES, 0) for a in CLASSES}
        for r in det:
            if key in r["at"]:
                conf[r["truth"]["cls"]][r["at"][key]["cls"]] += 1
        out[f"confusion_{key}"] = {a: {b: n for b, n in row.items() if n} for a, row in conf.items()
                                   if sum(row.values())}
    # estimates at the release for holds >= 3 s
    holds = [r for r in det if r["truth"]["duration"] >= 3.0]
    est: dict[str, Any] = {"holds_3s": len(holds)}
    ident = [r for r in holds if math.isfinite(r["at"]["end"]["T_f"])]
    errs = np.array([r["at"]["end"]["T_f"] - r["truth"]["T_f"] for r in ident])
    zs = np.array([(r["at"]["end"]["T_f"] - r["truth"]["T_f"]) / r["at"]["end"]["T_f_sd"] for r in ident])
    est["T_f_identifiable"] = len(ident)
    est["T_f_within_1p5K"] = int(np.sum(np.abs(errs) <= 1.5)) if len(errs) else 0
    est["T_f_abs_err_p50_K"] = float(np.median(np.abs(errs))) if len(errs) else math.nan
    est["T_f_abs_err_max_K"] = float(np.max(np.abs(errs))) if len(errs) else math.nan
    est["T_f_abs_z_p50"] = float(np.median(np.abs(zs))) if len(zs) else math.nan
    est["T_f_by_kind"] = {k: f"{sum(r['truth']['kind'] == k for r in ident)}/"
                             f"{sum(r['truth']['kind'] == k for r in holds)}" for k in kinds}
    post = np.array([r["at"]["end"]["post_T"] - r["truth"]["T_f"] for r in holds])
    est["T_f_posterior_abs_err_p50_K_all_holds"] = float(np.median(np.abs(post))) if len(post) else math.nan
    gi = [r for r in holds if math.isfinite(r["at"]["end"]["G"]) and r["truth"]["kind"] not in
          ("can_cold", "water_bag")]
    gr = np.array([r["at"]["end"]["G"] / r["truth"]["G"] - 1.0 for r in gi])
    gz = np.array([(r["at"]["end"]["G"] - r["truth"]["G"]) / r["at"]["end"]["G_sd"] for r in gi])
    est["G_identifiable"] = len([r for r in holds if math.isfinite(r["at"]["end"]["G"])])
    est["G_rel_err_p50"] = float(np.median(np.abs(gr))) if len(gr) else math.nan
    est["G_abs_z_p50"] = float(np.median(np.abs(gz))) if len(gz) else math.nan
    ei = [r for r in det if math.isfinite(r["at"]["end"]["e"])]
    er = np.array([math.log(r["at"]["end"]["e"] / r["truth"]["e"]) for r in ei])
    est["effusivity_reported"] = f"{len(ei)}/{len(det)}"
    est["effusivity_abs_ln_ratio_p50"] = float(np.median(np.abs(er))) if len(er) else math.nan
    est["effusivity_within_factor_1p5"] = _share(list(np.abs(er) <= math.log(1.5)))
    out["estimates"] = est
    reg = [run["regulation"] for run in runs]
    out["regulation_K"] = {k: float(np.nanmax([g[k] for g in reg])) if k.endswith("max")
                           else float(np.nanmedian([g[k] for g in reg])) for k in reg[0]}
    return out


def figure(summary: dict[str, Any], path: str) -> None:
    """Accuracy against time since onset (person/object, material class) for every
    configuration with the anchor of Bhattacharjee et al., and the confusion matrix of the
    material class at 1.5 s for the first configuration."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.4), gridspec_kw={"width_ratios": [1, 1, 1.1]})
    styles = {"table1/none": ("C0", "-"), "table1/square": ("C0", "--"), "bonded/none": ("C1", "-"),
              "bonded/square": ("C1", "--")}
    for ax, what, title in ((axes[0], "person_object", "person or object"),
                            (axes[1], "material", f"material class ({len(CLASSES)})")):
        for key, s in summary["configs"].items():
            taus = [float(k) for k in s["accuracy_vs_time"]]
            acc = [100 * v[what] for v in s["accuracy_vs_time"].values()]
            c, ls = styles.get(key, ("k", ":"))
            ax.plot(taus, acc, color=c, ls=ls, marker="o", ms=3, label=key)
        if what == "material":
            ax.plot(list(ANCHORS), [100 * v for v in ANCHORS.values()], "k*", ms=10,
                    label="Bhattacharjee et al. 2015\n(11 materials, heated sensor)")
        else:
            ax.axhline(95, color="k", lw=0.8, ls=":", label="target 95 % at 1.5 s")
        ax.set_title(title)
        ax.set_xlabel("time since onset (s)")
        ax.grid(alpha=0.3)
        ax.set_ylim(0, 102)
        ax.legend(loc="lower right", fontsize=7)
    axes[0].set_ylabel("correct (% of detected contacts)")
    key0 = next(iter(summary["configs"]))
    conf = summary["configs"][key0]["confusion_1.5"]
    rows = [c for c in CLASSES if c in conf]
    m = np.array([[conf[r].get(c, 0) for c in CLASSES] for r in rows], dtype=float)
    share = m / np.maximum(m.sum(axis=1, keepdims=True), 1)
    ax = axes[2]
    ax.imshow(share, cmap="Blues", vmin=0, vmax=1, aspect="auto")
    for i in range(len(rows)):
        for j in range(len(CLASSES)):
            if m[i, j]:
                ax.text(j, i, f"{int(m[i, j])}", ha="center", va="center",
                        color="white" if share[i, j] > 0.6 else "black", fontsize=8)
    ax.set_xticks(range(len(CLASSES)), CLASSES, rotation=35, ha="right", fontsize=8)
    ax.set_yticks(range(len(rows)), rows, fontsize=8)
    ax.set_xlabel("called at 1.5 s")
    ax.set_ylabel("true class")
    ax.set_title(f"confusion at 1.5 s ({key0})")
    fig.suptitle(f"What touched the skin: held-out seeds {summary['seeds'][0]}-{summary['seeds'][1]}, "
                 "closed loop (skin/probe)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=12)
    ap.add_argument("--seed0", type=int, default=SEED0)
    ap.add_argument("--duration", type=float, default=300.0)
    ap.add_argument("--skins", default=",".join(SKINS))
    ap.add_argument("--probes", default=",".join(PROBES))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--figure", default=None, help="Write the figure (PNG) here.")
    ap.add_argument("--from-json", default=None,
                    help="Draw --figure from this benchmark's saved JSON output instead of running.")
    a = ap.parse_args()
    if a.from_json:
        with open(a.from_json) as fh:
            figure(json.load(fh), a.figure or "docs/img/characterise.png")
        return
    wall0 = time.perf_counter()
    jobs = [(a.seed0 + i, skin, probe, a.duration) for skin in a.skins.split(",")
            for probe in a.probes.split(",") for i in range(a.seeds)]
    with ProcessPoolExecutor(a.workers) as pool:
        runs = list(pool.map(run_one, jobs))
    configs = {}
    for skin in a.skins.split(","):
        for probe in a.probes.split(","):
            configs[f"{skin}/{probe}"] = summarise([r for r in runs if r["skin"] == skin
                                                    and r["probe"] == probe])
    summary = {"seeds": [a.seed0, a.seed0 + a.seeds - 1], "duration_s": a.duration, "taus_s": TAUS,
               "configs": configs, "wall_s": time.perf_counter() - wall0,
               "anchors": {f"{k:g}": v for k, v in ANCHORS.items()}}
    if a.figure:
        figure(summary, a.figure)
    if not a.json:
        for key, s in configs.items():
            c = s["accuracy_vs_time"]
            print(f"{key:14s} detected {s['detected']}/{s['touches']} FA {s['false_alarms']} | person/object "
                  + " ".join(f"{k}:{100 * v['person_object']:.0f}" for k, v in c.items())
                  + " | material " + " ".join(f"{k}:{100 * v['material']:.0f}" for k, v in c.items()),
                  file=sys.stderr)
    print(json.dumps(summary, default=float))


if __name__ == "__main__":
    main()
