"""Finger contact: a fingertip as a contact conductance to a body at its skin temperature.

A touch adds to the sheet node of the network (docs/model.md, ``physics.network``)::

    q_i = G_c (T_f - T_g),   G_c = n_fingers G_finger

``T_f`` is the fingertip skin temperature (°C) and ``G_finger`` (W/K) the contact
conductance of one fingertip. Pressing and releasing are linear ramps of
:data:`RAMP_S` seconds inside the touch, so that ``G_c > 0`` exactly on
``(t_on, t_on + duration)``::

    G_c(t) = n G_finger clip(min(t - t_on, t_on + duration - t) / RAMP_S, 0, 1)

Overlapping touches add their conductances; the body temperature seen by the sheet is
then the conductance-weighted mean ``T_f = sum(G_j T_j) / sum(G_j)`` (two conductances
in parallel to the same node).

A touch may override both factors: ``G`` (W/K) replaces ``n_fingers G_finger`` (a weak
fingertip, 0.02 W/K; a palm, 0.3 W/K) and ``T_body`` (°C) the person's fingertip
temperature (an object: a 15 °C can, a 45 °C mug). A touch with ``G`` may have
``n_fingers = 0`` (an object or a palm: no fingertip), which the ``n_fingers`` column
then counts as none.

Where the numbers of :data:`PERSONS` come from (the paper, Sec. VI, names three persons,
``man1``, ``woman1``, ``woman2``, aged 27-28, and gives no thermal data for them):

- ``T_body``: fingertip skin temperature of a person at rest indoors is about 32-35 °C
  in the thermophysiology literature (fingertips run cooler than the core and vary
  between persons; women's hands are on average slightly cooler). The values are
  assumptions inside that range, not measurements.
- ``G_finger``: docs/model.md's order of magnitude, about 0.05 W/K for one fingertip (a
  contact area of roughly 1 cm² and a contact coefficient of a few hundred W/(m² K)).
  The per-person spread of about ±10 % stands for the "variations depending on
  persons" of Fig. 18. Again assumptions, not measurements.

``Touch.position`` places a touch on the spatial skin (Fig. 19); the lumped two-node
network ignores it.

``Touch.toucher`` names a toucher with a body of its own (:mod:`thermoskin.physics.contact`:
``"finger"``, ``"palm"``, ``"hand"``, ``"can_cold"``, ``"mug_hot"``, ``"wood_block"``, any
material name, ...): the plant then steps it against the sheet every sample instead of
holding ``T_f``. ``T_body`` is its starting surface temperature (default: the preset's),
``G`` its contact conductance once pressed (default ``h_c(pressure) area`` with the preset's
or the touch's ``area`` m² and ``pressure`` Pa). Here its ``T_f`` is that starting
temperature (the truth's ``T_f_true``) and its conductance ``G`` (``G_true``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

RAMP_S = 0.03
"""Duration of the linear press and release ramps of the contact conductance, s."""

T_F_IDLE = 0.0
"""Body temperature returned when nothing touches (``G_c = 0``, so it has no effect)."""


@dataclass(frozen=True)
class Person:
    """A toucher: fingertip skin temperature ``T_body`` (°C), one fingertip's ``G_finger`` (W/K)."""

    name: str
    T_body: float
    G_finger: float

    def __post_init__(self) -> None:
        if not 0.0 < self.G_finger < 10.0:
            raise ValueError(f"Person {self.name!r}: G_finger = {self.G_finger} W/K must be in (0, 10)")
        if not 0.0 <= self.T_body <= 50.0:
            raise ValueError(f"Person {self.name!r}: T_body = {self.T_body} °C must be in [0, 50]")


PERSONS: dict[str, Person] = {
    "man1": Person("man1", T_body=34.0, G_finger=0.055),
    "woman1": Person("woman1", T_body=33.0, G_finger=0.045),
    "woman2": Person("woman2", T_body=32.5, G_finger=0.050),
}
"""The three persons of Sec. VI (values: see the module docstring)."""


