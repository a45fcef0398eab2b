"""The nonlinear multi-harmonic model (snapjump_cli.fe.branch.model, kernels/multiharmonic.py).

Checks, each able to fail on a wrong term:

* harmonic 0 alone is the axisymmetric model: energy, residual, tangent and volume to round-off;
* linearised at an axisymmetric state it gives the harmonic check's ``K_n`` for every kept ``n``,
  and no coupling between harmonics;
* its residual and tangent are the derivatives of its energy and cavity volume (finite
  differences at non-axisymmetric states, Q4 and Q9);
* a finite rigid rotation (harmonics 0, 1, 2) and translation leave energy and volume unchanged;
* at a finite amplitude its energy and volume agree with the independent numpy evaluator of the
  harmonic-check tests (a different phi rule, complex-step phi derivative).
"""
from __future__ import annotations

import numpy as np
import pytest

from snapjump_cli.fe.stability.harmonics import harmonic_operator
from snapjump_cli.fe.axisym.model import Model
from snapjump_cli.fe.branch.model import MultiHarmonicModel, component_index
from tests.unit.test_harmonics_fd import Energy3D, _model, _state


def _smooth_modes(M: Model, hn, scale: float, shift: float = 0.0) -> dict:
    """Smooth amplitude fields per harmonic (vanishing on the axis like r^min(n, 2))."""
    X = M.X
    out = {}
    for n in hn[1:]:
        r = X[:, 0:1] ** min(n, 2)
        out[n] = scale * r * np.stack([np.sin(3 * X[:, 0] + n + shift) * np.cos(2 * X[:, 1]),
                                       np.cos(X[:, 0] - n * X[:, 1] + shift), np.sin(X[:, 1] + X[:, 0] - shift)], 1)
    return out


@pytest.mark.parametrize("order", [1, 2])
def test_harmonic_zero_alone_is_the_axisymmetric_model(order):
    M = _model(order)
    u, p = _state(M, 1), 0.7
    mh = MultiHarmonicModel(M, [0])
    U = mh.embed(u)
    assert mh.n == M.n
    a, b = M.linearize(u, p), mh.linearize(U, p)
    assert b.E == pytest.approx(a.E, rel=1e-13)
    assert b.V == pytest.approx(a.V, rel=1e-13)
    scale = np.abs(a.R).max()
    assert scale > 1e-3  # not an equilibrium: the comparison means something
    np.testing.assert_allclose(b.R, a.R, rtol=0, atol=1e-12 * scale)
    Ka, Kb = a.stiffness().toarray(), b.stiffness().toarray()
    np.testing.assert_allclose(Kb, Ka, rtol=0, atol=1e-12 * np.abs(Ka).max())


@pytest.mark.parametrize("hn", [[0, 1, 2], [0, 2, 4], [0, 3]])
def test_linearised_at_an_axisymmetric_state_it_gives_K_n(hn):
    M = _model(2)
    u, p = _state(M, 2), 0.9
    mh = MultiHarmonicModel(M, hn)
    K = mh.linearize(mh.embed(u), p).stiffness()
    rng = np.random.default_rng(3)
    nn = M.X.shape[0]
    for n in hn[1:]:
        op = harmonic_operator(M, n)
        Kn = op.matrix(u, p)
        x = op.to_nodal(op.to_vector(rng.standard_normal((nn, 3))))
        y = op.to_nodal(op.to_vector(rng.standard_normal((nn, 3))))
        xm, ym = mh.embed(np.zeros(M.n), {n: x}), mh.embed(np.zeros(M.n), {n: y})
        ref = op.to_vector(y) @ (Kn @ op.to_vector(x))
        assert ym @ (K @ xm) == pytest.approx(ref, rel=1e-11)
        # no coupling to the other harmonics at an axisymmetric state
        z0 = mh.embed(rng.standard_normal(M.n))
        size = np.sqrt(abs(ym @ (K @ ym)) * abs(z0 @ (K @ z0)))
        assert abs(z0 @ (K @ xm)) < 1e-11 * size
        for m in hn[1:]:
            if m != n:
                zm = mh.embed(np.zeros(M.n), {m: rng.standard_normal((nn, 3))})
                assert abs(zm @ (K @ xm)) < 1e-11 * np.sqrt(abs(ym @ (K @ ym)) * abs(zm @ (K @ zm)))


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("hn", [[0, 1, 2], [0, 2, 4]])
def test_residual_and_tangent_are_the_derivatives_of_the_energy(order, hn):
    M = _model(order)
    mh = MultiHarmonicModel(M, hn)
    p = 0.6
    U = mh.embed(_state(M, 4), _smooth_modes(M, hn, 0.02))
    v = mh.embed(0.01 * np.random.default_rng(5).standard_normal(M.n), _smooth_modes(M, hn, 1.0, shift=0.4))
    assert_derivatives_of_the_energy(mh, U, v, p)


def assert_derivatives_of_the_energy(mh: MultiHarmonicModel, U: np.ndarray, v: np.ndarray, p: float) -> None:
    """``dV/du``, the residual and the tangent of ``mh`` at ``U`` against central differences of
    its energy, volume and residual in the direction ``v``."""
    lin = mh.linearize(U, p)
    assert lin is not None
    h = 1e-6
    Ep, Em = mh.energy_volume(U + h * v), mh.energy_volume(U - h * v)
    dW, dV = (Ep[0] - Em[0]) / (2 * h), (Ep[1] - Em[1]) / (2 * h)
    assert lin.g @ v == pytest.approx(dV, rel=1e-7)
    assert lin.R @ v == pytest.approx(dW - p * dV, rel=1e-7)
    Kv = lin.stiffness() @ v
    fd = (mh.residual(U + h * v, p) - mh.residual(U - h * v, p)) / (2 * h)
    assert np.abs(fd - Kv).max() < 1e-7 * np.abs(Kv).max()


