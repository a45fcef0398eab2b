"""The mirror-antisymmetric block of a multi-harmonic state (snapjump_cli.fe.stability.mirror).

On the coarse design of ``test_axisym_landing.py`` (sample row 12's, Q9, nt 1, aspect 8, its
``n = 1`` branch followed in the actuator mode) and on the small sphere of the harmonic check's
finite-difference tests:

* at an axisymmetric state (the landing state, and the bifurcation) the block is, harmonic by
  harmonic, the harmonic check's ``K_n`` turned by ``pi / 2n`` (``a' = -a``, ``b' = -b``,
  ``c' = c``; for ``n = 0`` its torsion), entry by entry, with no coupling between harmonics; the
  pencils have the same eigenvalues; the check's smallest eigenvalue and count are those of the
  dense pencil on the complement of the rigid modes;
* at an asymmetric equilibrium of the branch (traced on from the actuator mode's first step to a
  largest harmonic amplitude of 0.05 R_i) the translation along y and the rotation about the axis
  are null vectors of the block to round-off relative to its scale, and the check's numbers are
  those of the dense pencil with the excluded modes projected out;
* the block is the second derivative of the 3D potential ``W - p V`` of the state plus an
  antisymmetric perturbation, evaluated by an independent numpy code on the whole circle
  (:class:`tests.unit.test_harmonics_fd.Energy3D` with a general field).
"""
from __future__ import annotations

from contextlib import contextmanager

import numpy as np
import pytest
import scipy.linalg as sl

from snapjump_cli.fe.branch.followed import followed_metrics
from snapjump_cli.fe.branch.model import MultiHarmonicModel
from snapjump_cli.fe.continuation.stepping import trace
from snapjump_cli.fe.solve import solve_scene
from snapjump_cli.fe.stability.harmonics import check_harmonics, harmonic_operator
from snapjump_cli.fe.stability.mirror import MirrorOperator, mirror_stability
from snapjump_cli.geometry.caps import Design
from snapjump_cli.settings import MeshSettings, SolverSettings
from tests.unit.test_harmonics_fd import Energy3D, _mixed_fd, _model, _state
from tests.unit.test_multiharmonic import _smooth_modes


@pytest.fixture(scope="module")
def branch():
    """The followed branch of the landing test's design (actuator mode: it lands on the
    axisymmetric inverted state)."""
    res = solve_scene(Design(8.0, 72.5, 10.0, 76.0, 5.8), MeshSettings(order=2, nt=1, aspect=8.0),
                      SolverSettings(harmonics=4))
    chk = check_harmonics(res, 4)
    fr = followed_metrics(res, chk, mode="actuator").branch
    return res, fr


@pytest.fixture(scope="module")
def asymmetric(branch):
    """An asymmetric equilibrium of that branch: traced on from the actuator mode's first step
    until the largest harmonic amplitude reaches 0.05 (scaled by R_i)."""
    _, fr = branch
    mh = fr.model

    def amp(u):
        return max(float(np.abs(mh.harmonic_part(u, n)).max()) for n in (1, 2, 3, 4))

    def stop(path):
        if amp(path.points[-1].u) >= 0.05:
            return "asymmetric enough"
        return "too many steps" if len(path.points) > 150 else None

    path = trace(mh, fr.tracer.cfg, stop, tracer=fr.tracer, start=fr.path.points[-1])
    pt = path.points[-1]
    assert amp(pt.u) >= 0.05
    return mh, pt


def _dense(A) -> np.ndarray:
    return A.toarray() if hasattr(A, "toarray") else np.asarray(A)


@contextmanager
def _one_blas_thread():
    """scipy's OpenBLAS on one thread while inside (restored after; a no-op where its library is
    not found): a dense eigensolve of a few hundred rows takes 5 s instead of 0.02 s when the
    other core is busy and its threads wait for each other."""
    import ctypes
    import glob
    import os

    import scipy

    libs = glob.glob(os.path.join(os.path.dirname(scipy.__file__), os.pardir, "scipy.libs", "*openblas*"))
    dll = None
    for path in libs:
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        if hasattr(lib, "scipy_openblas_set_num_threads") and hasattr(lib, "scipy_openblas_get_num_threads"):
            dll = lib
            break
    before = dll.scipy_openblas_get_num_threads() if dll is not None else None
    if dll is not None:
        dll.scipy_openblas_set_num_threads(1)
    try:
        yield
    finally:
        if dll is not None:
            dll.scipy_openblas_set_num_threads(before)


