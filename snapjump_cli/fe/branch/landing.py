"""Where a subcritical branch of the multi-harmonic model lands at the volume of its bifurcation
(docs/harmonics.md sections 10.7-10.8): the sphere path from the bifurcation along the branch's
tangent (:func:`snapjump_cli.fe.axisym.sphere_path.descend_on_spheres`); for a secondary branch
the energy descent started in coarser models
(:func:`snapjump_cli.fe.branch.coarse.descend_coarse_to_fine`) where it finds nothing."""
from __future__ import annotations

from typing import Callable

import numpy as np

from snapjump_cli.fe.axisym.sphere_path import descend_on_spheres
from snapjump_cli.fe.branch.coarse import descend_coarse_to_fine
from snapjump_cli.fe.branch.model import MultiHarmonicModel
from snapjump_cli.fe.continuation import PathPoint, Tracer

__all__ = ["KICK", "kick_along", "sphere_landing", "land_from_bifurcation"]

#: A descent or a sphere path leaves an unstable state displaced along its mode by this fraction
#: of the state's largest nodal amplitude (a jump off a branch: the branch's symmetric subspace is
#: invariant under both, and without the kick they would stay on the branch).
KICK = 1e-3


def kick_along(model: MultiHarmonicModel, u: np.ndarray, mode: np.ndarray, frac: float | None = None) -> np.ndarray:
    """``mode`` scaled so that its largest nodal amplitude is ``frac`` (default :data:`KICK`, read
    at the call) of the state ``u``'s."""
    frac = KICK if frac is None else frac
    return mode * (frac * float(np.abs(model.amplitudes(u)).max()) / float(np.abs(model.amplitudes(mode)).max()))


def sphere_landing(tracer: Tracer, upper: PathPoint, climb: float | None = None, max_steps: int = 400,
                   falling: bool = False) -> tuple[PathPoint | None, str]:
    """The stable state at ``upper``'s volume that the sphere path reaches from it (a bifurcation)
    along its tangent ``du_ds`` (:func:`~snapjump_cli.fe.axisym.sphere_path.descend_on_spheres`,
    whose ``climb``, ``max_steps`` and ``falling`` these are): ``(state or None, message)``."""
    return descend_on_spheres(tracer, upper, upper, kick_along(tracer.pb, upper.u, upper.du_ds), climb=climb,
                              max_steps=max_steps, falling=falling)


def land_from_bifurcation(tracer: Tracer, upper: PathPoint, descent: bool = True,
                          before_descent: Callable[[], tuple[PathPoint | None, str]] | None = None,
                          climb: float | None = None, max_steps: int = 400,
                          on_spheres: tuple[PathPoint | None, str] | None = None) -> tuple[PathPoint | None, str]:
    """The stable state at ``upper``'s volume reached from it (a bifurcation whose branch lowers the
    volume) along its tangent ``du_ds``: by the sphere path, else ``before_descent()`` (a known
    state, ``(state or None, message)``), else (with ``descent``) by the energy descent started in
    coarser models. Returns ``(state or None, message)``, the messages of each way tried joined.
    ``climb``, ``max_steps``: as :func:`~snapjump_cli.fe.axisym.sphere_path.descend_on_spheres`'s;
    ``on_spheres``: the sphere path's result where the caller has it (:func:`sphere_landing`)."""
    low, msg = sphere_landing(tracer, upper, climb=climb, max_steps=max_steps) if on_spheres is None else on_spheres
    if low is None and before_descent is not None:
        low, msg_b = before_descent()
        msg = "; ".join(x for x in (msg, msg_b) if x)
    if low is not None or not descent:
        return low, msg
    low, msg_d = descend_coarse_to_fine(tracer, upper)
    return low, f"{msg}; {msg_d}"
