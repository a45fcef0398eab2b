"""Geometry of the actuators and single caps (paper S1, eqs 1-6): :mod:`.caps` (``Design``,
``CapScene``, their cross-section points, volumes and validity) and :mod:`.designs` (the paper's
named designs, package data ``designs.yaml``). The names of :mod:`.caps` are re-exported here."""
from __future__ import annotations

from snapjump_cli.geometry.caps import (
    BASE_CONDITIONS,
    BaseCondition,
    CapScene,
    Design,
    InvalidDesign,
    cap_points,
    cap_volumes,
    centre_offset,
    design_points,
    design_volumes,
    outer_radius,
    spherical_cap_volume,
)

__all__ = ["InvalidDesign", "Design", "CapScene", "BaseCondition", "BASE_CONDITIONS", "outer_radius",
           "centre_offset", "design_points", "cap_points", "spherical_cap_volume", "design_volumes", "cap_volumes"]
