"""Arc-length continuation (modified Riks) over a small problem interface.

The continuation sees only (see :mod:`snapjump_cli.fe.axisym.model`): ``n``, ``residual(u, p)``,
``measures(u, p)`` and ``factor_bordered(u, p, c_u, c_p)``. The arc length is measured in the
space of scaled path measures ``zeta = (V / s_V, p / s_p, w / s_w)`` (cavity volume, pressure,
pole displacement), so a step means the same thing for every design and neither u nor p
dominates it, plus (``u_scale > 0``) the RMS displacement ``|u| / (sqrt(n) u_scale)``, which keeps
the path smooth where all three measures are momentarily stationary (sharp corners in the
measure space would otherwise force tiny steps). Each step is a Riks step: the corrector stays on the hyperplane orthogonal to the
unit tangent ``t`` at the previous point, ``t . (zeta - zeta_0) = ds``, solved together with the
equilibrium equations as one bordered system ``[[K_T, dR/dp], [c_u^T, c_p]]``, which stays
regular at limit points in pressure and in volume. The tangent at a converged point solves the
same system with right-hand side ``[0, 1]``; its orientation follows the previous tangent
automatically (``t_prev . t_new > 0``).

Path points are accepted by an error test (the Newton correction at the iterate, in the
arc-length metric, below ``tol_path``), their tangent solved with the same factorisation; the
snap states and limit points by the residual test (``tol``). A problem may also carry an
auxiliary field along the path (``aux``: the element pressures of the mixed element), which the
predictor extrapolates and the problem's Newton uses in its tangent (docs/numerics.md).

Bifurcations: the sign of the bordered Jacobian's determinant (from the LDL^T inertia and the
Schur complement) flips at a simple bifurcation point but not at limit points; a step that
crosses one is redone with a short step so that the corrector stays on the branch it follows,
and the crossing is counted.

Step control: the step grows when Newton converges fast and the tangent turns little, and is cut
back (halved, then retried) on a failed corrector, a Gent-domain violation or a tangent that
turns by more than ``max_turn_deg`` (which would skip small folds; docs/physics.md, pitfall b).
"""
from __future__ import annotations

import logging
import math
from typing import Callable

import numpy as np

from snapjump_cli.fe.continuation.path import ContinuationFailed, ContinuationSettings, Path, PathPoint, Problem
from snapjump_cli.fe.continuation.tracer import Tracer, start_point

log = logging.getLogger(__name__)

__all__ = ["Problem", "PathPoint", "Path", "ContinuationFailed", "ContinuationSettings", "trace", "Tracer"]

#: Step control after an accepted step: the next step is ``STEP_GROW`` times longer (the default
#: of ``ContinuationSettings.step_grow``) when Newton
#: took at most ``n_opt`` iterations, ``STEP_KEEP`` times up to ``n_opt + 2`` and ``STEP_SHRINK``
#: times beyond; the growth is capped so that the next step turns by about ``TURN_AIM`` of
#: ``max_turn_deg``, and never falls below ``STEP_FACTOR_MIN``. A rejected step is cut by
#: ``STEP_CUT`` and tried again.
STEP_GROW = ContinuationSettings.step_grow
STEP_KEEP = 1.0
STEP_SHRINK = 0.6
TURN_AIM = 0.5
STEP_FACTOR_MIN = 0.5
STEP_CUT = 0.5



def step_turn(a: PathPoint, b: PathPoint, alpha: float = 0.0) -> float:
    """How far a step from ``a`` to ``b`` turns, degrees: the larger of :func:`turn_angle` and
    :func:`chord_angle` (what ``max_turn_deg`` limits)."""
    return max(turn_angle(a, b, alpha), chord_angle(a, b, alpha))


def _split(tr: Tracer, a: PathPoint, b: PathPoint) -> PathPoint | None:
    """The point half way along a step from ``a`` to ``b`` that turned more than ``max_turn_deg``,
    if each half turns less and neither half crosses a bifurcation (else ``None``: the step is
    rejected). Sets ``b.s`` to its arc length from the half-way point, as a step from there measures
    it (the projection on that point's tangent)."""
    cfg = tr.cfg
    mid = tr.step_between(a, b, tol=cfg.tol_path, error_test=cfg.error_test)
    if mid is None or a.det_sign * mid.det_sign < 0 or mid.det_sign * b.det_sign < 0:
        return None
    if step_turn(a, mid, tr.alpha) > cfg.max_turn_deg or step_turn(mid, b, tr.alpha) > cfg.max_turn_deg:
        return None
    h = float(mid.tangent @ (b.zeta - mid.zeta)) + tr.alpha**2 * float(mid.du_ds @ (b.u - mid.u))
    if not h > 0.0:
        return None
    b.s = mid.s + h
    return mid


def turn_angle(a: PathPoint, b: PathPoint, alpha: float = 0.0) -> float:
    """Angle between the unit tangents of two path points (measure and weighted u parts), degrees."""
    c = float(a.tangent @ b.tangent) + alpha * alpha * float(a.du_ds @ b.du_ds)
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


def chord_angle(a: PathPoint, b: PathPoint, alpha: float = 0.0) -> float:
    """Largest angle between the chord from ``a`` to ``b`` and either end tangent, degrees.

    Equal end tangents do not prove a smooth step: a small fold can lie entirely inside it, and
    then the chord points elsewhere (docs/physics.md, pitfall b)."""
    dz = b.zeta - a.zeta
    du = alpha * (b.u - a.u)
    n = math.sqrt(float(dz @ dz) + float(du @ du))
    if n == 0.0:
        return 0.0
    out = 0.0
    for t in (a, b):
        c = (float(dz @ t.tangent) + alpha * float(du @ t.du_ds)) / n
        out = max(out, math.degrees(math.acos(max(-1.0, min(1.0, c)))))
    return out


