"""The band LDL^T kernel with its envelope (kernels/banded.py)."""
from __future__ import annotations

import numpy as np
import pytest

from snapjump_kernels.banded import (band_ldlt, band_ldlt_solve, envelope_extents,
                                     sym_band_matvec)


def full_extents(n: int, kl: int) -> np.ndarray:
    """The extents of a full band (no envelope information)."""
    return np.minimum(kl, n - 1 - np.arange(n, dtype=np.int64))


def _random_profile_matrix(n: int, kl: int, seed: int, shift: float):
    """A symmetric matrix whose rows start at random columns within the band (a profile)."""
    rng = np.random.default_rng(seed)
    first = np.maximum(0, np.arange(n) - rng.integers(0, kl + 1, n))
    A = np.zeros((n, n))
    for r in range(n):
        A[r, first[r]:r] = rng.standard_normal(r - first[r])
    A = A + A.T + np.diag(shift + rng.random(n))
    return A


def _to_band(A: np.ndarray, kl: int) -> np.ndarray:
    n = len(A)
    ab = np.zeros((n, kl + 1))
    for j in range(n):
        for i in range(min(kl, n - 1 - j) + 1):
            ab[j, i] = A[j + i, j]
    return ab


def _extents_of(A: np.ndarray, kl: int) -> np.ndarray:
    r, c = np.nonzero(A)
    return envelope_extents(r, c, len(A), kl)


def test_extents_of_a_known_pattern():
    # rows start at columns 0, 0, 1, 1, 3, 4 (lower triangle); kl = 3
    A = np.eye(6)
    for r, f in enumerate([0, 0, 1, 1, 3, 4]):
        A[r, f] = A[f, r] = 1.0
    ext = _extents_of(A, 3)
    # column 0 reaches row 1; column 1 rows 2, 3; column 2 row 3; column 3 row 4; column 4 row 5
    assert ext.tolist() == [1, 2, 1, 1, 1, 0]
    assert full_extents(6, 3).tolist() == [3, 3, 3, 2, 1, 0]


@pytest.mark.parametrize("shift", [8.0, 0.5])  # positive definite / indefinite
def test_envelope_factorisation_solves_and_counts_negative_eigenvalues(shift):
    n, kl = 120, 9
    A = _random_profile_matrix(n, kl, 3, shift)
    ext = _extents_of(A, kl)
    assert (ext <= full_extents(n, kl)).all() and ext.sum() < full_extents(n, kl).sum()
    ab = _to_band(A, kl)
    b = np.random.default_rng(1).standard_normal(n)
    assert np.allclose(sym_band_matvec(ab, b, ext), A @ b, rtol=0, atol=1e-12)
    fac = ab.copy()
    ok, nneg = band_ldlt(fac, ext)
    assert ok
    assert nneg == int((np.linalg.eigvalsh(A) < 0).sum())
    x = band_ldlt_solve(fac, b, ext)
    assert np.abs(A @ x - b).max() < 1e-9 * max(1.0, np.abs(x).max())


def test_envelope_gives_the_full_band_result_bit_for_bit():
    n, kl = 200, 15
    A = _random_profile_matrix(n, kl, 7, 1.0)
    ab = _to_band(A, kl)
    f1, f2 = ab.copy(), ab.copy()
    r1 = band_ldlt(f1, _extents_of(A, kl))
    r2 = band_ldlt(f2, full_extents(n, kl))
    assert r1 == r2
    assert np.array_equal(f1[:, 0], f2[:, 0])
    # entries outside the envelope stay exact zeros in the full-band factor, inside they are equal
    ext = _extents_of(A, kl)
    inside = np.arange(kl + 1)[None, :] <= ext[:, None]
    assert np.array_equal(f1[inside], f2[inside]) and not np.any(f2[~inside])


def test_model_envelope_on_design_D():
    """The actuator's tangent factorised inside its envelope equals the full-band factorisation."""
    from snapjump_cli.geometry.designs import get_design
    from snapjump_cli.mesh.build import mesh_scene
    from snapjump_cli.settings import MeshSettings, SolverSettings
    from snapjump_cli.fe.solve import build_model

    d = get_design("D")
    m = build_model(d, mesh_scene(d, MeshSettings()), SolverSettings())
    u = 1e-3 * np.random.default_rng(0).standard_normal(m.n)
    lin = m.linearize(u, 0.01)
    K = lin.data.reshape(m.n, m.kl + 1)
    f1, f2 = K.copy(), K.copy()
    assert band_ldlt(f1, m.band_ext) == band_ldlt(f2, full_extents(m.n, m.kl))
    assert np.array_equal(f1, f2)
    # the factorisation's work goes with sum(ext^2): the band is wide only at the ring junction
    assert (m.band_ext.astype(float) ** 2).sum() < 0.4 * (full_extents(m.n, m.kl).astype(float) ** 2).sum()


