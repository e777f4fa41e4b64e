"""What touched the skin: the characterisation of a contact and the kind of touch.

:mod:`~thermoskin.touch.characterise` says from a contact's heat flow and readings whether a
person or an object touched, of which material, its conductance and temperature, with their
uncertainty; :mod:`~thermoskin.touch.kinds` joins contacts (on one patch or on neighbouring
patches) into touches and calls them tap, hold, stroke or grasp. Both read the estimator's
contact events (:mod:`thermoskin.estimation.events`) and know nothing of where they came from.
"""
