"""Thermoskin: touch sensing and temperature control for soft thermal robot skins."""

__version__ = "0.1.0"
