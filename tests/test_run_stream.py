"""`thermoskin run` and `simulate` in memory that does not grow with the run: the plant's
windowed profiles, the loop's blocks, and the run's report gathered block by block
(RunDigest: the plot's envelope, each command's tracking, what touched)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from thermoskin.analysis.evaluation import TrackingStream, tracking_errors
from thermoskin.params import Config
from thermoskin.plots.digest import PlotDigest, TrailingMean
from thermoskin.plots.log import _moving_mean, plot_log
from thermoskin.runtime.closed_loop import run_closed_loop
from thermoskin.runtime.digest import RunDigest
from thermoskin.sim.scenarios import SCENARIOS
from thermoskin.touch.characterise import characterise_events

CFG = Config()


def _cuts(n: int, rng: np.random.Generator, most: int = 700) -> list[slice]:
    edges = np.unique(np.concatenate(([0, n], rng.integers(1, n, size=max(1, n // most)))))
    return [slice(int(a), int(b)) for a, b in itertools.pairwise(edges)]


# ----------------------------------------------------------------------------- tracking
def _setpoint_log(rng: np.random.Generator) -> dict[str, np.ndarray]:
    t = np.arange(0, 250_000) * 1e-3
    cmd = np.where(t < 70.0, 24.0, np.where(t < 100.0, 26.0, 28.0))
    T_w = cmd + 0.01 * rng.standard_normal(t.size) + np.where(t < 70.0, 0.05, -0.02)
    T_w[rng.integers(0, t.size, 300)] = np.nan
    return {"t": t, "T_w": T_w, "T_w_cmd": cmd, "T_p_cmd": cmd + 2.0 + np.sin(t)}


def test_tracking_by_hand_and_in_any_chunks() -> None:
    """Three commands: 70 s and 30 s (errors over the last half of each: shorter than the
    last 60 s), 150 s (its last 60 s): the means by hand over those windows (NaNs left out),
    T_p_cmd's range over the whole segment; fed in ragged chunks (cut inside and at the command
    changes) the same numbers, bit for bit, as the whole log in one."""
    log = _setpoint_log(np.random.default_rng(3))
    segs = tracking_errors(log)
    t, e = log["t"], log["T_w"] - log["T_w_cmd"]
    for seg, (a, b, lo) in zip(segs, [(0.0, 70.0, 34.9995), (70.0, 100.0, 84.9995),
                                        (100.0, 250.0, 189.999)], strict=True):
        w = (t >= lo) & (t < b) & np.isfinite(e)
        assert seg.mean_error == pytest.approx(float(np.mean(e[w])), rel=1e-9)
        assert seg.mean_abs_error == pytest.approx(float(np.mean(np.abs(e[w]))), rel=1e-9)
        in_seg = (t >= a) & (t < b)
        assert seg.T_p_cmd_min == np.min(log["T_p_cmd"][in_seg])
        assert seg.T_p_cmd_max == np.max(log["T_p_cmd"][in_seg])
    assert [s.T_w_cmd for s in segs] == [24.0, 26.0, 28.0]
    rng = np.random.default_rng(5)
    cuts = _cuts(len(t), rng, 20_000)
    for extra in ([slice(0, 70_000), slice(70_000, 250_000)], cuts):
        ts = TrackingStream()
        for c in extra:
            ts.feed(log["t"][c], log["T_w"][c], log["T_w_cmd"][c], log["T_p_cmd"][c])
        assert ts.finish() == segs


# ----------------------------------------------------------------------------- plot digest
def test_trailing_mean_in_chunks_is_the_plots_moving_mean() -> None:
    rng = np.random.default_rng(8)
    y = rng.standard_normal(20_000)
    y[rng.integers(0, y.size, 500)] = np.nan
    y[3000:3400] = np.nan  # longer than the window: NaN there
    t = np.arange(y.size) * 1e-3
    want = _moving_mean(t, y, 0.1)
    for most in (300, 20):  # chunks longer and shorter than the window (a fixed-rate loop's)
        tm = TrailingMean(100)
        got = np.concatenate([tm(y[c]) for c in _cuts(y.size, rng, most)])
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
        assert np.isnan(got[3200]) and np.isnan(want[3200])


def test_plot_digest_keeps_a_short_run_whole_and_a_long_runs_exact_envelope() -> None:
    """Up to ``rows`` rows, every row as fed (the plot is the whole log's). Beyond, each pair of
    rows is a range of contiguous samples: its first and last ``t``, and each column's minimum and
    maximum over exactly those samples in time order; the ranges cover every sample once; the
    rows stay within ``rows`` however long the run."""
    rng = np.random.default_rng(11)
    n = 100_003
    t = np.arange(n) * 1e-3
    cols = {"t": t, "T_w": np.cumsum(rng.standard_normal(n)) * 0.01,
            "q_i_hat": rng.standard_normal(n), "contact": (np.sin(t / 3) > 0.8).astype(np.int8),
            "v": np.where(np.sin(t) > 0, 0.141, 0.0)}
    cols["T_w"][rng.integers(0, n, 1000)] = np.nan
    cols["T_w"][50_000:51_000] = np.nan
    short = PlotDigest(1e-3, rows=n)
    for c in _cuts(n, rng):
        short.feed({k: x[c] for k, x in cols.items()})
    whole = short.columns()
    assert set(whole) == set(cols) and all(np.array_equal(whole[k], cols[k], equal_nan=True) for k in cols)

    d = PlotDigest(1e-3, rows=1000)
    for c in _cuts(n, rng):
        d.feed({k: x[c] for k, x in cols.items()})
        assert d.rows <= 1000 + d.span
    out = d.columns()
    assert 250 < len(out["t"]) <= 1000 + 2
    idx = np.searchsorted(t, out["t"])
    starts, ends = idx[0::2], idx[1::2]
    assert starts[0] == 0 and ends[-1] == n - 1 and np.array_equal(starts[1:], ends[:-1] + 1)
    means = {"q_i_hat_mean": _moving_mean(t, cols["q_i_hat"], 0.1), "v_mean": _moving_mean(t, cols["v"], 1.0)}
    for k, x in {**cols, **means}.items():
        if k == "t":
            continue
        for r, (a, b) in enumerate(zip(starts, ends, strict=True)):
            seg = np.asarray(x[a:b + 1], dtype=float)
            pair = out[k][2 * r:2 * r + 2]
            if np.isnan(seg).all():
                assert np.isnan(pair).all(), (k, r)
                continue
            lo, hi = np.nanmin(seg), np.nanmax(seg)
            np.testing.assert_allclose(sorted(pair), [lo, hi], rtol=0, atol=1e-9, err_msg=f"{k} {r}")
            near = np.isclose(seg, lo, rtol=0, atol=1e-9) | np.isclose(seg, hi, rtol=0, atol=1e-9)
            first = np.flatnonzero(near)
            assert abs(seg[first[0]] - pair[0]) <= 1e-9 or lo == hi, (k, r)  # time order
    assert np.nanmax(out["T_w"]) == np.nanmax(cols["T_w"]) and np.nanmin(out["T_w"]) == np.nanmin(cols["T_w"])


def test_a_long_runs_digest_draws(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """plot_log takes a digest holding ranges (its means given, not computed)."""
    c = run_closed_loop(SCENARIOS["mixed"].with_duration(12.0), CFG).columns
    d = PlotDigest(CFG.sampling.t_s, rows=2000)
    for i in range(0, len(c["t"]), 1000):
        d.feed({k: x[i:i + 1000] for k, x in c.items()})
    cols = d.columns()
    assert d.span > 1 and "q_i_hat_mean" in cols and "v_mean" in cols
    assert plot_log(cols, tmp_path / "p.png").stat().st_size > 10_000


# ----------------------------------------------------------------------------- run digest
def _blocks(cols: dict[str, np.ndarray], rng: np.random.Generator) -> list[dict[str, np.ndarray]]:
    return [{k: x[c] for k, x in cols.items()} for c in _cuts(len(cols["t"]), rng, 1500)]


def test_run_digest_is_the_whole_logs_report() -> None:
    """A closed-loop run of touchers fed to a RunDigest block by block, each event told as the
    loop ends it: the events characterised as characterise_events does on the whole log, the
    tracking as tracking_errors, the rows and last t; and the loop's blocks (keep=False) are the
    kept run's columns."""
    sc = SCENARIOS["touchers"].with_duration(60.0)
    digest = RunDigest(CFG)
    blocks: list[dict[str, np.ndarray]] = []

    def on_block(b: dict[str, np.ndarray]) -> None:
        blocks.append(b)
        digest.feed(b)

    res = run_closed_loop(sc, CFG, on_block=on_block, on_event=digest.event, keep=False)
    assert res.columns == {} and res.summary["rows"] == 60_000
    kept = run_closed_loop(sc, CFG).columns
    for k, x in kept.items():
        assert np.array_equal(np.concatenate([b[k] for b in blocks]), x, equal_nan=True), k
    events = digest.events(res.events)
    want = characterise_events(res.events, kept, CFG)
    assert len(events) >= 3 and events == want
    assert any(e.toucher for e in events)  # what touched is told
    assert digest.tracking_errors() == tracking_errors(kept)
    assert digest.rows == 60_000 and digest.t_last == kept["t"][-1]


def test_a_contact_early_in_a_long_run_is_still_characterised() -> None:
    """The characteriser holds only its last minutes of binned signals: fed a run seven minutes
    long whole, it had dropped the bins of the first minute's contacts (what `run` did when it
    read its log back at the end). The digest characterises each contact as its samples come
    in, and characterise_events feeds the log up to each contact's window: both tell the early
    contacts as the first minute alone tells them."""
    from thermoskin.touch.characterise import Characteriser

    c = run_closed_loop(SCENARIOS["touchers"].with_duration(40.0), CFG).columns
    res_events: list = []
    run_closed_loop(SCENARIOS["touchers"].with_duration(40.0), CFG, on_event=res_events.append)
    quiet = 420.0  # then seven minutes without a touch (steady readings)
    n = int(quiet / CFG.sampling.t_s)
    tail = {k: np.full(n, x[-1]) for k, x in c.items()}
    tail["t"] = c["t"][-1] + CFG.sampling.t_s * np.arange(1, n + 1)
    tail["dq_i_hat"] = np.zeros(n)
    long = {k: np.concatenate((c[k], tail[k])) for k in c}
    d = RunDigest(CFG)
    for e_i, b in enumerate(_blocks(long, np.random.default_rng(2))):
        d.feed(b)
        if e_i == 40:
            for e in res_events:
                d.event(e)
    got = d.events(res_events)
    short = characterise_events(res_events, c, CFG)
    assert got == short and any(e.toucher for e in got)
    assert characterise_events(res_events, long, CFG) == short
    whole = Characteriser(CFG)  # the log fed whole, then each contact: nothing left of them
    whole.feed(long["t"], long["dq_i_hat"], long["T_w"], long["T_a"])
    whole.finish()
    assert [whole.annotate(e) for e in res_events] != short


# ----------------------------------------------------------------------------- memory
@pytest.mark.parametrize("what", ["simulate", "run"])
def test_memory_does_not_grow_with_the_run(what: str, monkeypatch: pytest.MonkeyPatch,
                                           peak_memory) -> None:  # type: ignore[no-untyped-def]
    """Python's peak allocation for a run twice as long is the same (within 10 %): the plant
    holds a window of its profiles (about 250 bytes a sample when it held them whole), the loop
    its current block, the digest its bounded rows."""
    import thermoskin.plots.digest as pd
    import thermoskin.sim.plant as plant_mod
    from thermoskin.sim.run import simulate_blocks

    monkeypatch.setattr(plant_mod, "WINDOW", 2048)
    monkeypatch.setattr(pd, "ROWS", 4000)
    sc = SCENARIOS["realistic"]

    def go(d: float) -> None:
        if what == "simulate":
            for _ in simulate_blocks(sc, CFG, d, block=2048):
                pass
        else:
            dg = RunDigest(CFG)
            run_closed_loop(sc.with_duration(d), CFG, on_block=dg.feed, on_event=dg.event, keep=False)
            dg.events([])
            dg.columns()  # what run draws

    go(2.0)  # imports and compiled kernels first
    # (10 s more of profiles held whole would be 2.5 MB over a peak of about 13 MB)
    p1, p2 = peak_memory(lambda: go(10.0)), peak_memory(lambda: go(20.0))
    assert p2 < 1.1 * p1, (p1, p2)


def test_timing_histogram_quantiles_are_numpys_within_its_bins() -> None:
    """The fixed-rate loop's timing without its rows: p50/p99 within 0.15 % of numpy's percentile
    of the same samples (1000 bins a decade, negative values too), the maximum exact, NaNs left
    out, magnitudes of 0.1 µs and below read as 0."""
    from thermoskin.runtime.realtime import _I, NF, TimingHistogram

    rng = np.random.default_rng(4)
    n = 200_000
    rows = np.full((n, NF), np.nan)
    rows[:, _I["late"]] = rng.lognormal(np.log(60e-6), 0.8, n)
    rows[:, _I["lag"]] = np.where(rng.random(n) < 0.3, -1e-6, rng.lognormal(np.log(5e-6), 1.0, n))
    rows[:, _I["busy"]] = rng.lognormal(np.log(20e-6), 0.3, n)
    rows[rng.integers(0, n, 50), _I["busy"]] = np.nan
    h = TimingHistogram()
    for c in _cuts(n, rng, 5000):
        h.add(rows[c])
    fig = h.figures()
    assert h.rows == n
    for k in ("late", "lag", "busy"):
        x = rows[:, _I[k]]
        x = x[np.isfinite(x)] * 1e6
        assert fig[f"{k}_max_us"] == x.max()
        for q in (50, 99):
            want = float(np.percentile(x, q))
            assert fig[f"{k}_p{q}_us"] == pytest.approx(want, rel=1.5e-3), (k, q)
    assert h.quantile("lag", 0.2) == pytest.approx(-1e-6, rel=1.5e-3)  # the 30 % at -1 µs
    z = TimingHistogram()  # a lateness of zero, and below 0.1 µs either side: read as 0
    rows = np.full((3, NF), np.nan)
    rows[:, _I["late"]] = [0.0, 5e-8, -5e-8]
    z.add(rows)
    assert z.quantile("late", 0.5) == 0.0
