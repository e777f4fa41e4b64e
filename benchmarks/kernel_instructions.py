"""The many-patch kernel's instructions per patch and sample, counted by valgrind, and its time.

Is the 1000-patch tick bound by waiting (memory, long chains of dependent arithmetic) or by
the number of instructions it executes? This counts them. N idle patches (each its own
thermocouple noise on a steady skin, after the detector's warm-up) are stepped by
:func:`~thermoskin.estimation.kernel.step_many_parallel` on one thread; ``valgrind
--tool=callgrind`` counts the instructions of the whole process for two tick counts, and
the difference over the extra patch-samples is the kernel's count per patch and sample
(the process's start-up cancels out). The same process, run natively, times those ticks.

Valgrind does not execute AVX-512, so the kernel is compiled for ``--cpu`` (default
``x86-64-v3``: AVX2 and FMA, no AVX-512) in a cache of its own, for the count and for the
native time alike. Needs ``valgrind`` on the PATH; about five minutes (numba's compile for
that CPU first, then two runs under valgrind, side by side).

Prints one JSON line ``{"n", "ticks", "cpu", "instructions_per_patch_sample",
"ns_per_patch_sample", "instructions_per_ns"}``. ``--branches`` also counts the conditional
branches a patch-sample and those valgrind's branch predictor (``--branch-sim=yes``: a simple
table of two-bit counters, not the EPYC's) mispredicts: ``"branches_per_patch_sample"``,
``"mispredicted_per_patch_sample"``. Whatever a real core predicts better, a branch on noise
(a CUSUM at zero or not) it cannot.

    python benchmarks/kernel_instructions.py [--n 500] [--ticks 200,1200] [--cpu x86-64-v3]
        [--branches] [--json]
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile

from _idle_patches import CHILD, child_env, child_options, tick_counts  # idle patches, timed


def native(args: list[str], env: dict[str, str]) -> str:
    """The child's output, run natively; a failure ends the script with its last words."""
    r = subprocess.run([sys.executable, "-c", CHILD, *args, "parallel"], capture_output=True, text=True,
                       env=env)
    if r.returncode:
        raise SystemExit(f"the child failed ({r.returncode}): {r.stderr.strip()[-400:]}")
    return r.stdout


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    child_options(ap, n=500, ticks="200,1200")
    ap.add_argument("--branches", action="store_true",
                    help="also count conditional branches and valgrind's mispredictions of them")
    ap.add_argument("--json", action="store_true", help="only the JSON line")
    a = ap.parse_args()
    if shutil.which("valgrind") is None:
        raise SystemExit("kernel_instructions.py: needs valgrind on the PATH")
    lo, hi = tick_counts(a.ticks)
    with tempfile.TemporaryDirectory(prefix="kernel_instructions_") as cache:
        env = child_env(cache, a.cpu, NUMBA_NUM_THREADS="1")
        if not a.json:
            print(f"compiling for {a.cpu} ...", file=sys.stderr)
        native([str(a.n), str(a.warm), "10"], env)  # fills the cache
        ns = [float(native([str(a.n), str(a.warm), str(hi)], env).split()[0]) for _ in range(5)]
        if not a.json:
            print("counting under valgrind ...", file=sys.stderr)
        sim = ["--branch-sim=yes"] if a.branches else []
        procs = [subprocess.Popen(["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null", *sim,
                                   sys.executable, "-c", CHILD, str(a.n), str(a.warm), str(t), "parallel"],
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
                 for t in (lo, hi)]
        counts, idle = [], []
        for p in procs:
            out, err = p.communicate()
            # the events: Ir, and with --branches Bc Bcm Bi Bim (conditional, mispredicted, indirect)
            m = re.search(r"Collected\s*:\s*([\d ]+)", err)
            if p.returncode or m is None:
                raise SystemExit(f"valgrind failed ({p.returncode}): {err.strip()[-400:]}")
            counts.append([int(x) for x in m.group(1).split()])
            idle.append(int(out.split()[1]))
    per_ev = [(y - x) / ((hi - lo) * a.n) for x, y in zip(counts[0], counts[1], strict=True)]
    per = per_ev[0]
    ns_med = sorted(ns)[len(ns) // 2]
    res = {"n": a.n, "ticks": [lo, hi], "cpu": a.cpu, "idle_patches": min(idle),
           "instructions_per_patch_sample": round(per, 1),
           "ns_per_patch_sample": round(ns_med, 1), "ns_runs": [round(x, 1) for x in ns],
           "instructions_per_ns": round(per / ns_med, 2)}
    if a.branches:
        res["branches_per_patch_sample"] = round(per_ev[1], 1)
        res["mispredicted_per_patch_sample"] = round(per_ev[2], 2)
    if not a.json:
        print(res)
    print(json.dumps(res))


if __name__ == "__main__":
    main()
