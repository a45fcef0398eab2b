"""The band LDL^T of the multi-harmonic tangent, into a buffer the caller keeps.

:func:`envelope_ldlt` is :func:`snapjump_kernels.banded.band_ldlt` (the same storage, envelope,
blocks of 6 columns, and the same arithmetic: every entry receives the same terms in the same
order, so the factors are bit for bit those of ``band_ldlt``) with the trailing rank-6 update of
a block done for two target columns at a time: the 6 entries of ``L`` of a row are loaded once
for both columns. :func:`bordered_factor_into` is
:func:`snapjump_kernels.banded.bordered_factor` writing the factors into a given array instead
of a fresh copy of the matrix (only the envelope is copied and factorised: entries outside it
are neither read nor written, so a buffer that is zero there stays a valid band of ``L``).

JIT-compiled only (not in the ahead-of-time build). Arrays in, arrays out.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from snapjump_kernels.banded import band_ldlt_solve

#: Columns per block (as :data:`snapjump_kernels.banded._NB`: the blocks fix the order of the sums).
_NB = 6


@njit(cache=True)
def envelope_ldlt(ab: np.ndarray, ext: np.ndarray):
    """See :func:`_envelope_ldlt` (in place)."""
    return _envelope_ldlt(ab, ext, ab, False)


@njit(cache=True)
def _envelope_ldlt(ab: np.ndarray, ext: np.ndarray, src: np.ndarray, copy: bool):
    """Factorise the lower band ``ab`` in place: ``ab[:, 0]`` holds ``D`` and ``ab[:, 1:]`` the
    unit-lower ``L``, as :func:`snapjump_kernels.banded.band_ldlt` (see there for the storage,
    the envelope ``ext`` and the algorithm), with the same result bit for bit.

    The trailing update of a block, ``A[r, c] -= sum_t L[r, t] d_t L[c, t]`` over the block's 6
    columns ``t`` (summed in their order, as ``band_ldlt`` does), runs over two target columns
    ``c, c + 1`` at a time, sharing the loads of ``L[r, t]``.

    With ``copy``, the matrix is read from ``src`` instead: the envelope of each column is copied
    into ``ab`` just before the column is first updated (while it is about to be used, instead
    of in a pass of its own over the whole band).

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
def bordered_factor_into(K: np.ndarray, ext: np.ndarray, b: np.ndarray, c: np.ndarray, d: float,
                         fac: np.ndarray):
    """Factorise the bordered matrix ``[[K, b], [c^T, d]]`` as
    :func:`snapjump_kernels.banded.bordered_factor` does (the same results bit for bit), with the
    band LDL^T of ``K`` written into ``fac`` (same shape as ``K``; only its envelope is written,
    each column copied from ``K`` just before it is first updated: entries outside the envelope
    must be zero, as a fresh ``np.zeros`` band is).

    Returns
    -------
    (ok, n_negative, Kib, schur)
        ``Kib = K^-1 b``, ``schur = d - c^T K^-1 b``; ``ok`` False if ``K`` is singular to round-off.
    """
    ok, nneg = _envelope_ldlt(fac, ext, K, True)
    if not ok:
        return False, nneg, np.zeros(0), 0.0
    Kib = band_ldlt_solve(fac, b, ext)
    schur = d - np.dot(c, Kib)
    return True, nneg, Kib, schur
