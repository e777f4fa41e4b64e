"""The command line: contract columns, and one-line errors with exit code 2."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from thermoskin.cli import main
from thermoskin.logio import read_log, write_log
from thermoskin.params import load_config
from thermoskin.sim.run import simulate
from thermoskin.sim.scenarios import SCENARIOS


@pytest.fixture(scope="module")
def sim_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    p = tmp_path_factory.mktemp("cli") / "sim.csv"
    write_log(p, simulate(SCENARIOS["one-finger"].with_duration(20.0), load_config()))
    return p


def invoke(*args: str) -> tuple[int, str, str]:
    res = CliRunner().invoke(main, list(args))
    return res.exit_code, res.stdout, res.stderr


def test_observe_writes_the_contract_columns(sim_log: Path, tmp_path: Path) -> None:
    out = tmp_path / "out.csv"
    code, stdout, _ = invoke("observe", str(sim_log), "-o", str(out))
    assert code == 0
    inp = read_log(sim_log)
    res = read_log(out)
    assert list(res)[:len(inp)] == list(inp)  # every input column, in order
    assert {"q_i_hat", "contact"} <= set(res)
    assert len(res["t"]) == len(inp["t"])
    for k in inp:
        np.testing.assert_allclose(res[k], inp[k], rtol=1e-5, atol=1e-6)
    assert set(np.unique(res["contact"])) == {0.0, 1.0}
    assert "Detected contacts" in stdout


def test_observe_survives_a_nan_burst(sim_log: Path, tmp_path: Path) -> None:
    log = read_log(sim_log)
    log["T_w"][6000:6100] = np.nan
    bad = tmp_path / "nan.csv"
    write_log(bad, log)
    out = tmp_path / "out.csv"
    code, stdout, _ = invoke("observe", str(bad), "-o", str(out))
    assert code == 0
    res = read_log(out, nan_columns=("T_w",))
    assert np.isfinite(res["q_i_hat"][1000:]).all()
    assert res["gap"][6000:6100].all() and not res["gap"][6100:].any()
    assert "100 NaN samples held over" in stdout


def _write(tmp_path: Path, name: str, text: str) -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


GOOD_ROWS = "".join(f"{k * 0.001:.3f},24.0,24.3,0.141,20.0\n" for k in range(50))


@pytest.mark.parametrize(("make", "needle"), [
    (lambda d: d / "nope.csv", "not found"),
    (lambda d: _write(d, "empty.csv", ""), "empty"),
    (lambda d: _write(d, "miss.csv", "t,T_w,T_p,v\n0,24,24,0.1\n0.001,24,24,0.1\n"), "T_a"),
    (lambda d: _write(d, "txt.csv", "t,T_w,T_p,v,T_a\n" + GOOD_ROWS + "0.050,hot,24,0.1,20\n"),
     "line 52"),
    (lambda d: _write(d, "back.csv", "t,T_w,T_p,v,T_a\n0.0,24,24,0.1,20\n0.002,24,24,0.1,20\n"
                      "0.001,24,24,0.1,20\n"), "increasing"),
    (lambda d: _write(d, "jump.csv", "t,T_w,T_p,v,T_a\n" + GOOD_ROWS + "0.070,24,24,0.1,20\n"),
     "non-uniform"),
])
@pytest.mark.parametrize("cached", [True, False], ids=["warm", "cold"])
def test_observe_bad_input_one_line_exit_2(tmp_path: Path, make, needle: str, cached: bool,  # type: ignore[no-untyped-def]
                                           monkeypatch) -> None:
    """One line, whether the kernel is in numba's cache or not: on a cold cache (the first run
    after an install) the log's first chunk is checked before the note that compiling begins."""
    from thermoskin import _numba_cache

    monkeypatch.setattr(_numba_cache, "has_compiled", lambda stem: cached)
    code, _, err = invoke("observe", str(make(tmp_path)), "-o", str(tmp_path / "o.csv"))
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("thermoskin: error:"), err
    assert needle in lines[0]
    assert not (tmp_path / "o.csv").exists()


