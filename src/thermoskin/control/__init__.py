"""Temperature control (Sec. V of the paper): the MPC, the Peltier's inner loop and the pump.

:mod:`~thermoskin.control.mpc` is the model predictive controller of eqs. 9-11, a dense
box-constrained QP solved every sample by daqp; :mod:`~thermoskin.control.inner` the PI on the
Peltier drive (with an identified feed-forward); :mod:`~thermoskin.control.pump` the pump's
switching with its dwell; :mod:`~thermoskin.control.probe` active sensing, set-point steps
during a contact. Blocks with ``reset``/``step``; the loop that runs them is the runtime's.
"""
