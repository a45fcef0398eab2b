"""The corrector's mixed linearisation and error test (docs/numerics.md, "Newton on the mixed
element"): the element-pressure derivative against finite differences, the mixed tangent against
the exact one, and the same snap with fewer assemblies."""
from __future__ import annotations

import numpy as np
import pytest

from snapjump_cli.fe.continuation import ContinuationSettings
from snapjump_cli.geometry.designs import get_design
from snapjump_cli.fe.axisym.model import Model
from snapjump_cli.settings import MeshSettings, SolverSettings
from snapjump_cli.fe.solve import solve_scene
from tests.sphere import sphere_mesh


def _model(order: int) -> Model:
    m = sphere_mesh(1.0, 1.4, 2, 4, order)
    mat = (np.arange(m.n_elements) % 2).astype(np.int8)
    m = type(m)(**{**m.__dict__, "material": mat})
    return Model(m, np.array([1.0, 1.0 / 5.8]), np.array([24.0, 24.0]), 50.0, 1.0, 1.0)


def _state(M: Model, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return 0.15 * M.free_vector(M.X) + 0.005 * rng.standard_normal(M.n)


@pytest.mark.parametrize("order", [1, 2])
def test_element_pressure_derivative_matches_finite_differences(order):
    M = _model(order)
    u, p = _state(M, 5), 0.2
    d = np.random.default_rng(6).standard_normal(M.n)
    an = M.linearize(u, p).aux_dir(d)
    errs = []
    for eps in (1e-4, 1e-5):
        fd = (M.linearize(u + eps * d, p).aux - M.linearize(u - eps * d, p).aux) / (2 * eps)
        errs.append(np.linalg.norm(fd - an) / np.linalg.norm(an))
    assert errs[1] < 1e-8
    assert errs[1] < 0.05 * errs[0] or errs[1] < 1e-10  # central differences: error ~ eps^2


@pytest.mark.parametrize("order", [1, 2])
def test_mixed_tangent_with_the_elements_own_pressure_is_the_exact_tangent(order):
    M = _model(order)
    u, p = _state(M, 7), 0.3
    lin = M.linearize(u, p)
    own = M.linearize(u, p, aux=lin.aux)
    scale = np.abs(lin.data).max()
    assert np.abs(own.data - lin.data).max() <= 1e-12 * scale

    def K(a):
        return M.linearize(u, p, aux=a).data

    da = np.random.default_rng(8).standard_normal(lin.aux.shape)
    a0 = lin.aux
    # only the geometric term p d2J changes, linearly in the pressure; the residual not at all
    assert np.abs(K(a0 + da) - K(a0)).max() > 1e-6 * scale
    assert np.abs((K(a0 + 2 * da) - K(a0)) - 2 * (K(a0 + da) - K(a0))).max() <= 1e-10 * scale
    assert np.array_equal(M.linearize(u, p, aux=a0 + da).R, lin.R)


_FROM_SOLVER = ContinuationSettings.from_solver.__func__


def _solve_C(monkeypatch, **internal):
    orig = _FROM_SOLVER
    monkeypatch.setattr(ContinuationSettings, "from_solver",
                        classmethod(lambda cls, *a, **k: orig(cls, *a, **{**k, **internal})))
    return solve_scene(get_design("C"), MeshSettings(order=2, nt=2, aspect=3.0), SolverSettings())


def test_error_test_and_mixed_tangent_keep_the_snap_and_halve_the_assemblies(monkeypatch):
    old = _solve_C(monkeypatch, error_test=False, mixed_tangent=False)
    new = _solve_C(monkeypatch)
    for k in ("dE_J", "dy_pole_m", "V_star_m3", "p_star_Pa", "h_imp_m", "dE_path_J"):
        assert new.metrics[k] == pytest.approx(old.metrics[k], rel=1e-6), k
    assert new.metrics["self_crossing"] == old.metrics["self_crossing"]
    assert new.metrics["n_assemblies"] < 0.6 * old.metrics["n_assemblies"]
    # the path points the error test accepted are equilibria: residual well below the load
    M, tr = new.model, new.tracer
    worst = 0.0
    for pt in new.path.points[1:]:
        lin = M.linearize(pt.u, pt.p)
        ref = np.linalg.norm(lin.g) * max(abs(pt.p), 1e-3 * tr.sc[1])
        worst = max(worst, np.linalg.norm(lin.R) / ref)
    assert worst < 1e-4