@pytest.mark.parametrize(("toml", "needle"), [
    ("[skin]\nCw = 1.0\n", "skin.Cw"),
    ("[skin]\nR_g = -3\n", "skin.R_g = -3"),
    ("[detector]\nh_on = 0\n", "detector.h_on"),
    ("[nonsense]\nx = 1\n", "[nonsense]"),
    ("[skin\n", "not valid TOML"),
])
def test_bad_config_one_line_exit_2(sim_log: Path, tmp_path: Path, toml: str, needle: str) -> None:
    cfg = _write(tmp_path, "c.toml", toml)
    code, _, err = invoke("observe", str(sim_log), "-o", str(tmp_path / "o.csv"),
                          "--config", str(cfg))
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and needle in err


def test_config_override_changes_the_estimate(sim_log: Path, tmp_path: Path) -> None:
    cfg = _write(tmp_path, "c.toml", "[skin]\nR_ag = 2.0\n")
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    assert invoke("observe", str(sim_log), "-o", str(a))[0] == 0
    assert invoke("observe", str(sim_log), "-o", str(b), "--config", str(cfg))[0] == 0
    qa, qb = read_log(a)["q_i_hat"], read_log(b)["q_i_hat"]
    # the q_ag correction (T_w - T_a)/R_ag halves: about 2 W lower (T_w - T_a = 4 K)
    assert np.median(qa - qb) == pytest.approx(2.0, abs=0.3)


def test_simulate_and_unknown_scenario(tmp_path: Path) -> None:
    out = tmp_path / "s.csv"
    code, _, _ = invoke("simulate", "--scenario", "none", "--duration", "2", "-o", str(out))
    assert code == 0
    log = read_log(out)
    assert {"t", "T_w", "T_p", "v", "T_a", "q_i", "T_g"} <= set(log)
    assert len(log["t"]) == 2000
    code, _, err = invoke("simulate", "--scenario", "bogus", "-o", str(out))
    assert code == 2 and "unknown scenario 'bogus'" in err


def test_run_writes_log_and_plot(tmp_path: Path) -> None:
    log, png = tmp_path / "run.csv", tmp_path / "run.png"
    code, stdout, _ = invoke("run", "--scenario", "one-finger", "--duration", "27",
                             "--log", str(log), "--plot", str(png))
    assert code == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    cols = read_log(log)
    assert {"q_i_hat", "contact", "q_i", "T_g"} <= set(cols)
    assert "2 touches scripted, 2 detected, 0 missed, 0 false alarms" in stdout
    # the scenario's fingers are the simple model, which the characteriser may call objects: said
    assert "what: the scenario's fingers are the paper's simple finger" in stdout


def test_real_entry_point_no_traceback(tmp_path: Path) -> None:
    p = subprocess.run([sys.executable, "-m", "thermoskin.cli", "observe", str(tmp_path / "x.csv"),
                        "-o", str(tmp_path / "y.csv")], capture_output=True, text=True)
    assert p.returncode == 2
    assert "Traceback" not in p.stderr and p.stderr.count("\n") == 1


def test_excitation_then_identify(tmp_path: Path) -> None:
    from thermoskin.fit.identify import load_model

    log, model = tmp_path / "exc.csv", tmp_path / "peltier.toml"
    code, _, _ = invoke("simulate", "--scenario", "excitation", "--duration", "200", "-o", str(log))
    assert code == 0
    assert {"t", "T_p", "drive", "T_a"} <= set(read_log(log))
    code, stdout, _ = invoke("identify", str(log), "-o", str(model))
    assert code == 0 and "NRMSE" in stdout
    m = load_model(model)
    assert m.na >= 1 and np.isfinite(m.nrmse) and m.steady_state_gain() > 0  # heating warms
    # what identify writes is a config that run accepts (the inner loop's feed-forward)
    assert "[peltier_model]" in model.read_text() and "run --config" in stdout
    code, stdout, err = invoke("run", "--scenario", "none", "--duration", "12", "--config", str(model),
                               "--log", str(tmp_path / "ff.csv"))
    assert code == 0, err
    assert "tracking T_w_cmd 24 degC" in stdout


def test_identify_bad_log_exit_2(sim_log: Path, tmp_path: Path) -> None:
    code, _, err = invoke("identify", str(sim_log), "-o", str(tmp_path / "m.toml"))
    assert code == 2 and "drive" in err and len(err.strip().splitlines()) == 1


