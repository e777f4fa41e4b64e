"""Every file in examples/ works with every command that takes its kind, and each kind given
where another goes is refused with one line that names both (the layout and the parameter file
were both called SKIN.toml; `calibrate --config examples/single.toml` said "unknown table [name]")."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest
from click.testing import CliRunner

from thermoskin.cli import main
from thermoskin.params import FILE_KINDS, file_kind

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
TOMLS = sorted(EXAMPLES.glob("*.toml"))


def kind(p: Path) -> str | None:
    return file_kind(tomllib.loads(p.read_text(encoding="utf-8")))


def invoke(*args: str) -> tuple[int, str, str]:
    res = CliRunner().invoke(main, [str(a) for a in args])
    return res.exit_code, res.stdout, res.stderr


def test_every_example_is_of_a_known_kind() -> None:
    kinds = {p.name: kind(p) for p in TOMLS}
    assert kinds == {"forearm.toml": "layout", "params.toml": "parameters", "single.toml": "layout",
                     "sweep-small.toml": "sweep", "sweep.toml": "sweep"}
    assert set(kinds.values()) == set(FILE_KINDS)


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A one-patch log (a touch, the pump switching) and its recording; made once."""
    d = tmp_path_factory.mktemp("examples")
    code, _, err = invoke("run", "--scenario", "one-finger", "--duration", "14", "--log", d / "run.csv",
                          "--record", d / "run.mcap", "--config", EXAMPLES / "params.toml")
    assert code == 0, err
    return {"log": d / "run.csv", "mcap": d / "run.mcap", "dir": d}


@pytest.mark.parametrize("example", [p for p in TOMLS if kind(p) == "parameters"], ids=lambda p: p.name)
def test_parameter_files_work_with_every_command_taking_one(example: Path, logs: dict[str, Path]) -> None:
    d = logs["dir"]
    for args in (("simulate", "--scenario", "one-finger", "--duration", "3", "-o", d / "sim.csv"),
                 ("observe", logs["log"], "-o", d / "obs.csv"),
                 ("replay", logs["mcap"], "-o", d / "rep.csv"),
                 ("calibrate", logs["log"], "--params", "R_g", "--t-fit", "0.1", "-o", d / "fit.toml")):
        code, _, err = invoke(*args, "--config", example)
        assert code == 0, (args, err)


@pytest.mark.parametrize("example", [p for p in TOMLS if kind(p) == "layout"], ids=lambda p: p.name)
def test_layout_files_work_with_every_command_taking_one(example: Path, tmp_path: Path) -> None:
    log = tmp_path / "skin.parquet"
    for args in (("simulate", "--skin", example, "--duration", "2", "-o", log),
                 ("observe", log, "--skin", example, "-o", tmp_path / "out.parquet"),
                 ("run", "--skin", example, "--duration", "2", "--log", tmp_path / "run.parquet")):
        code, _, err = invoke(*args)
        assert code == 0, (args, err)


def test_sweep_files_load_and_the_small_one_runs(tmp_path: Path) -> None:
    from thermoskin.sweep.spec import load_sweep

    for p in TOMLS:
        if kind(p) == "sweep":
            assert len(load_sweep(p).points) >= 12, p  # every point's config is built and checked
    code, _, err = invoke("sweep", EXAMPLES / "sweep-small.toml", "-o", tmp_path / "small.parquet")
    assert code == 0, err  # the 1000-design sweep.toml: README's own command, 17 s on two cores


@pytest.mark.parametrize(("args", "given", "wanted"), [
    (("calibrate", "LOG", "--config", EXAMPLES / "single.toml", "-o", "OUT.toml"), "layout", "parameter"),
    (("run", "--config", EXAMPLES / "forearm.toml"), "layout", "parameter"),
    (("run", "--skin", EXAMPLES / "params.toml"), "parameter", "layout"),
    (("simulate", "--skin", EXAMPLES / "sweep-small.toml", "-o", "X.parquet"), "sweep", "layout"),
    (("sweep", EXAMPLES / "forearm.toml", "-o", "X.parquet"), "layout", "sweep"),
    (("sweep", EXAMPLES / "params.toml", "-o", "X.parquet"), "parameter", "sweep"),
    (("observe", "LOG", "--config", EXAMPLES / "sweep.toml", "-o", "OUT.csv"), "sweep", "parameter"),
])
def test_a_file_of_another_kind_is_refused_naming_both(args: tuple, given: str, wanted: str,  # type: ignore[type-arg]
                                                       logs: dict[str, Path], tmp_path: Path) -> None:
    args = tuple(logs["log"] if a == "LOG" else tmp_path / a if a in ("OUT.toml", "OUT.csv", "X.parquet")
                 else a for a in args)
    code, _, err = invoke(*args)
    line = err.strip()
    assert code == 2 and "\n" not in line, err
    assert f"is {FILE_KINDS[{'parameter': 'parameters'}.get(given, given)].split(' (')[0]}" in line
    assert f"not {FILE_KINDS[{'parameter': 'parameters'}.get(wanted, wanted)].split(' (')[0]}" in line


def test_calibrate_no_longer_takes_skin_for_its_parameter_file(logs: dict[str, Path], tmp_path: Path) -> None:
    code, _, err = invoke("calibrate", logs["log"], "--skin", EXAMPLES / "params.toml",
                          "-o", tmp_path / "f.toml")
    assert code == 2 and "--config" in err and "layout" in err
