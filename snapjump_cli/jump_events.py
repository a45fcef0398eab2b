"""Closed-form phases and event location of the two-mass jump model (:mod:`snapjump_cli.jump`).

Eqs 16-17 in modal coordinates (:func:`system_matrices`, :func:`eigensystem`): in flight the
centre of mass falls freely and the spring extension is a damped oscillator (:class:`_Osc`) of
reduced mass ``mu = m_i m_o / M``; while ``m_i`` rests on the ground ``m_o`` alone oscillates
about its static equilibrium. :class:`_Model` evaluates both phase kinds (:class:`_Phase`) and
holds the shared rules: the energy bound on later heights and the impossibility of a lift-off.
Impacts, lift-offs and apexes are located by sampling on a grid far finer than the oscillation
period (:func:`_time_grid`) and root finding (:func:`_first_fall`, :func:`_maxima`), one phase
at a time (:func:`_scan_flight`, :func:`_scan_rest`). The flight scan asks for its samples
(it is a generator, :data:`Request`), so that :mod:`snapjump_cli.jump_batch` can answer many
designs' scans at once; the root finders' scalar evaluations are done in place (:class:`_FlightAt`).
See the docstring of :mod:`snapjump_cli.jump` for the conventions.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable, Generator, Iterator, Sequence

import numpy as np
from scipy.optimize import brentq, minimize_scalar

if TYPE_CHECKING:
    from snapjump_cli.jump_params import JumpParams

__all__ = ["system_matrices", "eigensystem"]

#: Rebound speed (relative to sqrt(2 dE / mu)) below which a pressed-down m_i comes to rest.
_V_STICK_REL = 1e-7
#: Samples per oscillation period when scanning for contacts, lift-offs and apexes.
_SAMPLES_PER_PERIOD = 64
_CHUNK = 4096
#: Samples in the first piece of a chunk sampled by the flight scan (:func:`_samples_to_fall`)
#: and fewest in the next: most flights on the ground again within 32 samples (rebounds), the
#: others much later, before :meth:`_Model.fall_time_bound`, where the second piece ends.
_PIECE_FIRST = 32
_PIECE_MIN = 16
_STEPS = np.arange(1.0, _CHUNK + 1.0)  # j of the chunks' times base + dt j
_STEPS.flags.writeable = False
#: Relative tolerance of the root finders (``brentq``).
_RTOL = 4 * np.finfo(float).eps


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

    @classmethod
    def stacked(cls, oscs: Sequence[_Osc]) -> _Osc:
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
        return _flight(self.r, self.g, self.rel, ph, t)

    def flight_at(self, ph: _Phase) -> _FlightAt:
        """The flight phase ``ph`` evaluated at one local time at a time (:class:`_FlightAt`)."""
        return _FlightAt(self, ph)

    def fall_time_bound(self, ph: _Phase) -> float:
        """A local time by which a flight from ``ph`` has surely reached the ground (``inf``
        without gravity).

        ``y_i = y0 + w0 t - g t^2 / 2 - r (x(t) - x0)`` with ``|x(t)| <=`` :meth:`_Osc.sup_bound`,
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



def _flight(r: float | np.ndarray, g: float | np.ndarray, osc: _Osc, ph: _Phase,
            t: np.ndarray) -> tuple[np.ndarray, ...]:
    """``(y_i, v_i, e, e_dot)`` at local times ``t`` of a flight phase (:meth:`_Model.flight`).

    With column constants (``r``, ``g``, ``ph``'s numbers, :meth:`_Osc.stacked`) and a 2-D
    ``t``, many flights at once, row by row (:mod:`snapjump_cli.jump_batch`).
    """
    t = np.asarray(t, dtype=float)
    w0 = ph.v0 + r * ph.ed0  # centre-of-mass velocity
    de, e, ed = osc.xv(ph.e0, ph.ed0, t)
    y = ph.y0 + w0 * t - 0.5 * g * t * t - r * de
    v = w0 - g * t - r * ed
    return y, v, e, ed


