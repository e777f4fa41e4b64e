"""Contacts across patches: events on neighbouring patches that overlap in time, one body contact.

Whole-body skins report a contact as a body link, a place on it, the cells involved and a
strength (iCub's ``skinContact``). Two patch events belong to one contact when they are on the
same link, overlap in time (``[onset, release]``, with ``slack`` s of tolerance) and the
patches are neighbours: their rectangles on the link's unrolled surface come within ``reach``
m of each other. Grouping is transitive (a grasp over four patches in a row is one contact).

A :class:`BodyContact` has the link, the time span, the patches, the total heat flow (the sum
of the events' mean estimated heat, W, signed) and the centre on the link: the heat-weighted
mean of each event's point (its position along the pipe where known, else the patch's centre).

**Scale.** Neighbours come from the layout (:func:`neighbours`: each link's patches in a grid
of cells at least as wide as a patch and ``reach``, so a patch is compared with those of its
own and the eight cells around: linear in the patches, not the ``P**2`` gaps of every pair,
10**8 for 10 000 patches), and events are joined by a sweep over their onsets that keeps only
those still open (:func:`group_events`, :func:`touch_kinds`): linear in the events times the
contacts open at once, not their square.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from thermoskin.skin.layout import Skin
from thermoskin.skin.observe import SkinEvent

REACH = 0.02
"""Patches whose rectangles come within this distance (m) are neighbours."""
SLACK = 0.3
"""Events this far apart in time (s) still overlap (detections differ by a few tenths)."""

GROUP_COLUMNS = ("contact", "link", "onset", "release", "n_patches", "patches", "x", "y", "heat")
"""Columns of the groups table: number, link, span (s), patches (names joined by ``+``), centre on
the link (m), total heat flow (W)."""


@dataclass(frozen=True)
class BodyContact:
    """One contact on a body link (module doc)."""

    link: str
    onset: float
    release: float
    patches: tuple[str, ...]
    centre: tuple[float, float]
    heat: float
    members: tuple[int, ...]
    """Indices of the member events in the list given to :func:`group_events`."""

    def row(self, number: int) -> dict[str, object]:
        return {"contact": number, "link": self.link, "onset": self.onset, "release": self.release,
                "n_patches": len(self.patches), "patches": "+".join(self.patches),
                "x": self.centre[0], "y": self.centre[1], "heat": self.heat}


def gap(skin: Skin, a: int, b: int) -> float:
    """Distance (m) between the rectangles of patches ``a`` and ``b`` on their link (inf on
    different links; 0 where they overlap)."""
    pa, pb = skin.patches[a], skin.patches[b]
    if pa.link != pb.link:
        return math.inf
    ca, cb = pa.corners(), pb.corners()
    if _overlap(ca, cb):
        return 0.0
    return min(min(_seg_dist(p, cb[k], cb[(k + 1) % 4]) for p in ca for k in range(4)),
               min(_seg_dist(p, ca[k], ca[(k + 1) % 4]) for p in cb for k in range(4)))


def _seg_dist(p: tuple[float, float], a: tuple[float, float], b: tuple[float, float]) -> float:
    ax, ay = a
    dx, dy = b[0] - ax, b[1] - ay
    L2 = dx * dx + dy * dy
    u = 0.0 if L2 == 0 else min(1.0, max(0.0, ((p[0] - ax) * dx + (p[1] - ay) * dy) / L2))
    return math.hypot(p[0] - ax - u * dx, p[1] - ay - u * dy)


def _overlap(ca: list[tuple[float, float]], cb: list[tuple[float, float]]) -> bool:
    """Two convex quadrilaterals intersect (separating axis test)."""
    for poly in (ca, cb):
        for k in range(4):
            (x0, y0), (x1, y1) = poly[k], poly[(k + 1) % 4]
            nx, ny = y0 - y1, x1 - x0
            pa = [nx * x + ny * y for x, y in ca]
            pb = [nx * x + ny * y for x, y in cb]
            if max(pa) < min(pb) - 1e-12 or max(pb) < min(pa) - 1e-12:
                return False
    return True


def _box(corners: list[tuple[float, float]]) -> tuple[float, float, float, float]:
    xs, ys = [c[0] for c in corners], [c[1] for c in corners]
    return min(xs), min(ys), max(xs), max(ys)


def neighbours(skin: Skin, reach: float = REACH) -> list[frozenset[int]]:
    """Per patch, the other patches on its link whose rectangles come within ``reach`` m of its own
    (:func:`gap` ``<= reach``), found through a grid of each link's surface (module doc)."""
    P = len(skin.patches)
    out: list[set[int]] = [set() for _ in range(P)]
    by_link: dict[str, list[int]] = {}
    for p in skin.patches:
        by_link.setdefault(p.link, []).append(p.index)
    for members in by_link.values():
        boxes = {i: _box(skin.patches[i].corners()) for i in members}
        size = max(max(b[2] - b[0], b[3] - b[1]) for b in boxes.values()) + reach
        size = size if size > 0 else 1.0
        cells: dict[tuple[int, int], list[int]] = {}
        where = {}
        for i, (x0, y0, x1, y1) in boxes.items():
            key = (math.floor(0.5 * (x0 + x1) / size), math.floor(0.5 * (y0 + y1) / size))
            where[i] = key
            cells.setdefault(key, []).append(i)
        for a in members:
            ax0, ay0, ax1, ay1 = boxes[a]
            cx, cy = where[a]
            for kx in (cx - 1, cx, cx + 1):
                for ky in (cy - 1, cy, cy + 1):
                    for b in cells.get((kx, ky), ()):
                        if b <= a:
                            continue
                        bx0, by0, bx1, by1 = boxes[b]
                        if bx0 - ax1 > reach or ax0 - bx1 > reach or by0 - ay1 > reach or ay0 - by1 > reach:
                            continue  # their boxes are farther apart: so are the rectangles
                        if gap(skin, a, b) <= reach:
                            out[a].add(b)
                            out[b].add(a)
    return [frozenset(s) for s in out]


