"""The stable state at fixed volume reached from a saddle, by the path of the energy's minima on
growing spheres around it (docs/harmonics.md section 10.7).

From an equilibrium ``c`` at the volume ``V*`` that is unstable there (the unstable landing of a
jump), the state the actuator comes to rest on lies at the end of a long curved valley of the
energy. An energy descent (:func:`snapjump_cli.fe.axisym.descent.descend_at_volume`) takes
Newton steps that the valley's curvature keeps short: hundreds of iterations. Displacement
control along the unstable mode (:func:`snapjump_cli.fe.axisym.lower_state.snap_at_fixed_volume`)
follows the valley while the mode's amplitude grows along it, and climbs where the valley turns
away from the mode. This module follows the valley by the distance from ``c`` instead, which
grows along it as long as the valley leads away from the saddle:

* unknowns ``x = (u, p)`` (the pressure the multiplier of the volume constraint) and the load
  ``F``; equations ``f_int(u) - p dV/du - F M (u - c) = 0`` and ``c_V (V(u) - V*) = 0``, with
  ``M`` the diagonal Jacobi metric ``|diag K|`` at ``c`` (mean 1), the metric of the descent;
* measures ``w = |u - c|_M`` and ``F``: the solutions at fixed ``w`` are the stationary points of
  the energy on the sphere of radius ``w`` at ``V*`` (``-F`` the multiplier of the sphere), and
  the path of their minima leaves ``c`` along the unstable mode (``F`` its eigenvalue) and comes
  to ``F = 0`` at an equilibrium, the end of the valley. Along it the energy falls
  (``dW = F w dw``, ``F < 0``);
* every zero of ``F`` is an equilibrium at ``V*``; the first that is stable under volume control
  and lies below ``c``'s energy is the state;
* where the minima on the spheres end (a fold of the path in ``w``: the valley turns away from the
  spheres), past an unstable equilibrium (``F`` turning positive) or above ``c``'s energy, the
  path gives up and the caller descends. (New paths centred where the minima turn back, started
  with the Levenberg-Marquardt step, reached a stable state on ``follow_strata_n2`` rows 3, 13
  and 23, but on rows 13 and 23 not the state that the descent and the damped motion reach;
  scratch runs.)
* the spheres lie at ``c``'s own volume: a landing state taken from a path point lies near the
  fold's volume, not at it, and the state found is brought to ``V*`` by the volume-control
  Newton and checked stable there.

This is the trust-region path of the energy at fixed volume (the Levenberg-Marquardt path in
the metric ``M``), followed by continuation (:func:`snapjump_cli.fe.continuation.trace`) on the
small problem :class:`SpherePathProblem`, with longer steps than a pressure-volume path (its
points are not an answer; its end is polished and checked).
"""
from __future__ import annotations

import logging
import math
from dataclasses import replace

import numpy as np

from snapjump_cli.fe.continuation import ContinuationFailed, PathPoint, Tracer, hermite, point_between, start_point, trace
from snapjump_cli.fe.axisym.lower_state import FixedVolumeLinearization, constrained_instability
from snapjump_cli.fe.axisym.snap import root_on_step

log = logging.getLogger(__name__)

__all__ = ["SpherePathProblem", "descend_on_spheres", "NOT_FALLING"]

#: Step growth, largest turn per step and Newton tolerance (the error test's) of the sphere path:
#: its points are not an answer (the state it ends on is polished to the residual test and checked),
#: so it steps further and is corrected less than a pressure-volume path (1.2, 10 degrees and 1e-6).
#: On ``follow_strata`` rows 0, 2, 5, 10, 23 and ``follow_strata_n2`` rows 0, 1, 4, 5 the path took
#: 18-25 steps and 33-60 Newton iterations with 1.5, 30 degrees and 1e-6, and 9-18 steps and 19-45
#: with 4, 30 degrees and 1e-4 (growth 2 or 3: a few more), on the same states (``bench.profile.follow``
#: with these constants changed, a scratch sweep of them; docs/performance.md).
SPHERE_STEP_GROW = 4.0


SPHERE_TURN_DEG = 30.0


SPHERE_TOL_PATH = 1e-4


