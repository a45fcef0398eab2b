"""The two-mass jump model in closed form (:mod:`snapjump_cli.jump`): eqs 16-17 in modal coordinates
(:func:`system_matrices`, :func:`eigensystem`). In flight the centre of mass falls freely and the
spring extension is a damped oscillator (:class:`Oscillator`) of reduced mass ``mu = m_i m_o / M``;
while ``m_i`` rests on the ground ``m_o`` alone oscillates about its static equilibrium.
:class:`PhaseModel` evaluates both phase kinds (:class:`Phase`) and holds the shared rules: the
energy bound on later heights and the impossibility of a lift-off; :class:`FlightAt` evaluates one
flight at one time, as the root finders of :mod:`snapjump_cli.jump.events` call it. See the
docstring of :mod:`snapjump_cli.jump.trajectory` for the conventions.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Sequence

import numpy as np

from snapjump_cli.jump.params import check_real

if TYPE_CHECKING:
    from snapjump_cli.jump.params import JumpParams

__all__ = ["spring_stiffness", "system_matrices", "eigensystem"]

#: Rebound speed (relative to sqrt(2 dE / mu)) below which a pressed-down m_i comes to rest.
V_STICK_REL = 1e-7
#: Samples per oscillation period when scanning for contacts, lift-offs and apexes.
SAMPLES_PER_PERIOD = 64


def spring_stiffness(dE_J: float, dy_pole_m: float) -> float:
    """Spring stiffness ``k_s = 2 dE / dy_pole^2`` [N/m] (``0`` if ``dE <= 0`` or ``dy_pole <= 0``)."""
    dE = check_real("dE_J", dE_J)
    dy = check_real("dy_pole_m", dy_pole_m)
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
class Oscillator:
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
        self.dt = period / SAMPLES_PER_PERIOD

    @classmethod
    def stacked(cls, oscs: Sequence[Oscillator]) -> Oscillator:
        """Under-damped ``oscs`` as one oscillator whose constants are columns, one row each.

        Its :meth:`xv` at a 2-D time array evaluates row ``i`` with exactly the operations of
        ``oscs[i]`` (numpy broadcasts element by element). ``D`` stays a number, the smallest:
        every row takes the under-damped branch.
        """
        if not all(o.D > 0.0 for o in oscs):
            raise ValueError("only under-damped oscillators are stacked")
        st = cls.__new__(cls)
        for name in ("m", "c", "k", "sig", "w0sq", "w", "dt"):
            setattr(st, name, np.array([getattr(o, name) for o in oscs])[:, None])
        st.D = min(o.D for o in oscs)
        return st

    def _ec_es(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``exp(-sig t) C(t)``, ``exp(-sig t) S(t)`` and ``exp(-sig t) C(t) - 1`` (accurate)."""
        t = np.asarray(t, dtype=float)
        sig, w = self.sig, self.w
        st = sig * t
        wt = w * t
        if self.D > 0.0:
            E = np.exp(-st)
            cos_wt = np.cos(wt)  # each evaluated once: the scan calls this on long time grids
            EC = E * cos_wt
            ES = E * np.sin(wt) / w
            ECm1 = np.expm1(-st) * cos_wt - 2.0 * np.sin(0.5 * wt) ** 2
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
class Phase:
    """One motion phase: ``kind`` ``"flight"`` (both free) or ``"rest"`` (m_i on the ground)."""

    kind: str
    t0: float
    t1: float
    y0: float   # y_i at t0
    v0: float   # v_i at t0
    e0: float   # spring extension at t0
    ed0: float  # extension rate at t0