def test_finite_rigid_rotation_and_translation_leave_energy_and_volume_unchanged():
    """A rotation by theta about a horizontal axis of an axisymmetric state ``(r, z)`` is exactly
    ``a_0 = r (1 + cos) / 2 - R, b_0 = z cos - Z``, ``a_1 = z sin, b_1 = -r sin, c_1 = -z sin``,
    ``a_2 = r (cos - 1) / 2, c_2 = r (1 - cos) / 2``: a state of harmonics 0, 1, 2."""
    M = _model(2)
    u = _state(M, 6)
    mh = MultiHarmonicModel(M, [0, 1, 2], free_body=True)
    W0, V0 = M.energy(u), M.volume(u)
    x = M.positions(u)
    r, z = x[:, 0], x[:, 1]
    th = 0.3
    c, s = np.cos(th), np.sin(th)
    A = np.zeros((M.X.shape[0], mh.nc))
    A[:, 0] = r * (1 + c) / 2 - M.X[:, 0]
    A[:, 1] = z * c - M.X[:, 1]
    o1, o2 = component_index(1, 0), component_index(2, 0)
    A[:, o1], A[:, o1 + 1], A[:, o1 + 2] = z * s, -r * s, -z * s
    A[:, o2], A[:, o2 + 2] = r * (c - 1) / 2, r * (1 - c) / 2
    # the axis nodes satisfy the axis conditions exactly (r = 0); the model's own n = 0 constraints
    # (the sphere's poles fixed vertically? none: a free sphere) hold
    Ur = mh.free_vector(A)
    assert np.allclose(mh.amplitudes(Ur), A, atol=1e-14)
    W, V = mh.energy_volume(Ur)
    assert W == pytest.approx(W0, rel=1e-12)
    assert V == pytest.approx(V0, rel=1e-12)
    # a translation across the axis: a_1 = 1, c_1 = -1
    A2 = np.zeros_like(A)
    A2[:, :2] = M.full_displacement(u)
    A2[:, o1], A2[:, o1 + 2] = 0.2, -0.2
    W, V = mh.energy_volume(mh.free_vector(A2))
    assert W == pytest.approx(W0, rel=1e-12)
    assert V == pytest.approx(V0, rel=1e-12)


@pytest.mark.parametrize("n", [1, 2])
def test_finite_amplitude_energy_matches_the_independent_3d_evaluator(n):
    M = _model(2)
    u = _state(M, 7)
    ev = Energy3D(M, n, m_phi=96)
    mh = MultiHarmonicModel(M, [0, n], n_phi=48)
    A = _smooth_modes(M, [0, n], 1.0)[n]
    eps = 0.03
    A = harmonic_operator(M, n).to_nodal(harmonic_operator(M, n).to_vector(A))  # the axis conditions
    W_ref, V_ref = ev.potential(M.full_displacement(u), A, eps, 0.0)
    W, V = mh.energy_volume(mh.embed(u, {n: eps * A}))
    assert W == pytest.approx(W_ref, rel=1e-11)
    assert V == pytest.approx(V_ref, rel=1e-12)
    assert abs(W - M.energy(u)) > 1e-4 * abs(W)  # the amplitude matters


def test_the_phi_rule_converges():
    """The energy at a finite amplitude with the default rule against a fine one."""
    M = _model(2)
    U_axi = _state(M, 8)
    hn = [0, 1, 2]
    coarse, fine = MultiHarmonicModel(M, hn), MultiHarmonicModel(M, hn, n_phi=40)
    modes = _smooth_modes(M, hn, 0.02)
    Wc, Vc = coarse.energy_volume(coarse.embed(U_axi, modes))
    Wf, Vf = fine.energy_volume(fine.embed(U_axi, modes))
    assert Vc == pytest.approx(Vf, rel=1e-13)  # the cavity is a cubic: exact
    assert Wc == pytest.approx(Wf, rel=1e-6)


@pytest.mark.parametrize("hn, turned", [([0, 2, 4, 6], True), ([0, 3, 6], False), ([0, 1, 2], False)])
def test_a_turn_by_pi_over_n_c_is_a_symmetry_of_a_branch_model(hn, turned):
    """``secondary.rotation_signs``: for an even ``n_c`` the state turned by ``pi / n_c`` (harmonic
    ``m n_c`` times ``(-1)^m``) has the same energy and volume and the residual turned alike (a
    state of a branch turned is one of the same branch model; the secondary check looks at its
    other class of mirror planes through it); for an odd ``n_c`` and ``n_c = 1`` there is none."""
    from snapjump_cli.fe.branch.secondary import rotation_signs

    M = _model(2)
    mh = MultiHarmonicModel(M, hn)
    U = mh.embed(_state(M, 2), _smooth_modes(M, hn, 0.05))
    sgn = rotation_signs(mh)
    assert (sgn is not None) == turned
    if sgn is None:
        return
    assert set(np.unique(sgn)) == {-1.0, 1.0}
    a, b = mh.linearize(U, 0.9), mh.linearize(sgn * U, 0.9)
    assert b.E == pytest.approx(a.E, rel=1e-12) and b.V == pytest.approx(a.V, rel=1e-12)
    scale = np.abs(a.R).max()
    assert scale > 1e-3 and not np.allclose(sgn * U, U)  # not an equilibrium, and truly turned
    np.testing.assert_allclose(b.R, sgn * a.R, rtol=0, atol=1e-11 * scale)
