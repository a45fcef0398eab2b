"""Numerical cross-check of the two-mass jump model: eqs 16-17 integrated with ``solve_ivp``.

:func:`jump_height_ode` (re-exported by :mod:`snapjump_cli.jump`) integrates the model in the
original coordinates ``[y_i, y_o, v_i, v_o]`` phase by phase and applies the same impact,
resting-contact, micro-bounce and stopping rules as the closed form
(:func:`snapjump_cli.jump.jump_height`); the rules' bounds come from
:class:`snapjump_cli.jump.events.PhaseModel`, the dynamics do not.
"""
from __future__ import annotations

import math
from typing import Callable, NamedTuple

import numpy as np

from snapjump_cli.jump.closed_form import SAMPLES_PER_PERIOD, V_STICK_REL, PhaseModel, spring_stiffness, system_matrices
from snapjump_cli.jump.params import JumpParams, JumpResult, finish, no_snap, validate

__all__ = ["jump_height_ode"]


def jump_height_ode(dE_J: float, dy_pole_m: float, h_imp_m: float, m_i_kg: float, m_o_kg: float,
                    params: JumpParams = JumpParams(), rtol: float = 1e-11,
                    atol: float = 1e-16) -> JumpResult:
    """The same model integrated numerically (cross-check of :func:`snapjump_cli.jump.jump_height`).

    Integrates eqs 16-17 in the original coordinates ``[y_i, y_o, v_i, v_o]`` with
    ``scipy.integrate.solve_ivp`` (DOP853) phase by phase: terminal events at ground impacts
    (``y_i = 0`` falling) and lift-offs, a non-terminal event at each apex (``v_i = 0`` falling).
    Impacts, resting contact, micro-bounces and the stopping certificates follow the same rules
    as :func:`snapjump_cli.jump.jump_height`.

    Parameters
    ----------
    dE_J, dy_pole_m, h_imp_m, m_i_kg, m_o_kg, params
        As for :func:`snapjump_cli.jump.jump_height`.
    rtol, atol : float
        Tolerances of ``solve_ivp``.

    Returns
    -------
    JumpResult
        As :func:`snapjump_cli.jump.jump_height` returns it, with ``method="ode"``.

    Raises
    ------
    ValueError
        Non-finite inputs, negative ``h_imp_m``, non-positive masses.
    """
    dE, dy, h, mi, mo = validate(dE_J, dy_pole_m, h_imp_m, m_i_kg, m_o_kg, params)
    ns = no_snap(dE, dy, h, mi, mo, "ode")
    if ns is not None:
        return ns
    return _OdeJump(dE, dy, h, mi, mo, params, rtol, atol).run()


class _OdeFunctions(NamedTuple):
    """Right-hand sides and event functions of both phases, as ``solve_ivp`` takes them."""

    rhs_flight: Callable
    ev_contact: Callable
    ev_apex: Callable
    rhs_rest: Callable
    ev_lift: Callable
    ev_settle: Callable


def _ode_functions(k: float, mi: float, mo: float, c: float, g: float, L_rest: float,
                   A: np.ndarray, B: np.ndarray, md: PhaseModel) -> _OdeFunctions:
    """Flight: ``Y = [y_i, y_o, v_i, v_o]``, impact at ``y_i = 0`` falling (terminal), apex at
    ``v_i = 0`` falling; rest (``m_i`` on the ground): ``Z = [y_o, v_o]``, lift-off when the net
    upward pull on ``m_i`` turns positive, settled once no lift-off is possible (both terminal)."""

    def rhs_flight(_t, Y):
        return A @ Y + B

    def ev_contact(_t, Y):
        return Y[0]
    ev_contact.terminal = True
    ev_contact.direction = -1

    def ev_apex(_t, Y):
        return Y[2]
    ev_apex.direction = -1

    def rhs_rest(_t, Z):
        return [Z[1], (-k * (Z[0] - L_rest) - c * Z[1] - mo * g) / mo]

    def ev_lift(_t, Z):
        return k * (Z[0] - L_rest) + c * Z[1] - mi * g
    ev_lift.terminal = True
    ev_lift.direction = 1

    def ev_settle(_t, Z):
        return md.lift_margin(Z[0] - L_rest, Z[1])
    ev_settle.terminal = True
    ev_settle.direction = -1

    return _OdeFunctions(rhs_flight, ev_contact, ev_apex, rhs_rest, ev_lift, ev_settle)


