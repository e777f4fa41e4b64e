"""Where the many-patch kernel's sample goes: valgrind's count of each of its instructions.

``benchmarks/kernel_instructions.py`` counts the whole process's instructions; this counts
each instruction of the compiled loop itself (:func:`~thermoskin.estimation.kernel.step_many`,
one thread) over the ticks of idle patches, so that the sample's own work is seen apart from
Python's: ``valgrind --tool=callgrind --dump-instr=yes --branch-sim=yes`` for two tick counts
(the difference over the extra patch-samples: the warm-up and start-up cancel out), joined
to ``objdump``'s listing of the compiled object (numba's cache of it). Per patch and sample:

- ``instructions``, ``branches`` (conditional), ``mispredicted`` (by valgrind's simple
  predictor, not the EPYC's: a branch on noise, e.g. a CUSUM at zero or not, no predictor
  foresees; a regular one the EPYC's predicts better);
- ``loads`` and ``stores`` (instructions reading or writing memory), of which
  ``stack_loads`` and ``stack_stores`` are the compiler's spills and reloads (``%rsp``);
- ``divisions`` and ``square_roots``.

Compiled for ``--cpu`` (default ``x86-64-v3``: valgrind does not run AVX-512; that build has
16 vector registers, the EPYC's 32, so it spills more than the native one). ``--listing
FILE`` writes the annotated listing (count a patch-sample, mispredicted, offset, instruction).
Needs ``valgrind`` and ``objdump``; about a minute.

    python benchmarks/kernel_profile.py [--n 200] [--ticks 100,400] [--listing FILE] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from collections import defaultdict

from _idle_patches import CHILD, child_env, child_options, tick_counts  # idle patches; the object

EVENTS = ("Ir", "Bc", "Bcm")
_FILE_KEYS = ("ob", "fn", "fl", "fi", "fe", "cob", "cfi", "cfn", "calls")


def costs(path: str) -> dict[int, list[int]]:
    """Instruction address -> (executed, conditional branches, mispredicted) of the hottest
    function of a callgrind output (the kernel: compiled code valgrind has no name for). The
    columns are found from the file's ``positions:`` and ``events:`` lines (a ``~/.valgrindrc``
    may add others)."""
    by_fn: dict[str, dict[int, list[int]]] = defaultdict(lambda: defaultdict(lambda: [0, 0, 0]))
    fn, last, after_call = "", 0, False
    npos, cols = 0, None
    with open(path) as f:
        for line in f:
            if line.startswith("positions:"):
                pos_names = line.split(":", 1)[1].split()
                if not pos_names or pos_names[0] != "instr":
                    raise SystemExit(f"{path}: positions {pos_names}, not by instruction (--dump-instr=yes)")
                npos = len(pos_names)
                continue
            if line.startswith("events:"):
                names = line.split(":", 1)[1].split()
                missing = [e for e in EVENTS if e not in names]
                if missing:
                    raise SystemExit(f"{path}: no {', '.join(missing)} among its events {names}")
                cols = [names.index(e) for e in EVENTS]
                continue
            key = line.split("=", 1)[0]
            if "=" in line and key in _FILE_KEYS:
                if key == "fn":
                    fn = line.split("=", 1)[1].split(")")[0]
                after_call = after_call or key == "calls"
                continue
            if not line.strip() or line[0] not in "0123456789+-*":
                continue
            if cols is None:
                raise SystemExit(f"{path}: costs before its events: line")
            parts = line.split()
            pos = parts[0]
            here = (int(pos, 16) if pos.startswith("0x") else last + int(pos) if pos[0] in "+-"
                    else last if pos == "*" else int(pos))
            if after_call:  # the call's inclusive cost, not this function's own
                after_call = False
                continue
            last = here
            vals = parts[npos:]
            c = by_fn[fn][last]
            for i, j in enumerate(cols):
                if j < len(vals):  # trailing zero costs are left out
                    c[i] += int(vals[j])
    hot = max(by_fn.values(), key=lambda d: sum(c[0] for c in d.values()))
    base = min(hot) & ~0xFFF  # the object's code section starts on a page of its own
    return {a - base: c for a, c in hot.items()}


def listing(obj: str) -> list[tuple[int, str]]:
    """(offset, instruction) of the object's first function (the kernel), in order."""
    out = subprocess.run(["objdump", "-d", "--no-show-raw-insn", obj], capture_output=True,
                         text=True, check=True).stdout
    rows, started = [], False
    for line in out.splitlines():
        if line.endswith(">:"):
            if started:
                break
            started = True
            continue
        m = re.match(r"\s+([0-9a-f]+):\s+(.*)", line)
        if m and started:
            rows.append((int(m.group(1), 16), re.sub(r"<[^>]*>", "", m.group(2)).strip()))
    return rows


