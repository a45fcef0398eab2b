"""What the arc-length continuation (:mod:`snapjump_cli.fe.continuation`) works with: the problem
interface it sees (:class:`Problem`), its settings in scaled units (:class:`ContinuationSettings`),
the converged path points (:class:`PathPoint`) and the path (:class:`Path`)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from snapjump_cli.settings import SolverSettings

__all__ = ["Problem", "ContinuationFailed", "ContinuationSettings", "PathPoint", "Path"]


class Problem(Protocol):
    """What the continuation needs (see :mod:`snapjump_cli.fe.axisym.model`)."""

    n: int

    # optional: ``newton(u, p, scales, tol, max_newton, target=None, riks=None, aux=None, tol_inc=0.0,
    # theta_max=0.5)``,
    # the corrector of :meth:`Tracer.correct` compiled for this problem (see
    # :meth:`snapjump_cli.fe.axisym.model.Model.newton`)

    def linearize(self, u: np.ndarray, p: float, stiffness: bool = True):
        """Object with ``.R`` (residual) and ``.factor(c_u, c_p)`` -> solver with
        ``.solve(rhs, refine=True)`` for the bordered matrix ``[[dR/du, dR/dp], [c_u^T, c_p]]``
        (``refine=False``: the Newton corrections, which may skip a refinement step); ``None`` for
        a failed iterate.
        With ``stiffness=False`` only ``.R`` is needed (no ``factor``).

        Optional auxiliary field: a problem that accepts ``linearize(u, p, aux=a)`` builds the
        tangent with ``a`` and gives ``.aux`` (the field at ``u``) and ``.aux_dir(x)`` (its
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
        per failed step (``lab/newton_study.py@51d9ff8 contraction``)
    mixed_tangent : linearise with the auxiliary field carried along the path, if the problem has one
    step_grow : growth of the next step after a step whose Newton took at most ``n_opt`` iterations
        (:data:`snapjump_cli.fe.continuation.stepping.STEP_GROW` by default; a followed branch's:
        :data:`snapjump_cli.fe.branch.trace.FOLLOW_STEP_GROW`, the sphere path's: its own)
    split_steps : a step that turned more than ``max_turn_deg`` is kept, with its half-way point
        added, when each half turns less (else it is rejected and the step halved); the converged
        end point is not thrown away
    fail_cap : after a step whose corrector failed, the steps that follow are kept below
        ``fail_cap`` times the failed step's length, a bound that grows by ``step_grow`` with every
        accepted step (0: no bound; a path whose steps alternate between growing past Newton's
        basin and being cut back)
    grow_easy : growth of the next step after a step that converged in one Newton iteration and
        turned less than a tenth of ``max_turn_deg`` (0: ``step_grow``)
    theta_aim : the contraction aimed at in a step's first Newton iteration (the second correction
        over the first, ``theta``; the corrector gives up above ``theta_max``): after a step whose
        ``theta`` was measured the next is at most ``(theta_aim / theta)^(1/3)`` times as long, and
        a step given up for its contraction is retried at that fraction (between 0.25 and 0.8) of
        its length instead of half (0: off; the Python corrector only)
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
    step_grow: float = 1.6
    fail_cap: float = 0.0
    grow_easy: float = 0.0
    theta_aim: float = 0.0

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
