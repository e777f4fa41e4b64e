"""Touches on a skin of many patches: where each contact is, when, how strong; the ``multi`` scenario.

A :class:`SkinContact` is a :class:`~thermoskin.physics.finger.Touch` (when and how strong:
``t_on``, ``duration``, fingers and person or ``G``, ``T_body``; its conductance ramps as in
``physics.finger``) placed on the skin, either

- **fixed** on a patch: ``patch`` (name) and ``position`` (m from the patch's inlet along
  its pipe), or
- **moving** over a link's surface (a stroke): ``link`` and ``path = ((t, x, y), ...)``,
  ``t`` in s from ``t_on``, ``(x, y)`` in m on the link's unrolled surface, linear in
  between and held before the first and after the last point. At each instant the contact
  is on the patch whose rectangle holds the point (the first in the description's order),
  at the point's ``s`` along its pipe; between patches it touches no patch (its heat goes
  to the bare link, not to the skin).

A :class:`SkinScenario` is a single-patch :class:`~thermoskin.sim.scenarios.Scenario` (the
duration, the command(s), the ambient, the prescribed tank of an open-loop run) with
contacts. :func:`skin_scenario` gives the named ones for a skin: every single-patch
scenario (its touches on the skin's first patch, ``Touch.position`` read as on the single
patch: 0 at the thermocouple end, 1 at the far end) and ``multi``, built from the skin's
own loops and links (:func:`multi_scenario`).

:func:`contact_arrays` evaluates the contacts over a block of sample times, vectorised:
per contact its patch (-1 for none), its conductance and its place along that patch's pipe.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from thermoskin.physics.finger import PERSONS, RAMP_S, Touch, body_temperature, full_conductance
from thermoskin.sim.scenarios import SCENARIOS, Scenario
from thermoskin.skin.layout import Skin

Array = NDArray[np.float64]


@dataclass(frozen=True)
class SkinContact:
    """One contact on the skin (module doc): ``touch`` fixed at ``(patch, position)`` or moving
    along ``path`` on ``link``; ``label`` names it in pictures."""

    touch: Touch
    patch: str | None = None
    position: float = 0.0
    link: str | None = None
    path: tuple[tuple[float, float, float], ...] = ()
    label: str = ""

    def __post_init__(self) -> None:
        fixed, moving = self.patch is not None, self.link is not None
        if fixed == moving:
            raise ValueError(f"SkinContact at t_on = {self.touch.t_on}: give a patch (fixed) or a link "
                             "and a path (a stroke), not both or neither")
        if moving:
            pts = tuple((float(t), float(x), float(y)) for t, x, y in self.path)
            if not pts or any(b[0] <= a[0] for a, b in itertools.pairwise(pts)):
                raise ValueError(f"SkinContact at t_on = {self.touch.t_on}: a stroke needs a path of "
                                 "(t, x, y) points with increasing t")
            object.__setattr__(self, "path", pts)
        elif not (math.isfinite(self.position) and self.position >= 0.0):
            raise ValueError(f"SkinContact at t_on = {self.touch.t_on}: position = {self.position} m "
                             "must be >= 0")

    @property
    def t_on(self) -> float:
        return self.touch.t_on

    @property
    def t_off(self) -> float:
        return self.touch.t_off

    def check(self, skin: Skin) -> None:
        """``ValueError`` if the patch or link is not the skin's, or the position off its pipe."""
        if self.patch is not None:
            p = skin.patch(self.patch)
            if self.position > p.length + 1e-12:
                raise ValueError(f"contact at t_on = {self.t_on} s: position {self.position} m is beyond "
                                 f"patch {p.name!r}'s pipe ({p.length} m)")
        elif self.link not in skin.links:
            raise ValueError(f"contact at t_on = {self.t_on} s: no link {self.link!r} "
                             f"(links: {', '.join(skin.links)})")

    def point(self, t: Array) -> tuple[Array, Array]:
        """``(x, y)`` of a stroke on its link at times ``t`` (s)."""
        tt, xs, ys = (np.array(c) for c in zip(*self.path, strict=True))
        rel = np.asarray(t, dtype=float) - self.t_on
        return np.interp(rel, tt, xs), np.interp(rel, tt, ys)


@dataclass(frozen=True)
class SkinScenario:
    """A scenario on a skin: ``base`` (duration, command(s), ambient, prescribed tank, pump) and
    the ``contacts``."""

    name: str
    description: str
    base: Scenario
    contacts: tuple[SkinContact, ...] = field(default_factory=tuple)

    @property
    def duration(self) -> float:
        return self.base.duration

    def check(self, skin: Skin) -> None:
        """Every contact on this skin (``ValueError`` otherwise)."""
        for c in self.contacts:
            c.check(skin)

    def with_duration(self, duration: float) -> SkinScenario:
        """The same over ``duration`` s (contacts starting later are dropped)."""
        return SkinScenario(self.name, self.description, self.base.with_duration(duration),
                            tuple(c for c in self.contacts if c.t_on < duration))


