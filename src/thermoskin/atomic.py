"""Files written whole or not at all: a temporary file beside the target, renamed over it.

A full disk, a kill or an error while writing leaves the earlier file at the path as it was
(and no temporary file, unless killed outright). For what is written at once (a config, a
plot); logs and recordings, written as they go, have their own writers (``logio``,
``runtime.record``).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """A temporary path beside ``path`` to write to; renamed over ``path`` when the block ends
    without error (an earlier file's permissions kept; a symbolic link's target rewritten, the
    link kept), removed otherwise. A writer that picks its format by the extension must be
    told it (the temporary path ends in ``.tmp``)."""
    path = Path(os.path.realpath(path))  # a symbolic link: its target is what is rewritten
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        yield tmp
        if path.exists():  # the earlier file's permissions stay
            os.chmod(tmp, path.stat().st_mode & 0o7777)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def write_text(path: str | os.PathLike[str], text: str) -> None:
    """``Path(path).write_text(text)`` (UTF-8), whole or not at all."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def arrow_name(path: str | os.PathLike[str]) -> str | None:
    """``path`` as pyarrow takes a file name (UTF-8 text), or None where it is not one: under an
    ASCII locale a name holding other bytes comes as text with escaped bytes (surrogates), which
    pyarrow cannot encode."""
    s = os.fspath(path)
    try:
        s.encode("utf-8")
    except UnicodeEncodeError:
        return None
    return s


@contextlib.contextmanager
def arrow_target(path: str | os.PathLike[str], mode: str = "rb") -> Iterator[str | IO[Any]]:
    """What to hand pyarrow for ``path``: its name (:func:`arrow_name`), or where that cannot
    be, the file opened in ``mode`` for the block."""
    name = arrow_name(path)
    if name is not None:
        yield name
        return
    with open(path, mode) as fh:
        yield fh