class _FlightAt:
    """``y_i``, ``v_i`` and the whole state of one flight phase at one local time ``t``, as floats.

    They are what the root finders call (most of the model's evaluations), so the phase's
    constants are bound once and the scalar is never wrapped in an array. Every value equals
    the general form's ``float(_Model.flight(ph, t)[j])`` to the bit: the same operations in the
    same order, numpy's ``exp``/``expm1``/``sin``/``cos`` (``math``'s differ from them in the
    last bit) and the scalar ``** 2`` (``pow``, which rounds differently from the arrays'
    ``square``: the array form can differ from both in the last bit).
    """

    def __init__(self, md: _Model, ph: _Phase) -> None:
        osc = self.osc = md.rel
        self.md, self.ph = md, ph
        # never the case for a real design: the general path, unhurried
        self.general = osc.D <= 0.0
        self.sig, self.w, self.g, self.r = osc.sig, osc.w, md.g, md.r
        self.x0, self.v0, self.y0 = ph.e0, ph.ed0, ph.y0
        self.w0 = ph.v0 + md.r * ph.ed0             # as in _Model.flight
        self.b = self.v0 + osc.sig * self.x0          # as in _Osc.xv: dx = x0 ECm1 + b ES
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


class _Chunk:
    """The sample times of one chunk of the time grid (:func:`_time_grid`), made on demand.

    ``head``, then ``base + dt * j`` for ``j = 1 .. n_steps``; only the times before ``t_end``
    are kept, and if any is not, ``t_end`` itself ends the chunk (and the grid). A flight is
    usually on the ground again within a few hundred of a chunk's ~4100 times, so they are made
    piece by piece (:meth:`times`), each the number the whole array would hold (``base + dt j``
    is computed the same way element by element).
    """

    def __init__(self, head: np.ndarray, base: float, dt: float, n_steps: int, t_end: float) -> None:
        self.base, self.dt, self.t_end = base, dt, t_end
        n_head = int(np.searchsorted(head, t_end))  # the times never decrease
        if n_head < head.size:
            n_steps, self.ends = 0, True
        else:
            n_steps_before = self._steps_before(t_end, n_steps)
            self.ends = n_steps_before < n_steps
            n_steps = n_steps_before
        self.head = head[:n_head]
        self.n_head, self.n_steps = n_head, n_steps
        self.size = n_head + n_steps + self.ends
        self.last_step = base + dt * float(n_steps)  # the next chunk's base (if this one is whole)

    def _steps_before(self, t: float, n_steps: int) -> int:
        """How many of ``base + dt * j`` (``j = 1 .. n_steps``) are ``< t``."""
        base, dt = self.base, self.dt
        if base + dt * float(n_steps) < t:
            return n_steps
        # an estimate, then set right on the exact values (they never decrease)
        j = min(max(int((t - base) / dt), 0), n_steps)
        while j < n_steps and base + dt * float(j + 1) < t:
            j += 1
        while j > 0 and not base + dt * float(j) < t:
            j -= 1
        return j

    def count_before(self, t: float) -> int:
        """How many of the chunk's times are ``< t``."""
        n = int(np.searchsorted(self.head, t))
        if n < self.n_head:
            return n
        n += self._steps_before(t, self.n_steps)
        return n + (n == self.size - 1 and self.ends and self.t_end < t)

    def times(self, lo: int, hi: int) -> np.ndarray:
        """The chunk's times ``lo`` to ``hi - 1``."""
        parts = []
        if lo < self.n_head:
            parts.append(self.head[lo:hi])
        a, b = max(lo - self.n_head, 0), min(hi - self.n_head, self.n_steps)
        if a < b:
            parts.append(self.base + self.dt * _STEPS[a:b])
        if self.ends and hi >= self.size:
            parts.append(np.array([self.t_end]))
        return parts[0] if len(parts) == 1 else np.concatenate(parts)


_NO_TIMES = np.empty(0)


def _time_grid(h0: float, dt: float, t_end: float) -> Iterator[_Chunk]:
    """Yield chunks of increasing sample times in ``(0, t_end]`` (the last one ends at ``t_end``).

    Steps grow geometrically from ``h0`` up to ``dt`` and then stay at ``dt``.
    """
    h0 = min(h0, dt)
    n_geo = int(math.ceil(math.log2(dt / h0))) if h0 < dt else 0
    # the running sum of h0 2^k in Python floats (a few numbers: cheaper than numpy, the same sums)
    head = np.array(list(itertools.accumulate(h0 * 2.0**k for k in range(n_geo))))
    base = float(head[-1]) if head.size else 0.0
    while True:
        chunk = _Chunk(head, base, dt, _CHUNK, t_end)
        yield chunk
        if chunk.ends:
            return
        head, base = _NO_TIMES, chunk.last_step


# Indices where samples change in a given way: for short arrays (most of the flights' scans)
# a loop over Python floats, as numpy's cost per call is then most of the work; the same
# comparisons either way (NaN compares false in both).
#: Longest array scanned as a list of floats.
_SHORT = 64


