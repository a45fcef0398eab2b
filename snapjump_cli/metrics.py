"""Snap metrics (docs/physics.md section 5) from a traced path: V*, p*, the lower state, dE two ways.

:class:`SnapTracker` is the continuation's stop criterion: it watches the accepted points, and

1. at the first limit point in volume (``dV/ds`` changes sign from + to -) locates it precisely
   as the root of ``dV/ds`` (regula falsi on the arc length of a re-solved step, docs/physics.md, pitfall d):
   the *upper state* at ``V*``;
2. follows the path until the volume comes back to ``V*`` with ``dV/ds > 0`` and solves that
   state exactly at ``V = V*`` (volume control): the *lower state* (``lower_state_method="path"``);
3. stops (unless the whole curve was asked for) or reports that the path did not come back.

Where the path does not come back to ``V*`` (it can fold several times and turn back,
docs/physics.md section 5) or comes back on an unstable branch, the lower state is found instead
at fixed volume (:mod:`snapjump_cli.lower_state`), with :func:`descend_at_volume` as the fallback:
a volume-constrained energy descent (implicit gradient flow in pseudo
time) from the upper state, started along the path's unstable direction
(``lower_state_method="descent"``). Stability at fixed volume is read off the inertia of the
band LDL^T (:func:`constrained_instability`).

``dE`` is computed both as the strain-energy difference of the two states and as
``-integral p dV`` along the path between them (cubic Hermite interpolation of ``V(s)`` and
``p(s)`` from the tangents, so the quadrature is fourth-order accurate in the step).
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np

from snapjump_cli.continuation import Path, PathPoint, Tracer

log = logging.getLogger(__name__)

__all__ = ["SnapTracker", "root_on_step", "hermite_p_dV", "path_self_crosses", "SnapStates", "descend_at_volume", "constrained_instability", "descent_starts"]

_G3 = np.polynomial.legendre.leggauss(4)


def root_on_step(tr: Tracer, a: PathPoint, b: PathPoint, a_prev: PathPoint | None, f, tol: float,
                  max_iter: int) -> PathPoint:
    """Illinois regula falsi on the length of a re-solved step from ``a`` for a root of ``f``
    (a function of a path point; ``f(a)`` and ``f(b)`` have opposite signs). Returns the point
    where ``|f| < tol``, else the last one found on ``b``'s side of the root (``b`` if none)."""
    lo, flo = 0.0, f(a)
    hi, fhi, best = b.s - a.s, f(b), b
    b_positive = fhi > 0
    side = 0
    for _ in range(max_iter):
        if abs(fhi) < tol:
            break
        s = hi - fhi * (hi - lo) / (fhi - flo)
        if not (lo < s < hi):
            s = 0.5 * (lo + hi)
        c = tr.step(a, s, a_prev)
        if c is None:  # the predictor may fail where the path curves: bisect
            s = 0.5 * (lo + hi)
            c = tr.step(a, s, a_prev)
            if c is None:
                break
        fc = f(c)
        if abs(fc) < tol:
            return c
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


def hermite_p_dV(a: PathPoint, b: PathPoint, h: float, sV: float, sp: float) -> float:
    """``integral p dV`` from ``a`` to ``b`` (arc length ``h``; scaled units), cubic Hermite."""
    V0, V1 = a.zeta[0] * sV, b.zeta[0] * sV
    p0, p1 = a.p, b.p
    dV0, dV1 = a.tangent[0] * sV * h, b.tangent[0] * sV * h  # derivatives w.r.t. t in [0, 1]
    dp0, dp1 = a.tangent[1] * sp * h, b.tangent[1] * sp * h
    x, w = _G3
    t = 0.5 * (x + 1.0)
    h00 = 2 * t**3 - 3 * t**2 + 1
    h10 = t**3 - 2 * t**2 + t
    h01 = -2 * t**3 + 3 * t**2
    h11 = t**3 - t**2
    d00 = 6 * t**2 - 6 * t
    d10 = 3 * t**2 - 4 * t + 1
    d01 = -6 * t**2 + 6 * t
    d11 = 3 * t**2 - 2 * t
    p = h00 * p0 + h10 * dp0 + h01 * p1 + h11 * dp1
    Vt = d00 * V0 + d10 * dV0 + d01 * V1 + d11 * dV1
    return float(0.5 * np.sum(w * p * Vt))


