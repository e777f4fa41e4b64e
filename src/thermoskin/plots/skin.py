"""The layout of a skin of many patches: links, patches, their pipes and thermocouples, the water
loops and their tanks, and contacts marked on it.

Drawn with matplotlib's object API on an Agg canvas (no pyplot, no global state), in mm.
Each link is its surface unrolled (x along its axis, y around it) placed at its ``origin``;
a patch is its rectangle on that surface, its pipe an arrow from inlet to outlet, its
thermocouples dots (``T_w`` filled, ``T_w2``... open); each loop's water path is a dashed
line in the loop's colour from its tank through every patch in order and back.

A large skin (more than :data:`DETAIL_PATCHES` patches) is drawn plainly, so that the picture
takes seconds, not minutes: each loop's patches as one collection, no names, pipe arrows,
thermocouples or tank labels, the loops' legend only for a few loops, and beyond
:data:`DETAIL_CONTACTS` contacts, each a cross without its label.

``contacts`` are marked in red: each a mapping with ``patch`` (name or index) and
``position`` (m from its inlet; NaN or absent: the patch as a whole) and optionally
``position_sd`` (m, drawn as a bar along the pipe) and ``label``; or ``link``, ``x``, ``y`` (m,
on the link); or a :class:`~thermoskin.sim.skin_scenarios.SkinContact` (a stroke drawn as its
path).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from thermoskin.atomic import atomic_path
from thermoskin.paths import shown
from thermoskin.skin.layout import Skin

MM = 1000.0
#: More patches than this: the plain picture (module doc).
DETAIL_PATCHES = 200
#: More contacts than this: crosses without labels.
DETAIL_CONTACTS = 200
#: More loops than this: no legend of the loops.
LEGEND_LOOPS = 12
LOOP_COLOURS = ("tab:blue", "tab:green", "tab:purple", "tab:orange", "tab:brown", "tab:cyan", "tab:olive")


def _xy(skin: Skin, link: str, x: float, y: float) -> tuple[float, float]:
    """A point on a link's surface in the picture, mm."""
    ox, oy = skin.links[link].origin
    return (ox + x) * MM, (oy + y) * MM


def _contact_points(skin: Skin, c: Any) -> tuple[list[tuple[float, float]], str, float, Any]:
    """(points in mm, label, sd in mm, patch) of one contact to mark."""
    from thermoskin.sim.skin_scenarios import SkinContact

    if isinstance(c, SkinContact):
        if c.patch is None:
            pts = [_xy(skin, c.link, x, y) for _, x, y in c.path]  # type: ignore[arg-type]
            return pts, c.label or "stroke", 0.0, None
        c = {"patch": c.patch, "position": c.position, "label": c.label}
    if not isinstance(c, Mapping):
        raise ValueError(f"plot_layout: a contact must be a mapping or a SkinContact, got {c!r}")
    label = str(c.get("label", ""))
    if "patch" in c:
        p = skin.patch(c["patch"])
        s = c.get("position", math.nan)
        s = math.nan if s is None else float(s)
        sd = float(c.get("position_sd", 0.0) or 0.0)
        if math.isnan(s):
            return [_xy(skin, p.link, *p.centre)], label, -1.0, p
        return [_xy(skin, p.link, *p.point_at(min(max(s, 0.0), p.length)))], label, sd * MM, p
    return [_xy(skin, str(c["link"]), float(c["x"]), float(c["y"]))], label, 0.0, None


