"""Impacts, lift-offs and apexes of the two-mass jump model, located on its closed form
(:mod:`snapjump_cli.jump.closed_form`).

They are located by sampling on a grid far finer than the oscillation period (:func:`time_grid`)
and root finding (:func:`first_fall`, :func:`maxima`), one phase at a time (:func:`scan_flight`,
:func:`scan_rest`). The flight scan asks for its samples (it is a generator, :data:`Request`), so
that :mod:`snapjump_cli.jump.batch` can answer many designs' scans at once; the root finders'
scalar evaluations are done in place (:class:`~snapjump_cli.jump.closed_form.FlightAt`).
"""
from __future__ import annotations

import itertools
import math
from typing import Callable, Generator, Iterator, Sequence

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from snapjump_cli.jump.closed_form import Phase, PhaseModel


CHUNK = 4096
#: Samples in the first piece of a chunk sampled by the flight scan (:func:`samples_to_fall`)
#: and fewest in the next: most flights on the ground again within 32 samples (rebounds), the
#: others much later, before :meth:`PhaseModel.fall_time_bound`, where the second piece ends.
_PIECE_FIRST = 32
_PIECE_MIN = 16
_STEPS = np.arange(1.0, CHUNK + 1.0)  # j of the chunks' times base + dt j
_STEPS.flags.writeable = False
#: Relative tolerance of the root finders (``brentq``).
_RTOL = 4 * np.finfo(float).eps


class Chunk:
    """The sample times of one chunk of the time grid (:func:`time_grid`), made on demand.

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


def time_grid(h0: float, dt: float, t_end: float) -> Iterator[Chunk]:
    """Yield chunks of increasing sample times in ``(0, t_end]`` (the last one ends at ``t_end``).

    Steps grow geometrically from ``h0`` up to ``dt`` and then stay at ``dt``.
    """
    h0 = min(h0, dt)
    n_geo = int(math.ceil(math.log2(dt / h0))) if h0 < dt else 0
    # the running sum of h0 2^k in Python floats (a few numbers: cheaper than numpy, the same sums)
    head = np.array(list(itertools.accumulate(h0 * 2.0**k for k in range(n_geo))))
    base = float(head[-1]) if head.size else 0.0
    while True:
        chunk = Chunk(head, base, dt, CHUNK, t_end)
        yield chunk
        if chunk.ends:
            return
        head, base = _NO_TIMES, chunk.last_step


# Indices where samples change in a given way: for short arrays (most of the flights' scans)
# a loop over Python floats, as numpy's cost per call is then most of the work; the same
# comparisons either way (NaN compares false in both).
#: Longest array scanned as a list of floats.
_SHORT = 64


def down_crossings(a: np.ndarray | list[float]) -> Sequence[int]:
    """Indices ``k`` with ``a[k] > 0`` and ``a[k + 1] <= 0``, increasing."""
    if isinstance(a, list):
        return [k for k in range(len(a) - 1) if a[k] > 0.0 and a[k + 1] <= 0.0]
    return ((a[:-1] > 0.0) & (a[1:] <= 0.0)).nonzero()[0]


def sampled_minima(a: np.ndarray | list[float]) -> Sequence[int]:
    """Indices ``k`` (not the ends) with ``a[k] <= a[k - 1]``, ``a[k] < a[k + 1]`` and ``a[k] > 0``."""
    if isinstance(a, list):
        return [k for k in range(1, len(a) - 1) if a[k] <= a[k - 1] and a[k] < a[k + 1] and a[k] > 0.0]
    mid = a[1:-1]
    return ((mid <= a[:-2]) & (mid < a[2:]) & (mid > 0.0)).nonzero()[0] + 1


def sampled_maxima(a: np.ndarray | list[float]) -> Sequence[int]:
    """Indices ``k`` (not the ends) with ``a[k] >= a[k - 1]`` and ``a[k] > a[k + 1]``."""
    if isinstance(a, list):
        return [k for k in range(1, len(a) - 1) if a[k] >= a[k - 1] and a[k] > a[k + 1]]
    mid = a[1:-1]
    return ((mid >= a[:-2]) & (mid > a[2:])).nonzero()[0] + 1


def first_fall(F: Callable[[float], float], dF: Callable[[float], float],
                T: np.ndarray, Fv: np.ndarray, dFv: np.ndarray) -> float | None:
    """First time after ``T[0]`` at which ``F`` (``>= 0`` at ``T[0]``) reaches ``<= 0``, or ``None``.

    Looks at sign changes between samples and at sampled local minima (refined to the root of
    ``dF``) so that grazing dips between samples are not missed. ``T[0]`` itself is excluded.
    """
    n = T.size
    best: float | None = None
    Fs = Fv.tolist() if n <= _SHORT else Fv
    down = down_crossings(Fs)
    if len(down):
        k = int(down[0])
        best_bracket = (T[k], T[k + 1])
        best = best_bracket[1]
    # sampled local minima with positive value: refine
    if n >= 3:
        for k in sampled_minima(Fs):
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


def maxima(F: Callable[[float], float], dF: Callable[[float], float], T: np.ndarray,
            Fv: np.ndarray, dFv: np.ndarray, skip: int = 0) -> list[tuple[float, float]]:
    """Local maxima ``(t, F(t))`` of ``F`` on ``[T[0], T[-1]]``.

    Roots of ``dF`` where it changes sign ``+ -> -`` between samples, plus sampled local maxima
    without such a sign change next to them (refined by bounded minimisation). Intervals and
    samples with index ``< skip`` are ignored (already handled with the previous chunk).
    """
    out: list[tuple[float, float]] = []
    short = T.size <= _SHORT
    covered: set[int] = set()
    for k in down_crossings(dFv.tolist() if short else dFv):
        covered.update((int(k), int(k) + 1))
        if k < skip:
            continue
        a, b = T[k], T[k + 1]
        t = b if dFv[k + 1] == 0.0 else brentq(dF, a, b, xtol=1e-300, rtol=_RTOL)
        out.append((float(t), float(F(t))))
    if T.size >= 3:
        for k in sampled_maxima(Fv.tolist() if short else Fv):
            if k - 1 < skip or k in covered or (k - 1) in covered:
                continue
            a, b = float(T[k - 1]), float(T[k + 1])
            res = minimize_scalar(lambda s: -F(s), bounds=(a, b), method="bounded",
                                  options={"xatol": 1e-13 * max(b, 1e-300)})
            t = float(res.x) if -res.fun > Fv[k] else float(T[k])
            out.append((t, float(F(t))))
    return out


#: A request of the flight scan (a generator): ``(key, t)`` asks for ``(y_i, v_i)`` of the flight
#: ``key`` (a :class:`FlightAt`) at the times ``t`` (an array), to be sent back into it.
Request = tuple[object, np.ndarray]
Samples = tuple[np.ndarray, np.ndarray]


def scan_flight(md: "PhaseModel", ph: "Phase", t_avail: float,
                 h0: float) -> Generator[Request, Samples, tuple[float | None, list[tuple[float, float]]]]:
    """First impact (local time, or ``None`` before ``t_avail``) and the apexes before it.

    A generator: the flight's values on the time grid are asked for (:data:`Request`) rather
    than computed here, so that the scans of many designs can be answered together
    (:mod:`snapjump_cli.jump.batch`); the scalar evaluations of the root finders are done here.
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
    for chunk in time_grid(h0, md.rel.dt, t_avail):
        # a short piece, then up to where the impact must have come: a guess of the work only,
        # any piece sizes give the same answer
        n_fall = chunk.count_before(t_fall) + 2
        first = min(n_fall, _PIECE_FIRST)
        T, Yv, Vv, t_hit = yield from samples_to_fall(at, Fy, Fv, chunk, T_prev, Y_prev, V_prev,
                                                       first, max(n_fall - first, _PIECE_MIN))
        if t_hit is not None:  # cut at the impact (the samples before it are a prefix)
            m = int(np.searchsorted(T, t_hit))
            T, Yv, Vv = T[:m + 1], Yv[:m + 1], Vv[:m + 1]  # samples_to_fall's own arrays
            T[m], Yv[m], Vv[m] = t_hit, 0.0, Fv(t_hit)
        apexes.extend(maxima(Fy, Fv, T, Yv, Vv, skip=T_prev.size - 1))
        if t_hit is not None:
            return t_hit, apexes
        T_prev, Y_prev, V_prev = T[-2:], Yv[-2:], Vv[-2:]
    return None, apexes