def contact_arrays(skin: Skin, contacts: tuple[SkinContact, ...], t: Array
                   ) -> tuple[NDArray[np.int64], Array, Array, Array]:
    """Per contact and sample of ``t``: ``(patch, G, s, T_body)``, each of shape ``(C, len(t))``.

    ``patch`` is the patch index (-1: on no patch, or not touching), ``G`` the conductance (W/K,
    the ramp of ``physics.finger``; 0 off any patch), ``s`` m from that patch's inlet (NaN off),
    ``T_body`` the toucher's temperature (°C).
    """
    t = np.asarray(t, dtype=float)
    C, m = len(contacts), t.size
    patch = np.full((C, m), -1, dtype=np.int64)
    G = np.zeros((C, m))
    s = np.full((C, m), math.nan)
    Tb = np.zeros((C, m))
    for c, ct in enumerate(contacts):
        tc = ct.touch
        f = np.minimum(t - tc.t_on, tc.t_on + tc.duration - t) / RAMP_S
        g = full_conductance(tc, PERSONS) * np.clip(f, 0.0, 1.0)
        on = g > 0.0
        if not on.any():
            continue
        Tb[c] = body_temperature(tc, PERSONS)
        if ct.patch is not None:
            p = skin.patch(ct.patch)
            patch[c, on] = p.index
            s[c, on] = ct.position
            G[c, on] = g[on]
            continue
        x, y = ct.point(t[on])
        idx = np.flatnonzero(on)
        where = np.full(idx.size, -1, dtype=np.int64)
        pos = np.full(idx.size, math.nan)
        for p in skin.patches:
            if p.link != ct.link:
                continue
            dx, dy = p.direction
            rx, ry = x - p.centre[0], y - p.centre[1]
            along = rx * dx + ry * dy
            across = -rx * dy + ry * dx
            inside = (np.abs(along) <= 0.5 * p.length + 1e-12) & (np.abs(across) <= 0.5 * p.width + 1e-12)
            new = inside & (where < 0)
            where[new] = p.index
            pos[new] = np.clip(along[new] + 0.5 * p.length, 0.0, p.length)
        hit = where >= 0
        patch[c, idx[hit]] = where[hit]
        s[c, idx[hit]] = pos[hit]
        G[c, idx[hit]] = g[idx[hit]]
    return patch, G, s, Tb


# ------------------------------------------------------------------------------ scenarios


def from_single(sc: Scenario, skin: Skin) -> SkinScenario:
    """A single-patch scenario on the skin's first patch (``Touch.position`` as on the single
    patch: 0 at the thermocouple end, 1 at the far end, with the patch's fingertip footprint)."""
    p = skin.patches[0]
    f = p.spatial.footprint
    contacts = tuple(SkinContact(tc, patch=p.name,
                                 position=p.length * (1.0 - (0.5 * f + tc.position * (1.0 - f))))
                     for tc in sc.touches)
    return SkinScenario(sc.name, sc.description + f" (on patch {p.name!r})", sc, contacts)


def _rows(skin: Skin) -> list[list[int]]:
    """Rows of patches: on one link, pipes along one line (same angle, centres on its line)."""
    rows: list[list[int]] = []
    for link in skin.links:
        ps = [p for p in skin.patches if p.link == link]
        for p in ps:
            dx, dy = p.direction
            row = [q for q in ps if abs(q.angle - p.angle) < 1e-9
                   and abs(-(q.centre[0] - p.centre[0]) * dy + (q.centre[1] - p.centre[1]) * dx)
                   < 0.25 * p.width]
            row.sort(key=lambda q: (q.centre[0] - p.centre[0]) * dx + (q.centre[1] - p.centre[1]) * dy)
            ids = [q.index for q in row]
            if ids not in rows:
                rows.append(ids)
    rows.sort(key=len, reverse=True)
    return rows


