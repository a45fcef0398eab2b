"""Two-mass spring-dashpot jump model (paper Fig. 4B, S5 eqs 15-25; docs/physics.md section 6).

Conventions (``docs/physics.md`` section 6)
-------------------------------------------
Two point masses move on the vertical line: ``m_i`` (inner cap with its ring, at the inner cap's
lower pole) and ``m_o`` (outer cap, at its pole), heights ``y_i`` and ``y_o`` above the ground.
They are joined by a linear spring of stiffness ``k_s = 2 dE / dy_pole**2`` and a dashpot ``c_d``.
The spring is stress-free in the post-snap state and starts compressed by ``dy_pole``, so it
stores exactly ``dE``. Gravity acts on both masses; only ``m_i`` touches the ground, which is
unilateral: an impact (``y_i = 0``, ``v_i < 0``) sets ``v_i <- -alpha v_i`` (eq 25), and while the
spring and dashpot press ``m_i`` onto the ground it rests there (``y_i = 0``, ``v_i = 0``) until
the net non-contact force on it turns upward. The system is released from rest at ``t = 0`` with
``y_i = h_imp``. The spring's rest length is immaterial for ``y_i``: the motion is written in the
spring *extension* ``e = y_o - y_i - L_rest`` (``e(0) = -dy_pole``).

Closed form
-----------
Eqs 16-17 have the eigenvalues ``0, 0`` (eigenvector ``P1``, generalised eigenvector ``P2``: the
centre of mass, which falls freely in flight) and the pair ``lambda_{3,4}`` (eigenvectors
``P3, P4``: the relative motion, a damped oscillator of reduced mass ``mu = m_i m_o / M`` in the
extension ``e``). Writing the solution in these modal coordinates is exactly eqs 18-23 with the
paper's typos corrected (``lambda_4`` takes ``+sqrt``; the second component of ``P3, P4`` is
``-2 m_i m_o / X``); see :func:`eigensystem`. While ``m_i`` rests on the ground ``m_o`` alone is a
damped oscillator about its static equilibrium. Under-, critically and over-damped cases are
evaluated with one numerically stable formula. Impacts and lift-offs are located by root finding
(``scipy.optimize.brentq``) on brackets found by sampling with a step far below the oscillation
period (and the predicted flight time), with every sampled local minimum refined so grazing
contacts are not missed; the apexes are the roots of ``v_i`` (sign ``+ -> -``).

Jump height
-----------
``y_jump = max_{t >= 0} y_i(t)`` (docs/physics.md section 6), *including* ``t = 0``, so
``y_jump >= h_imp``. A design that does not jump therefore reports ``y_jump = h_imp`` with
``t_peak = 0`` (the inner pole never rises above where it started; the paper's "no jump" for
designs A and B), and ``jumped = y_jump > h_imp``. A design that cannot jump at all
(``dE <= 0``: no snap, or ``dy_pole <= 0``) is not simulated and reports the same
``y_jump = h_imp``, ``jumped = False`` with a reason. The simulation stops once the maximum is
certified: the energy ``E(t)`` (kinetic + gravitational + spring) never increases (dashpot,
impacts with ``alpha <= 1``, a workless resting contact), and
``M g y_i <= E + (m_o g)^2 / (2 k_s)`` (up to a constant), so once that bound falls below the
running maximum no later height can exceed it. A resting phase also ends the simulation once a
lift-off is provably impossible (modal envelope of the upward pull, :meth:`PhaseModel.lift_margin`).
``JumpResult.complete`` is ``False`` only when ``t_max`` / ``max_contacts`` / ``max_samples`` (the work
limit, a bound on the run time) stop it first (e.g.
no dissipation at all: ``c_d = 0``, ``alpha = 1``).

Micro-bounces: a rebound slower than ``1e-7`` times the relative-speed scale
``sqrt(2 dE / mu)`` while the spring presses ``m_i`` down is treated as the end of the bounce
sequence (``m_i`` comes to rest); the neglected hop is below 1e-13 m for realistic designs.

Modules
-------
This module is the public API (import everything from here). The parameters, the result and the
input checks are in :mod:`snapjump_cli.jump.params`; the closed-form phases and the location of
impacts, lift-offs and apexes in :mod:`snapjump_cli.jump.events`; running one simulation or
many together (:func:`jump_heights`, for ranking a sweep) in :mod:`snapjump_cli.jump.batch`; the
numerical cross-check :func:`jump_height_ode` (``solve_ivp``) in :mod:`snapjump_cli.jump.ode`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Iterable

import numpy as np

from snapjump_cli.jump.batch import Simulation, run_many, run_one
from snapjump_cli.jump.closed_form import V_STICK_REL, Phase, PhaseModel, spring_stiffness
from snapjump_cli.jump.events import scan_flight, scan_rest
from snapjump_cli.jump.params import JumpParams, JumpResult, check_real, finish, no_snap, validate
from snapjump_cli.settings import JUMP_RHO

__all__ = [
    "JumpParams",
    "JumpResult",
    "JumpTrajectory",
    "masses",
    "jump_height",
    "jump_heights",
    "jump_trajectory",
]


def masses(V_inner_solid_m3: float, V_outer_solid_m3: float, rho: float = JUMP_RHO) -> tuple[float, float]:
    """Masses of the two bodies from their solid rubber volumes.

    Parameters
    ----------
    V_inner_solid_m3 : float
        Solid volume of the inner cap with its ring [m^3].
    V_outer_solid_m3 : float
        Solid volume of the outer cap [m^3].
    rho : float
        Density [kg/m^3].

    Returns
    -------
    (m_i, m_o) : tuple of float
        Masses [kg].

    Raises
    ------
    ValueError
        If any input is not a finite positive number.
    """
    vi = check_real("V_inner_solid_m3", V_inner_solid_m3, positive=True)
    vo = check_real("V_outer_solid_m3", V_outer_solid_m3, positive=True)
    r = check_real("rho", rho, positive=True)
    return r * vi, r * vo


# --------------------------------------------------------------------------------------------
# Trajectory
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class JumpTrajectory:
    """Piecewise closed-form trajectory of the jump model.

    Attributes
    ----------
    result : JumpResult
        The summary.
    contact_times : tuple of float
        Times of the ground impacts [s].
    apexes : tuple of (float, float)
        ``(t, y_i)`` of every local maximum of ``y_i`` found in flight.
    L_rest : float
        Spring rest length used to report ``y_o`` [m] (immaterial for ``y_i``).
    """

    result: JumpResult
    contact_times: tuple[float, ...]
    apexes: tuple[tuple[float, float], ...]
    L_rest: float
    _phases: tuple[Phase, ...] = field(repr=False, default=())
    _model: PhaseModel | None = field(repr=False, default=None)

    @property
    def t_end(self) -> float:
        """End of the simulated interval [s]."""
        return self._phases[-1].t1 if self._phases else 0.0

    @property
    def phases(self) -> tuple[tuple[str, float, float], ...]:
        """``(kind, t_start, t_end)`` of each phase (``"flight"`` or ``"rest"``)."""
        return tuple((p.kind, p.t0, p.t1) for p in self._phases)

    def state(self, t: np.ndarray | float) -> np.ndarray:
        """State ``[y_i, y_o, v_i, v_o]`` at times ``t`` (within ``[0, t_end]``).

        Returns
        -------
        ndarray, shape (4,) + shape(t)
        """
        t_arr = np.atleast_1d(np.asarray(t, dtype=float))
        out = np.empty((4,) + t_arr.shape)
        if self._model is None:
            raise ValueError("no trajectory (the design does not snap)")
        starts = np.array([p.t0 for p in self._phases])
        idx = np.clip(np.searchsorted(starts, t_arr, side="right") - 1, 0, len(starts) - 1)
        for j in np.unique(idx):
            ph = self._phases[j]
            sel = idx == j
            tl = np.maximum(t_arr[sel] - ph.t0, 0.0)
            if ph.kind == "flight":
                y, v, e, ed = self._model.flight(ph, tl)
            else:
                e, ed = self._model.rest_state(ph, tl)
                y = np.zeros_like(tl)
                v = np.zeros_like(tl)
            out[0, sel] = y
            out[1, sel] = y + self.L_rest + e
            out[2, sel] = v
            out[3, sel] = v + ed
        if np.ndim(t) == 0:
            return out[:, 0]
        return out


def jump_trajectory(dE_J: float, dy_pole_m: float, h_imp_m: float, m_i_kg: float, m_o_kg: float,
                    params: JumpParams = JumpParams(), L0_m: float | None = None) -> JumpTrajectory:
    """Simulate the jump in closed form and return the whole trajectory.

    Parameters are those of :func:`jump_height`; ``L0_m`` is the pre-snap pole distance used
    only to report ``y_o`` (default ``dy_pole_m``), the spring's rest length being
    ``L0_m + dy_pole_m``.

    Returns
    -------
    JumpTrajectory
        Its ``result`` equals ``jump_height(...)``. For a non-snapping design it holds no
        phases and :meth:`JumpTrajectory.state` raises ``ValueError``.
    """
    return run_one(_simulate(dE_J, dy_pole_m, h_imp_m, m_i_kg, m_o_kg, params, L0_m))


def jump_heights(designs: Iterable[tuple[float, float, float, float, float]],
                 params: JumpParams = JumpParams()) -> list[JumpResult | Exception]:
    """:func:`jump_height` of many designs, simulated together (faster than one by one).

    Parameters
    ----------
    designs : iterable of (dE_J, dy_pole_m, h_imp_m, m_i_kg, m_o_kg)
        The arguments of :func:`jump_height`, one tuple per design.
    params : JumpParams
        Model parameters, the same for all.

    Returns
    -------
    list of JumpResult or Exception
        Per design, in order, exactly what ``jump_height(*design, params)`` returns, or the
        exception it raises (e.g. ``ValueError`` for bad inputs); the others go on.
    """
    return [traj.result if isinstance(traj, JumpTrajectory) else traj
            for traj in run_many(_simulate(*d, params) for d in designs)]


def _simulate(dE_J: float, dy_pole_m: float, h_imp_m: float, m_i_kg: float, m_o_kg: float,
              params: JumpParams, L0_m: float | None = None) -> Simulation:
    """:func:`jump_trajectory` as a generator that asks for the flights' values on their time
    grids (:mod:`snapjump_cli.jump.batch` answers); returns the :class:`JumpTrajectory`."""
    dE, dy, h, mi, mo = validate(dE_J, dy_pole_m, h_imp_m, m_i_kg, m_o_kg, params)
    L0 = dy if L0_m is None else check_real("L0_m", L0_m)
    ns = no_snap(dE, dy, h, mi, mo, "closed-form")
    if ns is not None:
        return JumpTrajectory(result=ns, contact_times=(), apexes=(), L_rest=L0 + max(dy, 0.0))
    p = params
    k = spring_stiffness(dE, dy)
    md = PhaseModel(k, mi, mo, p)
    v_stick = V_STICK_REL * math.sqrt(2.0 * dE / md.mu)

    phases: list[Phase] = []
    contacts: list[float] = []
    apexes: list[tuple[float, float]] = []
    t, y, v, e, ed = 0.0, h, 0.0, -dy, 0.0
    ymax, tpeak = h, 0.0
    lift_off = False
    complete = False
    resting = h == 0.0 and md.lift_force(e, ed) <= 0.0

    used = 0.0  # the work so far, in sample steps of the phases (p.max_samples)
    while True:
        if md.height_bound(y, v, e, ed) <= ymax:
            complete = True
            break
        if t >= p.t_max or len(contacts) >= p.max_contacts or used >= p.max_samples:
            break
        t_avail = p.t_max - t
        dt = md.rest.dt if resting else md.rel.dt
        cut = (p.max_samples - used) * dt < t_avail  # the work limit ends this phase first
        if cut:
            t_avail = (p.max_samples - used) * dt
        if not resting:
            ph = Phase("flight", t, t, y, v, e, ed)
            if y == 0.0:
                lift_off = True
            a0 = md.flight_acc(e, ed)
            h0 = md.rel.dt * 1e-4
            if y == 0.0 and v > 0.0 and a0 < 0.0:
                h0 = min(h0, (2.0 * v / -a0) / 16.0)
            t_hit, found = yield from scan_flight(md, ph, t_avail, h0)
            for tm, ym in found:
                apexes.append((t + tm, ym))
                if ym > ymax:
                    ymax, tpeak = ym, t + tm
            t_loc = t_avail if t_hit is None else t_hit
            yy, vv, ee, eed = md.flight_at(ph).state(t_loc)
            phases.append(Phase("flight", t, t + t_loc, y, v, e, ed))
            used += t_loc / dt
            if t_hit is None:  # ran out of time (or work) in flight
                t, y, v, e, ed = (t + t_loc if cut else p.t_max), yy, vv, ee, eed
                used = p.max_samples if cut else used
                continue
            t += t_hit
            contacts.append(t)
            vm = min(vv, 0.0)
            vp = -p.alpha * vm
            eed_new = eed + vm - vp  # v_o is unchanged by the impact
            y, e = 0.0, ee
            if vp <= v_stick and md.flight_acc(e, eed_new) <= 0.0:
                resting = True
                v, ed = 0.0, eed + vm  # m_i stops: e_dot = v_o
            else:
                v, ed = vp, eed_new
                lift_off = True  # it rebounds
        else:
            ph = Phase("rest", t, t, 0.0, 0.0, e, ed)
            if not md.can_lift(e, ed):
                phases.append(ph)
                complete = True
                break
            # until lift_off is known, only a final rest (no lift-off possible) may end the scan
            what, t_loc = scan_rest(md, ph, t_avail, ymax if lift_off else -math.inf)
            ee, eed = (float(a) for a in md.rest_state(ph, t_loc))
            phases.append(Phase("rest", t, t + t_loc, 0.0, 0.0, e, ed))
            t, y, v, e, ed = t + t_loc, 0.0, 0.0, ee, eed
            used += t_loc / dt
            if what == "settled":
                complete = True
                break
            if what == "lift":
                resting = False
            elif cut:
                used = p.max_samples
            else:
                t = p.t_max

    if not phases or phases[-1].t0 < t:  # the state reached at the end, as a zero-length phase
        phases.append(Phase("rest" if resting else "flight", t, t, y, v, e, ed))
    res = finish(ymax, tpeak, len(contacts), k, mi, mo, h, lift_off, complete, "closed-form")
    return JumpTrajectory(result=res, contact_times=tuple(contacts), apexes=tuple(apexes),
                          L_rest=L0 + dy, _phases=tuple(phases), _model=md)


def jump_height(dE_J: float, dy_pole_m: float, h_imp_m: float, m_i_kg: float, m_o_kg: float,
                params: JumpParams = JumpParams()) -> JumpResult:
    """Jump height of the two-mass model, in closed form between exactly located contacts.

    Parameters
    ----------
    dE_J : float
        Energy released by the snap [J]. ``<= 0``: no snap, no jump.
    dy_pole_m : float
        Pole travel during the snap [m] (the spring's precompression). ``<= 0``: no jump.
    h_imp_m : float
        Start height of ``m_i`` above the ground [m] (``>= 0``).
    m_i_kg, m_o_kg : float
        Masses of the inner (with ring) and outer caps [kg] (``> 0``).
    params : JumpParams
        Model parameters.

    Returns
    -------
    JumpResult
        ``y_jump_m = max_{t>=0} y_i(t)`` (``= h_imp_m`` when it does not jump).

    Raises
    ------
    ValueError
        Non-finite inputs, negative ``h_imp_m``, non-positive masses (the message names the value).
    """
    return jump_trajectory(dE_J, dy_pole_m, h_imp_m, m_i_kg, m_o_kg, params).result
