"""Fitting models to a lab's logs: the network's parameters and the Peltier's dynamics.

:mod:`~thermoskin.fit.calibrate` fits the thermal network's parameters (and the sensors')
to a no-touch log by least squares on the exact discretisation, with their uncertainty and
correlation; :mod:`~thermoskin.fit.identify` fits an ARX model of the Peltier and tank (Sec.
V of the paper) for the MPC and the inner loop's feed-forward. Each writes a parameter file
(``load_config`` reads it).
"""
