"""Parameters, result and input checks of the two-mass jump model (:mod:`snapjump_cli.jump`).

:class:`JumpParams` and :class:`JumpResult` are re-exported by :mod:`snapjump_cli.jump`, the
module to import them from. The helpers here validate the inputs of a simulation, answer for a
design that cannot jump and assemble the result; both the closed form (:mod:`snapjump_cli.jump`)
and the ODE cross-check (:mod:`snapjump_cli.jump.ode`) use them.
"""
from __future__ import annotations

import logging
import math
import sys
from dataclasses import dataclass

from snapjump_cli.settings import JUMP_ALPHA, JUMP_C_D, JUMP_RHO

#: Default work limit of one jump simulation (:attr:`JumpParams.max_samples`): sample steps of its
#: phases. A design of the paper's grid takes a few hundred to a few thousand; this many take
#: a few seconds (an actuator of R_i = 0.1 mm, heavily over-damped, would need ten times more).
MAX_SAMPLES = 2.0e7

__all__ = ["JumpParams", "JumpResult"]

#: The jump model's messages keep the logger of its public module.
log = logging.getLogger("snapjump_cli.jump")


def check_real(name: str, value: float, *, positive: bool = False, nonneg: bool = False) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a real number, got {value!r}") from None
    if isinstance(value, bool) or not math.isfinite(x):
        raise ValueError(f"{name} must be a finite real number, got {value!r}")
    if x != 0.0 and abs(x) < sys.float_info.min:
        raise ValueError(f"{name} must be a normal number, got {value!r} (subnormal, below {sys.float_info.min:.4g}: "
                         f"a typo in the exponent?)")
    if positive and not x > 0.0:
        raise ValueError(f"{name} must be > 0, got {x!r}")
    if nonneg and not x >= 0.0:
        raise ValueError(f"{name} must be >= 0, got {x!r}")
    return x


@dataclass(frozen=True)
class JumpParams:
    """Physical and numerical parameters of the jump model.

    Parameters
    ----------
    rho : float
        Rubber density [kg/m^3] used by :func:`masses` (docs/physics.md section 6: 1000).
    c_d : float
        Dashpot coefficient between the masses [kg/s].
    g : float
        Gravitational acceleration [m/s^2] (``>= 0``; ``0`` only for tests).
    alpha : float
        Coefficient of restitution of ``m_i`` on the ground, in ``[0, 1]`` (eq 25).
    t_max : float
        Simulated-time limit [s]; reaching it before the maximum is certified gives
        ``JumpResult.complete = False``.
    max_contacts : int
        Limit on the number of ground impacts (same consequence as ``t_max``).
    max_samples : float
        Limit on the work of one simulation: the simulated time in sample steps of its phases
        (a flight's or a rest's oscillation period / 64), so that no design runs for minutes (a
        tiny, heavily over-damped actuator would need ~10^9 of them to reach ``t_max``); same
        consequence as ``t_max``. A simulation that ends before it takes no step differently.
    """

    rho: float = JUMP_RHO
    c_d: float = JUMP_C_D
    g: float = 9.81
    alpha: float = JUMP_ALPHA
    t_max: float = 5.0
    max_contacts: int = 200
    max_samples: float = MAX_SAMPLES

    def __post_init__(self) -> None:
        check_real("rho", self.rho, positive=True)
        check_real("c_d", self.c_d, nonneg=True)
        check_real("g", self.g, nonneg=True)
        a = check_real("alpha", self.alpha)
        if not 0.0 <= a <= 1.0:
            raise ValueError(f"alpha must lie in [0, 1], got {a!r}")
        check_real("t_max", self.t_max, positive=True)
        if isinstance(self.max_contacts, bool) or int(self.max_contacts) != self.max_contacts \
                or self.max_contacts < 1:
            raise ValueError(f"max_contacts must be an integer >= 1, got {self.max_contacts!r}")
        check_real("max_samples", self.max_samples, positive=True)


