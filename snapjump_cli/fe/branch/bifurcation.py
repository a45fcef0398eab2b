"""Where a harmonic leaves the axisymmetric path (docs/harmonics.md, section 10).

When the harmonic check (:func:`snapjump_cli.fe.stability.harmonics.check_harmonics`) finds that
harmonic ``n_c`` loses stability before ``V*``, the actuator leaves the axisymmetric path there:
:func:`locate_bifurcation` finds the volume at which the smallest eigenvalue of the pencil
``(K_n, M_n)`` crosses zero (secant iterations between the last stable and the first unstable path
state, each a Newton solve at fixed volume) and its critical mode; :func:`default_harmonics` the
harmonics ``0, n_c, 2 n_c, ..., N`` the branch is traced with, :func:`harmonic1_gauge` the
amplitudes of harmonic 1 that fix a free body's rigid modes.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from snapjump_cli.fe.axisym.snap import root_on_step
from snapjump_cli.fe.continuation import PathPoint
from snapjump_cli.fe.stability.eigen import lowest_eigen
from snapjump_cli.fe.stability.harmonics import harmonic_operator

log = logging.getLogger(__name__)

__all__ = ["default_harmonics", "Bifurcation", "locate_bifurcation", "first_bifurcation", "harmonic1_gauge"]


def default_harmonics(n_c: int, N: int | None = None) -> list[int]:
    """The harmonics kept for a branch of harmonic ``n_c``: ``0, n_c, 2 n_c, ...`` up to ``N``
    (default ``4 n_c``: with ``2 n_c`` the second-order field is complete but the branch's
    quartic term is not, and the branch folds back spuriously; docs/harmonics.md)."""
    if N is None or N == 0:
        N = 4 * n_c
    if N < n_c:
        raise ValueError(f"N = {N} is below the critical harmonic {n_c}")
    return [0] + list(range(n_c, N + 1, n_c))


@dataclass
class Bifurcation:
    """The point where harmonic ``n`` loses stability on the axisymmetric path."""

    n: int
    u: np.ndarray
    p: float
    zeta: np.ndarray  # scaled measures
    mode: np.ndarray  # (nn, 3) critical mode, largest entry 1
    eig: float  # the eigenvalue there (~0)
    iterations: int
    s: float = float("nan")  # arc length of the axisymmetric path there (scaled)


def locate_bifurcation(result, n: int, tol_eig: float = 1e-9, max_iter: int = 30) -> Bifurcation | None:
    """The bifurcation of harmonic ``n`` on the axisymmetric path before ``V*`` (``None`` if the
    harmonic stays stable up to it): the first path state whose ``K_n`` has a negative eigenvalue
    and the last stable one before it bracket it; the smallest eigenvalue's zero (``mu_min / L^2``
    units) is then found on that path step to ``tol_eig`` by
    :func:`snapjump_cli.fe.axisym.snap.root_on_step` (secant and Illinois steps, each point re-solved on the
    path)."""
    model, pts, st, tracer = result.model, result.path.points, result.states, result.tracer
    op = harmonic_operator(model, n)
    states = list(pts[: st.k_before + 1]) + [st.upper] if st.upper is not None else list(pts)
    prev = None
    for pt in states:
        if op.inertia(pt.u, pt.p) != 0:
            break
        prev = pt
    else:
        return None
    if prev is None:
        return None
    a, b = prev, pt
    k = next(i for i, q in enumerate(states) if q is a)
    a_prev = states[k - 1] if k > 0 else None
    solved: dict = {}  # id -> (point, eigenpair): the points kept, so that no id is reused

    def f(q: PathPoint) -> float:
        ev = lowest_eigen(op, q.u, q.p)
        if ev is None:
            return math.nan
        solved[id(q)] = (q, ev)
        return ev[0]

    fa, fb = f(a), f(b)
    if not (fa > 0.0 > fb):
        return None
    root = root_on_step(tracer, a, b, a_prev, f, tol_eig, max_iter, f_ends=(fa, fb))
    eig, mode = solved[id(root)][1]  # (root_on_step returns a point it evaluated)
    log.debug("bifurcation of harmonic %d at V = %.9g (scaled), eigenvalue %.2g", n, root.zeta[0], eig)
    return Bifurcation(n, np.array(root.u), float(root.p), np.array(root.zeta), mode, eig, len(solved), float(root.s))


def first_bifurcation(result, harmonics: list[int]) -> Bifurcation | None:
    """Of the bifurcations of ``harmonics`` on the axisymmetric path (:func:`locate_bifurcation`),
    the first along the path (the smallest arc length; the lower harmonic on a tie); ``None`` if
    none is located. The harmonic check reports every harmonic unstable at its first unstable
    state; where its refinement of that state did not separate them (near a fold of the volume, a
    small volume interval holds a long stretch of the path), the located points say which one the
    actuator meets first."""
    found = [b for b in (locate_bifurcation(result, int(n)) for n in sorted(set(harmonics))) if b is not None]
    return min(found, key=lambda b: (b.s, b.n)) if found else None


def harmonic1_gauge(base, n: int, u: np.ndarray) -> list[tuple[int, int]]:
    """The ``(node, comp)`` amplitudes of harmonic 1 that the harmonic check's gauge fixes at the
    axisymmetric state ``u`` (the rigid translation and tilt of a free body); ``[]`` unless
    ``n == 1`` (a branch of ``n >= 2`` does not keep harmonic 1)."""
    if n != 1:
        return []
    op1 = harmonic_operator(base, 1)
    L = op1.layout
    gauge = []
    for d in op1.gauge_dofs(u):
        nodes, comps = np.nonzero((L.dofmap == d) & (L.coef > 0))
        gauge.append((int(nodes[0]), int(comps[0])))
    return gauge
