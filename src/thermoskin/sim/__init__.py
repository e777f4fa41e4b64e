"""The simulated skin and its boards: one plant behind ``measure()``/``apply(drive, v)``.

:mod:`~thermoskin.sim.plant` is the one simulated plant (the network or the spatial skin, the
Peltier tank or a prescribed one, the thermocouple boards of :mod:`~thermoskin.sim.sensors`,
scripted touches, the air); :mod:`~thermoskin.sim.scenarios` the named scenarios and
:mod:`~thermoskin.sim.conditions` the detection bench's conditions; :mod:`~thermoskin.sim.run`
simulates one open-loop log. A skin of many patches is stepped together in a compiled kernel
(:mod:`~thermoskin.sim.skin_plant`, its boards in :mod:`~thermoskin.sim.board_bank`, its
scenarios in :mod:`~thermoskin.sim.skin_scenarios`).
"""
