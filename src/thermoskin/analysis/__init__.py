"""Offline analysis of a recorded log: the one-patch pipeline and scoring against the truth.

:mod:`~thermoskin.analysis.observe` is ``thermoskin observe``'s path: a log (CSV or Parquet,
streamed) cleaned of implausible samples, estimated by the same compiled kernel as the live
loop, its contacts detected, dated again and characterised (what touched), and written.
:mod:`~thermoskin.analysis.evaluation` scores detected contacts against a scenario's true
touches (detections, misses, false alarms, latency). It sits above estimation and what
touched, which it composes; the skin of many patches has its own pipeline
(:mod:`thermoskin.skin.observe`).
"""
