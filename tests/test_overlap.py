"""Reading ahead and writing behind (logio.overlap): same items, same order, same errors."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from thermoskin.logio import LogError, LogReader, LogWriter, WriteBehind, prefetch, read_log


def _slow(n: int, fail_at: int | None = None):
    for i in range(n):
        if i == fail_at:
            raise LogError(f"bad item {i}")
        time.sleep(0.001)
        yield i


@pytest.mark.parametrize("depth", [1, 3, 50])
def test_prefetch_gives_every_item_in_order(depth: int) -> None:
    assert list(prefetch(_slow(40), depth=depth)) == list(range(40))


def test_prefetch_raises_where_the_error_was() -> None:
    got = []
    with pytest.raises(LogError, match="bad item 7"):
        for x in prefetch(_slow(20, fail_at=7), depth=4):
            got.append(x)
    assert got == list(range(7))  # every item before the fault, none after


def test_prefetch_close_stops_the_worker() -> None:
    produced = []

    def items():
        for i in range(10_000):
            produced.append(i)
            yield i

    with prefetch(items(), depth=2) as it:
        assert next(it) == 0
    assert not any(t.name == "thermoskin-read" and t.is_alive() for t in threading.enumerate())
    assert len(produced) <= 5  # stopped after the items in the queue, not at the end


def test_prefetch_runs_ahead_while_the_caller_works() -> None:
    """The worker starts at once: items are ready before the first ``next``."""
    done = threading.Event()

    def items():
        yield 1
        done.set()
        yield 2

    it = prefetch(items(), depth=2)
    assert done.wait(5.0)
    assert list(it) == [1, 2]


class _Recorder:
    def __init__(self, fail_at: int | None = None) -> None:
        self.got: list[int] = []
        self.fail_at = fail_at

    def write(self, chunk) -> None:
        time.sleep(0.002)
        if chunk["i"] == self.fail_at:
            raise OSError(f"disk full at {chunk['i']}")
        self.got.append(chunk["i"])


def test_write_behind_keeps_the_order() -> None:
    rec = _Recorder()
    with WriteBehind(rec) as wb:
        for i in range(30):
            wb.write({"i": i})
    assert rec.got == list(range(30))


def test_write_behind_raises_the_writers_error_on_the_next_call() -> None:
    rec = _Recorder(fail_at=3)
    wb = WriteBehind(rec)
    with pytest.raises(OSError, match="disk full at 3"):
        for i in range(10):
            wb.write({"i": i})
    assert rec.got == [0, 1, 2]
    wb.close()


def test_write_behind_does_not_hide_the_first_error() -> None:
    rec = _Recorder(fail_at=0)
    with pytest.raises(KeyError), WriteBehind(rec) as wb:
        wb.write({"i": 0})  # fails in the worker
        raise KeyError("the caller's own error")


def test_a_log_through_both_threads_is_the_log(tmp_path) -> None:
    """Arrow in a worker thread reads the same values as in the caller's (CSV and Parquet)."""
    rng = np.random.default_rng(3)
    n = 5000
    cols = {"t": np.arange(n) * 1e-3, "T_w": 24 + rng.normal(0, 0.1, n), "T_p": 25 + rng.normal(0, 0.1, n),
            "v": np.where(rng.random(n) < 0.5, 0.0, 0.141), "T_a": np.full(n, 20.0)}
    for ext in ("csv", "parquet"):
        src, dst = tmp_path / f"a.{ext}", tmp_path / f"b.{ext}"
        with LogWriter(src, list(cols)) as w:
            w.write(cols)
        with LogReader(src, chunk_rows=700) as r, LogWriter(dst, list(cols)) as w, WriteBehind(w) as wb:
            for chunk in prefetch(r, depth=3):
                wb.write(chunk)
        back = read_log(dst)
        for k, a in cols.items():
            np.testing.assert_array_equal(back[k], a)
