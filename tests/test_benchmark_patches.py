"""``benchmarks/patches.py``, the many-patch kernel's benchmark (issue 10's contract): one JSON
line with the tick's time and the difference from the plain-Python reference, on every core."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_patches_benchmark_prints_its_json_line(later_kernels) -> None:  # type: ignore[no-untyped-def]
    """A small run (80 patches: the parallel kernel), with a skin's detector: one line of JSON
    with the contract's keys, each patch within 1e-9 W of the reference. (``--peer`` is left to
    the benchmark's users: a peer is compiled without numba's cache, 13 s of the suite's CPU.)"""
    later_kernels("parallel")  # (compiled once for the suite, not again in the benchmark's process)
    r = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "patches.py"), "--n", "80",
                        "--ticks", "300", "--check", "1", "--skin-detector", "--json"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    lines = r.stdout.strip().splitlines()
    assert len(lines) == 1, r.stdout
    out = json.loads(lines[0])
    assert out["n"] == 80 and out["parallel"] is True and out["ticks"] == 300
    assert 0.0 < out["p50_us"] <= out["p99_us"]
    assert out["checked_patches"] == 1 and out["max_abs_diff_W"] <= 1e-9
    assert out["skin_detector"]["checked_patches"] == 1 and out["skin_detector"]["max_abs_diff_W"] <= 1e-9
    assert "peer" not in out
