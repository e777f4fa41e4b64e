"""The public API: `import thermoskin` exports it, and every example of docs/api.md runs."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import thermoskin

DOC = Path(__file__).resolve().parents[1] / "docs" / "api.md"


def test_every_name_resolves() -> None:
    for name in thermoskin.__all__:
        assert getattr(thermoskin, name) is not None, name


def test_import_is_light() -> None:
    """`import thermoskin` loads none of numba, scipy or polars (the CLI's start-up)."""
    code = ("import sys, thermoskin; print(sorted(m for m in ('numba', 'scipy', 'polars', 'pyarrow') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_docs_examples_run() -> None:
    """The page's python blocks, in order, in one namespace (they build on each other)."""
    blocks = re.findall(r"```python\n(.*?)```", DOC.read_text(encoding="utf-8"), re.S)
    assert len(blocks) >= 6
    ns: dict[str, object] = {}
    for i, block in enumerate(blocks):
        try:
            exec(compile(block, f"{DOC.name} block {i + 1}", "exec"), ns)
        except Exception as e:  # the failing block, in the message
            raise AssertionError(f"docs/api.md block {i + 1} fails: {e!r}\n{block}") from e


def test_readme_example_runs() -> None:
    """The README's Python example runs as it is, from the repository's root."""
    import os

    readme = DOC.parents[1] / "README.md"
    blocks = re.findall(r"```python\n(.*?)```", readme.read_text(encoding="utf-8"), re.S)
    assert blocks
    here = os.getcwd()
    os.chdir(readme.parent)
    try:
        for block in blocks:
            exec(compile(block, "README.md", "exec"), {})
    finally:
        os.chdir(here)


def test_no_public_name_hides_a_module() -> None:
    """A lazily exported name equal to a submodule's would replace ``thermoskin.<module>``
    once used (``thermoskin.fit.calibrate`` the function instead of the module)."""
    import pkgutil

    import thermoskin

    modules = {m.name for m in pkgutil.iter_modules(thermoskin.__path__)}
    assert not modules & set(thermoskin.__all__)
