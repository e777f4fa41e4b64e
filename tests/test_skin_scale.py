"""Skins of many patches (issue 46): neighbours from the layout's grid equal the gaps of every
pair; events and contacts joined by a sweep over their onsets give the groups and kinds of a
pass over every pair (the algorithms as they were, written out below as the reference); a
skin log's blocks hold at most ``ROWS_PER_BLOCK`` rows whatever the skin's size, and the
estimates do not depend on the blocks."""

from __future__ import annotations

import math
import random
from pathlib import Path

import pytest

from thermoskin.estimation.events import ContactEvent, one_patch_kind
from thermoskin.skin import log as skin_log
from thermoskin.skin.groups import REACH, SLACK, gap, group_events, neighbours, touch_kinds
from thermoskin.skin.layout import load_skin, parse_skin
from thermoskin.skin.observe import SkinEvent
from thermoskin.touch.kinds import GRASP_S, LINK_S, _overlap_longest, touches

ROOT = Path(__file__).resolve().parents[1]


def random_skin(n: int, seed: int):  # type: ignore[no-untyped-def]
    """``n`` patches of random sizes and angles on two links, packed so that many are near."""
    rng = random.Random(seed)
    links = {"a": (0.30, 0.20), "b": (0.15, 0.10)}
    data: dict = {"name": f"random{n}", "loops": {}, "patches": {},
                  "links": {k: {"length": L, "circumference": C, "origin": [0.4 * i, 0.0]}
                            for i, (k, (L, C)) in enumerate(links.items())}}
    names = [f"p{k}" for k in range(n)]
    for j in range(0, n, 5):
        members = names[j:j + 5]
        data["loops"][f"l{j}"] = {"patches": members, "pipes": [0.1] + [0.02] * (len(members) - 1) + [0.1],
                                  "tank": [-0.05, 0.0]}
    for name in names:
        link = rng.choice(list(links))
        L, C = links[link]
        data["patches"][name] = {"link": link, "angle": rng.uniform(0.0, 180.0),
                                 "centre": [rng.uniform(0.02, L - 0.02), rng.uniform(0.02, C - 0.02)],
                                 "length": rng.choice([0.02, 0.03, 0.04]),
                                 "width": rng.choice([0.005, 0.01, 0.02])}
    return parse_skin(data, f"random{n}")


SKINS = {"forearm": lambda: load_skin(ROOT / "examples" / "forearm.toml"),
         "upper_arm": lambda: load_skin(ROOT / "benchmarks" / "skins" / "upper_arm.toml"),
         "random": lambda: random_skin(120, 3)}


@pytest.mark.parametrize("name", list(SKINS))
@pytest.mark.parametrize("reach", [0.0, REACH, 0.05])
def test_neighbours_are_the_pairs_within_reach(name: str, reach: float) -> None:
    skin = SKINS[name]()
    P = len(skin.patches)
    brute = [frozenset(b for b in range(P) if b != a and gap(skin, a, b) <= reach) for a in range(P)]
    got = neighbours(skin, reach)
    assert got == brute
    if name == "random" and reach == REACH:
        assert sum(map(len, got)) > P  # a test where patches are near each other


def _event(rng: random.Random, t0: float) -> ContactEvent:
    onset = t0 + rng.uniform(0.0, 30.0)
    dur = rng.choice([0.1, 0.3, 0.8, 2.0, 5.0]) * rng.uniform(0.5, 1.5)
    dq = rng.uniform(0.05, 2.0) * rng.choice([1, -1])
    return ContactEvent(onset, onset + 0.1, onset + dur, dur, 1 if dq > 0 else -1, 1.5 * dq, dq, dq * dur)


def random_events(skin, n: int, seed: int) -> list[SkinEvent]:  # type: ignore[no-untyped-def]
    rng = random.Random(seed)
    P = len(skin.patches)
    out = []
    for _ in range(n):
        i = rng.randrange(P)
        out.append(SkinEvent(i, skin.patches[i].name, _event(rng, 0.0)))
    return out


def reference_groups(skin, events, reach=REACH, slack=SLACK):  # type: ignore[no-untyped-def]
    """The grouping as it was (every pair of events, the gap of every pair of patches)."""
    n = len(events)
    parent = list(range(n))

    def find(a: int) -> int:
        while parent[a] != a:
            a = parent[a]
        return a

    for a in range(n):
        for b in range(a + 1, n):
            ea, eb = events[a].event, events[b].event
            if ea.onset > eb.release + slack or eb.onset > ea.release + slack:
                continue
            if events[a].patch == events[b].patch or gap(skin, events[a].patch, events[b].patch) > reach:
                continue
            ra, rb = find(a), find(b)
            if ra != rb:
                parent[ra] = rb
    groups: dict[int, list[int]] = {}
    for a in range(n):
        groups.setdefault(find(a), []).append(a)
    return sorted(tuple(g) for g in groups.values())