def samples_to_fall(key: object, F: Callable[[float], float], dF: Callable[[float], float],
                     chunk: Chunk, T_prev: np.ndarray, F_prev: np.ndarray,
                     dF_prev: np.ndarray, piece: int, then: int
                     ) -> Generator[Request, Samples, tuple[np.ndarray, np.ndarray, np.ndarray, float | None]]:
    """``T = [T_prev, chunk]`` with ``F``, ``dF`` sampled on it (``F_prev``, ``dF_prev`` at
    ``T_prev``) up to the first fall of ``F`` to ``<= 0``, and that time (:func:`first_fall` on
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
        t_fall = first_fall(F, dF, T[k:hi], Fv[k:hi], dFv[k:hi])
        if t_fall is not None:
            return T[:hi], Fv[:hi], dFv[:hi], t_fall
        lo, size, size_next = hi, size_next, 2 * size_next
    return T, Fv, dFv, None


def scan_rest(md: "PhaseModel", ph: "Phase", t_avail: float,
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
    for ch in time_grid(md.rest.dt * 1e-4, md.rest.dt, t_avail):
        chunk = ch.times(0, ch.size)
        Ec, EDc = md.rest_state(ph, chunk)
        T = np.concatenate([T_prev, chunk])
        Fv = np.concatenate([F_prev, -md.lift_force(Ec, EDc)])
        Dv = np.concatenate([D_prev, -(md.k * EDc + md.c * md.rest.acc(Ec - md.e_eq, EDc))])
        t_lift = first_fall(Ff, dFf, T, Fv, Dv)
        if t_lift is not None:
            return "lift", t_lift
        e_end, ed_end = float(Ec[-1]), float(EDc[-1])
        if not md.can_lift(e_end, ed_end) or md.height_bound(0.0, 0.0, e_end, ed_end) <= ymax:
            return "settled", float(chunk[-1])
        T_prev, F_prev, D_prev = T[-2:], Fv[-2:], Dv[-2:]
    return "timeout", t_avail
