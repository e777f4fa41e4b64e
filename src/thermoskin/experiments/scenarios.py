"""Sec. VI as scenarios: set-points (Fig. 8), one to three fingers (Figs. 9-17), persons (Fig. 18),
contact positions (Fig. 19).

Reading of "the human finger contacted the prototype every 3 seconds" (Sec. VI-A): one
contact starts every :data:`PERIOD_S` = 3 s and lasts :data:`TOUCH_S` = 1.5 s (press 1.5 s,
release 1.5 s). The paper gives no duty; half the period is the plainest reading. All
contact runs start from ambient, settle for :data:`SETTLE_S` s at ``T_w_cmd = 24 °C`` (the
closed loop reaches the command within about 8 s) and then carry ``n_contacts`` contacts.

Positions (Fig. 19): ``Touch.position`` is the normalised place along the pipe (0 = the
thermocouple end, 1 = the far end); :data:`POSITIONS` puts "near" at 0, "middle" at 0.5
and "far" at 1 (the 10 mm fingertip then covers the first, middle or last third of the
30 mm skin).
"""

from __future__ import annotations

from thermoskin.physics.finger import PERSONS, Touch
from thermoskin.sim.scenarios import Scenario

SETTLE_S = 10.0
"""Quiet time from ambient before the first contact, s."""
PERIOD_S = 3.0
"""One contact every 3 s (Sec. VI-A)."""
TOUCH_S = 1.5
"""Contact duration within each period, s (our reading: half the period)."""
N_CONTACTS = 15
"""Contacts per run of the full reproduction (45 s of contacts)."""
TAIL_S = 1.5
"""Quiet time after the last release, s."""
SETPOINTS = (24.0, 26.0, 28.0)
"""The commands of Fig. 8, °C."""
SETPOINT_S = 60.0
"""Duration of one set-point run from ambient, s."""
T_W_CMD = 24.0
"""The command during the contact experiments (Sec. VI-A), °C."""
T_A = 20.0
"""Ambient air, °C (the paper does not give it)."""
POSITIONS: dict[str, float] = {"near": 0.0, "middle": 0.5, "far": 1.0}
"""Fig. 19's cases 1-3 as normalised positions along the skin."""
PERSON_NAMES = tuple(PERSONS)
"""The three persons of Fig. 18."""


def setpoint_scenario(T_w_cmd: float, duration: float = SETPOINT_S) -> Scenario:
    """Fig. 8: from ambient to ``T_w_cmd`` and held, no contact."""
    return Scenario(f"setpoint-{T_w_cmd:g}", f"T_w_cmd = {T_w_cmd:g} degC from ambient, no contact (Fig. 8)",
                    duration=float(duration), T_w_cmd=float(T_w_cmd), T_a=T_A)


def contact_scenario(n_fingers: int = 1, person: str = "man1", position: float = 0.0,
                     n_contacts: int = N_CONTACTS, *, name: str | None = None) -> Scenario:
    """A contact every :data:`PERIOD_S` s (:data:`TOUCH_S` s long) after :data:`SETTLE_S` s, at 24 °C."""
    touches = tuple(Touch(t_on=SETTLE_S + i * PERIOD_S, duration=TOUCH_S, n_fingers=n_fingers,
                          person=person, position=position) for i in range(n_contacts))
    duration = SETTLE_S + (n_contacts - 1) * PERIOD_S + TOUCH_S + TAIL_S
    return Scenario(name or f"contacts-{n_fingers}f-{person}-x{position:g}",
                    f"{n_contacts} contacts of {n_fingers} finger(s) by {person} at x = {position:g}, "
                    f"one every {PERIOD_S:g} s ({TOUCH_S:g} s long), T_w_cmd = {T_W_CMD:g} degC",
                    duration=duration, T_w_cmd=T_W_CMD, T_a=T_A, touches=touches)
