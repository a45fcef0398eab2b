"""Arc-length continuation (modified Riks) over a small problem interface.

The continuation sees only (see :mod:`snapjump_cli.model`): ``n``, ``residual(u, p)``,
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
from dataclasses import dataclass, field
from typing import Callable, Protocol

import numpy as np

from snapjump_cli import hermite
from snapjump_cli.settings import SolverSettings

log = logging.getLogger(__name__)

__all__ = ["Problem", "PathPoint", "Path", "ContinuationFailed", "ContinuationSettings", "trace", "Tracer"]


class Problem(Protocol):
    """What the continuation needs (see :mod:`snapjump_cli.model`)."""

    n: int

    # optional: ``newton(u, p, scales, tol, max_newton, target=None, riks=None, aux=None, tol_inc=0.0,
    # theta_max=0.5)``,
    # the corrector of :meth:`Tracer.correct` compiled for this problem (see
    # :meth:`snapjump_cli.model.Model.newton`)

    def linearize(self, u: np.ndarray, p: float, stiffness: bool = True):
        """Object with ``.R`` (residual) and ``.factor(c_u, c_p)`` -> solver with
        ``.solve(rhs, refine=True)`` for the bordered matrix ``[[dR/du, dR/dp], [c_u^T, c_p]]``
        (``refine=False``: the Newton corrections, which may skip a refinement step); ``None`` for
        a failed iterate.
        With ``stiffness=False`` only ``.R`` is needed (no ``factor``).

        Optional auxiliary field: a problem that accepts ``linearize(u, p, aux=a)`` builds the
        tangent with ``a`` and gives ``.aux`` (the field at ``u``) and ``.aux_step(x)`` (its
        linearised change for a correction ``x``) on the result."""
        ...

    def measures(self, u: np.ndarray, p: float, lin=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Path measures ``zeta`` (k,), ``d zeta / du`` (k, n), ``d zeta / dp`` (k,); ``lin``, an
        evaluation of ``linearize`` at the same state, may be used to avoid recomputing them."""
        ...

    # optional: ``measure_rates(lin, v, q) -> (zeta, d zeta)``: the measures at the evaluated state
    # ``lin`` and their change along ``(v, q)``, i.e. ``d zeta / du @ v + d zeta / dp * q``
    # (what a tangent needs, without forming ``d zeta / du``)


class ContinuationFailed(RuntimeError):
    """The path could not be continued; the message gives the cause."""


#: The user-facing defaults (one source of truth): :class:`ContinuationSettings` takes its
#: defaults of the settings it shares with :class:`~snapjump_cli.settings.SolverSettings` from them.
_USER_DEFAULTS = SolverSettings()


@dataclass(frozen=True)
class ContinuationSettings:
    """Settings of :func:`trace` in scaled units.

    The settings a user sets (``tol``, ``ds0``, ``ds_max``, ``max_steps``, ``max_newton``,
    ``max_turn_deg``, ``tol_path`` and, in other units, ``u_scale``) and their defaults are those
    of :class:`snapjump_cli.settings.SolverSettings`; :meth:`from_solver` copies them, unchanged.
    The others tune the step control and are not exposed to users.

    Parameters
    ----------
    scales : scales of the path measures ``zeta`` (the arc length is measured in ``zeta / scales``)
    tol : relative Newton tolerance of the limit points, the lower state and the descent
    ds0, ds_max, ds_min : initial, largest and smallest arc length (scaled)
    max_steps : bound on continuation steps
    max_newton : Newton iterations per step before a cut-back
    max_turn_deg : largest turn of the path tangent (or chord) within one step
    n_opt : Newton iterations up to which the step grows
    hermite_predictor : cubic Hermite predictor through the last two points (else the tangent)
    u_scale : scale of the RMS displacement in the arc length, in the problem's displacement units
        (0: arc length in the measures only). ``SolverSettings.u_scale`` is in units of the
        pole-displacement scale; the caller, which knows that scale, converts it.
    ds_bifurcation : step that crosses a bifurcation point
    tol_path : Newton tolerance of ordinary path points (``None``: ``tol``)
    fused : use the problem's compiled corrector (``problem.newton``) if it has one
    error_test : accept ordinary path points by the error test (else by the residual test)
    theta_max : with the error test, Newton gives up on a step as soon as a correction (above the
        tolerance) is more than ``theta_max`` times the one before: converging steps contract by
        ~1e-3 per iteration (90 % below 2e-2; above 0.5 in 3 of ~800 steps), failing ones by ~0.9
        in the median (often growing), and iterating on to ``max_newton`` cost ~9 element passes
        per failed step (``scripts/newton_study.py contraction``)
    mixed_tangent : linearise with the auxiliary field carried along the path, if the problem has one
    split_steps : a step that turned more than ``max_turn_deg`` is kept, with its half-way point
        added, when each half turns less (else it is rejected and the step halved); the converged
        end point is not thrown away
    """

    scales: tuple[float, float, float]
    tol: float = _USER_DEFAULTS.tol
    ds0: float = _USER_DEFAULTS.ds0
    ds_max: float = _USER_DEFAULTS.ds_max
    ds_min: float = 1e-7
    max_steps: int = _USER_DEFAULTS.max_steps
    max_newton: int = _USER_DEFAULTS.max_newton
    max_turn_deg: float = _USER_DEFAULTS.max_turn_deg
    n_opt: int = 4
    hermite_predictor: bool = True
    u_scale: float = 0.0
    ds_bifurcation: float = 1e-3
    tol_path: float | None = _USER_DEFAULTS.tol_path
    fused: bool = True
    error_test: bool = True
    theta_max: float = 0.5
    split_steps: bool = True
    mixed_tangent: bool = True

    @classmethod
    def from_solver(cls, solver: SolverSettings, scales: tuple[float, float, float], u_unit: float = 1.0,
                    **internal) -> "ContinuationSettings":
        """The continuation settings of the user's ``solver`` settings, values unchanged.

        Parameters
        ----------
        solver : the user's settings (its continuation fields are copied as they are)
        scales : scales of the path measures
        u_unit : the unit of ``solver.u_scale`` in the problem's displacement units (the
            pole-displacement scale; ``u_scale = solver.u_scale * u_unit``)
        **internal : settings not exposed to users (``ds_min``, ``n_opt``, ``fused``, ...)
        """
        return cls(scales=scales, tol=solver.tol, ds0=solver.ds0, ds_max=solver.ds_max,
                   max_steps=solver.max_steps, max_newton=solver.max_newton, max_turn_deg=solver.max_turn_deg,
                   u_scale=solver.u_scale * u_unit, tol_path=solver.tol_path, **internal)


