"""`observe --skin` streams its log: the same outputs, events and positions as the whole log, block
by block, memory that does not grow with the log, and a fault in a late block still one line."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from thermoskin.logio import LogError, LogReader, write_log
from thermoskin.physics.finger import Touch
from thermoskin.sim.scenarios import Scenario
from thermoskin.sim.skin_scenarios import SkinContact, SkinScenario
from thermoskin.skin.layout import load_skin

ROOT = Path(__file__).resolve().parent.parent
FOREARM = ROOT / "examples" / "forearm.toml"


@pytest.fixture(scope="module")
def skin_log(tmp_path_factory):  # type: ignore[no-untyped-def]
    """A forearm's closed loop with three touches on the patches with two thermocouples (whose
    positions are located), as Parquet and as CSV."""
    from thermoskin.runtime.skin_loop import run_skin
    from thermoskin.skin.log import long_columns, read_skin_log

    skin = load_skin(FOREARM)
    base = Scenario("t", "test", duration=19.0, T_w_cmd=24.0, T_a=20.0, pump="logic")
    touches = [SkinContact(Touch(t_on=10.0, duration=2.5, n_fingers=3, person="man1"), patch="dorsal1",
                           position=0.015),
               SkinContact(Touch(t_on=11.0, duration=3.0, n_fingers=2, person="man1"), patch="ventral1",
                           position=0.01),
               SkinContact(Touch(t_on=15.0, duration=1.5, n_fingers=3, person="man1"), patch="dorsal2",
                           position=0.02)]
    d = tmp_path_factory.mktemp("skinlog")
    pq = d / "log.parquet"
    run_skin(skin, SkinScenario("t", "test", base, tuple(touches)), pq)
    csv = d / "log.csv"
    write_log(csv, long_columns(read_skin_log(pq, skin), {}))
    return skin, pq, csv


@pytest.mark.parametrize("fmt", ["parquet", "csv"])
def test_streamed_observation_is_the_whole_logs(skin_log, tmp_path, fmt) -> None:  # type: ignore[no-untyped-def]
    """Blocks of 997 samples (cut anywhere: mid-contact, mid-window of a position) give the outputs,
    events and positions of :func:`observe_skin` on the whole log read at once."""
    from thermoskin.skin.log import SkinLogReader, long_columns, read_skin_log
    from thermoskin.skin.observe import observe_skin, observe_skin_file

    skin, pq, csv = skin_log
    path = pq if fmt == "parquet" else csv
    log = read_skin_log(path, skin)
    whole = observe_skin(log, skin)
    out = tmp_path / f"o.{fmt}"
    got = observe_skin_file(path, skin, out, chunk_samples=997)
    assert got.n == log.n and got.t_s == pytest.approx(log.t_s, rel=1e-9)  # the first block's median
    assert [(e.patch, e.event) for e in got.events] == [(e.patch, e.event) for e in whole.events]
    located = [e for e in whole.events if math.isfinite(e.position.mean)]
    assert len(located) >= 2, whole.events  # the windows are exercised
    for a, b in zip(whole.events, got.events, strict=True):
        assert (a.position.mean, a.position.sd, a.position.heat) == pytest.approx(
            (b.position.mean, b.position.sd, b.position.heat), nan_ok=True, rel=0, abs=0)
    expect = long_columns(log, {"T_in": whole.T_in, **whole.columns})
    read: dict[str, list[np.ndarray]] = {}
    for _, cols in SkinLogReader(out, skin):
        for k, v in cols.items():
            read.setdefault(k, []).append(v)
    assert list(read) == list(expect)
    for k, v in expect.items():
        np.testing.assert_array_equal(np.concatenate(read[k]).ravel(), np.asarray(v, dtype=float), err_msg=k)


def test_without_an_output_the_observation_leaves_nothing(skin_log, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """``output=None`` (``run --skin``'s check of its live contacts): the same events and positions
    as with an output, through a temporary file beside the log that is gone afterwards."""
    import shutil

    from thermoskin.skin.observe import observe_skin_file

    skin, pq, _ = skin_log
    log = tmp_path / "log.parquet"
    shutil.copy(pq, log)
    a = observe_skin_file(log, skin, tmp_path / "o.parquet")
    before = sorted(p.name for p in tmp_path.iterdir())
    b = observe_skin_file(log, skin, None)
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    def rows(o):  # type: ignore[no-untyped-def]
        return [(e.patch, e.event, e.position) for e in o.events]

    assert rows(a) == rows(b) and any(math.isfinite(e.position.mean) for e in b.events)


def test_streamed_memory_does_not_follow_the_log(skin_log, tmp_path, peak_memory) -> None:  # type: ignore[no-untyped-def]
    """The arrays the streamed observation holds at once (``tracemalloc``: numpy's allocations;
    CSV out, whose writer hands its rows over every 65 536) are a few blocks' and a few seconds'
    for each contact's position, not the log's: no more for a log twice as long, and less than
    the whole log's observation holds, which is at least the log's columns. (A Parquet output
    holds a row group, 262 144 rows, before writing it: bounded too.)"""
    from thermoskin.skin.log import long_columns, read_skin_log
    from thermoskin.skin.observe import observe_skin, observe_skin_file

    skin, pq, _ = skin_log
    log = read_skin_log(pq, skin)
    twice = tmp_path / "twice.parquet"
    cols = long_columns(log, {})
    n = log.n * len(skin.patches)
    write_log(twice, {k: np.concatenate((v, v + (log.t[-1] - log.t[0] + log.t_s) if k == "t" else v))
                      for k, v in cols.items()})
    del log, cols

    observe_skin_file(pq, skin, tmp_path / "warm.csv", chunk_samples=1000)  # compiled, imported
    p_whole = peak_memory(lambda: observe_skin(read_skin_log(pq, skin), skin))
    p_one = peak_memory(lambda: observe_skin_file(pq, skin, tmp_path / "a.csv", chunk_samples=1000))
    p_two = peak_memory(lambda: observe_skin_file(twice, skin, tmp_path / "b.csv", chunk_samples=1000))
    assert p_whole > 8 * n * 8  # the whole log's arrays: (n, P) columns of 8 bytes, many of them
    assert p_two < 1.1 * p_one, (p_one, p_two)
    assert p_one < p_whole, (p_one, p_whole)


def _rows(P: int, n: int) -> dict[str, np.ndarray]:
    t = np.repeat(np.arange(n) * 1e-3, P)
    return {"t": t, "patch": np.tile(np.arange(P), n), "T_w": np.full(n * P, 24.0),
            "T_p": np.full(n * P, 25.0), "v": np.zeros(n * P), "T_a": np.full(n * P, 20.0)}


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_a_skin_log_read_in_whole_samples(tmp_path, fmt) -> None:  # type: ignore[no-untyped-def]
    """``LogReader(rows_per_sample=P)`` gives chunks of whole samples whatever ``chunk_rows`` (7 rows
    of a 3-patch log: 2 samples, the row left over carried to the next chunk), with ``t_s`` the
    sample interval, not 0 between a sample's rows."""
    p = tmp_path / f"s.{fmt}"
    write_log(p, _rows(3, 50))
    with LogReader(p, rows_per_sample=3, chunk_rows=7) as r:
        chunks = list(r)
    assert all(len(c["t"]) % 3 == 0 for c in chunks) and sum(len(c["t"]) for c in chunks) == 150
    assert r.t_s == pytest.approx(1e-3) and r.rows == 150
    np.testing.assert_array_equal(np.concatenate([c["patch"] for c in chunks]), np.tile(np.arange(3), 50))


class ThreePatches:
    """What :class:`~thermoskin.skin.log.SkinLogReader` asks of a skin."""

    name = "three"
    patches = (0, 1, 2)


def _carried_edges(p: Path, monkeypatch, chunk_rows: int) -> list[int]:  # type: ignore[no-untyped-def]
    """The log's rows where its source's raw chunks end, among them those that cut a sample (the
    rows after it carried to the next chunk)."""
    edges: list[int] = []
    checked = LogReader._checked

    def spy(self):  # type: ignore[no-untyped-def]
        for cols in checked(self):
            edges.append((edges[-1] if edges else 0) + len(cols[0]))
            yield cols

    with monkeypatch.context() as m:
        m.setattr(LogReader, "_checked", spy)
        with LogReader(p, rows_per_sample=3, chunk_rows=chunk_rows) as r:
            for _ in r:
                pass
    return [e for e in edges[:-1] if e % 3]


FAULTS = ("patch", "t", "order", "inf", "text", "dropped")


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_a_fault_at_a_carried_sample_is_one_line_naming_its_row(tmp_path, monkeypatch, fmt) -> None:  # type: ignore[no-untyped-def]
    """A skin log's fault on either side of a raw chunk's end that cuts a sample (its rows carried
    to the next chunk: CSV blocks of 64 KiB; Parquet batches of 100 rows, which the skin's reader,
    asking whole samples, never cuts by itself), far into the log: one
    :class:`LogError` naming the file's line (CSV) or row (Parquet) of the fault, whether from the
    reader (``t`` within a sample, ``t`` not increasing, an infinite or a text value) or from the
    skin's own check of the patches' order, which comes first (a dropped row is a patch out of
    place, not a sample of two times)."""
    from thermoskin.logio import LogWriter
    from thermoskin.skin.log import RTOL, SkinLogReader, _nan_ok

    P, n = 3, 20_000
    base = tmp_path / f"base.{fmt}"
    with LogWriter(base, list(_rows(P, 1)), row_group_rows=100) as w:
        w.write(_rows(P, n))
    chunk_rows = 192 if fmt == "csv" else 100
    edges = [e for e in _carried_edges(base, monkeypatch, chunk_rows) if e > 6000]
    assert len(edges) >= 2, edges  # the faults below do fall at carried samples
    place = (lambda r: f"line {r + 2}") if fmt == "csv" else (lambda r: f"row {r + 1}")
    checked = 0
    for e in edges[:2]:
        for r in (e - 1, e, e + 1):
            for fault in FAULTS:
                if fault == "text" and fmt == "parquet":
                    continue
                cols = _rows(P, n)
                if fault == "patch" or fault == "dropped":
                    if r % P == 0:
                        continue  # patch 0 set to 0 is no fault
                    if fault == "patch":
                        cols["patch"][r] = 0
                    else:
                        cols = {k: np.delete(v, r) for k, v in cols.items()}
                    want = f"{place(r)}, column 'patch'"
                elif fault == "t":
                    if r % P == 0:
                        continue
                    cols["t"][r] += 0.5e-3
                    want = f"{place(r)}, column 't'"
                elif fault == "order":
                    k0 = r - r % P  # the sample's first row
                    cols["t"][k0:k0 + P] = cols["t"][k0 - P]
                    want = f"{place(k0)}, column 't': time not strictly increasing"
                elif fault == "inf":
                    cols["T_w"][r] = np.inf
                    want = f"{place(r)}, column 'T_w'"
                p = tmp_path / f"bad.{fmt}"
                with LogWriter(p, list(cols), row_group_rows=100) as w:
                    w.write(cols)
                if fault == "text":
                    lines = p.read_text().splitlines()
                    f = lines[r + 1].split(",")
                    f[2] = "warm"
                    lines[r + 1] = ",".join(f)
                    p.write_text("\n".join(lines) + "\n")
                    want = f"{place(r)}, column 'T_w'"
                reader = SkinLogReader(p, ThreePatches(), chunk_samples=64)  # type: ignore[arg-type]
                reader._r = LogReader(p, ("t",), _nan_ok, chunk_rows=chunk_rows, rows_per_sample=P,
                                      check=reader._patches, rtol=RTOL)
                with pytest.raises(LogError) as exc:
                    for _ in reader:
                        pass
                msg = str(exc.value)
                assert "\n" not in msg and msg.startswith(str(p)) and want in msg, (fault, r, msg)
                checked += 1
    assert checked >= 20


@pytest.mark.parametrize(("fault", "needle"), [
    ("cut", "the last sample (line 1502 on) has 1 of its 3 rows"),
    ("jitter", "line 1202, column 't': non-uniform sampling"),
    ("one patch", "column(s) patch missing (a skin log has t, patch"),
    ("one sample", "only 1 sample (3 rows)"),
])
def test_a_skin_log_fault_of_its_own(tmp_path, fault, needle) -> None:  # type: ignore[no-untyped-def]
    """Faults a skin log alone has, one line each: its last sample cut short, an interval 0.5 %
    long (a skin log's tolerance is 0.1 %, as before it was streamed), a single patch's log given
    for a skin's (said so), a log of one sample."""
    from thermoskin.skin.log import SkinLogReader

    cols = _rows(3, 500)
    if fault == "cut":
        cols = {k: np.r_[v, v[-3:][:1]] for k, v in cols.items()}
    elif fault == "jitter":
        cols["t"][1200:] += 0.005e-3
    elif fault == "one patch":
        cols = {k: v[::3] for k, v in cols.items() if k != "patch"}
    elif fault == "one sample":
        cols = {k: v[:3] for k, v in cols.items()}
    p = tmp_path / "bad.csv"
    write_log(p, cols)
    with pytest.raises(LogError) as exc:
        for _ in SkinLogReader(p, ThreePatches(), chunk_samples=64):  # type: ignore[arg-type]
            pass
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith(str(p)) and needle in msg, msg
    if fault == "one patch":
        assert "looks like one patch's log" in msg


def test_contacts_are_placed_by_the_logs_own_times(skin_log, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """A log whose clock runs 0.09 % slow (within the 0.1 % at which the estimator takes the
    configured interval): each contact's samples are found from the log's own times, so the
    positions are those of the same log with the configured interval, and a contact's window
    does not slide along the log (1.6 s in 30 minutes)."""
    from thermoskin.skin.log import long_columns, read_skin_log
    from thermoskin.skin.observe import observe_skin_file

    skin, pq, _ = skin_log
    cols = long_columns(read_skin_log(pq, skin), {})
    slow = tmp_path / "slow.parquet"
    write_log(slow, {**cols, "t": cols["t"] * 1.0009})
    a = observe_skin_file(pq, skin, tmp_path / "a.parquet")
    b = observe_skin_file(slow, skin, tmp_path / "b.parquet")
    assert [e.patch for e in a.events] == [e.patch for e in b.events]
    assert sum(math.isfinite(e.position.mean) for e in a.events) >= 2
    for x, y in zip(a.events, b.events, strict=True):
        assert y.event.onset == pytest.approx(1.0009 * x.event.onset, rel=1e-9)
        assert (y.position.mean, y.position.sd) == pytest.approx((x.position.mean, x.position.sd),
                                                                 rel=1e-9, nan_ok=True)


def test_observe_skin_of_a_bad_late_row_writes_nothing(skin_log, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """`observe --skin` on a log whose patch order breaks far into it: one error line, exit 2, no
    output (the log is checked whole before the first estimate is written)."""
    from click.testing import CliRunner

    from thermoskin.cli import main

    _, _, csv = skin_log
    lines = csv.read_text().splitlines()
    k = len(lines) - 40
    f = lines[k].split(",")
    f[1] = "7" if f[1] != "7" else "6"
    lines[k] = ",".join(f)
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(lines) + "\n")
    out = tmp_path / "o.csv"
    r = CliRunner().invoke(main, ["observe", "--skin", str(FOREARM), str(bad), "-o", str(out)])
    err = r.stderr.strip().splitlines() if r.stderr else r.output.strip().splitlines()
    assert r.exit_code == 2 and len(err) == 1, r.output
    assert f"line {k + 1}, column 'patch'" in err[0], err
    assert not out.exists() and not list(tmp_path.glob(".o.csv*"))
