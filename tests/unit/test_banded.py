"""The band LDL^T kernel with its envelope (kernels/banded.py)."""
from __future__ import annotations

import numpy as np
import pytest

from snapjump_kernels.banded import (band_ldlt, band_ldlt_solve, envelope_extents, full_extents,
                                     sym_band_matvec)


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
    from snapjump_cli.designs import get_design
    from snapjump_cli.mesh import mesh_scene
    from snapjump_cli.settings import MeshSettings, SolverSettings
    from snapjump_cli.solve import build_model

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
