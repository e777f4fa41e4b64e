"""Tests of thermoskin.plots.log: a PNG is written, with and without optional columns."""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from thermoskin.plots.log import decimate, plot_run

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@dataclass
class _Event:
    onset: float
    release: float


def _png_size(path: Path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data[:8] == PNG_MAGIC
    assert data[12:16] == b"IHDR"
    assert data.rstrip(b"\x00")[-8:-4] == b"IEND"
    w, h = struct.unpack(">II", data[16:24])
    return w, h


def _columns(n: int, full: bool) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(3)
    t = np.arange(n) * 1e-2
    touch = (t % 3 > 1.0) & (t % 3 < 2.0)
    cols = {
        "t": t,
        "T_w": 24 + rng.normal(0, 0.02, n),
        "T_p": 22 + rng.normal(0, 0.1, n),
        "q_i_hat": 3.6 + rng.normal(0, 0.005, n) + 0.03 * touch,
    }
    cols["T_w"][50:60] = np.nan  # a thermocouple gap
    if full:
        cols |= {
            "T_g": 24.2 + 0.3 * touch,
            "T_w_cmd": np.full(n, 24.0),
            "T_a": np.full(n, 20.0),
            "dq_i_hat": rng.normal(0, 0.005, n) + 0.03 * touch,
            "q_i": 0.03 * touch,
            "contact_true": touch.astype(float),
        }
    return cols


def _check_png(p: Path) -> None:
    assert p.is_file()
    assert p.stat().st_size > 20_000
    w, h = _png_size(p)
    assert 600 <= w <= 3000 and 400 <= h <= 2000


def test_plot_full(tmp_path: Path) -> None:
    events = [_Event(a + 0.2, a + 1.1) for a in (1.0, 4.0, 7.0)]
    out = plot_run(_columns(1000, True), events, tmp_path / "sub" / "full.png", title="one finger")
    assert out == tmp_path / "sub" / "full.png"
    _check_png(out)


def test_plot_minimal(tmp_path: Path) -> None:
    out = plot_run(_columns(1000, False), [], tmp_path / "min.png")
    _check_png(out)


def test_plot_only_t_and_Tw_with_open_event(tmp_path: Path) -> None:
    cols = {"t": np.arange(200) * 0.1, "T_w": np.linspace(24, 25, 200)}
    out = plot_run(cols, [{"onset": 5.0, "release": None}], str(tmp_path / "tw.png"))
    _check_png(out)


def test_plot_long_run_is_thinned(tmp_path: Path) -> None:
    out = plot_run(_columns(120_000, True), [_Event(10.0, 11.0)], tmp_path / "long.png", max_points=4000)
    _check_png(out)


def test_plot_needs_t(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="'t'"):
        plot_run({"T_w": np.ones(3)}, [], tmp_path / "x.png")


def test_decimate_keeps_extremes_and_gaps() -> None:
    n = 100_000
    t = np.arange(n, dtype=float)
    y = np.sin(t / 5000.0)
    y[12345] = 5.0
    y[50_000:50_500] = np.nan
    td, yd = decimate(t, y, max_points=2000)
    assert td.size <= 2100
    assert np.all(np.diff(td) >= 0)
    assert yd[np.isfinite(yd)].max() == 5.0
    assert np.isnan(yd).any()
    t2, y2 = decimate(t[:100], y[:100], max_points=2000)
    assert t2.size == 100 and np.array_equal(y2, y[:100])
