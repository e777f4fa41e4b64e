"""The sweep: the batched rows equal the one-point paths, the QP equals daqp, the sweep file's
points and errors, Parquet rows written as chunks finish, resume after a kill, Dask, the plot."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner

from thermoskin.analysis.evaluation import match_events
from thermoskin.analysis.observe import observe
from thermoskin.cli import main
from thermoskin.control.mpc import Mpc
from thermoskin.params import load_config
from thermoskin.physics.peltier import PeltierTank
from thermoskin.runtime.closed_loop import run_closed_loop
from thermoskin.sim.run import simulate
from thermoskin.sweep import qp
from thermoskin.sweep.engine import ScenarioSpec, build_scenario, run_chunk
from thermoskin.sweep.spec import load_sweep

ROOT = Path(__file__).resolve().parents[1]
SMALL = ROOT / "examples" / "sweep-small.toml"


def test_box_qp_equals_daqp() -> None:
    """The compiled active-set QP against daqp on the MPC's own QP (Table I, H = 100), over
    states where the bounds are active, inactive and in between."""
    cfg = load_config()
    m = Mpc(cfg.skin, cfg.control, cfg.sampling.t_s, v_on=cfg.pump.v_on)
    rng = np.random.default_rng(3)
    active = 0
    for _ in range(60):
        th = np.array([rng.uniform(19, 26), rng.uniform(18, 22), rng.uniform(22, 28), rng.uniform(7, 37)])
        ref = m.solve(*th[:3], th[3]).copy()
        u, rounds = qp.solve(m.P, m.F @ th, m.T_p_min, m.T_p_max)
        assert rounds > 0
        assert np.max(np.abs(u - ref)) < 1e-8
        active += int(np.any((ref >= m.T_p_max - 1e-9) | (ref <= m.T_p_min + 1e-9)))
    assert 5 < active < 60  # both kinds of QP were tried


def _reference_metrics(cols: dict[str, np.ndarray], events: list, sc, spec: ScenarioSpec,
                       t_s: float) -> dict[str, float]:
    """The metrics from a one-point log, computed from its columns (engine's module doc)."""
    t = cols["t"]
    after = t >= spec.settle
    e = cols["T_w_true"][after] - cols["T_w_cmd"][after]
    m = match_events(sc.touches, events, late=spec.late, t_end=len(t) * t_s)
    on = np.asarray(cols["contact_true"]) > 0
    # quiet: no contact now nor within the last 3 s, counted by a plain loop
    quiet = np.zeros(len(t), bool)
    last = -math.inf
    for k in range(len(t)):
        if on[k]:
            last = t[k]
        quiet[k] = (not on[k]) and (t[k] - last > 3.0 + 1e-9)
    one = on & (np.asarray(cols["n_fingers"]) == 1) & after
    q = cols["dq_i_hat"][quiet & after]
    snr = (cols["dq_i_hat"][one].mean() - q.mean()) / q.std() if one.any() else math.nan
    hours = after.sum() * t_s / 3600.0  # the time watched for false alarms, in hours
    lat = sorted(m.latencies)
    # the 90th percentile between order statistics (numpy's default, written out)
    pos = 0.9 * (len(lat) - 1)
    lo, hi = int(pos), min(int(pos) + 1, len(lat) - 1)
    p90 = lat[lo] + (pos - lo) * (lat[hi] - lat[lo]) if lat else math.nan
    return {"tracking_rms_K": float(np.sqrt(np.mean(e * e))), "hits": m.hits, "misses": m.misses,
            "false_alarms": m.false_alarms, "false_alarms_per_h": m.false_alarms / hours,
            "latency_p90_s": float(p90),
            "latency_median_s": float(np.median(m.latencies)) if m.hits else math.nan,
            "snr_one_finger": float(snr), "observed_s": float(after.sum() * t_s)}


def _close(a: float, b: float, rel: float) -> bool:
    return (math.isnan(a) and math.isnan(b)) or abs(a - b) <= rel * max(1.0, abs(b))


def test_batch_equals_closed_loop(monkeypatch: pytest.MonkeyPatch) -> None:
    """Two closed-loop points (different skins and seeds) as rows of one batch against
    ``run_closed_loop`` per point: the same contacts, and every metric within 1e-7 (the
    box QP's rounding against daqp's is all that differs)."""
    spec = ScenarioSpec(duration=25.0, settle=8.0)
    base = load_config()
    points = [(base.replace(sensor={"seed": 4}), 4),
              (base.replace(skin={"R_g": 12.0}, detector={"h_on": 5.0}, sensor={"seed": 7}), 7)]
    got = run_chunk(points, spec)
    energy = [0.0]
    step = PeltierTank.step

    def counting(self, drive, T_a, q_out=0.0):  # type: ignore[no-untyped-def]
        step(self, drive, T_a, q_out)
        energy[0] += self.P_elec * self.t_s

    monkeypatch.setattr(PeltierTank, "step", counting)
    for (cfg, seed), row in zip(points, got, strict=True):
        energy[0] = 0.0
        sc = build_scenario(spec, seed)
        res = run_closed_loop(sc, cfg)
        ref = _reference_metrics(res.columns, res.events, sc, spec, cfg.sampling.t_s)
        assert row["touches"] == len(sc.touches) >= 1
        for k in ("hits", "misses", "false_alarms"):
            assert row[k] == ref[k], k
        for k in ("tracking_rms_K", "latency_median_s", "latency_p90_s", "observed_s",
                  "false_alarms_per_h"):
            assert _close(row[k], ref[k], 1e-7), (k, row[k], ref[k])
        # the SNR's spread of dq_i_hat over quiet stretches: what the estimator learns of the
        # sensors (its variances' median trackers, a step each reading) can step otherwise for
        # the QP's rounding of a command, within 2 % here
        assert _close(row["snr_one_finger"], ref["snr_one_finger"], 2e-2), (row, ref)
        assert _close(row["energy_J"], energy[0], 1e-7)
        assert row["detection_rate"] == ref["hits"] / (ref["hits"] + ref["misses"])


def test_metrics_from_hand_numbers() -> None:
    """:func:`score` on touches and contacts laid out by hand: 10 touches (one more after the run's
    end, not scored), 8 of them detected (latencies 0.1 to 0.8 s), one detected 0.7 s after its
    touch's end (outside ``late`` = 0.5 s: a miss and a false alarm), 3 more contacts; watched
    1 800 000 samples of 1 ms (half an hour): 8 false alarms an hour, detection 0.8, latency median
    0.45 s and 90th percentile 0.73 s (0.7 + 0.3 of the way to 0.8: numpy's linear rule, position
    0.9 x 7 = 6.3); the one-finger SNR from the kernel's sums (mean 0.5 over 4 samples, quiet mean
    0.3 and variance 0.02 over 5: 0.2 / sqrt(0.02)); every key, and no warning."""
    import warnings
    from types import SimpleNamespace

    from thermoskin.estimation.events import ContactEvent
    from thermoskin.physics.finger import Touch
    from thermoskin.sweep import kernel as SK  # noqa: N812
    from thermoskin.sweep.engine import EXTRA, METRICS, score

    touches = [Touch(t_on=10.0 * k, duration=1.0, n_fingers=1) for k in range(1, 11)]
    touches.append(Touch(t_on=210.0, duration=1.0, n_fingers=1))  # after t_end = 200 s
    lat = [0.1 * (k + 1) for k in range(8)]
    on = [10.0 * (k + 1) for k in range(8)]
    events = [ContactEvent(on[k], on[k] + lat[k], on[k] + 1.2, 1.2, 1, 0.5, 0.3, 0.36) for k in range(8)]
    events.append(ContactEvent(90.0, 91.7, 92.0, 2.0, 1, 0.5, 0.3, 0.6))  # 0.7 s after the 9th's end
    events += [ContactEvent(t, t + 0.1, t + 0.5, 0.5, 1, 0.2, 0.1, 0.05) for t in (5.0, 103.0, 150.0)]
    res = np.zeros(SK.NR)
    res[SK.R_NARMED] = 1_800_000
    res[SK.R_SSE], res[SK.R_NTRACK] = 0.09 * 400, 400  # rms 0.3 K
    res[SK.R_SUM1], res[SK.R_N1] = 2.0, 4
    res[SK.R_SUMQ], res[SK.R_SUMQ2], res[SK.R_NQ] = 1.5, 0.55, 5  # 0.1 .. 0.5
    res[SK.R_ENERGY], res[SK.R_QPS] = 12.5, 7
    spec = ScenarioSpec(late=0.5)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        row = score(SimpleNamespace(touches=touches), events, res, spec, 200.0, 1e-3)
        assert set(row) == set(METRICS) | set(EXTRA)
        assert (row["touches"], row["hits"], row["misses"], row["false_alarms"]) == (11, 8, 2, 4)
        assert row["detection_rate"] == pytest.approx(0.8)
        assert row["false_alarms_per_h"] == pytest.approx(8.0, rel=1e-12)
        assert row["observed_s"] == pytest.approx(1800.0)
        assert row["latency_median_s"] == pytest.approx(0.45, abs=1e-12)
        assert row["latency_p90_s"] == pytest.approx(0.73, abs=1e-12)
        assert row["tracking_rms_K"] == pytest.approx(0.3, rel=1e-12)
        assert row["snr_one_finger"] == pytest.approx(0.2 / math.sqrt(0.02), rel=1e-9)
        assert row["energy_J"] == 12.5 and row["qp_solves"] == 7 and isinstance(row["qp_solves"], int)
        # the edges: one sample of contact and two quiet ones are enough; fewer, or no spread, no SNR
        for n1, nq, sq2, ok in ((1, 2, 0.26, True), (0, 5, 0.55, False), (4, 1, 0.09, False),
                                (4, 5, 0.45, False)):
            r = res.copy()
            r[SK.R_N1], r[SK.R_SUM1] = n1, 0.5 * n1
            r[SK.R_NQ], r[SK.R_SUMQ], r[SK.R_SUMQ2] = nq, 0.3 * nq, sq2
            snr = score(SimpleNamespace(touches=touches), events, r, spec, 200.0, 1e-3)["snr_one_finger"]
            assert math.isfinite(snr) == ok, (n1, nq, sq2, snr)
        # nothing to measure: NaN, never a division by zero
        none = score(SimpleNamespace(touches=[]), [], np.zeros(SK.NR), spec, 200.0, 1e-3)
        for k in ("detection_rate", "false_alarms_per_h", "latency_median_s", "latency_p90_s",
                  "snr_one_finger", "tracking_rms_K"):
            assert math.isnan(none[k]), k
        unwatched = res.copy()
        unwatched[SK.R_NARMED] = 0
        assert math.isnan(score(SimpleNamespace(touches=touches), events, unwatched, spec, 200.0,
                                1e-3)["false_alarms_per_h"])


def test_batch_equals_open_loop() -> None:
    """An open-loop point against ``simulate`` then ``observe`` of its log."""
    spec = ScenarioSpec(loop="open", duration=20.0, settle=5.0)
    cfg = load_config().replace(skin={"C_g": 0.06}, sensor={"seed": 3})
    (row,) = run_chunk([(cfg, 3)], spec)
    sc = build_scenario(spec, 3)
    log = simulate(sc, cfg)
    obs = observe(log, cfg)
    cols = {**log, **obs.columns}
    ref = _reference_metrics(cols, obs.events, sc, spec, cfg.sampling.t_s)
    for k in ("hits", "misses", "false_alarms"):
        assert row[k] == ref[k]
    for k in ("tracking_rms_K", "latency_median_s", "snr_one_finger"):
        assert _close(row[k], ref[k], 1e-9), (k, row[k], ref[k])
    assert math.isnan(row["energy_J"])


def test_rows_do_not_depend_on_their_chunk() -> None:
    """A point alone and among others: the same numbers (what makes Dask's rows the local ones)."""
    spec = ScenarioSpec(duration=12.0, settle=5.0, touches="one-finger")
    base = load_config()
    pts = [(base.replace(skin={"R_g": r}), s) for r, s in ((9.0, 1), (11.0, 2), (10.0, 3))]
    together = run_chunk(pts, spec)
    alone = run_chunk([pts[1]], spec)
    assert _same_rows([together[1]], [alone[0]])


def test_points_of_the_samplers(tmp_path: Path) -> None:
    """Grid: every combination; LHS: one point in each of n strata per key; random: in range."""
    sw = load_sweep(SMALL)
    assert len(sw.points) == 2 * 3 * 2
    assert {(p.values["skin.R_g"], p.values["detector.h_on"], p.seed) for p in sw.points} == {
        (r, h, s) for r in (8.0, 12.0) for h in (4.0, 6.0, 8.0) for s in (0, 1)}
    assert len({p.hash for p in sw.points}) == len(sw.points)
    f = tmp_path / "lhs.toml"
    f.write_text('[sweep]\nsampler = "lhs"\npoints = 40\n[keys]\n"skin.R_g" = {lo = 5.0, hi = 15.0}\n'
                 '"pump.v_on" = {lo = 0.05, hi = 0.5, log = true}\n')
    sw = load_sweep(f)
    r = np.array([p.values["skin.R_g"] for p in sw.points])
    v = np.array([p.values["pump.v_on"] for p in sw.points])
    assert sorted(np.floor((r - 5.0) / 10.0 * 40).astype(int)) == list(range(40))
    assert sorted(np.floor(np.log(v / 0.05) / np.log(10.0) * 40).astype(int)) == list(range(40))
    assert all(p.cfg.skin.R_g == p.values["skin.R_g"] for p in sw.points)
    f.write_text('[sweep]\nsampler = "random"\npoints = 30\nseeds = [5]\n[keys]\n'
                 '"patch.length" = {lo = 0.02, hi = 0.06}\n')
    sw = load_sweep(f)
    base = load_config()
    for p in sw.points:
        L = p.values["patch.length"]
        assert 0.02 <= L < 0.06 and p.seed == 5 and p.cfg.sensor.seed == 5
        assert p.cfg.skin.C_w == pytest.approx(base.skin.C_w * L / 0.03, rel=1e-12)
        assert p.cfg.skin.R_g == pytest.approx(base.skin.R_g * 0.03 / L, rel=1e-12)


@pytest.mark.parametrize("body, what", [
    ('[keys]\n"skin.R_x" = [1.0]\n', "keys.skin.R_x: unknown key"),
    ('[keys]\n"skin.R_g" = [-1.0]\n', "skin.R_g"),
    ('[keys]\n"skin.R_g" = {lo = 2.0, hi = 1.0, n = 2}\n', "lo = 2 must be below"),
    ('[keys]\n"skin.R_g" = {lo = 1.0, hi = 2.0}\n', "needs n"),
    ('[scenario]\nloop = "sideways"\n', "scenario.loop"),
    ('[scenario]\nduration = -5\n', "scenario.duration"),
    ('[scenario]\ntouches = "nobody"\n', "scenario.touches"),
    ('[sweep]\nsampler = "sobol"\n', "sweep.sampler"),
    ('[sweep]\nmetrics = ["speed"]\n', "unknown metric"),
    ('[sweep]\nseeds = [1, 1]\n', "sweep.seeds"),
    ("[sweep\n", "not valid TOML"),
])
def test_bad_sweep_one_line_exit_2(tmp_path: Path, body: str, what: str) -> None:
    f = tmp_path / "bad.toml"
    f.write_text(body)
    r = CliRunner().invoke(main, ["sweep", str(f), "-o", str(tmp_path / "r.parquet")])
    assert r.exit_code == 2, r.output
    lines = [x for x in r.output.splitlines() if x.strip()]
    assert len(lines) == 1 and what in lines[0] and "Traceback" not in r.output
    assert not (tmp_path / "r.parquet").exists()


def test_bad_output_and_plot_input(tmp_path: Path) -> None:
    r = CliRunner().invoke(main, ["sweep", str(SMALL), "-o", str(tmp_path / "r.csv")])
    assert r.exit_code == 2 and "must end in .parquet" in r.output
    r = CliRunner().invoke(main, ["sweep-plot", str(tmp_path / "none.parquet"),
                                  "-o", str(tmp_path / "p.png")])
    assert r.exit_code == 2 and "does not exist" in r.output


def _same_rows(a: list[dict], b: list[dict]) -> bool:
    """Equal rows, NaN equal to NaN (a metric with nothing to measure)."""
    def norm(r: dict) -> dict:
        return {k: ("nan" if isinstance(v, float) and math.isnan(v) else v) for k, v in r.items()}
    return [norm(r) for r in a] == [norm(r) for r in b]


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(ROOT / "src")}


