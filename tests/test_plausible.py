"""Implausible samples are bad samples: one absurd value in a log or from the device is
dropped (held over, flagged `gap`), never fed to the filters; the contacts are those of the
clean log and every output outside the flagged rows is finite."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from thermoskin.analysis.observe import observe
from thermoskin.cli import main
from thermoskin.cli.run import SETTLE_S
from thermoskin.logio import write_log
from thermoskin.logio.plausible import admit, clean_log, limits
from thermoskin.params import Config, load_config
from thermoskin.runtime.closed_loop import COLUMNS, run_closed_loop
from thermoskin.sim.plant import SimulatedPlant
from thermoskin.sim.scenarios import SCENARIOS

CFG = load_config()
SC = SCENARIOS["mixed"].shifted(SETTLE_S).with_duration(36.0)  # 4 touches after the settling
K_BAD = 25_000  # a sample 25 s in, 2 s before a touch


@pytest.fixture(scope="module")
def run_log() -> dict[str, np.ndarray]:
    """The log `thermoskin run` writes (closed loop: drive and T_w_cmd included)."""
    res = run_closed_loop(SC, CFG)
    return {k: np.asarray(res.columns[k], dtype=float) for k in COLUMNS}


@pytest.fixture(scope="module")
def clean(run_log: dict[str, np.ndarray]):  # type: ignore[no-untyped-def]
    res = observe(run_log, CFG)
    assert len(res.events) == 4
    return res


def spans(events: list) -> np.ndarray:  # type: ignore[type-arg]
    return np.array([(e.onset, e.release) for e in events])


def test_admit_keeps_the_range_and_drops_the_rest() -> None:
    lim = limits(Config().plausible)  # -50 to 150 degC for the three readings
    assert admit(lim, 24.0, -50.0, 150.0) == (24.0, -50.0, 150.0)  # the bounds are plausible
    for bad in (150.0001, -50.0001, 1e30, -1e300, math.inf, -math.inf, math.nan):
        w, p, a = admit(lim, bad, bad, bad)
        assert math.isnan(w) and math.isnan(p) and math.isnan(a), bad


#: Limits that differ for every column and bound (a mix-up of two of them shows).
DISTINCT = {"T_w_min": -10.0, "T_w_max": 60.0, "T_p_min": 0.0, "T_p_max": 80.0, "T_a_min": -20.0,
            "T_a_max": 45.0, "v_min": 0.01, "v_max": 2.0, "drive_min": -0.9, "drive_max": 0.8}


@pytest.mark.parametrize("col", ["T_w", "T_p", "T_a"])
def test_every_bound_is_inside_and_the_next_double_outside(col: str) -> None:
    """Each reading exactly at its own lower and upper bound is kept, the next double beyond is
    dropped, on the loop's path (admit, admit_arrays) and the log's (clean_log): the bounds are
    closed, on every channel and side (issue 46: ``<`` for ``<=`` at the upper bound survived)."""
    from thermoskin.logio.plausible import admit_arrays

    cfg = Config().replace(plausible=DISTINCT)
    lim = limits(cfg.plausible)
    j = ("T_w", "T_p", "T_a").index(col)
    lo, hi = DISTINCT[f"{col}_min"], DISTINCT[f"{col}_max"]
    mid = [20.0, 30.0, 20.0]  # plausible for every channel
    for value, kept in ((lo, True), (hi, True), (np.nextafter(lo, -np.inf), False),
                        (np.nextafter(hi, np.inf), False)):
        x = list(mid)
        x[j] = value
        got = admit(lim, *x)
        assert (got[j] == value) if kept else math.isnan(got[j]), (col, value)
        assert [g for k, g in enumerate(got) if k != j] == [m for k, m in enumerate(mid) if k != j]
        arr = admit_arrays(lim, *(np.array([v]) for v in x))
        assert (arr[j][0] == value) if kept else math.isnan(arr[j][0])
        log = {"t": np.array([0.0]),
               **{k: np.array([v]) for k, v in zip(("T_w", "T_p", "T_a"), x, strict=True)}}
        c = clean_log(log, cfg)
        assert (c.columns[col][0] == value) if kept else math.isnan(c.columns[col][0])
        assert c.counts == ({} if kept else {col: 1})


@pytest.mark.parametrize("col", ["v", "drive"])
def test_velocity_and_drive_bounds_are_closed(col: str) -> None:
    cfg = Config().replace(plausible=DISTINCT)
    lo, hi = DISTINCT[f"{col}_min"], DISTINCT[f"{col}_max"]
    x = np.array([lo, hi, np.nextafter(lo, -np.inf), np.nextafter(hi, np.inf), 0.5 * (lo + hi)])
    c = clean_log({"t": np.arange(5) * 1e-3, col: x}, cfg)
    np.testing.assert_array_equal(c.columns[col], [lo, hi, np.nan, np.nan, 0.5 * (lo + hi)])
    assert c.counts == {col: 2} and c.first == {col: 2e-3}
    np.testing.assert_array_equal(c.rejected, [0, 0, 1, 1, 0])


def test_hold_takes_the_last_plausible_command_and_the_first_before_it() -> None:
    """The command held over implausible values: the last one before that was plausible or NaN (a
    NaN command is an unknown one: what follows it stays unknown), not the first of the log; the
    first plausible one for those before it; all NaN where none is plausible."""
    cfg = Config()
    t = np.arange(7) * 1e-3
    cmd = np.array([999.0, 22.0, 24.0, 999.0, np.nan, 999.0, 26.0])
    c = clean_log({"t": t, "T_w_cmd": cmd}, cfg)
    np.testing.assert_array_equal(c.columns["T_w_cmd"], [22.0, 22.0, 24.0, 24.0, np.nan, np.nan, 26.0])
    c = clean_log({"t": t[:3], "T_w_cmd": np.array([999.0, -999.0, 1e9])}, cfg)
    assert np.isnan(c.columns["T_w_cmd"]).all() and c.counts == {"T_w_cmd": 3}
    c = clean_log({"t": t[:4], "T_w_cmd": np.array([23.0, 999.0, 999.0, 25.0])}, cfg)  # the first plausible
    np.testing.assert_array_equal(c.columns["T_w_cmd"], [23.0, 23.0, 23.0, 25.0])


@pytest.mark.parametrize("col", ["T_w", "T_p", "T_a", "v"])
def test_a_measured_column_with_no_plausible_value_is_named(col: str) -> None:
    """Each measured column with no plausible value at all is named (its own line); a command or a
    drive with none is not a measured column."""
    n = 4
    log = {"t": np.arange(n) * 1e-3, "T_w": np.full(n, 24.0), "T_p": np.full(n, 25.0),
           "T_a": np.full(n, 20.0), "v": np.full(n, 0.1), "T_w_cmd": np.full(n, 999.0),
           "drive": np.full(n, 5.0)}
    log[col] = np.array([np.nan, 1e9, np.nan, -1e9])
    c = clean_log(log, Config())
    assert c.no_valid == [col]
    assert c.warnings(Config())[-1] == (f"column {col} has no valid sample (all NaN or implausible): every "
                                        "row is a gap; no estimate and no contact can come from this log")


def test_warnings_say_what_became_of_each_column() -> None:
    """The warning lines, word for word: a reading held over as a gap, the command held, the drive
    unknown (each with its range, unit and first time)."""
    t = np.arange(4) * 1e-3
    log = {"t": t, "T_w": np.array([24.0, 1e30, 24.0, 24.0]), "T_w_cmd": np.array([24.0, 24.0, 999.0, 24.0]),
           "drive": np.array([0.1, 0.1, 0.1, 7.0])}
    got = clean_log(log, Config()).warnings(Config())
    assert got == [
        "1 value(s) of T_w outside the plausible range [-50, 150] degC (first at t = 0.001 s) treated as "
        "missing (held over, gap)",
        "1 value(s) of drive outside the plausible range [-1, 1]  (first at t = 0.003 s) taken as an "
        "unknown drive",
        "1 value(s) of T_w_cmd outside the plausible range [-50, 150] degC (first at t = 0.002 s) held at "
        "the last plausible command"]


def test_clean_log_counts_and_holds_the_command() -> None:
    t = np.arange(6) * 1e-3
    log = {"t": t, "T_w": np.array([24, 1e30, 24, np.nan, 24, 24.0]),
           "T_p": np.full(6, 25.0), "T_a": np.full(6, 20.0), "v": np.array([0.1, 0, -1, 0.1, 11, 0.1]),
           "T_w_cmd": np.array([24, 24, 999, 999, 26, 26.0])}
    c = clean_log(log, Config())
    assert c.counts == {"T_w": 1, "v": 2, "T_w_cmd": 2}
    assert c.first == {"T_w": 1e-3, "v": 2e-3, "T_w_cmd": 2e-3}
    np.testing.assert_array_equal(c.columns["T_w"], [24, np.nan, 24, np.nan, 24, 24])
    np.testing.assert_array_equal(c.columns["v"], [0.1, 0, np.nan, 0.1, np.nan, 0.1])
    np.testing.assert_array_equal(c.columns["T_w_cmd"], [24, 24, 24, 24, 26, 26])  # held
    np.testing.assert_array_equal(c.rejected, [0, 1, 1, 1, 1, 0])  # a NaN reading is not "rejected"
    assert len(c.warnings(Config())) == 3 and c.no_valid == []
    narrow = Config().replace(plausible={"v_max": 0.05})  # configurable per column
    assert clean_log(log, narrow).counts["v"] == 5


@pytest.mark.parametrize(("col", "value"), [("T_w", 1e30), ("v", 1e100), ("v", 1e308), ("T_w", 1e200),
                                            ("T_a", -1e300), ("T_p", math.inf), ("drive", 1e300),
                                            ("T_w_cmd", 1e300)])
def test_one_absurd_sample_in_a_log(run_log, clean, col: str, value: float) -> None:  # type: ignore[no-untyped-def]
    bad = {k: v.copy() for k, v in run_log.items()}
    bad[col][K_BAD] = value
    warn: list[str] = []
    res = observe(bad, CFG, warnings=warn)
    assert len(res.events) == len(clean.events)
    np.testing.assert_allclose(spans(res.events), spans(clean.events), atol=0.02)
    gap = res.columns["gap"].astype(bool)
    assert gap[K_BAD] and gap.sum() == clean.columns["gap"].sum() + 1
    for k in ("q_i_hat", "dq_i_hat", "sd"):
        assert np.isfinite(res.columns[k][~gap]).all(), k
    assert len(warn) == 1 and col in warn[0] and "t = 25.000 s" in warn[0]


def test_absurd_readings_from_the_device_are_held(monkeypatch: pytest.MonkeyPatch, clean) -> None:  # type: ignore[no-untyped-def]
    """The loop drops them before the supervisor and the blocks: no fault (a single bad
    sample is a short gap), the same contacts, finite commands and estimates."""
    measure = SimulatedPlant.measure
    bad_at = {K_BAD: (1e30, None, None), K_BAD + 5000: (None, -1e300, None),
              K_BAD + 9000: (None, None, 1e200)}

    def absurd(self: SimulatedPlant) -> tuple[float, float, float]:
        r = list(measure(self))
        for i, x in enumerate(bad_at.get(self.k, (None, None, None))):
            if x is not None:
                r[i] = x
        return r[0], r[1], r[2]

    monkeypatch.setattr(SimulatedPlant, "measure", absurd)
    res = run_closed_loop(SC, CFG)
    c = res.columns
    assert res.fault is None and len(c["t"]) == len(clean.columns["gap"])
    assert c["T_w"][K_BAD] == 1e30  # the log keeps what the device sent
    gap = c["gap"].astype(bool)
    assert gap[list(bad_at)].all() and gap.sum() == 3
    for k in ("q_i_hat", "dq_i_hat", "T_p_cmd", "drive", "v"):
        assert np.isfinite(c[k]).all(), k
    np.testing.assert_allclose(spans(res.events), spans(clean.events), atol=0.02)
    # offline on that log: the same values dropped, the live estimates again to the bit
    off = observe({k: np.asarray(c[k], dtype=float) for k in COLUMNS}, CFG)
    np.testing.assert_array_equal(off.columns["q_i_hat"], c["q_i_hat"])
    np.testing.assert_array_equal(off.columns["contact"], c["contact"])


def invoke(*args: str) -> tuple[int, str, str]:
    r = CliRunner().invoke(main, list(args))
    return r.exit_code, r.stdout, r.stderr


def test_observe_warns_where_the_user_gets_nothing(run_log, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """An all-NaN T_w column and a log shorter than the detector needs: one warning line
    each saying what the user gets; one absurd value: one line saying what was dropped."""
    nan_tw = {k: v.copy() for k, v in run_log.items()}
    nan_tw["T_w"][:] = np.nan
    short = {k: v[:500] for k, v in run_log.items()}
    absurd = {k: v.copy() for k, v in run_log.items()}
    absurd["T_w"][1000] = 1e200
    for name, log, needle in (("nan", nan_tw, "column T_w has no valid sample"),
                              ("short", short, "less than the detector needs"),
                              ("absurd", absurd, "1 value(s) of T_w outside the plausible range")):
        write_log(tmp_path / f"{name}.csv", log)
        code, _, err = invoke("observe", str(tmp_path / f"{name}.csv"), "-o", str(tmp_path / f"o{name}.csv"))
        lines = [ln for ln in err.splitlines() if ln.startswith("thermoskin: warning")]
        assert code == 0 and len(lines) == 1 and needle in lines[0], (name, err)
