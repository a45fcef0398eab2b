"""The corrector and the tangents of the arc-length continuation (:mod:`snapjump_cli.fe.continuation`):
:class:`Tracer` holds a problem and its settings and computes Riks corrections (the compiled
corrector of the problem when it has one), tangents and the bordered determinant's sign;
:func:`start_point` the first path point."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from snapjump_cli.fe.continuation import hermite
from snapjump_cli.fe.continuation.path import ContinuationFailed, ContinuationSettings, PathPoint, Problem

__all__ = ["Tracer", "start_point", "point_between"]


@dataclass
class _Corrected:
    """A Riks state accepted by the error test: the last iterate plus its correction (not
    evaluated), with the iterate's factorisation for the tangent and the auxiliary field's
    linearised update."""

    u: np.ndarray
    p: float
    tangent_solver: object
    aux_next: np.ndarray | None = None
    aux_dir: Callable | None = None


class Tracer:
    """Stateful helper around a problem: Newton corrections and tangents.

    Parameters
    ----------
    problem : the problem interface
    settings : continuation settings
    """

    def __init__(self, problem: Problem, settings: ContinuationSettings) -> None:
        self.pb = problem
        self.cfg = settings
        self.sc = np.asarray(settings.scales, float)
        self.n_newton = 0
        self.last_det_sign = 0
        self.last_n_neg = -1
        #: the first contraction of the last correction (its second Newton correction over its
        #: first, in the arc-length metric; None where fewer than two were computed or compiled)
        self.last_theta: float | None = None
        # weight of the RMS displacement in the arc length (0: measures only)
        self.alpha = 1.0 / (math.sqrt(problem.n) * settings.u_scale) if settings.u_scale > 0 else 0.0

    # ---- measures -----------------------------------------------------------------------------
    def zeta(self, u, p, lin=None):
        z, dz_du, dz_dp = self.pb.measures(u, p, lin) if lin is not None else self.pb.measures(u, p)
        return z / self.sc, dz_du / self.sc[:, None], dz_dp / self.sc

    def residual_scale(self, lin, dz_du, p) -> float:
        """Residual scale: the problem's ``residual_ref(lin)`` if it has one, else the pressure
        load ``|dV/du| max(|p|, 1e-3 s_p)`` (``zeta_0 = V``, ``zeta_1 = p``)."""
        ref_fn = getattr(self.pb, "residual_ref", None)
        if ref_fn is not None:
            return ref_fn(lin)
        return float(np.linalg.norm(dz_du[0])) * self.sc[0] * max(abs(p), 1e-3 * self.sc[1])

    def tangent(self, lin, t_prev: np.ndarray):
        """Unit tangent at a converged state (its linearisation ``lin``), oriented along ``t_prev``.

        Solves ``[[K_T, dR/dp], [t_prev . dzeta/du, t_prev . dzeta/dp]] [v; q] = [0; 1]``, so
        ``t_prev . dzeta = 1 > 0``: the orientation follows the previous tangent.
        """
        u, p = lin.u, lin.p
        z, dz_du, dz_dp = self.zeta(u, p, lin)
        t_z, t_u = t_prev
        a = self.alpha
        solver = lin.factor(t_z @ dz_du + a * t_u, float(t_z @ dz_dp))
        if solver is None:
            raise ContinuationFailed("singular bordered matrix at a converged state")
        rhs = np.zeros(self.pb.n + 1)
        rhs[-1] = 1.0
        t, v, q, z, _ = self._unit_tangent(lin, solver.solve(rhs))
        self.last_n_neg = int(getattr(solver, "n_negative", -1))
        self.last_det_sign = _det_sign(self.last_n_neg, getattr(solver, "schur", None))
        return t, v, q, z

    def _unit_tangent(self, lin, x: np.ndarray):
        """``(t, v, q, zeta, norm)``: the solution ``x = [v; q]`` of the tangent system at ``lin``
        scaled to unit length in the arc-length metric."""
        evaluated = getattr(lin, "g", None) is not None
        v, q = x[:-1], x[-1]
        rates = getattr(self.pb, "measure_rates", None)
        if rates is not None and evaluated:  # without forming d zeta / du
            z, dz = rates(lin, v, q)
            z, dz = z / self.sc, dz / self.sc
        else:
            z, dz_du, dz_dp = self.zeta(lin.u, lin.p, lin if evaluated else None)
            dz = dz_du @ v + dz_dp * q
        a = self.alpha
        nrm = math.sqrt(float(dz @ dz) + a * a * float(v @ v))
        if not np.isfinite(nrm) or nrm == 0.0:
            raise ContinuationFailed("degenerate tangent (no change of volume, pressure or pole)")
        return dz / nrm, v / nrm, q / nrm, z, nrm

    def _tangent_at(self, lin, t_prev: np.ndarray):
        """The unit tangent at an accepted Riks iterate, with the auxiliary field and its
        derivative: from the corrector's last factorisation if it kept it, else
        :meth:`tangent` (a new one). Returns ``(t, v, q, zeta, aux, daux_ds)``."""
        x = getattr(lin, "tangent_x", None)
        solver = getattr(lin, "tangent_solver", None)
        if x is None and solver is not None:
            rhs = np.zeros(self.pb.n + 1)
            rhs[-1] = 1.0
            x = solver.solve(rhs)
        if x is None:
            t, v, q, z = self.tangent(lin, t_prev)
            aux = getattr(lin, "aux", None)
            return t, v, q, z, aux, None
        t, v, q, z, nrm = self._unit_tangent(lin, x)
        n_neg, schur = ((getattr(solver, "n_negative", -1), getattr(solver, "schur", None)) if solver is not None
                        else lin.tangent_inertia)
        self.last_n_neg = int(n_neg)
        self.last_det_sign = _det_sign(n_neg, schur)
        aux = getattr(lin, "aux_next", None)
        if aux is None:
            aux = getattr(lin, "aux", None)
        daux = getattr(lin, "daux_x", None)
        if daux is None and aux is not None and getattr(lin, "aux_dir", None) is not None:
            daux = lin.aux_dir(x[:-1])
        return t, v, q, z, aux, (daux / nrm if daux is not None else None)

    def correct(self, u, p, z0, t, ds, target=None, tol=None, aux=None, error_test=False):
        """Newton on ``R = 0`` and one linear constraint in measure space.

        With ``target=None`` the constraint is the Riks hyperplane ``t . (zeta - z0) = ds``;
        with ``target=(k, value)`` it fixes one scaled measure, ``zeta_k = value``.

        Returns ``(linearisation at the converged state, iterations)`` or ``None`` on failure.
        Converged (residual test): the residual below ``tol`` times the pressure load
        ``|p| |dV/du|`` (floored at 1e-3 of the pressure scale), or at its round-off floor after a
        negligible correction. With ``error_test`` (Riks only) an iterate is also accepted when the
        Newton correction computed there, in the arc-length metric, is below ``tol`` and smaller
        than the one before (it estimates the iterate's error); the state returned is then the
        iterate plus that correction, not evaluated (its error is of the order of the correction
        squared), and Newton gives up once a correction above ``tol`` exceeds
        ``settings.theta_max`` times the one before. A Riks result keeps the last factorisation for the tangent (``tangent_solver``
        or, compiled, ``tangent_x``). ``aux``: the auxiliary field to linearise with (the
        problem's mixed pressures), if any.
        """
        cfg = self.cfg
        tol = cfg.tol if tol is None else tol
        tol_inc = tol if (error_test and target is None) else 0.0
        fused = getattr(self.pb, "newton", None) if cfg.fused else None
        self.last_theta = None
        if fused is not None:  # the same iteration, compiled (snapjump_kernels.corrector)
            riks = None
            if target is None:
                t_z, t_u, u_0 = t
                riks = (z0, t_z, t_u, u_0, ds, self.alpha**2)
            res = fused(u, p, self.sc, tol, cfg.max_newton, target=target, riks=riks, aux=aux, tol_inc=tol_inc,
                        theta_max=cfg.theta_max)
            if res is not None:
                self.n_newton += res[1]
            return res
        u = u.copy()
        step_small = False
        inc_prev = math.inf
        for it in range(0, cfg.max_newton + 1):
            lin = self.pb.linearize(u, p) if aux is None else self.pb.linearize(u, p, aux=aux)
            if lin is None:
                return None
            R = lin.R
            z, dz_du, dz_dp = self.zeta(u, p, lin)
            if target is None:
                t_z, t_u, u_0 = t
                h = float(t_z @ (z - z0) + self.alpha**2 * (t_u @ (u - u_0)) - ds)
                c_u = t_z @ dz_du + self.alpha**2 * t_u
                c_p = float(t_z @ dz_dp)
            else:
                k, val = target
                h = float(z[k] - val)
                c_u = dz_du[k]
                c_p = float(dz_dp[k])
            ref = self.residual_scale(lin, dz_du, p)
            rn = float(np.linalg.norm(R)) / ref
            converged = it > 0 and abs(h) < tol * max(1.0, abs(ds)) and (
                rn < tol or (step_small and rn < 100.0 * tol))
            if converged and target is not None:
                self.n_newton += it
                return lin, it
            if not converged and (it == cfg.max_newton or not np.isfinite(rn)):
                return None
            solver = lin.factor(c_u, c_p)
            if solver is None:
                return None
            if converged:  # Riks: keep the factorisation for the tangent
                lin.tangent_solver = solver
                self.n_newton += it
                return lin, it
            x = solver.solve(np.concatenate([-R, [-h]]), refine=False)  # Newton corrects its error
            du, dp = x[:-1], x[-1]
            if not (np.all(np.isfinite(du)) and np.isfinite(dp)):
                return None
            dz = dz_du @ du + dz_dp * dp
            inc = math.sqrt(float(dz @ dz) + self.alpha**2 * float(du @ du))
            if it == 1 and inc_prev > 0.0:
                self.last_theta = inc / inc_prev
            if tol_inc > 0.0 and it > 0 and inc < tol_inc and inc < inc_prev:
                aux_dir = getattr(lin, "aux_dir", None) if getattr(lin, "aux", None) is not None else None
                aux_next = lin.aux + aux_dir(du) if aux_dir is not None else None
                self.n_newton += it
                return _Corrected(u + du, p + dp, solver, aux_next, aux_dir), it
            if tol_inc > 0.0 and it > 0 and inc >= tol_inc and inc > cfg.theta_max * inc_prev:
                return None  # no contraction: the caller halves the step
            inc_prev = inc
            if aux is not None:  # the mixed Newton's update of the auxiliary field
                aux = lin.aux + lin.aux_dir(du)
            u = u + du
            p = p + dp
            step_small = float(np.linalg.norm(dz)) < 1e-12
        return None

    def step(self, pt: PathPoint, ds: float, prev: PathPoint | None = None, tol: float | None = None,
             error_test: bool = False):
        """One predictor-corrector step of length ``ds`` from ``pt``; ``PathPoint`` or ``None``.

        The predictor is the tangent line, or with ``prev`` (the point before ``pt``) the cubic
        Hermite extrapolation through both points and their tangents (fewer steps than the
        quadratic through ``prev`` tangent at ``pt``: bench/profile_designs.py@51d9ff8, docs/performance.md).
        The auxiliary field, if the points carry one, is extrapolated along its tangent.
        ``error_test``: accept the state by the error test (ordinary path points), else by the
        residual test (snap states, roots).
        """
        u0 = pt.u + ds * pt.du_ds
        p0 = pt.p + ds * pt.dp_ds
        if prev is not None:
            h = pt.s - prev.s
            if h > 0:
                # the cubic q(sg) with q(0) = pt, q'(0) = h t_pt, q(-1) = prev, q'(-1) = h t_prev
                sg = ds / h
                Au = prev.u - pt.u + h * pt.du_ds
                Ap = prev.p - pt.p + h * pt.dp_ds
                Bu = h * (prev.du_ds - pt.du_ds)
                Bp = h * (prev.dp_ds - pt.dp_ds)
                u0 = u0 + (3 * Au + Bu) * sg**2 + (2 * Au + Bu) * sg**3
                p0 = p0 + (3 * Ap + Bp) * sg**2 + (2 * Ap + Bp) * sg**3
        aux0 = None
        if pt.aux is not None and self.cfg.mixed_tangent:
            aux0 = pt.aux + ds * pt.daux_ds if pt.daux_ds is not None else pt.aux
        return self._point(pt, u0, p0, aux0, ds, tol, error_test)

    def step_between(self, pt: PathPoint, end: PathPoint, ds: float | None = None, tol: float | None = None,
                     error_test: bool = False):
        """The path point at arc length ``ds`` (default: half way) from ``pt`` towards ``end``, a
        converged point of a step of length ``end.s - pt.s`` from ``pt``: predicted by the cubic
        Hermite interpolation between the two (far closer than an extrapolation), then corrected
        onto the Riks hyperplane at ``ds`` from ``pt``; ``PathPoint`` or ``None``. Used to split
        a step that turned too far, and by the root finding inside a step."""
        h = end.s - pt.s
        ds = 0.5 * h if ds is None else ds
        u0, p0, aux0 = point_between(pt, end, ds / h)
        return self._point(pt, u0, p0, aux0 if self.cfg.mixed_tangent else None, ds, tol, error_test)

    def _point(self, pt: PathPoint, u0: np.ndarray, p0: float, aux0, ds: float, tol: float | None,
               error_test: bool):
        """Correct the predicted state ``(u0, p0)`` onto the Riks hyperplane at ``ds`` from ``pt``
        and make it a ``PathPoint`` (``None`` if Newton failed)."""
        res = self.correct(u0, p0, pt.zeta, (pt.tangent, pt.du_ds, pt.u), ds, tol=tol, aux=aux0,
                           error_test=error_test)
        if res is None:
            return None
        lin, it = res
        try:
            t, v, q, z, aux, daux = self._tangent_at(lin, (pt.tangent, self.alpha * pt.du_ds))
        except ContinuationFailed:
            return None
        return PathPoint(lin.u, lin.p, z, t, v, q, pt.s + ds, it, self.last_det_sign, self.last_n_neg, aux, daux)


def _det_sign(n_neg: int, schur: float | None) -> int:
    """Sign of the determinant of a factorised bordered matrix from the inertia of ``K``
    (``n_neg`` negative pivots, -1 if unknown) and the Schur complement:
    ``det [[K, b], [c^T, d]] = det K * (d - c^T K^-1 b)``; 0 if unknown."""
    if n_neg < 0 or schur is None:
        return 0
    return (-1) ** int(n_neg) * (1 if schur > 0 else -1)


def point_between(a: PathPoint, b: PathPoint, t: float):
    """``(u, p, aux)`` at the fraction ``t`` of the step from the path point ``a`` to ``b``: the
    cubic Hermite interpolation of the state and the load, and of the auxiliary field where both
    points carry one (linear if they carry no derivative of it; ``None`` if either carries none)."""
    h = b.s - a.s
    u = hermite.interpolate(t, a.u, a.du_ds, b.u, b.du_ds, h)
    p = hermite.interpolate(t, a.p, a.dp_ds, b.p, b.dp_ds, h)
    aux = None
    if a.aux is not None and b.aux is not None:
        if a.daux_ds is not None and b.daux_ds is not None:
            aux = hermite.interpolate(t, a.aux, a.daux_ds, b.aux, b.daux_ds, h)
        else:
            aux = (1 - t) * a.aux + t * b.aux
    return u, p, aux


def start_point(tracer: Tracer, u0: np.ndarray, p0: float = 0.0, t_prev: np.ndarray | None = None,
                lin=None) -> PathPoint:
    """The first path point (a converged state, e.g. the stress-free reference), oriented along
    ``t_prev`` in measure space (default: the first measure, the cavity volume, increases).
    ``lin``: the problem's linearisation at ``(u0, p0)`` where the caller has it (not formed again)."""
    if t_prev is None:
        t_prev = np.zeros(len(tracer.sc))
        t_prev[0] = 1.0
    if lin is None:
        lin = tracer.pb.linearize(u0, p0)
    if lin is None:
        raise ContinuationFailed("the initial state lies outside the material domain")
    t, v, q, z = tracer.tangent(lin, (t_prev, np.zeros(tracer.pb.n)))
    aux = getattr(lin, "aux", None)
    daux = lin.aux_dir(v) if aux is not None else None
    return PathPoint(u0.copy(), p0, z, t, v, q, 0.0, 0, tracer.last_det_sign, tracer.last_n_neg, aux, daux)
