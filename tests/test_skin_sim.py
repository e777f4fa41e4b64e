"""``simulate --skin``: the long-format log's contract, the ``multi`` scenario, the closed loop per
water loop, the layout picture."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from thermoskin.cli import main
from thermoskin.logio import LogReader
from thermoskin.plots.skin import plot_layout
from thermoskin.runtime.skin_loop import run_skin
from thermoskin.sim.skin_scenarios import contact_arrays, skin_scenario
from thermoskin.skin.layout import load_skin

ROOT = Path(__file__).resolve().parent.parent
FOREARM = ROOT / "examples" / "forearm.toml"


def _read(path: Path) -> dict[str, np.ndarray]:
    """The whole long log (``t`` repeats across a sample's patches: read it not as a time series)."""
    import pyarrow.csv as pc
    import pyarrow.parquet as pq

    table = pq.read_table(path) if path.suffix == ".parquet" else pc.read_csv(path)
    return {n: table.column(n).to_numpy() for n in table.column_names}


@pytest.mark.parametrize("ext", ["csv", "parquet"])
def test_log_contract(tmp_path: Path, ext: str) -> None:
    out = tmp_path / f"skin.{ext}"
    res = CliRunner().invoke(main, ["simulate", "--skin", str(FOREARM), "--scenario", "one-finger",
                                    "--duration", "6.5", "-o", str(out)])
    assert res.exit_code == 0, res.output
    skin = load_skin(FOREARM)
    P = len(skin.patches)
    assert "0 dorsal1" in res.output and f"{6500 * P} rows" in res.output
    log = _read(out)
    assert list(log) == ["t", "patch", "T_w", "T_p", "v", "T_a", "T_w2", "q_i", "contact_true",
                         "position_true", "fresh"]
    n = 6500
    assert all(len(x) == n * P for x in log.values())
    t = log["t"].reshape(n, P)
    np.testing.assert_allclose(t, np.repeat(np.arange(n)[:, None] * 1e-3, P, axis=1), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(log["patch"].reshape(n, P), np.tile(np.arange(P), (n, 1)))
    two = np.array([len(p.thermocouples) == 2 for p in skin.patches])
    Tw2 = log["T_w2"].reshape(n, P)
    assert np.isfinite(Tw2[:, two]).all() and np.isnan(Tw2[:, ~two]).all()
    for c in ("T_w", "T_p", "v", "T_a", "q_i", "fresh", "contact_true"):
        assert np.isfinite(log[c]).all(), c
    # a patch reads its own loop's tank, pump and air
    loop = np.array([p.loop for p in skin.patches])
    Tp = log["T_p"].reshape(n, P)
    for j in range(len(skin.loops)):
        assert (Tp[:, loop == j] == Tp[:, [np.flatnonzero(loop == j)[0]]]).all()
    # ideal boards: every channel fresh every sample; T_w2's bit where there is one
    fresh = log["fresh"].reshape(n, P).astype(int)
    assert (fresh & 7 == 7).all() and ((fresh & 8 > 0) == two).all()
    # one-finger on the first patch: its touch, and no other patch touched
    on = log["contact_true"].reshape(n, P).astype(bool)
    q = log["q_i"].reshape(n, P)
    pos = log["position_true"].reshape(n, P)
    assert on[:, 0].any() and not on[:, 1:].any()
    assert (q[~on] == 0).all() and (q[on] > 0.02).all()
    assert np.isnan(pos[~on]).all()
    # position m from the inlet: one-finger's position 0 (the single patch's thermocouple end)
    # is the outlet end: the footprint's centre 5 mm before it
    assert np.allclose(pos[on[:, 0], 0], 0.025)


def test_cli_errors(tmp_path: Path) -> None:
    runner = CliRunner()
    bad = tmp_path / "bad.toml"
    bad.write_text(FOREARM.read_text().replace('link = "hand"', 'link = "foot"', 1))
    for args, msg in (
        (["--skin", str(bad)], "bad.toml: patches.hand_back.link = 'foot' is not a link"),
        (["--skin", str(tmp_path / "none.toml")], "does not exist"),
        (["--skin", str(FOREARM), "--scenario", "excitation"], "unknown scenario 'excitation'"),
        (["--skin", str(FOREARM), "--duration", "-1"], "--duration -1.0 must be > 0 s"),
    ):
        res = runner.invoke(main, ["simulate", *args, "-o", str(tmp_path / "x.csv")])
        assert res.exit_code == 2, res.output
        lines = [ln for ln in res.output.splitlines() if ln.strip()]
        assert len(lines) == 1 and lines[0].startswith("thermoskin: error: ") and msg in lines[0], res.output
    res = runner.invoke(main, ["simulate", "--skin", str(FOREARM), "-o", str(tmp_path / "x.txt")])
    assert res.exit_code == 2 and "must end in .csv or .parquet" in res.output


def test_written_in_blocks_and_reproducible(tmp_path: Path) -> None:
    skin = load_skin(FOREARM)
    sc = skin_scenario("multi", skin, 1.5)
    sizes: list[int] = []
    a = run_skin(skin, sc, tmp_path / "a.parquet", block=400, on_block=lambda c: sizes.append(len(c["t"])))
    run_skin(skin, sc, tmp_path / "b.parquet", block=250)
    P = len(skin.patches)
    assert sizes == [400 * P] * 3 + [300 * P]  # memory bounded by the block, not the duration
    x, y = _read(tmp_path / "a.parquet"), _read(tmp_path / "b.parquet")
    for k in x:
        np.testing.assert_array_equal(x[k], y[k])
    assert a.n == 1500
    with LogReader(tmp_path / "a.parquet", required=("patch",), uniform=False) as r:
        assert r.n_rows == 1500 * P


def test_multi_scenario_covers_the_cases() -> None:
    skin = load_skin(FOREARM)
    sc = skin_scenario("multi", skin)
    t = np.arange(0.0, sc.duration, 0.01)
    patch, G, _, _ = contact_arrays(skin, sc.contacts, t)
    labels = [c.label for c in sc.contacts]
    # a single touch on every patch, each alone on the skin while it lasts
    for p in skin.patches:
        c = labels.index(f"touch {p.name}")
        others = np.delete(G, c, axis=0)
        mine = G[c] > 0
        assert mine.any() and (patch[c, mine] == p.index).all() and (others[:, mine] == 0).all()
    # two at once on the longest loop: its first (upstream) and last (downstream) patch
    pair = [c for c, lab in enumerate(labels) if lab.startswith("pair")]
    both = (G[pair] > 0).all(axis=0)
    assert both.any()
    longest = max(skin.loops, key=lambda lp: len(lp.patches))
    assert {int(patch[c, both][0]) for c in pair} == {longest.patches[0], longest.patches[-1]}
    # a grasp: three or more patches at once
    grasp = [c for c, lab in enumerate(labels) if lab.startswith("grasp")]
    assert len(grasp) >= 3 and (G[grasp] > 0).all(axis=0).any()
    # a stroke across three patches, one after another, with no patch in between
    s = labels.index("stroke")
    seen = [int(i) for i in patch[s] if i >= 0]
    order = [seen[0], *(b for a, b in itertools.pairwise(seen) if b != a)]
    assert len(order) >= 3 and len(set(order)) == len(order)
    gaps = (patch[s] < 0) & (t > sc.contacts[s].t_on + 0.5) & (t < sc.contacts[s].t_off - 0.5)
    assert gaps.any()
    # quiet stretches: 6 s and more with no contact at all
    quiet = ~(G > 0).any(axis=0)
    runs = np.diff(np.flatnonzero(np.diff(np.concatenate(([0], quiet.astype(int), [0])))))[::2]
    assert (runs * 0.01 >= 6.0).sum() >= 5


def test_closed_loop_holds_every_loop_at_its_command() -> None:
    skin = load_skin(FOREARM)
    res = run_skin(skin, skin_scenario("none", skin, 12.0))
    assert len(res.tracking) == 2
    assert max(res.tracking) < 0.2  # mean |T_w - T_w_cmd| of each loop's feedback patch, last 6 s
    assert res.realtime_factor > 1.0


def test_layout_picture(tmp_path: Path) -> None:
    skin = load_skin(FOREARM)
    sc = skin_scenario("multi", skin)
    path = tmp_path / "layout.png"
    fig = plot_layout(skin, [*sc.contacts[-3:], {"patch": "palm", "position": 0.02, "position_sd": 0.005},
                             {"patch": 3, "position": math.nan}, {"link": "hand", "x": 0.02, "y": 0.1}], path)
    assert path.stat().st_size > 20_000 and path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    ax = fig.axes[0]
    from matplotlib.patches import Polygon

    assert sum(isinstance(a, Polygon) for a in ax.patches) == len(skin.patches)
    with pytest.raises(KeyError, match="no patch 'elbow'"):
        plot_layout(skin, [{"patch": "elbow", "position": 0.0}])
