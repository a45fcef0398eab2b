"""The band layout of a symmetric sparsity pattern (plain numpy, no numba: the solver computes it
before any kernel runs)."""
from __future__ import annotations

import numpy as np


def envelope_extents(rows: np.ndarray, cols: np.ndarray, n: int, kl: int) -> np.ndarray:
    """Column extents ``ext`` of the envelope of a symmetric sparsity pattern.

    Parameters
    ----------
    rows, cols : indices of the structurally non-zero entries (either triangle, any order)
    n : matrix size
    kl : half-bandwidth of the storage

    Returns
    -------
    ext : int64 array of length ``n``, ``0 <= ext[j] <= min(kl, n - 1 - j)``
    """
    r = np.maximum(rows, cols).astype(np.int64)
    c = np.minimum(rows, cols).astype(np.int64)
    first = np.arange(n, dtype=np.int64)  # first non-zero column of each row (the diagonal at most)
    np.minimum.at(first, r, c)
    last_row = np.full(n, -1, dtype=np.int64)  # the last row whose envelope starts at column j
    np.maximum.at(last_row, first, np.arange(n, dtype=np.int64))
    reach = np.maximum.accumulate(last_row)  # the last row whose envelope contains column j
    ext = reach - np.arange(n, dtype=np.int64)
    return np.minimum(np.maximum(ext, 0), np.minimum(kl, n - 1 - np.arange(n, dtype=np.int64)))
