"""Numba's on-disk cache, kept per version of the compiled sources.

Numba invalidates a cached function only when its own source file changes: a function that
calls a compiled function of another file (the sweep's batch inlines the estimator's ``step``)
keeps its cached machine code, old state layout included, after that other file changed,
and then reads and writes the state vectors at the old offsets (a crash, or wrong numbers,
after a ``git pull`` on an editable install). So the cache goes in a directory named by a
hash of every source file that holds compiled code; a change to any of them starts a fresh
one (the others are removed). ``NUMBA_CACHE_DIR`` set by the user is kept; this must run
before numba is imported (:mod:`thermoskin` imports it first).
"""

from __future__ import annotations

import hashlib
import os
import shutil
from pathlib import Path

HERE = Path(__file__).resolve().parent

COMPILED_ELSEWHERE = ("control/mpc.py", "physics/peltier.py", "sim/skin.py")
"""Modules of plain functions another module compiles (``njit(f)``: the sweep's batch compiles
the MPC's interval test, the tank's and the skin's own arithmetic), whose changes must renew
its cache too (numba would keep the caller's stale copy)."""

CONSTANTS_FROM = ("estimation/model.py", "estimation/events.py", "physics/finger.py", "sim/sensors.py")
"""Modules whose constants (upper-case names) a compiled module imports: numba freezes a
global's value into the machine code (the event record's layout, the onset threshold's rate
tolerance, the noise block's length)."""

SOURCES = ("estimation/kernel.py", "estimation/redate.py", "sweep/kernel.py", "sweep/qp.py",
           "sim/skin_plant.py", "sim/board_bank.py", "skin/transport.py", "fit/calibrate.py",
           *COMPILED_ELSEWHERE, *CONSTANTS_FROM)
"""Every module with compiled (``@njit``) code, relative to the package, and those of
:data:`COMPILED_ELSEWHERE` and :data:`CONSTANTS_FROM` (a test keeps it whole)."""

PREFIX = "numba-"


def sources_hash() -> str:
    """A short hash of the compiled sources' contents."""
    h = hashlib.sha1()
    for rel in SOURCES:
        h.update((HERE / rel).read_bytes())
    return h.hexdigest()[:12]


def cache_root() -> Path:
    """Where the cache directories live: beside the package if it is writable, else the
    user's cache directory."""
    local = HERE / "__pycache__"
    if os.access(HERE, os.W_OK) and (not local.exists() or os.access(local, os.W_OK)):
        return local
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "thermoskin"


def configure() -> None:
    """Set ``NUMBA_CACHE_DIR`` (module doc), unless the user did; remove stale directories."""
    if "NUMBA_CACHE_DIR" in os.environ:
        return
    try:
        root = cache_root()
        target = root / f"{PREFIX}{sources_hash()}"
        if root.is_dir():
            for old in root.glob(f"{PREFIX}*"):
                if old != target and old.is_dir():
                    shutil.rmtree(old, ignore_errors=True)
    except OSError:  # an unreadable install: numba's own default
        return
    os.environ["NUMBA_CACHE_DIR"] = str(target)


def has_compiled(where: str) -> bool:
    """Whether the cache holds compiled code of ``where``: ``package/module.function`` (e.g.
    ``estimation/kernel.step``), so that a command can say it is about to compile for a
    while; True where the cache is not where :func:`configure` put it (nothing to say then)."""
    d = os.environ.get("NUMBA_CACHE_DIR")
    if not d:
        return True
    folder, stem = where.split("/")
    try:  # numba's layout: <cache>/<package>_<hash of its path>/<module>.<function>-<line>...nbi
        return any(Path(d).glob(f"{folder}_*/{stem}-*.nbi"))
    except OSError:
        return True


def lean_loading() -> None:
    """Load cached compiled code without what only compiling needs (about 0.1 s of every
    command's start-up; each part harmless if numba is laid out otherwise).

    - A cached function is loaded without refreshing numba's registries: numba's
      ``Cache.load_overload`` first imports every module of its typing and lowering
      implementations (``numba.np.arraymath``, ``numba.cpython.*``, ...) and installs their
      registries, which a compilation reads but loading machine code from the cache does
      not (the machine code is linked against numba's runtime, initialised here as numba
      would). A compilation still refreshes them itself, first (``compiler.compile_extra``).
    - When a compilation does load them, numba's probe for BLAS is skipped
      (:func:`skip_blas_probe`).

    Called by :mod:`thermoskin._jit`, through which every compiled module imports numba."""
    try:
        from numba.core import caching, cpu
        from numba.core.runtime import rtsys
    except ImportError:
        return
    cache, ctx = getattr(caching, "Cache", None), getattr(cpu, "CPUContext", None)
    if cache is not None and hasattr(cache, "_load_overload") and hasattr(cache, "load_overload") \
            and not getattr(cache.load_overload, "lean", False):
        def load_overload(self, sig, target_context):  # type: ignore[no-untyped-def]
            rtsys.initialize(target_context)  # what refresh did that loading needs
            with self._guard_against_spurious_io_errors():
                return self._load_overload(sig, target_context)

        load_overload.lean = True  # type: ignore[attr-defined]
        cache.load_overload = load_overload
    registries = getattr(ctx, "load_additional_registries", None)
    if registries is not None and not getattr(registries, "lean", False):
        def load_additional_registries(self, _orig=registries):  # type: ignore[no-untyped-def]
            skip_blas_probe()
            return _orig(self)

        load_additional_registries.lean = True  # type: ignore[attr-defined]
        ctx.load_additional_registries = load_additional_registries


def skip_blas_probe() -> None:
    """Load numba's array registry without its probe for BLAS, which imports ``scipy.linalg``.

    Numba's first compiled call (a cached one too) imports ``numba.np.arraymath``, which at
    import checks that ``scipy.linalg.cython_blas`` imports, only to choose how it compiles
    the inner products of ``np.correlate`` and ``np.convolve``; that import is
    ``scipy.linalg`` whole, about 0.2 s of a short ``observe`` (0.3 s with what scipy imports
    of numpy). scipy is a dependency of this package, so the probe's answer is known: the
    module is imported here with the probe answering yes. Numba's linear algebra
    (``numba.np.linalg``, none of it used here) keeps its own checks. Called by
    :func:`lean_loading` as numba loads its registries to compile; harmless if numba has
    loaded the registry already or is laid out otherwise."""
    import sys

    if "numba.np.arraymath" in sys.modules:
        return
    try:
        import numba.np.linalg as nlinalg
    except ImportError:  # another layout of numba: it probes as usual
        return
    probe = getattr(nlinalg, "ensure_blas", None)
    if probe is None:
        return
    nlinalg.ensure_blas = lambda: None
    try:
        import numba.np.arraymath  # noqa: F401
    except ImportError:  # laid out otherwise: numba loads its registry (and probes) itself
        pass
    finally:
        nlinalg.ensure_blas = probe
