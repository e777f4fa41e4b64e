"""Reading ahead and writing behind: a log's I/O in worker threads while the caller computes.

Arrow's CSV and Parquet readers, polars' CSV writer, Arrow's Parquet writer and the compiled
estimation kernel all release the GIL, so on two cores a log streamed through
:func:`prefetch` and :class:`WriteBehind` is read, estimated and written at once: the wall
time of ``observe`` on a long log is about its slowest stage instead of their sum.

At most ``depth`` items are read ahead and one is written behind, so memory stays that of
a few chunks. An exception
in a worker is raised in the caller at the point where the item is needed (the next
``next()`` for reading; the next :meth:`WriteBehind.write` or :meth:`WriteBehind.close` for
writing), so errors name the same file, line and column as without the threads.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Iterable, Iterator, Mapping
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any, Protocol, TypeVar

T = TypeVar("T")
_ITEM, _END, _ERROR = 0, 1, 2


class prefetch(Iterator[T]):  # noqa: N801 (used as a function)
    """Iterate ``items`` with up to ``depth`` items produced ahead in a worker thread.

    The thread starts at once, so the caller can do other work (imports, set-up) while the
    first items are read. :meth:`close` (or the end of a ``with`` block) stops the worker."""

    def __init__(self, items: Iterable[T], depth: int = 1) -> None:
        if depth < 1:
            raise ValueError(f"prefetch: depth must be >= 1, got {depth}")
        self._q: queue.Queue[tuple[int, Any]] = queue.Queue(maxsize=depth)
        self._stop = threading.Event()
        self._done = False
        self._thread = threading.Thread(target=self._produce, args=(items,), daemon=True,
                                        name="thermoskin-read")
        self._thread.start()

    def _put(self, kind: int, x: Any) -> bool:
        while not self._stop.is_set():
            try:
                self._q.put((kind, x), timeout=0.05)
                return True
            except queue.Full:
                continue
        return False

    def _produce(self, items: Iterable[T]) -> None:
        try:
            for item in items:
                if not self._put(_ITEM, item):
                    return
            self._put(_END, None)
        except BaseException as e:  # handed to the caller, raised where the item is needed
            self._put(_ERROR, e)

    def __iter__(self) -> prefetch[T]:
        return self

    def __next__(self) -> T:
        if self._done:
            raise StopIteration
        kind, x = self._q.get()
        if kind == _ITEM:
            return x  # type: ignore[no-any-return]
        self.close()
        if kind == _ERROR:
            raise x
        raise StopIteration

    def close(self) -> None:
        """Stop the worker (after the item it is producing) and wait for it."""
        self._done = True
        self._stop.set()
        self._thread.join()

    def __enter__(self) -> prefetch[T]:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        self._stop.set()


class _Writer(Protocol):
    def write(self, chunk: Mapping[str, Any]) -> None: ...


class WriteBehind:
    """Hand each chunk to ``writer.write`` in a worker thread and return at once.

    The previous chunk's write is waited for first (one in flight), so the chunks reach the
    writer in order. :meth:`close` waits for the last one; the writer itself is closed by its
    owner. The chunk's arrays must not be changed after :meth:`write` (fresh arrays per
    chunk, as the estimators and readers give, are safe)."""

    def __init__(self, writer: _Writer) -> None:
        self.writer = writer
        self._ex = ThreadPoolExecutor(1, thread_name_prefix="thermoskin-write")
        self._fut: Future[None] | None = None

    def write(self, chunk: Mapping[str, Any]) -> None:
        self.wait()
        self._fut = self._ex.submit(self.writer.write, chunk)

    def wait(self) -> None:
        """Wait for the chunk in flight; raise its writer's exception, if any."""
        fut, self._fut = self._fut, None
        if fut is not None:
            fut.result()

    def close(self) -> None:
        try:
            self.wait()
        finally:
            self._ex.shutdown(wait=True)

    def __enter__(self) -> WriteBehind:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, *exc: object) -> None:
        if exc_type is None:
            self.close()
            return
        try:  # already failing: the writer's own error would only hide the first
            self.wait()
        except BaseException:
            pass
        finally:
            self._ex.shutdown(wait=True)
