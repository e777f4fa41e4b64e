"""Kind of touch: tap and hold on one patch, stroke and grasp across patches, on event lists
written by hand (each case's expected kind follows from the rule's definition, not from the code)."""

from __future__ import annotations

import math

import pytest

from thermoskin.estimation.events import TAP_S, ContactEvent, one_patch_kind
from thermoskin.touch.kinds import GRASP_S, LINK_S, kinds_of, touches


def ev(onset: float, release: float) -> ContactEvent:
    return ContactEvent(onset=onset, detected_at=onset + 0.04, release=release,
                        duration=release - onset, sign=1, peak_dq=1.0, mean_dq=0.5, energy=1.0)


def test_one_patch_tap_and_hold() -> None:
    assert one_patch_kind(0.3) == "tap"
    assert one_patch_kind(TAP_S - 1e-9) == "tap"
    assert one_patch_kind(TAP_S) == "hold"
    assert one_patch_kind(4.0) == "hold"
    assert one_patch_kind(math.nan) == ""  # still on: not known yet


def test_repeated_contacts_on_one_patch_stay_separate() -> None:
    cs = [(0, ev(1.0, 1.3)), (0, ev(1.5, 1.8)), (0, ev(3.0, 6.0))]
    assert kinds_of(cs) == ["tap", "tap", "hold"]
    assert len(touches(cs)) == 3


def test_a_hand_closing_on_three_patches_is_one_grasp() -> None:
    cs = [(2, ev(5.05, 8.0)), (0, ev(5.0, 8.1)), (1, ev(5.1, 7.9)), (3, ev(20.0, 20.3))]
    tcs = touches(cs)
    assert [t.kind for t in tcs] == ["grasp", "tap"]
    assert tcs[0].patches == (0, 2, 1) and tcs[0].onset == 5.0 and tcs[0].release == 8.1
    assert kinds_of(cs) == ["grasp", "grasp", "grasp", "tap"]


def test_a_finger_sliding_along_a_row_of_patches_is_one_stroke() -> None:
    # each patch touched 0.6 s, the next one 0.5 s after (0.1 s of overlap), then a gap of 0.3 s
    cs = [(0, ev(1.0, 1.6)), (1, ev(1.5, 2.1)), (2, ev(2.4, 3.0))]
    tcs = touches(cs)
    assert len(tcs) == 1 and tcs[0].kind == "stroke" and tcs[0].patches == (0, 1, 2)


def test_overlap_threshold_separates_stroke_from_grasp() -> None:
    d = 0.01
    stroke = [(0, ev(0.0, 1.0)), (1, ev(1.0 - (GRASP_S - d), 2.0))]
    grasp = [(0, ev(0.0, 1.0)), (1, ev(1.0 - (GRASP_S + d), 2.0))]
    assert kinds_of(stroke) == ["stroke", "stroke"]
    assert kinds_of(grasp) == ["grasp", "grasp"]


def test_contacts_further_apart_than_the_link_are_separate_touches() -> None:
    cs = [(0, ev(0.0, 2.0)), (1, ev(2.0 + LINK_S + 0.01, 4.0))]
    assert kinds_of(cs) == ["hold", "hold"]
    cs = [(0, ev(0.0, 2.0)), (1, ev(2.0 + LINK_S - 0.01, 4.0))]
    assert kinds_of(cs) == ["stroke", "stroke"]


@pytest.mark.parametrize(("neighbours", "kinds"), [
    ({0: {1}, 1: {0, 2}, 2: {1}}, ["stroke", "stroke"]),  # 0 and 1 are neighbours
    ({0: set(), 1: set()}, ["tap", "tap"]),  # far apart on the body: two touches at once
])
def test_neighbours_decide_whether_two_patches_share_a_touch(neighbours: dict[int, set[int]],
                                                             kinds: list[str]) -> None:
    cs = [(0, ev(0.0, 0.5)), (1, ev(0.45, 0.9))]
    assert kinds_of(cs, neighbours) == kinds


def test_on_the_forearm_neighbours_are_the_patches_side_by_side() -> None:
    """`touch_kinds` on examples/forearm.toml: dorsal1-3 lie 10 mm apart along the back of the arm
    (neighbours), ventral1 on the inside 100 mm away (not): a hand closing on dorsal1-3 is a grasp,
    a finger sliding dorsal1 -> dorsal2 a stroke, and a touch on ventral1 at the same time as the
    grasp a hold of its own."""
    from pathlib import Path

    from thermoskin.skin.groups import touch_kinds
    from thermoskin.skin.layout import load_skin
    from thermoskin.skin.observe import SkinEvent

    skin = load_skin(Path(__file__).resolve().parents[1] / "examples" / "forearm.toml")
    idx = {p.name: p.index for p in skin.patches}

    def se(name: str, onset: float, release: float) -> SkinEvent:
        return SkinEvent(idx[name], name, ev(onset, release))

    events = [se("dorsal1", 10.0, 13.0), se("dorsal2", 10.1, 13.0), se("dorsal3", 10.2, 12.9),
              se("ventral1", 10.5, 12.5),
              se("dorsal1", 20.0, 20.6), se("dorsal2", 20.6, 21.2)]
    assert touch_kinds(skin, events) == ["grasp", "grasp", "grasp", "hold", "stroke", "stroke"]
