"""Who touches a robot skin, and how: the distributions of touchers, their contacts and temperatures.

One table serves both sides: :func:`thermoskin.sim.scenarios.toucher_scenario` draws its
touches from it, and :mod:`thermoskin.touch.characterise` takes it as its prior (what a person or
an object touching the skin is likely to be). A skin working elsewhere (a kitchen, a
foundry) would get another table; the numbers here are assumptions for a robot among
people indoors, with the sources given where there are some.

**Persons** (share :data:`P_HUMAN`): a finger pad, a palm or a whole hand
(:data:`HUMAN_PARTS`: share among persons, contact area m², contact pressure Pa, uniform
in the ranges), skin at ``U(*T_SKIN_RANGE)`` °C.

**Objects** (:data:`OBJECT_TEMPS`, equally likely): the presets of
:data:`thermoskin.physics.contact.OBJECTS`, each with its temperatures; its contact area is
the preset's times ``U(*OBJECT_AREA_SCALE)``, pressed at ``U(*OBJECT_PRESSURE)`` Pa.
"""

from __future__ import annotations

P_HUMAN = 0.5
"""Share of touches by a person."""

HUMAN_PARTS: dict[str, tuple[float, tuple[float, float], tuple[float, float]]] = {
    "finger": (0.5, (1.0e-4, 2.0e-4), (3.0e3, 15.0e3)),
    "palm": (0.25, (40e-4, 80e-4), (1.0e3, 3.0e3)),
    "hand": (0.25, (80e-4, 120e-4), (1.0e3, 2.0e3)),
}
"""``part: (share among persons, area range m², pressure range Pa)``: a finger pad of
1-2 cm² under 0.3-3 N, a palm (40-80 cm² of its ~90 cm²) or a palm with fingers (80-120
cm² of ~140 cm², Rossiter, Chapman & Haywood, Burns 22:1996) resting or pressing lightly."""

T_SKIN_RANGE = (30.0, 36.0)
"""Skin surface temperature of a person's hand, °C: cool hands indoors to warm ones."""

OBJECT_TEMPS: dict[str, tuple[tuple[float, str, float, float], ...]] = {
    "can_cold": ((1.0, "abs", 3.0, 8.0),),
    "glass_of_water": ((0.5, "abs", 5.0, 12.0), (0.5, "room", -1.0, 2.0)),
    "mug_hot": ((1.0, "abs", 40.0, 65.0),),
    "water_bag": ((0.5, "abs", 5.0, 15.0), (0.5, "abs", 38.0, 50.0)),
    "aluminium_block": ((1.0, "room", -1.0, 2.0),),
    "steel_tool": ((1.0, "room", -1.0, 2.0),),
    "plastic_box": ((1.0, "room", -1.0, 2.0),),
    "wood_block": ((1.0, "room", -1.0, 2.0),),
    "foam_block": ((1.0, "room", -1.0, 2.0),),
}
"""Object presets (equally likely) and their temperatures: ``(share, "abs", lo, hi)``
uniform in ``[lo, hi]`` °C, or ``(share, "room", lo, hi)`` the room's air plus ``U(lo, hi)``
K: drinks from a fridge (3-8 °C in a can, 5-12 °C in a glass), hot drinks (40-65 °C), a
cold or warm water bag, tools and blocks at room temperature (a shelf a little warmer than
the air near the skin)."""

OBJECT_AREA_SCALE = (0.5, 1.5)
"""Contact area of an object: its preset's times a factor uniform in this range."""
OBJECT_PRESSURE = (1.0e3, 5.0e3)
"""Contact pressure of an object, Pa (held or resting against the skin)."""

TAP_S = (0.2, 0.6)
"""Duration of a tap, s."""
HOLD_S = (1.5, 6.0)
"""Duration of a hold, s."""
P_TAP = 0.2
"""Share of taps among touches."""
