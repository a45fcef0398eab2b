"""The lower state by energy descent at fixed volume (the fallback of :mod:`snapjump_cli.fe.axisym.lower_state`
when the fixed-volume path does not reach it): a shifted, volume-constrained Newton iteration from
the upper state (or a post-snap path point) that restores ``V*`` gradually and goes downhill in
every mode until the state is stable at fixed volume."""
from __future__ import annotations

import logging
import math

import numpy as np

from snapjump_cli.fe.continuation import PathPoint, Tracer

log = logging.getLogger(__name__)

__all__ = ["descend_at_volume", "descent_starts", "constrained_negatives", "UNCONVERGED"]


def constrained_negatives(solver, g: np.ndarray, c: float = 0.0) -> int:
    """Negative eigenvalues of ``K`` restricted to ``g^T du = 0`` (with a compliance ``c > 0``:
    of ``K + g g^T / c``) from a bordered solver's ``LDL^T`` (Haynsworth); -1 if the inertia is
    not available."""
    if solver is None or getattr(solver, "n_negative", -1) < 0:
        return -1
    gKg = -float(g @ solver.Kib)  # Kib = K^-1 (-g)
    return int(solver.n_negative - (1 if c + gKg < 0 else 0))


#: The energy descent at fixed volume (:func:`descend_at_volume`): the largest volume change per
#: iteration while ``V*`` is restored, ``max(DESCENT_DH_ABS, DESCENT_DH_REL |V*|)`` (scaled units);
#: the diagonal shift (relative to ``|diag K|``) grows by ``DESCENT_SHIFT_GROW`` after a rejected
#: trial step or while the shifted system is not positive definite, up to ``DESCENT_SHIFT_MAX``,
#: and shrinks by ``DESCENT_SHIFT_SHRINK`` after an accepted one; below ``DESCENT_SHIFT_NEWTON``
#: (and without an unstable mode) the step is Newton's; ``DESCENT_STALL`` iterations without an
#: energy change at round-off end the descent.
DESCENT_DH_ABS = 0.05


DESCENT_DH_REL = 0.01


DESCENT_SHIFT_GROW = 8.0


DESCENT_SHIFT_SHRINK = 0.25


DESCENT_SHIFT_MAX = 1e6


DESCENT_SHIFT_NEWTON = 1e-10


DESCENT_STALL = 20


#: The start of :func:`descend_at_volume`'s message when it runs out of iterations.
UNCONVERGED = "descent did not converge"