def _down_crossings(a: np.ndarray | list[float]) -> Sequence[int]:
    """Indices ``k`` with ``a[k] > 0`` and ``a[k + 1] <= 0``, increasing."""
    if isinstance(a, list):
        return [k for k in range(len(a) - 1) if a[k] > 0.0 and a[k + 1] <= 0.0]
    return ((a[:-1] > 0.0) & (a[1:] <= 0.0)).nonzero()[0]


def _sampled_minima(a: np.ndarray | list[float]) -> Sequence[int]:
    """Indices ``k`` (not the ends) with ``a[k] <= a[k - 1]``, ``a[k] < a[k + 1]`` and ``a[k] > 0``."""
    if isinstance(a, list):
        return [k for k in range(1, len(a) - 1) if a[k] <= a[k - 1] and a[k] < a[k + 1] and a[k] > 0.0]
    mid = a[1:-1]
    return ((mid <= a[:-2]) & (mid < a[2:]) & (mid > 0.0)).nonzero()[0] + 1


def _sampled_maxima(a: np.ndarray | list[float]) -> Sequence[int]:
    """Indices ``k`` (not the ends) with ``a[k] >= a[k - 1]`` and ``a[k] > a[k + 1]``."""
    if isinstance(a, list):
        return [k for k in range(1, len(a) - 1) if a[k] >= a[k - 1] and a[k] > a[k + 1]]
    mid = a[1:-1]
    return ((mid >= a[:-2]) & (mid > a[2:])).nonzero()[0] + 1


def _first_fall(F: Callable[[float], float], dF: Callable[[float], float],
                T: np.ndarray, Fv: np.ndarray, dFv: np.ndarray) -> float | None:
    """First time after ``T[0]`` at which ``F`` (``>= 0`` at ``T[0]``) reaches ``<= 0``, or ``None``.

    Looks at sign changes between samples and at sampled local minima (refined to the root of
    ``dF``) so that grazing dips between samples are not missed. ``T[0]`` itself is excluded.
    """
    n = T.size
    best: float | None = None
    Fs = Fv.tolist() if n <= _SHORT else Fv
    down = _down_crossings(Fs)
    if len(down):
        k = int(down[0])
        best_bracket = (T[k], T[k + 1])
        best = best_bracket[1]
    # sampled local minima with positive value: refine
    if n >= 3:
        for k in _sampled_minima(Fs):
            if best is not None and T[k - 1] >= best:
                break
            a, b = T[k - 1], T[k + 1]
            if not (dFv[k - 1] < 0.0 < dFv[k + 1]):
                continue
            tm = brentq(dF, a, b, xtol=1e-300, rtol=_RTOL)
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
    return float(brentq(F, a, b, xtol=1e-300, rtol=_RTOL))


def _maxima(F: Callable[[float], float], dF: Callable[[float], float], T: np.ndarray,
            Fv: np.ndarray, dFv: np.ndarray, skip: int = 0) -> list[tuple[float, float]]:
    """Local maxima ``(t, F(t))`` of ``F`` on ``[T[0], T[-1]]``.

    Roots of ``dF`` where it changes sign ``+ -> -`` between samples, plus sampled local maxima
    without such a sign change next to them (refined by bounded minimisation). Intervals and
    samples with index ``< skip`` are ignored (already handled with the previous chunk).
    """
    out: list[tuple[float, float]] = []
    short = T.size <= _SHORT
    covered: set[int] = set()
    for k in _down_crossings(dFv.tolist() if short else dFv):
        covered.update((int(k), int(k) + 1))
        if k < skip:
            continue
        a, b = T[k], T[k + 1]
        t = b if dFv[k + 1] == 0.0 else brentq(dF, a, b, xtol=1e-300, rtol=_RTOL)
        out.append((float(t), float(F(t))))
    if T.size >= 3:
        for k in _sampled_maxima(Fv.tolist() if short else Fv):
            if k - 1 < skip or k in covered or (k - 1) in covered:
                continue
            a, b = float(T[k - 1]), float(T[k + 1])
            res = minimize_scalar(lambda s: -F(s), bounds=(a, b), method="bounded",
                                  options={"xatol": 1e-13 * max(b, 1e-300)})
            t = float(res.x) if -res.fun > Fv[k] else float(T[k])
            out.append((t, float(F(t))))
    return out


#: A request of the flight scan (a generator): ``(key, t)`` asks for ``(y_i, v_i)`` of the flight
#: ``key`` (a :class:`_FlightAt`) at the times ``t`` (an array), to be sent back into it.
Request = tuple[object, np.ndarray]
Samples = tuple[np.ndarray, np.ndarray]


