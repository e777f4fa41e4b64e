"""Touch estimation, one patch or many: eq. 8, the sensor-aware filter, the detector, events.

:mod:`~thermoskin.estimation.observer` is the paper's thermal exchange observer (eq. 8, its
filters in :mod:`~thermoskin.estimation.dsp`); :mod:`~thermoskin.estimation.model` the network
with the touch heat and the tank as states and its exact discretisation;
:mod:`~thermoskin.estimation.kernel` the compiled per-sample kernel (eq. 8, the Kalman filter,
the two-sided CUSUM detector) looped over samples, patches and long-format rows, and
:mod:`~thermoskin.estimation.reference` the same algorithm in plain Python, which the tests hold
it to; :mod:`~thermoskin.estimation.redate` dates a contact again when it has ended;
:mod:`~thermoskin.estimation.freshness` says which readings of a log are new and at what rate.
:class:`~thermoskin.estimation.estimator.TouchEstimator` (one patch) and
:class:`~thermoskin.estimation.patches.PatchEstimators` (many) are the blocks the loops call;
:mod:`~thermoskin.estimation.events` the contact events they give.
"""