#: The sphere path's step after a step that converged in one Newton iteration and hardly turned
#: (``ContinuationSettings.grow_easy``): the path leaves the saddle along its unstable mode with the
#: load nearly constant, and took 4-5 such steps at a growth of 4. And after a step whose Newton
#: failed, the steps that follow are kept below 0.8 of it (``fail_cap``): the steps had grown past
#: Newton's basin and been cut back in turn (``follow_strata_n2`` row 5: 5 refused steps). On the
#: 13 sphere-path rows of ``follow_strata`` and 10 of ``follow_strata_n2``: 659 -> 624 and 570 -> 515
#: assemblies of the model with every harmonic, the answers within 6e-14 (``bench.profile.follow
#: --json`` as it is and with ``--set snapjump_cli.fe.axisym.sphere_path.SPHERE_GROW_EASY=0.0 --set
#: snapjump_cli.fe.axisym.sphere_path.SPHERE_FAIL_CAP=0.0``, compared with ``bench.profile.answers``;
#: the counts of the model with every harmonic from a scratch counter).
SPHERE_GROW_EASY = 16.0


#: The sphere path's steps are also held to a first Newton contraction of about this
#: (``ContinuationSettings.theta_aim``; 0: off). The turn aim alone let the steps grow past Newton's
#: basin and be cut back in turn: on ``follow_strata_n2`` row 11 six of 21 steps tried failed, each
#: after two corrections, and the first contraction grew as ``ds^3`` (0.07 at ``ds`` 0.088, 0.57 at
#: 0.147; the corrector gives up above 0.5). On 10 jumps of ``follow_strata_n2`` (rows 0, 1, 2, 5,
#: 9, 11, 14, 16, 21, 22) the model with every harmonic took 489 assemblies without it and 440 with
#: 0.25 (row 11: 71 -> 50; rows 0, 1, 5, 11: off 220, 0.1 204, 0.15 197, 0.25 184; the other six:
#: off 269, 0.25 256, 0.35 259); on 13 sphere-path designs of ``follow_strata`` 586 and 583. The
#: same states, every answer value within 3e-13 (``bench.profile.follow --json ... --set
#: snapjump_cli.fe.axisym.sphere_path.SPHERE_THETA_AIM=0.0``, compared with ``bench.profile.answers``;
#: the assemblies are the ``assemblies`` column of those runs).
SPHERE_THETA_AIM = 0.25
SPHERE_FAIL_CAP = 0.8


#: A zero of the load ``F`` is polished at ``V*`` from the cubic Hermite interpolation of its step
#: (the state and ``F``), without first locating the zero on the path (the path's points are not
#: an answer; Newton at fixed volume lands on the same equilibrium: ``follow_strata`` rows 0, 2, 5
#: and ``follow_strata_n2`` rows 0, 2, 4, every answer value within 2.4e-9, 0-10 % less CPU; scratch
#: runs). Where the state so found is not stable and lower, the zero is located on the path and
#: polished as before.
SPHERE_ZERO_GUESS = True


#: The polish of a zero of the load takes the mixed Newton matrix, with the element pressures
#: interpolated along the step as the state is (as the path's own corrector does).
SPHERE_POLISH_MIXED = True


#: The message of :func:`descend_on_spheres` with ``falling`` where the first state's load is not
#: negative (its start: callers tell that case by it).
NOT_FALLING = "sphere path: the energy does not fall along the kick"


#: Volumes closer than this (relative) are the same: the centre's volume and ``V*`` that differ only
#: by round-off (the centre's volume evaluated anew) need no correction at the end.
SAME_VOLUME = 1e-12


#: The load's scale in the path's arc length, relative to the first state's load: large, so that
#: the arc length is the distance travelled (near the centre the load can go as ``1 / w``).
SPHERE_LOAD_SCALE = 1e6


class _SphereLinearization(FixedVolumeLinearization):
    """The sphere path's linearisation: the load acts along ``M d`` (``d = u - c``), and its
    derivative ``-F M`` shifts the stiffness."""

    def __init__(self, problem: "SpherePathProblem", x: np.ndarray, F: float, R: np.ndarray, lin, d: np.ndarray):
        super().__init__(problem, x, F, R, lin)
        self.d = d

    def direction(self) -> np.ndarray:
        return self.problem.m * self.d

    def shift(self) -> np.ndarray:
        return -self.p * self.problem.m