def _dense_projected(op: MirrorOperator, u, p) -> np.ndarray:
    """The eigenvalues of the block's pencil on the ``M``-orthogonal complement of the modes the
    check excludes (dense)."""
    K, M = _dense(op.matrix(u, p)), _dense(op.mass())
    Q, _, _ = op.null_modes(u)
    with _one_blas_thread():
        Z = sl.null_space((M @ Q.T).T) if Q.shape[0] else np.eye(K.shape[0])
        return sl.eigh(Z.T @ K @ Z, Z.T @ M @ Z, eigvals_only=True)


def _harmonic_map(op: MirrorOperator, hop, n: int):
    """The block's dofs of harmonic ``n`` matching the harmonic check's dofs of ``n``, with the
    signs of the rotation by ``pi / 2n`` (``a' = -a``, ``b' = -b``, ``c' = c``; the torsion alone
    for ``n = 0``)."""
    idx_h, idx_a, sgn = [], [], []
    L = hop.layout
    for node in range(L.dofmap.shape[0]):
        for comp in range(3):
            dh = L.dofmap[node, comp]
            if dh < 0 or (comp == 2 and hop.tied[node]) or (n == 0 and comp < 2):
                continue
            da = op.dofmap[node, 3 * n + comp]
            assert da >= 0, (node, n, comp)  # the same constraints
            idx_h.append(dh)
            idx_a.append(da)
            sgn.append(-1.0 if comp < 2 else 1.0)
    return np.array(idx_h), np.array(idx_a), np.array(sgn)


@pytest.mark.parametrize("which", ["lower", "upper"])
def test_at_an_axisymmetric_state_the_block_is_the_harmonic_check_turned(branch, which):
    res, fr = branch
    mh = fr.model
    pt = getattr(fr.states, which)
    for n in mh.hn[1:]:
        assert np.abs(mh.harmonic_part(pt.u, int(n))).max() < 1e-12  # axisymmetric
    u_axi = res.model.free_vector(mh.amplitudes(pt.u)[:, :2])
    op = MirrorOperator(mh)
    K, Mm = _dense(op.matrix(pt.u, pt.p)), _dense(op.mass())
    scale = np.abs(K).max()
    seen = np.zeros(op.ndof, bool)
    blocks = []
    for n in range(5):
        hop = harmonic_operator(res.model, n)
        ih, ia, s = _harmonic_map(op, hop, n)
        assert len(set(ia)) == len(ia)
        Kn = _dense(hop.matrix(u_axi, pt.p))[np.ix_(ih, ih)]
        Mn = _dense(hop.mass())[np.ix_(ih, ih)]
        Ka = K[np.ix_(ia, ia)] * np.outer(s, s)
        assert np.abs(Ka - Kn).max() <= 1e-12 * scale, n
        assert np.abs(Mm[np.ix_(ia, ia)] * np.outer(s, s) - Mn).max() <= 1e-14 * np.abs(Mn).max(), n
        with _one_blas_thread():
            ev_a = sl.eigh(K[np.ix_(ia, ia)], Mm[np.ix_(ia, ia)], eigvals_only=True)
            ev_h = sl.eigh(Kn, Mn, eigvals_only=True)
        # the dense solver's eigenvalues are accurate to round-off of the largest (the rigid zeros
        # of n = 1 come out at +-1e-8 with a largest eigenvalue of 4e8)
        assert np.allclose(ev_a, ev_h, rtol=1e-9, atol=1e-14 * np.abs(ev_h).max()), n
        seen[ia] = True
        blocks.append(ia)
    assert seen.all()  # every dof of the block is one of some harmonic's
    for i, a in enumerate(blocks):  # no coupling between harmonics at an axisymmetric state
        for b in blocks[i + 1:]:
            assert np.abs(K[np.ix_(a, b)]).max() <= 1e-12 * scale
    # the check: the dense pencil with the rigid modes projected out
    chk = mirror_stability(op, pt.u, pt.p)
    assert chk.n_rigid == chk.n_excluded == 3  # translation along y, rotations about x and z
    for name in ("ty", "rx", "rz"):
        assert abs(chk.rigid_quotients[name]) < 1e-9, (name, chk.rigid_quotients)
    ev = _dense_projected(op, pt.u, pt.p)
    assert chk.certified
    # to the dense solver's accuracy: round-off of the largest eigenvalue (the bifurcation's ~0)
    assert chk.smallest == pytest.approx(ev[0], rel=1e-7, abs=1e-16 * np.abs(ev).max())
    assert chk.n_unstable == int(np.sum(ev < -1e-6 * float(np.min(res.model.mu))))


