"""Mutation testing of the modules outside the compiled kernel (``mutmut``): does the test suite
notice a small change in the protocol, the log I/O, the plausibility check, the sweep's
metrics, the events, the position or the supervisor? Prints JSON.

    pip install -e '.[test,mutation]'
    python benchmarks/mutation.py                    # every module below (about an hour on 2 cores)
    python benchmarks/mutation.py --module protocol --module plausible --workdir /tmp/mut
    python benchmarks/mutation.py --merge a.json b.json > docs/mutation.json  # runs module by module
    python benchmarks/mutation.py --table docs/mutation.json                  # docs/reliability.md's table

For each run the script copies ``src``, ``tests``, ``examples`` and ``benchmarks/skins`` into a
work folder (a temporary one unless ``--workdir``), writes mutmut's settings there (only the
modules asked for mutated; only their tests run; pytest in one process) and runs ``mutmut run``;
mutmut makes every mutant of those modules (an operator swapped, a number or a string changed,
an argument dropped, ...), and runs, for each, the tests that reach the mutated function. Raise
statements are left as they are (what an error says is held by the one-line tests; a mutant of
its words changes no behaviour; the conditions that raise are mutated). A
mutant the tests fail on is *killed*; one they pass on *survived*. In the sweep's engine only
:func:`~thermoskin.sweep.engine.score` (the metrics) is mutated: the rest is the batched
simulation, which ``tests/test_sweep.py`` holds to the one-point runs (minutes per mutant).

The JSON: the date, the commit and the command; per module the mutants, killed, survived,
timed out (a mutant that made a test hang: caught) and not reached by a test (``no tests``),
the survival rate (survived over the mutants the tests ran on: killed + survived + timed out),
and each survivor's name and diff (``mutmut show``). ``--merge`` joins the JSON of runs made
module by module (each module with its own run's date and commit) and sums the totals;
``--table`` prints the table of docs/reliability.md from such a JSON. ``--retest`` runs the
survivors of the run kept in ``--workdir`` again against the tests as they are now (which
tests reach which code traced again; a mutant killed before stays killed, the tests having only
been added to), for the tests written from a run's survivors; ``--report`` writes the JSON of a
kept run as it stands (one stopped before its end: the mutants not yet run again keep their
earlier status). docs/reliability.md lists the survivors of the last run with why each does not
matter.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: What each module is: the files mutated (``src/thermoskin/...``), the functions of them mutated
#: (None: every one), the tests that hold them.
MODULES: dict[str, tuple[list[str], list[str] | None, list[str]]] = {
    "protocol": (["devices/protocol.py"], None, ["tests/test_protocol.py", "tests/test_properties.py"]),
    # the log I/O without test_properties.py: its readers' examples took a minute a mutant
    "logio": (["logio/common.py", "logio/csvlog.py", "logio/parquetlog.py", "logio/units.py"], None,
              ["tests/test_logio.py", "tests/test_units.py"]),
    "plausible": (["logio/plausible.py"], None, ["tests/test_plausible.py"]),
    "sweep-metrics": (["sweep/engine.py"], ["score"],
                      ["tests/test_sweep.py::test_metrics_from_hand_numbers"]),
    "events": (["estimation/events.py"], None, ["tests/test_events_stream.py", "tests/test_touchkind.py"]),
    "position": (["skin/position.py"], None, ["tests/test_skin_position.py"]),
    "supervisor": (["runtime/supervisor.py"], None, ["tests/test_supervisor.py"]),
}


def only_functions(path: Path, names: list[str]) -> None:
    """Mark everything in ``path`` but the top-level functions ``names`` ``# pragma: no mutate``."""
    lines = path.read_text(encoding="utf-8").splitlines()
    out = ["# pragma: no mutate start"]
    inside = False
    for ln in lines:
        m = re.match(r"def (\w+)\(", ln)
        if m and m.group(1) in names and not inside:
            out.append("# pragma: no mutate end")
            inside = True
        elif inside and ln and not ln[0].isspace() and not ln.startswith(")"):
            out.append("# pragma: no mutate start")
            inside = False
        out.append(ln)
    if not inside:
        out.append("# pragma: no mutate end")
    path.write_text("\n".join(out) + "\n", encoding="utf-8")


