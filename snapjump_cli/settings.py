"""Solver settings shared by ``curve`` and ``sweep`` (one place for every numerical default)."""
from __future__ import annotations

from dataclasses import dataclass, asdict, fields

__all__ = ["MeshSettings", "SolverSettings"]


@dataclass(frozen=True)
class MeshSettings:
    """Mesh density.

    Parameters
    ----------
    order : 1 (bilinear Q4, mean dilatation) or 2 (biquadratic Q9, linear discontinuous pressure)
    nt : elements through the thickness of each cap (the thinnest cap gets at least this many)
    aspect : maximum element aspect ratio (length along the arc / size through the thickness)
    """

    order: int = 2
    nt: int = 2
    aspect: float = 2.0

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class SolverSettings:
    """Continuation and Newton settings (all in scaled units: lengths / R_i, stresses / mu_i).

    Parameters
    ----------
    tol : relative Newton tolerance on the residual (scaled by the load norm)
    ds0 : initial arc length (scaled)
    ds_max : maximum arc length (scaled)
    max_steps : bound on continuation steps
    max_newton : Newton iterations per step before a cut-back
    max_turn_deg : largest allowed turn of the path tangent between steps (catches small folds)
    full : trace the whole curve (to 1.5 p_c or the volume bound) instead of stopping once the snap
        is characterised
    bulk_ratio : kappa / mu of the volumetric penalty of the mixed formulation
    tol_path : Newton tolerance of ordinary path points; the limit point, the lower state and the
        descent always use ``tol``
    u_scale : scale of the RMS displacement in the arc length, in units of the pole-displacement
        scale (0 = arc length in (V, p, pole) only)
    """

    tol: float = 1e-8
    ds0: float = 0.02
    ds_max: float = 1.0
    max_steps: int = 2000
    max_newton: int = 8
    max_turn_deg: float = 10.0
    full: bool = False
    bulk_ratio: float = 1.0e4
    u_scale: float = 1.0
    tol_path: float = 1e-6

    def as_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in fields(cls))
