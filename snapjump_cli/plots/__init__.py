"""Figures (matplotlib, imported inside the functions that draw): :mod:`.figures` (the ranked
table's figures and the pressure-volume curve)."""
