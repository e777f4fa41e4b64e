"""Units checked (issue 46): a log's ``t`` in milliseconds (or microseconds) and its temperatures
in kelvin are refused with the unit they look like and the option that says it; said, they are
converted, and the estimates are those of the same log written in seconds and °C."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from thermoskin.cli import main
from thermoskin.logio import LogError, Units, read_log, write_log
from thermoskin.logio.units import suspected_time_unit

pytestmark = pytest.mark.usefixtures("compiled_estimator")


@pytest.mark.parametrize(("step", "unit"), [
    (1.0, "ms"), (0.5, "ms"), (0.1, "ms"), (10.0, "ms"), (2.0, "ms"), (0.2, "ms"),   # 0.1-10 ms in ms
    (1000.0, "us"), (100.0, "us"), (10_000.0, "us"),                                  # 0.1-10 ms in us
    (1e-3, None), (1e-2, None), (0.05, None), (2e-4, None),                           # seconds
    (0.25, None), (0.123, None), (1.5e-3, None),                                      # not whole tenths
    (20.0, None), (5e5, None), (0.0, None), (float("nan"), None),                     # neither
    (float("inf"), None), (-1.0, None), (99.5, None), (10_000.5, None), (10.04, None),
    (1.0000001, "ms"),                                                                # a float's slack
])
def test_suspected_time_unit(step: float, unit: str | None) -> None:
    assert suspected_time_unit(step) == unit


def _log(path: Path, t: np.ndarray, offset: float = 0.0, seed: int = 0) -> Path:
    rng = np.random.default_rng(seed)
    n = len(t)
    write_log(path, {"t": t, "T_w": 24.0 + offset + 0.01 * rng.standard_normal(n),
                     "T_p": 25.0 + offset + 0.01 * rng.standard_normal(n), "v": np.full(n, 0.141),
                     "T_a": np.full(n, 20.0 + offset)})
    return path


@pytest.fixture
def logs(tmp_path: Path) -> dict[str, Path]:
    k = np.arange(12_000, dtype=float)
    cwd = Path.cwd()
    os.chdir(tmp_path)
    try:
        yield {"s": _log(tmp_path / "s.csv", k * 1e-3), "ms": _log(tmp_path / "ms.csv", k),
               "us": _log(tmp_path / "us.parquet", k * 1000.0),
               "K": _log(tmp_path / "k.csv", k * 1e-3, 273.15)}
    finally:
        os.chdir(cwd)


def invoke(*args: str) -> tuple[int, str, str]:
    r = CliRunner().invoke(main, list(args))
    return r.exit_code, r.stdout, r.stderr


@pytest.mark.parametrize(("log", "option"), [("ms", "--time-unit ms"), ("us", "--time-unit us"),
                                             ("K", "--temp-unit K")])
def test_a_log_in_another_unit_is_refused_with_the_option(logs: dict[str, Path], log: str,
                                                          option: str) -> None:
    for cmd in (["observe", str(logs[log]), "-o", "o.csv"], ["plot", str(logs[log]), "-o", "p.png"]):
        code, _, err = invoke(*cmd)
        assert code == 2, err
        lines = err.strip().splitlines()
        assert len(lines) == 1 and option in lines[0], err
    assert not Path("o.csv").exists() and not Path("p.png").exists()


@pytest.mark.parametrize(("log", "args"), [("ms", ["--time-unit", "ms"]), ("us", ["--time-unit", "us"])])
def test_said_time_unit_gives_the_seconds_log_estimates(logs: dict[str, Path], log: str,
                                                        args: list[str]) -> None:
    """The same samples with t in seconds and in ms (us): the same output, bit for bit (1e-3 * k
    and k * 1e-3 are the same double; 1000 k * 1e-6 may differ in its last bit: within 1e-12)."""
    assert invoke("observe", str(logs["s"]), "-o", "ref.csv")[0] == 0
    code, _, err = invoke("observe", str(logs[log]), "-o", "got.csv", *args)
    assert code == 0, err
    ref = read_log("ref.csv", required=("t", "q_i_hat"))
    got = read_log("got.csv", required=("t", "q_i_hat"))
    assert np.allclose(got["t"], ref["t"], rtol=0, atol=1e-12)
    if log == "ms":
        assert np.array_equal(got["t"], ref["t"]) and np.array_equal(got["q_i_hat"], ref["q_i_hat"])
    np.testing.assert_allclose(got["q_i_hat"], ref["q_i_hat"], rtol=0, atol=1e-9)


def test_said_kelvin_gives_the_celsius_estimates(logs: dict[str, Path]) -> None:
    assert invoke("observe", str(logs["s"]), "-o", "ref.csv")[0] == 0
    assert invoke("observe", str(logs["K"]), "-o", "got.csv", "--temp-unit", "K")[0] == 0
    ref = read_log("ref.csv", required=("T_w", "q_i_hat"))
    got = read_log("got.csv", required=("T_w", "q_i_hat"))
    np.testing.assert_allclose(got["T_w"], ref["T_w"], rtol=0, atol=1e-12)  # written in degC
    np.testing.assert_allclose(got["q_i_hat"], ref["q_i_hat"], rtol=0, atol=1e-9)


def test_seconds_said_reads_a_slow_log_as_it_is(logs: dict[str, Path]) -> None:
    """--time-unit s: a log whose rows are 1 s apart is read as seconds (the user said so)."""
    d = read_log(logs["ms"], units=Units("s"))
    assert d["t"][1] == 1.0


def test_the_reader_refuses_and_converts() -> None:
    """:class:`Units` on the reader: checked on the first chunk, converted on every one."""
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        p = _log(Path(d) / "x.csv", np.arange(5000, dtype=float))
        with pytest.raises(LogError, match="give --time-unit ms"):
            read_log(p, units=Units())
        got = read_log(p, units=Units("ms"))
        assert got["t"][-1] == 4999 * 1e-3
        assert read_log(p)["t"][-1] == 4999.0  # no units: as it is (the library's default)


def test_a_skin_log_in_ms_is_refused(tmp_path: Path) -> None:
    root = Path(__file__).resolve().parents[1]
    from thermoskin.skin.layout import load_skin

    skin = load_skin(root / "examples" / "forearm.toml")
    P, n = len(skin.patches), 200
    t = np.repeat(np.arange(n, dtype=float), P)
    write_log(tmp_path / "skin.csv", {"t": t, "patch": np.tile(np.arange(P), n), "T_w": np.full(n * P, 24.0),
                                      "T_p": np.full(n * P, 25.0), "v": np.full(n * P, 0.141),
                                      "T_a": np.full(n * P, 20.0)})
    r = CliRunner().invoke(main, ["observe", str(tmp_path / "skin.csv"), "--skin",
                                  str(root / "examples" / "forearm.toml"), "-o", str(tmp_path / "o.csv")])
    assert r.exit_code == 2 and "--time-unit ms" in r.stderr and len(r.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize(("step", "unit"), [(10.5, None), (10.1, None), (9.9, "ms"), (0.1, "ms")])
def test_the_edges_of_the_millisecond_rule(step: float, unit: str | None) -> None:
    """10.1 and 10.5 are past 10 ms; 9.9 ms and 0.1 ms are inside."""
    assert suspected_time_unit(step) == unit


def test_the_refusals_word_for_word(tmp_path: Path) -> None:
    """What the refusals say (the rate as read, the step in the suspected unit, the option), for a
    log of two rows already, and for temperatures at the very ends of the kelvin range; at most
    four columns named."""
    p = tmp_path / "x.csv"
    p.write_text("t,T_w\n0,24\n2,24\n")
    with pytest.raises(LogError) as e:
        read_log(p, required=("t",), units=Units())
    assert str(e.value) == (f"{p}: t steps by 2 a row: read as seconds the log is sampled at 0.5 Hz, which a "
                            "skin's log never is (rows every 0.1 to 10 ms); read as milliseconds it is every "
                            "2 ms: give --time-unit ms (or --time-unit s if t is in seconds)")
    p.write_text("t,T_w\n0,24\n5000,24\n")
    with pytest.raises(LogError, match="read as microseconds it is every 5 ms: give --time-unit us"):
        read_log(p, required=("t",), units=Units())
    for edge in (200.0, 400.0):
        p.write_text(f"t,T_w\n0,{edge}\n0.001,{edge}\n")
        with pytest.raises(LogError, match=f"T_w about {edge:.1f}: no skin"):
            read_log(p, required=("t",), units=Units())
    p.write_text("t,T_w,T_w2,T_p,T_a,T_w_cmd\n0,297,297,298,293,297\n0.001,297,297,298,293,297\n")
    with pytest.raises(LogError) as e:
        read_log(p, required=("t",), units=Units())
    assert str(e.value) == (f"{p}: T_w about 297.0, T_w2 about 297.0, T_p about 298.0, T_a about 293.0: no "
                            "skin is that warm in degrees Celsius; read as kelvin that is 23.9 degC: give "
                            "--temp-unit K (or --temp-unit C if they are in degrees Celsius)")


def test_check_on_its_own_takes_one_row_a_sample() -> None:
    """:meth:`Units.check` without ``rows_per_sample``: each row a sample (a step of 1 between rows)."""
    cols = [np.array([0.0, 1.0, 2.0, 3.0])]
    with pytest.raises(LogError, match="t steps by 1 a row"):
        Units().check(Path("x.csv"), ["t"], cols)
    Units().check(Path("x.csv"), ["t"], [np.array([0.0, 0.0, 1e-3, 1e-3])], rows_per_sample=2)