def descend_at_volume(
    tracer: Tracer, upper: PathPoint, kick: float = 0.2, max_iter: int = 2000, tol: float | None = None,
    start: PathPoint | None = None, control: Tracer | None = None,
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
    With ``control`` (a gas in series, :func:`find_lower_state`) the constraint is its first
    measure ``V + e(p) = V_d*`` (the bordered row gains the compliance ``c = e'(p)``) and the merit
    is ``W + G(p) - p (V + e(p) - V_d*)``, whose stationary points are the equilibria at ``V_d*``.

    Returns
    -------
    (PathPoint or None, message)
    """
    cfg = tracer.cfg
    tol = cfg.tol if tol is None else tol
    V_star = upper.zeta[0]
    ctl = control or tracer
    if control is not None:
        V_star = float(control.zeta(upper.u, upper.p)[0][0])
    pb = tracer.pb
    if start is not None:
        u, p = start.u.copy(), start.p
    else:
        u = upper.u + kick * upper.du_ds
        p = upper.p + kick * upper.dp_ds
    sigma_rel = 1.0
    dh_max = max(DESCENT_DH_ABS, DESCENT_DH_REL * abs(V_star))  # largest volume change per iteration while restoring V*
    step_small = False
    E_hist: list[float] = []  # energy of the accepted iterates
    n_stall = DESCENT_STALL
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
            z, dz_du, dz_dp = ctl.zeta(u, p, lin)
            h = float(z[0] - V_star)
            base, n_unstable = None, None
        else:
            # a trial step: energy and volume decide; the stiffness is assembled only if it is taken
            lin, E_trial, h_trial, outside = _trial_step(tracer, u, p, accepted, V_star, control)
            if outside:
                dh_max *= 0.5
            if lin is None:
                sigma_rel = min(sigma_rel * DESCENT_SHIFT_GROW, DESCENT_SHIFT_MAX)
                u, p, lin, E_new, h, base, n_unstable = accepted
            else:
                E_new, h = E_trial, h_trial
                sigma_rel *= DESCENT_SHIFT_SHRINK
                base, n_unstable = None, None
            z, dz_du, dz_dp = ctl.zeta(u, p, lin)
        c = float(dz_dp[0])  # the control's compliance (0 at fixed volume)
        c_model = c * float(ctl.sc[0])
        # the unshifted factorisation and its instability are formed only where they decide
        # something (the convergence test, Newton's step once sigma -> 0): a shifted step that is
        # positive definite on the constraint needs neither
        accepted = (u, p, lin, E_new, h, base, n_unstable)
        ref = tracer.residual_scale(lin, dz_du, p)
        rn = float(np.linalg.norm(lin.R)) / ref
        log.debug("descent %d: E=%.12g rn=%.2e h=%.2e sigma_rel=%.1e unstable=%s", it, E_new, rn, h, sigma_rel,
                  "?" if n_unstable is None else n_unstable)
        E_hist.append(E_new)
        # Newton at round-off: a snap at p ~ 0 has a tiny residual scale (the pressure load), and
        # the residual can stall above tol while energy, volume and state no longer change
        stalled = (len(E_hist) > n_stall and sigma_rel < DESCENT_SHIFT_NEWTON and rn < 1e-3
                   and abs(E_hist[-1] - E_hist[-1 - n_stall]) <= 1e-13 * max(abs(E_new), 1e-300))
        if abs(h) < tol and (rn < tol or (rn < 100 * tol and step_small) or stalled):
            if base is None:
                base, n_unstable = _unshifted(lin, dz_du, c, c_model)
                accepted = (u, p, lin, E_new, h, base, n_unstable)
            if n_unstable == 0:
                t, v, q, zz = tracer.tangent(lin, (upper.tangent, tracer.alpha * upper.du_ds))
                how = f"at round-off, residual {rn:.1e}, " if rn >= tol else ""
                return PathPoint(lin.u, lin.p, zz, t, v, q, float("nan"), it), f"descent converged {how}in {it} iterations"
        # the smallest shift (from the current sigma_rel up) that makes the shifted system
        # positive definite on the constraint: the step then goes downhill in every mode
        if sigma_rel <= DESCENT_SHIFT_NEWTON and base is None:
            base, n_unstable = _unshifted(lin, dz_du, c, c_model)
            accepted = (u, p, lin, E_new, h, base, n_unstable)
        solver, sigma_rel = _descent_solver(lin, dz_du, base, n_unstable, sigma_rel, c, c_model)
        if solver is None:
            return None, f"descent: no positive definite shift at iteration {it}"
        # restore the volume gradually when starting far from V* (a homotopy in the constraint)
        h_step = float(np.clip(h, -dh_max, dh_max))
        x = solver.solve(np.concatenate([-lin.R, [-h_step]]))
        u = u + x[:-1]
        p = p + x[-1]
        step_small = float(np.linalg.norm(dz_du @ x[:-1] + dz_dp * x[-1])) < 1e-12
    return None, f"{UNCONVERGED} in {max_iter} iterations"


def _unshifted(lin, dz_du: np.ndarray, c: float, c_model: float) -> tuple:
    """The unshifted bordered factorisation of :func:`descend_at_volume` at ``lin`` and the number of
    its unstable modes on the constraint."""
    base = lin.factor(dz_du[0], c)
    return base, constrained_negatives(base, lin.g, c_model)


def _trial_step(tracer: Tracer, u: np.ndarray, p: float, accepted: tuple, V_star: float, control=None) -> tuple:
    """Judge a trial step of :func:`descend_at_volume` from ``accepted`` (the last accepted
    iterate ``(u, p, lin, E, h, ...)``) to ``(u, p)`` (with ``control``: under its constraint,
    ``h`` of both iterates taken at the new multiplier ``p``).

    Returns ``(lin, E, h, outside)``: the linearisation at ``(u, p)`` if the step is taken, else
    ``None``; its energy and volume error (meaningful if taken); ``outside`` when the step left
    the material domain while the volume was still being restored (the caller then halves the
    largest volume change per iteration).
    """
    pb = tracer.pb
    _, p0, _, E0, h0, _, _ = accepted
    ev = pb.energy_volume(u)
    ok = ev is not None
    E_new = h = math.nan
    if ok:
        E_new = ev[0]
        h = float(ev[1] / tracer.sc[0] - V_star)
        if control is not None:  # V + e(p) - V_d*, both at the new p (the gas energy G(p) then cancels)
            h += float(control.pb.extra_volume(p)) / tracer.sc[0]
    if control is not None:
        h0 += (float(control.pb.extra_volume(p)) - float(control.pb.extra_volume(p0))) / tracer.sc[0]
    # compare with the new multiplier: merit W - p (V - V*); while the volume is still
    # being restored from a start far from V* any step inside the material domain is
    # taken. (With a tight threshold here, steps that overshot to |V - V*| ~ 1e-5 were
    # accepted unchecked and the flow climbed to 5x the energy on thin inner caps.)
    feasible = abs(h0) < 1e-3 * max(1.0, abs(V_star))
    lin = None
    if ok and not (feasible and E_new - p * h * tracer.sc[0] > E0 - p * h0 * tracer.sc[0] + 1e-13 * max(1.0, abs(E0))):
        lin = pb.linearize(u, p)
    return lin, E_new, h, not ok and not feasible


#: A shifted system whose positive definiteness on the constraint is checked (``n_unstable`` not
#: known to be 0) is factorised only up to its second negative pivot: with two, ``K`` has two
#: negative eigenvalues and the constraint removes at most one, so the shift must rise whatever the
#: rest of the band holds (the same shifts and steps; ``follow_strata_n2`` row 17: 361 of its 1,591
#: factorisations given up there, docs/performance.md). ``False``: every one factorised whole (a
#: switch for measurements).
DESCENT_STOP_AT_NEGATIVE = True


def _descent_solver(lin, dz_du: np.ndarray, base, n_unstable: int | None, sigma_rel: float, c: float = 0.0,
                    c_model: float = 0.0) -> tuple:
    """The smallest shift, from ``sigma_rel`` up (by factors of 8), that makes the shifted system
    of :func:`descend_at_volume` positive definite on the constraint: ``(solver, sigma_rel)``, or
    ``(None, sigma_rel)`` if none up to ``1e6`` does. Without unstable modes and with
    ``sigma_rel <= 1e-10`` the unshifted factorisation ``base`` is used (Newton's step; the caller
    factorises it there). ``n_unstable`` ``None``: not known (``base`` not factorised; ``sigma_rel >
    1e-10``): each shifted system's own inertia decides. ``c``: the bordered row's compliance
    (``c_model`` in the model's units; 0 at fixed volume)."""
    solver = None
    while sigma_rel <= DESCENT_SHIFT_MAX:
        if n_unstable != 0 or sigma_rel > DESCENT_SHIFT_NEWTON:
            checked = n_unstable != 0 and DESCENT_STOP_AT_NEGATIVE
            solver = lin.factor(dz_du[0], c, shift=sigma_rel * lin.diag_abs(), max_negative=1 if checked else -1)
        else:
            solver = base
        if solver is not None and (n_unstable == 0 or constrained_negatives(solver, lin.g, c_model) == 0):
            break
        sigma_rel = max(sigma_rel * DESCENT_SHIFT_GROW, DESCENT_SHIFT_NEWTON)
        solver = None
    return solver, sigma_rel


def descent_starts(path_points: list[PathPoint], upper: PathPoint, k_before: int, n: int = 3,
                   control: Tracer | None = None) -> list[PathPoint]:
    """Start states for :func:`descend_at_volume`: post-snap path points whose volume (with
    ``control``: its controlled volume) is closest to ``V*``, skipping the first fifth of the
    post-snap arc (the flat neighbourhood of the degenerate saddle, where a descent would crawl)."""
    after = path_points[k_before + 1 :]
    if not after:
        return []
    s0, s1 = upper.s, after[-1].s
    far = [pt for pt in after if pt.s >= s0 + 0.2 * (s1 - s0)]
    if control is not None:
        def vd(pt: PathPoint) -> float:
            return float(control.zeta(pt.u, pt.p)[0][0])

        far.sort(key=lambda pt: abs(vd(pt) - vd(upper)))
        return far[:n]
    far.sort(key=lambda pt: abs(pt.zeta[0] - upper.zeta[0]))
    return far[:n]