def _accept(path: Path, point: PathPoint, tracer: Tracer, stop: Callable[[Path], str | None]) -> bool:
    """Append an accepted point to ``path``; True if ``stop`` ends the trace (reason recorded)."""
    path.points.append(point)
    path.n_newton = tracer.n_newton
    reason = stop(path)
    if reason:
        path.stop_reason = reason
    return bool(reason)


def trace(
    problem: Problem,
    settings: ContinuationSettings,
    stop: Callable[[Path], str | None],
    u0: np.ndarray | None = None,
    tracer: Tracer | None = None,
    start: PathPoint | None = None,
) -> Path:
    """Trace the equilibrium path from the stress-free state until ``stop(path)`` returns a reason.

    Parameters
    ----------
    problem : the problem interface
    settings : continuation settings (scaled units)
    stop : called after every accepted step; a non-empty string ends the trace (the reason)
    u0 : initial displacement (default zeros)
    start : the first path point (default :func:`start_point` at ``u0``, ``p = 0``)

    Raises
    ------
    ContinuationFailed
        if the step had to be cut below ``ds_min`` (the message names the cause and state)
    """
    cfg = settings
    tr = tracer or Tracer(problem, settings)
    if u0 is None:
        u0 = np.zeros(problem.n)
    path = Path()
    path.points.append(start if start is not None else start_point(tr, u0))
    ds = cfg.ds0
    ds_cap = math.inf  # the bound on the step after a failed corrector (cfg.fail_cap)
    while True:
        if len(path.points) > cfg.max_steps:
            path.stop_reason = "max_steps"
            break
        pt = path.points[-1]
        prev = path.points[-2] if (cfg.hermite_predictor and len(path.points) > 1) else None
        new = tr.step(pt, ds, prev, tol=cfg.tol_path, error_test=cfg.error_test)
        if new is not None:
            ang = step_turn(pt, new, tr.alpha)
            crossed = pt.det_sign * new.det_sign < 0  # a bifurcation point lies inside the step
            if ang > cfg.max_turn_deg and ds > 4 * cfg.ds_min and not crossed and cfg.split_steps:
                # keep the converged end point if the step's two halves each turn little enough
                mid = _split(tr, pt, new)
                if mid is not None:
                    path.n_split += 1
                    if _accept(path, mid, tr, stop):
                        break
                    pt, ds = mid, new.s - mid.s
                    ang = step_turn(pt, new, tr.alpha)
            if ang > cfg.max_turn_deg and ds > 4 * cfg.ds_min:
                new = None
                cause = f"tangent or chord turned {ang:.1f} deg"
            elif crossed and ds > cfg.ds_bifurcation:
                # cross a bifurcation with a short step so that the corrector stays on this branch
                new = None
                cause = "bifurcation inside the step"
                ds = 2.0 * max(cfg.ds_bifurcation, ds / 8.0)
            else:
                if crossed:
                    path.n_bifurcations += 1
                if _accept(path, new, tr, stop):
                    break
                # Newton's iteration count hardly depends on the step while the predictor is in
                # its basin: grow while it converges in <= n_opt iterations, shrink beyond
                its = max(new.newton, 1)
                grow = cfg.step_grow if its <= cfg.n_opt else (STEP_KEEP if its <= cfg.n_opt + 2 else STEP_SHRINK)
                if cfg.grow_easy > 0.0 and its == 1 and ang < 0.1 * cfg.max_turn_deg:
                    grow = cfg.grow_easy
                if ang > 0:
                    grow = min(grow, TURN_AIM * cfg.max_turn_deg / ang)
                if cfg.theta_aim > 0.0 and tr.last_theta:
                    grow = min(grow, (cfg.theta_aim / tr.last_theta) ** (1.0 / 3.0))
                ds_done = ds
                ds = min(cfg.ds_max, ds * max(STEP_FACTOR_MIN, grow))
                if cfg.fail_cap > 0.0:  # not past a step that failed, but not below the one just taken
                    ds = min(ds, max(ds_cap, ds_done))
                    ds_cap *= cfg.step_grow
                continue
        else:
            cause = "corrector did not converge"
            if cfg.fail_cap > 0.0:
                ds_cap = cfg.fail_cap * ds
        path.n_rejected += 1
        theta = tr.last_theta if new is None else None
        if cfg.theta_aim > 0.0 and theta is not None and theta > cfg.theta_max:  # given up for its contraction
            ds *= min(0.8, max(0.25, (cfg.theta_aim / theta) ** (1.0 / 3.0)))
        else:
            ds *= STEP_CUT
        log.debug("step rejected (%s); ds -> %.3g", cause, ds)
        if ds < cfg.ds_min:
            z = pt.zeta * tr.sc
            path.n_newton = tr.n_newton
            path.stop_reason = "continuation failed"
            exc = ContinuationFailed(
                f"step cut below ds_min={cfg.ds_min:g} ({cause}) at V={z[0]:.6g}, p={z[1]:.6g} (scaled), "
                f"after {len(path.points) - 1} steps"
            )
            exc.path = path  # the partial path, for the caller's fallbacks
            raise exc
    path.n_newton = tr.n_newton
    return path
