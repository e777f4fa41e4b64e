"""Tests of thermoskin.logio: error messages, NaN handling, round trip."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from thermoskin.logio import LogError, read_log, sample_time, write_log

HEADER = "t,T_w,T_p,v,T_a,q_i_hat,contact"


def _rows(n: int = 5, ts: float = 0.01) -> list[str]:
    return [f"{i * ts:.6f},24.0,20.0,0.141,20.0,3.6,0" for i in range(n)]


def _write(tmp_path: Path, lines: list[str], name: str = "log.csv") -> Path:
    p = tmp_path / name
    p.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return p


def _error(path: Path, **kw: object) -> str:
    with pytest.raises(LogError) as info:
        read_log(path, **kw)  # type: ignore[arg-type]
    msg = str(info.value)
    assert "\n" not in msg, msg
    assert path.name in msg, msg
    return msg


# ------------------------------------------------------------------------- good logs


def test_read_basic(tmp_path: Path) -> None:
    p = _write(tmp_path, [HEADER, *_rows()])
    log = read_log(p)
    assert list(log) == HEADER.split(",")
    assert all(a.dtype == np.float64 and a.shape == (5,) for a in log.values())
    assert log["t"][-1] == pytest.approx(0.04)
    assert sample_time(log["t"]) == pytest.approx(0.01)


def test_round_trip(tmp_path: Path) -> None:
    n = 1000
    rng = np.random.default_rng(1)
    cols = {
        "t": 100.0 + np.arange(n) * 1e-3,
        "T_w": 24 + rng.normal(0, 0.02, n),
        "T_p": 20 + rng.normal(0, 0.1, n),
        "v": np.where(rng.random(n) < 0.5, 0.141, 0.0),
        "T_a": np.full(n, 20.0),
        "q_i_hat": 3.6 + rng.normal(0, 0.01, n),
        "contact": (rng.random(n) < 0.3).astype(float),
        "n_fingers": rng.integers(0, 4, n).astype(float),
    }
    cols["T_w"][10:20] = np.nan
    p = write_log(tmp_path / "deep" / "dir" / "run.csv", cols)
    assert p.exists()
    assert not [f for f in p.parent.iterdir() if f.name != "run.csv"]  # no temporary left
    lines = p.read_text().splitlines()
    assert lines[0] == ",".join(cols)
    first = lines[1].split(",")
    assert first[6] in ("0", "1") and first[7] in ("0", "1", "2", "3")  # flags as integers
    log = read_log(p)
    assert list(log) == list(cols)
    for k, a in cols.items():
        np.testing.assert_allclose(log[k], a, rtol=1e-5, atol=1e-9, equal_nan=True, err_msg=k)
    assert np.diff(log["t"]) == pytest.approx(1e-3, rel=1e-6)


def test_write_replaces_atomically(tmp_path: Path) -> None:
    p = tmp_path / "x.csv"
    write_log(
        p, {"t": np.arange(3.0), "T_w": np.ones(3), "T_p": np.ones(3), "v": np.zeros(3), "T_a": np.ones(3)}
    )
    write_log(
        p, {"t": np.arange(4.0), "T_w": np.ones(4), "T_p": np.ones(4), "v": np.zeros(4), "T_a": np.ones(4)}
    )
    assert read_log(p)["t"].size == 4
    assert sorted(os.listdir(tmp_path)) == ["x.csv"]


def test_write_rejects_bad_input(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="different lengths"):
        write_log(tmp_path / "a.csv", {"t": np.arange(3.0), "T_w": np.ones(2)})
    with pytest.raises(ValueError, match="column name"):
        write_log(tmp_path / "a.csv", {"t": np.arange(3.0), "a,b": np.ones(3)})
    assert not (tmp_path / "a.csv").exists()


def test_nan_accepted_in_temperature_and_velocity(tmp_path: Path) -> None:
    rows = _rows(6)
    rows[1] = "0.010000,nan,NaN,NA,,3.6,0"
    rows[2] = "0.020000,,NA,,nan,3.6,1"
    p = _write(tmp_path, [HEADER, *rows])
    log = read_log(p)
    for k in ("T_w", "T_p", "v", "T_a"):
        assert np.isnan(log[k][1]) and np.isnan(log[k][2]), k
        assert np.isfinite(log[k][[0, 3, 4, 5]]).all(), k
    assert log["contact"][2] == 1.0


def test_trailing_blank_lines_and_crlf(tmp_path: Path) -> None:
    p = tmp_path / "crlf.csv"
    p.write_bytes(("\r\n".join([HEADER, *_rows()]) + "\r\n\r\n").encode())
    assert read_log(p)["t"].size == 5


# ------------------------------------------------------------------------- errors


def test_missing_file(tmp_path: Path) -> None:
    msg = _error(tmp_path / "nope.csv")
    assert "not found" in msg


def test_not_a_regular_file(tmp_path: Path) -> None:
    d = tmp_path / "dir.csv"
    d.mkdir()
    assert "not a regular file" in _error(d)


def test_empty_file(tmp_path: Path) -> None:
    p = tmp_path / "empty.csv"
    p.write_text("")
    assert "empty file" in _error(p)
    p.write_text("\n  \n")
    assert "empty file" in _error(p)


def test_no_header(tmp_path: Path) -> None:
    p = _write(tmp_path, _rows())
    msg = _error(p)
    assert "line 1" in msg and "no header" in msg


def test_no_data_rows(tmp_path: Path) -> None:
    p = _write(tmp_path, [HEADER])
    assert "no data rows" in _error(p)


def test_one_row_only(tmp_path: Path) -> None:
    p = _write(tmp_path, [HEADER, *_rows(1)])
    assert "at least 2" in _error(p)


def test_duplicate_columns(tmp_path: Path) -> None:
    p = _write(tmp_path, [HEADER + ",T_w", *[r + ",1" for r in _rows()]])
    msg = _error(p)
    assert "line 1" in msg and "duplicate" in msg and "T_w" in msg


def test_empty_column_name(tmp_path: Path) -> None:
    p = _write(tmp_path, [HEADER + ",", *[r + ",1" for r in _rows()]])
    assert "empty name" in _error(p)


def test_missing_required_columns(tmp_path: Path) -> None:
    p = _write(tmp_path, ["t,T_w,q_i_hat", "0,24,3.6", "1,24,3.6"])
    msg = _error(p)
    assert "missing required column(s) T_p, v, T_a" in msg
    assert "columns found: t, T_w, q_i_hat" in msg
    assert read_log(p, required=("t", "T_w"))["q_i_hat"].size == 2


def test_t_always_required(tmp_path: Path) -> None:
    p = _write(tmp_path, ["time,T_w", "0,24", "1,24"])
    assert "missing required column(s) t" in _error(p, required=("T_w",))


def test_wrong_number_of_fields(tmp_path: Path) -> None:
    rows = _rows(8)
    rows[4] = rows[4] + ",99"  # line 6
    msg = _error(_write(tmp_path, [HEADER, *rows]))
    assert "line 6" in msg and "8 fields" in msg and "expected 7" in msg


def test_blank_line_inside(tmp_path: Path) -> None:
    rows = _rows(8)
    rows[2] = ""  # line 4
    msg = _error(_write(tmp_path, [HEADER, *rows]))
    assert "line 4" in msg and "empty line" in msg


def test_non_numeric_value(tmp_path: Path) -> None:
    rows = _rows(8)
    rows[5] = "0.050000,24.0,20.0,0.141,20.0,oops,0"  # line 7
    msg = _error(_write(tmp_path, [HEADER, *rows]))
    assert "line 7" in msg and "'q_i_hat'" in msg and "'oops'" in msg and "non-numeric" in msg


def test_non_numeric_in_temperature(tmp_path: Path) -> None:
    rows = _rows(8)
    rows[3] = "0.030000,24.0,20.0,0.141,N/A,3.6,0"  # line 5: N/A is not a NaN spelling
    msg = _error(_write(tmp_path, [HEADER, *rows]))
    assert "line 5" in msg and "'T_a'" in msg and "'N/A'" in msg


@pytest.mark.parametrize("bad", ["nan", "NA", "", "NaN"])
def test_nan_not_allowed_in_other_columns(tmp_path: Path, bad: str) -> None:
    rows = _rows(8)
    rows[2] = f"0.020000,24.0,20.0,0.141,20.0,{bad},0"  # line 4
    msg = _error(_write(tmp_path, [HEADER, *rows]))
    assert "line 4" in msg and "'q_i_hat'" in msg and repr(bad) in msg


@pytest.mark.parametrize("bad", ["nan", "NA", "", "inf"])
def test_t_must_be_finite(tmp_path: Path, bad: str) -> None:
    rows = _rows(8)
    rows[6] = f"{bad},24.0,20.0,0.141,20.0,3.6,0"  # line 8
    msg = _error(_write(tmp_path, [HEADER, *rows]))
    assert "line 8" in msg and "'t'" in msg and repr(bad) in msg


def test_infinite_temperature(tmp_path: Path) -> None:
    rows = _rows(8)
    rows[1] = "0.010000,inf,20.0,0.141,20.0,3.6,0"  # line 3
    msg = _error(_write(tmp_path, [HEADER, *rows]))
    assert "line 3" in msg and "'T_w'" in msg and "infinite" in msg


def test_nan_columns_override(tmp_path: Path) -> None:
    rows = _rows(4)
    rows[1] = "0.010000,24.0,20.0,0.141,20.0,nan,0"
    p = _write(tmp_path, [HEADER, *rows])
    assert np.isnan(read_log(p, nan_columns=("q_i_hat",))["q_i_hat"][1])


def test_t_not_increasing(tmp_path: Path) -> None:
    rows = _rows(8)
    rows[5] = rows[4]  # line 7 repeats t of line 6
    msg = _error(_write(tmp_path, [HEADER, *rows]))
    assert "line 7" in msg and "not strictly increasing" in msg


def test_t_non_uniform(tmp_path: Path) -> None:
    rows = _rows(10)
    rows = rows[:6] + rows[7:]  # a dropped sample: interval 0.02 s before line 8
    msg = _error(_write(tmp_path, [HEADER, *rows]))
    assert "line 8" in msg and "non-uniform" in msg and "0.02 s" in msg and "expected 0.01 s" in msg


def test_t_jitter_within_tolerance(tmp_path: Path) -> None:
    rows = [f"{i * 0.01 + (0.00005 if i % 2 else 0):.6f},24,20,0,20,3.6,0" for i in range(10)]
    assert read_log(_write(tmp_path, [HEADER, *rows]))["t"].size == 10


def test_bad_encoding(tmp_path: Path) -> None:
    p = tmp_path / "latin.csv"
    p.write_bytes((HEADER + "\n" + "\n".join(_rows(3)) + "\n# Temp \xb0C\n").encode("latin-1"))
    msg = _error(p)
    assert "line 5" in msg and "UTF-8" in msg


def test_error_in_long_file_located(tmp_path: Path) -> None:
    rows = _rows(5000, ts=0.001)
    rows[4321] = rows[4321].replace(",0.141,", ",fast,")  # line 4323
    msg = _error(_write(tmp_path, [HEADER, *rows]))
    assert "line 4323" in msg and "'v'" in msg and "'fast'" in msg


def test_sample_time() -> None:
    assert sample_time([0.0, 0.5, 1.0, 1.5]) == pytest.approx(0.5)
    with pytest.raises(ValueError):
        sample_time([1.0])
