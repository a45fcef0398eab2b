"""The post-snap (lower) state at fixed cavity volume, by displacement control of the snap.

When the traced pressure-volume path does not come back to ``V*`` (or comes back on an unstable
branch), the lower state is the stable equilibrium that the isochoric snap reaches from the upper
state. :func:`snap_at_fixed_volume` finds it by following the equilibria at ``V = V*`` under a
generalised force ``F`` along a control direction ``e``, parameterised by arc length in
(``w = e . u``, ``F``). The control is first the pole (``e`` a unit vector on the pole's vertical
dof: a point force; the inner cap's inversion moves the pole one way all along), then, if that
path turns back, the fold's mode itself (``e`` the unit path tangent ``du/ds`` at the volume
limit: design A on meshes fine along the arc needs it):

* unknowns ``x = (u, p)`` (displacements and the cavity pressure, now the Lagrange multiplier of
  the volume constraint) and the load ``F``;
* equations ``f_int(u) - p dV/du - F e = 0`` and ``c_V (V(u) - V*) = 0`` (``c_V`` a constant that
  puts the volume equation in force units);
* the path starts at the upper state (``F = 0``: the fold in volume is an equilibrium with a zero
  eigenvalue of the volume-constrained stiffness along the fold's mode, so ``dF/dw = 0`` there)
  and leaves it the way the pressure-volume path continues (the energy falls that way);
* every zero of ``F`` along it is an equilibrium at ``V*``: the first one that is stable under
  volume control (inertia of the bordered ``LDL^T``) and lies below the upper state's energy is
  the lower state. It is polished by the same volume-control Newton as a lower state on the path.
  A path that climbs above the upper state's energy (it went the way the snap does not) is given
  up at once: the caller falls back on the energy descent.

This is the classical displacement control of a snap-through, at fixed volume: the path of
constrained equilibria is smooth where the energy landscape is a long curved valley, so it is
followed in tens of steps where an energy descent (:func:`snapjump_cli.metrics.descend_at_volume`,
kept as the fallback) needs hundreds of iterations. The continuation is the ordinary one
(:func:`snapjump_cli.continuation.trace`) on the small problem :class:`FixedVolumeProblem`.
"""
from __future__ import annotations

import logging
import math
from dataclasses import replace

import numpy as np

from snapjump_cli.continuation import ContinuationFailed, PathPoint, Tracer, start_point, trace
from snapjump_kernels.banded import band_ldlt_solve, sym_band_matvec

log = logging.getLogger(__name__)

__all__ = ["FixedVolumeProblem", "snap_at_fixed_volume"]


class _MultiBorderedSolver:
    """Solves ``[[K, B], [C^T, D]] [x; y] = [r; s]`` (``B``, ``C``: n x m, ``D``: m x m) by block
    elimination with the band ``LDL^T`` of ``K`` and one step of iterative refinement."""

    def __init__(self, base, B: np.ndarray, C: np.ndarray, D: np.ndarray):
        self.base, self.B, self.C, self.D = base, B, C, D
        self._solve_K = lambda r: band_ldlt_solve(base.fac, r, base.ext)
        KiB = np.empty_like(B)
        KiB[:, 0] = base.Kib  # K^-1 b_0, from the factorisation
        for k in range(1, B.shape[1]):
            KiB[:, k] = self._solve_K(np.ascontiguousarray(B[:, k]))
        self.KiB = KiB
        self.S = D - C.T @ KiB
        self.n_negative = -1  # the inertia of the whole matrix is not tracked (no det sign)

    def _once(self, r, s):
        z = self._solve_K(r)
        y = np.linalg.solve(self.S, s - self.C.T @ z)
        return z - self.KiB @ y, y

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        m = self.B.shape[1]
        r, s = rhs[:-m], rhs[-m:]
        x, y = self._once(r, s)
        top = sym_band_matvec(self.base.K, x, self.base.ext) + self.B @ y
        bot = self.C.T @ x + self.D @ y
        dx, dy = self._once(r - top, s - bot)
        return np.concatenate([x + dx, y + dy])


