"""The paper's experiments (Sec. VI) on the simulated skin: scenarios, runs, figures, report.

:mod:`~thermoskin.experiments.reproduce` is ``thermoskin reproduce``: the runs of
:mod:`~thermoskin.experiments.runs` on the scenarios of :mod:`~thermoskin.experiments.scenarios`,
analysed (:mod:`~thermoskin.experiments.analysis`), drawn as the paper's figures
(:mod:`~thermoskin.experiments.figures`) and reported beside the paper's numbers
(:mod:`~thermoskin.experiments.report`).
"""
