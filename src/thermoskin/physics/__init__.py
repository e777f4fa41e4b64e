"""The skin's physics, written once for every use: water, convection, the thermal network,
the Peltier, the finger and what touches.

:mod:`~thermoskin.physics.water` gives the water's properties and :mod:`~thermoskin.physics.convection`
the pipe's resistance ``R_w(v)`` (eq. 1) and the water's capacity ``C_w`` (eq. 2);
:mod:`~thermoskin.physics.network` the two-node network of Fig. 3 (eqs. 3-7) and its exact
discretisation (:mod:`~thermoskin.physics.expm`, the matrix exponential in numpy alone);
:mod:`~thermoskin.physics.spatial` the skin along its pipe; :mod:`~thermoskin.physics.peltier` the
two modules between tank and heat sink; :mod:`~thermoskin.physics.finger`,
:mod:`~thermoskin.physics.contact` and :mod:`~thermoskin.physics.world` the touches: the paper's
finger, tissue and solids in contact, and the ranges they are drawn from.
"""
