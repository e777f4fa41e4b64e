"""The contracts of issue 13 on the command line: ``simulate --scenario touchers`` writes the
truth per contact, ``observe --events`` writes what touched, ``run --probe`` checks its value."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from thermoskin.cli import main
from thermoskin.estimation.events import EVENT_COLUMNS
from thermoskin.logio import read_log
from thermoskin.physics.contact import CLASSES
from thermoskin.sim.scenarios import SCENARIOS


def invoke(*args: str) -> tuple[int, str, str]:
    res = CliRunner().invoke(main, list(args))
    return res.exit_code, res.stdout, res.stderr


@pytest.fixture(scope="module")
def sim(tmp_path_factory: pytest.TempPathFactory) -> Path:
    p = tmp_path_factory.mktemp("touchers") / "sim.csv"
    code, _, err = invoke("simulate", "--scenario", "touchers", "--duration", "45", "-o", str(p))
    assert code == 0, err
    return p


def test_simulate_touchers_writes_the_truth_per_contact(sim: Path) -> None:
    log = read_log(sim, nan_columns=("T_f_true",))
    assert {"toucher_true", "material_true", "T_f_true", "G_true"} <= set(log)
    sc = SCENARIOS["touchers"]
    for tc in sc.touches:
        if tc.t_off > 44.0:
            continue
        k = round((tc.t_on + 0.5 * tc.duration) / 1e-3)
        human = tc.toucher in ("finger", "palm", "hand")
        assert log["toucher_true"][k] == (1 if human else 0)
        assert log["T_f_true"][k] == pytest.approx(tc.T_body)  # its surface at the onset
        assert log["G_true"][k] > 0.0
        assert (CLASSES[int(log["material_true"][k])] == "human") == human
    idle = log["contact_true"] == 0
    assert (log["toucher_true"][idle] == -1).all() and (log["material_true"][idle] == -1).all()
    assert np.isnan(log["T_f_true"][idle]).all() and (log["G_true"][idle] == 0.0).all()


def test_observe_events_say_what_touched(sim: Path, tmp_path: Path) -> None:
    ev = tmp_path / "ev.csv"
    code, _, err = invoke("observe", str(sim), "-o", str(tmp_path / "o.csv"), "--events", str(ev))
    assert code == 0, err
    with open(ev) as fh:
        rows = list(csv.DictReader(fh))
    assert rows and list(rows[0]) == list(EVENT_COLUMNS)
    log = read_log(sim, nan_columns=("T_f_true",))
    decided = [r for r in rows if r["toucher"]]
    assert len(decided) >= 2 and {r["toucher"] for r in decided} == {"human", "object"}  # not all empty
    for r in rows:
        assert r["kind"] in ("tap", "hold")
        assert 0.0 <= float(r["p_human"]) <= 1.0
        k = round((float(r["onset"]) + 0.1) / 1e-3)
        if r["toucher"]:  # where it is decided, it is right
            assert r["toucher"] == ("human" if log["toucher_true"][k] == 1 else "object")
        for name in ("T_f_hat", "G_hat", "effusivity_hat"):
            assert r[name] == "" or math.isfinite(float(r[name]))


@pytest.mark.parametrize(("args", "msg"), [
    (["--probe", "5"], "--probe 5.0: A = 5.0 K must be in [0, 2]"),
    (["--probe", "0.3", "--realtime"], "--probe: only with the simulated skin"),
])
def test_run_probe_bad_value_is_one_line(tmp_path: Path, args: list[str], msg: str) -> None:
    code, _, err = invoke("run", "--scenario", "none", "--duration", "1", "--log",
                          str(tmp_path / "r.csv"), *args)
    assert code == 2
    assert msg in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "r.csv").exists()