@dataclass(frozen=True)
class Touch:
    """One touch: ``n_fingers`` fingers of ``person`` on the skin from ``t_on`` for ``duration`` s.

    ``T_body`` (°C) overrides the person's fingertip temperature for this touch; ``G``
    (W/K) overrides the total contact conductance ``n_fingers G_finger`` (then
    ``n_fingers`` may be 0: not a fingertip); ``position`` places the touch on the spatial
    skin (0 = at the thermocouple, 1 = the far end); ``toucher`` names a physical toucher
    (:func:`thermoskin.physics.contact.kinds`) with its contact ``area`` (m²) and ``pressure``
    (Pa) (default: the preset's), stepped by the plant (see the module doc).
    """

    t_on: float
    duration: float
    n_fingers: int
    person: str = "man1"
    position: float = 0.0
    T_body: float | None = None
    G: float | None = None
    toucher: str | None = None
    area: float | None = None
    pressure: float | None = None

    def __post_init__(self) -> None:
        free = self.G is not None or self.toucher is not None
        allowed = (0, 1, 2, 3) if free else (1, 2, 3)
        if isinstance(self.n_fingers, bool) or self.n_fingers not in allowed:
            raise ValueError(f"Touch at t_on = {self.t_on}: n_fingers = {self.n_fingers!r} must be 1, 2 or 3"
                             + (" (or 0 with G)" if self.G is not None else
                                " (or 0 with a toucher)" if free else ""))
        if self.toucher is not None:
            _preset(self)  # a known kind, its area and pressure in range
        elif self.area is not None or self.pressure is not None:
            raise ValueError(f"Touch at t_on = {self.t_on}: area and pressure need a toucher")
        if self.G is not None and not (math.isfinite(self.G) and 0.0 < self.G < 100.0):
            raise ValueError(f"Touch at t_on = {self.t_on}: G = {self.G} W/K must be in (0, 100)")
        if self.T_body is not None and not (math.isfinite(self.T_body) and -20.0 <= self.T_body <= 100.0):
            raise ValueError(f"Touch at t_on = {self.t_on}: T_body = {self.T_body} °C must be in [-20, 100]")
        if not (math.isfinite(self.duration) and self.duration > 0):
            raise ValueError(f"Touch at t_on = {self.t_on}: duration = {self.duration} s must be > 0")
        if not math.isfinite(self.t_on):
            raise ValueError(f"Touch: t_on = {self.t_on} s must be finite")

    @property
    def t_off(self) -> float:
        """End of the contact, s."""
        return self.t_on + self.duration


def _person(touch: Touch, persons: Mapping[str, Person]) -> Person:
    try:
        return persons[touch.person]
    except KeyError:
        raise KeyError(f"Touch at t_on = {touch.t_on}: unknown person {touch.person!r} "
                       f"(known: {', '.join(persons)})") from None


def _preset(touch: Touch) -> tuple[float, float, float]:
    """``(area m², pressure Pa, T_start °C)`` of a toucher touch: the touch's, else its preset's."""
    from thermoskin.physics import contact as ct

    kind = touch.toucher
    if kind in ct.HUMANS:
        part = ct.HUMANS[kind]
        A, p, T0 = part.area, part.pressure, ct.T_SKIN_DEFAULT
    elif kind in ct.OBJECTS:
        pre = ct.OBJECTS[kind]
        A, p, T0 = pre.area, pre.pressure, pre.T_start
    elif kind in ct.MATERIALS:
        pre = ct.ObjectPreset(kind, ((kind, ct.SLAB_THICKNESS),), ct.T_ENV)
        A, p, T0 = pre.area, pre.pressure, pre.T_start
    else:
        raise ValueError(f"Touch at t_on = {touch.t_on}: unknown toucher {kind!r} "
                         f"(known: {', '.join(ct.kinds())})")
    A = A if touch.area is None else float(touch.area)
    p = p if touch.pressure is None else float(touch.pressure)
    try:
        ct.G_contact(A, p)
    except ValueError as e:
        raise ValueError(f"Touch at t_on = {touch.t_on}: {e}") from None
    return A, p, T0


