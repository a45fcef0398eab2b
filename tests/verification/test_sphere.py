"""Thick-walled Gent hollow sphere: closed-form p(V) traced through its pressure maximum."""
from __future__ import annotations

import math

import numpy as np
import pytest

from snapjump_cli.fe.continuation import ContinuationSettings, trace
from snapjump_cli.fe.axisym.model import Model
from tests.sphere import sphere_mesh, sphere_pressure

A, B, MU, JM = 1.0, 1.5, 1.0, 24.0


def _trace_sphere(order: int, nt: int, bulk: float = 1e4):
    m = sphere_mesh(A, B, nt, 4 * nt, order)
    M = Model(m, np.array([MU]), np.array([JM]), bulk, 1.0, 1.0)
    V0 = M.volume(np.zeros(M.n))
    cfg = ContinuationSettings(scales=(V0, 0.5, 0.5), ds0=0.1, ds_max=0.5, max_steps=300, tol_path=None)
    path = trace(M, cfg, lambda path: "done" if path.points[-1].zeta[0] > 12.0 else None)
    p = np.array([pt.p for pt in path.points])
    V = np.array([pt.zeta[0] * V0 for pt in path.points])
    a = (3 * V / (2 * math.pi)) ** (1 / 3)  # the cavity is the upper half sphere
    p_exact = np.array([sphere_pressure(ai, A, B, MU, JM) for ai in a])
    return M, path, p, p_exact


@pytest.fixture(scope="module")
def curves():
    out = {}
    for order, nts in ((1, (2, 4, 8)), (2, (1, 2, 4))):
        for nt in nts:
            M, path, p, pe = _trace_sphere(order, nt)
            out[order, nt] = (M, path, p, pe)
    return out


def test_traced_through_the_pressure_maximum(curves):
    _, path, p, pe = curves[2, 2]
    k = int(np.argmax(p))
    assert 0 < k < len(p) - 3, "the pressure maximum must be an interior point of the path"
    assert p[k:].min() < 0.99 * p[k], "the path must come down from the maximum"


@pytest.mark.parametrize("order,nt", [(1, 4), (2, 2)])
def test_error_at_default_density_below_half_percent(curves, order, nt):
    _, _, p, pe = curves[order, nt]
    err = np.max(np.abs(p - pe)) / np.max(pe)
    assert err <= 5e-3


def test_error_decreases_under_refinement_order1(curves):
    errs = [np.max(np.abs(curves[1, nt][2] - curves[1, nt][3])) for nt in (2, 4, 8)]
    assert errs[1] < 0.6 * errs[0] and errs[2] < 0.6 * errs[1], errs


def test_order2_error_decreases_to_the_incompressibility_floor():
    # with the default kappa/mu = 1e4 order 2 sits at the O(p/kappa) floor already at nt = 2;
    # with kappa/mu = 1e6 the discretisation error is visible and must decrease
    errs = []
    for nt in (1, 2):
        _, _, p, pe = _trace_sphere(2, nt, bulk=1e6)
        errs.append(np.max(np.abs(p - pe)) / np.max(pe))
    assert errs[1] < 0.5 * errs[0], errs


def test_volume_preserved(curves):
    M, path, p, pe = curves[2, 2]
    k = int(np.argmax(p))
    J = M.jacobians(path.points[k].u)
    assert np.abs(J - 1).max() < 2e-3  # kappa/mu = 1e4: |J - 1| ~ p / kappa
