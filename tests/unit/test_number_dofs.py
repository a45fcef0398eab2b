"""snapjump_cli.mesh.data.number_dofs against its definition (a loop over the nodes in order)."""
from __future__ import annotations

import numpy as np

from snapjump_cli.mesh.data import number_dofs


def _by_definition(order: np.ndarray, fixed: np.ndarray) -> tuple[np.ndarray, int]:
    dofmap = -np.ones(fixed.shape, np.int64)
    k = 0
    for v in order:
        for c in range(fixed.shape[1]):
            if not fixed[v, c]:
                dofmap[v, c] = k
                k += 1
    return dofmap, k


def test_free_dofs_are_numbered_node_by_node_in_order():
    rng = np.random.default_rng(0)
    for _ in range(200):
        nn, nc = int(rng.integers(1, 40)), int(rng.integers(1, 4))
        fixed = rng.random((nn, nc)) < rng.random()
        order = rng.permutation(nn)
        dofmap, k = number_dofs(order, fixed)
        ref, kr = _by_definition(order, fixed)
        assert k == kr and dofmap.dtype == np.int64 and np.array_equal(dofmap, ref)
