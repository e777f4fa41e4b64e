"""Pictures: a run's or a log's plot, the skin's layout with its contacts, a sweep, a calibration.

Every figure is drawn with matplotlib's object API (no global state, safe in threads) and
written atomically. :mod:`~thermoskin.plots.log` plots a log (a long one from an exact
min/max envelope, :mod:`~thermoskin.plots.digest`, gathered chunk by chunk),
:mod:`~thermoskin.plots.skin` the layout of a skin of many patches,
:mod:`~thermoskin.plots.sweep` a sweep's designs, :mod:`~thermoskin.plots.calibration` a
calibration's fit.
"""
