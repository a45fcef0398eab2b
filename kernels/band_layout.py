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


def band_of_maps(maps, n: int) -> tuple[int, np.ndarray]:
    """Half-bandwidth ``kl`` and envelope extents of the symmetric matrix assembled from dense
    blocks: each of ``maps`` is an ``(ne, nd)`` array of the dofs of a block's rows and columns
    (element dofs, cavity edges; -1: not assembled)."""
    rows, cols = [], []
    for d in maps:
        nd = d.shape[1]
        r, c = np.repeat(d, nd, axis=1).ravel(), np.tile(d, (1, nd)).ravel()
        ok = (r >= 0) & (c >= 0)
        rows.append(r[ok])
        cols.append(c[ok])
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    kl = int(np.abs(rows - cols).max()) if len(rows) else 0
    return kl, envelope_extents(rows, cols, n, kl)
