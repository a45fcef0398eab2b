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

__all__ = ["default_harmonics", "Bifurcation", "Bracket", "locate_bifurcation", "bracket_bifurcation", "first_bifurcation",
           "FIRST_BRACKET_ONLY", "harmonic1_gauge"]


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
    and the last stable one before it bracket it (:func:`bracket_bifurcation`); the smallest
    eigenvalue's zero (``mu_min / L^2`` units) is then found on that path step to ``tol_eig`` by
    :func:`snapjump_cli.fe.axisym.snap.root_on_step` (secant and Illinois steps, each point re-solved on the
    path)."""
    return _locate(result, bracket_bifurcation(result, n), tol_eig, max_iter)


@dataclass
class Bracket:
    """The path step on which harmonic ``n`` loses stability: ``states[k - 1]`` stable, ``states[k]``
    (``k >= 1``) not, with ``op`` its operator (:func:`bracket_bifurcation`)."""

    n: int
    op: object
    states: list
    k: int


def bracket_bifurcation(result, n: int) -> Bracket | None:
    """The first state of the axisymmetric path (up to its upper state) at which ``K_n`` has a
    negative eigenvalue, and the stable one before it; ``None`` if there is none or the path's
    first state is already unstable."""
    model, pts, st = result.model, result.path.points, result.states
    op = harmonic_operator(model, n)
    states = list(pts[: st.k_before + 1]) + [st.upper] if st.upper is not None else list(pts)
    for k, pt in enumerate(states):
        if op.inertia(pt.u, pt.p) != 0:
            return Bracket(n, op, states, k) if k > 0 else None
    return None


def _locate(result, br: Bracket | None, tol_eig: float = 1e-9, max_iter: int = 30,
            ends: tuple | None = None) -> Bifurcation | None:
    """The zero of the bracket's smallest eigenvalue (:func:`locate_bifurcation`); ``ends``: the
    eigenpairs at the bracket's two states where the caller has them (:func:`_ends`)."""
    if br is None:
        return None
    n, op, states, k = br.n, br.op, br.states, br.k
    a, b = states[k - 1], states[k]
    a_prev = states[k - 2] if k > 1 else None
    ea, eb = _ends(br) if ends is None else ends
    if ea is None or eb is None or not (ea[0] > 0.0 > eb[0]):
        return None
    solved: dict = {id(a): (a, ea), id(b): (b, eb)}  # id -> (point, eigenpair): the points kept (no id reused)

    def f(q: PathPoint) -> float:
        ev = lowest_eigen(op, q.u, q.p)
        if ev is None:
            return math.nan
        solved[id(q)] = (q, ev)
        return ev[0]

    root = root_on_step(result.tracer, a, b, a_prev, f, tol_eig, max_iter, f_ends=(ea[0], eb[0]))
    eig, mode = solved[id(root)][1]  # (root_on_step returns a point it evaluated)
    log.debug("bifurcation of harmonic %d at V = %.9g (scaled), eigenvalue %.2g", n, root.zeta[0], eig)
    return Bifurcation(n, np.array(root.u), float(root.p), np.array(root.zeta), mode, eig, len(solved),
                       float(root.s))


def _ends(br: Bracket) -> tuple:
    """The smallest eigenpairs of ``K_n`` at the bracket's two states (``None`` where not solved)."""
    a, b = br.states[br.k - 1], br.states[br.k]
    return lowest_eigen(br.op, a.u, a.p), lowest_eigen(br.op, b.u, b.p)


#: :func:`first_bifurcation` locates, of the harmonics bracketed on the same step of the path, first
#: the one whose eigenvalue the linear interpolation between the step's ends puts at zero first;
#: another is located only where its ``K_n`` is already unstable at that point (a harmonic stable
#: there crosses later on the step); ``False``: every one located, then the first taken (the same
#: point, bit for bit: each is located on its bracket as before; a switch for measurements).
FIRST_BRACKET_ONLY = True


def first_bifurcation(result, harmonics: list[int]) -> Bifurcation | None:
    """Of the bifurcations of ``harmonics`` on the axisymmetric path (:func:`locate_bifurcation`),
    the first along the path (the smallest arc length; the lower harmonic on a tie); ``None`` if
    none is located. The harmonic check reports every harmonic unstable at its first unstable
    state; where its refinement of that state did not separate them (near a fold of the volume, a
    small volume interval holds a long stretch of the path), the located points say which one the
    actuator meets first. A harmonic bracketed on a later step than another's, or still stable at a
    point located first on the same step, is not located (:data:`FIRST_BRACKET_ONLY`)."""
    brackets = [br for br in (bracket_bifurcation(result, int(n)) for n in sorted(set(harmonics))) if br is not None]
    if not FIRST_BRACKET_ONLY:
        found = [b for b in (_locate(result, br) for br in brackets) if b is not None]
        return min(found, key=lambda b: (b.s, b.n)) if found else None
    for k in sorted({br.k for br in brackets}):
        tied = [(br, _ends(br)) for br in brackets if br.k == k]
        tied.sort(key=lambda t: (_zero_fraction(t[1]), t[0].n))
        found: list[Bifurcation] = []
        for br, ends in tied:
            if found and all(br.op.inertia(b.u, b.p) == 0 for b in found):
                continue  # stable at a point located before: its zero lies later on the step
            b = _locate(result, br, ends=ends)
            if b is not None:
                found.append(b)
        if found:
            return min(found, key=lambda b: (b.s, b.n))
    return None


def _zero_fraction(ends: tuple) -> float:
    """Where on the step the linear interpolation of the eigenvalue between its ends is zero (the
    fraction of the step; ``inf`` where the ends do not bracket a zero)."""
    ea, eb = ends
    if ea is None or eb is None or not (ea[0] > 0.0 > eb[0]):
        return math.inf
    return ea[0] / (ea[0] - eb[0])


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
