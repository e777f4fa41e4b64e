"""No traceback from any input: every bad parameter, path and duration of issue 11 gives one
line, exit code 2, and leaves nothing written (checked before any work starts)."""

from __future__ import annotations

import contextlib
import os
import subprocess
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from thermoskin.cli import main
from thermoskin.logio import read_log, write_log
from thermoskin.paths import PathError, check_output


def invoke(*args: str) -> tuple[int, str, str]:
    res = CliRunner().invoke(main, list(args))
    return res.exit_code, res.stdout, res.stderr


def tree(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


@contextlib.contextmanager
def unwritable(folder: Path) -> Iterator[bool]:
    """``folder`` made unwritable (chmod; as root, which chmod does not stop, the immutable
    flag); yields whether that worked on this machine."""
    folder.mkdir(exist_ok=True)
    folder.chmod(0o555)
    immutable = False
    if os.geteuid() == 0:
        immutable = subprocess.run(["chattr", "+i", str(folder)], capture_output=True).returncode == 0
    try:
        probe = folder / "probe"
        try:
            probe.write_text("x")
            probe.unlink()
            ok = False
        except OSError:
            ok = True
        yield ok
    finally:
        if immutable:
            subprocess.run(["chattr", "-i", str(folder)], capture_output=True)
        folder.chmod(0o755)


@pytest.fixture
def work(tmp_path: Path) -> Path:
    """A folder with a small log, a file, a folder and bad configs, the working directory."""
    (tmp_path / "a_dir").mkdir()
    (tmp_path / "a_file").write_text("x")
    (tmp_path / "cw.toml").write_text("[skin]\nC_w = 1e300\n")
    (tmp_path / "ts.toml").write_text("[sampling]\nt_s = 1e-12\n")
    (tmp_path / "euler.toml").write_text("[sampling]\nt_s = 0.1\n")
    (tmp_path / "safety.toml").write_text("[safety]\nT_p_min = 40.0\n")  # a check across fields
    n = 400
    t = np.arange(n) * 1e-3
    write_log(tmp_path / "log.csv", {"t": t, "T_w": np.full(n, 24.0), "T_p": np.full(n, 25.0),
                                     "v": np.full(n, 0.141), "T_a": np.full(n, 20.0),
                                     "drive": np.linspace(-1, 1, n)})
    write_log(tmp_path / "tiny_dt.csv", {"t": np.arange(n) * 1e-12, "T_w": np.full(n, 24.0),
                                         "T_p": np.full(n, 25.0), "v": np.full(n, 0.141),
                                         "T_a": np.full(n, 20.0)})
    write_log(tmp_path / "skin.csv", {"t": np.repeat(t, 2), "patch": np.tile([0.0, 1.0], n),
                                      "T_w": np.full(2 * n, 24.0), "T_p": np.full(2 * n, 25.0),
                                      "v": np.full(2 * n, 0.141), "T_a": np.full(2 * n, 20.0)})
    cwd = Path.cwd()
    os.chdir(tmp_path)
    try:
        yield tmp_path
    finally:
        os.chdir(cwd)


CASES = [
    # parameters: a physical range on both sides
    (["run", "--duration", "1", "--config", "cw.toml"], "skin.C_w = 1e+300 is out of range"),
    (["simulate", "--duration", "1", "--config", "ts.toml", "-o", "s.csv"], "sampling.t_s = 1e-12"),
    (["observe", "log.csv", "-o", "o.csv", "--config", "cw.toml"], "skin.C_w"),
    (["run", "--duration", "1", "--config", "euler.toml"], "too long for the MPC's model"),
    (["observe", "tiny_dt.csv", "-o", "o.csv"], "tiny_dt.csv is sampled every 1e-12 s"),
    (["run", "--duration", "1", "--config", "safety.toml"], "safety.T_p_max = 40.0 in safety.toml"),
    # a directory given as a config
    (["run", "--duration", "1", "--config", "a_dir"], "is a directory"),
    (["simulate", "--duration", "1", "--config", "a_dir", "-o", "s.csv"], "is a directory"),
    # durations: finite, and what fits
    (["simulate", "--duration", "inf", "-o", "s.csv"], "must be a finite number"),
    (["simulate", "--duration", "nan", "-o", "s.csv"], "must be a finite number"),
    (["simulate", "--duration", "-1", "-o", "s.csv"], "must be a finite number"),
    (["simulate", "--duration", "1e12", "-o", "s.csv"], "more than this machine has free"),
    (["simulate", "--scenario", "excitation", "--duration", "1e12", "-o", "s.csv"], "more than"),
    (["run", "--duration", "inf"], "must be a finite number"),
    (["run", "--duration", "1e12"], "more than this machine has free"),
    # output paths: a directory, a path under a file
    (["simulate", "--duration", "1", "-o", "a_dir"], "must end in"),
    (["simulate", "--duration", "1", "-o", "a_dir.csv"], "is a directory"),
    (["simulate", "--duration", "1", "-o", "a_file/x.csv"], "a_file is a file, not a folder"),
    (["run", "--duration", "1", "--log", "a_file/x.csv"], "a_file is a file, not a folder"),
    (["run", "--duration", "1", "--log", "r.csv", "--plot", "a_file/x.png"], "not a folder"),
    (["run", "--duration", "1", "--log", "r.csv", "--events", "a_file/e.csv"], "not a folder"),
    (["run", "--duration", "1", "--log", "r.csv", "--record", "a_file/r.mcap"], "not a folder"),
    (["run", "--duration", "1", "--log", "r.csv", "--events", "r.csv"], "is also given as --log"),
    (["observe", "log.csv", "-o", "a_file/o.csv"], "not a folder"),
    (["observe", "log.csv", "-o", "o.csv", "--events", "a_file/e.csv"], "not a folder"),
    (["identify", "log.csv", "-o", "a_file/p.toml"], "not a folder"),
    (["plot", "log.csv", "-o", "a_file/p.png"], "not a folder"),
    (["plot", "log.csv", "-o", "p.gif"], "must end in"),
    (["export", "a_dir", "-o", "x.csv"], "is a directory"),
    (["replay", "a_dir", "-o", "x.csv"], "is a directory"),
    (["reproduce", "--out", "a_file"], "is a file, not a folder"),
    # a skin's long-format log where one patch's is read
    (["observe", "skin.csv", "-o", "o.csv"], "a skin's log (its 'patch' column"),
    (["plot", "skin.csv"], "observe reads it with --skin"),
    # calibrate: its outputs and options checked before the fit
    (["calibrate", "log.csv", "-o", "f.txt"], "must end in .toml"),
    (["calibrate", "log.csv", "-o", "a_dir.toml"], "is a directory"),
    (["calibrate", "log.csv", "-o", "f.toml", "--t-fit", "-1"], "--t-fit -1.0 must be >= 0 s"),
]


@pytest.mark.parametrize(("args", "needle"), CASES, ids=[" ".join(a)[:60] for a, _ in CASES])
def test_bad_input_one_line_exit_2_nothing_written(work: Path, args: list[str], needle: str | None) -> None:
    for a in ("a_dir.csv", "a_dir.toml"):
        if a in args:
            (work / a).mkdir()
    before = tree(work)
    code, out, err = invoke(*args)
    assert code == 2, (args, out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("thermoskin: error: "), err
    assert needle is None or needle in lines[0], lines[0]
    assert "Traceback" not in out + err
    assert tree(work) == before  # nothing written, not even a header


def test_unwritable_folder_refused_before_the_work(work: Path) -> None:
    with unwritable(work / "ro") as ok:
        if not ok:
            pytest.skip("cannot make a folder unwritable here")
        before = tree(work)
        for args in (["simulate", "--duration", "1", "-o", "ro/s.csv"],
                     ["run", "--duration", "1", "--log", "ro/r.csv"],
                     ["run", "--duration", "1", "--log", "r.csv", "--record", "ro/r.mcap"],
                     ["observe", "log.csv", "-o", "ro/o.csv"]):
            code, _, err = invoke(*args)
            assert code == 2 and len(err.strip().splitlines()) == 1, (args, err)
            assert "cannot write in the folder" in err
        assert tree(work) == before


def test_check_output_leaves_nothing(tmp_path: Path) -> None:
    """The probe of a folder is removed; a missing folder is fine (the writers make it)."""
    assert check_output(tmp_path / "new" / "deeper" / "x.csv", "-o", (".csv",)) is not None
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(PathError, match="is a directory"):
        check_output(tmp_path, "-o")


def test_config_written_by_a_failed_run_is_untouched(work: Path) -> None:
    """A run refused for its config leaves an existing log as it was."""
    write_log(work / "keep.csv", {"t": [0.0, 1.0], "T_w": [1.0, 2.0]})
    before = (work / "keep.csv").read_bytes()
    code, _, _ = invoke("run", "--duration", "1", "--config", "cw.toml", "--log", "keep.csv")
    assert code == 2 and (work / "keep.csv").read_bytes() == before
    assert read_log(work / "keep.csv", required=("t",))["t"].tolist() == [0.0, 1.0]


def _disk_full(*_: object, **__: object) -> None:
    import errno

    raise OSError(errno.ENOSPC, "No space left on device")


def test_full_disk_is_one_line_and_keeps_the_earlier_output(tmp_path: Path,
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    """A disk that fills while a log is written: one line naming the file, exit 2, and the
    earlier file at that path (an atomic writer's) left as it was; the same for a config."""
    import thermoskin.logio.stream as stream
    from thermoskin.atomic import write_text
    from thermoskin.params import load_config, save_config

    src = tmp_path / "in.csv"
    r = CliRunner().invoke(main, ["simulate", "--duration", "3", "-o", str(src)])
    assert r.exit_code == 0, r.output
    out = tmp_path / "out.csv"
    out.write_text("an earlier output\n")
    monkeypatch.setattr(stream, "write_rows", _disk_full)
    r = CliRunner().invoke(main, ["observe", str(src), "-o", str(out)])
    assert r.exit_code == 2, r.output
    lines = r.stderr.strip().splitlines()
    assert lines[-1] == f"thermoskin: error: cannot write {out}: No space left on device", r.stderr
    assert "Traceback" not in r.output and out.read_text() == "an earlier output\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.csv", "out.csv"]
    cfg = tmp_path / "c.toml"
    save_config(load_config(), cfg)
    before = cfg.read_bytes()
    monkeypatch.setattr(Path, "write_text", _disk_full)
    with pytest.raises(OSError):
        save_config(load_config(), cfg)
    with pytest.raises(OSError):
        write_text(cfg, "x")
    assert cfg.read_bytes() == before and sorted(p.name for p in tmp_path.iterdir()) == [
        "c.toml", "in.csv", "out.csv"]


def test_storage_errors_are_one_line(monkeypatch: pytest.MonkeyPatch) -> None:
    """An OSError of the file system's (full, read-only, a drive gone) reaching the command
    line is one line with the file it names and exit 2; any other OSError is not swallowed."""
    import errno

    import thermoskin.cli as cli

    def boom(code: int):  # type: ignore[no-untyped-def]
        @cli.common._user_errors
        def f() -> None:
            raise OSError(code, os.strerror(code), "/mnt/usb/run.mcap")
        return f

    r = CliRunner().invoke(click_command(boom(errno.ENOSPC)))
    assert r.exit_code == 2
    assert r.stderr.strip() == ("thermoskin: error: /mnt/usb/run.mcap: No space left on device (the "
                                "file system); what was written before is kept")
    r = CliRunner().invoke(click_command(boom(errno.ENOENT)))
    assert r.exit_code == 1 and isinstance(r.exception, FileNotFoundError)


def click_command(f):  # type: ignore[no-untyped-def]
    import click

    return click.command()(f)


def test_atomic_write_keeps_a_link_and_the_permissions(tmp_path: Path) -> None:
    """:func:`thermoskin.atomic.write_text` through a symbolic link rewrites its target (the link
    stays a link) and keeps the earlier file's permissions."""
    from thermoskin.atomic import write_text

    target = tmp_path / "configs" / "skin.toml"
    target.parent.mkdir()
    target.write_text("old")
    os.chmod(target, 0o600)
    link = tmp_path / "current.toml"
    link.symlink_to(target)
    write_text(link, "new")
    assert link.is_symlink() and target.read_text() == "new"
    assert target.stat().st_mode & 0o777 == 0o600
    assert sorted(p.name for p in target.parent.iterdir()) == ["skin.toml"]


@pytest.mark.parametrize(("args", "needle"), [
    (["observe"], "Missing argument 'INPUT_CSV'. (see main observe --help)"),
    (["observe", "x.csv"], "Missing option '-o' / '--output'."),
    (["observe", "x.csv", "-o", "y.csv", "--bogus"], "No such option '--bogus'"),
    (["simulate", "--duration", "abc", "-o", "x.csv"], "'abc' is not a valid float"),
    (["nosuch"], "No such command 'nosuch'."),
])
def test_usage_errors_are_one_line_exit_2(args: list[str], needle: str) -> None:
    """click's own usage errors (a missing argument or option, an unknown one, a value of the
    wrong type, an unknown command) are one line and exit 2, as every other user error;
    ``--help`` and ``--version`` still exit 0."""
    code, _, err = invoke(*args)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("thermoskin: error: ") and needle in lines[0], err
    assert invoke("observe", "--help")[0] == 0 and invoke("--version")[0] == 0
