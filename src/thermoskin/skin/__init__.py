"""A skin of many patches: its layout, its log, and every patch estimated together.

:mod:`~thermoskin.skin.layout` describes a skin (links, water loops, patches, their
thermocouples) from a layout TOML; :mod:`~thermoskin.skin.log` reads and writes its long-format
log (one row per sample and patch); :mod:`~thermoskin.skin.inlet` carries each patch's inlet
water from the patch upstream, and :mod:`~thermoskin.skin.transport` corrects a reading for the
transport the lumped pipe node leaves out; :mod:`~thermoskin.skin.observe` runs every patch on
the compiled kernel (live in ``run --skin``, offline in ``observe --skin``);
:mod:`~thermoskin.skin.position` says where along the pipe a contact sits and
:mod:`~thermoskin.skin.groups` joins neighbouring patches' contacts into body contacts.
"""