def _dense_ldlt_reference(A: np.ndarray):
    """Unblocked LDL^T without pivoting (the textbook column algorithm), dense."""
    n = len(A)
    L, d, W = np.eye(n), np.zeros(n), A.astype(float).copy()
    for j in range(n):
        d[j] = W[j, j]
        L[j + 1:, j] = W[j + 1:, j] / d[j]
        W[j + 1:, j + 1:] -= d[j] * np.outer(L[j + 1:, j], L[j + 1:, j])
    return L, d


@pytest.mark.parametrize("n, kl, seed", [(125, 11, 2), (121, 20, 5), (120, 7, 9), (47, 30, 4), (5, 3, 1), (1, 0, 0)])
def test_blocked_factor_and_solves_against_dense_numpy(n, kl, seed):
    """Factor, inertia, solve, product and the bordered solve against numpy on an indefinite profile
    matrix; sizes that are and are not multiples of the block size (the last block is shorter)."""
    from snapjump_kernels.banded import _NB, bordered_factor, bordered_solve

    assert _NB == 6  # n = 125, 121, 47, 5, 1: a last block of 5 or 1 columns (the generic update)

    A = _random_profile_matrix(n, kl, seed, 0.3)  # indefinite: ~40 % negative eigenvalues
    ext = _extents_of(A, kl)
    ab = _to_band(A, kl)
    eig = np.linalg.eigvalsh(A)
    fac = ab.copy()
    ok, nneg = band_ldlt(fac, ext)
    assert ok and nneg == int((eig < 0).sum())
    if n > 20:
        assert nneg > 0
    # L D L^T = A to round-off (backward error, entrywise), and the factors equal the textbook
    # algorithm's to round-off times the growth of the entries (no pivoting)
    Lf = np.eye(n)
    for j in range(n):
        Lf[j + 1:j + 1 + ext[j], j] = fac[j, 1:ext[j] + 1]
    d = fac[:, 0]
    size = np.abs(Lf) @ np.diag(np.abs(d)) @ np.abs(Lf).T
    assert np.all(np.abs(Lf @ np.diag(d) @ Lf.T - A) <= 1e-13 * n * (size + 1.0))
    L, d_ref = _dense_ldlt_reference(A)
    growth = max(1.0, size.max())
    assert np.abs(d - d_ref).max() < 1e-13 * n * growth and np.abs(Lf - L).max() < 1e-13 * n * growth
    cond = np.abs(eig).max() / np.abs(eig).min()
    rng = np.random.default_rng(seed + 100)
    b = rng.standard_normal(n)
    x_ref = np.linalg.solve(A, b)
    x = band_ldlt_solve(fac, b, ext)
    assert np.abs(x - x_ref).max() < 1e-13 * growth * cond * np.abs(x_ref).max()
    assert np.abs(sym_band_matvec(ab, b, ext) - A @ b).max() < 1e-12 * np.abs(A).max() * np.abs(b).sum()
    # the bordered system [[A, g], [c^T, e]], with and without the refinement step
    g, c, e = rng.standard_normal(n), rng.standard_normal(n), 0.7
    B = np.block([[A, g[:, None]], [c[None, :], np.array([[e]])]])
    rhs = rng.standard_normal(n + 1)
    ok, nneg2, fac2, Kib, schur = bordered_factor(ab, ext, g, c, e)
    assert ok and nneg2 == nneg and np.array_equal(fac2, fac)
    Kig = np.linalg.solve(A, g)
    assert abs(schur - (e - c @ Kig)) < 1e-13 * growth * cond * np.abs(c).sum() * np.abs(Kig).max()
    z_ref = np.linalg.solve(B, rhs)
    cond_b = np.linalg.cond(B)
    for refine in (False, True):
        z = bordered_solve(fac2, ab, ext, g, c, e, Kib, schur, rhs, refine)
        assert np.abs(z - z_ref).max() < 1e-13 * growth * max(cond, cond_b) * np.abs(z_ref).max()
        assert np.abs(B @ z - rhs).max() < 1e-12 * growth * np.abs(B).max() * np.abs(z).sum()


