"""The child process of ``kernel_instructions.py`` and ``kernel_profile.py``: idle patches on a
steady skin, each its own thermocouple noise, stepped by the many-patch kernel on one thread.

``python -c CHILD N WARM TICKS parallel|serial [OBJECT]``: ``WARM`` ticks (the detector's
warm-up: 1000), then ``TICKS`` timed ones, by ``step_many_parallel`` (``parallel``) or
``step_many`` (``serial``); prints the timed ticks' ns a patch-sample and the idle patches'
count. With ``OBJECT``, the serial kernel's compiled object is written there (only where it
was compiled in this process, not loaded from numba's cache).

Also the two scripts' common options (:func:`child_options`, :func:`tick_counts`) and the
child's environment (:func:`child_env`).
"""

from __future__ import annotations

import argparse
import os

CHILD = """
import sys, time
import numpy as np
from thermoskin.estimation import kernel as K
from thermoskin.params import load_config
from thermoskin.estimation.patches import PatchEstimators

n, warm, ticks = (int(x) for x in sys.argv[1:4])
pe = PatchEstimators(load_config(), n=n, parallel=sys.argv[4] == "parallel")
rng = np.random.default_rng(0)
m = warm + ticks
T_w = 30.0 + rng.normal(0.0, 0.01, (m, n))
T_p = 30.5 + rng.normal(0.0, 0.01, (m, n))
T_a = 22.0 + rng.normal(0.0, 0.01, (m, n))
iv = pe.index(np.full(n, pe.v_values[1]))
cmd, drive = np.full(n, np.nan), np.full(n, np.nan)
fresh = np.full(n, 7, dtype=np.int64)
t0 = 0
for k in range(m):
    if k == warm:
        t0 = time.perf_counter_ns()
    pe.tick(k * 1e-3, T_w[k], T_p[k], T_a[k], cmd, iv, drive, fresh)
dt = time.perf_counter_ns() - t0
if len(sys.argv) > 5:
    cres = K.step_many.overloads[K.step_many.signatures[0]]
    open(sys.argv[5], "wb").write(cres.library._get_compiled_object())
idle = int((pe.ST[:, K.MODE] == K.IDLE).sum())
print(f"{dt / max(ticks * n, 1):.3f} {idle}")
"""


def child_options(ap: argparse.ArgumentParser, n: int, ticks: str) -> None:
    """``--n``, ``--ticks``, ``--warm`` and ``--cpu``, with these defaults for the first two."""
    ap.add_argument("--n", type=int, default=n, help="patches")
    ap.add_argument("--ticks", default=ticks, help="the two tick counts counted (after the warm-up)")
    ap.add_argument("--warm", type=int, default=1100, help="ticks before them (the detector's warm-up: 1000)")
    ap.add_argument("--cpu", default="x86-64-v3", help="the CPU numba compiles for (valgrind: no AVX-512)")


def tick_counts(text: str) -> tuple[int, int]:
    """``--ticks LO,HI``: two counts, the first smaller; the script ends otherwise."""
    try:
        lo, hi = (int(x) for x in text.split(","))
    except ValueError:
        raise SystemExit(f"--ticks {text}: two whole numbers, LO,HI") from None
    if not 0 < lo < hi:
        raise SystemExit(f"--ticks {text}: two counts, the first smaller")
    return lo, hi


def child_env(cache: str, cpu: str, **more: str) -> dict[str, str]:
    """The child's environment: numba's cache in ``cache``, compiled for ``cpu`` alone."""
    return {**os.environ, "NUMBA_CACHE_DIR": cache, "NUMBA_CPU_NAME": cpu, "NUMBA_CPU_FEATURES": "",
            **more}