class _FixedVolumeLinearization:
    def __init__(self, problem: "FixedVolumeProblem", x, F, R, lin):
        self.problem, self.u, self.p, self.R, self.lin = problem, x, F, R, lin

    def factor(self, c_x: np.ndarray, c_F: float):
        """Factorise ``[[K, -g, -e_w], [c_V g^T, 0, 0], [c_u^T, c_p, c_F]]``; ``None`` if singular."""
        pb, lin = self.problem, self.lin
        n = pb.model.n
        e = pb.e
        base = lin.factor(pb.c_V * lin.g, 0.0)
        if base is None or getattr(base, "kind", "") != "banded":
            return None
        B = np.stack([-lin.g, -e], axis=1)
        C = np.stack([pb.c_V * lin.g, c_x[:n]], axis=1)
        D = np.array([[0.0, 0.0], [float(c_x[n]), float(c_F)]])
        s = _MultiBorderedSolver(base, B, C, D)
        if not np.all(np.isfinite(s.S)) or abs(np.linalg.det(s.S)) == 0.0:
            return None
        return s


class FixedVolumeProblem:
    """Equilibria at the fixed cavity volume ``V_star`` under a generalised force ``F`` along
    ``e``: the problem interface of :mod:`snapjump_cli.continuation` with state ``x = (u, p)`` and
    load ``F``; the measures are ``(e . u, F)``.

    Parameters
    ----------
    model : the FE model (:class:`snapjump_cli.model.Model`)
    V_star : the volume (scaled, as ``Linearization.V``)
    e : the controlled direction (length ``model.n``; a unit vector on one dof is a point force)
    c_V : weight of the volume equation (force / volume)
    p_floor : floor of the pressure in the residual reference (as in the pressure-volume trace)
    """

    def __init__(self, model, V_star: float, e: np.ndarray, c_V: float, p_floor: float) -> None:
        self.model, self.V_star, self.c_V, self.p_floor = model, V_star, c_V, p_floor
        self.e = np.ascontiguousarray(e, dtype=float)
        self.n = model.n + 1

    def linearize(self, x: np.ndarray, F: float, stiffness: bool = True):
        lin = self.model.linearize(x[:-1], float(x[-1]), stiffness)
        if lin is None:
            return None
        R = np.empty(self.n)
        R[:-1] = lin.R - F * self.e
        R[-1] = self.c_V * (lin.V - self.V_star)
        return _FixedVolumeLinearization(self, x, F, R, lin)

    def measures(self, x: np.ndarray, F: float, lin=None):
        """``zeta = (e . u, F)`` and their derivatives."""
        dz = np.zeros((2, self.n))
        dz[0, :-1] = self.e
        return np.array([float(self.e @ x[:-1]), F]), dz, np.array([0.0, 1.0])

    def residual_ref(self, lin) -> float:
        """The residual scale of the pressure-volume trace: ``|dV/du| max(|p|, p_floor)``."""
        return float(np.linalg.norm(lin.lin.g)) * max(abs(float(lin.u[-1])), self.p_floor)


