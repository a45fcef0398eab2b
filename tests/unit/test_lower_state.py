"""The fixed-volume problem of the lower-state continuation (snapjump_cli/fe/lower_state.py)."""
from __future__ import annotations

import numpy as np

from snapjump_cli.fe.axisym.lower_state import FixedVolumeProblem
from snapjump_cli.fe.axisym.model import Model
from tests.sphere import sphere_mesh


def _model() -> Model:
    m = sphere_mesh(1.0, 1.4, 2, 4, 2)
    return Model(m, np.array([1.0]), np.array([24.0]), 50.0, 1.0, 1.0, pole_node=None)


def _state(M: Model):
    rng = np.random.default_rng(3)
    u = 0.1 * M.free_vector(M.X) + 0.002 * rng.standard_normal(M.n)
    return u, 0.4


def test_fixed_volume_residual_and_its_jacobian():
    """Residual = [f - p g - F e_w; c_V (V - V*)]; the doubly bordered solve inverts its Jacobian
    (checked by finite differences of the residual along the computed solution)."""
    M = _model()
    u, p = _state(M)
    lin0 = M.linearize(u, p)
    e = np.random.default_rng(5).standard_normal(M.n)
    e /= np.linalg.norm(e)
    pb = FixedVolumeProblem(M, lin0.V + 1e-3, e, c_V=2.0, p_floor=1e-3)
    x, F = np.concatenate([u, [p]]), 0.05
    L = pb.linearize(x, F)
    assert np.allclose(L.R[:-1], lin0.R - F * e, rtol=0, atol=1e-12)
    assert L.R[-1] == 2.0 * (lin0.V - pb.V_star)
    # the bordered system [[dR/dx, dR/dF], [c_x, c_F]] with an arbitrary last row
    rng = np.random.default_rng(4)
    c_x, c_F = rng.standard_normal(pb.n), 0.7
    solver = L.factor(c_x, c_F)
    rhs = rng.standard_normal(pb.n + 1)
    y = solver.solve(rhs)
    dx, dF = y[:-1], y[-1]
    # J y by central differences of the residual; the last row is linear
    eps = 1e-6
    Rp = pb.linearize(x + eps * dx, F + eps * dF).R
    Rm = pb.linearize(x - eps * dx, F - eps * dF).R
    Jy = (Rp - Rm) / (2 * eps)
    scale = np.abs(rhs[:-1]).max()
    assert np.abs(Jy - rhs[:-1]).max() < 1e-5 * scale
    assert abs(c_x @ dx + c_F * dF - rhs[-1]) < 1e-10 * max(1.0, abs(rhs[-1]))


def test_fixed_volume_measures():
    M = _model()
    e = np.zeros(M.n)
    e[M.pole_dof] = 1.0  # a point force on the pole
    pb = FixedVolumeProblem(M, 1.0, e, c_V=1.0, p_floor=1e-3)
    x = np.arange(pb.n, dtype=float)
    z, dz, dzF = pb.measures(x, 0.25)
    assert z.tolist() == [x[M.pole_dof], 0.25]
    assert dz[0, M.pole_dof] == 1.0 and dz.sum() == 1.0 and dzF.tolist() == [0.0, 1.0]
