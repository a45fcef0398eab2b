"""Symmetric banded LDL^T (no pivoting) for the tangent stiffness, with its inertia.

Storage: the lower band of a symmetric matrix, column by column: ``ab`` of shape ``(n, kl + 1)``
with ``A[i, j] = ab[j, i - j]`` for ``0 <= i - j <= kl`` (the transpose of LAPACK's ``'L'`` band
storage, so that the inner loops run over contiguous memory).

Envelope: ``ext[j]`` is the number of entries below the diagonal of column ``j`` that can be
non-zero in ``L`` (every row ``r <= j + ext[j]`` whose first non-zero lies at or left of ``j``; see
:func:`envelope_extents`; ``j + ext[j]`` never decreases). LDL^T creates no fill outside the rows'
envelope, so the kernels touch only those entries: the arithmetic on them is exactly that of the
plain band algorithm (the skipped terms are exact zeros), at the cost of a profile solver. On the C-shaped actuators the
band is widest only where the ring joins the caps: 3.6-7.5x fewer flops than the full band.

No pivoting: like the LDL^T solvers of commercial FE codes, the factorisation relies on the
stiffness matrix being symmetric with few negative eigenvalues; a pivot that is zero to round-off
is reported as a failure (the continuation then cuts its step). The number of negative pivots is
the number of negative eigenvalues of ``K_T`` (Sylvester's law of inertia), which tells stable
from unstable equilibria.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from snapjump_kernels.band_layout import envelope_extents  # noqa: F401 - numba-free, re-exported


#: Columns per block of :func:`band_ldlt` (its trailing update is a rank-``_NB`` update; the update
#: is written out term by term for 6 columns, any other value takes a generic, slower loop).
_NB = 6


@njit(fastmath={"reassoc", "contract"}, cache=True)
def dot_any_order(a: np.ndarray, b: np.ndarray) -> float:
    """``a @ b`` of two equally long vectors, summed in any order (so that LLVM vectorises it).

    Reassociation and fused multiply-adds only (no assumptions about NaN or infinity), and only
    here: the result differs from the sequential sum by round-off. Also the row products of the
    plain element pass (:func:`snapjump_kernels.element_plain.assemble_plain`, for elements other
    than the grid's Q9).
    """
    s = 0.0
    for k in range(a.size):
        s += a[k] * b[k]
    return s


@njit(cache=True)
def band_ldlt(ab: np.ndarray, ext: np.ndarray):
    """Factorise in place: on return ``ab[:, 0]`` holds ``D`` and ``ab[:, 1:]`` the unit-lower ``L``.

    Blocked right-looking LDL^T: ``_NB`` columns at a time are factorised (each updating the
    block's later columns over all their rows), then the columns below the block, up to the
    block's reach in the envelope, receive the block's rank-``_NB`` update in one pass. The
    arithmetic is that of the column-by-column algorithm with the ``_NB`` updates of an entry
    summed first, in the order of the block's columns. On the actuators the blocking made it
    1.8-1.9x faster than the column algorithm (bench/profile_designs.py@51d9ff8): the column
    algorithm's inner loops are ~20 long, so it was bound by loop overhead and by loading and
    storing the trailing entries once per column.

    The trailing update keeps the block's columns of ``L`` transposed in ``P`` (one contiguous row
    per column) and runs its innermost loop over the rows of two trailing columns at a time, with
    the 6 products of an entry written out, and the loops index views from 0 (an offset index such
    as ``row[r - c]`` kept them scalar): contiguous loops that LLVM vectorises, with the same result
    bit for bit as the blocked loop with the block's columns innermost, and 2.0-2.5x less CPU time
    than it on D and C (455 to 1111 dofs, ``nt = 2`` and ``3``; D, ``nt = 2``: 0.10-0.17 ms instead
    of 0.20-0.34 ms on a shared machine, with one trailing column at a time).

    Returns
    -------
    (ok, n_negative) : (bool, int)
    """
    return _ldlt(ab, ext, ab, False, -1)


@njit(cache=True)
def band_ldlt_into(out: np.ndarray, ext: np.ndarray, src: np.ndarray):
    """:func:`band_ldlt` of the lower band ``src`` with the factors written into ``out`` (same
    shape; ``src`` is not changed): the envelope of each column is copied into ``out`` just before
    the column is first updated (while it is about to be used, instead of in a pass of its own over
    the whole band). Entries outside the envelope are neither read nor written: a buffer that is
    zero there stays a valid band of ``L``. The same factors, bit for bit, as ``band_ldlt`` of a
    copy of ``src``.

    Returns
    -------
    (ok, n_negative) : (bool, int)
    """
    return _ldlt(out, ext, src, True, -1)


@njit(cache=True)
def _ldlt(ab: np.ndarray, ext: np.ndarray, src: np.ndarray, copy: bool, max_neg: int):
    """The LDL^T of :func:`band_ldlt` (in place) and :func:`band_ldlt_into` (``copy``).

    The trailing update of a block, ``A[r, c] -= sum_t L[r, t] d_t L[c, t]`` over the block's 6
    columns ``t`` (summed in their order), runs over two target columns ``c, c + 1`` at a time,
    sharing the loads of ``L[r, t]``: the terms of an entry and their order are those of one target
    column at a time, so the factors are bit for bit those of the column-by-column update (the
    in-place kernel before 2026-11-28, which the multi-harmonic band's copy duplicated).

    With ``copy``, the matrix is read from ``src`` instead: the envelope of each column is copied
    into ``ab`` just before the column is first updated (while it is about to be used, instead
    of in a pass of its own over the whole band).

    With ``max_neg >= 0`` the factorisation stops at the pivot that makes the negative ones more
    than ``max_neg`` (the factors are then incomplete; the count is at least that many).

    Returns
    -------
    (ok, n_negative) : (bool, int); ``ok`` False when a pivot is zero to round-off
    """
    n, m1 = ab.shape
    kl = m1 - 1
    scale = 0.0
    for j in range(n):
        a = abs(src[j, 0])  # the diagonal of the matrix (src is ab without copy)
        if a > scale:
            scale = a
    tiny = 1e-14 * scale
    nneg = 0
    nb = _NB
    P = np.empty((nb, kl + 1))  # P[t, rr] = L[r0 + rr, j0 + t]: the block's columns below the block
    dvec = np.empty(nb)
    copied = 0  # columns 0 .. copied - 1 of src are in ab
    j0 = 0
    while j0 < n:
        b = min(nb, n - j0)
        R = j0  # the block's reach: the last row of its envelope
        for t in range(j0, j0 + b):
            if t + ext[t] > R:
                R = t + ext[t]
        if copy:
            upto = max(R, j0 + b - 1)  # the block's columns and every column it updates
            for c in range(copied, upto + 1):
                m = ext[c] + 1
                dst = ab[c, :m]
                col = src[c, :m]
                for x in range(m):
                    dst[x] = col[x]
            if upto + 1 > copied:
                copied = upto + 1
        # the block's columns, each updating the block's later columns (all their rows)
        for j in range(j0, j0 + b):
            d = ab[j, 0]
            if not (abs(d) > tiny):
                return False, nneg
            if d < 0.0:
                nneg += 1
                if 0 <= max_neg < nneg:
                    return True, nneg
            dvec[j - j0] = d
            m = ext[j]
            colj = ab[j]
            for i in range(1, m + 1):
                colj[i] = colj[i] / d
            for c in range(j + 1, min(j0 + b, j + m + 1)):
                f = colj[c - j] * d
                row = ab[c, :j + m + 1 - c]
                lj = colj[c - j:m + 1]
                for k in range(row.size):
                    row[k] -= lj[k] * f
        # the columns below the block, up to its reach: one rank-b update
        r0 = j0 + b
        if R >= r0:
            h = R - r0 + 1
            for t in range(b):
                jt = j0 + t
                lo = r0 - jt  # the offset of row r0 in column jt
                hi = min(h, max(ext[jt] - lo + 1, 0))  # rows r0 .. r0 + hi - 1 are in its envelope
                p = P[t, :h]
                lt = ab[jt, lo:lo + hi]
                for rr in range(hi):
                    p[rr] = lt[rr]
                for rr in range(hi, h):
                    p[rr] = 0.0
            if b == 6:
                cc = 0
                while cc + 1 < h:  # columns cc and cc + 1: rows cc.. and cc + 1..
                    w0, w1, w2 = P[0, cc] * dvec[0], P[1, cc] * dvec[1], P[2, cc] * dvec[2]
                    w3, w4, w5 = P[3, cc] * dvec[3], P[4, cc] * dvec[4], P[5, cc] * dvec[5]
                    v0, v1, v2 = P[0, cc + 1] * dvec[0], P[1, cc + 1] * dvec[1], P[2, cc + 1] * dvec[2]
                    v3, v4, v5 = P[3, cc + 1] * dvec[3], P[4, cc + 1] * dvec[4], P[5, cc + 1] * dvec[5]
                    ra = ab[r0 + cc, :h - cc]
                    ra[0] -= (P[0, cc] * w0 + P[1, cc] * w1 + P[2, cc] * w2 + P[3, cc] * w3 + P[4, cc] * w4
                              + P[5, cc] * w5)
                    ra = ra[1:]
                    rb = ab[r0 + cc + 1, :h - cc - 1]
                    p0, p1, p2 = P[0, cc + 1:h], P[1, cc + 1:h], P[2, cc + 1:h]
                    p3, p4, p5 = P[3, cc + 1:h], P[4, cc + 1:h], P[5, cc + 1:h]
                    for k in range(h - cc - 1):
                        x0 = p0[k]
                        x1 = p1[k]
                        x2 = p2[k]
                        x3 = p3[k]
                        x4 = p4[k]
                        x5 = p5[k]
                        ra[k] -= x0 * w0 + x1 * w1 + x2 * w2 + x3 * w3 + x4 * w4 + x5 * w5
                        rb[k] -= x0 * v0 + x1 * v1 + x2 * v2 + x3 * v3 + x4 * v4 + x5 * v5
                    cc += 2
                if cc < h:  # the last column, if h is odd
                    row = ab[r0 + cc, :h - cc]
                    p0, p1, p2 = P[0, cc:h], P[1, cc:h], P[2, cc:h]
                    p3, p4, p5 = P[3, cc:h], P[4, cc:h], P[5, cc:h]
                    w0, w1, w2 = p0[0] * dvec[0], p1[0] * dvec[1], p2[0] * dvec[2]
                    w3, w4, w5 = p3[0] * dvec[3], p4[0] * dvec[4], p5[0] * dvec[5]
                    for k in range(h - cc):
                        row[k] -= p0[k] * w0 + p1[k] * w1 + p2[k] * w2 + p3[k] * w3 + p4[k] * w4 + p5[k] * w5
            else:  # a last block of fewer columns (never has rows below it: kept for generality)
                for cc in range(h):
                    row = ab[r0 + cc]
                    for rr in range(cc, h):
                        s = 0.0
                        for t in range(b):
                            s += P[t, rr] * (P[t, cc] * dvec[t])
                        row[rr - cc] -= s
        j0 += b
    return True, nneg


@njit(cache=True)
def _solve_in_place(fac: np.ndarray, x: np.ndarray, ext: np.ndarray) -> None:
    """Overwrite ``x`` with ``A^-1 x`` (the factors of :func:`band_ldlt`)."""
    n = fac.shape[0]
    for j in range(n):  # L y = b (column by column: an axpy), then D z = y
        xj = x[j]
        m = ext[j]
        lj = fac[j, 1:m + 1]
        xs = x[j + 1:j + m + 1]
        for k in range(m):
            xs[k] -= lj[k] * xj
        x[j] = xj / fac[j, 0]
    for j in range(n - 1, -1, -1):  # L^T x = z (row by row: a dot product)
        m = ext[j]
        x[j] -= dot_any_order(fac[j, 1:m + 1], x[j + 1:j + m + 1])


@njit(cache=True)
def band_ldlt_solve(fac: np.ndarray, b: np.ndarray, ext: np.ndarray) -> np.ndarray:
    """Solve ``A x = b`` with the factors from :func:`band_ldlt`.

    The forward substitution runs over the columns of ``L`` (contiguous axpys, with the division
    by ``D`` in the same pass), the backward one over the same columns as rows of ``L^T`` (dot
    products, summed in any order by :func:`dot_any_order`): 1.9-2.2x faster than with sequential sums,
    and equal to them to round-off (against dense numpy: ``bench/profile_designs.py@51d9ff8 --kernels D``).
    """
    x = b.copy()
    _solve_in_place(fac, x, ext)
    return x


@njit(cache=True)
def _matvec_into(ab: np.ndarray, x: np.ndarray, ext: np.ndarray, y: np.ndarray) -> None:
    """``y = A @ x`` for the symmetric matrix whose lower band is ``ab``."""
    n = ab.shape[0]
    y[:] = 0.0
    for j in range(n):
        m = ext[j]
        aj = ab[j, 1:m + 1]
        xj = x[j]
        ys = y[j + 1:j + m + 1]
        for k in range(m):  # the lower triangle: column j
            ys[k] += aj[k] * xj
        y[j] += ab[j, 0] * xj + dot_any_order(aj, x[j + 1:j + m + 1])  # the upper: row j (complete now)


@njit(cache=True)
def sym_band_matvec(ab: np.ndarray, x: np.ndarray, ext: np.ndarray) -> np.ndarray:
    """``A @ x`` for the symmetric matrix whose lower band is ``ab`` (unfactorised).

    Column ``j`` of the lower triangle is an axpy and row ``j`` of the upper one a :func:`dot_any_order`
    (2-2.5x faster than one loop doing both, which cannot vectorise).
    """
    y = np.empty(ab.shape[0])
    _matvec_into(ab, x, ext, y)
    return y


@njit(cache=True)
def bordered_factor(K: np.ndarray, ext: np.ndarray, b: np.ndarray, c: np.ndarray, d: float):
    """Factorise the bordered matrix ``[[K, b], [c^T, d]]`` by block elimination (one call).

    Returns
    -------
    (ok, n_negative, fac, Kib, schur)
        ``fac`` the band LDL^T of ``K`` (a copy; ``K`` is kept for the refinement step),
        ``Kib = K^-1 b``, ``schur = d - c^T K^-1 b``; ``ok`` False if ``K`` is singular to round-off.
    """
    fac = K.copy()
    ok, nneg = band_ldlt(fac, ext)
    if not ok:
        return False, nneg, fac, np.zeros(0), 0.0
    Kib = band_ldlt_solve(fac, b, ext)
    schur = d - np.dot(c, Kib)
    return True, nneg, fac, Kib, schur


@njit(cache=True)
def bordered_factor_into(K: np.ndarray, ext: np.ndarray, b: np.ndarray, c: np.ndarray, d: float,
                         fac: np.ndarray):
    """Factorise the bordered matrix ``[[K, b], [c^T, d]]`` as :func:`bordered_factor` does (the
    same results bit for bit), with the band LDL^T of ``K`` written into ``fac`` (same shape as
    ``K``; :func:`band_ldlt_into`: only its envelope is written, so entries outside it must be
    zero, as a fresh ``np.zeros`` band is).

    Returns
    -------
    (ok, n_negative, Kib, schur)
        ``Kib = K^-1 b``, ``schur = d - c^T K^-1 b``; ``ok`` False if ``K`` is singular to round-off.
    """
    return bordered_factor_upto(K, ext, b, c, d, fac, -1)


@njit(cache=True)
def bordered_factor_upto(K: np.ndarray, ext: np.ndarray, b: np.ndarray, c: np.ndarray, d: float,
                         fac: np.ndarray, max_neg: int):
    """:func:`bordered_factor_into`, given up (``ok`` False, the count of negative pivots so far)
    once ``K`` has more than ``max_neg >= 0`` negative pivots (``-1``: never): a caller that wants a
    matrix positive definite on a constraint (at most one negative eigenvalue of ``K``) knows the
    answer there, and the rest of the band is not factorised."""
    ok, nneg = _ldlt(fac, ext, K, True, max_neg)
    if not ok or 0 <= max_neg < nneg:
        return False, nneg, np.zeros(0), 0.0
    Kib = band_ldlt_solve(fac, b, ext)
    schur = d - np.dot(c, Kib)
    return True, nneg, Kib, schur


@njit(cache=True)
def bordered_solve(fac: np.ndarray, K: np.ndarray, ext: np.ndarray, b: np.ndarray, c: np.ndarray, d: float,
                   Kib: np.ndarray, schur: float, rhs: np.ndarray, refine: bool) -> np.ndarray:
    """Solve ``[[K, b], [c^T, d]] [x; y] = rhs`` with the factors of :func:`bordered_factor`,
    with one step of iterative refinement on the full bordered system if ``refine``.

    The first solution is formed in the output's storage and the refinement's residual
    ``rhs - [[K, b], [c^T, d]] [x; y]`` is solved in place (fewer temporaries); with the faster
    solves and product, the refined solve takes 2.0-2.3x less CPU time than before. Summed in any
    order, its result moves by round-off, which on the actuators' bordered matrices (condition
    numbers 2e9 to 4e9) is at the level of its error: within 1e-10 to 2e-10 of a solution refined
    with extended-precision residuals (``bench/profile_designs.py@51d9ff8 --kernels D [--nt 3]``).
    """
    n = fac.shape[0]
    s = rhs[n]
    out = np.empty(n + 1)
    x = out[:n]
    x[:] = rhs[:n]
    _solve_in_place(fac, x, ext)  # z = K^-1 r
    y = (s - np.dot(c, x)) / schur
    for i in range(n):
        x[i] -= y * Kib[i]
    out[n] = y
    if not refine:
        return out
    r2 = np.empty(n)
    _matvec_into(K, x, ext, r2)
    for i in range(n):
        r2[i] = rhs[i] - (r2[i] + b[i] * y)  # r - (K x + b y)
    bot = np.dot(c, x) + d * y
    _solve_in_place(fac, r2, ext)  # z2
    y2 = ((s - bot) - np.dot(c, r2)) / schur
    for i in range(n):
        x[i] += r2[i] - y2 * Kib[i]
    out[n] = y + y2
    return out
