"""Kind of touch: tap, hold, stroke, grasp, from contacts on one patch or on several.

**One patch** (one thermocouple per patch: where on the patch the contact sits is not
seen): a contact shorter than :data:`thermoskin.estimation.events.TAP_S` is a ``tap``, a
longer one a ``hold``.

**Several patches** (a skin description, :mod:`thermoskin.skin.layout`, with one contact list
per patch): the contacts are first joined into *touches*. Two contacts on different
patches belong to the same touch when one begins before the other has ended, or at most
:data:`LINK_S` after it (a hand sliding across the gap between two patches), and, when
the patches' neighbours are given, when the two patches are neighbours. A touch on one
patch only is split back into its contacts (each a tap or a hold). A touch over several
patches is a

- ``grasp`` when at least two patches are in contact *at once* for :data:`GRASP_S` or
  longer (a hand closing on a forearm covers several patches together), else a
- ``stroke`` (the contact moves: each patch's contact begins after the previous one's,
  and any overlap between them is shorter than :data:`GRASP_S`).

A stroke *along* one patch cannot be told from a hold with one thermocouple per patch;
the spatial skin's several thermocouples along the pipe could (a later issue).

The rule is a decision on the contacts' times only: it needs no estimate of the heat,
and it works with any detector's events. Until the log of a skin of many patches is
observed per patch (events with a ``patch`` column), it is applied to lists of
``(patch, event)`` pairs (:func:`touches`).
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from thermoskin.estimation.events import ContactEvent, one_patch_kind

LINK_S = 0.5
"""Contacts on two patches up to this long apart belong to one touch, s."""
GRASP_S = 0.5
"""Several patches in contact at once for this long make a grasp, s."""


@dataclass(frozen=True)
class Touch:
    """One touch: its ``kind``, the indices of its contacts in the list given to
    :func:`touches`, the patches in the order they were first touched, its start and end (s)."""

    kind: str
    members: tuple[int, ...]
    patches: tuple[int, ...]
    onset: float
    release: float


def _overlap_longest(spans: Sequence[tuple[int, float, float]]) -> float:
    """The longest stretch during which two or more distinct patches are in contact at once, s."""
    edges = sorted({t for _, a, b in spans for t in (a, b)})
    best = run = 0.0
    for a, b in itertools.pairwise(edges):
        mid = 0.5 * (a + b)
        on = {p for p, lo, hi in spans if lo <= mid < hi}
        if len(on) >= 2:
            run += b - a
            best = max(best, run)
        else:
            run = 0.0
    return best


def touches(contacts: Sequence[tuple[int, ContactEvent]],
            neighbours: Mapping[int, set[int] | frozenset[int]] | None = None) -> list[Touch]:
    """The touches made of ``contacts`` (``(patch, event)`` pairs, any order; module doc),
    in the order of their onsets. ``neighbours[p]``: the patches next to patch ``p``
    (default: any two patches may share a touch)."""
    order = sorted(range(len(contacts)), key=lambda i: contacts[i][1].onset)
    groups: list[list[int]] = []
    group_of: dict[int, int] = {}
    # Contacts in order of onset: one that began earlier (f.onset <= e.onset <= e.release) joins
    # e while f.release + LINK_S >= e.onset, a test that every later contact fails once this
    # one does. So only the contacts still open are looked at, and e joins the first group
    # (in the order they were made) holding one of them on a neighbouring patch: the touches of
    # a pass over every pair, in time linear in the contacts times those open at once.
    open_: list[int] = []
    for i in order:
        p, e = contacts[i]
        open_ = [j for j in open_ if contacts[j][1].release + LINK_S >= e.onset]
        near = None if neighbours is None else neighbours.get(p, ())
        joined = None
        for j in open_:
            q, f = contacts[j]
            if q == p or (near is not None and q not in near):
                continue
            if f.onset <= e.release + LINK_S and (joined is None or group_of[j] < joined):
                joined = group_of[j]
        if joined is None:
            group_of[i] = len(groups)
            groups.append([i])
        else:
            group_of[i] = joined
            groups[joined].append(i)
        open_.append(i)
    out: list[Touch] = []
    for g in groups:
        patches = tuple(dict.fromkeys(contacts[i][0] for i in g))
        if len(patches) == 1:  # one patch: each contact a tap or a hold of its own
            out.extend(Touch(one_patch_kind(contacts[i][1].duration), (i,), patches,
                             contacts[i][1].onset, contacts[i][1].release) for i in g)
            continue
        spans = [(contacts[i][0], contacts[i][1].onset, contacts[i][1].release) for i in g]
        kind = "grasp" if _overlap_longest(spans) >= GRASP_S else "stroke"
        out.append(Touch(kind, tuple(g), patches, min(s[1] for s in spans), max(s[2] for s in spans)))
    out.sort(key=lambda tc: tc.onset)
    return out


def kinds_of(contacts: Sequence[tuple[int, ContactEvent]],
             neighbours: Mapping[int, set[int] | frozenset[int]] | None = None) -> list[str]:
    """Per contact of ``contacts``, the kind of the touch it belongs to (:func:`touches`)."""
    kinds = [""] * len(contacts)
    for tc in touches(contacts, neighbours):
        for i in tc.members:
            kinds[i] = tc.kind
    return kinds