def _scan_flight(md: "_Model", ph: "_Phase", t_avail: float,
                 h0: float) -> Generator[Request, Samples, tuple[float | None, list[tuple[float, float]]]]:
    """First impact (local time, or ``None`` before ``t_avail``) and the apexes before it.

    A generator: the flight's values on the time grid are asked for (:data:`Request`) rather
    than computed here, so that the scans of many designs can be answered together
    (:mod:`snapjump_cli.jump_batch`); the scalar evaluations of the root finders are done here.
    """
    at = md.flight_at(ph)
    Fy, Fv = at.y, at.v
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
    t_fall = md.fall_time_bound(ph)
    for chunk in _time_grid(h0, md.rel.dt, t_avail):
        # a short piece, then up to where the impact must have come: a guess of the work only,
        # any piece sizes give the same answer
        n_fall = chunk.count_before(t_fall) + 2
        first = min(n_fall, _PIECE_FIRST)
        T, Yv, Vv, t_hit = yield from _samples_to_fall(at, Fy, Fv, chunk, T_prev, Y_prev, V_prev,
                                                       first, max(n_fall - first, _PIECE_MIN))
        if t_hit is not None:  # cut at the impact (the samples before it are a prefix)
            m = int(np.searchsorted(T, t_hit))
            T, Yv, Vv = T[:m + 1], Yv[:m + 1], Vv[:m + 1]  # _samples_to_fall's own arrays
            T[m], Yv[m], Vv[m] = t_hit, 0.0, Fv(t_hit)
        apexes.extend(_maxima(Fy, Fv, T, Yv, Vv, skip=T_prev.size - 1))
        if t_hit is not None:
            return t_hit, apexes
        T_prev, Y_prev, V_prev = T[-2:], Yv[-2:], Vv[-2:]
    return None, apexes


def _samples_to_fall(key: object, F: Callable[[float], float], dF: Callable[[float], float],
                     chunk: _Chunk, T_prev: np.ndarray, F_prev: np.ndarray,
                     dF_prev: np.ndarray, piece: int, then: int
                     ) -> Generator[Request, Samples, tuple[np.ndarray, np.ndarray, np.ndarray, float | None]]:
    """``T = [T_prev, chunk]`` with ``F``, ``dF`` sampled on it (``F_prev``, ``dF_prev`` at
    ``T_prev``) up to the first fall of ``F`` to ``<= 0``, and that time (:func:`_first_fall` on
    the whole of ``T``; ``None``: none, all of ``T`` sampled).

    A generator: it yields ``(key, t)`` and expects ``(F(t), dF(t))`` (arrays) sent back.
    The first fall (a flight's impact) usually comes within a few hundred of a chunk's ~4100
    samples, so the chunk is sampled in pieces of ``piece``, ``then``, twice that, ... samples,
    each scanned with the two samples before it, until one holds the fall. That finds what the
    whole chunk gives: every sample is interior to exactly one piece (local minima), every pair
    of neighbours lies in one (sign changes), the pieces are scanned in time order and refined
    with the same brackets, and each sample is the same number (the formulas are element-wise).
    The arrays returned are new (the caller may overwrite them).
    """
    p = T_prev.size
    n = p + chunk.size
    # room for the first two pieces (usually all that is sampled: many scans are alive at once
    # in jump_batch), for the whole chunk only if more is needed
    T, Fv, dFv = (np.empty(min(n, p + piece + then)) for _ in range(3))
    T[:p], Fv[:p], dFv[:p] = T_prev, F_prev, dF_prev
    lo, size, size_next = p, piece, then
    while lo < n:
        hi = min(lo + size, n)
        if hi > T.size:
            T, Fv, dFv = (np.concatenate([a[:lo], np.empty(n - lo)]) for a in (T, Fv, dFv))
        T[lo:hi] = chunk.times(lo - p, hi - p)
        Fv[lo:hi], dFv[lo:hi] = yield key, T[lo:hi]
        k = max(lo - 2, 0)
        t_fall = _first_fall(F, dF, T[k:hi], Fv[k:hi], dFv[k:hi])
        if t_fall is not None:
            return T[:hi], Fv[:hi], dFv[:hi], t_fall
        lo, size, size_next = hi, size_next, 2 * size_next
    return T, Fv, dFv, None


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
    for ch in _time_grid(md.rest.dt * 1e-4, md.rest.dt, t_avail):
        chunk = ch.times(0, ch.size)
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
