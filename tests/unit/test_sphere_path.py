"""The sphere-path problem of the landing search (snapjump_cli/fe/axisym/sphere_path.py): its
residual, the Newton matrix its factorisation inverts (central differences of the residual) and
its measures."""
from __future__ import annotations

import math

import numpy as np
import pytest

from snapjump_cli.fe.axisym.model import Model
from snapjump_cli.fe.axisym.sphere_path import SpherePathProblem
from tests.sphere import sphere_mesh


def _model() -> Model:
    m = sphere_mesh(1.0, 1.4, 2, 4, 2)
    return Model(m, np.array([1.0]), np.array([24.0]), 50.0, 1.0, 1.0, pole_node=None)


def _problem(M: Model):
    rng = np.random.default_rng(3)
    u = 0.1 * M.free_vector(M.X) + 0.002 * rng.standard_normal(M.n)
    centre = u + 0.01 * rng.standard_normal(M.n)
    m = 0.5 + rng.random(M.n)
    lin0 = M.linearize(u, 0.4)
    return SpherePathProblem(M, lin0.V + 1e-3, centre, m, c_V=2.0, p_floor=1e-3), u, 0.4, lin0


@pytest.mark.parametrize("F", [-0.3, 0.0, 0.05])
def test_the_residual_and_the_matrix_its_factorisation_inverts(F):
    """Residual = [f - p g - F M (u - c); c_V (V - V*)]; the doubly bordered solve with the shift
    ``-F M`` and the column ``-M (u - c)`` inverts its Jacobian (central differences of the
    residual along the computed solution; the last row is linear)."""
    M = _model()
    pb, u, p, lin0 = _problem(M)
    x = np.concatenate([u, [p]])
    L = pb.linearize(x, F)
    d = u - pb.centre
    assert np.allclose(L.R[:-1], lin0.R - F * pb.m * d, rtol=0, atol=1e-12)
    assert L.R[-1] == 2.0 * (lin0.V - pb.V_star)
    rng = np.random.default_rng(4)
    c_x, c_F = rng.standard_normal(pb.n), 0.7
    y = L.factor(c_x, c_F).solve(rhs := rng.standard_normal(pb.n + 1))
    dx, dF = y[:-1], y[-1]
    errs = []
    for eps in (1e-4, 1e-5):
        Jy = (pb.linearize(x + eps * dx, F + eps * dF).R - pb.linearize(x - eps * dx, F - eps * dF).R) / (2 * eps)
        errs.append(np.abs(Jy - rhs[:-1]).max() / np.abs(rhs[:-1]).max())
    assert errs[1] < 1e-6
    assert errs[1] < 0.05 * errs[0] or errs[1] < 1e-9  # second order in eps (round-off aside)
    assert abs(c_x @ dx + c_F * dF - rhs[-1]) < 1e-10 * max(1.0, abs(rhs[-1]))


def test_the_measures_are_the_distance_in_the_metric_and_the_load():
    M = _model()
    pb, u, p, _ = _problem(M)
    x = np.concatenate([u, [p]])
    z, dz, dzF = pb.measures(x, 0.25)
    d = u - pb.centre
    w = math.sqrt(float(np.sum(pb.m * d * d)))
    assert z[0] == pytest.approx(w, rel=1e-14) and z[1] == 0.25 and dzF.tolist() == [0.0, 1.0]
    h = 1e-6 * rng_dir(pb.n)
    wp = pb.measures(x + h, 0.25)[0][0]
    wm = pb.measures(x - h, 0.25)[0][0]
    assert (wp - wm) / 2 == pytest.approx(float(dz[0] @ h), rel=1e-7)
    assert dz[0, -1] == 0.0
    # at the centre the distance is 0 and its derivative is taken as 0 (the path never starts there)
    z0, dz0, _ = pb.measures(np.concatenate([pb.centre, [p]]), 0.0)
    assert z0[0] == 0.0 and not dz0.any()


def rng_dir(n: int) -> np.ndarray:
    v = np.random.default_rng(7).standard_normal(n)
    v[-1] = 0.0
    return v / np.linalg.norm(v)
