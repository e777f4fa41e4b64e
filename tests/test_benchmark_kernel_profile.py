"""``benchmarks/kernel_profile.py``'s reading of callgrind's counts and of the listing (the
valgrind run itself is the script's, not the suite's)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def kp():  # type: ignore[no-untyped-def]
    """The script as a module (its folder on the path, as when it runs: it imports its child)."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    spec = importlib.util.spec_from_file_location("kernel_profile", ROOT / "benchmarks" / "kernel_profile.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(mod)
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    return mod


@pytest.mark.parametrize(("ins", "expect"), [
    ("vmovsd %xmm1,0xb0(%rsp)", {"stores", "stack_stores"}),
    ("vmovsd 0x10(%rsp),%xmm7", {"loads", "stack_loads"}),
    ("vmovsd 0x2b8(%r12),%xmm2", {"loads"}),
    ("movq   $0x0,0x530(%rdx,%rcx,8)", {"stores"}),
    ("add    %rax,0x140(%rsp)", {"loads", "stores", "stack_loads", "stack_stores"}),
    ("cmpq   $0x0,0x70(%rsp)", {"loads", "stack_loads"}),
    ("vfmadd231sd 0x140(%rsi),%xmm3,%xmm2", {"loads"}),
    ("lea    0x260(%r12),%rax", set()),
    ("nopw   0x0(%rax,%rax,1)", set()),
    ("vdivsd %xmm4,%xmm3,%xmm4", {"divisions"}),
    ("vsqrtsd %xmm1,%xmm1,%xmm3", {"square_roots"}),
    ("jae    3138", set()),
    ("vmaskmovpd %ymm3,%ymm0,0x420(%r14)", {"stores"}),
    ("vmaskmovpd 0x420(%r14),%ymm0,%ymm3", {"loads"}),
    ("data16 cs nopw 0x0(%rax,%rax,1)", set()),
])
def test_each_instruction_is_classified(kp, ins: str, expect: set[str]) -> None:  # type: ignore[no-untyped-def]
    """Loads, stores (AT&T order: the destination last), the stack's apart, on hand-picked
    instructions of the kernel's listing."""
    got = {k for k, v in kp.classify(ins).items() if v}
    assert got == expect


def test_costs_reads_the_hottest_function_relative_to_its_page(kp, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """A callgrind file in its compressed form (absolute, +relative and * positions; a call's
    inclusive cost line skipped): the hottest function's own counts, by offset from its page."""
    f = tmp_path / "cg.out"
    f.write_text("""# callgrind format
positions: instr line
events: Ir Bc Bcm

ob=(1) /usr/bin/python
fn=(1) main
0x401000 0 5
cfn=(2)
calls=1 0x7f0000001000 0
* 0 1000 40 3

ob=(2) ???
fn=(2) 0x7f0000001000
0x7f0000001000 0 100
+4 0 100 100 7
* 0 20
+8 0 300
""")
    c = kp.costs(str(f))
    assert c == {0x0: [100, 0, 0], 0x4: [120, 100, 7], 0xC: [300, 0, 0]}


def test_costs_finds_its_columns_by_name(kp, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """Other events (a ~/.valgrindrc's cache simulation) and another order: the columns are
    taken by their names; a file without the branch events is refused."""
    f = tmp_path / "cg.out"
    f.write_text("""positions: instr line
events: Ir Dr Bc Bcm Dw

fn=(2) 0x7f0000001000
0x7f0000001000 0 10 99 4 1 98
+2 0 5
""")
    assert kp.costs(str(f)) == {0x0: [10, 4, 1], 0x2: [5, 0, 0]}
    g = tmp_path / "nobranch.out"
    g.write_text("positions: instr line\nevents: Ir\nfn=(1) x\n0x1000 0 3\n")
    with pytest.raises(SystemExit, match="Bc"):
        kp.costs(str(g))