class SpherePathProblem:
    """Equilibria at the fixed volume ``V_star`` under the load ``F M (u - c)``: the problem
    interface of :mod:`snapjump_cli.fe.continuation` with state ``x = (u, p)`` and load ``F``;
    the measures are ``(|u - c|_M, F)``.

    Parameters
    ----------
    model : the FE model (its ``linearize`` factorises with a diagonal ``shift``)
    V_star : the volume (scaled, as ``Linearization.V``)
    centre : ``c``, the sphere's centre (length ``model.n``)
    m : the diagonal of the metric ``M`` (length ``model.n``, positive)
    c_V : weight of the volume equation (force / volume)
    p_floor : floor of the pressure in the residual reference
    """

    #: no other control than the cavity volume (:class:`FixedVolumeLinearization` reads it)
    control = None

    def __init__(self, model, V_star: float, centre: np.ndarray, m: np.ndarray, c_V: float, p_floor: float) -> None:
        self.model, self.V_star, self.c_V, self.p_floor = model, V_star, c_V, p_floor
        self.centre = np.ascontiguousarray(centre, dtype=float)
        self.m = np.ascontiguousarray(m, dtype=float)
        self.n = model.n + 1

    def linearize(self, x: np.ndarray, F: float, stiffness: bool = True, aux: np.ndarray | None = None):
        lin = self.model.linearize(x[:-1], float(x[-1]), stiffness, aux=aux)
        if lin is None:
            return None
        d = x[:-1] - self.centre
        R = np.empty(self.n)
        R[:-1] = lin.R - F * self.m * d
        R[-1] = self.c_V * (lin.V - self.V_star)
        return _SphereLinearization(self, x, F, R, lin, d)

    def measures(self, x: np.ndarray, F: float, lin=None):
        """``zeta = (|u - c|_M, F)`` and their derivatives."""
        d = x[:-1] - self.centre
        w = math.sqrt(float(d @ (self.m * d)))
        dz = np.zeros((2, self.n))
        if w > 0.0:
            dz[0, :-1] = self.m * d / w
        return np.array([w, F]), dz, np.array([0.0, 1.0])

    def residual_ref(self, lin) -> float:
        """The residual scale of the pressure-volume trace: ``|dV/du| max(|p|, p_floor)``."""
        return float(np.linalg.norm(lin.lin.g)) * max(abs(float(lin.u[-1])), self.p_floor)


