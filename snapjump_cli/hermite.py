"""Cubic Hermite interpolation on one path step (the unit interval ``t`` in [0, 1]).

The continuation interpolates between two converged path points from their values and arc-length
tangents: to predict a point inside a step (:meth:`snapjump_cli.continuation.Tracer.step_between`),
to place a first estimate of a root (:mod:`snapjump_cli.snap`), and to integrate ``p dV`` and test
the path for self-crossings (:mod:`snapjump_cli.metrics`). The one definition lives here.
"""

from __future__ import annotations

import numpy as np

__all__ = ["basis", "power_coefficients"]


def basis(t):
    """The cubic Hermite basis on [0, 1] at ``t`` (scalar or array).

    Returns
    -------
    tuple
        ``(h00, h10, h01, h11)``: the weights of the value at the start, the derivative at the
        start, the value at the end and the derivative at the end (derivatives in ``d/dt``).
    """
    t2 = t * t
    t3 = t2 * t
    return 2 * t3 - 3 * t2 + 1, t3 - 2 * t2 + t, -2 * t3 + 3 * t2, t3 - t2


def power_coefficients(y0: float, d0: float, y1: float, d1: float) -> np.ndarray:
    """The same cubic in power form: ``c`` with ``y(t) = c[0] + c[1] t + c[2] t^2 + c[3] t^3``
    for end values ``y0``, ``y1`` and end derivatives ``d0``, ``d1`` (in ``d/dt``)."""
    return np.array([y0, d0, -3 * y0 - 2 * d0 + 3 * y1 - d1, 2 * y0 + d0 - 2 * y1 + d1])
