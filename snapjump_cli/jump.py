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
lift-off is provably impossible (modal envelope of the upward pull, :meth:`_Model.lift_margin`).
``JumpResult.complete`` is ``False`` only when ``t_max`` / ``max_contacts`` stop it first (e.g.
no dissipation at all: ``c_d = 0``, ``alpha = 1``).

Micro-bounces: a rebound slower than ``1e-7`` times the relative-speed scale
``sqrt(2 dE / mu)`` while the spring presses ``m_i`` down is treated as the end of the bounce
sequence (``m_i`` comes to rest); the neglected hop is below 1e-13 m for realistic designs.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq, minimize_scalar

__all__ = [
    "JumpParams",
    "JumpResult",
    "JumpTrajectory",
    "masses",
    "spring_stiffness",
    "eigensystem",
    "system_matrices",
    "jump_height",
    "jump_trajectory",
    "jump_height_ode",
]

log = logging.getLogger(__name__)

#: Rebound speed (relative to sqrt(2 dE / mu)) below which a pressed-down m_i comes to rest.
_V_STICK_REL = 1e-7
#: Samples per oscillation period when scanning for contacts, lift-offs and apexes.
_SAMPLES_PER_PERIOD = 64
_CHUNK = 4096


# --------------------------------------------------------------------------------------------
# Parameters and results
# --------------------------------------------------------------------------------------------
def _check_real(name: str, value: float, *, positive: bool = False, nonneg: bool = False) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a real number, got {value!r}") from None
    if isinstance(value, bool) or not math.isfinite(x):
        raise ValueError(f"{name} must be a finite real number, got {value!r}")
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
    """

    rho: float = 1000.0
    c_d: float = 0.4
    g: float = 9.81
    alpha: float = 0.5
    t_max: float = 5.0
    max_contacts: int = 200

    def __post_init__(self) -> None:
        _check_real("rho", self.rho, positive=True)
        _check_real("c_d", self.c_d, nonneg=True)
        _check_real("g", self.g, nonneg=True)
        a = _check_real("alpha", self.alpha)
        if not 0.0 <= a <= 1.0:
            raise ValueError(f"alpha must lie in [0, 1], got {a!r}")
        _check_real("t_max", self.t_max, positive=True)
        if isinstance(self.max_contacts, bool) or int(self.max_contacts) != self.max_contacts \
                or self.max_contacts < 1:
            raise ValueError(f"max_contacts must be an integer >= 1, got {self.max_contacts!r}")


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
        ``t_max`` or ``max_contacts`` stopped the simulation first.
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


def masses(V_inner_solid_m3: float, V_outer_solid_m3: float, rho: float = 1000.0) -> tuple[float, float]:
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
    vi = _check_real("V_inner_solid_m3", V_inner_solid_m3, positive=True)
    vo = _check_real("V_outer_solid_m3", V_outer_solid_m3, positive=True)
    r = _check_real("rho", rho, positive=True)
    return r * vi, r * vo


def spring_stiffness(dE_J: float, dy_pole_m: float) -> float:
    """Spring stiffness ``k_s = 2 dE / dy_pole^2`` [N/m] (``0`` if ``dE <= 0`` or ``dy_pole <= 0``)."""
    dE = _check_real("dE_J", dE_J)
    dy = _check_real("dy_pole_m", dy_pole_m)
    if dE <= 0.0 or dy <= 0.0:
        return 0.0
    return 2.0 * dE / dy**2


def system_matrices(k_s: float, m_i: float, m_o: float, c_d: float, g: float,
                    L_rest: float) -> tuple[np.ndarray, np.ndarray]:
    """Matrices ``A`` (4x4) and ``B`` (4,) of eqs 16-17 for ``Y = [y_i, y_o, v_i, v_o]``.

    ``L_rest`` is the spring's rest length (the paper's ``L_0`` in eq 15).
    """
    A = np.array([
        [0.0, 0.0, 1.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
        [-k_s / m_i, k_s / m_i, -c_d / m_i, c_d / m_i],
        [k_s / m_o, -k_s / m_o, c_d / m_o, -c_d / m_o],
    ])
    B = np.array([0.0, 0.0, -g - k_s * L_rest / m_i, -g + k_s * L_rest / m_o])
    return A, B


def eigensystem(k_s: float, m_i: float, m_o: float, c_d: float) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues and (generalised) eigenvectors of eq 17's ``A``, paper typos corrected.

    Returns
    -------
    lam : ndarray, shape (4,), complex
        ``[0, 0, lambda_3, lambda_4]`` with
        ``lambda_{3,4} = (-c_d M -/+ sqrt(M) sqrt(c_d^2 M - 4 k_s m_i m_o)) / (2 m_i m_o)``
        (the paper prints ``-`` for both).
    P : ndarray, shape (4, 4), complex
        Columns ``P1 = [1, 1, 0, 0]``, ``P2 = [0, 0, 1, 1]`` (``A P2 = P1``) and
        ``P_{3,4} = [2 m_o^2 / X, -2 m_i m_o / X, -m_o / m_i, 1]`` with
        ``X = c_d M +/- sqrt(M) sqrt(c_d^2 M - 4 k_s m_i m_o)`` (the paper prints ``+2 m_i m_o / X``).
    """
    M = m_i + m_o
    root = np.sqrt(complex(M)) * np.sqrt(complex(c_d**2 * M - 4.0 * k_s * m_i * m_o))
    lam = np.zeros(4, dtype=complex)
    P = np.zeros((4, 4), dtype=complex)
    P[:, 0] = [1, 1, 0, 0]
    P[:, 1] = [0, 0, 1, 1]
    for j, s in ((2, +1.0), (3, -1.0)):
        X = c_d * M + s * root
        lam[j] = -X / (2.0 * m_i * m_o)
        P[:, j] = [2.0 * m_o**2 / X, -2.0 * m_i * m_o / X, -m_o / m_i, 1.0]
    return lam, P