def plot_layout(skin: Skin, contacts: Iterable[Any] = (), path: str | Path | None = None, *,
                title: str | None = None) -> Any:
    """The skin's layout with ``contacts`` marked (module doc); saved to ``path`` (PNG) if given.

    Returns the matplotlib ``Figure``.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import PolyCollection
    from matplotlib.figure import Figure
    from matplotlib.patches import Polygon, Rectangle

    detail = len(skin.patches) <= DETAIL_PATCHES
    contacts = list(contacts)

    fig = Figure(figsize=(10, 6.2), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    ax.set_aspect("equal")
    ax.set_xlabel("x along the link (mm)")
    ax.set_ylabel("y around the link (mm)")
    ax.set_title(shown(title or f"{skin.name}: {len(skin.patches)} patches on {len(skin.loops)} water loops"))
    for name, link in skin.links.items():
        x0, y0 = _xy(skin, name, 0.0, 0.0)
        ax.add_patch(Rectangle((x0, y0), link.length * MM, link.circumference * MM, facecolor="0.95",
                               edgecolor="0.6", lw=1.0, zorder=0))
        ax.text(x0 + 2, y0 + link.circumference * MM - 2, f"link {name}", va="top", fontsize=8, color="0.35")
    xs: list[float] = []
    ys: list[float] = []
    for lp in skin.loops:
        col = LOOP_COLOURS[lp.index % len(LOOP_COLOURS)]
        tank = (lp.tank[0] * MM, lp.tank[1] * MM)
        route = [tank]
        for i in lp.patches:
            p = skin.patches[i]
            route += [_xy(skin, p.link, *p.point_at(0.0)), _xy(skin, p.link, *p.point_at(p.length))]
        route.append(tank)
        label = (f"loop {lp.name}: {' > '.join(skin.patches[i].name for i in lp.patches)}"
                 if len(skin.loops) <= LEGEND_LOOPS else None)
        ax.plot([q[0] for q in route], [q[1] for q in route], ls="--", lw=0.9 if detail else 0.3, color=col,
                alpha=0.8, zorder=1, label=label)
        ax.add_patch(Rectangle((tank[0] - 6, tank[1] - 6), 12, 12, facecolor=col, edgecolor="k", zorder=3))
        xs += [tank[0] - 8, tank[0] + 8]
        ys += [tank[1] - 20, tank[1] + 8]
        if not detail:  # the plain picture: the loop's patches as one collection
            polys = [[_xy(skin, skin.patches[i].link, *c) for c in skin.patches[i].corners()]
                     for i in lp.patches]
            ax.add_collection(PolyCollection(polys, facecolors=col, alpha=0.35, edgecolors=col,
                                             linewidths=0.3, zorder=2))
            continue
        ax.text(tank[0], tank[1] - 9, f"tank\n{lp.name}", ha="center", va="top", fontsize=7)
        for i in lp.patches:
            p = skin.patches[i]
            corners = [_xy(skin, p.link, *c) for c in p.corners()]
            ax.add_patch(Polygon(corners, closed=True, facecolor=col, alpha=0.25, edgecolor=col, lw=1.2,
                                 zorder=2))
            a, b = _xy(skin, p.link, *p.point_at(0.0)), _xy(skin, p.link, *p.point_at(p.length))
            ax.annotate("", xy=b, xytext=a, arrowprops={"arrowstyle": "->", "color": col, "lw": 1.3},
                        zorder=4)
            cx, cy = _xy(skin, p.link, *p.centre)
            dx, dy = p.direction
            off = 0.5 * p.width * MM + 3
            ax.text(cx - dy * off, cy + dx * off, f"{p.index} {p.name}", ha="center", va="center", fontsize=7)
            for j, s in enumerate(p.thermocouples):
                tx, ty = _xy(skin, p.link, *p.point_at(s))
                ax.plot([tx], [ty], "o", ms=4, mfc=col if j == 0 else "white", mec="k", mew=0.7, zorder=5)
    for name, link in skin.links.items():
        x0, y0 = _xy(skin, name, 0.0, 0.0)
        xs += [x0, x0 + link.length * MM]
        ys += [y0, y0 + link.circumference * MM]
    first = True
    if len(contacts) > DETAIL_CONTACTS:  # many: crosses, one artist
        pts = [_contact_points(skin, c)[0][-1] for c in contacts]
        ax.plot([q[0] for q in pts], [q[1] for q in pts], marker="x", ms=5, mew=1.2, ls="none", color="red",
                zorder=6, label=f"contact ({len(pts)})")
        contacts = []
    for c in contacts:
        pts, label, sd, _ = _contact_points(skin, c)
        kw = {"color": "red", "zorder": 6}
        if len(pts) > 1:
            ax.plot([q[0] for q in pts], [q[1] for q in pts], lw=2.0, alpha=0.8, **kw)
            ax.annotate("", xy=pts[-1], xytext=pts[-2],
                        arrowprops={"arrowstyle": "->", "color": "red", "lw": 2.0}, zorder=6)
        else:
            x, y = pts[0]
            ax.plot([x], [y], marker="x" if sd >= 0 else "s", ms=9 if sd >= 0 else 11, mew=2.2,
                    mfc="none", ls="none", label="contact" if first else None, **kw)
            first = False
            if sd > 0:
                p = _contact_points(skin, c)[3]
                dx, dy = p.direction
                ax.plot([x - dx * sd, x + dx * sd], [y - dy * sd, y + dy * sd], lw=3, alpha=0.5, **kw)
        if label:
            x, y = pts[-1] if len(pts) > 1 else pts[0]
            ax.text(x, y - 5, label, color="red", fontsize=6.5, ha="center", va="top", zorder=7)
    ax.set_xlim(min(xs) - 5, max(xs) + 5)
    ax.set_ylim(min(ys) - 5, max(ys) + 5)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), fontsize=7, ncol=1, frameon=False)
    fig.tight_layout()
    if path is not None:
        with atomic_path(path) as tmp:  # whole or not at all
            fig.savefig(tmp, format=Path(path).suffix[1:].lower() or "png")
    return fig
