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


# ------------------------------------------------------------------------- precision, formats, streaming

from thermoskin.logio import FLAG_COLUMNS, LogReader, LogWriter, check_time  # noqa: E402


def _digits(text: str) -> str:
    """Significant digits of a decimal number's text (sign, point, exponent and leading zeros dropped)."""
    mant = text.lower().lstrip("+-").split("e")[0].replace(".", "")
    return mant.lstrip("0").rstrip("0") or "0"


def _awkward(n: int, seed: int = 3) -> np.ndarray:
    """Finite doubles of every magnitude (random bit patterns) plus hand-picked hard cases."""
    rng = np.random.default_rng(seed)
    bits = rng.integers(0, 2**63, n, dtype=np.int64)
    x = bits.view(np.float64).copy()
    x[~np.isfinite(x)] = 1.5
    x *= np.where(rng.random(n) < 0.5, -1.0, 1.0)
    hard = [0.1, 1 / 3, 20.03125, 2**-1074, 2.2250738585072014e-308, 1.7976931348623157e308, -0.0, 0.0,
            1e22, 1e16, 2**53 + 2.0, 123456789012.5, 1e-7, 9.999999999999999e22, 5e-324]
    x[: len(hard)] = hard
    return x


def _same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and bool(np.all(a.view(np.int64) == b.view(np.int64)))


