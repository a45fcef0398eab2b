"""Stability of a multi-harmonic state against the mirror-antisymmetric perturbations it leaves out.

:class:`~snapjump_cli.fe.branch.model.MultiHarmonicModel` keeps the displacements that are
mirror-symmetric about ``phi = 0``::

    u_r = sum_k a_k cos k phi,   u_z = sum_k b_k cos k phi,   u_phi = sum_k c_k sin k phi.

That subspace is invariant, so a state of the model is an equilibrium of the 3D problem, but the
model's own inertia checks its stability only against perturbations of the same symmetry. At a
mirror-symmetric state the second variation of ``Pi = W - p (V - V*)`` has no terms coupling these
to the antisymmetric perturbations (the cross terms are odd in phi and the rule integrates them to
zero), so the rest of the answer is the *antisymmetric block*, the second variation over::

    du_r = sum_k a'_k sin k phi,   du_z = sum_k b'_k sin k phi,   du_phi = sum_k c'_k cos k phi

``k = 0..N`` (for ``k = 0`` only ``c'_0``: the torsion). It is assembled by
:mod:`snapjump_kernels.mh_mirror` for the model's own phi rule. The cavity volume's first
variation vanishes in these directions (its integrand is odd in phi), so volume control places no
constraint on them: the pressure enters only through ``-p d2V``, and the block is checked as a
harmonic ``K_n`` is (docs/harmonics.md, sections 4-6 and "Mirror-antisymmetric perturbations").

Constraints of the antisymmetric amplitudes (single-valued on the axis: ``u_x = (a' - c')/2
sin(k+1)phi + (a' + c')/2 sin(k-1)phi``, ``u_y = (a' + c')/2 cos(k-1)phi + (c' - a')/2
cos(k+1)phi``): ``k = 0``: ``c'_0 = 0`` on the axis (and where the model holds a node, as the
harmonic check's ``n = 0`` torsion); ``k = 1``: ``b' = 0`` and ``c' = +a'`` on the axis (the
translation along y; the symmetric family has ``c = -a``); ``k >= 2``: all zero there. A supported
cap keeps its supports (``dirichlet_y``: ``b' = 0``; ``dirichlet_x``: ``a' = c' = 0``), as the model
does for ``k >= 1``.

Modes excluded (those the constraints admit; :meth:`MirrorOperator.null_modes`): the rigid
motions of the *current* configuration in this family, the translation along y, the rotation about
the x axis and the rotation about the axis z, and, at an asymmetric state, the rotation of the
state's shape about the axis, ``-du/dphi`` (the reference body is axisymmetric, so the turned state
is an equilibrium as well: a neutral direction of an O(2)-symmetric problem, not a margin). The
translation and the rotation about z lie in the truncated space of harmonics ``0..N`` exactly and
are null vectors of the block at an equilibrium (to round-off and the state's residual). The
rotation about x of a state with harmonic ``N`` needs harmonic ``N + 1``: it is a null vector only
at an axisymmetric state; at an asymmetric one its truncation to ``0..N`` is one only to the
truncation's accuracy (quotients up to ~0.3 ``mu_i / R_i^2`` at the landing states of the sample,
whose amplitudes reach 0.4 ``R_i``). The shape's rotation is exact for the phi-average and a null
vector to the trapezoidal rule's aliasing (quotients up to ~4e-3). The quotients are reported
(:attr:`MirrorCheck.rigid_quotients`). Both numbers of the check are those of the pencil
``(K', M')`` on the ``M'``-orthogonal complement of the excluded modes: the count from Sylvester's
and Haynsworth's laws (:func:`_restricted_count`: the band ``LDL^T`` of ``K' + ZERO_TOL mu_min M'``
and a ``k x k`` Schur complement), the smallest eigenvalue by shift-invert Lanczos with the bordered
solve (as the margins), certified by the same count just below it.

Units: the eigenvalues are those of the scaled model (lengths / ``R_i``, stresses / ``mu_i``),
``mu_i / R_i^2``, as the harmonic margins (docs/harmonics.md, section 11): ``M'`` is the L2 mass
of the 3D perturbation, ``1/2`` per amplitude of ``k >= 1`` and ``1`` for ``c'_0``.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from snapjump_cli.fe.stability.eigen import negative_eigenvalues
from snapjump_cli.fe.stability.harmonics import ZERO_TOL
from snapjump_cli.mesh.data import number_dofs
from snapjump_kernels.calls import mirror_cavity, mirror_elements

if TYPE_CHECKING:
    from snapjump_cli.fe.branch.model import MultiHarmonicModel

log = logging.getLogger(__name__)

__all__ = ["MirrorCheck", "MirrorOperator", "mirror_stability"]


def _column(k: int, comp: int) -> int:
    """Column of harmonic index ``k`` and component ``comp`` (0 a, 1 b, 2 c) in the model's nodal
    amplitudes (:func:`snapjump_cli.fe.branch.model.component_index`, which ``fe/stability`` may
    not import: the branch stage is above it)."""
    return comp if k == 0 else 2 + 3 * (k - 1) + comp


@dataclass
class MirrorCheck:
    """What :func:`mirror_stability` found at one state.

    ``n_unstable``: eigenvalues of the antisymmetric block's pencil below ``-tol mu_min`` on the
    ``M``-orthogonal complement of the excluded modes (-1 if a zero pivot made the count fail, or
    outside the Gent domain); ``smallest``: its smallest eigenvalue there (``mu_i / R_i^2``; None if
    not computed or outside the domain); ``certified``: the inertia count found no eigenvalue below
    ``smallest``; ``n_rigid``: rigid motions excluded (3 for a free body: translation along y,
    rotations about x and z); ``n_excluded``: all modes excluded (``n_rigid`` plus the rotation of
    an asymmetric state's shape about the axis); ``rigid_quotients``: ``r^T K r / r^T M r`` of each
    candidate mode by name (``ty``, ``rx``, ``rz``, ``phase``; ``mu_i / R_i^2``; zero for an exact
    null vector); ``ndof``: the block's size; ``wall_s``: the time it took."""

    n_unstable: int
    smallest: float | None
    n_rigid: int
    ndof: int
    n_excluded: int = 0
    certified: bool = False
    rigid_quotients: dict[str, float] = field(default_factory=dict)
    wall_s: float = 0.0

    def as_dict(self) -> dict:
        """The fields as a plain dict (JSON-friendly)."""
        return {"n_unstable": self.n_unstable, "smallest": self.smallest, "n_rigid": self.n_rigid,
                "n_excluded": self.n_excluded, "ndof": self.ndof, "certified": self.certified,
                "rigid_quotients": dict(self.rigid_quotients), "wall_s": self.wall_s}


class MirrorOperator:
    """The antisymmetric block of a :class:`~snapjump_cli.fe.branch.model.MultiHarmonicModel` with
    the consecutive harmonics ``0, 1, ..., N``: its dof layout (module docstring), the block and
    its mass at any state, the rigid modes.

    Parameters
    ----------
    model : the multi-harmonic model; its ``hn`` must be ``0, 1, ..., N`` (``N >= 1``): a model of
        the multiples of ``n_c >= 2`` is rejected (its antisymmetric perturbations of the other
        harmonics are not in the block; lift its states into the model of every harmonic,
        :func:`snapjump_cli.fe.branch.secondary.full_model`, first)
    """

    def __init__(self, model: MultiHarmonicModel) -> None:
        hn = np.asarray(model.hn, np.int64)
        if len(hn) < 2 or not np.array_equal(hn, np.arange(len(hn))):
            raise ValueError("the mirror check needs the consecutive harmonics 0, 1, ..., N (N >= 1), "
                             f"got {list(map(int, hn))}: lift a branch of n_c >= 2 into the model of every "
                             "harmonic first")
        self.model = model
        base = model.base
        mesh = base.mesh
        self.K = K = len(hn)
        self.nda = 3 * K
        nn = base.X.shape[0]
        fixed = np.zeros((nn, self.nda), bool)
        tied = np.zeros(nn, bool)
        axis = np.asarray(mesh.node_sets["axis"], np.int64)
        dx = np.asarray(mesh.node_sets.get("dirichlet_x", np.zeros(0, np.int64)), np.int64)
        dy = np.asarray(mesh.node_sets.get("dirichlet_y", np.zeros(0, np.int64)), np.int64)
        # k = 0: only the torsion c'_0, held as the harmonic check's n = 0 torsion is
        fixed[:, 0:2] = True
        fixed[axis, 2] = True
        fixed[base.fixed[:, 0] & base.fixed[:, 1], 2] = True
        fixed[dx, 2] = True
        for k in range(1, K):
            o = 3 * k
            if not model.free_body:
                fixed[dx, o] = fixed[dx, o + 2] = True
                fixed[dy, o + 1] = True
            fixed[axis, o + 1] = True
            if k == 1:
                tied[axis] = ~fixed[axis, o]
                fixed[axis, o + 2] = True  # c' = +a' on the axis: represented by the a' dof
            else:
                fixed[axis, o:o + 3] = True
        self.fixed, self.tied = fixed, tied
        key = np.where(base.dofmap >= 0, base.dofmap, np.iinfo(np.int64).max).min(axis=1)
        order = np.argsort(key, kind="stable")  # the model's (banded) node order
        dofmap, ndof = number_dofs(order, fixed)
        coef = np.ones((nn, self.nda))
        dofmap[tied, 5] = dofmap[tied, 3]
        self.dofmap, self.coef, self.ndof = dofmap, coef, ndof
        conn, edges = base.conn, base.edges
        self.edofs = dofmap[conn].reshape(conn.shape[0], -1)
        self.ecoef = coef[conn].reshape(conn.shape[0], -1)
        self.gdofs = dofmap[edges].reshape(edges.shape[0], -1)
        self.gcoef = coef[edges].reshape(edges.shape[0], -1)
        self._mass = None

    # ---- vectors -------------------------------------------------------------------------------
    def to_vector(self, A: np.ndarray) -> np.ndarray:
        """Nodal antisymmetric amplitudes ``(nn, 3 K)`` -> dof vector (fixed entries dropped; a tied
        ``c'`` is represented by its ``a'``)."""
        v = np.zeros(self.ndof)
        m = self.dofmap >= 0
        m[self.tied, 5] = False
        v[self.dofmap[m]] = np.asarray(A)[m] / self.coef[m]
        return v

    def to_nodal(self, v: np.ndarray) -> np.ndarray:
        """Dof vector -> nodal amplitudes ``(nn, 3 K)`` (zeros where fixed)."""
        A = np.zeros(self.dofmap.shape)
        m = self.dofmap >= 0
        A[m] = v[self.dofmap[m]] * self.coef[m]
        return A

    # ---- matrices ------------------------------------------------------------------------------
    @staticmethod
    def _coo(Me: np.ndarray, d: np.ndarray, c: np.ndarray, fac: float):
        nd = d.shape[1]
        r, cc = np.repeat(d, nd, axis=1), np.tile(d, (1, nd))
        v = fac * Me.reshape(len(d), -1) * np.repeat(c, nd, axis=1) * np.tile(c, (1, nd))
        ok = (r >= 0) & (cc >= 0)
        return r[ok], cc[ok], v[ok]

    def matrix(self, u: np.ndarray, p: float):
        """The antisymmetric block at the state ``(u, p)`` of the model (scipy CSR, scaled units);
        ``None`` outside the Gent domain."""
        import scipy.sparse as sp

        mh, M = self.model, self.model.base
        A = np.ascontiguousarray(mh.total_amplitudes(u))
        ok, Ke = mirror_elements(A, M.conn, M.mat, M.mu, M.jm, M.kappa, M.dNdX, M.N_ref, M.Rq, M.Wq, M.Np, M.Minv,
                                 mh.hn, mh.phis, mh.wphi, mh.Fi, mh.Jimp, mh.Minvp)
        if not ok:
            return None
        He = mirror_cavity(M.X, A, M.edges, mh.hn, mh.phis, mh.wphi)
        parts = [self._coo(Ke, self.edofs, self.ecoef, 1.0), self._coo(He, self.gdofs, self.gcoef, -float(p))]
        r = np.concatenate([x[0] for x in parts])
        c = np.concatenate([x[1] for x in parts])
        v = np.concatenate([x[2] for x in parts])
        Kc = sp.csr_matrix((v, (r, c)), shape=(self.ndof, self.ndof))
        Kc.sum_duplicates()
        return Kc

    def mass(self):
        """The L2 mass of the 3D perturbation, ``int |du|^2 dV`` (phi-averages ``1/2`` for the
        amplitudes of ``k >= 1``, ``1`` for ``c'_0``; scipy CSR)."""
        import scipy.sparse as sp

        if self._mass is None:
            M = self.model.base
            Me = np.einsum("eq,qa,qb->eab", M.Wq, M.N_ref, M.N_ref)
            ne, nen = Me.shape[0], Me.shape[1]
            Me3 = np.zeros((ne, nen, self.nda, nen, self.nda))
            for col in range(self.nda):
                w = 1.0 if col < 3 else 0.5
                Me3[:, :, col, :, col] = w * Me
            r, c, v = self._coo(Me3.reshape(ne, nen * self.nda, nen * self.nda), self.edofs, self.ecoef, 1.0)
            self._mass = sp.csr_matrix((v, (r, c)), shape=(self.ndof, self.ndof))
            self._mass.sum_duplicates()
        return self._mass

    # ---- rigid modes ---------------------------------------------------------------------------
    def rigid_nodal(self, u: np.ndarray) -> np.ndarray:
        """The translation along y, the rotation about x and the rotation about z of the current
        configuration at ``u`` as antisymmetric nodal amplitudes ``(3, nn, 3 K)`` (harmonics
        ``0..N``; the rotation about x of a state with harmonic ``N`` loses its part in ``N + 1``).

        Each rigid velocity ``v`` (``e_y``, ``e_x x x``, ``e_z x x``) is sampled on a uniform phi grid
        fine enough for its harmonics (at most ``N + 1``), taken to cylindrical components and
        projected on ``sin k phi`` (``v_r``, ``v_z``) and ``cos k phi`` (``v_phi``)."""
        mh = self.model
        A = mh.total_amplitudes(u)
        X = mh.base.X
        K = self.K
        ms = 4 * (K + 2)
        phi = 2.0 * np.pi * np.arange(ms) / ms
        kk = np.arange(K)
        cos, sin = np.cos(np.outer(kk, phi)), np.sin(np.outer(kk, phi))  # (K, ms)
        a = np.stack([A[:, _column(k, 0)] for k in range(K)], axis=1)  # (nn, K)
        b = np.stack([A[:, _column(k, 1)] for k in range(K)], axis=1)
        c = np.stack([np.zeros(len(X))] + [A[:, _column(k, 2)] for k in range(1, K)], axis=1)
        r = X[:, :1] + a @ cos  # (nn, ms)
        s = c @ sin
        z = X[:, 1:2] + b @ cos
        cp, sp_ = np.cos(phi), np.sin(phi)
        x = r * cp - s * sp_
        y = r * sp_ + s * cp
        one, zero = np.ones_like(x), np.zeros_like(x)
        vel = [(zero, one, zero), (zero, -z, y), (-y, x, zero)]
        out = np.zeros((3, len(X), self.nda))
        for i, (vx, vy, vz) in enumerate(vel):
            vr = vx * cp + vy * sp_
            vp = -vx * sp_ + vy * cp
            for k in range(K):
                f = (1.0 if k == 0 else 2.0) / ms
                if k > 0:
                    out[i, :, 3 * k] = f * (vr @ sin[k])
                    out[i, :, 3 * k + 1] = f * (vz @ sin[k])
                out[i, :, 3 * k + 2] = f * (vp @ cos[k])
        return out

    def phase_nodal(self, u: np.ndarray) -> np.ndarray:
        """The rotation of the state's *shape* about the axis, ``-d u / d phi``, as antisymmetric
        nodal amplitudes ``(nn, 3 K)``: ``a'_k = k a_k``, ``b'_k = k b_k``, ``c'_k = -k c_k``.

        The reference body is axisymmetric, so the state turned about the axis (material and
        spatial rotation together) is an equilibrium too: at an asymmetric state this is a null
        vector of the block (an exact one for the phi-average, to the phi rule's aliasing for the
        model's trapezoidal rule), a neutral direction, not a margin; zero at an axisymmetric state."""
        A = self.model.amplitudes(u)
        out = np.zeros((A.shape[0], self.nda))
        for k in range(1, self.K):
            o = _column(k, 0)
            out[:, 3 * k] = k * A[:, o]
            out[:, 3 * k + 1] = k * A[:, o + 1]
            out[:, 3 * k + 2] = -k * A[:, o + 2]
        return out

    def null_modes(self, u: np.ndarray) -> tuple[np.ndarray, int, dict[str, np.ndarray]]:
        """The modes excluded from the block at ``u``: ``(Q, n_rigid, named)``.

        ``named``: the candidates as dof vectors, each scaled to a largest entry of 1 (``"ty"``
        translation along y, ``"rx"`` rotation about x, ``"rz"`` rotation about z, and, at an
        asymmetric state of a body without imperfection, ``"phase"``: :meth:`phase_nodal`);
        ``Q (k, ndof)``: an orthonormal basis of their combinations that vanish on every fixed
        amplitude (those the constraints admit); ``n_rigid``: how many of the ``k`` are rigid
        motions (the rest is the phase mode)."""
        nodal = list(self.rigid_nodal(u))
        names = ["ty", "rx", "rz"]
        ph = self.phase_nodal(u)
        scale = max(1.0, float(np.abs(self.model.amplitudes(u)).max()))
        if not self.model.A_imp.any() and np.abs(ph).max() > 1e-9 * scale:
            nodal.append(ph)
            names.append("phase")
        modes = np.stack(nodal)
        modes /= np.abs(modes).reshape(len(modes), -1).max(axis=1)[:, None, None]
        fixed = self.fixed.copy()
        fixed[self.tied, 5] = False
        vecs = np.stack([self.to_vector(m) for m in modes])
        named = dict(zip(names, vecs))

        def basis(V: np.ndarray) -> np.ndarray:
            if V.shape[0] == 0:
                return V
            _, sv, vt = np.linalg.svd(V, full_matrices=False)
            return vt[sv > 1e-8 * sv[0]]

        C = modes[:, fixed].T  # (n_fixed, k): the modes' values on the fixed amplitudes
        if C.shape[0] and np.abs(C).max() > 1e-12:
            _, sv, vt = np.linalg.svd(C, full_matrices=True)
            vecs_ok = vt[int(np.sum(sv > 1e-8)):] @ vecs  # (the modes' largest entries are 1)
            _, svr, vtr = np.linalg.svd(C[:, :3], full_matrices=True)
            rig_ok = vtr[int(np.sum(svr > 1e-8)):] @ vecs[:3]
        else:
            vecs_ok, rig_ok = vecs, vecs[:3]
        Qr = basis(rig_ok)
        Q = basis(vecs_ok)
        return Q, int(Qr.shape[0]), named


def _projected_eigs(K, M, R: np.ndarray, sigma: float, k: int = 2):
    """The ``k`` eigenvalues of ``(K, M)`` nearest ``sigma`` on the ``M``-orthogonal complement of the
    rows of ``R`` (shift-invert Lanczos; the inverse is the bordered solve ``[[K - sigma M, M R^T],
    [R M, 0]]``, as :func:`snapjump_cli.fe.stability.eigen._eig_near_projected`)."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    n, m = K.shape[0], R.shape[0]
    if m:
        C = sp.csr_matrix(M @ R.T)
        lu = spla.splu(sp.bmat([[K - sigma * M, C], [C.T, None]], format="csc"))
        inv = spla.LinearOperator((n, n), matvec=lambda x: lu.solve(np.concatenate([np.ravel(x), np.zeros(m)]))[:n],
                                  dtype=float)
    else:
        lu = spla.splu((K - sigma * M).tocsc())
        inv = spla.LinearOperator((n, n), matvec=lambda x: lu.solve(np.ravel(x)), dtype=float)
    v0 = np.random.default_rng(0).standard_normal(n)  # fixed: reproducible answers
    return spla.eigsh(K, k=k, M=M, sigma=sigma, which="LM", v0=v0, OPinv=inv)


def _restricted_count(K, M, Q: np.ndarray, s: float) -> int:
    """Eigenvalues below ``s`` of the pencil ``(K, M)`` restricted to the ``M``-orthogonal
    complement of the rows of ``Q`` (``(k, n)``, independent); -1 on a zero pivot.

    With ``A = K - s M`` and ``C = M Q^T``, the bordered matrix ``[[A, C], [C^T, 0]]`` has the
    inertia of ``A`` on ``ker C^T`` plus ``k`` positive and ``k`` negative eigenvalues, and by
    Haynsworth that of ``A`` plus that of ``-C^T A^-1 C``: the count is ``neg(A) + pos(C^T A^-1 C)
    - k`` (``neg(A)``: the negative pivots of its band ``LDL^T``, Sylvester; ``C^T A^-1 C`` from a
    sparse LU)."""
    import scipy.sparse.linalg as spla

    A = (K - s * M).tocsc()
    A.sum_duplicates()
    neg = negative_eigenvalues(A)
    if neg < 0:
        return -1
    k = Q.shape[0]
    if k == 0:
        return neg
    C = np.asarray(M @ Q.T)
    S = C.T @ spla.splu(A).solve(C)
    pos = int(np.sum(np.linalg.eigvalsh(0.5 * (S + S.T)) > 0.0))
    return neg + pos - k


def mirror_stability(model: MultiHarmonicModel | MirrorOperator, u: np.ndarray, p: float, tol: float = ZERO_TOL,
                     eigen: bool = True, shift: float = 2.0, rel: float = 1e-6) -> MirrorCheck:
    """The antisymmetric block's unstable count and smallest eigenvalue at a state of ``model``.

    The rigid modes the constraints admit and, at an asymmetric state, the rotation of the shape
    about the axis (:meth:`MirrorOperator.null_modes`) are excluded: both numbers are those of the
    pencil ``(K', M')`` on the ``M'``-orthogonal complement of those modes.

    Parameters
    ----------
    model : :class:`~snapjump_cli.fe.branch.model.MultiHarmonicModel` with harmonics ``0, 1, ..., N``
        (otherwise ValueError, see :class:`MirrorOperator`), or its :class:`MirrorOperator`
    u, p : the state (free vector of ``model``, scaled pressure); an equilibrium for the excluded
        modes to be null vectors
    tol : eigenvalues above ``-tol mu_min`` count as zero (the harmonic check's
        :data:`~snapjump_cli.fe.stability.harmonics.ZERO_TOL`)
    eigen : also compute the smallest eigenvalue (shift-invert Lanczos)
    shift, rel : the first shift ``-shift mu_min`` of the Lanczos search, and the relative margin
        ``delta = rel max(|lambda|, mu_min)`` of its certificate (as
        :func:`snapjump_cli.fe.stability.eigen.smallest_eigenvalue`)

    Returns
    -------
    MirrorCheck
    """
    t0 = time.perf_counter()
    op = model if isinstance(model, MirrorOperator) else MirrorOperator(model)
    K = op.matrix(u, p)
    if K is None:
        return MirrorCheck(-1, None, 0, op.ndof, wall_s=time.perf_counter() - t0)
    M = op.mass()
    mu = float(np.min(op.model.base.mu))
    Q, nr, named = op.null_modes(u)
    quot = {k: float(r @ (K @ r)) / float(r @ (M @ r)) for k, r in named.items()}
    n_unst = _restricted_count(K, M, Q, -tol * mu)
    if n_unst < 0:
        log.warning("mirror check: zero pivot in the band LDL^T; count not available")
    out = MirrorCheck(n_unst, None, nr, op.ndof, n_excluded=int(Q.shape[0]), rigid_quotients=quot)
    if eigen:
        sigma = -shift * mu
        lam = None
        for _ in range(6):
            vals, _ = _projected_eigs(K, M, Q, sigma)
            lam = float(np.min(vals))
            below = _restricted_count(K, M, Q, lam - rel * max(abs(lam), mu))
            if below == 0:
                out.certified = True
                break
            sigma = lam - 10.0 * max(abs(lam), mu)  # a lower one exists: search below
        else:
            log.warning("mirror check: smallest eigenvalue not certified")
        out.smallest = lam
    out.wall_s = time.perf_counter() - t0
    log.info("mirror-antisymmetric block: %d unstable, smallest %s (%d dofs, %d modes excluded, %.2f s)",
             out.n_unstable, "n/a" if out.smallest is None else f"{out.smallest:.6g}", op.ndof, out.n_excluded,
             out.wall_s)
    return out
