"""The multi-harmonic model's mixed linearisation (docs/harmonics.md, section 10.4).

The tangent's geometric term ``p d2J`` may take the element pressures of every phi point from
the three-field Newton iteration (``aux``) instead of the condensed ``kappa M^-1 g_j(u)``; the
residual never changes. Checked here: with the condensed pressures as ``aux`` the band is the
reduced one bit for bit; ``aux`` enters the band linearly and the residual not at all; the
pressures' derivative ``aux_dir`` against central differences of the condensed pressures
(second-order convergence); and a branch traced with either tangent lands on the same state.
"""
from __future__ import annotations

import numpy as np
import pytest

from snapjump_cli.fe.branch import trace as trace_mod
from snapjump_cli.fe.branch.bifurcation import default_harmonics, locate_bifurcation
from snapjump_cli.fe.branch.model import MultiHarmonicModel
from snapjump_cli.fe.solve import solve_scene
from snapjump_cli.fe.stability.harmonics import check_harmonics
from snapjump_cli.geometry.caps import CapScene
from snapjump_cli.settings import MeshSettings, SolverSettings
from tests.unit.test_harmonics_fd import _model, _state
from tests.unit.test_imperfection import _imperfection
from tests.unit.test_multiharmonic import _smooth_modes


def _mh_state(order: int, hn):
    M = _model(order)
    mh = MultiHarmonicModel(M, hn)
    rng = np.random.default_rng(11 + order + len(hn))
    U = mh.embed(_state(M, 4), _smooth_modes(M, hn, 0.03)) + 1e-3 * rng.standard_normal(mh.n)
    return mh, U


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("hn", [[0], [0, 1, 2], [0, 2, 4]])
def test_the_condensed_pressures_give_the_reduced_tangent_bit_for_bit(order, hn):
    mh, U = _mh_state(order, hn)
    p = 0.37
    red = mh.linearize(U, p)
    assert red.aux.shape == (mh.base.conn.shape[0], mh.phis.shape[0], mh.base.Np.shape[1])
    assert np.abs(red.aux).max() > 0.0
    mix = mh.linearize(U, p, aux=red.aux.copy())
    assert np.array_equal(mix.data, red.data) and np.array_equal(mix.R, red.R)
    assert np.array_equal(mix.aux, red.aux)


@pytest.mark.parametrize("hn", [[0, 1, 2], [0, 2, 4]])
def test_the_pressures_enter_the_tangent_linearly_and_not_the_residual(hn):
    mh, U = _mh_state(2, hn)
    p = 0.37
    red = mh.linearize(U, p)
    rng = np.random.default_rng(5)
    d = 0.1 * np.abs(red.aux).max() * rng.standard_normal(red.aux.shape)
    one = mh.linearize(U, p, aux=red.aux + d)
    two = mh.linearize(U, p, aux=red.aux + 2.0 * d)
    assert np.array_equal(one.R, red.R) and np.array_equal(two.R, red.R)
    d1, d2 = one.data - red.data, two.data - red.data
    assert np.abs(d1).max() > 1e-6 * np.abs(red.data).max()  # the pressures are used
    assert np.abs(d2 - 2.0 * d1).max() <= 1e-9 * np.abs(d1).max()


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("hn", [[0, 1, 2], [0, 2, 4]])
def test_the_pressures_derivative_against_central_differences(order, hn):
    mh, U = _mh_state(order, hn)
    p = 0.2
    lin = mh.linearize(U, p)
    x = np.random.default_rng(7).standard_normal(mh.n)
    exact = lin.aux_dir(x)
    scale = np.abs(exact).max()
    errs = []
    for h in (1e-4, 1e-5):
        fd = (mh.linearize(U + h * x, p).aux - mh.linearize(U - h * x, p).aux) / (2.0 * h)
        errs.append(np.abs(fd - exact).max() / scale)
    assert errs[1] < 1e-7
    assert errs[1] < 0.05 * errs[0]  # second order (a hundredfold for a tenfold h)


def test_an_imperfect_body_takes_no_pressures():
    M = _model(1)
    mh0 = MultiHarmonicModel(M, [0, 1, 2])
    mh = MultiHarmonicModel(M, [0, 1, 2], imperfection=_imperfection(mh0, 0.04))
    U = np.zeros(mh.n)
    assert getattr(mh.linearize(U, 0.0), "aux", None) is None
    with pytest.raises(ValueError, match="perfect body"):
        mh.linearize(U, 0.0, aux=np.zeros((M.conn.shape[0], mh.phis.shape[0], M.Np.shape[1])))


@pytest.fixture(scope="module")
def cap():
    """A clamped cap above the asymmetric threshold: harmonic 2 goes first, subcritically."""
    res = solve_scene(CapScene(theta_deg=30.0, eta=50.0, bc="clamped"), MeshSettings(nt=1, aspect=2.0),
                      SolverSettings())
    chk = check_harmonics(res, 4)
    return res, locate_bifurcation(res, int(chk.asym_n))


def test_a_branch_traced_with_either_tangent_lands_on_the_same_state(cap, monkeypatch):
    res, bif = cap
    out = {}
    for mixed in (False, True):
        monkeypatch.setattr(trace_mod, "MIXED_TANGENT", mixed)
        fr = trace_mod.follow_branch(res, bif, default_harmonics(bif.n))
        assert fr.states is not None and fr.states.lower is not None
        out[mixed] = fr
    a, b = out[False], out[True]
    for key in ("dE_J", "dy_pole_m", "V_star_m3", "p_star_Pa"):
        assert b.metrics[key] == pytest.approx(a.metrics[key], rel=1e-8, abs=0.0), key
    du = np.linalg.norm(b.states.lower.u - a.states.lower.u) / np.linalg.norm(a.states.lower.u)
    assert du < 1e-7