def path_self_crosses(V: np.ndarray, p: np.ndarray) -> bool:
    """Whether the polyline ``(V, p)`` crosses itself (non-adjacent segments intersect)."""
    P = np.stack([V, p], axis=1)
    n = len(P) - 1
    if n < 3:
        return False
    A, B = P[:-1], P[1:]
    scale = np.ptp(P, axis=0)
    scale[scale == 0] = 1.0
    A = A / scale
    B = B / scale

    def orient(a, b, c):
        return (b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1]) - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0])

    i, j = np.triu_indices(n, k=2)
    a1, b1, a2, b2 = A[i], B[i], A[j], B[j]
    o1 = orient(a1, b1, a2)
    o2 = orient(a1, b1, b2)
    o3 = orient(a2, b2, a1)
    o4 = orient(a2, b2, b1)
    return bool(np.any((o1 * o2 < 0) & (o3 * o4 < 0)))


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
    """Stop criterion of :func:`snapjump_cli.continuation.trace` that characterises the snap.

    Parameters
    ----------
    tracer : the tracer (used for the precise limit-point location and the volume-control solve)
    p_stop : pressure (in units of the stress scale, like ``PathPoint.p``) beyond which a path
        without a volume limit counts as not snapping
    V_stop : scaled volume bound (in units of ``sV``) of the trace
    full : keep tracing after the snap is characterised (to ``p_stop`` or ``V_stop``)
    """

    tracer: Tracer
    p_stop: float
    V_stop: float
    full: bool = False
    post_snap_steps: int = 1500
    cusp_window: float = 1e-3
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
                            tol: float = 1e-9, max_iter: int = 30) -> PathPoint:
        """Root of ``dV/ds`` between the path points ``a`` (dV/ds > 0) and ``b`` (dV/ds <= 0)."""
        return root_on_step(self.tracer, a, b, a_prev, lambda pt: pt.tangent[0], tol, max_iter)

    def locate_volume(self, a: PathPoint, b: PathPoint, V_target: float, a_prev: PathPoint | None = None,
                      max_iter: int = 40) -> PathPoint | None:
        """The path point at scaled volume ``V_target`` between path points ``a`` and ``b``
        (``V_a < V_target <= V_b``), then a volume-control Newton polish at exactly ``V_target``.
        Being on the path, the point's arc length is exact for the path integral of dE."""
        tol = 1e-10 * max(1.0, abs(V_target))
        best = root_on_step(self.tracer, a, b, a_prev, lambda pt: pt.zeta[0] - V_target, tol, max_iter)
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


def constrained_instability(tracer: Tracer, lin) -> int:
    """Number of unstable modes of the equilibrium ``lin`` under volume control.

    With ``K`` the tangent and ``g = dV/du``, the inertia of the bordered matrix gives
    ``neg(Z^T K Z) = neg(K) - [g^T K^-1 g < 0]`` (Haynsworth), ``Z`` spanning ``g``'s complement.
    Returns -1 if the inertia is not available (SuperLU solver).
    """
    z, dz_du, dz_dp = tracer.zeta(lin.u, lin.p)
    return _constrained_negatives(lin.factor(dz_du[0], 0.0), lin.g)


def _constrained_negatives(solver, g: np.ndarray) -> int:
    """Negative eigenvalues of ``K`` restricted to ``g^T du = 0`` from a bordered solver's
    ``LDL^T`` (Haynsworth); -1 if the inertia is not available."""
    if solver is None or getattr(solver, "n_negative", -1) < 0:
        return -1
    gKg = -float(g @ solver.Kib)  # Kib = K^-1 (-g)
    return int(solver.n_negative - (1 if gKg < 0 else 0))


