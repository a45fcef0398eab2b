"""Snap detection along the traced path (docs/physics.md section 5): the upper state at ``V*`` and,
where the path comes back to ``V*``, the lower state on it.

:class:`SnapTracker` is the continuation's stop criterion: it watches the accepted points, and

1. at the first limit point in volume (``dV/ds`` changes sign from + to -) locates it precisely
   as the root of ``dV/ds`` (regula falsi on the arc length of a re-solved step, :func:`root_on_step`;
   docs/physics.md, pitfall d): the *upper state* at ``V*``;
2. follows the path until the volume comes back to ``V*`` with ``dV/ds > 0`` and solves that
   state exactly at ``V = V*`` (volume control): the *lower state* (``lower_state_method="path"``);
3. stops (unless the whole curve was asked for) or reports that the path did not come back.

What it found is kept in :class:`SnapStates`. Where the path does not come back to ``V*`` (it can
fold several times and turn back, docs/physics.md section 5) or comes back on an unstable branch,
the lower state is found off the path, at fixed volume (:func:`snapjump_cli.fe.axisym.lower_state.find_lower_state`).
:func:`state_at_pressure` solves the state at a given pressure on the path (an outer cap alone).
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from snapjump_cli.fe.continuation import hermite
from snapjump_cli.fe.continuation import Path, PathPoint, Tracer

log = logging.getLogger(__name__)

__all__ = ["SnapStates", "SnapTracker", "root_on_step", "state_at_pressure", "POST_SNAP_SKIPPED"]

#: The stop reason of a trace told not to follow the post-snap path (``SnapTracker(post_snap=False)``).
POST_SNAP_SKIPPED = "upper state located; post-snap path not traced"


def root_on_step(tr: Tracer, a: PathPoint, b: PathPoint, a_prev: PathPoint | None,
                 f: Callable[[PathPoint], float], tol: float, max_iter: int, s0: float | None = None,
                 f_ends: tuple[float, float] | None = None) -> PathPoint:
    """A root of ``f`` (a function of a path point; ``f(a)`` and ``f(b)`` have opposite signs) on
    the length of a re-solved step from ``a``: the secant through the last two trial points while
    it stays inside the bracket, else Illinois regula falsi on the bracket; the first trial at
    the arc length ``s0`` if given (a better first estimate than the secant's). Returns the point
    where ``|f| < tol``, else the last one found on ``b``'s side of the root (``b`` if none).
    Each trial point is predicted by the cubic Hermite interpolation between ``a`` and ``b``
    (:meth:`~snapjump_cli.fe.continuation.Tracer.step_between`; an extrapolation from ``a`` if that
    fails). ``f_ends``: ``(f(a), f(b))`` where the caller has them (an eigen-solve each)."""
    fa, fb = (f(a), f(b)) if f_ends is None else f_ends
    lo, flo = 0.0, fa
    hi, fhi, best = b.s - a.s, fb, b
    b_positive = fhi > 0
    side = 0
    trials: list[tuple[float, float]] = []
    for _ in range(max_iter):
        if abs(fhi) < tol:
            break
        if s0 is not None:
            s, s0 = s0, None
        elif len(trials) >= 2 and trials[-1][1] != trials[-2][1]:
            (s1, f1), (s2, f2) = trials[-2], trials[-1]
            s = s2 - f2 * (s2 - s1) / (f2 - f1)
        else:
            s = hi - fhi * (hi - lo) / (fhi - flo)
        if not (lo < s < hi):
            s = hi - fhi * (hi - lo) / (fhi - flo)
            if not (lo < s < hi):
                s = 0.5 * (lo + hi)
        c = tr.step_between(a, b, s) or tr.step(a, s, a_prev)
        if c is None:  # the predictor may fail where the path curves: bisect
            s = 0.5 * (lo + hi)
            c = tr.step(a, s, a_prev)
            if c is None:
                break
        fc = f(c)
        if abs(fc) < tol:
            return c
        trials.append((s, fc))
        if (fc > 0) == b_positive:
            hi, fhi, best = s, fc, c
            if side == 1:
                flo *= 0.5
            side = 1
        else:
            lo, flo = s, fc
            if side == -1:
                fhi *= 0.5
            side = -1
        if hi - lo < 1e-13:
            break
    return best


def _hermite_root(a: PathPoint, b: PathPoint, value: float, derivative: bool = False) -> float | None:
    """Arc length from ``a`` where the cubic Hermite interpolation of the scaled volume between the
    path points ``a`` and ``b`` (their values and tangents) takes ``value`` (with ``derivative``:
    where its derivative ``dV/ds`` does); ``None`` if it has no such point inside the step.
    A first estimate for :func:`root_on_step`, exact to the interpolation's error."""
    h = b.s - a.s
    t = hermite.first_root(a.zeta[0], a.tangent[0] * h, b.zeta[0], b.tangent[0] * h, None if derivative else value)
    return None if t is None else t * h


@dataclass
class SnapStates:
    """What the tracker found (indices refer to ``path.points``)."""

    k_before: int | None = None  # last point with dV/ds > 0 before the first volume limit
    upper: PathPoint | None = None  # the state at the volume limit point
    k_return: int | None = None  # first point after the limit with V >= V* and dV/ds > 0
    lower: PathPoint | None = None  # the lower state solved at V = V*
    lower_method: str = ""
    p_max: float = -math.inf
    fold_note: str = ""  # set when the volume limit is a near-cusp (see SnapTracker.cusp_window)
    cusp_change: tuple[int, int] | None = None  # first change of neg(K_T) after the limit ...
    cusp_gap: float | None = None  # ... and its relative distance from (V*, p*) (0: the fold's step)


@dataclass
class SnapTracker:
    """Stop criterion of :func:`snapjump_cli.fe.continuation.trace` that characterises the snap.

    Parameters
    ----------
    tracer : the tracer (used for the precise limit-point location and the volume-control solve)
    p_stop : pressure (in units of the stress scale, like ``PathPoint.p``) beyond which a path
        without a volume limit counts as not snapping
    V_stop : scaled volume bound (in units of ``sV``) of the trace
    full : keep tracing after the snap is characterised (to ``p_stop`` or ``V_stop``)
    post_snap_steps : steps after the volume limit within which the path must come back to V*
        (the solver passes :func:`snapjump_cli.fe.solve.post_snap_budget`)
    post_snap : follow the post-snap path until it comes back to V* or stops otherwise (the cavity
        volume at zero, the step budget). ``False``: stop as soon as the upper state is located and
        the near-cusp watch has decided (the first change of ``neg(K_T)`` after the fold,
        :meth:`_watch_cusp`), unless the path is back at V* before then; the lower state is then
        sought at fixed volume. The mesh re-check of a design whose coarse path went to zero
        volume uses it (:func:`snapjump_cli.fe.solve.solve_scene`, docs/performance.md).
    """

    tracer: Tracer
    p_stop: float
    V_stop: float
    full: bool = False
    post_snap_steps: int = 1500
    cusp_window: float = 1e-3
    post_snap: bool = True
    states: SnapStates = field(default_factory=SnapStates)

    def __call__(self, path: Path) -> str | None:
        st = self.states
        pts = path.points
        new = pts[-1]
        prev = pts[-2]
        if st.upper is None:
            st.p_max = max(st.p_max, new.p)
            if prev.tangent[0] > 0 and new.tangent[0] <= 0:
                st.k_before = len(pts) - 2
                st.upper = self.locate_volume_limit(prev, new, pts[-3] if len(pts) > 2 else None)
                self._watch_cusp(prev, new, 0.0)
                log.debug("volume limit: V*=%.6g p*=%.6g", st.upper.zeta[0], st.upper.p)
        elif st.lower is None:
            Vs = st.upper.zeta[0]
            if st.cusp_change is None:
                self._watch_cusp(prev, new, min(self._distance(prev), self._distance(new)))
            if new.tangent[0] > 0 and new.zeta[0] >= Vs and prev.zeta[0] < Vs:
                st.k_return = len(pts) - 1
                st.lower = self.locate_volume(prev, new, Vs, pts[-3] if len(pts) > 2 else None)
                if st.lower is not None:
                    st.lower_method = "path"
                    if not self.full:
                        return "snap characterised"
            elif len(pts) - 1 - st.k_before > self.post_snap_steps:
                return "path did not return to V*"
        if new.zeta[0] > self.V_stop:
            return "volume bound"
        if new.zeta[0] <= 0.0:  # the caps interpenetrate (no contact is modelled): nothing physical follows
            return "cavity volume reached zero"
        if new.p > self.p_stop and (st.upper is None or st.lower is not None or self.full):
            return "pressure bound"
        if not self.post_snap and not self.full and st.upper is not None and st.lower is None \
                and st.cusp_change is not None:
            return POST_SNAP_SKIPPED
        return None

    def _distance(self, pt: PathPoint) -> float:
        """Relative distance of a path point from the upper state in (V, p) (p relative to the
        larger of |p*| and the path's maximum pressure so far)."""
        st = self.states
        up = st.upper
        return max(abs(pt.zeta[0] / up.zeta[0] - 1.0), abs(pt.p - up.p) / max(abs(up.p), st.p_max, 1e-300))

    def _watch_cusp(self, prev: PathPoint, new: PathPoint, gap: float) -> None:
        """The first change of ``neg(K_T)`` after the volume limit decides whether it is a near-cusp.

        A clean fold keeps ``neg(K_T)`` (or gains the first unstable mode when it lies just past the
        pressure maximum, as on thin caps); the next pressure extremum or bifurcation comes well
        after it (design B: 6-9 % lower in p). When K_T gains a further mode within ``cusp_window``
        of the fold in both V and p (``gap``; 0 in the fold's own step), the path turns there
        through a near-cusp whose branch a small change of the mesh switches (design A: 6e-7 at
        nt 2 / aspect 3, the same step at aspect 2; on finer meshes the fold is gone).
        """
        st = self.states
        if min(prev.n_neg, new.n_neg) < 0 or new.n_neg == prev.n_neg:  # unknown (SuperLU) or no change
            return
        st.cusp_change, st.cusp_gap = (prev.n_neg, new.n_neg), gap
        if max(prev.n_neg, new.n_neg) >= 2 and gap <= self.cusp_window:
            st.fold_note = (f"volume limit at a near-cusp: K_T's unstable modes go {prev.n_neg} -> {new.n_neg} "
                            f"within {gap:.1e} of (V*, p*)")

    def locate_volume_limit(self, a: PathPoint, b: PathPoint, a_prev: PathPoint | None = None,
                            tol: float = 1e-7, max_iter: int = 30) -> PathPoint:
        """Root of ``dV/ds`` between the path points ``a`` (dV/ds > 0) and ``b`` (dV/ds <= 0),
        to ``|dV/ds| < tol`` (the unit tangent's volume component: it carries round-off of a few
        1e-9 from the Newton tolerance, so a tighter ``tol`` only makes the iteration dither; the
        limit point then lies within ~``tol`` of the root in arc length, and ``V*`` within ~``tol^2``)."""
        return root_on_step(self.tracer, a, b, a_prev, lambda pt: pt.tangent[0], tol, max_iter,
                            s0=_hermite_root(a, b, 0.0, derivative=True))

    def locate_volume(self, a: PathPoint, b: PathPoint, V_target: float, a_prev: PathPoint | None = None,
                      max_iter: int = 40) -> PathPoint | None:
        """The path point at scaled volume ``V_target`` between path points ``a`` and ``b``
        (``V_a < V_target <= V_b``), to ``|V - V_target| < 1e-8 max(1, |V_target|)``, then a
        volume-control Newton polish at exactly ``V_target``. Being on the path, the point's arc
        length is exact for the path integral of dE (to the ~1e-8 the polish moves it)."""
        tol = 1e-8 * max(1.0, abs(V_target))
        best = root_on_step(self.tracer, a, b, a_prev, lambda pt: pt.zeta[0] - V_target, tol, max_iter,
                            s0=_hermite_root(a, b, V_target))
        polished = self.solve_at_volume(best, best, V_target) if best.tangent[0] > 0 else None
        if polished is None:  # fall back on interpolating between the bracketing points
            log.debug("locate_volume: regula falsi did not reach V*; interpolating")
            return self.solve_at_volume(a, b, V_target)
        polished.s = best.s  # the polish moves the state by ~tol: keep the path's arc length
        return polished

    def solve_at_volume(self, a: PathPoint, b: PathPoint, V_target: float) -> PathPoint | None:
        """The equilibrium state at scaled volume ``V_target`` between path points ``a`` and ``b``."""
        tr = self.tracer
        dV = b.zeta[0] - a.zeta[0]
        w = (V_target - a.zeta[0]) / dV if dV != 0 else 0.0
        u0 = (1 - w) * a.u + w * b.u
        p0 = (1 - w) * a.p + w * b.p
        res = tr.correct(u0, p0, None, None, 0.0, target=(0, V_target))
        if res is None:
            return None
        lin, it = res
        t, v, q, z = tr.tangent(lin, (b.tangent, tr.alpha * b.du_ds))
        h = float(np.sqrt(np.sum((z - a.zeta) ** 2) + tr.alpha**2 * np.sum((lin.u - a.u) ** 2)))
        return PathPoint(lin.u, lin.p, z, t, v, q, a.s + h, it, tr.last_det_sign, tr.last_n_neg)


def state_at_pressure(tracer: Tracer, path: Path, p: float) -> np.ndarray | None:
    """The displacement of the equilibrium at pressure ``p`` (units of the stress scale, like
    ``PathPoint.p``) on the first step of the path that reaches it, solved exactly at ``p`` from
    the linear interpolation in the step; ``None`` if the path does not reach ``p`` or Newton fails."""
    pts = path.points
    sp = tracer.sc[1]
    for a, b in zip(pts[:-1], pts[1:]):
        if a.p < p <= b.p:
            w = (p - a.p) / (b.p - a.p)
            res = tracer.correct((1 - w) * a.u + w * b.u, p, None, None, 0.0, target=(1, p / sp))
            if res is None:
                return None
            return res[0].u
    return None