class PhaseModel:
    """Closed-form evaluation of both phase kinds for one parameter set."""

    def __init__(self, k: float, m_i: float, m_o: float, p: JumpParams) -> None:
        self.k, self.m_i, self.m_o, self.p = k, m_i, m_o, p
        self.M = m_i + m_o
        self.r = m_o / self.M
        self.mu = m_i * m_o / self.M
        self.g = p.g
        self.c = p.c_d
        self.rel = Oscillator(self.mu, p.c_d, k)          # flight: relative motion
        self.rest = Oscillator(m_o, p.c_d, k)             # m_i resting: m_o about equilibrium
        self.e_eq = -m_o * p.g / k                  # static extension while m_i rests

    # ---- flight ----
    def flight(self, ph: Phase, t: np.ndarray) -> tuple[np.ndarray, ...]:
        """``(y_i, v_i, e, e_dot)`` at local times ``t`` of a flight phase."""
        return flight_state(self.r, self.g, self.rel, ph, t)

    def flight_at(self, ph: Phase) -> FlightAt:
        """The flight phase ``ph`` evaluated at one local time at a time (:class:`FlightAt`)."""
        return FlightAt(self, ph)

    def fall_time_bound(self, ph: Phase) -> float:
        """A local time by which a flight from ``ph`` has surely reached the ground (``inf``
        without gravity).

        ``y_i = y0 + w0 t - g t^2 / 2 - r (x(t) - x0)`` with ``|x(t)| <=`` :meth:`Oscillator.sup_bound`,
        so ``y_i < 0`` once ``y0 + r (|x0| + sup |x|) + w0 t - g t^2 / 2 < 0``.
        """
        if self.g <= 0.0:
            return math.inf
        H = ph.y0 + self.r * (abs(ph.e0) + self.rel.sup_bound(ph.e0, ph.ed0))
        w0 = ph.v0 + self.r * ph.ed0
        return (w0 + math.sqrt(w0 * w0 + 2.0 * self.g * H)) / self.g

    def flight_acc(self, e: float, ed: float) -> float:
        """Acceleration of a free ``m_i`` (spring + dashpot + gravity)."""
        return (self.k * e + self.c * ed) / self.m_i - self.g

    # ---- resting on the ground ----
    def rest_state(self, ph: Phase, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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
        ``sup_future |F| <= `` :meth:`Oscillator.sup_bound` ``< M g`` (a non-increasing quantity).
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



def flight_state(r: float | np.ndarray, g: float | np.ndarray, osc: Oscillator, ph: Phase,
            t: np.ndarray) -> tuple[np.ndarray, ...]:
    """``(y_i, v_i, e, e_dot)`` at local times ``t`` of a flight phase (:meth:`PhaseModel.flight`).

    With column constants (``r``, ``g``, ``ph``'s numbers, :meth:`Oscillator.stacked`) and a 2-D
    ``t``, many flights at once, row by row (:mod:`snapjump_cli.jump.batch`).
    """
    t = np.asarray(t, dtype=float)
    w0 = ph.v0 + r * ph.ed0  # centre-of-mass velocity
    de, e, ed = osc.xv(ph.e0, ph.ed0, t)
    y = ph.y0 + w0 * t - 0.5 * g * t * t - r * de
    v = w0 - g * t - r * ed
    return y, v, e, ed


class FlightAt:
    """``y_i``, ``v_i`` and the whole state of one flight phase at one local time ``t``, as floats.

    They are what the root finders call (most of the model's evaluations), so the phase's
    constants are bound once and the scalar is never wrapped in an array. Every value equals
    the general form's ``float(PhaseModel.flight(ph, t)[j])`` to the bit: the same operations in the
    same order, numpy's ``exp``/``expm1``/``sin``/``cos`` (``math``'s differ from them in the
    last bit) and the scalar ``** 2`` (``pow``, which rounds differently from the arrays'
    ``square``: the array form can differ from both in the last bit).
    """

    def __init__(self, md: PhaseModel, ph: Phase) -> None:
        osc = self.osc = md.rel
        self.md, self.ph = md, ph
        # never the case for a real design: the general path, unhurried
        self.general = osc.D <= 0.0
        self.sig, self.w, self.g, self.r = osc.sig, osc.w, md.g, md.r
        self.x0, self.v0, self.y0 = ph.e0, ph.ed0, ph.y0
        self.w0 = ph.v0 + md.r * ph.ed0             # as in PhaseModel.flight
        self.b = self.v0 + osc.sig * self.x0          # as in Oscillator.xv: dx = x0 ECm1 + b ES
        self.c = osc.sig * self.v0 + osc.w0sq * self.x0  # v = v0 EC - c ES
        self.hg = 0.5 * md.g

    # numpy's exp, expm1, sin, cos of one number, turned into Python floats at once: arithmetic
    # on floats is several times cheaper than on numpy scalars and rounds the same (``x ** 2``
    # is ``pow`` on both)
    def y(self, t: float) -> float:
        """``y_i(t)``."""
        if self.general:
            return float(self.md.flight(self.ph, t)[0])
        t = float(t)
        st = self.sig * t
        wt = self.w * t
        ES = float(np.exp(-st)) * float(np.sin(wt)) / self.w
        ECm1 = float(np.expm1(-st)) * float(np.cos(wt)) - 2.0 * float(np.sin(0.5 * wt)) ** 2
        return self.y0 + self.w0 * t - self.hg * t * t - self.r * (self.x0 * ECm1 + self.b * ES)

    def v(self, t: float) -> float:
        """``v_i(t)``."""
        if self.general:
            return float(self.md.flight(self.ph, t)[1])
        t = float(t)
        st = self.sig * t
        wt = self.w * t
        E = float(np.exp(-st))
        ES = E * float(np.sin(wt)) / self.w
        return self.w0 - self.g * t - self.r * (self.v0 * (E * float(np.cos(wt))) - self.c * ES)

    def state(self, t: float) -> tuple[float, float, float, float]:
        """``(y_i, v_i, e, e_dot)`` at ``t``."""
        if self.general:
            return tuple(float(a) for a in self.md.flight(self.ph, t))  # type: ignore[return-value]
        t = float(t)
        st = self.sig * t
        wt = self.w * t
        E = float(np.exp(-st))
        cos_wt = float(np.cos(wt))
        ES = E * float(np.sin(wt)) / self.w
        ECm1 = float(np.expm1(-st)) * cos_wt - 2.0 * float(np.sin(0.5 * wt)) ** 2
        dx = self.x0 * ECm1 + self.b * ES
        ed = self.v0 * (E * cos_wt) - self.c * ES
        y = self.y0 + self.w0 * t - self.hg * t * t - self.r * dx
        v = self.w0 - self.g * t - self.r * ed
        return y, v, self.x0 + dx, ed