def descend_on_spheres(tracer: Tracer, upper: PathPoint, centre: PathPoint, kick: np.ndarray,
                       max_steps: int = 400, max_zeros: int = 6, climb: float | None = None,
                       falling: bool = False) -> tuple[PathPoint | None, str]:
    """The stable state at the volume of ``upper`` reached from the saddle ``centre`` along ``kick``.

    Parameters
    ----------
    tracer : the tracer of the pressure-volume problem (its problem is the FE model)
    upper : the state before the jump: its volume is ``V*``; its tangent orients the result's
    centre : an equilibrium at (or near) ``V*`` that is unstable there (the state the jump lands on)
    kick : the first displacement from ``centre`` (a small multiple of its unstable mode)
    max_steps : continuation steps
    max_zeros : zeros of ``F`` examined before giving up
    climb : how far (scaled energy) the path may rise above the centre's energy before it gives up
        (default ``1e-9 max(1, |W_c|)``: round-off). From a nearly degenerate saddle, a barely
        subcritical bifurcation, the path can rise above it and come down to the state the branch
        comes back to (docs/harmonics.md section 10.7)
    falling : give up at once where the load ``F`` of the first state is not negative (the energy
        does not fall from the centre along the kick: at a bifurcation, a branch that is not
        subcritical)

    Returns
    -------
    (PathPoint or None, message)
        The state as a point of the pressure-volume problem, or ``None`` with the reason (the
        caller falls back on the energy descent).
    """
    model = tracer.pb
    cfg = tracer.cfg
    sV, sp, sw = (float(s) for s in tracer.sc)
    lin_c = model.linearize(centre.u, centre.p)
    if lin_c is None:
        return None, "sphere path: the centre lies outside the material domain"
    # the spheres lie at the centre's own volume (a landing state taken from a path point lies near
    # V*, not at it); the state found there is then brought to V* by Newton at fixed volume
    V_c = float(lin_c.V)
    W_c = lin_c.E
    p_floor = 1e-3 * sp
    ref = float(np.linalg.norm(lin_c.g)) * max(abs(float(lin_c.p)), p_floor)
    m = lin_c.diag_abs()
    m = m / float(m.mean())
    s_w = math.sqrt(model.n) * sw
    c, p_c = centre.u.copy(), float(centre.p)
    pb = SpherePathProblem(model, V_c, c, m, ref / sV, p_floor)
    first = _first_state(pb, replace(cfg, max_steps=min(cfg.max_steps, int(max_steps))), s_w,
                         _kicks(model, c, p_c, m, np.asarray(kick, float)))
    if first is None:
        return None, "sphere path: no first state"
    ftr, lin_s = first
    if falling and not lin_s.p < 0.0:
        return None, f"{NOT_FALLING} (first state F {lin_s.p:.3g})"
    climb = 1e-9 * max(1.0, abs(W_c)) if climb is None else float(climb)
    found, (why, n_steps) = _follow(tracer, ftr, pb, lin_s, W_c, V_c / sV, max_zeros, climb)
    log.debug("sphere path: %s after %d steps (first state w %.3g, F %.3g)", why, n_steps,
              float(pb.measures(lin_s.u, lin_s.p)[0][0]), lin_s.p)
    if found is None:
        return None, f"sphere path: {why} after {n_steps} steps"
    lin, it = found
    if abs(V_c - float(upper.zeta[0]) * sV) > SAME_VOLUME * abs(V_c):
        res = tracer.correct(lin.u.copy(), float(lin.p), None, None, 0.0, target=(0, float(upper.zeta[0])),
                             aux=getattr(lin, "aux", None) if SPHERE_POLISH_MIXED else None)
        if res is None or constrained_instability(tracer, res[0]) != 0 or not res[0].E < model.energy(upper.u):
            return None, f"sphere path: the stable state at the centre's volume does not reach V* ({n_steps} steps)"
        lin, it = res[0], it + res[1]
    t, v, q, z = tracer.tangent(lin, (upper.tangent, tracer.alpha * upper.du_ds))
    return (PathPoint(lin.u, lin.p, z, t, v, q, math.nan, it),
            f"sphere path: stable state in {n_steps} steps ({ftr.n_newton} Newton iterations)")


