"""Checks of the files a command will write or read, made before any work starts.

A command that would fail only at its end (a directory given as ``-o``, a path under a
file, a folder it may not write to) wastes the run and may leave half its outputs. The
CLI therefore checks every output path first (:func:`check_output`): nothing is created
or left behind by the check itself (writability is probed with a temporary file in the
nearest existing folder, removed at once). Inputs (:func:`check_input`) are told apart
as missing, a directory, or unreadable.

Every problem raises :class:`PathError` (a ``ValueError``) with one line naming the
option, the path and the reason.

One writer per output (:func:`lock_output`): a command takes an exclusive lock on each of its
outputs before any work, on a file ``.NAME.lock`` beside it that holds the holder's process
id; a second command writing the same path is refused with one line naming that process.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
import time
from collections.abc import Iterable
from pathlib import Path

try:
    import fcntl
except ImportError:  # not POSIX: no locks (one writer per output is then the user's to keep)
    fcntl = None  # type: ignore[assignment]

#: Extensions of a log (``logio``).
LOG_SUFFIXES = (".csv", ".parquet")
#: Extensions matplotlib's Agg canvas writes.
PLOT_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg", ".webp", ".tif", ".tiff", ".eps", ".ps")


def shown(text: str) -> str:
    """``text`` (a title holding a file name) as any font can show it: bytes of a name that the
    locale could not decode (Python's escapes for them, lone surrogates) as U+FFFD."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return text.encode("utf-8", "surrogateescape").decode("utf-8", "replace")
    return text


class PathError(ValueError):
    """A path cannot be used; the message (one line) names the option, the path and why."""


def _nearest_existing(p: Path) -> Path:
    """``p``'s nearest existing ancestor (``p.parent`` first; the working folder for a bare name)."""
    q = p.parent if str(p.parent) else Path(".")
    while not q.exists() and not q.is_symlink():
        if q.parent == q:
            break
        q = q.parent
    return q


def _probe(folder: Path) -> str | None:
    """Why a new file cannot be created in ``folder`` (``None`` if it can): tried, then removed."""
    try:
        fd, tmp = tempfile.mkstemp(prefix=".thermoskin-probe-", dir=folder)
    except OSError as e:
        return e.strerror or str(e)
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(tmp)
    return None


def check_output(path: Path, option: str, suffixes: Iterable[str] | None = None,
                 what: str = "file") -> Path:
    """Check that ``path`` can be written as a file; return it.

    Refused: a directory; a path whose folder is a file (``x.csv/out.csv``); a folder in
    which no file can be created; an existing file that cannot be written; with
    ``suffixes``, any other extension. Missing folders are fine (the writers create them).
    """
    p = Path(path)
    if suffixes is not None:
        allowed = tuple(suffixes)
        if p.suffix.lower() not in allowed:
            raise PathError(f"{option} {p}: the {what} name must end in {' or '.join(allowed)}")
    if p.is_dir():
        raise PathError(f"{option} {p} is a directory, not a file; give the {what} a file name")
    base = _nearest_existing(p)
    if not base.is_dir():
        raise PathError(f"{option} {p}: cannot write there: {base} is a file, not a folder")
    if p.exists() and not os.access(p, os.W_OK):
        raise PathError(f"{option} {p}: cannot write: permission denied")
    why = _probe(base)
    if why is not None:
        raise PathError(f"{option} {p}: cannot write in the folder {base}: {why}")
    return p


def check_output_dir(path: Path, option: str) -> Path:
    """Check that ``path`` is, or can be made, a folder in which files can be written."""
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise PathError(f"{option} {p} is a file, not a folder")
    base = p if p.is_dir() else _nearest_existing(p / "x")
    if not base.is_dir():
        raise PathError(f"{option} {p}: cannot make the folder: {base} is a file, not a folder")
    why = _probe(base)
    if why is not None:
        raise PathError(f"{option} {p}: cannot write in the folder {base}: {why}")
    return p


def check_input(path: Path, what: str) -> Path:
    """Check that ``path`` is an existing, readable file (not a directory); return it."""
    p = Path(path)
    if p.is_dir():
        raise PathError(f"{what} {p} is a directory, not a file")
    if not p.exists():
        raise PathError(f"{what} {p} does not exist")
    if not os.access(p, os.R_OK):
        raise PathError(f"{what} {p}: cannot read: permission denied")
    return p


def not_an_input(path: Path, option: str, what: str, inputs: tuple[Path, ...]) -> None:
    """Refuse an output at the path of one of the command's ``inputs`` (by any name for it)."""
    for src in inputs:
        if path.exists() and src.exists() and path.samefile(src):
            raise PathError(f"{option} {path}: that is the input; write the {what} to another file")


def distinct(*paths: tuple[str, Path | None]) -> None:
    """Refuse two outputs of one command at the same path (one would overwrite the other)."""
    seen: dict[Path, str] = {}
    for option, p in paths:
        if p is None:
            continue
        key = Path(os.path.abspath(p))
        if key in seen:
            raise PathError(f"{option} {p} is also given as {seen[key]}: give each output its own file")
        seen[key] = option


class Replaced:
    """Files of an earlier run at the paths a run is about to write as it goes, moved aside
    (to a hidden sibling ``.NAME.previous``) before it opens its own: :meth:`close` removes
    them once the run wrote samples, and puts them back where it wrote none (no device
    answered, a live address refused, ...), so a run that fails to start loses nothing.
    A run killed outright (SIGKILL) leaves them aside, not lost."""

    def __init__(self, *paths: Path | None) -> None:
        self.aside: list[tuple[Path, Path]] = []
        for p in paths:
            if p is not None and p.is_file():
                a = p.with_name(f".{p.name}.previous")
                try:
                    os.replace(p, a)
                except OSError as e:  # put back what was moved; nothing is written
                    self.close(wrote=False)
                    raise PathError(f"cannot move the earlier {p} aside (to {a.name}) while the run "
                                    f"starts: {e.strerror or e}") from None
                self.aside.append((p, a))

    def close(self, wrote: bool) -> None:
        """The run is over: it ``wrote`` samples (its files stand) or not (the earlier ones
        come back in place of what it left)."""
        for p, a in self.aside:
            with contextlib.suppress(OSError):
                if wrote:
                    a.unlink()
                else:
                    os.replace(a, p)
        self.aside = []


def lock_file(path: Path) -> Path:
    """The file whose lock stands for the output ``path``: ``.NAME.lock`` beside it."""
    p = Path(path)
    return p.with_name(f".{p.name}.lock")


class OutputLock:
    """An exclusive lock on one output (:func:`lock_output`); :meth:`release` frees it, removes
    its lock file and the folders made for it that are still empty."""

    def __init__(self, path: Path, fd: int, made: list[Path]) -> None:
        self.path = path
        self.fd = fd
        self.made = made

    def release(self) -> None:
        if self.fd < 0:
            return
        with contextlib.suppress(OSError):  # removed while held: an acquirer that opened it
            os.unlink(self.path)            # before finds another file there and tries again
        os.close(self.fd)
        self.fd = -1
        for d in reversed(self.made):
            with contextlib.suppress(OSError):
                d.rmdir()  # only if empty: what the command wrote there stays
        self.made = []


def _holder(fd: int) -> str:
    """What the holder of the lock on ``fd`` wrote in it (its pid and command), read for up to
    0.2 s (a holder writes it just after it locks)."""
    for _ in range(20):
        with contextlib.suppress(OSError):
            text = os.pread(fd, 200, 0).decode("utf-8", "replace").strip()
            if text:
                pid, _, what = text.partition(" ")
                return f"{what or 'thermoskin'} (pid {pid})"
        time.sleep(0.01)
    return "another thermoskin command (pid unknown)"


def lock_output(path: Path, option: str, what: str = "file",
                command: str = "thermoskin") -> OutputLock | None:
    """Take the exclusive lock on the output ``path`` (its lock file :func:`lock_file`, made with
    its missing folders), writing this process's id and ``command`` in it; :class:`PathError`
    naming the holder if another process holds it. None where the OS has no such locks."""
    if fcntl is None:
        return None
    p = Path(path)
    folder = p.parent if str(p.parent) else Path(".")
    made: list[Path] = []
    missing = []
    q = folder
    while not q.exists() and q.parent != q:
        missing.append(q)
        q = q.parent
    lp = lock_file(p)
    try:
        for d in reversed(missing):
            try:
                d.mkdir()
                made.append(d)
            except FileExistsError:
                pass
        for _ in range(100):
            fd = os.open(lp, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = _holder(fd)
                os.close(fd)
                raise PathError(f"{option} {p}: another process is writing this {what}: {holder}; "
                                "wait for it to end, or give another path") from None
            try:  # the file locked may have been removed by its last holder meanwhile
                same = os.fstat(fd).st_ino == os.stat(lp).st_ino
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        else:  # pragma: no cover (a lock file removed under us a hundred times)
            raise PathError(f"{option} {p}: cannot lock {lp}")
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()} {command}\n".encode("utf-8", "replace"), 0)
    except OSError as e:
        for d in reversed(made):
            with contextlib.suppress(OSError):
                d.rmdir()
        raise PathError(f"{option} {p}: cannot lock it ({lp}: {e.strerror or e})") from None
    except BaseException:
        for d in reversed(made):
            with contextlib.suppress(OSError):
                d.rmdir()
        raise
    return OutputLock(lp, fd, made)