def multi_scenario(skin: Skin, *, T_w_cmd: float = 24.0, T_a: float = 20.0, seed: int = 12,
                   t_first: float = 10.0) -> SkinScenario:
    """The ``multi`` scenario of a skin: single touches, simultaneous touches, a grasp, a stroke.

    Quiet for ``t_first`` s, then, with 6-8 s of quiet between episodes:

    1. a single touch on every patch of every loop, in the water's order (so upstream and
       downstream patches of each series loop), at 1/4, 1/2, 3/4 of the pipe in turn,
       1-3 fingers of the three persons, 1.8-2.6 s;
    2. two simultaneous touches on the first and last patches of the longest loop, the second
       0.6 s after the first;
    3. a grasp: a palm (0.2 W/K) on the three or four patches nearest the middle of the link
       with most patches, all within 0.1 s, 2.5 s long;
    4. a stroke (two fingers) along the longest row of patches on one link (pipes in line,
       at least three patches if there are), 5 mm before the first to 5 mm past the third, at
       40 mm/s;
    5. quiet to the end (8 s).
    """
    rng = np.random.default_rng(seed)
    persons = sorted(PERSONS)
    contacts: list[SkinContact] = []
    t = t_first

    def gap() -> float:
        return float(rng.uniform(6.0, 8.0))

    k = 0
    for loop in skin.loops:
        for i in loop.patches:
            p = skin.patches[i]
            dur = float(rng.uniform(1.8, 2.6))
            frac = (0.25, 0.5, 0.75)[k % 3]
            tc = Touch(t_on=round(t, 3), duration=round(dur, 3), n_fingers=1 + k % 3,
                       person=persons[k % 3], T_body=round(float(rng.uniform(32.5, 34.5)), 2))
            contacts.append(SkinContact(tc, patch=p.name, position=frac * p.length,
                                        label=f"touch {p.name}"))
            t += dur + gap()
            k += 1
    longest = max(skin.loops, key=lambda lp: len(lp.patches))
    if len(longest.patches) >= 2:
        a, b = skin.patches[longest.patches[0]], skin.patches[longest.patches[-1]]
        for j, (p, dt) in enumerate(((a, 0.0), (b, 0.6))):
            tc = Touch(t_on=round(t + dt, 3), duration=2.4, n_fingers=2, person=persons[j])
            contacts.append(SkinContact(tc, patch=p.name, position=0.5 * p.length, label=f"pair {p.name}"))
        t += 3.0 + gap()
    by_link = max(skin.links, key=lambda name: sum(p.link == name for p in skin.patches))
    on_link = [p for p in skin.patches if p.link == by_link]
    if len(on_link) >= 3:
        mid = float(np.median([p.centre[0] for p in on_link]))
        near = sorted(on_link, key=lambda p: (abs(p.centre[0] - mid), p.index))[:min(4, len(on_link))]
        for j, p in enumerate(near):
            tc = Touch(t_on=round(t + 0.03 * j, 3), duration=2.5, n_fingers=0, G=0.2, T_body=33.5)
            contacts.append(SkinContact(tc, patch=p.name, position=0.5 * p.length, label=f"grasp {p.name}"))
        t += 2.6 + gap()
    row = _rows(skin)[0]
    first, last = skin.patches[row[0]], skin.patches[row[min(2, len(row) - 1)]]
    start = first.point_at(-0.005)
    end = last.point_at(last.length + 0.005)
    dist = math.hypot(end[0] - start[0], end[1] - start[1])
    dur = dist / 0.04
    tc = Touch(t_on=round(t, 3), duration=round(dur, 3), n_fingers=2, person="man1")
    contacts.append(SkinContact(tc, link=first.link, path=((0.0, *start), (dur, *end)), label="stroke"))
    t += dur + 8.0
    base = Scenario("multi", "single touches on every patch, a pair on one loop, a grasp, a stroke",
                    duration=round(t, 3), T_w_cmd=T_w_cmd, T_a=T_a, pump="logic")
    return SkinScenario("multi", f"on {skin.name}: single touches on each of its {len(skin.patches)} patches "
                        "(loop by loop, in the water's order), two at once on one loop, a grasp, a stroke "
                        "across a row of patches, quiet stretches", base, tuple(contacts))


SKIN_SCENARIOS = {"multi": "single touches on every patch (loop by loop, in the water's order), two at "
                            "once on one loop, a grasp, a stroke across a row of patches, quiet stretches"}
"""Scenarios made for a skin, with what they do (the single-patch ones apply too, on its first patch)."""


def skin_scenario(name: str, skin: Skin, duration: float | None = None) -> SkinScenario:
    """A named scenario on ``skin`` (``multi`` or any single-patch one); ``KeyError`` if unknown."""
    if name == "multi":
        sc = multi_scenario(skin)
    elif name in SCENARIOS:
        sc = from_single(SCENARIOS[name], skin)
    else:
        raise KeyError(f"unknown scenario {name!r} (known: {', '.join([*SKIN_SCENARIOS, *SCENARIOS])})")
    sc.check(skin)
    return sc.with_duration(duration) if duration is not None else sc
