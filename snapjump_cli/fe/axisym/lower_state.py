"""The post-snap (lower) state at the volume ``V*`` of the upper state (docs/physics.md section 5).

:func:`find_lower_state` is the entry point. The lower state the snap tracker found on the path
(:mod:`snapjump_cli.fe.axisym.snap`) is kept if it is stable under volume control
(:func:`constrained_instability`: the inertia of the band LDL^T). Otherwise, and where the path did
not come back to ``V*``, the lower state is found off the path, at fixed volume
(``lower_state_method="descent"``): by displacement control of the snap
(:func:`snap_at_fixed_volume`, ``lower_state_solver="volume-path"``), with the volume-constrained
energy descent as the fallback (:func:`descend_at_volume`, ``lower_state_solver="energy-descent"``).

Displacement control at fixed volume
------------------------------------
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
followed in tens of steps where an energy descent (:func:`descend_at_volume`, kept as the
fallback) needs hundreds of iterations. The continuation is the ordinary one
(:func:`snapjump_cli.fe.continuation.trace`) on the small problem :class:`FixedVolumeProblem`.

Energy descent at fixed volume
------------------------------
:func:`descend_at_volume`: a volume-constrained energy descent (implicit gradient flow in pseudo
time) from the upper state, started along the path's unstable direction or from post-snap path
points (:func:`descent_starts`).
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, replace

import numpy as np

from snapjump_cli.fe.continuation import ContinuationFailed, PathPoint, Tracer, start_point, trace
from snapjump_cli.fe.axisym.descent import constrained_negatives, descend_at_volume, descent_starts
from snapjump_cli.fe.axisym.snap import SnapStates, root_on_step
from snapjump_kernels.calls import band_ldlt_solve, sym_band_matvec

log = logging.getLogger(__name__)

__all__ = [
    "LowerState",
    "find_lower_state",
    "FixedVolumeProblem",
    "FixedVolumeLinearization",
    "MultiBorderedSolver",
    "snap_at_fixed_volume",
    "descend_at_volume",
    "descent_starts",
    "constrained_instability",
]


@dataclass
class LowerState:
    """What :func:`find_lower_state` found.

    Attributes
    ----------
    state : the lower state (``None``: no volume limit, or no lower state found)
    method : ``"path"`` (on the traced path), ``"descent"`` (off the path, at fixed volume) or ``""``
    solver : off the path, the solver that found it (or was tried last): ``"volume-path"`` or
        ``"energy-descent"``; ``None`` on the path
    note : why the path's own lower state was rejected (``""``: it was not)
    reason : why the lower state was sought off the path
    message : the off-path solver's report
    from_path : whether the off-path solver needed the traced path beyond the upper state (the energy
        descent started from a post-snap path point: :func:`descent_starts`); the volume path and
        the descent along the fold's unstable mode start from the upper state alone
    """

    state: PathPoint | None
    method: str = ""
    solver: str | None = None
    note: str = ""
    reason: str = ""
    message: str = ""
    from_path: bool = False


def find_lower_state(tracer: Tracer, states: SnapStates, points: list[PathPoint], why: str = "",
                     control: Tracer | None = None, volume_path: bool = True) -> LowerState:
    """The lower state of a snap: on the path if the tracker found a stable one, else at fixed volume.

    Parameters
    ----------
    tracer : the tracer of the pressure-volume path (its problem is the FE model)
    states : what the snap tracker found (not modified)
    points : the traced path's points (post-snap points are start states of the descent)
    why : why the path gave no lower state (the continuation's failure or stop reason), for the
        messages
    control : another control than the cavity volume (a gas in series,
        :class:`snapjump_cli.fe.axisym.air_snap.GasControlled`): a tracer whose problem's first measure is
        the controlled volume; the lower state is then found at that volume
    volume_path : try the fixed-volume path before the energy descent (``False``: the descent
        alone, for models where that path does not reach the state)

    Returns
    -------
    LowerState
        ``state`` is ``None`` without a volume limit (``states.upper is None``) or when every
        method failed (``reason`` and ``message`` say why).
    """
    if states.upper is None:
        return LowerState(None)
    note = ""
    if states.lower is not None:
        lin = tracer.pb.linearize(states.lower.u, states.lower.p)
        n_unstable = constrained_instability(control or tracer, lin) if lin is not None else 1
        if n_unstable <= 0:
            return LowerState(states.lower, states.lower_method)
        note = f"the path returned to V* on an unstable branch ({n_unstable} unstable modes)"
    reason = note or why
    low, msg = snap_at_fixed_volume(tracer, states.upper, control=control) if volume_path else (None, "")
    solver = "volume-path"
    if low is None:
        if msg:
            log.debug("%s; falling back on the energy descent", msg)
        solver = "energy-descent"
        # from the upper state along its unstable mode first; post-snap path points as fallbacks
        for start in [None] + descent_starts(points, states.upper, states.k_before, control=control):
            low, msg = descend_at_volume(tracer, states.upper, start=start, control=control)
            if low is not None:
                from_path = start is not None
                break
        else:
            from_path = True  # (every start was tried: the path's points were needed)
    else:
        from_path = False
    if low is not None:
        log.info("lower state at fixed volume (%s): %s", reason, msg)
    return LowerState(low, "descent" if low is not None else "", solver, note, reason, msg, from_path)


class MultiBorderedSolver:
    """Solves ``[[K, B], [C^T, D]] [x; y] = [r; s]`` (``B``, ``C``: n x m, ``D``: m x m) by block
    elimination with the band ``LDL^T`` of ``K`` (and, with ``refine``, one step of iterative
    refinement)."""

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
        self._S_inv = None  # the m x m Schur complement's inverse, on the first solve

    def _once(self, r, s):
        z = self._solve_K(r)
        if self._S_inv is None:
            self._S_inv = np.linalg.inv(self.S)
        y = self._S_inv @ (s - self.C.T @ z)
        return z - self.KiB @ y, y

    def solve(self, rhs: np.ndarray, refine: bool = True) -> np.ndarray:
        m = self.B.shape[1]
        r, s = rhs[:-m], rhs[-m:]
        x, y = self._once(r, s)
        if refine:
            top = sym_band_matvec(self.base.K, x, self.base.ext) + self.B @ y
            bot = self.C.T @ x + self.D @ y
            dx, dy = self._once(r - top, s - bot)
            x, y = x + dx, y + dy
        return np.concatenate([x, y])


class FixedVolumeLinearization:
    """The linearisation of an equilibrium problem at fixed volume under a load ``F`` (the problem's
    ``model``, ``c_V`` and ``control``): :class:`FixedVolumeProblem`'s, whose load acts along the
    fixed direction ``e``; a subclass sets :meth:`direction` and :meth:`shift` for another."""

    def __init__(self, problem, x, F, R, lin):
        self.problem, self.u, self.p, self.R, self.lin = problem, x, F, R, lin
        self.aux = lin.aux  # the model's element pressures (the mixed linearisation)

    def aux_dir(self, x: np.ndarray) -> np.ndarray:
        """Linearised change of the element pressures for a change ``x = (du, dp)``."""
        return self.lin.aux_dir(x[:-1])

    def direction(self) -> np.ndarray:
        """``-dR/dF`` of the displacement equations: the direction the load acts along."""
        return self.problem.e

    def shift(self) -> "float | np.ndarray":
        """``dR/du`` of the load term, added to the stiffness's diagonal."""
        return 0.0

    def factor(self, c_x: np.ndarray, c_F: float):
        """Factorise ``[[K + shift, -g, -e_w], [c_V g^T, 0, 0], [c_u^T, c_p, c_F]]``; ``None`` if singular."""
        pb, lin = self.problem, self.lin
        n = pb.model.n
        base = lin.factor(pb.c_V * lin.g, 0.0, shift=self.shift())
        if base is None:
            return None
        B = np.stack([-lin.g, -self.direction()], axis=1)
        C = np.stack([pb.c_V * lin.g, c_x[:n]], axis=1)
        D = np.array([[0.0, 0.0], [float(c_x[n]), float(c_F)]])
        if pb.control is not None:  # the volume equation's dependence on the pressure (the gas)
            D[0, 0] = pb.c_V * float(pb.control.compliance(float(self.u[-1])))
        s = MultiBorderedSolver(base, B, C, D)
        if not np.all(np.isfinite(s.S)) or abs(np.linalg.det(s.S)) == 0.0:
            return None
        return s


class FixedVolumeProblem:
    """Equilibria at the fixed cavity volume ``V_star`` under a generalised force ``F`` along
    ``e``: the problem interface of :mod:`snapjump_cli.fe.continuation` with state ``x = (u, p)`` and
    load ``F``; the measures are ``(e . u, F)``.

    Parameters
    ----------
    model : the FE model (:class:`snapjump_cli.fe.axisym.model.Model`)
    V_star : the volume (scaled, as ``Linearization.V``)
    e : the controlled direction (length ``model.n``; a unit vector on one dof is a point force)
    c_V : weight of the volume equation (force / volume)
    p_floor : floor of the pressure in the residual reference (as in the pressure-volume trace)
    control : the controlled problem of another control than the cavity volume (its
        ``extra_volume(p)`` and ``compliance(p)``: the constraint is ``V(u) + extra_volume(p) =
        V_star``), or ``None``
    """

    def __init__(self, model, V_star: float, e: np.ndarray, c_V: float, p_floor: float, control=None) -> None:
        self.model, self.V_star, self.c_V, self.p_floor = model, V_star, c_V, p_floor
        self.control = control
        self.e = np.ascontiguousarray(e, dtype=float)
        self.n = model.n + 1

    def linearize(self, x: np.ndarray, F: float, stiffness: bool = True, aux: np.ndarray | None = None):
        lin = self.model.linearize(x[:-1], float(x[-1]), stiffness, aux=aux)
        if lin is None:
            return None
        R = np.empty(self.n)
        R[:-1] = lin.R - F * self.e
        R[-1] = self.c_V * (lin.V - self.V_star)
        if self.control is not None:
            R[-1] = self.c_V * (lin.V + float(self.control.extra_volume(x[-1])) - self.V_star)
        return FixedVolumeLinearization(self, x, F, R, lin)

    def measures(self, x: np.ndarray, F: float, lin=None):
        """``zeta = (e . u, F)`` and their derivatives."""
        dz = np.zeros((2, self.n))
        dz[0, :-1] = self.e
        return np.array([float(self.e @ x[:-1]), F]), dz, np.array([0.0, 1.0])

    def residual_ref(self, lin) -> float:
        """The residual scale of the pressure-volume trace: ``|dV/du| max(|p|, p_floor)``."""
        return float(np.linalg.norm(lin.lin.g)) * max(abs(float(lin.u[-1])), self.p_floor)


def snap_at_fixed_volume(tracer: Tracer, upper: PathPoint, max_steps: int = 400, max_zeros: int = 6,
                         control: Tracer | None = None) -> tuple[PathPoint | None, str]:
    """The stable state at ``V*`` reached from the upper state (see the module docstring).

    Parameters
    ----------
    tracer : the tracer of the pressure-volume path (its problem is the FE model)
    upper : the upper state (the first volume limit point)
    max_steps : continuation steps of one fixed-volume path
    max_zeros : zeros of ``F`` examined on one path before giving up
    control : another control than the cavity volume (see :func:`find_lower_state`): the
        constraint, the polish, the stability and the energy (``potential``) are its problem's

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
    if control is not None:
        V_star = lin_up.V + float(control.pb.extra_volume(upper.p))
        W_up = control.pb.potential(lin_up.E, upper.p)
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
        attempts += [("mode", upper.du_ds / nrm, float(d), math.sqrt(model.n) * sw) for d in (1.0, -1.0)]
    msgs = []
    for name, e, direction, s_w in attempts:
        pb = FixedVolumeProblem(model, V_star, e, c_V=ref_up / sV, p_floor=p_floor,
                                control=control.pb if control is not None else None)
        fcfg = replace(cfg, scales=(s_w, sp * sV / s_w), max_steps=max_steps)  # force = p V / length
        found, msg, n_steps, n_newton = _follow(tracer, pb, fcfg, x0, direction, W_up, V_star / sV,
                                                1e-3 * cfg.tol * ref_up, max_zeros, control)
        if found is not None:
            lin, it = found
            t, v, q, z = tracer.tangent(lin, (upper.tangent, tracer.alpha * upper.du_ds))
            return (PathPoint(lin.u, lin.p, z, t, v, q, math.nan, it),
                    f"fixed-volume path ({name} control): stable state in {n_steps} steps ({n_newton} Newton iterations)")
        msgs.append(f"{name} {'+' if direction > 0 else '-'}: {msg} after {n_steps} steps")
    return None, "fixed-volume path: " + "; ".join(msgs)


def _follow(tracer: Tracer, pb: FixedVolumeProblem, fcfg, x0: np.ndarray, direction: float, W_up: float,
            V_target: float, F_tol: float, max_zeros: int, control: Tracer | None = None):
    """Follow the fixed-volume path from ``x0`` along ``direction * e``; returns
    ``((linearisation, iterations) or None, message, steps, Newton iterations)``. With ``control``
    the energies compared are its problem's ``potential`` and the zeros are polished and judged
    under that control."""
    model = tracer.pb
    ctl = control or tracer

    def energy(E: float, p: float) -> float:
        return E if control is None else control.pb.potential(E, p)
    ftr = Tracer(pb, fcfg)
    state = {"zeros": 0, "found": None}

    def stop(path) -> str | None:
        pts = path.points
        a, b = pts[-2], pts[-1]
        if not energy(model.energy(b.u[:-1]), float(b.u[-1])) <= W_up + 1e-9 * max(1.0, abs(W_up)):
            return "climbed above the upper state's energy"
        if not (a.p * b.p < 0.0 or (b.p == 0.0 and a.p != 0.0)):
            return None
        state["zeros"] += 1
        root = root_on_step(ftr, a, b, pts[-3] if len(pts) > 2 else None, lambda pt: pt.p, F_tol, 40)
        res = ctl.correct(root.u[:-1].copy(), float(root.u[-1]), None, None, 0.0, target=(0, V_target))
        if res is not None:
            lin, it = res
            n_unstable = constrained_instability(ctl, lin)
            W = energy(lin.E, lin.p)
            below = W < W_up - 1e-12 * max(1.0, abs(W_up))
            log.debug("fixed-volume path: F = 0 at w = %.6g (%d unstable, W %.6g vs upper %.6g)",
                      float(pb.e @ lin.u), n_unstable, W, W_up)
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


def constrained_instability(tracer: Tracer, lin) -> int:
    """Number of unstable modes of the equilibrium ``lin`` under the control of ``tracer``'s
    problem: its first path measure (the cavity volume; or the volume a syringe dispenses through
    a gas of compliance ``c = dV_d/dp``, the measure's pressure derivative).

    With ``K`` the tangent and ``g = dV/du``, the inertia of the bordered matrix gives
    ``neg(Z^T K Z) = neg(K) - [g^T K^-1 g < 0]`` (Haynsworth), ``Z`` spanning ``g``'s complement;
    under the gas the stiffness is ``K + g g^T / c`` and ``neg = neg(K) - [c + g^T K^-1 g < 0]``.
    Returns -1 if the inertia is not available.
    """
    z, dz_du, dz_dp = tracer.zeta(lin.u, lin.p)
    if dz_dp[0] == 0.0:  # volume control
        return constrained_negatives(lin.factor(dz_du[0], 0.0), lin.g)
    return constrained_negatives(lin.factor(dz_du[0], float(dz_dp[0])), lin.g, float(dz_dp[0]) * float(tracer.sc[0]))