class _OdeJump:
    """One phase-by-phase integration: the constants of the model and the running state."""

    def __init__(self, dE: float, dy: float, h: float, mi: float, mo: float, p: JumpParams,
                 rtol: float, atol: float) -> None:
        self.p, self.h, self.mi, self.mo = p, h, mi, mo
        k = spring_stiffness(dE, dy)
        c, g = p.c_d, p.g
        M = mi + mo
        mu = mi * mo / M
        md = PhaseModel(k, mi, mo, p)  # used only for the shared rules (bounds), not the dynamics
        L0 = dy
        L_rest = L0 + dy
        A, B = system_matrices(k, mi, mo, c, g, L_rest)
        self.k, self.c, self.g, self.md, self.L_rest = k, c, g, md, L_rest
        self.v_stick = V_STICK_REL * math.sqrt(2.0 * dE / mu)
        self.max_step_f = md.rel.dt * SAMPLES_PER_PERIOD / 20.0
        self.max_step_r = md.rest.dt * SAMPLES_PER_PERIOD / 20.0
        self.f = _ode_functions(k, mi, mo, c, g, L_rest, A, B, md)
        self.opts = dict(method="DOP853", rtol=rtol, atol=atol, dense_output=False)
        # the running state
        self.t = 0.0
        self.Y = np.array([h, h + L0, 0.0, 0.0])
        self.ymax, self.tpeak = h, 0.0
        self.n_contacts = 0
        self.lift_off = False
        self.complete = False
        self.resting = h == 0.0 and self.f.ev_lift(0.0, self.Y[[1, 3]]) <= 0.0

    def run(self) -> JumpResult:
        """Integrate phase after phase until the maximum is certified or a limit is reached."""
        p, md = self.p, self.md
        while True:
            Y = self.Y
            e, ed = Y[1] - Y[0] - self.L_rest, Y[3] - Y[2]
            if md.height_bound(Y[0], Y[2], e, ed) <= self.ymax:
                self.complete = True
                break
            if self.t >= p.t_max or self.n_contacts >= p.max_contacts:
                break
            if not self.resting:
                self._flight(e, ed)
            elif self._rest():
                break
        return finish(self.ymax, self.tpeak, self.n_contacts, self.k, self.mi, self.mo, self.h,
                       self.lift_off, self.complete, "ode")

    def _flight(self, e: float, ed: float) -> None:
        """One flight, up to the next impact (applied: rebound or rest) or to ``t_max``."""
        p, f, Y = self.p, self.f, self.Y
        k, c, g, mi = self.k, self.c, self.g, self.mi
        if Y[0] == 0.0:
            self.lift_off = True
        a0 = (k * e + c * ed) / mi - g
        first = self.max_step_f * 1e-4
        if Y[0] == 0.0 and Y[2] > 0.0 and a0 < 0.0:
            first = min(first, (2.0 * Y[2] / -a0) / 16.0)
        from scipy.integrate import solve_ivp  # on use: importing jump (rank) need not load it

        sol = solve_ivp(f.rhs_flight, (self.t, p.t_max), Y, events=[f.ev_contact, f.ev_apex],
                        max_step=self.max_step_f, first_step=first, **self.opts)
        for ta, Ya in zip(sol.t_events[1], sol.y_events[1]):
            if Ya[0] > self.ymax:
                self.ymax, self.tpeak = float(Ya[0]), float(ta)
        if sol.status != 1:
            self.t, self.Y = p.t_max, sol.y[:, -1]
            return
        self.t = float(sol.t_events[0][0])
        Yc = sol.y_events[0][0].copy()
        self.n_contacts += 1
        vm = min(Yc[2], 0.0)
        vp = -p.alpha * vm
        Y = self.Y = np.array([0.0, Yc[1], vp, Yc[3]])
        e = Y[1] - self.L_rest
        if vp <= self.v_stick and (k * e + c * (Y[3] - vp)) / mi - g <= 0.0:
            Y[2] = 0.0
            self.resting = True
        else:
            self.lift_off = True

    def _rest(self) -> bool:
        """One resting phase, up to the lift-off or to ``t_max``; ``True`` when it settles for
        good (the maximum is then certified)."""
        p, f, t = self.p, self.f, self.t
        Z = self.Y[[1, 3]]
        if f.ev_settle(t, Z) < 0.0:
            self.complete = True
            return True
        from scipy.integrate import solve_ivp

        sol = solve_ivp(f.rhs_rest, (t, p.t_max), Z, events=[f.ev_lift, f.ev_settle],
                        max_step=self.max_step_r, first_step=self.max_step_r * 1e-4, **self.opts)
        if sol.status != 1:
            self.t, self.Y = p.t_max, np.array([0.0, sol.y[0, -1], 0.0, sol.y[1, -1]])
            return False
        if sol.t_events[1].size and (not sol.t_events[0].size
                                     or sol.t_events[1][0] <= sol.t_events[0][0]):
            self.complete = True
            return True
        self.t = float(sol.t_events[0][0])
        Zl = sol.y_events[0][0]
        self.Y = np.array([0.0, Zl[0], 0.0, Zl[1]])
        self.resting = False
        return False