@dataclass
class PathPoint:
    """A converged equilibrium state with its unit tangent in measure space."""

    u: np.ndarray
    p: float
    zeta: np.ndarray  # scaled measures (V/sV, p/sp, w/sw)
    tangent: np.ndarray  # d zeta / ds (unit)
    du_ds: np.ndarray  # du/ds
    dp_ds: float
    s: float  # arc length from the start
    newton: int = 0
    det_sign: int = 0  # sign of det of the bordered Jacobian (0: unknown); flips at bifurcations
    n_neg: int = -1  # negative eigenvalues of K_T (unstable modes under pressure control; -1: unknown)
    aux: np.ndarray | None = None  # the problem's auxiliary field (element pressures), if it has one
    daux_ds: np.ndarray | None = None  # its derivative along the path


@dataclass
class Path:
    points: list[PathPoint] = field(default_factory=list)
    n_newton: int = 0
    n_rejected: int = 0
    n_split: int = 0  # steps that turned too far, kept by adding their half-way point
    n_bifurcations: int = 0
    stop_reason: str = ""


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
        #: called as ``on_increment(iteration, size)`` with every Newton correction of the Python
        #: corrector (diagnostics; the compiled one does not report them)
        self.on_increment: Callable[[int, float], None] | None = None
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
            if self.on_increment is not None:  # diagnostics (scripts/newton_study.py)
                self.on_increment(it, inc)
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
        quadratic through ``prev`` tangent at ``pt``: scripts/profile_designs.py, docs/performance.md).
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
        t = ds / h
        h00, h10, h01, h11 = hermite.basis(t)
        u0 = h00 * pt.u + (h10 * h) * pt.du_ds + h01 * end.u + (h11 * h) * end.du_ds
        p0 = h00 * pt.p + h10 * h * pt.dp_ds + h01 * end.p + h11 * h * end.dp_ds
        aux0 = None
        if pt.aux is not None and end.aux is not None and self.cfg.mixed_tangent:
            if pt.daux_ds is not None and end.daux_ds is not None:
                aux0 = h00 * pt.aux + (h10 * h) * pt.daux_ds + h01 * end.aux + (h11 * h) * end.daux_ds
            else:
                aux0 = (1 - t) * pt.aux + t * end.aux
        return self._point(pt, u0, p0, aux0, ds, tol, error_test)

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


def start_point(tracer: Tracer, u0: np.ndarray, p0: float = 0.0, t_prev: np.ndarray | None = None) -> PathPoint:
    """The first path point (a converged state, e.g. the stress-free reference), oriented along
    ``t_prev`` in measure space (default: the first measure, the cavity volume, increases)."""
    if t_prev is None:
        t_prev = np.zeros(len(tracer.sc))
        t_prev[0] = 1.0
    lin = tracer.pb.linearize(u0, p0)
    if lin is None:
        raise ContinuationFailed("the initial state lies outside the material domain")
    t, v, q, z = tracer.tangent(lin, (t_prev, np.zeros(tracer.pb.n)))
    aux = getattr(lin, "aux", None)
    daux = lin.aux_dir(v) if aux is not None else None
    return PathPoint(u0.copy(), p0, z, t, v, q, 0.0, 0, tracer.last_det_sign, tracer.last_n_neg, aux, daux)


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
                grow = 1.6 if its <= cfg.n_opt else (1.0 if its <= cfg.n_opt + 2 else 0.6)
                if ang > 0:
                    grow = min(grow, 0.5 * cfg.max_turn_deg / ang)
                ds = min(cfg.ds_max, ds * max(0.5, grow))
                continue
        else:
            cause = "corrector did not converge"
        path.n_rejected += 1
        ds *= 0.5
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