@pytest.mark.parametrize("seed", range(6))
def test_groups_equal_every_pair(seed: int) -> None:
    skin = random_skin(60, seed)
    events = random_events(skin, 150, seed)
    got = group_events(skin, events)
    assert sorted(g.members for g in got) == reference_groups(skin, events)
    assert [g.onset for g in got] == sorted(g.onset for g in got)
    multi = [g for g in got if len(g.patches) > 1]
    assert multi  # the case where joining matters


def reference_touches(contacts, neighbours=None):  # type: ignore[no-untyped-def]
    """:func:`touches` as it was: every contact against every member of every group so far."""
    order = sorted(range(len(contacts)), key=lambda i: contacts[i][1].onset)
    groups: list[list[int]] = []
    for i in order:
        p, e = contacts[i]
        joined = None
        for g in groups:
            for j in g:
                q, f = contacts[j]
                if q == p or (neighbours is not None and q not in neighbours.get(p, ())):
                    continue
                if e.onset <= f.release + LINK_S and f.onset <= e.release + LINK_S:
                    joined = g
                    break
            if joined is not None:
                break
        if joined is None:
            groups.append([i])
        else:
            joined.append(i)
    out = []
    for g in groups:
        patches = tuple(dict.fromkeys(contacts[i][0] for i in g))
        if len(patches) == 1:
            out.extend((one_patch_kind(contacts[i][1].duration), (i,)) for i in g)
            continue
        spans = [(contacts[i][0], contacts[i][1].onset, contacts[i][1].release) for i in g]
        out.append(("grasp" if _overlap_longest(spans) >= GRASP_S else "stroke", tuple(g)))
    return sorted(out, key=lambda x: (contacts[x[1][0]][1].onset, x[1]))


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("with_neighbours", [True, False])
def test_touches_equal_every_pair(seed: int, with_neighbours: bool) -> None:
    skin = random_skin(40, seed)
    events = random_events(skin, 120 if with_neighbours else 20, seed + 100)
    contacts = [(e.patch, e.event) for e in events]
    nb = dict(enumerate(neighbours(skin))) if with_neighbours else None
    got = sorted(((t.kind, t.members) for t in touches(contacts, nb)),
                 key=lambda x: (contacts[x[1][0]][1].onset, x[1]))
    assert got == reference_touches(contacts, nb)
    assert any(len(m) > 1 for _, m in got) and any(len(m) == 1 for _, m in got)


def test_touch_kinds_without_events_computes_nothing(monkeypatch: pytest.MonkeyPatch) -> None:
    """No event: no neighbour computed at all (it was every pair of patches, even then)."""
    import thermoskin.skin.groups as groups

    def boom(*_: object, **__: object) -> None:
        raise AssertionError("neighbours computed without an event")

    monkeypatch.setattr(groups, "neighbours", boom)
    assert touch_kinds(random_skin(30, 1), []) == []


def test_blocks_are_bounded_by_rows() -> None:
    """Samples a block: the chunk's, fewer for a big skin; never more than ROWS_PER_BLOCK rows."""
    R = skin_log.ROWS_PER_BLOCK
    assert skin_log.block_samples(9) == skin_log.CHUNK_SAMPLES
    assert skin_log.block_samples(10_000) == R // 10_000 == 104
    assert skin_log.block_samples(10 * R) == 1
    for P in (1, 7, 1000, 4097, 65_536, 10**6):
        m = skin_log.block_samples(P)
        assert m >= 1 and (m * P <= R or m == 1)


def test_estimates_do_not_depend_on_the_blocks(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`observe --skin` of a forearm log with blocks of 16 384 samples and of 7 (what a skin of
    150 000 patches would get): the same events, positions and estimates."""
    from thermoskin.runtime.skin_loop import run_skin
    from thermoskin.sim.skin_scenarios import skin_scenario
    from thermoskin.skin.observe import observe_skin_file

    skin = load_skin(ROOT / "examples" / "forearm.toml")
    log = tmp_path / "skin.csv"
    run_skin(skin, skin_scenario("multi", skin, 12.0), log)
    a = observe_skin_file(log, skin, tmp_path / "a.csv")
    monkeypatch.setattr(skin_log, "ROWS_PER_BLOCK", 7 * len(skin.patches))
    b = observe_skin_file(log, skin, tmp_path / "b.csv")
    assert a.events == b.events and len(a.events) > 0
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()
    assert math.isfinite(a.t_s)


def test_a_skin_beyond_the_limit_is_refused_at_once() -> None:
    """More patches than ``MAX_PATCHES``: one line with the limit and why, before any patch is read."""
    from thermoskin.params import ConfigError
    from thermoskin.skin.layout import MAX_PATCHES

    n = MAX_PATCHES + 1
    data = {"links": {"a": {"length": 1.0, "circumference": 1.0}},
            "loops": {"l": {"patches": ["p0"], "pipes": [0.1, 0.1]}},
            "patches": {f"p{k}": {"link": "a", "centre": "not even read"} for k in range(n)}}
    with pytest.raises(ConfigError) as e:
        parse_skin(data, "big.toml")
    msg = str(e.value)
    assert msg.startswith(f"big.toml: [patches] holds {n} patches, more than a skin may have ({MAX_PATCHES}")
    assert "\n" not in msg and len(msg) < 400