def _exact_cols(n: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(5)
    cols = {
        "t": 100.0 + np.arange(n) * 1e-3,  # 100.00100000000001...: not short decimals
        "T_w": np.round((24 + rng.normal(0, 0.05, n)) * 64) / 64,  # thermocouple steps of 1/64 K
        "T_p": 20 + rng.normal(0, 0.1, n),
        "v": np.where(rng.random(n) < 0.5, 0.141, 0.0),
        "T_a": np.full(n, 20.03125),
        "x": _awkward(n),
        "contact": (rng.random(n) < 0.3).astype(float),
        "sign": rng.integers(-1, 2, n).astype(float),
    }
    cols["T_w"][5:9] = np.nan
    return cols


@pytest.mark.parametrize("ext", [".csv", ".parquet"])
def test_round_trip_bit_exact(tmp_path: Path, ext: str) -> None:
    cols = _exact_cols(3000)
    p = write_log(tmp_path / f"exact{ext}", cols)
    log = read_log(p, nan_columns=("T_w",))
    assert list(log) == list(cols)
    for k, a in cols.items():
        assert _same_bits(log[k], a), k  # NaN and -0.0 included


def test_csv_text_is_shortest_round_trip(tmp_path: Path) -> None:
    cols = _exact_cols(2000)
    p = write_log(tmp_path / "exact.csv", cols)
    lines = p.read_text().splitlines()
    assert lines[0] == ",".join(cols)
    rows = [ln.split(",") for ln in lines[1:]]
    names = list(cols)
    for j, name in enumerate(names):
        fields = [r[j] for r in rows]
        for text, x in zip(fields, cols[name], strict=True):
            if np.isnan(x):
                assert text.lower() == "nan"
                continue
            assert float(text) == x and np.signbit(float(text)) == np.signbit(x), (name, text, x)
            # Python's repr is the shortest decimal that reads back to x (David Gay's algorithm)
            assert len(_digits(text)) <= len(_digits(repr(float(x)))), (name, text, repr(float(x)))
    assert "20.03125" in lines[1].split(",")[4]


def test_flags_written_as_integers(tmp_path: Path) -> None:
    n = 6
    cols = {
        "t": np.arange(n) * 0.5,
        "contact": np.array([0, 1, 1, 0, 0, 1], dtype=float),
        "gap": np.zeros(n, dtype=np.int8),
        "n_fingers": np.array([0, 1, 2, 3, 2, 1], dtype=float),
        "fresh": np.full(n, 7.0),
        "sign": np.array([-1, 0, 1, 1, 0, -1], dtype=float),
        "patch": np.arange(n, dtype=float),
        "contact_true": np.array([True, False] * 3),
        "q": np.array([1.0, 2.0, 3.0, 4.0, 5.0, 6.5]),  # not a flag: floats stay floats
        "seq": np.arange(n, dtype=np.int64),  # integer arrays are integers whatever their name
    }
    assert {"contact", "gap", "contact_true", "n_fingers", "fresh", "sign", "patch"} <= FLAG_COLUMNS
    p = write_log(tmp_path / "flags.csv", cols)
    rows = [ln.split(",") for ln in p.read_text().splitlines()[1:]]
    for j, name in enumerate(cols):
        if name in ("t", "q"):
            continue
        assert all(r[j].lstrip("-").isdigit() for r in rows), (name, [r[j] for r in rows])
    assert [r[5] for r in rows] == ["-1", "0", "1", "1", "0", "-1"]
    assert [r[8] for r in rows][-1] == "6.5"
    log = read_log(p, required=("t",))
    for k, a in cols.items():
        np.testing.assert_array_equal(log[k], np.asarray(a, dtype=float), err_msg=k)


def test_flag_with_nan_stays_readable(tmp_path: Path) -> None:
    cols = {"t": np.arange(4.0), "contact": np.array([0.0, np.nan, 1.0, 0.5])}
    p = write_log(tmp_path / "f.csv", cols)
    assert _same_bits(read_log(p, required=("t",), nan_columns=("contact",))["contact"], cols["contact"])


@pytest.mark.parametrize("name", ["log.txt", "log", "log.csv.gz", "log.pq"])
def test_unknown_extension(tmp_path: Path, name: str) -> None:
    p = tmp_path / name
    p.write_text(HEADER + "\n" + "\n".join(_rows()) + "\n")
    msg = _error(p)
    assert "must end in .csv or .parquet" in msg
    with pytest.raises(LogError, match=r"must end in \.csv or \.parquet") as info:
        write_log(p, {"t": np.arange(3.0)})
    assert name in str(info.value)
    with pytest.raises(LogError, match="unknown log format"):
        LogWriter(tmp_path / "w.json", ["t"])
    # a recording given where a log is expected: the message says what to do with it
    with pytest.raises(LogError, match=r"\.parquet \(an MCAP recording: `thermoskin export` makes a log"):
        read_log(tmp_path / "run.mcap")


def test_extension_case_insensitive(tmp_path: Path) -> None:
    p = _write(tmp_path, [HEADER, *_rows()], name="LOG.CSV")
    assert read_log(p)["t"].size == 5


def test_bom_header(tmp_path: Path) -> None:
    p = tmp_path / "bom.csv"
    p.write_bytes(b"\xef\xbb\xbf" + ("\n".join([HEADER, *_rows()]) + "\n").encode())
    assert list(read_log(p)) == HEADER.split(",")


# ------------------------------------------------------------------------- streaming


def _uniform_rows(n: int, t0: int = 10_000) -> list[str]:
    """Rows of equal width (t = 10.000 ... in ms steps), so that swapping two keeps the blocks."""
    return [f"{(t0 + i) / 1000:.3f},24.0,20.0,0.141,20.0,3.6,{i % 2}" for i in range(n)]


def test_reader_chunks_and_boundaries(tmp_path: Path) -> None:
    cols = _exact_cols(25_000)
    p = write_log(tmp_path / "c.csv", cols)
    with LogReader(p, nan_columns=("T_w",), chunk_rows=2000) as r:
        assert r.names == list(cols) and r.n_rows is None
        chunks = list(r)
        assert r.n_rows == r.rows == 25_000
        assert r.t_s == pytest.approx(1e-3)
        with pytest.raises(RuntimeError, match="iterated once"):
            list(r)
    sizes = [c["t"].size for c in chunks]
    assert len(chunks) > 5 and max(sizes) < 4 * 2000, sizes  # chunks of about chunk_rows rows
    for k, a in cols.items():
        got = np.concatenate([c[k] for c in chunks])
        assert _same_bits(got, a), k
        assert all(c[k].dtype == np.float64 and c[k].flags.writeable for c in chunks)


@pytest.mark.parametrize("ext", [".csv", ".parquet"])
def test_writer_in_uneven_chunks(tmp_path: Path, ext: str) -> None:
    cols = _exact_cols(5000)
    p = tmp_path / f"w{ext}"
    with LogWriter(p, list(cols), flush_rows=700, row_group_rows=900) as w:
        i = 0
        for size in [1, 2, 997, 0, 3000, 1000]:
            w.write({k: a[i : i + size] for k, a in cols.items()})
            i += size
        assert w.rows == 5000
    with LogReader(p, nan_columns=("T_w",), chunk_rows=1024) as r:
        if ext == ".parquet":
            assert r.n_rows == 5000
        got = list(r)
    for k, a in cols.items():
        assert _same_bits(np.concatenate([c[k] for c in got]), a), k


def test_error_in_a_later_chunk(tmp_path: Path) -> None:
    rows = _uniform_rows(20_000)
    rows[15_000] = rows[15_000].replace(",0.141,", ",fast,")  # line 15002
    p = _write(tmp_path, [HEADER, *rows])
    seen = 0
    with pytest.raises(LogError) as info, LogReader(p, chunk_rows=2000) as r:
        for c in r:
            seen += c["t"].size
    msg = str(info.value)
    assert "line 15002" in msg and "'v'" in msg and "'fast'" in msg and "\n" not in msg
    assert 10_000 <= seen <= 15_000  # the chunks before the bad one were given


@pytest.mark.parametrize("fault", ["repeat", "gap", "nan"])
def test_time_fault_at_a_chunk_boundary(tmp_path: Path, fault: str) -> None:
    rows = _uniform_rows(10_000)
    p = _write(tmp_path, [HEADER, *rows])
    with LogReader(p, chunk_rows=1000) as r:
        first = next(iter(r))["t"].size  # where the second chunk starts, as a row index
    k = first  # row k opens chunk 2, file line k + 2
    if fault == "repeat":
        rows[k] = rows[k - 1]
    elif fault == "gap":  # a sample lost: 2 ms before row k (then t repeats: reported second)
        rows[k] = rows[k + 1]
    else:
        rows[k] = "nan   " + rows[k][6:]  # same width: the blocks stay as they were
    p = _write(tmp_path, [HEADER, *rows])
    with LogReader(p, chunk_rows=1000) as r:
        it = iter(r)
        assert next(it)["t"].size == first  # the first chunk is unchanged and given
        with pytest.raises(LogError) as info:
            next(it)
    msg = str(info.value)
    assert f"line {k + 2}" in msg and "'t'" in msg, msg
    want = {"repeat": "not strictly increasing", "gap": "non-uniform", "nan": "finite number"}[fault]
    assert want in msg, msg


def test_uniform_optional(tmp_path: Path) -> None:
    rng = np.random.default_rng(7)
    t = np.cumsum(rng.uniform(0.8e-3, 1.2e-3, 3000))  # 20 % jitter
    cols = {"t": t, "T_w": np.full(3000, 24.0), "T_p": np.full(3000, 20.0), "v": np.zeros(3000),
            "T_a": np.full(3000, 20.0)}
    p = write_log(tmp_path / "jitter.csv", cols)
    assert "non-uniform" in _error(p)
    assert _same_bits(read_log(p, uniform=False)["t"], t)
    t[100] = t[99]  # still strictly increasing required
    write_log(p, cols)
    assert "line 102" in _error(p, uniform=False)


def test_check_time() -> None:
    t = np.arange(10) * 0.01
    assert check_time(t) is None
    t2 = np.delete(t, 6)  # interval 0.02 ends at index 6
    k, why = check_time(t2)  # type: ignore[misc]
    assert k == 6 and "non-uniform" in why and "0.02 s" in why
    assert check_time(t2, uniform=False) is None
    k, why = check_time(np.array([0.0, 1.0, 1.0]))  # type: ignore[misc]
    assert k == 2 and "not strictly increasing" in why
    k, why = check_time(np.array([0.5, 0.6]), t_prev=0.5)  # type: ignore[misc]
    assert k == 0 and "0.5 after 0.5" in why
    k, why = check_time(np.array([0.52, 0.53]), t_prev=0.5, t_s=0.01)  # type: ignore[misc]
    assert k == 0 and "non-uniform" in why  # 0.02 s across the boundary
    assert check_time(np.array([0.51005, 0.52]), t_prev=0.5, t_s=0.01) is None  # within 1 %
    assert check_time(np.array([0.5, 0.52]), t_s=0.01, rtol=1.5) is None


def test_check_time_holds_the_given_step_not_the_median() -> None:
    """With ``t_s`` given, every interval is compared with it, not with the median interval:
    hand numbers where the two differ."""
    # intervals 2, 1, 1 ms: the given step is 2 ms, the median 1 ms
    t = np.array([0.0, 0.002, 0.003, 0.004])
    k, why = check_time(t, t_s=0.002)  # type: ignore[misc]
    # the first interval off 2 ms by more than 1 % is the 1 ms one ending at t[2]
    assert k == 2 and "interval 0.001 s" in why and "expected 0.002 s" in why
    k, why = check_time(t)  # type: ignore[misc]
    assert k == 1 and "interval 0.002 s" in why and "expected 0.001 s" in why  # the median's
    # every interval 1 ms, said to be 2 ms: the first is already off
    k, why = check_time(np.arange(5) * 0.001, t_s=0.002)  # type: ignore[misc]
    assert k == 1 and "expected 0.002 s" in why
    assert check_time(np.arange(5) * 0.001) is None


# ------------------------------------------------------------------------- Parquet


def _parquet(tmp_path: Path, table: dict[str, object], name: str = "p.parquet") -> Path:
    import pyarrow as pa
    import pyarrow.parquet as pq

    p = tmp_path / name
    pq.write_table(pa.table(table), p)
    return p


def test_parquet_read_types_and_nulls(tmp_path: Path) -> None:
    p = _parquet(tmp_path, {
        "t": [0.0, 0.5, 1.0], "T_w": [24.0, None, 24.5], "T_p": [20.0, 20.0, 20.0],
        "v": [0.1, 0.1, 0.1], "T_a": [20.0, 20.0, 20.0], "contact": [0, 1, 0], "ok": [True, False, True],
    })
    log = read_log(p)
    assert np.isnan(log["T_w"][1]) and log["T_w"][2] == 24.5
    np.testing.assert_array_equal(log["contact"], [0.0, 1.0, 0.0])
    np.testing.assert_array_equal(log["ok"], [1.0, 0.0, 1.0])
    assert all(a.dtype == np.float64 for a in log.values())


@pytest.mark.parametrize(("col", "value", "want"), [
    ("q_i_hat", None, "row 3, column 'q_i_hat': null value"),
    ("q_i_hat", float("nan"), "row 3, column 'q_i_hat': NaN value"),
    ("t", float("nan"), "row 3, column 't': NaN value"),
    ("T_w", float("inf"), "row 3, column 'T_w': infinite value"),
])
def test_parquet_bad_values(tmp_path: Path, col: str, value: object, want: str) -> None:
    table: dict[str, list[object]] = {c: [float(i) for i in range(5)] for c in HEADER.split(",")}
    table[col][2] = value
    msg = _error(_parquet(tmp_path, table))  # type: ignore[arg-type]
    assert want in msg, msg


def test_parquet_errors(tmp_path: Path) -> None:
    p = _parquet(tmp_path, {"t": [0.0, 1.0], "T_w": ["a", "b"]}, "s.parquet")
    assert "column 'T_w' has type string" in _error(p, required=("t",))
    p = _parquet(tmp_path, {"t": [0.0, 1.0], "T_w": [1.0, 2.0]}, "m.parquet")
    assert "missing required column(s) T_p, v, T_a" in _error(p)
    p = _parquet(tmp_path, {"t": [0.0, 2.0, 1.0]}, "n.parquet")
    assert "row 3, column 't': time not strictly increasing" in _error(p, required=())
    p = _parquet(tmp_path, {"t": [0.0]}, "one.parquet")
    assert "at least 2 samples" in _error(p, required=())
    p = _parquet(tmp_path, {"t": np.zeros(0)}, "zero.parquet")
    assert "no data rows" in _error(p, required=())


def test_parquet_truncated_or_unclosed(tmp_path: Path) -> None:
    cols = _exact_cols(3000)
    p = write_log(tmp_path / "full.parquet", cols)
    cut = tmp_path / "cut.parquet"
    cut.write_bytes(p.read_bytes()[: p.stat().st_size // 2])
    msg = _error(cut, nan_columns=("T_w",))
    assert "not a readable Parquet file" in msg and "closed" in msg
    w = LogWriter(tmp_path / "open.parquet", list(cols), row_group_rows=1000)
    w.write(cols)  # three row groups on disk, no footer yet
    assert "not a readable Parquet file" in _error(tmp_path / "open.parquet")
    w.close()
    assert _same_bits(read_log(tmp_path / "open.parquet", nan_columns=("T_w",))["x"], cols["x"])
    bogus = tmp_path / "bogus.parquet"
    bogus.write_text(HEADER + "\n")
    assert "not a readable Parquet file" in _error(bogus)


# ------------------------------------------------------------------------- writer, live CSV


def test_writer_checks_chunks(tmp_path: Path) -> None:
    with LogWriter(tmp_path / "w.csv", ["t", "a"]) as w:
        with pytest.raises(ValueError, match="missing"):
            w.write({"t": np.zeros(2)})
        with pytest.raises(ValueError, match="unexpected"):
            w.write({"t": np.zeros(2), "a": np.zeros(2), "b": np.zeros(2)})
        with pytest.raises(ValueError, match="different lengths"):
            w.write({"t": np.zeros(2), "a": np.zeros(3)})
        w.write({"t": np.arange(2.0), "a": np.ones(2)})
    with pytest.raises(ValueError, match="after close"):
        w.write({"t": np.arange(2.0), "a": np.ones(2)})
    assert (tmp_path / "w.csv").read_text() == "t,a\n0.0,1.0\n1.0,1.0\n"
    with pytest.raises(ValueError, match="column name"):
        LogWriter(tmp_path / "x.csv", ["t", "a,b"])


@pytest.mark.parametrize("ext", [".csv", ".parquet"])
def test_atomic_writer_leaves_nothing_on_error(tmp_path: Path, ext: str) -> None:
    target = tmp_path / f"a{ext}"
    write_log(target, {"t": np.arange(3.0)})
    before = target.read_bytes()
    with pytest.raises(RuntimeError), LogWriter(target, ["t"], atomic=True) as w:
        w.write({"t": np.arange(10.0)})
        raise RuntimeError("crash")
    assert target.read_bytes() == before
    assert sorted(os.listdir(tmp_path)) == [target.name]


def test_plain_writer_keeps_rows_on_error(tmp_path: Path) -> None:
    p = tmp_path / "keep.csv"
    with pytest.raises(RuntimeError), LogWriter(p, ["t", "T_w", "T_p", "v", "T_a"]) as w:
        w.write({k: np.arange(4.0) for k in ("t", "T_w", "T_p", "v", "T_a")})
        raise RuntimeError("crash")
    assert read_log(p)["t"].size == 4


def test_csv_readable_while_written(tmp_path: Path) -> None:
    names = ["t", "T_w", "T_p", "v", "T_a"]
    p = tmp_path / "live.csv"
    w = LogWriter(p, names, flush_s=0.0)
    assert p.read_text() == ",".join(names) + "\n"  # the header is there at once
    for i in range(3):
        t = np.arange(i * 1000, (i + 1) * 1000) / 1000
        w.write({"t": t, "T_w": 24 + t / 64, "T_p": np.full(1000, 20.0), "v": np.zeros(1000), "T_a": t})
        log = read_log(p)  # another reader, while the writer is open
        assert log["t"].size == (i + 1) * 1000
        assert _same_bits(log["T_w"], 24 + log["t"] / 64)
    w.close()


def test_partial_last_line(tmp_path: Path) -> None:
    rows = _uniform_rows(50)
    p = tmp_path / "cut.csv"
    for cut in (rows[0][:9], rows[0][:-2]):  # a row still being written, or cut by a kill
        p.write_text(HEADER + "\n" + "\n".join(rows) + "\n" + cut)
        assert "line 52" in _error(p)
        with LogReader(p, live=True) as r:
            assert sum(c["t"].size for c in r) == 50


CHILD = """
import sys, time
import numpy as np
from thermoskin.logio import LogWriter
w = LogWriter(sys.argv[1], ["t", "T_w", "T_p", "v", "T_a"], flush_s=0.0)
n = 500
for i in range(10**6):
    t = np.arange(i * n, (i + 1) * n) / 1000
    w.write({"t": t, "T_w": 24 + t / 64, "T_p": 20 + np.sin(t), "v": np.zeros(n), "T_a": t * 3.3})
    print(i + 1, flush=True)
    time.sleep(0.005)
"""


def _check_live_rows(log: dict[str, np.ndarray], at_least: int) -> None:
    n = log["t"].size
    assert n >= at_least
    t = np.arange(n) / 1000
    want = {"t": t, "T_w": 24 + t / 64, "T_p": 20 + np.sin(t), "v": np.zeros(n), "T_a": t * 3.3}
    for k in want:
        assert _same_bits(log[k], want[k]), k


def test_csv_of_a_killed_writer(tmp_path: Path) -> None:
    import signal
    import subprocess
    import sys

    p = tmp_path / "run.csv"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    proc = subprocess.Popen([sys.executable, "-c", CHILD, str(p)], stdout=subprocess.PIPE, text=True, env=env)
    try:
        assert proc.stdout is not None
        flushed = 0
        while flushed < 4:
            flushed = int(proc.stdout.readline())
        _check_live_rows(read_log(p, live=True), 4 * 500)  # while it writes on
        flushed = int(proc.stdout.readline())
        proc.send_signal(signal.SIGKILL)
        proc.wait(10)
    finally:
        proc.kill()
    _check_live_rows(read_log(p, live=True), flushed * 500)


def test_parquet_encodings_by_column(tmp_path: Path) -> None:
    """A dictionary for the columns of few values (flags, 1/64 K steps), byte-stream-split
    values for the others (time, estimates), as the file's own metadata says; exact round
    trip; an empty log keeps its columns."""
    import pyarrow.parquet as pq

    n = 300_000
    rng = np.random.default_rng(4)
    cols = {"t": np.arange(n) * 1e-3, "T_w": np.round((24 + rng.normal(0, 0.05, n)) * 64) / 64,
            "q_i_hat": rng.normal(0.1, 0.02, n), "contact": (rng.random(n) < 0.2).astype(float)}
    cols["q_i_hat"][:5000] = np.nan  # a warm-up of NaN does not make a column of few values
    p = write_log(tmp_path / "enc.parquet", cols)
    meta = pq.ParquetFile(p).metadata
    for g in range(meta.num_row_groups):
        enc = {meta.row_group(g).column(i).path_in_schema: meta.row_group(g).column(i).encodings
               for i in range(meta.num_columns)}
        for k in ("T_w", "contact"):
            assert "RLE_DICTIONARY" in enc[k], (g, k, enc[k])
        for k in ("t", "q_i_hat"):
            assert "BYTE_STREAM_SPLIT" in enc[k] and "RLE_DICTIONARY" not in enc[k], (g, k, enc[k])
    log = read_log(p, required=("t",), nan_columns=("q_i_hat",))
    for k, a in cols.items():
        np.testing.assert_array_equal(log[k], a, err_msg=k)
    e = write_log(tmp_path / "none.parquet", {k: np.zeros(0) for k in cols})
    assert pq.read_schema(e).names == list(cols)


_ODD_FIELDS = ["1.", ".5", "5e", "e5", "1e", "--1", "1.2.3", "0x10", "+.5", "infinity", "-nan", "NaN1",
               "1e400", "1e-400", "-inf", "+inf", "INF", "nAn", "1E5", "1e+5", "0001", "-0.0e0", "1d5",
               "'1'", "1 ", " 1", "\t1", "true", "null", "N/A", "nan ", "1_000", "0b1", "-", "+", ".",
               "", "NA", '"2.5"', "9" * 400, "0." + "0" * 330 + "1", "4.9e-324", "2.2250738585072014e-308"]


@pytest.mark.parametrize("field", _ODD_FIELDS)
def test_polars_parses_as_arrow_or_not_at_all(field: str) -> None:
    """The CSV reader's first parser (polars) takes no field that Arrow's (the second) would
    read otherwise: every value polars gives is Arrow's, bit for bit (so the parser a block
    went through cannot change a log's numbers); what polars refuses goes to Arrow."""
    from thermoskin.logio.csvlog import _arrow_parse, _fast_parse, _polars_parse

    for block in (f"{field},1\n0,2\n".encode(), f"0,1\n2,{field}\n".encode()):
        p, a = _polars_parse(block, ["a", "b"]), _arrow_parse(block, ["a", "b"])
        if p is not None:
            assert a is not None, (field, p)
            for x, y in zip(p, a, strict=True):
                assert x.tobytes() == y.tobytes(), (field, x, y)
        f = _fast_parse(block, ["a", "b"])
        assert (f is None) == (a is None)
        if f is not None:
            assert all(x.tobytes() == y.tobytes() for x, y in zip(f, a, strict=True))


def test_a_row_short_of_fields_is_not_filled_in() -> None:
    """polars fills a short row with nulls; the reader sees that and Arrow refuses the block,
    so the line is named (the line-by-line pass) and nothing is read as NaN."""
    from thermoskin.logio.csvlog import _fast_parse, _polars_parse, parse_block

    block = b"0,1,2\n1,3\n2,5,6\n"
    assert _polars_parse(block, ["a", "b", "c"]) is None and _fast_parse(block, ["a", "b", "c"]) is None
    with pytest.raises(LogError, match="line 3: 2 fields, expected 3"):
        parse_block(Path("x.csv"), block, ["a", "b", "c"], [True, True, True], 2)
    # an empty last field is a NaN where allowed (Arrow reads that block)
    cols = parse_block(Path("x.csv"), b"0,1,\n1,3,4\n", ["a", "b", "c"], [False, True, True], 2)
    assert np.isnan(cols[2][0]) and cols[2][1] == 4.0


@pytest.mark.parametrize("ext", [".csv", ".parquet"])
def test_write_blocks_is_one_log_or_none(tmp_path: Path, ext: str) -> None:
    """:func:`write_blocks`: chunks made as they are asked for become one log, the same as
    :func:`write_log` of them joined; blocks that raise leave no file and no temporary file."""
    from thermoskin.logio import write_blocks

    def blocks(n: int, fail: bool = False):  # type: ignore[no-untyped-def]
        for k in range(n):
            t = np.arange(k * 100, (k + 1) * 100) * 1e-3
            yield {"t": t, "T_w": 24.0 + t, "contact": (t > 0.15).astype(np.int8)}
            if fail and k == 1:
                raise RuntimeError("the source broke")

    p = tmp_path / f"b{ext}"
    assert write_blocks(p, blocks(3)) == 300
    whole = {k: np.concatenate([b[k] for b in blocks(3)]) for k in ("t", "T_w", "contact")}
    write_log(tmp_path / f"w{ext}", whole)
    got, ref = read_log(p, required=("t",)), read_log(tmp_path / f"w{ext}", required=("t",))
    assert list(got) == list(ref) and all(np.array_equal(got[k], ref[k]) for k in ref)
    with pytest.raises(RuntimeError):
        write_blocks(tmp_path / f"x{ext}", blocks(3, fail=True))
    assert sorted(q.name for q in tmp_path.iterdir()) == sorted([f"b{ext}", f"w{ext}"])
    assert write_blocks(tmp_path / f"none{ext}", iter(())) == 0 and not (tmp_path / f"none{ext}").exists()


def test_write_blocks_by_rows_is_write_logs_bytes(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``by_rows``: blocks of any lengths (empty ones too) written in write_log's slices, so the
    CSV is write_log's byte for byte, a flag column with a NaN in one slice included (integers
    in the others); the slices here 64 rows (262 144 in use)."""
    import itertools

    import thermoskin.logio as logio
    from thermoskin.logio import write_blocks

    monkeypatch.setattr(logio, "_WRITE_SLICE", 64)
    rng = np.random.default_rng(3)
    n = 300
    contact = (rng.random(n) > 0.7).astype(float)
    contact[150] = np.nan
    whole = {"t": np.arange(n) * 1e-3, "contact": contact, "k": np.arange(n)}
    cuts = np.sort(rng.choice(np.arange(1, n), 17, replace=False))
    edges = [0, *cuts.tolist(), cuts[5], n]  # one empty block
    edges.sort()
    blocks = [{c: v[a:b] for c, v in whole.items()} for a, b in itertools.pairwise(edges)]
    assert write_blocks(tmp_path / "b.csv", iter(blocks), by_rows=True) == n
    write_log(tmp_path / "w.csv", whole)
    got, want = (tmp_path / "b.csv").read_bytes(), (tmp_path / "w.csv").read_bytes()
    lines = want.decode().splitlines()[1:]
    assert lines[10].split(",")[1] in ("0", "1") and lines[140].split(",")[1] in ("0.0", "1.0")
    assert got == want


@pytest.mark.parametrize("ext", [".csv", ".parquet"])
def test_read_log_keep_holds_only_those_columns(tmp_path: Path, ext: str, peak_memory) -> None:  # type: ignore[no-untyped-def]
    """``keep``: the columns asked for, in the file's order, equal to the whole read's; every
    column is still checked (a NaN where none is allowed, in a column not kept, is the same
    error); and Python holds those columns alone, not the log (two of eight columns of a log
    of four chunks: under half the whole read's peak)."""
    n = 150_000
    rng = np.random.default_rng(5)
    cols = {"t": np.arange(n) * 1e-3, **{f"c{j}": rng.normal(size=n) for j in range(28)},
            "T_p": rng.normal(size=n)}
    p = tmp_path / f"wide{ext}"
    write_log(p, cols)
    got = read_log(p, required=("t", "T_p"), keep=("T_p", "c3", "t", "nope"))
    assert list(got) == ["t", "c3", "T_p"]
    for k in got:
        assert np.array_equal(got[k], cols[k])
    if ext == ".parquet":  # a log of four chunks (262 144 rows each), eight columns
        m = 1_000_000
        big = tmp_path / "long.parquet"
        write_log(big, {"t": np.arange(m) * 1e-3, **{f"c{j}": np.zeros(m) for j in range(6)},
                        "T_p": np.ones(m)})
        whole = peak_memory(lambda: read_log(big, required=("t",)))
        kept = peak_memory(lambda: read_log(big, required=("t",), keep=("t", "T_p")))
        assert whole > 8 * 8 * m and kept < whole / 2, (kept, whole)
    bad = dict(cols)
    bad["c7"] = cols["c7"].copy()
    bad["c7"][100_000] = np.nan
    write_log(p, bad)
    with pytest.raises(LogError) as whole_err:
        read_log(p, required=("t",))
    with pytest.raises(LogError) as kept_err:
        read_log(p, required=("t",), keep=("t",))
    assert str(kept_err.value) == str(whole_err.value) and "c7" in str(kept_err.value)


def test_parquet_float32_and_other_widths_read_exactly(tmp_path: Path) -> None:
    """A Parquet log as many loggers write it: T_w float32, T_p float16, v a uint16 count, T_a an
    int8, t float64, a row group split into batches at an offset (issue 46: a float32 column
    failed with "buffer is smaller than requested size" when read as float64). Each value read
    is the float64 of the value written (numpy's own conversion, the reference)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from thermoskin.logio import LogReader

    n = 5003
    rng = np.random.default_rng(46)
    cols = {"t": np.arange(n) * 1e-3, "T_w": (24 + rng.standard_normal(n)).astype(np.float32),
            "T_p": (25 + rng.standard_normal(n)).astype(np.float16),
            "v": rng.integers(0, 300, n).astype(np.uint16), "T_a": rng.integers(18, 23, n).astype(np.int8)}
    mask = np.zeros(n, bool)
    mask[7::11] = True  # nulls in T_w: read as NaN
    table = pa.table({k: pa.array(v, mask=mask if k == "T_w" else None) for k, v in cols.items()})
    pq.write_table(table, tmp_path / "x.parquet", row_group_size=1000)
    got = read_log(tmp_path / "x.parquet")
    want_Tw = cols["T_w"].astype(np.float64)
    want_Tw[mask] = np.nan
    np.testing.assert_array_equal(got["T_w"], want_Tw)
    for k in ("t", "T_p", "v", "T_a"):
        assert got[k].dtype == np.float64
        np.testing.assert_array_equal(got[k], cols[k].astype(np.float64))
    with LogReader(tmp_path / "x.parquet", chunk_rows=333) as r:  # batches cut inside row groups
        chunks = list(r)
    np.testing.assert_array_equal(np.concatenate([c["T_w"] for c in chunks]), want_Tw)


def test_a_skins_patch_column_is_an_integer_in_parquet(tmp_path: Path) -> None:
    """A skin's long-format log stores ``patch`` as int64 (an index, not a float: a lab's pandas or
    polars reads it as one), the other columns as float64 (the skin's reader reads it back:
    tests/test_skin_stream.py); a non-whole patch index is refused rather than rounded."""
    import pyarrow.parquet as pq

    from thermoskin.logio import LogWriter

    path = tmp_path / "skin.parquet"
    with LogWriter(path, ["t", "patch", "T_w"]) as w:
        w.write({"t": np.repeat([0.0, 0.001], 3), "patch": np.tile(np.arange(3.0), 2),
                 "T_w": np.linspace(20, 21, 6)})
    schema = pq.read_schema(path)
    assert str(schema.field("patch").type) == "int64" and str(schema.field("T_w").type) == "double"
    assert pq.read_table(path)["patch"].to_pylist() == [0, 1, 2, 0, 1, 2]
    assert pq.read_table(path)["T_w"].to_pylist() == np.linspace(20, 21, 6).tolist()
    bad = tmp_path / "bad.parquet"
    with pytest.raises(ValueError, match="whole number"), LogWriter(bad, ["t", "patch"]) as w:
        w.write({"t": np.array([0.0]), "patch": np.array([0.5])})


def test_parquet_row_groups_and_integer_columns(tmp_path: Path) -> None:
    """The Parquet writer: a row group once ``row_group_rows`` rows are buffered (100, 100, 50 here,
    from chunks of 50), an integer column's values kept (not its bytes read as floats)."""
    import pyarrow.parquet as pq

    from thermoskin.logio import LogWriter

    p = tmp_path / "x.parquet"
    t = np.arange(250) * 1e-3
    with LogWriter(p, ["t", "T_w", "n"], row_group_rows=100) as w:
        for i in range(0, 250, 50):
            w.write({"t": t[i:i + 50], "T_w": 24.0 + t[i:i + 50], "n": np.arange(i, i + 50)})
    meta = pq.ParquetFile(p).metadata
    assert [meta.row_group(k).num_rows for k in range(meta.num_row_groups)] == [100, 100, 50]
    got = read_log(p, required=("t",))
    np.testing.assert_array_equal(got["t"], t)
    np.testing.assert_array_equal(got["T_w"], 24.0 + t)
    np.testing.assert_array_equal(got["n"], np.arange(250.0))


def test_parquet_at_a_name_pyarrow_cannot_take(tmp_path: Path) -> None:
    """A file name holding a byte no locale decodes (Python's escape for it, a lone surrogate, as
    under an ASCII locale): written through an open file, read back, seen to have rows."""
    from thermoskin.logio import has_rows

    p = tmp_path / (os.fsdecode(b"log\xff") + ".parquet")
    n = 50
    write_log(p, {"t": np.arange(n) * 1e-3, "T_w": np.full(n, 24.0), "T_p": np.full(n, 25.0),
                  "v": np.full(n, 0.1), "T_a": np.full(n, 20.0)})
    assert os.fsencode(p).endswith(b"log\xff.parquet") and has_rows(p)
    assert read_log(p)["t"][-1] == 49e-3


def test_a_file_that_is_not_parquet_says_what_pyarrow_found(tmp_path: Path) -> None:
    p = tmp_path / "x.parquet"
    p.write_bytes(b"t,T_w\n0,1\n")
    with pytest.raises(LogError) as e:
        read_log(p, required=("t",))
    msg = str(e.value)
    assert msg.startswith(f"{p}: not a readable Parquet file (") and "magic" in msg.lower()
    assert msg.endswith("a Parquet log is readable only once its writer has closed it")


def test_messages_of_long_lists_and_bad_bytes(tmp_path: Path) -> None:
    """What the reader says, word for word: at most 12 names (each cut at 40 characters) and how
    many more; the bad bytes of a line that is not UTF-8 (four at most), where on the line."""
    from thermoskin.logio.common import listing

    names = [f"c{k}" for k in range(15)]
    assert listing(names) == ", ".join(names[:12]) + " and 3 more"
    assert listing(names[:12]) == ", ".join(names[:12]) and listing(names, 2) == "c0, c1 and 13 more"
    long = "x" * 41
    assert listing(["y" * 40, long]) == "y" * 40 + ", " + "x" * 36 + "..."
    p = tmp_path / "x.csv"
    p.write_bytes(b"t,T_w\n0,1\n0.001,\xff\xfe\xfd\xfc\xfb\n")
    with pytest.raises(LogError) as e:
        read_log(p, required=("t",))
    assert str(e.value) == (f"{p}: line 3: not valid UTF-8 text (b'\\xff\\xfe\\xfd\\xfc' at byte 7 of "
                            "the line); save the log as UTF-8 CSV")


def test_blank_first_lines_and_a_blank_file(tmp_path: Path) -> None:
    """A file of blanks alone is empty; a blank first line before a header is not an empty file
    (its first line is the header, and blank: refused for that)."""
    p = tmp_path / "x.csv"
    p.write_text(" \n\t\n\n")
    with pytest.raises(LogError, match="empty file"):
        read_log(p, required=("t",))
    p.write_text("\nt,T_w\n0,1\n0.001,1\n")
    with pytest.raises(LogError) as e:
        read_log(p, required=("t",))
    assert "empty file" not in str(e.value)


def test_sample_time_of_two_samples() -> None:
    from thermoskin.logio import sample_time

    assert sample_time([0.0, 0.5]) == 0.5 and sample_time(np.array([[0.0, 1e-3, 2e-3]])) == 1e-3
    with pytest.raises(ValueError, match="at least 2 samples, got 1"):
        sample_time([1.0])


# ------------------------------------------------------------- Parquet: held edges (mutation run)


@pytest.mark.parametrize(("col", "value", "tail"), [
    ("q_i_hat", None, "null value (NaN is allowed only in temperature and velocity columns)"),
    ("contact", float("nan"), "NaN value (NaN is allowed only in temperature and velocity columns)"),
    ("t", float("nan"), "NaN value (t must be a finite number on every row)"),
    ("t", float("-inf"), "infinite value -inf (t must be a finite number on every row)"),
    ("T_w", float("inf"), "infinite value inf"),
])
def test_parquet_bad_value_messages_whole(tmp_path: Path, col: str, value: object, tail: str) -> None:
    """The whole message of a bad value, to its end: its row, column, what it is and the hint
    (t: must be finite; NaN where it is not allowed: where it is; an infinity elsewhere: none)."""
    table: dict[str, list[object]] = {c: [float(i) for i in range(5)] for c in HEADER.split(",")}
    table[col][2] = value
    p = _parquet(tmp_path, table)  # type: ignore[arg-type]
    assert _error(p) == f"{p}: row 3, column {col!r}: {tail}"


def test_few_values_counts_to_its_limit() -> None:
    """A dictionary is tried for a column of at most 1024 distinct values in its sample (every row
    of a column shorter than 2 x 4096 rows): 1024 yes, 1025 no; a column whose odd rows are all
    distinct is not few even when its even rows are one value."""
    from thermoskin.logio.parquetlog import few_values

    assert few_values(np.arange(1024.0)) and not few_values(np.arange(1025.0))
    odd = np.zeros(2050)
    odd[1::2] = np.arange(1.0, 1026.0)
    assert not few_values(odd)
    assert few_values(np.full(100, np.nan))  # NaN one value


def test_parquet_first_line_of_an_empty_error() -> None:
    """An Arrow error with no text is named by its type; otherwise its first line."""
    from thermoskin.logio.parquetlog import _first_line

    assert _first_line(OSError()) == "OSError"
    assert _first_line(ValueError("  one\ntwo")) == "one"


def test_parquet_column_count_limit_and_duplicates(tmp_path: Path) -> None:
    """4096 columns are a log's limit, read; 4097 refused; two columns of one name refused."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from thermoskin.logio.common import MAX_COLUMNS

    assert MAX_COLUMNS == 4096
    for n in (4096, 4097):
        names = ["t"] + [f"c{i}" for i in range(n - 1)]
        p = tmp_path / f"w{n}.parquet"
        pq.write_table(pa.Table.from_arrays([pa.array([0.0, 1.0])] * n, names=names), p)
        if n == 4096:
            assert len(read_log(p, required=("t",))) == 4096
        else:
            assert f"{n} columns, more than a log may have (4096)" in _error(p, required=("t",))
    p = tmp_path / "dup.parquet"
    pq.write_table(pa.Table.from_arrays([pa.array([0.0, 1.0])] * 3, names=["t", "T_w", "T_w"]), p)
    assert "duplicate column name(s): T_w" in _error(p, required=("t",))


def test_parquet_reader_chunks_and_writer_compression(tmp_path: Path) -> None:
    """Reading gives chunks of at most ``chunk_rows`` rows (bounded memory), 333 + 333 + 334 rows
    of a row group of 1000; the writer compresses with zstd; an integer patch index given as
    integers is stored as those integers."""
    import pyarrow.parquet as pq

    from thermoskin.logio import LogWriter

    n = 1000
    cols = {"t": np.arange(n) * 1e-3, "T_w": 24.0 + np.arange(n) * 1e-4}
    p = write_log(tmp_path / "c.parquet", cols)
    with LogReader(p, chunk_rows=333, required=("t",)) as r:
        sizes = [len(c["t"]) for c in r]
    assert sum(sizes) == n and max(sizes) <= 333
    meta = pq.ParquetFile(p).metadata
    assert {meta.row_group(0).column(i).compression for i in range(meta.num_columns)} == {"ZSTD"}
    skin = tmp_path / "skin.parquet"
    with LogWriter(skin, ["t", "patch"]) as w:
        w.write({"t": np.repeat([0.0, 0.001], 3), "patch": np.tile(np.arange(3, dtype=np.int32), 2)})
    assert pq.read_table(skin)["patch"].to_pylist() == [0, 1, 2, 0, 1, 2]


def test_reading_a_log_does_not_import_pandas(tmp_path: Path) -> None:
    """Reading a CSV or a Parquet log converts Arrow's columns from their buffers: pyarrow's own
    conversion imports pandas (0.2 s a command's start-up cannot afford). In a fresh interpreter
    (the package as imported here), after reading both, pandas is not loaded."""
    import subprocess
    import sys

    import thermoskin

    csv = tmp_path / "a.csv"
    csv.write_text("t,T_w\n0.0,24.0\n0.001,\n0.002,24.5\n", encoding="utf-8")
    pq = write_log(tmp_path / "a.parquet", {"t": np.arange(3) * 1e-3, "T_w": np.array([24.0, np.nan, 24.5])})
    code = ("import sys; from thermoskin.logio import read_log\n"
            "for p in sys.argv[1:]:\n"
            "    log = read_log(p, required=('t',), nan_columns=('T_w',))\n"
            "    assert log['T_w'][2] == 24.5 and log['T_w'][1] != log['T_w'][1], p\n"
            "print('pandas' in sys.modules)")
    for p in (csv, pq):  # here too: a mutation tool traces which tests reach which code in-process
        assert read_log(p, required=("t",), nan_columns=("T_w",))["T_w"][2] == 24.5
    env = {**os.environ, "PYTHONPATH": str(Path(thermoskin.__file__).resolve().parents[1])}
    out = subprocess.run([sys.executable, "-c", code, str(csv), str(pq)], capture_output=True, text=True,
                         env=env, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip() == "False"


def test_parquet_nulls_in_columns_arrow_converts(tmp_path: Path) -> None:
    """Columns converted by Arrow's own cast (float16, boolean): a null in a temperature reads as
    NaN, a null in a flag is refused as a null value at its row."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    p = tmp_path / "i.parquet"
    T_w = pa.array(np.array([24.0, 0.0, 25.0], np.float16), mask=np.array([False, True, False]))
    pq.write_table(pa.table({"t": [0.0, 0.5, 1.0], "T_w": T_w}), p)
    got = read_log(p, required=("t",), nan_columns=("T_w",))
    assert got["T_w"][0] == 24.0 and np.isnan(got["T_w"][1]) and got["T_w"][2] == 25.0
    q = tmp_path / "f.parquet"
    pq.write_table(pa.table({"t": [0.0, 0.5, 1.0], "contact": pa.array([False, True, None], pa.bool_())}), q)
    assert _error(q, required=("t",)) == (f"{q}: row 3, column 'contact': null value "
                                          "(NaN is allowed only in temperature and velocity columns)")


def test_parquet_reading_keeps_no_row_group_it_has_read(tmp_path: Path) -> None:
    """A Parquet log of 1.2 million rows (48 MB of float64 in 24 row groups) read chunk by chunk:
    Arrow's memory stays under 16 MB (the row groups read are not kept: memory does not grow with
    the log's length)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    n = 1_200_000
    rng = np.random.default_rng(1)
    p = tmp_path / "long.parquet"
    table = {"t": np.arange(n) * 1e-3, "T_w": rng.normal(24, 1, n), "T_p": rng.normal(24, 1, n),
             "v": rng.normal(0, 1, n), "T_a": rng.normal(20, 1, n)}
    pq.write_table(pa.table(table), p, row_group_size=50_000)
    base, peak, rows = pa.total_allocated_bytes(), 0, 0
    with LogReader(p, chunk_rows=50_000) as r:
        for c in r:
            rows += len(c["t"])
            peak = max(peak, pa.total_allocated_bytes() - base)
    assert rows == n and peak < 16e6, peak


# ------------------------------------------------- the shared helpers (logio.common), by hand


def test_short_keeps_a_message_one_short_line() -> None:
    """``short``: a value's repr up to 40 characters as it is; longer, its first 36 and ``...'``
    (40 in all); a huge field's start only; another limit taken."""
    from thermoskin.logio.common import short

    assert short("y" * 38) == "'" + "y" * 38 + "'"  # 40 characters: whole
    assert short("y" * 39) == "'" + "y" * 35 + "...'"  # 41: cut to 40
    assert short("x" * 10_000) == "'" + "x" * 35 + "...'"
    assert short(b"\xff" * 5) == repr(b"\xff" * 5)
    assert short(1.5) == "1.5"
    assert short("z" * 30, limit=10) == "'zzzzz...'"


def test_parse_value_by_hand() -> None:
    """One CSV field: a number, or why not (the words of the line's message)."""
    import math

    from thermoskin.logio.common import parse_value

    assert parse_value(" 2.5 ", False) == 2.5 and parse_value("-1e-3", False) == -0.001
    assert parse_value("", False) == "empty value" and parse_value("  ", False) == "empty value"
    assert parse_value("1_000", False) == "non-numeric value"
    assert parse_value("abc", False) == "non-numeric value"
    assert parse_value("nan", False) == "NaN value" and parse_value("-nan", False) == "NaN value"
    assert math.isnan(parse_value("-nan", True)) and math.isnan(parse_value("NA", True))  # type: ignore[arg-type]
    assert math.isnan(parse_value("", True))  # type: ignore[arg-type]
    assert parse_value("inf", True) == "infinite value"
    assert parse_value("-Infinity", False) == "infinite value"


def test_arrow_float64_from_buffers_by_hand() -> None:
    """Arrow columns read from their buffers: slices (an offset into a longer buffer) of int16 and
    float64 columns give just their values, nulls as NaN with their mask; an empty column is
    empty; a type it does not convert (float16) is left to the caller (None)."""
    import pyarrow as pa

    from thermoskin.logio.common import arrow_float64

    got = arrow_float64(pa.array(np.arange(10, dtype=np.int16))[2:5])
    assert got is not None and got[0].tolist() == [2.0, 3.0, 4.0] and got[1] is None
    col = pa.chunked_array([pa.array([1.5, None, 3.5, 4.5, None, 6.5])[1:5]])
    vals, mask = arrow_float64(col)  # type: ignore[misc]
    assert np.isnan(vals[0]) and vals[1:3].tolist() == [3.5, 4.5] and np.isnan(vals[3])
    assert mask.tolist() == [True, False, False, True]
    empty = arrow_float64(pa.array([], pa.float64()))
    assert empty is not None and empty[0].shape == (0,) and empty[1] is None
    assert arrow_float64(pa.array(np.ones(3, np.float16))) is None


def test_the_line_by_line_reader_values_and_messages(tmp_path: Path) -> None:
    """Fields the fast parsers refuse (`` NA`` with a space) send a block to the line-by-line
    reader: a quoted field is read as its number, `` NA`` as NaN where NaN is allowed; and its
    messages to their end: NaN-like text where NaN is not allowed (with the hint), other text
    (without), bad text in ``t`` (with t's hint), an empty line."""
    p = tmp_path / "slow.csv"
    p.write_text('t,T_w,T_p,v,T_a,contact\n0.0, NA,"25.5",0.1,20,0\n0.001,24.25,"25.5",0.1,20,1\n',
                 encoding="utf-8")
    log = read_log(p)
    assert np.isnan(log["T_w"][0]) and log["T_w"][1] == 24.25
    assert log["T_p"].tolist() == [25.5, 25.5] and log["t"].tolist() == [0.0, 0.001]
    assert log["contact"].tolist() == [0.0, 1.0] and log["T_a"].tolist() == [20.0, 20.0]
    head = "t,T_w,T_p,v,T_a,contact\n0.0,24,25,0.1,20,0\n"
    cases = {
        "0.001,24,25,0.1,20, NA\n": "line 3, column 'contact': non-numeric value ' NA' "
                                    "(NaN is allowed only in temperature and velocity columns)",
        "0.001,24,25,0.1,20,abc\n": "line 3, column 'contact': non-numeric value 'abc'",
        "abc,24,25,0.1,20,0\n": "line 3, column 't': non-numeric value 'abc' "
                                "(t must be a finite number on every row)",
        "\n0.002,24,25,0.1,20,0\n": "line 3: empty line, expected 6 fields (as in the header): ''",
        "0.001,24,25,0.1,20,-nan\n": "line 3, column 'contact': NaN value '-nan' "
                                      "(NaN is allowed only in temperature and velocity columns)",
    }
    for i, (row, want) in enumerate(cases.items()):
        q = tmp_path / f"bad{i}.csv"
        q.write_text(head + row, encoding="utf-8")
        assert _error(q) == f"{q}: {want}"


def test_the_line_by_line_reader_takes_a_line_of_64_kib_not_one_byte_more(tmp_path: Path) -> None:
    """A line of 65 536 bytes (the limit for six columns: 64 KiB, more than 6 x 128) is read
    (blanks before a number), one of 65 537 refused as it is."""
    head = "t,T_w,T_p,v,T_a,contact\n0.0, NA,25,0.1,20,0\n"
    start = "0.001,24,25,0.1,20,"
    for n, ok in ((65536, True), (65537, False)):
        p = tmp_path / f"l{n}.csv"
        p.write_text(head + start + " " * (n - len(start) - 1) + "1\n", encoding="utf-8")
        if ok:
            assert read_log(p)["contact"].tolist() == [0.0, 1.0]
        else:
            assert _error(p) == (f"{p}: line 3: a line of 65537 bytes, longer than a row of 6 numbers can be "
                                 "(65536 bytes at most): not a log row")


def test_blocks_of_a_csv_read_in_small_chunks(tmp_path: Path) -> None:
    """Read 10 rows at a time (blocks of 64 KiB): a first row of exactly 65 536 bytes (longer
    than a block: read on) and 4 000 rows after it come back whole and in order; a line past the
    limit after them is refused naming its own line (4 003), its blocks counted right."""
    head = "t,T_w,T_p,v,T_a,contact\n"
    first = "0.0,24,25,0.1,20,"
    first += " " * (65536 - len(first) - 1) + "0\n"
    rows = "".join(f"{k * 1e-3!r},{24 + k * 1e-4!r},25,0.1,20,{k % 2}\n" for k in range(1, 4001))
    p = tmp_path / "b.csv"
    p.write_text(head + first + rows, encoding="utf-8")
    with LogReader(p, chunk_rows=10) as r:
        got = list(r)
    t = np.concatenate([c["t"] for c in got])
    assert len(got) > 1 and np.array_equal(t, np.arange(4001) * 1e-3)
    assert np.concatenate([c["contact"] for c in got]).tolist() == [0.0] + [k % 2 for k in range(1, 4001)]
    q = tmp_path / "c.csv"
    q.write_text(head + first + rows + "4.001," + "9" * 300_000 + "\n", encoding="utf-8")
    with pytest.raises(LogError) as info, LogReader(q, chunk_rows=10) as r:
        list(r)
    msg = str(info.value)
    assert msg.startswith(f"{q}: line 4003: a line of ") and msg.endswith(
        "bytes or more, longer than a row of 6 numbers can be (65536 bytes at most): not a log row"), msg


def test_csv_header_limits_by_hand(tmp_path: Path) -> None:
    """A header of 4 096 columns is read, one of 4 097 refused; a header line of exactly 1 MiB
    (4 096 names, line end included) is read; an empty name is named by its column (from 1);
    a data line may take 128 bytes a column, 64 KiB at least."""
    from thermoskin.logio.common import max_line_bytes

    assert max_line_bytes(6) == 65536 and max_line_bytes(4096) == 128 * 4096
    for n in (4096, 4097):
        p = tmp_path / f"h{n}.csv"
        names = ["t"] + [f"c{i}" for i in range(1, n)]
        p.write_text(",".join(names) + "\n" + ",".join(["0"] * n) + "\n" + ",".join(["1"] * n) + "\n",
                     encoding="utf-8")
        if n == 4096:
            assert len(read_log(p, required=("t",))) == 4096
        else:
            assert _error(p, required=("t",)) == f"{p}: line 1: 4097 columns, more than a log may have (4096)"
    names = ["t"] + [f"c{i:04d}".ljust(255, "x") for i in range(1, 4095)]
    names.append("z" * (4096 * 255 - 1 - 4094 * 255))
    header = ",".join(names) + "\n"
    assert len(header.encode()) == 1 << 20
    p = tmp_path / "mib.csv"
    p.write_text(header + ",".join(["0"] * 4096) + "\n" + ",".join(["1"] * 4096) + "\n", encoding="utf-8")
    assert len(read_log(p, required=("t",))) == 4096
    p = tmp_path / "empty_name.csv"
    p.write_text("t,,T_w\n0,1,2\n1,1,2\n", encoding="utf-8")
    assert _error(p, required=("t",)) == f"{p}: line 1: column 2 has an empty name (header 't,,T_w')"


def test_a_csv_of_more_than_4_kib_without_a_final_line_end(tmp_path: Path) -> None:
    """The last line of a log, longer than 4 KiB (blanks before its last field) and without its
    line end, is read whole (its last field to its last digit)."""
    rows = "".join(f"{k * 1e-3!r},24.5,25,0.1,20\n" for k in range(400))
    p = tmp_path / "noend.csv"
    p.write_text("t,T_w,T_p,v,T_a\n" + rows + "0.4,24.5,25,0.1," + " " * 5000 + "21", encoding="utf-8")
    log = read_log(p)
    assert len(log["t"]) == 401 and log["T_a"][-1] == 21.0 and log["T_a"][-2] == 20.0


def test_column_names_and_dtypes_a_log_is_written_with() -> None:
    """``check_names``: a name that is not a string, empty, holds a comma, quote or line break, or
    has outer blanks is refused, a name with an X or a blank inside is not; ``as_column``: bools
    kept, integers int64, floats float64; ``writable``: a read-only or strided array copied."""
    from thermoskin.logio.common import as_column, check_names, writable

    check_names(["t", "T_w", "a X b"], "w")
    for bad in (1, "", "a,b", 'a"b', "a\nb", "a\rb", " a"):
        with pytest.raises(ValueError, match="invalid column name"):
            check_names(["t", bad], "w")  # type: ignore[list-item]
    b = np.array([True, False])
    assert as_column(b) is b
    assert as_column(np.array([1, 2], np.uint8)).dtype == np.int64
    assert as_column(np.array([1.5], np.float32)).dtype == np.float64
    ro = np.arange(3.0)
    ro.flags.writeable = False
    assert writable(ro) is not ro and writable(ro).flags.writeable
    strided = np.arange(6.0)[::2]
    assert writable(strided) is not strided and writable(strided).flags.c_contiguous
    ok = np.arange(3.0)
    assert writable(ok) is ok


def test_where_nan_is_allowed_and_the_first_bad_value_by_hand() -> None:
    """NaN is allowed in ``T_*``, ``v`` and ``v_*`` columns by default (not ``V_x``, not ``t``);
    a rule given as a function is asked for every column but ``t``; the first bad value is the
    first in reading order (row first, then column)."""
    from thermoskin.logio.common import allow_nan, first_bad_value

    names = ["t", "T_w", "v", "v_2", "V_x", "contact"]
    assert allow_nan(names) == [False, True, True, True, False, False]
    assert allow_nan(names, lambda n: n in ("t", "contact")) == [False, False, False, False, False, True]
    assert allow_nan(names, ("T_w",)) == [False, True, False, False, False, False]
    nan, inf = np.nan, np.inf
    cols = [np.array([0.0, 1.0, 2.0]), np.array([nan, 1.0, inf]), np.array([1.0, nan, 1.0])]
    assert first_bad_value(cols, [False, True, False]) == (1, 2)  # row 1, column 2 before row 2
    assert first_bad_value(cols, [False, True, True]) == (2, 1)   # the infinity in T_w
    cols = [np.array([0.0, 1.0]), np.array([1.0, inf]), np.array([1.0, nan])]
    assert first_bad_value(cols, [False, False, False]) == (1, 1)  # a tie: the first column


def test_check_time_non_uniform_message_by_hand() -> None:
    """A step off the median by more than 1 %: its interval, the times around it and the
    expected step with its tolerance; a step within the tolerance passes."""
    from thermoskin.logio.common import check_time

    k, why = check_time(np.array([0.0, 0.01, 0.02, 0.035, 0.045, 0.055]))  # type: ignore[misc]
    assert k == 3 and why == ("non-uniform sampling: interval 0.015 s (t = 0.02 -> 0.035), expected 0.01 s "
                              "± 1 % (read with uniform=False to accept jitter)")
    assert check_time(np.array([0.0, 0.01, 0.02, 0.0301, 0.0401])) is None