# --------------------------------------------------------------------------------------------
# Closed-form building blocks
# --------------------------------------------------------------------------------------------
class _Osc:
    """Closed form of ``m x'' + c x' + k x = 0`` (any damping), stable for all ``t >= 0``."""

    def __init__(self, m: float, c: float, k: float) -> None:
        self.m, self.c, self.k = m, c, k
        self.sig = c / (2.0 * m)
        self.w0sq = k / m
        self.D = self.w0sq - self.sig**2  # omega_d^2 (< 0: overdamped)
        self.w = math.sqrt(abs(self.D))
        if self.D > 0.0:
            period = 2.0 * math.pi / self.w
        else:  # critically / over-damped: the fastest time constant sets the scale
            period = 2.0 * math.pi / (self.sig + self.w)
        if self.D > 0.0 and self.sig > 0.0:
            period = min(period, 2.0 * math.pi / self.sig)
        self.dt = period / _SAMPLES_PER_PERIOD

    def _ec_es(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``exp(-sig t) C(t)``, ``exp(-sig t) S(t)`` and ``exp(-sig t) C(t) - 1`` (accurate)."""
        t = np.asarray(t, dtype=float)
        sig, w = self.sig, self.w
        st = sig * t
        wt = w * t
        if self.D > 0.0:
            E = np.exp(-st)
            EC = E * np.cos(wt)
            ES = E * np.sin(wt) / w
            ECm1 = np.expm1(-st) * np.cos(wt) - 2.0 * np.sin(0.5 * wt) ** 2
        elif self.D < 0.0:
            small = wt < 0.5
            ws = np.where(small, wt, 0.0)
            E = np.exp(-st)
            a = np.exp((w - sig) * t)
            b = np.exp(-(w + sig) * t)
            EC = np.where(small, E * np.cosh(ws), 0.5 * (a + b))
            ES = np.where(small, E * np.sinh(ws) / w, (a - b) / (2.0 * w))
            acc = np.expm1(-st) * np.cosh(ws) + 2.0 * np.sinh(0.5 * ws) ** 2
            ECm1 = np.where(small, acc, EC - 1.0)
        else:
            E = np.exp(-st)
            EC = E
            ES = E * t
            ECm1 = np.expm1(-st)
        return EC, ES, ECm1

    def xv(self, x0: float, v0: float, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(x(t) - x0, x(t), x'(t))`` from ``x(0) = x0``, ``x'(0) = v0``."""
        EC, ES, ECm1 = self._ec_es(t)
        dx = x0 * ECm1 + (v0 + self.sig * x0) * ES
        v = v0 * EC - (self.sig * v0 + self.w0sq * x0) * ES
        return dx, x0 + dx, v

    def acc(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        return -(self.c * v + self.k * x) / self.m

    def sup_bound(self, x0: float, v0: float) -> float:
        """Upper bound on ``sup_{t >= 0} |x(t)|`` from ``x(0) = x0``, ``x'(0) = v0``.

        Modal envelope: ``R exp(-sig t)`` (under-damped), ``|A| e^{r1 t} + |B| e^{r2 t}``
        (over-damped), ``max (|x0| + |b| t) exp(-sig t)`` (critical). Evaluated along a
        trajectory it never increases.
        """
        sig, w = self.sig, self.w
        b = v0 + sig * x0
        if self.D > 0.0:
            return math.hypot(x0, b / w)
        if self.D < 0.0:
            A = (b + w * x0) / (2.0 * w)  # coefficient of exp((-sig + w) t)
            return abs(A) + abs(x0 - A)
        if b == 0.0:
            return abs(x0)
        s = max(0.0, 1.0 / sig - abs(x0) / abs(b))
        return (abs(x0) + abs(b) * s) * math.exp(-sig * s)


@dataclass(frozen=True)
class _Phase:
    """One motion phase: ``kind`` ``"flight"`` (both free) or ``"rest"`` (m_i on the ground)."""

    kind: str
    t0: float
    t1: float
    y0: float   # y_i at t0
    v0: float   # v_i at t0
    e0: float   # spring extension at t0
    ed0: float  # extension rate at t0


class _Model:
    """Closed-form evaluation of both phase kinds for one parameter set."""

    def __init__(self, k: float, m_i: float, m_o: float, p: JumpParams) -> None:
        self.k, self.m_i, self.m_o, self.p = k, m_i, m_o, p
        self.M = m_i + m_o
        self.r = m_o / self.M
        self.mu = m_i * m_o / self.M
        self.g = p.g
        self.c = p.c_d
        self.rel = _Osc(self.mu, p.c_d, k)          # flight: relative motion
        self.rest = _Osc(m_o, p.c_d, k)             # m_i resting: m_o about equilibrium
        self.e_eq = -m_o * p.g / k                  # static extension while m_i rests

    # ---- flight ----
    def flight(self, ph: _Phase, t: np.ndarray) -> tuple[np.ndarray, ...]:
        """``(y_i, v_i, e, e_dot)`` at local times ``t`` of a flight phase."""
        t = np.asarray(t, dtype=float)
        w0 = ph.v0 + self.r * ph.ed0  # centre-of-mass velocity
        de, e, ed = self.rel.xv(ph.e0, ph.ed0, t)
        y = ph.y0 + w0 * t - 0.5 * self.g * t * t - self.r * de
        v = w0 - self.g * t - self.r * ed
        return y, v, e, ed

    def flight_acc(self, e: float, ed: float) -> float:
        """Acceleration of a free ``m_i`` (spring + dashpot + gravity)."""
        return (self.k * e + self.c * ed) / self.m_i - self.g

    # ---- resting on the ground ----
    def rest_state(self, ph: _Phase, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(e, e_dot)`` at local times ``t`` while ``m_i`` rests."""
        _, x, v = self.rest.xv(ph.e0 - self.e_eq, ph.ed0, np.asarray(t, dtype=float))
        return x + self.e_eq, v

    def lift_force(self, e: np.ndarray, ed: np.ndarray) -> np.ndarray:
        """Net non-contact upward force on a resting ``m_i``; it lifts off when this is ``> 0``."""
        return self.k * e + self.c * ed - self.m_i * self.g

    def lift_margin(self, e: float, ed: float) -> float:
        """Bound on the future upward pull on a resting ``m_i`` minus what lift-off needs.

        ``F = k x + c x'`` (``x = e - e_eq``) obeys the same oscillator equation as ``x``, and
        lift-off needs ``F > M g``; so no lift-off can ever happen once
        ``sup_future |F| <= `` :meth:`_Osc.sup_bound` ``< M g`` (a non-increasing quantity).
        """
        x = e - self.e_eq
        F = self.k * x + self.c * ed
        dF = self.k * ed + self.c * self.rest.acc(x, ed)
        return self.rest.sup_bound(F, dF) - self.M * self.g

    def can_lift(self, e: float, ed: float) -> bool:
        """``False`` once a resting ``m_i`` can provably never lift off again."""
        return self.lift_margin(e, ed) >= 0.0

    # ---- energy bound ----
    def height_bound(self, y: float, v: float, e: float, ed: float) -> float:
        """Upper bound on every later ``y_i`` from the current (non-increasing) energy."""
        if self.g <= 0.0:
            return math.inf
        vo = v + ed
        E = (0.5 * self.m_i * v * v + 0.5 * self.m_o * vo * vo + self.M * self.g * y
             + self.m_o * self.g * e + 0.5 * self.k * e * e)
        return (E + (self.m_o * self.g) ** 2 / (2.0 * self.k)) / (self.M * self.g)


def _time_grid(h0: float, dt: float, t_end: float):
    """Yield chunks of increasing sample times in ``(0, t_end]`` (the last one ends at ``t_end``).

    Steps grow geometrically from ``h0`` up to ``dt`` and then stay at ``dt``.
    """
    h0 = min(h0, dt)
    n_geo = int(math.ceil(math.log2(dt / h0))) if h0 < dt else 0
    head = np.cumsum(h0 * 2.0 ** np.arange(n_geo))
    last = float(head[-1]) if head.size else 0.0
    chunk = np.concatenate([head, last + dt * np.arange(1, _CHUNK + 1)])
    while True:
        sel = chunk[chunk < t_end]
        if sel.size < chunk.size:
            yield np.append(sel, t_end)
            return
        yield chunk
        chunk = float(chunk[-1]) + dt * np.arange(1, _CHUNK + 1)


def _first_fall(F: Callable[[float], float], dF: Callable[[float], float],
                T: np.ndarray, Fv: np.ndarray, dFv: np.ndarray) -> float | None:
    """First time after ``T[0]`` at which ``F`` (``>= 0`` at ``T[0]``) reaches ``<= 0``, or ``None``.

    Looks at sign changes between samples and at sampled local minima (refined to the root of
    ``dF``) so that grazing dips between samples are not missed. ``T[0]`` itself is excluded.
    """
    n = T.size
    best: float | None = None
    down = np.nonzero((Fv[:-1] > 0.0) & (Fv[1:] <= 0.0))[0]
    if down.size:
        k = int(down[0])
        best_bracket = (T[k], T[k + 1])
        best = best_bracket[1]
    # sampled local minima with positive value: refine
    if n >= 3:
        mins = np.nonzero((Fv[1:-1] <= Fv[:-2]) & (Fv[1:-1] < Fv[2:]) & (Fv[1:-1] > 0.0))[0] + 1
        for k in mins:
            if best is not None and T[k - 1] >= best:
                break
            a, b = T[k - 1], T[k + 1]
            if not (dFv[k - 1] < 0.0 < dFv[k + 1]):
                continue
            tm = brentq(dF, a, b, xtol=1e-300, rtol=4 * np.finfo(float).eps)
            if F(tm) <= 0.0:
                if best is None or tm < best:
                    best_bracket = (a, tm)
                    best = tm
                break
    if best is None:
        return None
    a, b = best_bracket
    if F(b) == 0.0:
        return float(b)
    return float(brentq(F, a, b, xtol=1e-300, rtol=4 * np.finfo(float).eps))


def _maxima(F: Callable[[float], float], dF: Callable[[float], float], T: np.ndarray,
            Fv: np.ndarray, dFv: np.ndarray, skip: int = 0) -> list[tuple[float, float]]:
    """Local maxima ``(t, F(t))`` of ``F`` on ``[T[0], T[-1]]``.

    Roots of ``dF`` where it changes sign ``+ -> -`` between samples, plus sampled local maxima
    without such a sign change next to them (refined by bounded minimisation). Intervals and
    samples with index ``< skip`` are ignored (already handled with the previous chunk).
    """
    out: list[tuple[float, float]] = []
    eps = 4 * np.finfo(float).eps
    idx = np.nonzero((dFv[:-1] > 0.0) & (dFv[1:] <= 0.0))[0]
    covered: set[int] = set()
    for k in idx:
        covered.update((int(k), int(k) + 1))
        if k < skip:
            continue
        a, b = T[k], T[k + 1]
        t = b if dFv[k + 1] == 0.0 else brentq(dF, a, b, xtol=1e-300, rtol=eps)
        out.append((float(t), float(F(t))))
    if T.size >= 3:
        smax = np.nonzero((Fv[1:-1] >= Fv[:-2]) & (Fv[1:-1] > Fv[2:]))[0] + 1
        for k in smax:
            if k - 1 < skip or k in covered or (k - 1) in covered:
                continue
            a, b = float(T[k - 1]), float(T[k + 1])
            res = minimize_scalar(lambda s: -F(s), bounds=(a, b), method="bounded",
                                  options={"xatol": 1e-13 * max(b, 1e-300)})
            t = float(res.x) if -res.fun > Fv[k] else float(T[k])
            out.append((t, float(F(t))))
    return out


def _scan_flight(md: "_Model", ph: "_Phase", t_avail: float,
                 h0: float) -> tuple[float | None, list[tuple[float, float]]]:
    """First impact (local time, or ``None`` before ``t_avail``) and the apexes before it."""

    def Fy(s: float) -> float:
        return float(md.flight(ph, s)[0])

    def Fv(s: float) -> float:
        return float(md.flight(ph, s)[1])

    apexes: list[tuple[float, float]] = []
    # A flight starting on the ground must be resolved by the first sample: shrink h0 if not.
    if ph.y0 == 0.0:
        for _ in range(40):
            if Fy(min(h0, md.rel.dt, t_avail)) > 0.0:
                break
            h0 /= 16.0
    T_prev = np.array([0.0])
    Y_prev = np.array([ph.y0])
    V_prev = np.array([ph.v0])
    for chunk in _time_grid(h0, md.rel.dt, t_avail):
        Yc, Vc, _, _ = md.flight(ph, chunk)
        T = np.concatenate([T_prev, chunk])
        Yv = np.concatenate([Y_prev, Yc])
        Vv = np.concatenate([V_prev, Vc])
        t_hit = _first_fall(Fy, Fv, T, Yv, Vv)
        if t_hit is not None:
            keep = T < t_hit
            T = np.append(T[keep], t_hit)
            Yv = np.append(Yv[keep], 0.0)
            Vv = np.append(Vv[keep], Fv(t_hit))
        apexes.extend(_maxima(Fy, Fv, T, Yv, Vv, skip=T_prev.size - 1))
        if t_hit is not None:
            return t_hit, apexes
        T_prev, Y_prev, V_prev = T[-2:], Yv[-2:], Vv[-2:]
    return None, apexes


def _scan_rest(md: "_Model", ph: "_Phase", t_avail: float,
               ymax: float) -> tuple[str, float]:
    """While ``m_i`` rests: ``("lift", t)`` at lift-off, ``("settled", t)`` once no lift-off
    (or no new maximum) is possible any more, or ``("timeout", t_avail)``."""

    def Ff(s: float) -> float:
        ee, eed = md.rest_state(ph, s)
        return -float(md.lift_force(ee, eed))

    def dFf(s: float) -> float:
        ee, eed = md.rest_state(ph, s)
        return -float(md.k * eed + md.c * md.rest.acc(ee - md.e_eq, eed))

    T_prev = np.array([0.0])
    F_prev = np.array([Ff(0.0)])
    D_prev = np.array([dFf(0.0)])
    for chunk in _time_grid(md.rest.dt * 1e-4, md.rest.dt, t_avail):
        Ec, EDc = md.rest_state(ph, chunk)
        T = np.concatenate([T_prev, chunk])
        Fv = np.concatenate([F_prev, -md.lift_force(Ec, EDc)])
        Dv = np.concatenate([D_prev, -(md.k * EDc + md.c * md.rest.acc(Ec - md.e_eq, EDc))])
        t_lift = _first_fall(Ff, dFf, T, Fv, Dv)
        if t_lift is not None:
            return "lift", t_lift
        e_end, ed_end = float(Ec[-1]), float(EDc[-1])
        if not md.can_lift(e_end, ed_end) or md.height_bound(0.0, 0.0, e_end, ed_end) <= ymax:
            return "settled", float(chunk[-1])
        T_prev, F_prev, D_prev = T[-2:], Fv[-2:], Dv[-2:]
    return "timeout", t_avail


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
    _phases: tuple[_Phase, ...] = field(repr=False, default=())
    _model: _Model | None = field(repr=False, default=None)

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


def _validate(dE_J, dy_pole_m, h_imp_m, m_i_kg, m_o_kg, params) -> tuple[float, ...]:
    if not isinstance(params, JumpParams):
        raise ValueError(f"params must be a JumpParams, got {type(params).__name__}")
    dE = _check_real("dE_J", dE_J)
    dy = _check_real("dy_pole_m", dy_pole_m)
    h = _check_real("h_imp_m", h_imp_m, nonneg=True)
    mi = _check_real("m_i_kg", m_i_kg, positive=True)
    mo = _check_real("m_o_kg", m_o_kg, positive=True)
    return dE, dy, h, mi, mo


def _no_snap(dE: float, dy: float, h: float, mi: float, mo: float, method: str) -> JumpResult | None:
    if dE <= 0.0:
        reason = "no snap (dE = 0)" if dE == 0.0 else f"no snap (dE = {dE:g} J <= 0)"
    elif dy <= 0.0:
        reason = f"no pole travel (dy_pole = {dy:g} m <= 0)"
    else:
        return None
    return JumpResult(y_jump_m=h, t_peak_s=0.0, n_contacts=0, k_s=0.0, m_i=mi, m_o=mo,
                      jumped=False, lift_off=False, reason=reason, h_imp_m=h, complete=True,
                      method=method)


def _finish(ymax: float, tpeak: float, n_contacts: int, k: float, mi: float, mo: float, h: float,
            lift_off: bool, complete: bool, method: str) -> JumpResult:
    jumped = ymax > h
    if jumped:
        reason = ""
    elif not lift_off:
        reason = "never leaves the ground"
    else:
        reason = "never rises above its start height h_imp"
    if not complete:
        log.warning("jump simulation (%s) stopped by t_max/max_contacts before the maximum was "
                    "certified (y_jump so far %.6g m)", method, ymax)
    return JumpResult(y_jump_m=float(ymax), t_peak_s=float(tpeak), n_contacts=int(n_contacts),
                      k_s=k, m_i=mi, m_o=mo, jumped=bool(jumped), lift_off=bool(lift_off),
                      reason=reason, h_imp_m=h, complete=bool(complete), method=method)


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
    dE, dy, h, mi, mo = _validate(dE_J, dy_pole_m, h_imp_m, m_i_kg, m_o_kg, params)
    L0 = dy if L0_m is None else _check_real("L0_m", L0_m)
    ns = _no_snap(dE, dy, h, mi, mo, "closed-form")
    if ns is not None:
        return JumpTrajectory(result=ns, contact_times=(), apexes=(), L_rest=L0 + max(dy, 0.0))
    p = params
    k = 2.0 * dE / dy**2
    md = _Model(k, mi, mo, p)
    v_stick = _V_STICK_REL * math.sqrt(2.0 * dE / md.mu)

    phases: list[_Phase] = []
    contacts: list[float] = []
    apexes: list[tuple[float, float]] = []
    t, y, v, e, ed = 0.0, h, 0.0, -dy, 0.0
    ymax, tpeak = h, 0.0
    lift_off = False
    complete = False
    resting = h == 0.0 and md.lift_force(e, ed) <= 0.0

    while True:
        if md.height_bound(y, v, e, ed) <= ymax:
            complete = True
            break
        if t >= p.t_max or len(contacts) >= p.max_contacts:
            break
        t_avail = p.t_max - t
        if not resting:
            ph = _Phase("flight", t, t, y, v, e, ed)
            if y == 0.0:
                lift_off = True
            a0 = md.flight_acc(e, ed)
            h0 = md.rel.dt * 1e-4
            if y == 0.0 and v > 0.0 and a0 < 0.0:
                h0 = min(h0, (2.0 * v / -a0) / 16.0)
            t_hit, found = _scan_flight(md, ph, t_avail, h0)
            for tm, ym in found:
                apexes.append((t + tm, ym))
                if ym > ymax:
                    ymax, tpeak = ym, t + tm
            t_loc = t_avail if t_hit is None else t_hit
            yy, vv, ee, eed = (float(a) for a in md.flight(ph, t_loc))
            phases.append(_Phase("flight", t, t + t_loc, y, v, e, ed))
            if t_hit is None:  # ran out of time in flight
                t, y, v, e, ed = p.t_max, yy, vv, ee, eed
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
            ph = _Phase("rest", t, t, 0.0, 0.0, e, ed)
            if not md.can_lift(e, ed):
                phases.append(ph)
                complete = True
                break
            # until lift_off is known, only a final rest (no lift-off possible) may end the scan
            what, t_loc = _scan_rest(md, ph, t_avail, ymax if lift_off else -math.inf)
            ee, eed = (float(a) for a in md.rest_state(ph, t_loc))
            phases.append(_Phase("rest", t, t + t_loc, 0.0, 0.0, e, ed))
            t, y, v, e, ed = t + t_loc, 0.0, 0.0, ee, eed
            if what == "settled":
                complete = True
                break
            if what == "lift":
                resting = False
            else:
                t = p.t_max

    if not phases or phases[-1].t0 < t:  # the state reached at the end, as a zero-length phase
        phases.append(_Phase("rest" if resting else "flight", t, t, y, v, e, ed))
    res = _finish(ymax, tpeak, len(contacts), k, mi, mo, h, lift_off, complete, "closed-form")
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


# --------------------------------------------------------------------------------------------
# ODE cross-check
# --------------------------------------------------------------------------------------------
def jump_height_ode(dE_J: float, dy_pole_m: float, h_imp_m: float, m_i_kg: float, m_o_kg: float,
                    params: JumpParams = JumpParams(), rtol: float = 1e-11,
                    atol: float = 1e-16) -> JumpResult:
    """The same model integrated numerically (cross-check of :func:`jump_height`).

    Integrates eqs 16-17 in the original coordinates ``[y_i, y_o, v_i, v_o]`` with
    ``scipy.integrate.solve_ivp`` (DOP853) phase by phase: terminal events at ground impacts
    (``y_i = 0`` falling) and lift-offs, a non-terminal event at each apex (``v_i = 0`` falling).
    Impacts, resting contact, micro-bounces and the stopping certificates follow the same rules
    as :func:`jump_height`. Parameters and return value as :func:`jump_height` (``method="ode"``).
    """
    dE, dy, h, mi, mo = _validate(dE_J, dy_pole_m, h_imp_m, m_i_kg, m_o_kg, params)
    ns = _no_snap(dE, dy, h, mi, mo, "ode")
    if ns is not None:
        return ns
    p = params
    k = 2.0 * dE / dy**2
    c, g = p.c_d, p.g
    M = mi + mo
    mu = mi * mo / M
    md = _Model(k, mi, mo, p)  # used only for the shared rules (bounds), not the dynamics
    L0 = dy
    L_rest = L0 + dy
    A, B = system_matrices(k, mi, mo, c, g, L_rest)
    v_stick = _V_STICK_REL * math.sqrt(2.0 * dE / mu)
    max_step_f = md.rel.dt * _SAMPLES_PER_PERIOD / 20.0
    max_step_r = md.rest.dt * _SAMPLES_PER_PERIOD / 20.0

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

    t = 0.0
    Y = np.array([h, h + L0, 0.0, 0.0])
    ymax, tpeak = h, 0.0
    n_contacts = 0
    lift_off = False
    complete = False
    resting = h == 0.0 and ev_lift(0.0, Y[[1, 3]]) <= 0.0
    opts = dict(method="DOP853", rtol=rtol, atol=atol, dense_output=False)

    while True:
        e, ed = Y[1] - Y[0] - L_rest, Y[3] - Y[2]
        if md.height_bound(Y[0], Y[2], e, ed) <= ymax:
            complete = True
            break
        if t >= p.t_max or n_contacts >= p.max_contacts:
            break
        if not resting:
            if Y[0] == 0.0:
                lift_off = True
            a0 = (k * e + c * ed) / mi - g
            first = max_step_f * 1e-4
            if Y[0] == 0.0 and Y[2] > 0.0 and a0 < 0.0:
                first = min(first, (2.0 * Y[2] / -a0) / 16.0)
            sol = solve_ivp(rhs_flight, (t, p.t_max), Y, events=[ev_contact, ev_apex],
                            max_step=max_step_f, first_step=first, **opts)
            for ta, Ya in zip(sol.t_events[1], sol.y_events[1]):
                if Ya[0] > ymax:
                    ymax, tpeak = float(Ya[0]), float(ta)
            if sol.status != 1:
                t, Y = p.t_max, sol.y[:, -1]
                continue
            t = float(sol.t_events[0][0])
            Yc = sol.y_events[0][0].copy()
            n_contacts += 1
            vm = min(Yc[2], 0.0)
            vp = -p.alpha * vm
            Y = np.array([0.0, Yc[1], vp, Yc[3]])
            e = Y[1] - L_rest
            if vp <= v_stick and (k * e + c * (Y[3] - vp)) / mi - g <= 0.0:
                Y[2] = 0.0
                resting = True
            else:
                lift_off = True
        else:
            Z = Y[[1, 3]]
            if ev_settle(t, Z) < 0.0:
                complete = True
                break
            sol = solve_ivp(rhs_rest, (t, p.t_max), Z, events=[ev_lift, ev_settle],
                            max_step=max_step_r, first_step=max_step_r * 1e-4, **opts)
            if sol.status != 1:
                t, Y = p.t_max, np.array([0.0, sol.y[0, -1], 0.0, sol.y[1, -1]])
                continue
            if sol.t_events[1].size and (not sol.t_events[0].size
                                         or sol.t_events[1][0] <= sol.t_events[0][0]):
                complete = True
                break
            t = float(sol.t_events[0][0])
            Zl = sol.y_events[0][0]
            Y = np.array([0.0, Zl[0], 0.0, Zl[1]])
            resting = False

    return _finish(ymax, tpeak, n_contacts, k, mi, mo, h, lift_off, complete, "ode")