def full_conductance(touch: Touch, persons: Mapping[str, Person] = PERSONS) -> float:
    """The touch's conductance once pressed, W/K: ``G``, a toucher's ``h_c(p) A``, or
    ``n_fingers G_finger``."""
    if touch.G is not None:
        return touch.G
    if touch.toucher is not None:
        from thermoskin.physics.contact import G_contact

        A, p, _ = _preset(touch)
        return G_contact(A, p)
    return touch.n_fingers * _person(touch, persons).G_finger


def body_temperature(touch: Touch, persons: Mapping[str, Person] = PERSONS) -> float:
    """The touching body's temperature, °C: ``T_body``, a toucher's preset start, or the person's."""
    if touch.T_body is not None:
        return touch.T_body
    if touch.toucher is not None:
        return _preset(touch)[2]
    return _person(touch, persons).T_body


def touch_conductance(touch: Touch, t: float, persons: Mapping[str, Person] = PERSONS) -> float:
    """``G_c`` of one touch at time ``t``, W/K (ramped, zero outside ``(t_on, t_off)``)."""
    f = min(t - touch.t_on, touch.t_on + touch.duration - t) / RAMP_S
    if f <= 0.0:
        return 0.0
    return full_conductance(touch, persons) * (f if f < 1.0 else 1.0)


def contact_at(touches: Sequence[Touch], t: float,
               persons: Mapping[str, Person] = PERSONS) -> tuple[float, float, int]:
    """``(G_c, T_f, n_fingers)`` at time ``t`` for a list of touches.

    ``G_c = sum_j G_j(t)`` (W/K), ``T_f = sum_j G_j T_j / G_c`` (°C; :data:`T_F_IDLE`
    when ``G_c = 0``), ``n_fingers`` the fingers of the touches with ``G_j > 0``.
    """
    G = 0.0
    GT = 0.0
    n = 0
    for touch in touches:
        g = touch_conductance(touch, t, persons)
        if g > 0.0:
            T_body = body_temperature(touch, persons)
            G += g
            GT += g * T_body
            n += touch.n_fingers
    if G <= 0.0:
        return 0.0, T_F_IDLE, 0
    return G, GT / G, n


def contact_profile(touches: Sequence[Touch], t: NDArray[np.float64],
                    persons: Mapping[str, Person] = PERSONS
                    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
    """Vectorised :func:`contact_at` over a time grid: arrays ``(G_c, T_f, n_fingers)``."""
    t = np.asarray(t, dtype=float)
    if t.ndim != 1:
        raise ValueError(f"contact_profile needs a 1-D time grid, got shape {t.shape}")
    ordered = bool(np.all(np.diff(t) >= 0))
    G = np.zeros_like(t)
    GT = np.zeros_like(t)
    n = np.zeros(t.shape, dtype=np.int64)
    for touch in touches:
        G_full = full_conductance(touch, persons)
        T_body = body_temperature(touch, persons)
        lo, hi = np.searchsorted(t, [touch.t_on, touch.t_off], side="right") if ordered else (0, t.size)
        seg = t[lo:hi]
        f = np.minimum(seg - touch.t_on, touch.t_on + touch.duration - seg) / RAMP_S
        g = G_full * np.clip(f, 0.0, 1.0)
        G[lo:hi] += g
        GT[lo:hi] += g * T_body
        n[lo:hi] += np.where(g > 0.0, touch.n_fingers, 0)
    T_f = np.full_like(t, T_F_IDLE)
    on = G > 0.0
    T_f[on] = GT[on] / G[on]
    return G, T_f, n