def snap_at_fixed_volume(tracer: Tracer, upper: PathPoint, max_steps: int = 400, max_zeros: int = 6
                         ) -> tuple[PathPoint | None, str]:
    """The stable state at ``V*`` reached from the upper state (see the module docstring).

    Parameters
    ----------
    tracer : the tracer of the pressure-volume path (its problem is the FE model)
    upper : the upper state (the first volume limit point)
    max_steps : continuation steps of one fixed-volume path
    max_zeros : zeros of ``F`` examined on one path before giving up

    Returns
    -------
    (PathPoint or None, message)
        The lower state as a point of the pressure-volume problem (its tangent in that problem),
        or ``None`` with the reason (the caller falls back on the energy descent).
    """
    model = tracer.pb
    cfg = tracer.cfg
    sV, sp, sw = (float(s) for s in tracer.sc)
    lin_up = model.linearize(upper.u, upper.p)
    if lin_up is None:
        return None, "upper state outside the material domain"
    V_star = lin_up.V
    W_up = lin_up.E
    p_floor = 1e-3 * sp
    ref_up = float(np.linalg.norm(lin_up.g)) * max(abs(upper.p), p_floor)
    x0 = np.concatenate([upper.u, [upper.p]])
    # controls, in turn: the pole (the inner cap's inversion moves it one way all along), then the
    # fold's mode itself, both ways (where the pole's path turns back)
    pole = model.pole_dof
    e_pole = np.zeros(model.n)
    e_pole[pole] = 1.0
    nrm = float(np.linalg.norm(upper.du_ds))
    attempts = []
    if upper.du_ds[pole] != 0.0:
        attempts.append(("pole", e_pole, float(np.sign(upper.du_ds[pole])), sw))
    if nrm > 0.0:
        attempts += [("mode", upper.du_ds / nrm, d, math.sqrt(model.n) * sw) for d in (1.0, -1.0)]
    msgs = []
    for name, e, direction, s_w in attempts:
        pb = FixedVolumeProblem(model, V_star, e, c_V=ref_up / sV, p_floor=p_floor)
        fcfg = replace(cfg, scales=(s_w, sp * sV / s_w), max_steps=max_steps)  # force = p V / length
        found, msg, n_steps, n_newton = _follow(tracer, pb, fcfg, x0, direction, W_up, V_star / sV,
                                                1e-3 * cfg.tol * ref_up, max_zeros)
        if found is not None:
            lin, it = found
            t, v, q, z = tracer.tangent(lin, (upper.tangent, tracer.alpha * upper.du_ds))
            return (PathPoint(lin.u, lin.p, z, t, v, q, math.nan, it),
                    f"fixed-volume path ({name} control): stable state in {n_steps} steps ({n_newton} Newton iterations)")
        msgs.append(f"{name} {'+' if direction > 0 else '-'}: {msg} after {n_steps} steps")
    return None, "fixed-volume path: " + "; ".join(msgs)


def _follow(tracer: Tracer, pb: FixedVolumeProblem, fcfg, x0: np.ndarray, direction: float, W_up: float,
            V_target: float, F_tol: float, max_zeros: int):
    """Follow the fixed-volume path from ``x0`` along ``direction * e``; returns
    ``((linearisation, iterations) or None, message, steps, Newton iterations)``."""
    from snapjump_cli.metrics import root_on_step, constrained_instability

    model = tracer.pb
    ftr = Tracer(pb, fcfg)
    state = {"zeros": 0, "found": None}

    def stop(path) -> str | None:
        pts = path.points
        a, b = pts[-2], pts[-1]
        if not model.energy(b.u[:-1]) <= W_up + 1e-9 * max(1.0, abs(W_up)):
            return "climbed above the upper state's energy"
        if not (a.p * b.p < 0.0 or (b.p == 0.0 and a.p != 0.0)):
            return None
        state["zeros"] += 1
        root = root_on_step(ftr, a, b, pts[-3] if len(pts) > 2 else None, lambda pt: pt.p, F_tol, 40)
        res = tracer.correct(root.u[:-1].copy(), float(root.u[-1]), None, None, 0.0, target=(0, V_target))
        if res is not None:
            lin, it = res
            n_unstable = constrained_instability(tracer, lin)
            below = lin.E < W_up - 1e-12 * max(1.0, abs(W_up))
            log.debug("fixed-volume path: F = 0 at w = %.6g (%d unstable, W %.6g vs upper %.6g)",
                      float(pb.e @ lin.u), n_unstable, lin.E, W_up)
            if n_unstable == 0 and below:
                state["found"] = (lin, it)
                return "stable state at V*"
        if state["zeros"] >= max_zeros:
            return "no stable state among the zeros of the force"
        return None

    try:
        start = start_point(ftr, x0, 0.0, t_prev=np.array([direction, 0.0]))
        path = trace(pb, fcfg, stop, u0=x0, tracer=ftr, start=start)
    except ContinuationFailed as exc:
        return None, f"failed ({exc})", 0, ftr.n_newton
    return state["found"], path.stop_reason, len(path.points) - 1, ftr.n_newton