def test_at_an_asymmetric_equilibrium_the_rigid_modes_are_null_and_the_check_runs(asymmetric):
    mh, pt = asymmetric
    op = MirrorOperator(mh)
    K = op.matrix(pt.u, pt.p)
    scale = float(np.abs(K.diagonal()).max())
    _, nr, named = op.null_modes(pt.u)
    assert nr == 3 and set(named) == {"ty", "rx", "rz", "phase"}
    for name in ("ty", "rz"):  # exactly in the truncated space: null to round-off and the state's residual
        r = named[name]
        assert np.linalg.norm(K @ r) <= 1e-10 * scale * np.linalg.norm(r), name
    # the rotation about x needs harmonic N + 1 and the shape's rotation is exact only for the
    # phi-average: null vectors only to the truncation and the rule (both are excluded); their
    # quotients are small beside the block's physical eigenvalues
    chk = mirror_stability(op, pt.u, pt.p)
    assert chk.n_excluded == 4 and chk.certified
    ev = _dense_projected(op, pt.u, pt.p)
    # to the dense solver's accuracy: round-off of the largest eigenvalue (the bifurcation's ~0)
    assert chk.smallest == pytest.approx(ev[0], rel=1e-7, abs=1e-16 * np.abs(ev).max())
    assert chk.n_unstable == int(np.sum(ev < -1e-6 * float(np.min(mh.base.mu))))
    assert max(abs(chk.rigid_quotients["rx"]), abs(chk.rigid_quotients["phase"])) < 0.1 * abs(chk.smallest)


class Energy3DGeneral(Energy3D):
    """:class:`Energy3D` of a general field: the multi-harmonic state's total amplitudes ``U =
    (hn, A)`` plus ``eps`` times an antisymmetric perturbation ``A`` ``(nn, 3 K)``."""

    def _rings(self, U, A, eps, phi):
        hn, S = U
        X = self.M.X
        rho = X[:, 0] + 0 * phi
        sig = 0 * X[:, 0] + 0 * phi
        z = X[:, 1] + 0 * phi
        o = 0
        for k, n in enumerate(hn):
            c, s = np.cos(n * phi), np.sin(n * phi)
            rho = rho + S[:, o] * c + eps * A[:, 3 * k] * s
            z = z + S[:, o + 1] * c + eps * A[:, 3 * k + 1] * s
            sig = sig + eps * A[:, 3 * k + 2] * c
            if k > 0:
                sig = sig + S[:, o + 2] * s
            o += 2 if k == 0 else 3
        cp, sp = np.cos(phi), np.sin(phi)
        return np.stack([rho * cp - sig * sp, rho * sp + sig * cp, z], axis=-1)


def test_the_block_is_the_second_variation_of_the_3d_potential():
    M = _model(2)
    hn = [0, 1, 2, 3]
    mh = MultiHarmonicModel(M, hn)
    u = mh.embed(_state(M, 21), _smooth_modes(M, hn, 0.05))
    p = 0.9
    op = MirrorOperator(mh)
    K = op.matrix(u, p)
    ev = Energy3DGeneral(M, 1)
    m = mh.n_phi
    ev.phi = np.pi * np.arange(2 * m) / m  # the model's rule on [0, pi], on the whole circle
    U = (hn, mh.total_amplitudes(u))
    rng = np.random.default_rng(5)
    for _ in range(3):
        v, w = rng.standard_normal(op.ndof), rng.standard_normal(op.ndof)
        Av, Aw = op.to_nodal(v), op.to_nodal(w)
        fd = _mixed_fd(lambda s, t: ev.Pi(U, s * Av + t * Aw, 1.0, p), 5e-4)
        exact = v @ (K @ w)
        scale = np.sqrt(abs(v @ (K @ v)) * abs(w @ (K @ w)))
        assert abs(fd - exact) <= 5e-9 * scale, (fd, exact, scale)
    assert abs(K - K.T).max() <= 1e-12 * abs(K).max()


def test_a_model_of_multiples_of_n_c_is_rejected(branch):
    res, _ = branch
    with pytest.raises(ValueError, match="consecutive harmonics"):
        MirrorOperator(MultiHarmonicModel(res.model, [0, 2, 4]))