def settings(files: list[str], tests: list[str]) -> str:
    q = lambda xs: "[" + ", ".join(json.dumps(x) for x in xs) + "]"  # noqa: E731
    return ("\n[tool.mutmut]\n"
            'source_paths = ["src"]\n'
            'also_copy = ["examples", "benchmarks/skins"]\n'
            f"only_mutate = {q(['src/thermoskin/' + f for f in files])}\n"
            f"pytest_add_cli_args = {q(['-p', 'no:cacheprovider', '-p', 'no:randomly', '-x', '-q'])}\n"
            f"pytest_add_cli_args_test_selection = {q(tests)}\n"
            "timeout_multiplier = 10.0\n"
            # what an error says is not mutated (its words are checked by the one-line tests; a
            # mutant of a message's text changes no behaviour): a raise statement, whole
            'do_not_mutate_patterns = ["^\\\\s*raise\\\\b"]\n'
            # each mutant's tests in a process forked from one that never ran a test: forked from
            # one that had, numba's worker threads (started by the compiled kernels) were lost
            # in the child, and its first parallel call hung
            'process_isolation = "forkserver"\n')


def prepare(work: Path, modules: list[str]) -> None:
    if work.exists():
        shutil.rmtree(work)
    work.mkdir(parents=True)
    for d in ("src", "tests", "examples"):
        shutil.copytree(ROOT / d, work / d, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    shutil.copytree(ROOT / "benchmarks" / "skins", work / "benchmarks" / "skins")
    text = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    text = re.sub(r'addopts = "[^"]*"', 'addopts = "-p no:xdist"', text)  # one process: mutmut forks
    files, tests = [], []
    for m in modules:
        fs, funcs, ts = MODULES[m]
        files += fs
        tests += [t for t in ts if t not in tests]
        if funcs is not None:
            for f in fs:
                only_functions(work / "src" / "thermoskin" / f, funcs)
    (work / "pyproject.toml").write_text(text + settings(files, tests), encoding="utf-8")


def mutmut(work: Path, *args: str, timeout: float | None = None) -> str:
    exe = Path(sys.executable).with_name("mutmut")
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    p = subprocess.run([str(exe), *args], cwd=work, capture_output=True, text=True, env=env, timeout=timeout)
    return p.stdout + p.stderr


def statuses(work: Path) -> dict[str, str]:
    """Each mutant's status in ``work`` (``mutmut results``)."""
    status: dict[str, str] = {}
    for ln in mutmut(work, "results", "--all", "true").splitlines():
        m = re.match(r"\s*([\w.]+__mutmut_\d+): (.+)$", ln)
        if m:
            status[m.group(1)] = m.group(2).strip()
    return status


def module_of(name: str) -> str:
    """The module key of a mutant's name (``thermoskin.devices.protocol.x_cobs_encode__mutmut_3``)."""
    for key, (files, _, _) in MODULES.items():
        for f in files:
            if name.startswith("thermoskin." + f.removesuffix(".py").replace("/", ".") + "."):
                return key
    return "?"


def totals(mods: list[dict[str, object]]) -> dict[str, object]:
    """Killed, survived, timed out over ``mods`` and the survival rate (module doc)."""
    tot = {k: sum(int(m.get(k, 0)) for m in mods) for k in ("killed", "survived", "timeout")}  # type: ignore[call-overload]
    ran = sum(tot.values())
    return {**tot, "survival_rate": round(tot["survived"] / ran, 4) if ran else None}


def merge(paths: list[str]) -> dict[str, object]:
    """One JSON from the JSON of several runs (or of earlier merges): each module as its run had
    it, with the run's date and commit, a later file's module replacing an earlier's; the totals
    summed."""
    out: dict[str, object] = {"modules": {}, "tool": None}
    for p in paths:
        run = json.loads(Path(p).read_text(encoding="utf-8"))
        out["tool"] = run.get("tool")
        for key, m in run["modules"].items():
            # a merged JSON (no date of its own) keeps each module's
            out["modules"][key] = {**m, "date": run.get("date", m.get("date")),  # type: ignore[index]
                                   "commit": run.get("commit", m.get("commit"))}
    out["total"] = totals(list(out["modules"].values()))  # type: ignore[attr-defined]
    return out


def table(path: str) -> str:
    """The Markdown table of a JSON (a run's or a merge's)."""
    d = json.loads(Path(path).read_text(encoding="utf-8"))
    rows = ["| module | mutants | killed | survived | timed out | not reached | survival |",
            "|---|---:|---:|---:|---:|---:|---:|"]
    pct = lambda r: "" if r is None else f"{100 * r:.1f} %"  # noqa: E731
    for key, m in d["modules"].items():
        rows.append(f"| {key} | {m['mutants']} | {m.get('killed', 0)} | {m.get('survived', 0)} | "
                    f"{m.get('timeout', 0)} | {m.get('no tests', 0)} | {pct(m['survival_rate'])} |")
    t = d["total"]
    n = sum(m["mutants"] for m in d["modules"].values())
    nr = sum(m.get("no tests", 0) for m in d["modules"].values())
    rows.append(f"| **all** | {n} | {t['killed']} | {t['survived']} | {t['timeout']} | {nr} | "
                f"**{pct(t['survival_rate'])}** |")
    return "\n".join(rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--module", action="append", choices=list(MODULES), help="(repeat) default: all")
    ap.add_argument("--workdir", default=None, help="work folder (emptied first; default: a temporary one)")
    ap.add_argument("--max-children", type=int, default=2)
    ap.add_argument("--keep", action="store_true", help="keep the work folder")
    ap.add_argument("--retest", action="store_true",
                    help="run the survivors of the run kept in --workdir again, against the tests now")
    ap.add_argument("--report", action="store_true", help="the JSON of the run in --workdir as it stands")
    ap.add_argument("--merge", nargs="+", metavar="JSON", help="join the JSON of runs made module by module")
    ap.add_argument("--table", metavar="JSON", help="print the Markdown table of a JSON")
    a = ap.parse_args()
    if a.merge:
        print(json.dumps(merge(a.merge), indent=1))
        return
    if a.table:
        print(table(a.table))
        return
    modules = a.module or list(MODULES)
    if (a.retest or a.report) and not (a.workdir and (Path(a.workdir) / "mutants").is_dir()):
        ap.error("--retest and --report need the --workdir of an earlier run")
    work = Path(a.workdir) if a.workdir else Path(tempfile.mkdtemp(prefix="thermoskin-mutation-"))
    # the commit whose tests are run (taken before: the run may outlast a commit)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                            text=True).stdout.strip()
    try:
        retested = None
        if a.report:
            log = ""
        elif a.retest:
            # the survivors of the run in --workdir again, against the tests as they are now
            before = [n for n, st in statuses(work).items() if st == "survived" and module_of(n) in modules]
            shutil.rmtree(work / "tests")
            shutil.copytree(ROOT / "tests", work / "tests", ignore=shutil.ignore_patterns("__pycache__"))
            # which tests reach which function, found again (mutmut would trace the new tests only)
            (work / "mutants" / "mutmut-stats.json").unlink(missing_ok=True)
            log = mutmut(work, "run", "--max-children", str(a.max_children), *before)
            retested = len(before)
        else:
            prepare(work, modules)
            log = mutmut(work, "run", "--max-children", str(a.max_children))
        if log:
            (work / "run.log").write_text(log, encoding="utf-8")
        status = statuses(work)
        out: dict[str, object] = {
            "date": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC"),
            "commit": commit, "command": "python benchmarks/mutation.py " + " ".join(sys.argv[1:]),
            "modules": {}, "tool": mutmut(work, "--version").strip()}
        if retested is not None:
            out["retested_survivors"] = retested
        for key in modules:
            names = [n for n in status if module_of(n) == key]
            counts: dict[str, int] = {}
            for n in names:
                counts[status[n]] = counts.get(status[n], 0) + 1
            ran = counts.get("killed", 0) + counts.get("survived", 0) + counts.get("timeout", 0)
            survivors = [{"name": n, "diff": mutmut(work, "show", n).strip()} for n in sorted(names)
                         if status[n] == "survived"]
            rate = round(counts.get("survived", 0) / ran, 4) if ran else None
            out["modules"][key] = {"mutants": len(names), **counts,  # type: ignore[index]
                                   "survival_rate": rate, "survivors": survivors}
        out["total"] = totals(list(out["modules"].values()))  # type: ignore[attr-defined]
        print(json.dumps(out, indent=1))
    finally:
        if not (a.keep or a.workdir):
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
