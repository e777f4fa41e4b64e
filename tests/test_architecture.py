"""The package's layers (docs/architecture.md): import-linter's contracts in pyproject.toml hold
on the package, and fail on a copy of it where a lower layer imports a higher one, or where two
modules of one package import each other."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LINT = shutil.which("lint-imports", path=str(Path(sys.executable).parent)) or shutil.which("lint-imports")

pytestmark = pytest.mark.skipif(LINT is None, reason="import-linter is not installed")


def lint(src: Path, config: Path) -> subprocess.CompletedProcess[str]:
    """``lint-imports`` on the package found under ``src`` (a fresh import graph, no cache)."""
    env = {"PYTHONPATH": str(src), "PATH": str(Path(sys.executable).parent)}
    return subprocess.run([LINT, "--config", str(config), "--no-cache"], cwd=src.parent, env=env,
                          capture_output=True, text=True, timeout=120)


def test_the_layers_hold() -> None:
    p = lint(ROOT / "src", ROOT / "pyproject.toml")
    assert p.returncode == 0, p.stdout + p.stderr
    assert "Contracts: 2 kept, 0 broken." in p.stdout


def copy_package(tmp_path: Path) -> Path:
    src = tmp_path / "src"
    shutil.copytree(ROOT / "src" / "thermoskin", src / "thermoskin",
                    ignore=shutil.ignore_patterns("__pycache__", "*.nbi", "*.nbc"))
    return src


@pytest.mark.parametrize(("module", "line", "broken"), [
    # the physics asking the command line for something, in a function (a lazy import counts)
    ("physics/water.py", "def _up():\n    from thermoskin.cli.common import console\n", "Layers"),
    # the estimator reaching up into the skin of many patches
    ("estimation/events.py", "from thermoskin.skin.layout import Skin  # noqa\n", "Layers"),
    # two modules of one package importing each other
    ("estimation/dsp.py", "from thermoskin.estimation import observer  # noqa\n", "No import cycles"),
])
def test_an_upward_import_or_a_cycle_breaks_the_contract(tmp_path: Path, module: str, line: str,
                                                         broken: str) -> None:
    src = copy_package(tmp_path)
    target = src / "thermoskin" / module
    target.write_text(target.read_text(encoding="utf-8") + "\n\n" + line, encoding="utf-8")
    p = lint(src, ROOT / "pyproject.toml")
    assert p.returncode != 0, p.stdout
    assert f"{broken}" in p.stdout and "BROKEN" in p.stdout, p.stdout