# ----------------------------------------------------------------------------- export, replay

@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("rec")
    rec = d / "run.mcap"
    code, _, err = invoke("run", "--scenario", "none", "--duration", "4", "--log", str(d / "run.csv"),
                          "--plot", str(d / "run.png"), "--record", str(rec))
    assert code == 0, err
    return rec


def middle_chunk(path: Path) -> tuple[int, int]:
    """Offset and length of the chunk record nearest the middle (the `mcap` library's index)."""
    from mcap.reader import make_reader

    with open(path, "rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None and len(summary.chunk_indexes) >= 3
    size = path.stat().st_size
    ci = min(summary.chunk_indexes, key=lambda c: abs(c.chunk_start_offset + c.chunk_length / 2 - size / 2))
    return ci.chunk_start_offset, ci.chunk_length


def test_export_and_replay_exit_codes(recording: Path, tmp_path: Path) -> None:
    pq = pytest.importorskip("pyarrow.parquet")
    n = len(read_log(recording.with_suffix(".csv"))["t"])
    # clean: exit 0, no warning
    code, stdout, err = invoke("export", str(recording), "-o", str(tmp_path / "x.parquet"))
    assert code == 0 and "wrote" in stdout and not err
    assert pq.read_table(tmp_path / "x.parquet").num_rows == n
    code, stdout, err = invoke("replay", str(recording), "-o", str(tmp_path / "r.csv"))
    assert code == 0 and "identical" in stdout and not err
    # 50 bytes flipped inside a chunk: the rest exported, one line saying what was lost, exit 4
    data = bytearray(recording.read_bytes())
    start, length = middle_chunk(recording)
    for i in range(start + length // 2, start + length // 2 + 50):
        data[i] ^= 0xFF
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(data))
    code, stdout, err = invoke("export", str(bad), "-o", str(tmp_path / "b.parquet"))
    assert code == 4 and "wrote" in stdout
    lines = err.strip().splitlines()
    assert len(lines) == 2 and lines[0].startswith(f"thermoskin: warning: {bad}: damaged bytes {start}-")
    lost = int(lines[0].split(" /skin/sample")[0].rsplit(" ", 1)[-1])
    kept = pq.read_table(tmp_path / "b.parquet").num_rows
    assert lost > 0 and kept == n - lost
    assert "messages lost" in lines[1]
    code, stdout, err = invoke("replay", str(bad), "-o", str(tmp_path / "rb.csv"))
    assert code == 4 and "damaged bytes" in err
    # cut off (killed recorder): exported up to its end with a warning saying where, exit 0
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(bytes(recording.read_bytes()[:start + length // 2]))
    code, stdout, err = invoke("export", str(cut), "-o", str(tmp_path / "c.csv"))
    assert code == 0
    rows = (tmp_path / "c.csv").read_text().splitlines()
    assert rows[0].startswith("t,") and 1 < len(rows) - 1 < n
    (line,) = err.strip().splitlines()
    assert "cut off" in line and f"it ends at t = {float(rows[-1].split(',')[0]):.3f} s" in line
    code, stdout, err = invoke("replay", str(cut), "-o", str(tmp_path / "rc.csv"))
    assert code == 0 and "identical" in stdout and "cut off" in err  # a prefix replays exactly


@pytest.mark.parametrize("command", ["export", "replay"])
def test_export_replay_bad_recording_one_line(tmp_path: Path, command: str) -> None:
    (tmp_path / "dir.mcap").mkdir()
    for path, needle in ((tmp_path / "dir.mcap", "is a directory"), (tmp_path / "no.mcap", "does not exist")):
        code, _, err = invoke(command, str(path), "-o", str(tmp_path / "o.csv"))
        assert code == 2 and needle in err and len(err.strip().splitlines()) == 1, err


def test_events_table_keeps_numbers_whole_in_80_columns() -> None:
    """In an 80-column terminal every number of the table is printed whole (they were cut to
    "15.0…" once the what-touched column came); only the text column wraps."""
    from rich.console import Console

    from thermoskin.cli.common import events_table
    from thermoskin.estimation.events import ContactEvent

    ev = [ContactEvent(1115.042, 1115.14, 1116.982, 1.94, 1, 1.002, 0.66, 1.28, "hold", "object",
                       "glass-ceramic", T_f_hat=55.3),
          ContactEvent(24.061, 24.127, 26.47, 2.41, -1, -0.143, -0.078, -0.632, "tap", "human", "human")]
    for width in (80, 120):
        c = Console(width=width, highlight=False, record=True)
        c.print(events_table(ev), soft_wrap=False)
        text = c.export_text()
        assert max(len(line) for line in text.splitlines()) <= width
        for s in ("1115.042", "1115.140", "1116.982", "1.94", "1.002", "0.660", "1.280", "24.061",
                  "24.127", "26.470", "2.41", "-0.143", "-0.078", "-0.632"):
            assert s in text, (width, s)
        assert "…" not in text


def test_what_touched_is_printed_whole_in_any_terminal(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """In 80 columns the what-touched words came out cut ("glass-" and "eramic"): they go to a
    table of their own there, and stay in the contacts table where they fit unbroken."""
    from rich.console import Console

    import thermoskin.cli as cli
    from thermoskin.estimation.events import ContactEvent

    ev = [ContactEvent(1115.042, 1115.14, 1116.982, 1.94, 1, 1.002, 0.66, 1.28, "hold", "object",
                       "glass-ceramic", T_f_hat=55.3),
          ContactEvent(24.061, 24.127, 26.47, 2.41, -1, -0.143, -0.078, -0.632, "tap", "human", "human")]
    for width, tables in ((80, 2), (140, 1)):
        c = Console(width=width, highlight=False, record=True)
        monkeypatch.setattr(cli.common, "console", c)
        cli.common.show_events(ev)
        text = c.export_text()
        assert max(len(line) for line in text.splitlines()) <= width
        assert "hold object glass-ceramic 55.3C" in text and "tap human" in text  # whole, one line
        assert "tap human human" not in text  # the material only where it says more
        assert text.count("What touched") == (tables == 2), width
        assert "1115.042" in text and "…" not in text


def test_observe_never_writes_over_its_input(sim_log: Path, tmp_path: Path) -> None:
    """`-o` or `--events` naming the input log (by another path too) is refused, with one line,
    and the log is left as it was (an events file over it would have lost the recording)."""
    log = tmp_path / "in.csv"
    log.write_bytes(sim_log.read_bytes())
    before = log.read_bytes()
    (tmp_path / "sub").mkdir()
    for args in (("-o", str(log)), ("-o", str(tmp_path / "out.csv"), "--events", str(log)),
                 ("-o", str(tmp_path / "sub" / ".." / "in.csv"))):
        code, _, err = invoke("observe", str(log), *args)
        assert code == 2 and "that is the input;" in err and len(err.strip().splitlines()) == 1, err
        assert log.read_bytes() == before
    # nor its log and its events into one file (the events table would replace the log)
    same = tmp_path / "same.csv"
    code, _, err = invoke("observe", str(log), "-o", str(same), "--events", str(same))
    assert code == 2 and "is also given as -o" in err and not same.exists(), err


def test_observe_says_when_it_compiles(sim_log: Path, tmp_path: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """A cold cache (the first run after an install) is announced on stderr, once; a warm one
    is not."""
    from thermoskin import _numba_cache

    code, _, err = invoke("observe", str(sim_log), "-o", str(tmp_path / "a.csv"))
    assert code == 0 and "compiling" not in err
    monkeypatch.setattr(_numba_cache, "has_compiled", lambda stem: False)
    code, _, err = invoke("observe", str(sim_log), "-o", str(tmp_path / "b.csv"))
    assert code == 0 and err.count("compiling the estimator") == 1


@pytest.mark.parametrize("device", ["sim", "realtime", "serial"])
def test_run_says_when_it_compiles_on_every_device(tmp_path: Path, monkeypatch, device: str) -> None:  # type: ignore[no-untyped-def]
    """`run` in this process, `--realtime` and `--device serial://` compile the same estimator
    kernels (the whole-log loop for the sensors' watch, then the sample step the loop uses, in
    the fixed-rate loop process for the last two): each asks the cache for them and, on a cold
    cache only, says so once, before the loop starts; a warm cache prints nothing more."""
    from thermoskin import _numba_cache, cli
    from thermoskin.runtime import closed_loop

    def loop(*args, **kwargs):  # type: ignore[no-untyped-def]
        raise cli.common.UserError("the loop would start here")

    monkeypatch.setattr(cli.run, "_run_fixed_rate", loop)
    monkeypatch.setattr(closed_loop, "run_closed_loop", loop)
    (tmp_path / "tty").touch()  # a port that exists (a missing one is refused before any of this)
    args = {"sim": [], "realtime": ["--realtime"],
            "serial": ["--device", f"serial://{tmp_path / 'tty'}"]}[device]
    for cached in (True, False):
        asked: list[str] = []
        monkeypatch.setattr(_numba_cache, "has_compiled", lambda w, c=cached, a=asked: a.append(w) or c)
        code, _, err = invoke("run", "--duration", "1", "--log", str(tmp_path / "run.csv"), *args)
        lines = err.strip().splitlines()
        want = ["estimation/kernel.run", "estimation/kernel.step"] if cached else ["estimation/kernel.run"]
        assert code == 2 and asked == want, (asked, err)
        assert lines[-1] == "thermoskin: error: the loop would start here"
        if cached:
            assert "compiling" not in err
        else:
            assert len(lines) == 2 and lines[0].startswith("thermoskin: compiling the estimator (once")


def test_note_compile_notes_once_if_any_is_missing(monkeypatch, capsys) -> None:  # type: ignore[no-untyped-def]
    from thermoskin import _numba_cache
    from thermoskin.cli.common import _note_compile

    names = ("a/b.c", "d/e.f", "g/h.i")
    for missing, expected in ((set(), 0), ({"d/e.f"}, 1), ({"g/h.i"}, 1), (set(names), 1)):
        monkeypatch.setattr(_numba_cache, "has_compiled", lambda w, m=missing: w not in m)
        _note_compile(names, "the thing", "a while")
        err = capsys.readouterr().err
        assert err.count("thermoskin: compiling the thing (once") == expected, (missing, err)
    monkeypatch.setattr(_numba_cache, "has_compiled", lambda w: w != "a/b.c")
    _note_compile("a/b.c")  # one name, as before
    assert capsys.readouterr().err.count("compiling the estimator") == 1


def test_run_skin_asks_for_every_kernel_it_compiles(tmp_path: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """`run --skin` compiles the skin's plant, its boards, the patches' estimators
    (``kernel.run_rows``, ...) and, with piped patches, the transport correction: the cache is
    asked for each, and any one missing (not only the plant's, as before) is said once."""
    from thermoskin import _numba_cache, cli
    from thermoskin.skin.layout import load_skin

    monkeypatch.setattr(cli.run, "_run_skin_loop", lambda *args, **kwargs: None)  # no loop: only the notice
    forearm = Path(__file__).parents[1] / "examples" / "forearm.toml"
    expected = [*cli.common.SKIN_KERNELS, cli.common.PIPE_KERNEL]
    assert cli.common.skin_kernels(load_skin(forearm, load_config())) == tuple(expected)  # forearm has pipes
    single = forearm.with_name("single.toml")  # one patch fed straight from its tank: no transport
    assert cli.common.skin_kernels(load_skin(single, load_config())) == cli.common.SKIN_KERNELS
    assert {"sim/skin_plant._advance", "estimation/kernel.run_rows_fixed"} <= set(expected)
    for missing in (None, *expected):
        asked: list[str] = []
        monkeypatch.setattr(_numba_cache, "has_compiled",
                            lambda w, m=missing, a=asked: a.append(w) or w != m)
        code, _, err = invoke("run", "--skin", str(forearm), "--duration", "1",
                              "--log", str(tmp_path / "skin.csv"))
        assert code == 0, err
        assert err.count("thermoskin: compiling the skin's plant and the estimator") == (missing is not None)
        if missing is None:
            assert sorted(asked) == sorted(expected) and "compiling" not in err


def test_observe_skin_asks_for_the_estimators_only(tmp_path: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """`observe --skin` compiles the patches' estimators (and the transport correction for
    piped patches), not the plant: the notice is about those, once, and only when one of them
    is missing from the cache."""
    from thermoskin import _numba_cache, cli
    from thermoskin.skin.layout import load_skin

    forearm = Path(__file__).parents[1] / "examples" / "forearm.toml"
    names = cli.common.skin_kernels(load_skin(forearm, load_config()), plant=False)
    assert not set(names) & set(cli.common.SKIN_PLANT_KERNELS) and cli.common.PIPE_KERNEL in names
    log = tmp_path / "skin.csv"
    code, _, err = invoke("simulate", "--skin", str(forearm), "--duration", "0.5", "-o", str(log))
    assert code == 0, err
    for missing in (None, "estimation/kernel.run_rows_fixed"):
        asked: list[str] = []
        monkeypatch.setattr(_numba_cache, "has_compiled", lambda w, m=missing, a=asked: a.append(w) or w != m)
        code, _, err = invoke("observe", "--skin", str(forearm), str(log), "-o", str(tmp_path / "o.csv"))
        assert code == 0, err
        if missing is None:  # (with one missing, the lookup stops there)
            assert sorted(asked) == sorted(names)
        assert err.count("thermoskin: compiling the patches' estimators") == (missing is not None)
    # a bad log on a cold cache: its error alone (the log is checked before the notice)
    rows = log.read_text().splitlines()
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join([*rows[:9], rows[9].replace(",", ",x", 1), *rows[10:]]) + "\n")
    monkeypatch.setattr(_numba_cache, "has_compiled", lambda w: False)
    code, _, err = invoke("observe", "--skin", str(forearm), str(bad), "-o", str(tmp_path / "b.csv"))
    assert code == 2 and len(err.strip().splitlines()) == 1 and "thermoskin: error:" in err, err


@pytest.mark.parametrize("args", [
    ["run", "--skin", "FOREARM", "--live", ":abc"],
    ["run", "--live", ":abc"],
    ["run", "--live", "8765", "--live-rate", "0"],
    ["replay", "REC", "-o", "OUT", "--live", "[::1"],
])
def test_a_bad_live_address_is_its_line_alone_on_a_cold_cache(tmp_path: Path, monkeypatch, args) -> None:  # type: ignore[no-untyped-def]
    """A bad ``--live`` (address, rate) is one error line, exit 2, before anything is compiled or
    written: on a cold cache no compile notice comes first (the skin's run said it was compiling,
    then gave the error), and ``replay -o`` writes nothing."""
    from thermoskin import _numba_cache

    forearm = Path(__file__).parents[1] / "examples" / "forearm.toml"
    rec = tmp_path / "r.mcap"
    rec.write_bytes(b"")  # never opened: the address is checked first
    out = tmp_path / "o.csv"
    args = [str(forearm) if a == "FOREARM" else str(rec) if a == "REC" else str(out) if a == "OUT" else a
            for a in args]
    monkeypatch.setattr(_numba_cache, "has_compiled", lambda w: False)
    monkeypatch.chdir(tmp_path)
    code, _, err = invoke(*args)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert err.startswith("thermoskin: error: --live"), err
    assert not out.exists() and not (tmp_path / "run.csv").exists()


def test_exit_freeze_still_finalises_garbage(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """The command line freezes its objects at exit (a faster teardown), after one last
    collection: an object in a reference cycle, garbage by then, is still finalised (its
    ``__del__`` runs), as the interpreter's own teardown would have done. The command run
    through ``main()`` (which registers the freeze), the garbage made after it."""
    import subprocess
    import sys

    out = tmp_path / "finalised.txt"
    code = ("import sys\n"
            "from thermoskin.cli import main\n"
            "main(['scenarios'], standalone_mode=False)\n"
            "class Holder:\n"
            "    def __del__(self):\n"
            f"        with open({str(out)!r}, 'w') as f:\n"
            "            f.write('done')\n"
            "h = Holder()\n"
            "h.self = h\n"
            "del h\n")
    subprocess.run([sys.executable, "-c", code], check=True, capture_output=True)
    assert out.read_text() == "done"


def test_exit_freeze_only_for_the_command_line() -> None:
    """Registered by the command line's ``main()``, not by importing the module (a program that
    imports it keeps the interpreter's own exit)."""
    import subprocess
    import sys

    probe = ("import atexit, sys\n"
             "seen = []\n"
             "real = atexit.register\n"
             "def spy(f, *a, **k):\n"
             "    seen.append(getattr(f, '__name__', ''))\n"
             "    return real(f, *a, **k)\n"
             "atexit.register = spy\n"
             "import thermoskin.cli as c\n"
             "print('import', '_freeze_at_exit' in seen)\n"
             "sys.argv = ['thermoskin', 'scenarios']\n"
             "try:\n"
             "    c.main()\n"
             "except SystemExit:\n"
             "    pass\n"
             "print('main', '_freeze_at_exit' in seen, file=sys.stderr)\n")
    r = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert "import False" in r.stdout and "main True" in r.stderr


def test_scenarios_lists_every_scenario_a_command_takes() -> None:
    """`scenarios` lists the patch's scenarios, `excitation` and the skin's (`multi`, which the
    README's `simulate --skin ... --scenario multi` uses): every name `run` or `simulate` takes."""
    from thermoskin.sim.scenarios import SCENARIOS
    from thermoskin.sim.skin_scenarios import SKIN_SCENARIOS

    code, out, _ = invoke("scenarios")
    assert code == 0
    names = {line.split("│")[1].strip() for line in out.splitlines() if line.count("│") > 2}
    assert {*SCENARIOS, "excitation", "multi"} <= names
    assert set(SKIN_SCENARIOS) == {"multi"}
    assert "--skin only" in " ".join(out.split())


def test_replay_and_reproduce_say_when_they_compile(tmp_path: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """`replay` (the estimator over the recording) and `reproduce` (the paper's runs) compile
    the estimator on a cold cache like `observe` and `run`, and said nothing for 8 and 15 s: they
    ask the cache and say so once; a warm cache, nothing."""
    from thermoskin import _numba_cache
    from thermoskin.experiments import reproduce as rep_mod

    rec = tmp_path / "r.mcap"
    code, _, err = invoke("run", "--duration", "1", "--log", str(tmp_path / "r.csv"), "--record", str(rec))
    assert code == 0, err

    def stop(*args, **kwargs):  # type: ignore[no-untyped-def]
        raise KeyboardInterrupt  # the reproduction would start here

    monkeypatch.setattr(rep_mod, "reproduce", stop)
    for cached in (True, False):
        asked: list[str] = []
        monkeypatch.setattr(_numba_cache, "has_compiled", lambda w, c=cached, a=asked: a.append(w) or c)
        code, _, err = invoke("replay", str(rec), "-o", str(tmp_path / "rep.csv"))
        assert code == 0 and "estimation/kernel.run" in asked, err
        assert err.count("thermoskin: compiling the estimator") == (not cached), err
        code, _, err = invoke("reproduce", "--only", "fig15", "--out", str(tmp_path / "repro"))
        assert code == 130, err
        assert err.count("thermoskin: compiling the estimator") == (not cached), err


def test_run_says_it_compiles_before_it_runs_the_estimator(tmp_path: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """`run` runs the estimator before its first line (what the configured sensors should give,
    ``_SensorWatch``): on a cold cache that compiles it for about 10 s, so the notice comes
    before it (a fresh clone's first `run` was silent for those 10 s, the notice coming after)."""
    from thermoskin import _numba_cache
    from thermoskin.cli import run as run_mod

    order: list[str] = []
    watch, note = run_mod._SensorWatch, run_mod._note_compile
    monkeypatch.setattr(_numba_cache, "has_compiled", lambda where: False)
    monkeypatch.setattr(run_mod, "_SensorWatch", lambda *a: order.append("estimator") or watch(*a))
    monkeypatch.setattr(run_mod, "_note_compile", lambda *a, **k: order.append("notice") or note(*a, **k))
    code, _, err = invoke("run", "--duration", "1", "--log", str(tmp_path / "r.csv"))
    assert code == 0, err
    assert "estimator" in order and order.index("notice") < order.index("estimator"), order
    assert err.startswith("thermoskin: compiling the estimator"), err
