"""`thermoskin reproduce`, reduced (4 contacts per run, 30 s set-point runs): files, summary shape, trends."""

from __future__ import annotations

import io
import json
from pathlib import Path

import pytest
from rich.console import Console
from rich.progress import Progress

from thermoskin.experiments.reproduce import FIGURES, reproduce


def _progress(description: str) -> Progress:
    return Progress(disable=True)


@pytest.fixture(scope="module")
def out(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("repro")
    reproduce(d, None, Console(file=io.StringIO()), _progress, n_contacts=4, setpoint_s=30.0)
    return d


@pytest.fixture(scope="module")
def summary(out: Path) -> dict:  # type: ignore[type-arg]
    return json.loads((out / "summary.json").read_text())


def test_files(out: Path) -> None:
    assert FIGURES == ("fig8", "fig12", "fig13", "fig14", "fig15", "fig16", "fig17", "fig18", "fig19")
    for fig in FIGURES:
        png = out / f"{fig}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000, fig
    report = (out / "report.md").read_text()
    for fig in FIGURES:
        assert f"]({fig}.png)" in report
    assert "Table I" in report and "q_ag" in report


def test_summary_shape(summary: dict) -> None:  # type: ignore[type-arg]
    assert set(summary["setpoints"]) == {"24", "26", "28"}
    for s in summary["setpoints"].values():
        assert {"steady_state_error_K", "settling_time_s"} <= set(s)
    groups = {"fingers": {"1", "2", "3"}, "persons": {"man1", "woman1", "woman2"},
              "positions": {"near", "middle", "far"}}
    for group, keys in groups.items():
        assert set(summary[group]) == keys, group
        for v in summary[group].values():
            assert isinstance(v["mean_dq_W"], float) and isinstance(v["peak_dq_W"], float)


def test_setpoints_held(summary: dict) -> None:  # type: ignore[type-arg]
    for c, s in summary["setpoints"].items():
        assert s["steady_state_error_K"] <= 0.1, c
        assert s["mean_abs_error_K"] <= 0.1, c
        assert 0.0 < s["settling_time_s"] < 20.0, c


def test_heat_flow_grows_with_fingers(summary: dict) -> None:  # type: ignore[type-arg]
    f = summary["fingers"]
    for key in ("mean_dq_W", "peak_dq_W"):
        assert 0 < f["1"][key] < f["2"][key] < f["3"][key], key
    # roughly proportional to the contact area (fingers)
    assert 1.6 < f["2"]["mean_dq_W"] / f["1"]["mean_dq_W"] < 2.4
    assert all(v["detected"] == v["contacts"] and v["false_alarms"] == 0 for v in f.values())


def test_persons_differ(summary: dict) -> None:  # type: ignore[type-arg]
    p = summary["persons"]
    means = sorted(v["mean_dq_W"] for v in p.values())
    assert means[0] > 0
    assert means[-1] / means[0] > 1.15  # spread between persons, well above the run-to-run noise
    # the order follows G_finger (T_f - T_g): man1 > woman2 > woman1
    assert p["man1"]["mean_dq_W"] > p["woman2"]["mean_dq_W"] > p["woman1"]["mean_dq_W"]


def test_positions_fall_with_distance(summary: dict) -> None:  # type: ignore[type-arg]
    pos = summary["positions"]
    for key in ("mean_dq_W", "peak_dq_W"):
        assert pos["near"][key] > 1.3 * pos["middle"][key] > 0, key
        assert pos["middle"][key] > 1.1 * pos["far"][key] > 0, key
    # closed loop with the pump switching: about position-independent (the water carries the heat)
    cl = summary["positions_closed_loop"]
    assert cl["far"]["mean_dq_W"] == pytest.approx(cl["near"]["mean_dq_W"], rel=0.15)


def test_spatial_agrees_with_network_at_the_thermocouple(summary: dict) -> None:  # type: ignore[type-arg]
    sv = summary["spatial_vs_network"]
    assert sv["ratio_mean"] == pytest.approx(1.0, abs=0.1)
    assert sv["ratio_peak"] == pytest.approx(1.0, abs=0.1)


def test_a_partial_reproduction_reports_no_missing_number(tmp_path: Path) -> None:
    """`--only fig8` (the set-point runs alone) and a report with no run at all: every number of
    the report is there or said why not: no "n/a" (it wrote "≈ n/a W" for eq. 8's no-touch
    level when the one-finger run was not among the runs). The level without that run is the
    correction's closed form (T_w_cmd - T_a)/R_ag."""
    from thermoskin.experiments.report import write_report
    from thermoskin.experiments.scenarios import T_A, T_W_CMD

    reproduce(tmp_path, ["fig8"], Console(file=io.StringIO()), _progress, n_contacts=2, setpoint_s=5.0)
    text = (tmp_path / "report.md").read_text()
    assert "n/a" not in text and f"≈ {(T_W_CMD - T_A) / 1.0:.2f} W at the" in text
    empty = write_report(tmp_path / "empty.md", [], {}, {}, {}).read_text()
    assert "n/a" not in empty


def test_the_full_report_has_no_missing_number(out: Path) -> None:
    text = (out / "report.md").read_text()
    assert "n/a" not in text and "≈ nan" not in text
