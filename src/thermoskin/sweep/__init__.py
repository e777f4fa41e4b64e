"""Design sweeps: many points of a skin's design simulated in closed loop, a row of metrics each.

:mod:`~thermoskin.sweep.spec` reads a sweep file and draws its points;
:mod:`~thermoskin.sweep.kernel` simulates a batch of points in one compiled loop (the plant's and
the estimator's own compiled functions, the MPC's box QP of :mod:`~thermoskin.sweep.qp`);
:mod:`~thermoskin.sweep.engine` turns runs into rows of metrics; :mod:`~thermoskin.sweep.store`
keeps finished chunks as Parquet parts (a killed sweep resumes); :mod:`~thermoskin.sweep.run`
runs them here or on a Dask cluster.
"""