def test_zero_pivot_is_reported_with_the_negative_pivots_before_it():
    A = np.array([[-2.0, 1.0, 0.0, 0.0],
                  [1.0, -0.5, 1.0, 0.0],  # pivot 2: -0.5 - 1 / -2 = 0 exactly
                  [0.0, 1.0, 3.0, 1.0],
                  [0.0, 0.0, 1.0, 4.0]])
    ab = _to_band(A, 1)
    assert band_ldlt(ab.copy(), full_extents(4, 1)) == (False, 1)
    ab[0, 0] = 0.0
    assert band_ldlt(ab, full_extents(4, 1)) == (False, 0)


def _blocked_ldlt_python(ab: np.ndarray, ext: np.ndarray, nb: int = 6) -> None:
    """The blocked algorithm of band_ldlt in plain Python, the ``nb`` updates of an entry summed
    first in the order of the block's columns (in place; no pivot checks)."""
    n = len(ab)
    j0 = 0
    while j0 < n:
        b = min(nb, n - j0)
        R = max(t + ext[t] for t in range(j0, j0 + b))
        for j in range(j0, j0 + b):
            d, m = ab[j, 0], ext[j]
            for i in range(1, m + 1):
                ab[j, i] = ab[j, i] / d
            for c in range(j + 1, min(j0 + b, j + m + 1)):
                f = ab[j, c - j] * d
                for r in range(c, j + m + 1):
                    ab[c, r - c] -= ab[j, r - j] * f
        for c in range(j0 + b, R + 1):
            for r in range(c, R + 1):
                s = 0.0
                for jt in range(j0, j0 + b):
                    lr = ab[jt, r - jt] if r - jt <= ext[jt] else 0.0
                    lc = ab[jt, c - jt] if c - jt <= ext[jt] else 0.0
                    s += lr * (lc * ab[jt, 0])
                ab[c, r - c] -= s
        j0 += b


@pytest.mark.parametrize("n", [64, 66])
def test_unrolled_block_update_is_the_blocked_algorithm_bit_for_bit(n):
    """The vectorised rank-6 update (and the last, shorter block) sums in the documented order."""
    kl = 13
    A = _random_profile_matrix(n, kl, 11, 0.3)
    ext = _extents_of(A, kl)
    f1, f2 = _to_band(A, kl), _to_band(A, kl)
    assert band_ldlt(f1, ext)[0]
    _blocked_ldlt_python(f2, ext)
    assert np.array_equal(f1, f2)


@pytest.mark.parametrize("shift", [8.0, 2.0, 0.5, -1.0])  # none, few and many negative eigenvalues
def test_the_factorisation_given_up_past_a_count_of_negative_pivots(shift):
    """``bordered_factor_upto`` (the descent's positive-definiteness test): with ``max_neg = 1`` it
    gives up exactly where ``K`` has two or more negative pivots, reporting two; otherwise it is
    ``bordered_factor_into`` bit for bit (as with ``max_neg = -1``, never given up)."""
    from snapjump_kernels.banded import bordered_factor_into, bordered_factor_upto

    n, kl = 120, 9
    A = _random_profile_matrix(n, kl, 5, shift)
    ext = _extents_of(A, kl)
    ab = _to_band(A, kl)
    rng = np.random.default_rng(2)
    b, c = rng.standard_normal(n), rng.standard_normal(n)
    n_neg = int((np.linalg.eigvalsh(A) < 0).sum())
    ref = bordered_factor_into(ab, ext, b, c, 0.3, fac_ref := np.zeros_like(ab))
    assert ref[0] and ref[1] == n_neg
    for max_neg in (-1, 1):
        got = bordered_factor_upto(ab, ext, b, c, 0.3, fac := np.zeros_like(ab), max_neg)
        if max_neg == 1 and n_neg >= 2:
            assert got[0] is False and got[1] == 2
        else:
            assert got[0] and got[1] == n_neg and got[3] == ref[3]
            assert np.array_equal(got[2], ref[2]) and np.array_equal(fac, fac_ref)
    assert shift != -1.0 or n_neg >= 2  # (the cases include a given-up one)
