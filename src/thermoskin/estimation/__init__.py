"""Sensor-aware touch estimation: the network's Kalman filter and the two-sided contact detector.

- :mod:`~thermoskin.estimation.model`: the model and its exact discretisation;
- :mod:`~thermoskin.estimation.kernel`: the compiled per-sample kernel (live, offline, many patches);
- :mod:`~thermoskin.estimation.reference`: the same algorithm in plain Python, for the tests;
- :mod:`~thermoskin.estimation.freshness`: which samples of a log carry new readings.
"""