@dataclass(frozen=True)
class JumpResult:
    """Outcome of one jump simulation.

    Attributes
    ----------
    y_jump_m : float
        ``max_{t>=0} y_i(t)`` [m]: the highest height of the inner pole above the ground,
        including the start, so ``y_jump_m >= h_imp_m``; equals ``h_imp_m`` when it does not jump.
    t_peak_s : float
        Time of that maximum [s] (``0`` when it does not jump).
    n_contacts : int
        Ground impacts of ``m_i`` simulated until the maximum was certified.
    k_s : float
        Spring stiffness ``2 dE / dy_pole^2`` [N/m] (``0`` when there is no snap).
    m_i, m_o : float
        The masses [kg].
    jumped : bool
        ``y_jump_m > h_imp_m``: the inner pole rises above its start height.
    lift_off : bool
        ``m_i`` leaves the ground at least once after touching it (a rebound with positive speed
        or a lift-off from resting contact); ``False`` if it never touches or never leaves.
    reason : str
        Empty when it jumps; otherwise why not (``"no snap (dE = 0)"``, ``"never leaves the
        ground"``, ``"never rises above its start height h_imp"``, ...).
    h_imp_m : float
        Start height of ``m_i`` [m].
    complete : bool
        ``True`` when the maximum is certified (energy bound or final rest); ``False`` when
        ``t_max``, ``max_contacts`` or ``max_samples`` stopped the simulation first.
    method : str
        ``"closed-form"`` or ``"ode"``.
    """

    y_jump_m: float
    t_peak_s: float
    n_contacts: int
    k_s: float
    m_i: float
    m_o: float
    jumped: bool
    lift_off: bool
    reason: str
    h_imp_m: float
    complete: bool = True
    method: str = "closed-form"

    @property
    def rise_m(self) -> float:
        """``y_jump_m - h_imp_m`` [m], the rise of the inner pole above its start (``>= 0``)."""
        return self.y_jump_m - self.h_imp_m


def validate(dE_J, dy_pole_m, h_imp_m, m_i_kg, m_o_kg, params) -> tuple[float, ...]:
    """The checked inputs ``(dE, dy, h, m_i, m_o)`` of a simulation as floats."""
    if not isinstance(params, JumpParams):
        raise ValueError(f"params must be a JumpParams, got {type(params).__name__}")
    dE = check_real("dE_J", dE_J)
    dy = check_real("dy_pole_m", dy_pole_m)
    h = check_real("h_imp_m", h_imp_m, nonneg=True)
    mi = check_real("m_i_kg", m_i_kg, positive=True)
    mo = check_real("m_o_kg", m_o_kg, positive=True)
    return dE, dy, h, mi, mo


def no_snap(dE: float, dy: float, h: float, mi: float, mo: float, method: str) -> JumpResult | None:
    """The result of a design that cannot jump (``dE <= 0`` or ``dy <= 0``); ``None`` if it can."""
    if dE <= 0.0:
        reason = "no snap (dE = 0)" if dE == 0.0 else f"no snap (dE = {dE:g} J <= 0)"
    elif dy <= 0.0:
        reason = f"no pole travel (dy_pole = {dy:g} m <= 0)"
    else:
        return None
    return JumpResult(y_jump_m=h, t_peak_s=0.0, n_contacts=0, k_s=0.0, m_i=mi, m_o=mo,
                      jumped=False, lift_off=False, reason=reason, h_imp_m=h, complete=True,
                      method=method)


def finish(ymax: float, tpeak: float, n_contacts: int, k: float, mi: float, mo: float, h: float,
            lift_off: bool, complete: bool, method: str) -> JumpResult:
    """The result of a simulation (the reason when it does not jump; a warning if incomplete)."""
    jumped = ymax > h
    if jumped:
        reason = ""
    elif not lift_off:
        reason = "never leaves the ground"
    else:
        reason = "never rises above its start height h_imp"
    if not complete:
        log.warning("jump simulation (%s) stopped by t_max/max_contacts/max_samples before the maximum was "
                    "certified (y_jump so far %.6g m)", method, ymax)
    return JumpResult(y_jump_m=float(ymax), t_peak_s=float(tpeak), n_contacts=int(n_contacts),
                      k_s=k, m_i=mi, m_o=mo, jumped=bool(jumped), lift_off=bool(lift_off),
                      reason=reason, h_imp_m=h, complete=bool(complete), method=method)
