"""The gauge of the harmonic check picks the pivot columns of a column-pivoted QR."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import qr

from snapjump_cli.fe.stability.harmonics import pivot_columns


@pytest.mark.parametrize("k", [1, 2])
def test_pivot_columns_are_those_of_lapack_geqp3(k):
    rng = np.random.default_rng(k)
    for _ in range(100):
        A = rng.standard_normal((k, 257)) * rng.uniform(0.1, 10.0, size=257)
        _, _, piv = qr(A, pivoting=True, mode="economic")
        assert list(pivot_columns(A)) == list(piv[:k])


def test_second_pivot_is_the_column_most_independent_of_the_first():
    A = np.array([[1.0, 0.9, 0.0, 0.5], [0.0, 0.1, 0.3, 0.5]])
    # first: the largest column norm (column 0, 1.0 against 0.906, 0.3, 0.707); then the largest
    # remainder orthogonal to it: column 3 (0.5) before column 2 (0.3) and column 1 (0.1)
    assert list(pivot_columns(A)) == [0, 3]
