"""The compiled code's cache is per version of the compiled sources (thermoskin/_numba_cache.py)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from thermoskin import _numba_cache as nc


def test_every_compiled_module_is_hashed() -> None:
    import ast
    import re

    pkg = nc.HERE
    texts = {str(p.relative_to(pkg)): p.read_text(encoding="utf-8") for p in pkg.rglob("*.py")
             if p.name != "_numba_cache.py"}
    compiled = [k for k, t in texts.items() if "@njit" in t]
    # a plain function compiled by another module (``njit(...)(f)``): its own module counts too
    wrapped = {name for t in texts.values() for name in re.findall(r"njit\([^)]*\)\((\w+)\)", t)}
    defined_in = {k for k, t in texts.items() for name in wrapped
                  if re.search(rf"^def {name}\(", t, re.M) and "@njit" not in t}
    assert wrapped and defined_in == set(nc.COMPILED_ELSEWHERE)
    # a constant (an upper-case name) a compiled module imports from another of the package
    consts = {node.module.removeprefix("thermoskin.").replace(".", "/") + ".py" for k in compiled
              for node in ast.walk(ast.parse(texts[k]))
              if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("thermoskin.")
              and any(a.name.isupper() for a in node.names)}
    consts -= {k for k in compiled} | set(nc.COMPILED_ELSEWHERE)
    assert consts == set(nc.CONSTANTS_FROM)
    assert sorted(compiled + sorted(defined_in) + sorted(consts)) == sorted(nc.SOURCES)


def _cache_dir(env: dict[str, str]) -> str:
    code = "import thermoskin, os; print(os.environ.get('NUMBA_CACHE_DIR', ''))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env=env)
    return out.stdout.strip()


def test_import_sets_a_directory_named_by_the_sources(tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    got = _cache_dir(env)
    assert Path(got).name == nc.PREFIX + nc.sources_hash()
    # a user's choice is kept
    assert _cache_dir({**env, "NUMBA_CACHE_DIR": str(tmp_path)}) == str(tmp_path)


def test_the_hash_follows_the_contents(tmp_path: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    for rel in nc.SOURCES:
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_bytes((nc.HERE / rel).read_bytes())
    monkeypatch.setattr(nc, "HERE", tmp_path)
    a = nc.sources_hash()
    assert a == nc.sources_hash() and len(a) == 12
    k = tmp_path / "estimation/kernel.py"
    k.write_bytes(b"# changed\n" + k.read_bytes())
    assert nc.sources_hash() != a
    # configure: a stale directory goes, the current one is named by the hash
    stale = tmp_path / "__pycache__" / "numba-0123456789ab"
    stale.mkdir(parents=True)
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    nc.configure()
    assert not stale.exists()
    assert os.environ["NUMBA_CACHE_DIR"] == str(tmp_path / "__pycache__" / ("numba-" + nc.sources_hash()))


def test_has_compiled_looks_in_the_cache(tmp_path: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    assert not nc.has_compiled("estimation/kernel.step")  # a cold cache: the command says so
    (tmp_path / "estimation_0123").mkdir()
    (tmp_path / "estimation_0123" / "kernel.run_rows-985.py311.nbi").write_bytes(b"")
    assert nc.has_compiled("estimation/kernel.run_rows")
    assert not nc.has_compiled("estimation/kernel.step")
    assert not nc.has_compiled("sweep/kernel.run_rows")  # another package's module of that name
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    assert nc.has_compiled("estimation/kernel.step")  # not our cache: nothing to say


def test_the_cli_looks_up_real_cached_functions() -> None:
    """Every ``package/module.function`` the command line looks up (``_note_compile``) names a
    compiled function cached on disk: a misspelt name would never be found, and the command
    would say it is compiling on every run."""
    import importlib
    import re

    from numba.core.caching import FunctionCache

    from thermoskin import cli

    text = "".join(f.read_text(encoding="utf-8") for f in sorted((nc.HERE / "cli").glob("*.py")))
    names = set(re.findall(r'"([a-z_]+/[a-z_]+\.[A-Za-z_]+)"', text))
    assert {cli.common.ESTIMATOR_KERNEL, cli.common.PIPE_KERNEL, *cli.common.SKIN_KERNELS} <= names
    assert {"estimation/kernel.run", "sweep/kernel.run_rows"} <= names
    for name in sorted(names):
        folder, stem = name.split("/")
        module, function = stem.split(".")
        path = f"thermoskin.{module}" if folder == "thermoskin" else f"thermoskin.{folder}.{module}"
        f = getattr(importlib.import_module(path), function)
        assert isinstance(getattr(f, "_cache", None), FunctionCache), name
        assert "/".join(path.split(".")[1:]) + ".py" in nc.SOURCES, name  # its cache is renewed


def test_cached_code_loads_without_the_registries(tmp_path: Path) -> None:
    """A fresh process loads the cached kernel without numba's typing and lowering registries
    (``lean_loading``), and its numbers are still the plain-Python reference's; a compilation
    afterwards in that process loads the registries itself and compiles correctly."""
    import json

    import numpy as np

    from thermoskin.estimation.estimator import TouchEstimator
    from thermoskin.estimation.reference import ReferenceEstimator
    from thermoskin.params import load_config
    from thermoskin.sim.run import simulate
    from thermoskin.sim.scenarios import SCENARIOS

    cfg = load_config().replace(detector={"redate_readings": 0.0})
    log = simulate(SCENARIOS["one-finger"].with_duration(3.0), cfg)
    keys = ("t", "T_w", "T_p", "v", "T_a")
    np.savez(tmp_path / "log.npz", **{k: log[k] for k in keys})
    TouchEstimator(cfg).run(*(log[k] for k in keys))  # compiled into the cache if it was cold
    code = f"""
import json, sys
import numpy as np
from thermoskin.estimation.estimator import TouchEstimator
from thermoskin.params import load_config
log = np.load({str(tmp_path / 'log.npz')!r})
res = TouchEstimator(load_config().replace(detector={{"redate_readings": 0.0}})).run(
    *(log[k] for k in {keys!r}))
lean = not {{"numba.np.arraymath", "numba.typed.dictimpl"}} & set(sys.modules)  # refresh's imports
from numba import njit
f = njit(lambda a: np.cumsum(np.sort(a))[-1] + len(str(a.size)))  # needs the registries
print(json.dumps({{"lean": lean, "f": f(np.array([3.0, 1.0, 2.0])),
                  "q": res.columns["q_i_hat"].tolist(), "dq": res.columns["dq_i_hat"].tolist(),
                  "linalg": "scipy.linalg" in sys.modules}}))
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert got["lean"], "the cached kernel's load imported numba's registries"
    assert got["f"] == 7.0 and not got["linalg"]  # 6 + len("3"); the BLAS probe still skipped
    ref = ReferenceEstimator(cfg, cfg.sampling.t_s)
    q, dq = np.array(got["q"]), np.array(got["dq"])
    worst = 0.0
    for i, row in enumerate(zip(*(log[k].tolist() for k in keys), strict=True)):
        ref.step(*row)
        for a, b in ((q[i], ref.q_i_hat), (dq[i], ref.dq)):
            if a == a and b == b:
                worst = max(worst, abs(a - b))
    assert worst <= 1e-9, worst