def group_events(skin: Skin, events: list[SkinEvent], *, reach: float = REACH,
                 slack: float = SLACK, near: list[frozenset[int]] | None = None) -> list[BodyContact]:
    """The body contacts of ``events`` (module doc), in order of onset. ``near``: the skin's
    :func:`neighbours` at ``reach`` where already known."""
    n = len(events)
    parent = list(range(n))

    def find(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    if n > 1:
        near = neighbours(skin, reach) if near is None else near
        order = sorted(range(n), key=lambda i: events[i].event.onset)
        open_: list[int] = []  # events whose release + slack is not yet behind the onsets reached
        for b in order:
            eb = events[b]
            onset = eb.event.onset
            open_ = [a for a in open_ if events[a].event.release + slack >= onset]
            nb = near[eb.patch]
            for a in open_:  # a began first: a.onset <= b.onset <= b.release + slack
                if events[a].patch in nb:
                    parent[find(a)] = find(b)
            open_.append(b)
    groups: dict[int, list[int]] = {}
    for a in range(n):
        groups.setdefault(find(a), []).append(a)
    out = []
    for members in groups.values():
        evs = [events[m] for m in members]
        link = skin.patches[evs[0].patch].link
        pts, ws = [], []
        for e in evs:
            p = skin.patches[e.patch]
            s = e.position.mean
            pts.append(p.point_at(s) if math.isfinite(s) else p.centre)
            ws.append(abs(e.event.mean_dq) + 1e-12)
        w = np.array(ws)
        xy = np.array(pts)
        cx, cy = (w @ xy) / w.sum()
        names = tuple(dict.fromkeys(e.name for e in evs))
        out.append(BodyContact(link, min(e.event.onset for e in evs), max(e.event.release for e in evs),
                               names, (float(cx), float(cy)), float(sum(e.event.mean_dq for e in evs)),
                               tuple(members)))
    out.sort(key=lambda g: (g.onset, g.link))
    return out


def groups_columns(groups: list[BodyContact]) -> dict[str, np.ndarray]:
    """The groups as columns of :data:`GROUP_COLUMNS` (numbered from 1)."""
    rows = [g.row(k + 1) for k, g in enumerate(groups)]
    kind = {"link": object, "patches": object, "contact": np.int64, "n_patches": np.int64}
    return {c: np.array([r[c] for r in rows], dtype=kind.get(c, float)) for c in GROUP_COLUMNS}


def touch_kinds(skin: Skin, events: list[SkinEvent], *, reach: float = REACH) -> list[str]:
    """Per event, the kind of the touch it belongs to: ``tap``, ``hold``, ``stroke`` or
    ``grasp`` (:func:`thermoskin.touch.kinds.touches`, with the patches within ``reach`` of
    each other on a link as neighbours)."""
    from thermoskin.touch.kinds import kinds_of

    if not events:
        return []
    near = neighbours(skin, reach)
    return kinds_of([(e.patch, e.event) for e in events], dict(enumerate(near)))