#: instruction prefixes (padding, locks, repeats): the operation is the word after them
_PREFIXES = {"data16", "cs", "ds", "es", "ss", "lock", "rep", "repz", "repnz", "repe", "repne", "notrack"}


def classify(ins: str) -> dict[str, bool]:
    """What one instruction does: reads or writes memory (on the stack or not), divides, takes
    a square root. (``lea`` computes an address and a ``nop`` or a prefetch reads nothing.)"""
    words = ins.split()
    while words and words[0] in _PREFIXES:
        words = words[1:]
    op = words[0] if words else ""
    args = " ".join(words[1:])
    mem = [] if op.startswith(("lea", "nop", "prefetch")) else re.findall(r"\((%\w+)[^)]*\)", args)
    # AT&T order: the destination last; a move (masked too), or an add or a subtract, to
    # memory writes it
    store = bool(mem) and args.endswith(")") and op.startswith(("mov", "vmov", "vmaskmov", "add", "sub"))
    load = bool(mem) and not (store and op.startswith(("mov", "vmov", "vmaskmov")))
    stack = bool(mem) and mem[-1 if store else 0] == "%rsp"
    return {"loads": load, "stores": store, "stack_loads": load and stack,
            "stack_stores": store and stack, "divisions": "div" in op, "square_roots": "sqrt" in op}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    child_options(ap, n=200, ticks="100,400")
    ap.add_argument("--listing", default=None, metavar="FILE", help="write the annotated listing here")
    ap.add_argument("--json", action="store_true", help="only the JSON line")
    a = ap.parse_args()
    for tool in ("valgrind", "objdump"):
        if shutil.which(tool) is None:
            raise SystemExit(f"kernel_profile.py: needs {tool} on the PATH")
    lo, hi = tick_counts(a.ticks)
    with tempfile.TemporaryDirectory(prefix="kernel_profile_") as tmp:
        env = child_env(os.path.join(tmp, "cache"), a.cpu)
        obj = os.path.join(tmp, "kernel.o")
        if not a.json:
            print(f"compiling for {a.cpu} ...", file=sys.stderr)
        r = subprocess.run([sys.executable, "-c", CHILD, "4", "10", "10", "serial", obj], capture_output=True,
                           text=True, env=env)
        if r.returncode or not os.path.getsize(obj):
            raise SystemExit(f"the child failed ({r.returncode}): {r.stderr.strip()[-400:]}")
        if not a.json:
            print("counting under valgrind ...", file=sys.stderr)
        outs = [os.path.join(tmp, f"cg.{t}") for t in (lo, hi)]
        procs = [subprocess.Popen(["valgrind", "--tool=callgrind", "--dump-instr=yes", "--branch-sim=yes",
                                   f"--callgrind-out-file={out}", sys.executable, "-c", CHILD,
                                   str(a.n), str(a.warm), str(t), "serial"],
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
                 for t, out in zip((lo, hi), outs, strict=True)]
        idle = []
        for p in procs:
            out, err = p.communicate()
            if p.returncode:
                raise SystemExit(f"valgrind failed ({p.returncode}): {err.strip()[-400:]}")
            idle.append(int(out.split()[1]))
        c_lo, c_hi = costs(outs[0]), costs(outs[1])
        rows = listing(obj)
    per = (hi - lo) * a.n
    diff = {k: [(y - x) / per for x, y in zip(c_lo.get(k, [0] * 3), c_hi.get(k, [0] * 3), strict=True)]
            for k in set(c_lo) | set(c_hi)}
    offsets = {off for off, _ in rows}
    unmatched = sum(v[0] for k, v in diff.items() if k not in offsets)
    total = sum(v[0] for v in diff.values())
    if total <= 0 or unmatched > 0.01 * total:
        raise SystemExit(f"the counts do not fall on the kernel's instructions ({unmatched:.0f} of "
                         f"{total:.0f} a patch-sample): not the listing of the code that ran")
    sums: dict[str, float] = defaultdict(float)
    for off, ins in rows:
        n_ex = diff.get(off, [0.0] * 3)[0]
        for k, yes in classify(ins).items():
            if yes:
                sums[k] += n_ex
    res = {"n": a.n, "ticks": [lo, hi], "cpu": a.cpu, "idle_patches": min(idle),
           "instructions": round(total, 1), "branches": round(sum(v[1] for v in diff.values()), 1),
           "mispredicted": round(sum(v[2] for v in diff.values()), 2),
           **{k: round(sums[k], 1) for k in ("loads", "stores", "stack_loads", "stack_stores",
                                             "divisions", "square_roots")}}
    if a.listing:
        with open(a.listing, "w") as f:
            for off, ins in rows:
                c = diff.get(off, [0.0] * 3)
                f.write(f"{c[0]:8.3f} {c[2]:6.3f} {off:6x}  {ins}\n")
    if not a.json:
        print(res)
    print(json.dumps(res))


if __name__ == "__main__":
    main()