def _zero_guess(a: PathPoint, b: PathPoint) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The state where the load ``F`` vanishes on the step from ``a`` to ``b`` (opposite signs), by
    the cubic Hermite interpolation of the step (``F`` and the state alike), with the points'
    auxiliary field (the element pressures) there (:func:`~snapjump_cli.fe.continuation.point_between`);
    ``(None, None)`` if the cubic of ``F`` has no root inside the step."""
    h = b.s - a.s
    t = hermite.first_root(a.p, a.dp_ds * h, b.p, b.dp_ds * h) if h > 0.0 else None
    if t is None:
        return None, None
    u, _, aux = point_between(a, b, t)
    return u, aux


def _kicks(model, c: np.ndarray, p_c: float, m: np.ndarray, kick: np.ndarray):
    """First-state guesses of the path from the saddle: ``c + kick`` (then 1/10 of it, 3 times) with
    the load ``F = d^T R / d^T M d`` there (the Rayleigh quotient of the unstable mode)."""
    d0 = kick
    for _ in range(4):
        R = model.residual(c + d0, p_c)  # (the residual alone: the tangent is not needed here)
        if R is not None:
            yield d0, p_c, float(d0 @ R) / float(d0 @ (m * d0))
        d0 = 0.1 * d0


def _first_state(pb: SpherePathProblem, cfg, s_w: float, starts):
    """The first state of the path: Newton on the sphere through the first of ``starts`` (guesses
    ``(d, p, F)`` of the state ``c + d``) from which it converges. Returns ``(tracer,
    linearisation)`` or ``None``; the path's first step is the sphere's radius."""
    m, c = pb.m, pb.centre
    for d0, p0, F0 in starts:
        w0 = math.sqrt(float(d0 @ (m * d0)))
        if not (w0 > 0.0 and math.isfinite(F0)):
            continue
        fcfg = replace(cfg, scales=(s_w, SPHERE_LOAD_SCALE * max(abs(F0), 1e-300)), step_grow=SPHERE_STEP_GROW,
                       max_turn_deg=SPHERE_TURN_DEG, tol_path=SPHERE_TOL_PATH, ds0=min(cfg.ds0, w0 / s_w),
                       fail_cap=SPHERE_FAIL_CAP, grow_easy=SPHERE_GROW_EASY, theta_aim=SPHERE_THETA_AIM)
        ftr = Tracer(pb, fcfg)
        res = ftr.correct(np.concatenate([c + d0, [p0]]), F0, None, None, 0.0, target=(0, w0 / s_w))
        if res is not None:
            return ftr, res[0]
    return None


def _follow(tracer: Tracer, ftr: Tracer, pb: SpherePathProblem, lin_s, W_c: float, V_target: float, max_zeros: int,
            climb: float):
    """Follow the path from its first state ``lin_s``. Returns ``(found, (reason, steps))``:
    ``found`` ``(linearisation, iterations)`` of the stable state (``None``: none)."""
    model = tracer.pb
    s_F = float(ftr.sc[1])
    state: dict = {"zeros": 0, "found": None}

    def stop(path) -> str | None:
        pts = path.points
        a, b = pts[-2], pts[-1]
        if not model.energy(b.u[:-1]) <= W_c + climb:
            return "climbed above the saddle's energy"
        if b.zeta[0] < a.zeta[0]:
            return "turned back"
        if not (a.p * b.p < 0.0 or (b.p == 0.0 and a.p != 0.0)):
            return None
        state["zeros"] += 1
        guess, aux = _zero_guess(a, b) if SPHERE_ZERO_GUESS else (None, None)
        if guess is not None:  # polished at V* from the step's interpolation: the root is not located first
            res = tracer.correct(guess[:-1].copy(), float(guess[-1]), None, None, 0.0, target=(0, V_target),
                                 aux=aux if SPHERE_POLISH_MIXED else None)
            if res is not None and constrained_instability(tracer, res[0]) == 0 and res[0].E < W_c:
                log.debug("sphere path: F = 0 at w = %.6g, polished from the step's interpolation", a.zeta[0])
                state["found"] = res
                return "stable state at V*"
        root = root_on_step(ftr, a, b, pts[-3] if len(pts) > 2 else None, lambda pt: pt.p, 1e-8 * s_F, 40)
        res = tracer.correct(root.u[:-1].copy(), float(root.u[-1]), None, None, 0.0, target=(0, V_target),
                             aux=root.aux if SPHERE_POLISH_MIXED else None)
        if res is not None:
            lin, it = res
            n_unstable = constrained_instability(tracer, lin)
            log.debug("sphere path: F = 0 at w = %.6g (%d unstable, W %.10g vs %.10g)", a.zeta[0], n_unstable,
                      lin.E, W_c)
            if n_unstable == 0 and lin.E < W_c:
                state["found"] = (lin, it)
                return "stable state at V*"
        if b.p > 0.0:  # beyond an unstable equilibrium the path leaves the valley (the energy rises)
            return "passed an unstable equilibrium"
        if state["zeros"] >= max_zeros:
            return "no stable state among the zeros of the load"
        return None

    try:
        start = start_point(ftr, lin_s.u, lin_s.p, t_prev=np.array([1.0, 0.0]), lin=lin_s)
        path = trace(pb, ftr.cfg, stop, u0=lin_s.u, tracer=ftr, start=start)
    except ContinuationFailed as exc:
        return None, (f"failed ({exc})", 0)
    return state["found"], (path.stop_reason, len(path.points) - 1)