def test_kill_and_resume(tmp_path: Path) -> None:
    """A real run SIGKILLed after its first parts: the rerun does only the rest, and the
    result has every point once, equal to a straight run's rows."""
    f = tmp_path / "s.toml"
    f.write_text(SMALL.read_text().replace("chunk = 4", "chunk = 2")
                 .replace("duration = 20.0", "duration = 14.0")
                 .replace("settle = 8.0", "settle = 6.0"))
    out = tmp_path / "r.parquet"
    cmd = [sys.executable, "-m", "thermoskin.cli", "sweep", str(f), "-o", str(out)]
    proc = subprocess.Popen(cmd, env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    parts = out.with_name(out.name + ".parts")
    t0 = time.monotonic()
    while time.monotonic() - t0 < 120:
        if parts.is_dir() and len(list(parts.glob("part-*.parquet"))) >= 1:
            break
        if proc.poll() is not None:
            break
        time.sleep(0.005)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert not out.exists(), "killed before the merge"
    n_parts = len(list(parts.glob("part-*.parquet")))
    # usually 1 to 5 of the 6 chunks; a fast machine may finish them all before the kill lands,
    # and then the rerun only merges them (still nothing redone)
    assert 1 <= n_parts <= 6
    r = subprocess.run(cmd, env=_env(), capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert f"{2 * n_parts} already done" in r.stdout or f"{12 - 2 * n_parts} run now" in r.stdout
    t = pq.read_table(out).to_pylist()
    assert [x["point"] for x in t] == list(range(12))
    assert not parts.exists()
    straight = tmp_path / "straight.parquet"
    r = CliRunner().invoke(main, ["sweep", str(f), "-o", str(straight)])
    assert r.exit_code == 0, r.output
    assert _same_rows(pq.read_table(straight).to_pylist(), t)
    r = CliRunner().invoke(main, ["sweep", str(f), "-o", str(straight)])
    assert "0 run now" in r.output and "12 already done" in r.output


def test_results_of_another_sweep_are_not_touched(tmp_path: Path) -> None:
    """An output holding other columns (another sweep, other metrics) is refused, kept as it was."""
    f = tmp_path / "s.toml"
    f.write_text(SMALL.read_text().replace("duration = 20.0", "duration = 10.0")
                 .replace("settle = 8.0", "settle = 4.0"))
    out = tmp_path / "r.parquet"
    assert CliRunner().invoke(main, ["sweep", str(f), "-o", str(out)]).exit_code == 0
    before = out.read_bytes()
    f.write_text(f.read_text().replace("chunk = 4", 'chunk = 4\nmetrics = ["tracking_rms_K"]'))
    r = CliRunner().invoke(main, ["sweep", str(f), "-o", str(out)])
    assert r.exit_code == 2 and "holds other columns" in r.output
    assert out.read_bytes() == before
    # the same columns, other points: its merge would have kept this sweep's points alone
    f.write_text(f.read_text().replace('\nmetrics = ["tracking_rms_K"]', "")
                 .replace('"skin.R_g" = [8.0, 12.0]', '"skin.R_g" = [9.0, 12.0]'))
    r = CliRunner().invoke(main, ["sweep", str(f), "-o", str(out)])
    assert r.exit_code == 2 and "holds 6 point(s) that are not in this sweep" in r.output, r.output
    assert len(r.output.strip().splitlines()) == 1
    assert out.read_bytes() == before


def test_dask_local_cluster_equals_local(tmp_path: Path) -> None:
    pytest.importorskip("dask.distributed",
                        reason="dask is an optional extra: pip install 'thermoskin[dask]'")
    f = tmp_path / "s.toml"
    f.write_text(SMALL.read_text().replace("duration = 20.0", "duration = 12.0")
                 .replace("settle = 8.0", "settle = 5.0"))
    a, b = tmp_path / "a.parquet", tmp_path / "b.parquet"
    r = CliRunner().invoke(main, ["sweep", str(f), "-o", str(a)])
    assert r.exit_code == 0, r.output
    r = subprocess.run([sys.executable, "-m", "thermoskin.cli", "sweep", str(f), "-o", str(b),
                        "--dask", "local"],
                       env=_env(), capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert _same_rows(pq.read_table(a).to_pylist(), pq.read_table(b).to_pylist())


def test_sweep_plot(tmp_path: Path) -> None:
    f = tmp_path / "s.toml"
    f.write_text(SMALL.read_text().replace("duration = 20.0", "duration = 10.0")
                 .replace("settle = 8.0", "settle = 4.0"))
    out = tmp_path / "r.parquet"
    assert CliRunner().invoke(main, ["sweep", str(f), "-o", str(out)]).exit_code == 0
    png = tmp_path / "p.png"
    r = CliRunner().invoke(main, ["sweep-plot", str(out), "-o", str(png), "--metric", "tracking_rms_K"])
    assert r.exit_code == 0, r.output
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    r = CliRunner().invoke(main, ["sweep-plot", str(out), "-o", str(png), "--metric", "speed"])
    assert r.exit_code == 2 and "--metric speed" in r.output


def test_sweep_plot_says_why_a_panel_is_empty(tmp_path: Path) -> None:
    """A metric with no value in any point (latencies where nothing was detected) drew an empty
    panel without a word: its panel now says why, and the command prints the same line."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from thermoskin.plots.sweep import plot_results

    n = 6
    cols = {"point": np.arange(n), "hash": [f"h{i}" for i in range(n)], "seed": np.zeros(n, dtype=np.int64),
            "pump.v_on": np.linspace(0.1, 0.2, n), "detection_rate": np.zeros(n),
            "latency_median_s": np.full(n, np.nan), "tracking_rms_K": np.linspace(0.04, 0.05, n)}
    res = tmp_path / "r.parquet"
    pq.write_table(pa.table(cols), res)
    png = tmp_path / "p.png"
    lines = plot_results(res, png, ["detection_rate", "latency_median_s", "tracking_rms_K"])
    assert lines == ["latency median, s: no value in any of the 6 points (no touch detected)"]
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    r = CliRunner().invoke(main, ["sweep-plot", str(res), "-o", str(png), "--metric", "latency_median_s"])
    assert r.exit_code == 0 and "no touch detected" in r.stderr, r.output