def descend_at_volume(
    tracer: Tracer, upper: PathPoint, kick: float = 0.2, max_iter: int = 2000, tol: float | None = None,
    start: PathPoint | None = None,
) -> tuple[PathPoint | None, str]:
    """The stable state reached from the upper state at fixed volume by energy descent.

    Implicit gradient flow of ``W(u)`` at ``V(u) = V*`` in pseudo time: each iteration solves
    ``[[K + diag(sigma), -g], [g^T, 0]] [du; dp] = [-R; V* - V]`` and is accepted if the merit
    ``W - p (V - V*)`` (with the new multiplier) does not rise. The shift is
    ``sigma = sigma_rel |diag K|`` (a Jacobi metric: a soft thin outer cap and a stiff thick inner
    cap relax at comparable rates). ``sigma_rel`` shrinks after an accepted step and grows after
    a rejected one, and is raised until the shifted system is positive definite on the
    constraint (its inertia from the LDL^T, Haynsworth): every step then goes downhill in every
    mode, so the flow leaves a saddle along its negative curvature, and where that curvature is
    small it leaves at the rate ``|lambda| / sigma`` with the smallest ``sigma`` that allows it
    (a fixed floor on ``sigma`` made the flow crawl for thousands of iterations on ballooning
    soft outer caps). Once stable, ``sigma -> 0`` ends in Newton's method.
    Started at ``kick`` (scaled arc length) along the path tangent at the volume limit, the
    unstable direction of the fold, or at ``start`` (a post-snap path point; its volume is
    brought back to ``V*`` by at most ``max(0.05, 0.01 V*)`` per iteration).

    Returns
    -------
    (PathPoint or None, message)
    """
    cfg = tracer.cfg
    tol = cfg.tol if tol is None else tol
    V_star = upper.zeta[0]
    pb = tracer.pb
    if start is not None:
        u, p = start.u.copy(), start.p
    else:
        u = upper.u + kick * upper.du_ds
        p = upper.p + kick * upper.dp_ds
    sigma_rel = 1.0
    dh_max = max(0.05, 0.01 * abs(V_star))  # largest volume change per iteration (scaled) while restoring V*
    step_small = False
    E_hist: list[float] = []  # energy of the accepted iterates
    n_stall = 20
    accepted = None  # (u, p, lin, merit-function pieces, unshifted factorisation, its instability)
    for it in range(max_iter):
        if accepted is None:
            lin = pb.linearize(u, p)
            if lin is None:
                kick *= 0.25
                u = upper.u + kick * upper.du_ds
                p = upper.p + kick * upper.dp_ds
                continue
            E_new = lin.E
            z, dz_du, dz_dp = tracer.zeta(u, p, lin)
            h = float(z[0] - V_star)
            base = None
        else:
            # a trial step: energy and volume decide; the stiffness is assembled only if it is taken
            u0, p0, lin0, E0, h0, base0, nu0 = accepted
            ev = pb.energy_volume(u)
            ok = ev is not None
            if ok:
                E_new = ev[0]
                h = float(ev[1] / tracer.sc[0] - V_star)
            # compare with the new multiplier: merit W - p (V - V*); while the volume is still
            # being restored from a start far from V* any step inside the material domain is
            # taken. (With a tight threshold here, steps that overshot to |V - V*| ~ 1e-5 were
            # accepted unchecked and the flow climbed to 5x the energy on thin inner caps.)
            feasible = abs(h0) < 1e-3 * max(1.0, abs(V_star))
            if not ok and not feasible:
                dh_max *= 0.5
            lin = None
            if ok and not (feasible and E_new - p * h * tracer.sc[0] > E0 - p * h0 * tracer.sc[0] + 1e-13 * max(1.0, abs(E0))):
                lin = pb.linearize(u, p)
            if lin is None:
                sigma_rel = min(sigma_rel * 8.0, 1e6)
                u, p, lin, E_new, h, base, n_unstable = u0, p0, lin0, E0, h0, base0, nu0
            else:
                sigma_rel *= 0.25
                base = None
            z, dz_du, dz_dp = tracer.zeta(u, p, lin)
        if base is None:
            base = lin.factor(dz_du[0], 0.0)  # unshifted: the inertia, and Newton's step once sigma -> 0
            n_unstable = _constrained_negatives(base, lin.g)
        accepted = (u, p, lin, E_new, h, base, n_unstable)
        ref = tracer.residual_scale(lin, dz_du, p)
        rn = float(np.linalg.norm(lin.R)) / ref
        log.debug("descent %d: E=%.12g rn=%.2e h=%.2e sigma_rel=%.1e unstable=%d", it, E_new, rn, h, sigma_rel, n_unstable)
        E_hist.append(E_new)
        # Newton at round-off: a snap at p ~ 0 has a tiny residual scale (the pressure load), and
        # the residual can stall above tol while energy, volume and state no longer change
        stalled = (len(E_hist) > n_stall and sigma_rel < 1e-10 and rn < 1e-3
                   and abs(E_hist[-1] - E_hist[-1 - n_stall]) <= 1e-13 * max(abs(E_new), 1e-300))
        if n_unstable == 0 and abs(h) < tol and (rn < tol or (rn < 100 * tol and step_small) or stalled):
            t, v, q, zz = tracer.tangent(lin, (upper.tangent, tracer.alpha * upper.du_ds))
            how = f"at round-off, residual {rn:.1e}, " if rn >= tol else ""
            return PathPoint(lin.u, lin.p, zz, t, v, q, float("nan"), it), f"descent converged {how}in {it} iterations"
        # the smallest shift (from the current sigma_rel up) that makes the shifted system
        # positive definite on the constraint: the step then goes downhill in every mode
        solver = None
        while sigma_rel <= 1e6:
            if n_unstable != 0 or sigma_rel > 1e-10:
                solver = lin.factor(dz_du[0], 0.0, shift=sigma_rel * lin.diag_abs())
            else:
                solver = base
            if solver is not None and (n_unstable == 0 or _constrained_negatives(solver, lin.g) == 0):
                break
            sigma_rel = max(sigma_rel * 8.0, 1e-10)
            solver = None
        if solver is None:
            return None, f"descent: no positive definite shift at iteration {it}"
        # restore the volume gradually when starting far from V* (a homotopy in the constraint)
        h_step = float(np.clip(h, -dh_max, dh_max))
        x = solver.solve(np.concatenate([-lin.R, [-h_step]]))
        u = u + x[:-1]
        p = p + x[-1]
        step_small = float(np.linalg.norm(dz_du @ x[:-1] + dz_dp * x[-1])) < 1e-12
    return None, f"descent did not converge in {max_iter} iterations"


def descent_starts(path_points: list[PathPoint], upper: PathPoint, k_before: int, n: int = 3) -> list[PathPoint]:
    """Start states for :func:`descend_at_volume`: post-snap path points whose volume is closest
    to ``V*``, skipping the first fifth of the post-snap arc (the flat neighbourhood of the
    degenerate saddle, where a descent would crawl)."""
    after = path_points[k_before + 1 :]
    if not after:
        return []
    s0, s1 = upper.s, after[-1].s
    far = [pt for pt in after if pt.s >= s0 + 0.2 * (s1 - s0)]
    far.sort(key=lambda pt: abs(pt.zeta[0] - upper.zeta[0]))
    return far[:n]
