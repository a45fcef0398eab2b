"""Cubic Hermite interpolation on one path step (the unit interval ``t`` in [0, 1]).

The continuation interpolates between two converged path points from their values and arc-length
tangents: to predict a point inside a step (:meth:`snapjump_cli.fe.continuation.Tracer.step_between`),
to place a first estimate of a root (:mod:`snapjump_cli.fe.axisym.snap`), and to integrate ``p dV`` and test
the path for self-crossings (:mod:`snapjump_cli.fe.axisym.metrics`). The one definition lives here.
"""

from __future__ import annotations

import numpy as np

__all__ = ["basis", "interpolate", "power_coefficients", "first_root", "segment_maxima"]


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


def interpolate(t: float, y0, d0, y1, d1, h: float = 1.0):
    """The cubic at ``t`` in [0, 1] from its end values ``y0``, ``y1`` and end derivatives ``d0``,
    ``d1`` in ``d/ds`` over a step of length ``h`` (scalars or arrays alike)."""
    h00, h10, h01, h11 = basis(t)
    return h00 * y0 + (h10 * h) * d0 + h01 * y1 + (h11 * h) * d1


def power_coefficients(y0: float, d0: float, y1: float, d1: float) -> np.ndarray:
    """The same cubic in power form: ``c`` with ``y(t) = c[0] + c[1] t + c[2] t^2 + c[3] t^3``
    for end values ``y0``, ``y1`` and end derivatives ``d0``, ``d1`` (in ``d/dt``)."""
    return np.array([y0, d0, -3 * y0 - 2 * d0 + 3 * y1 - d1, 2 * y0 + d0 - 2 * y1 + d1])


def first_root(y0: float, d0: float, y1: float, d1: float, value: float | None = 0.0) -> float | None:
    """The smallest ``t`` inside (0, 1) where the cubic (end values ``y0``, ``y1``, end derivatives
    ``d0``, ``d1`` in ``d/dt``) takes ``value`` (``None``: where its derivative vanishes); ``None`` if
    nowhere inside."""
    c = power_coefficients(y0, d0, y1, d1)
    coef = np.array([c[1], 2 * c[2], 3 * c[3]]) if value is None else c - np.array([value, 0.0, 0.0, 0.0])
    roots = np.roots(coef[::-1]) if np.any(coef[1:] != 0) else np.zeros(0)
    inside = [r.real for r in roots if abs(r.imag) < 1e-12 and 0.0 < r.real < 1.0]
    return float(min(inside)) if inside else None


def segment_maxima(y0: np.ndarray, d0: np.ndarray, y1: np.ndarray, d1: np.ndarray) -> np.ndarray:
    """The largest value of each segment's cubic on [0, 1] (arrays of segments, derivatives in
    ``d/dt``): the larger end value, or an interior maximum where ``y'(t) = 0`` inside the segment.

    A path's extreme value taken from its points alone is off by the curvature times the square of
    the step; from the cubics, by the fourth power of the step.
    """
    y0, d0, y1, d1 = (np.asarray(a, dtype=float) for a in (y0, d0, y1, d1))
    c1 = d0
    c2 = -3 * y0 - 2 * d0 + 3 * y1 - d1
    c3 = 2 * y0 + d0 - 2 * y1 + d1
    best = np.maximum(y0, y1)
    # roots of y'(t) = c1 + 2 c2 t + 3 c3 t^2; the quadratic (or linear) case, both roots tried
    a, b, c = 3 * c3, 2 * c2, c1
    disc = b * b - 4 * a * c
    with np.errstate(divide="ignore", invalid="ignore"):
        sq = np.sqrt(np.maximum(disc, 0.0))
        q = -0.5 * (b + np.copysign(sq, b))  # the stable pair of roots: q / a and c / q
        cand = [np.where(a != 0, q / a, np.nan), np.where(q != 0, c / q, np.nan),
                np.where((a == 0) & (b != 0), -c / b, np.nan)]
    for t in cand:
        t = np.where((disc >= 0) & (t > 0) & (t < 1), t, np.nan)
        y = c1 * t + c2 * t * t + c3 * t * t * t + y0
        best = np.fmax(best, y)
    return best
