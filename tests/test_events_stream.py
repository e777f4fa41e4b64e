"""The events table written as contacts end (``events.EventsStream``): readable row by row
before the writer closes (what a killed run leaves), in the same form as the whole table."""

from __future__ import annotations

import csv
import math
from pathlib import Path

from thermoskin.estimation.events import EVENT_COLUMNS, ContactEvent, EventsStream, write_events
from thermoskin.skin.observe import SKIN_EVENT_COLUMNS, SkinEvent

TAP = ContactEvent(onset=1.0, detected_at=1.1, release=1.5, duration=0.5, sign=1, peak_dq=0.2,
                   mean_dq=0.1, energy=0.05)
HOLD = ContactEvent(onset=3.0, detected_at=3.2, release=6.0, duration=3.0, sign=-1, peak_dq=-0.4,
                    mean_dq=-0.3, energy=-0.9)


def rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def test_rows_are_there_before_close_and_match_the_whole_table(tmp_path: Path) -> None:
    p = tmp_path / "ev.csv"
    s = EventsStream(p)
    assert p.read_text().splitlines() == [",".join(EVENT_COLUMNS)]  # the header at once
    s.add(TAP)
    got = rows(p)  # not closed: flushed row by row
    assert len(got) == 1 and got[0]["kind"] == "tap" and got[0]["toucher"] == ""
    s.add(HOLD)
    assert [r["kind"] for r in rows(p)] == ["tap", "hold"]
    s.close()
    whole = tmp_path / "whole.csv"
    write_events(whole, [TAP, HOLD])  # the table of the end of a run, no characterisation
    streamed, final = rows(p), rows(whole)
    for a, b in zip(streamed, final, strict=True):
        for k in EVENT_COLUMNS:
            if k == "kind":
                continue  # the whole table's kind comes from the characteriser
            assert a[k] == b[k], (k, a[k], b[k])
    assert float(streamed[1]["onset"]) == 3.0 and streamed[1]["sign"] == "-1"


def test_a_skin_table_keeps_its_patch_and_leaves_what_is_said_at_the_end_empty(tmp_path: Path) -> None:
    p = tmp_path / "skin_ev.csv"
    with EventsStream(p, (*SKIN_EVENT_COLUMNS, "kind"), fill_kind=False) as s:
        s.add_row(SkinEvent(2, "dorsal3", HOLD).row())
        got = rows(p)
    assert list(got[0]) == [*SKIN_EVENT_COLUMNS, "kind"]
    r = got[0]
    assert r["patch"] == "dorsal3" and r["position"] == "" and r["kind"] == ""
    assert math.isclose(float(r["mean_dq"]), -0.3) and r["sign"] == "-1"
