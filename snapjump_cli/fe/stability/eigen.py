"""The eigenvalue and inertia helpers of the stability checks, in one place.

* of a harmonic's pencil ``(K_n, M_n)`` (:class:`~snapjump_cli.fe.stability.harmonics.HarmonicOperator`,
  rigid modes gauged out): :func:`harmonic_inertia` (the count of unstable modes),
  :func:`eig_near` (the eigenvalues nearest a shift, shift-invert Lanczos; with ``project``, the
  rigid modes of ``n = 1`` projected out instead, ``M``-orthogonally),
  :func:`smallest_eigenvalue` (certified by the inertia: the margins, rigid modes projected out),
  :func:`lowest_eigen` (with its mode: the bifurcations of the axisymmetric path), and
  :func:`axis_rotation` (the rigid rotation about the axis that ``n = 0`` leaves out);
* of a symmetric band (the block of the harmonics outside a followed branch, whose model is any
  object with ``block_band(u, p, harmonics)`` and ``n``): :func:`extra_eigen`,
  :func:`band_smallest_eigen`, :func:`band_negatives` and :func:`negative_eigenvalues` (Sylvester:
  the negative pivots of the band ``LDL^T``, of a band or of a sparse matrix) and
  :func:`lowest_eigen_below` (the lowest eigenvalue bracketed by inertia counts).

The count of unstable modes under volume control (the bordered ``LDL^T``'s inertia) is
:func:`snapjump_cli.fe.axisym.descent.constrained_negatives`: the axisymmetric lower state needs it.
"""
from __future__ import annotations

import logging

import numpy as np

from snapjump_cli.fe.limits import check_time
from snapjump_cli.fe.stability.harmonics import ZERO_TOL, HarmonicOperator, harmonic_operator
from snapjump_kernels.calls import band_ldlt, band_ldlt_solve, envelope_extents, sym_band_matvec

log = logging.getLogger(__name__)

__all__ = ["harmonic_inertia", "axis_rotation", "ROTATION_COS", "ZERO_PIVOT", "eig_near", "smallest_eigenvalue",
           "lowest_eigen", "extra_eigen", "band_smallest_eigen", "band_negatives", "lowest_eigen_below",
           "negative_eigenvalues"]


def harmonic_inertia(model, u: np.ndarray, p: float, n: int, tol: float = ZERO_TOL,
                     free_body: bool | None = None) -> int:
    """Number of unstable modes of harmonic ``n >= 1`` at the equilibrium ``(u, p)``.

    For ``n >= 1`` volume control does not constrain the harmonic (docs/harmonics.md), so this is
    the number of negative eigenvalues of ``K_n`` (rigid modes removed, eigenvalues above
    ``-tol * mu_min`` of the pencil ``(K_n, M_n)`` counted as zero); -1 if the state is outside
    the Gent domain.
    """
    if n < 1:
        raise ValueError("harmonic_inertia needs n >= 1 (n = 0 is constrained by the cavity volume: "
                         "see snapjump_cli.fe.axisym.lower_state.constrained_instability)")
    return harmonic_operator(model, n, free_body).inertia(u, p, tol)
def axis_rotation(op: HarmonicOperator, u: np.ndarray) -> np.ndarray | None:
    """For ``n = 0``: the dof vector of the rigid rotation about the axis of the state ``u``
    (torsion ``c = r``, the current radius, at every node) when no constraint holds it, else
    ``None`` (``n >= 1``, or a node off the axis with its torsion fixed)."""
    if op.n != 0:
        return None
    R = op.model.X[:, 0]
    free = op.layout.dofmap[:, 2] >= 0
    if np.any(~free & (R > 1e-9 * float(R.max()))):
        return None
    A = np.zeros(op.layout.dofmap.shape)
    A[:, 2] = op.model.positions(u)[:, 0]
    return op.to_vector(A)


#: An eigenvector whose M-cosine with the rigid rotation exceeds this is that rotation.
ROTATION_COS = 0.99

#: The certificate of a projected margin counts eigenvalues below ``s = lambda - delta``; for
#: ``|s|`` below this (times ``mu_min``) the rigid modes' zero eigenvalues of ``K_1 - s M_1`` are
#: at round-off (a converged state leaves them at ~1e-10), and ``-ZERO_PIVOT mu_min`` is used.
ZERO_PIVOT = 1e-7


def eig_near(op: HarmonicOperator, u: np.ndarray, p: float, sigma: float, mode: bool = False,
             project: bool = False, ncv: int | None = None):
    """The smallest of the two eigenvalues of ``(K_n, M_n)`` nearest ``sigma`` (rigid modes gauged
    out, or with ``project`` projected out: :func:`_eig_near_projected`; the rotation about the
    axis of ``n = 0`` left out: :func:`axis_rotation`; scaled units), with (``mode``) its
    eigenvector as nodal amplitudes ``(nn, 3)``, largest entry 1; ``None`` outside the Gent
    domain. ``ncv``: ARPACK's Lanczos vectors (default: its own choice, 20 or more)."""
    import scipy.sparse.linalg as spla

    if project:
        rigid = op.rigid_dof_modes(u)
        if rigid.shape[0]:
            return _eig_near_projected(op, u, p, sigma, rigid, mode)
    K = op.matrix(u, p)
    if K is None:
        return None
    keep = np.setdiff1d(np.arange(op.ndof), op.gauge_dofs(u))
    K = K[keep][:, keep].tocsc()
    M = op.mass()[keep][:, keep].tocsc()
    # a fixed start vector: ARPACK's default is random, and the answers then differ between
    # processes at the level of the eigenvalue tolerance (followed dE by ~1e-8)
    v0 = np.random.default_rng(0).standard_normal(K.shape[0])
    if ncv is not None:
        ncv = min(int(ncv), K.shape[0])
    rot = axis_rotation(op, u)
    if rot is None and not mode:
        return float(np.min(spla.eigsh(K, k=2, M=M, sigma=sigma, which="LM", v0=v0, ncv=ncv,
                                       return_eigenvectors=False)))
    vals, vecs = spla.eigsh(K, k=2 if rot is None else 3, M=M, sigma=sigma, which="LM", v0=v0, ncv=ncv)
    if rot is not None:
        r = rot[keep]
        Mr = M @ r
        cos = np.abs(vecs.T @ Mr) / (np.sqrt(np.einsum("ij,ij->j", vecs, M @ vecs)) * np.sqrt(r @ Mr))
        vals, vecs = vals[cos < ROTATION_COS], vecs[:, cos < ROTATION_COS]
    if not mode:
        return float(np.min(vals))
    i = int(np.argmin(vals))
    x = np.zeros(op.ndof)
    x[keep] = vecs[:, i]
    A = op.to_nodal(x)
    return float(vals[i]), A / A.ravel()[np.argmax(np.abs(A))]


def _eig_near_projected(op: HarmonicOperator, u: np.ndarray, p: float, sigma: float, rigid: np.ndarray,
                        mode: bool):
    """:func:`eig_near` on the ``M``-orthogonal complement of the rigid modes ``rigid`` (``(k, ndof)``
    dof vectors): shift-invert Lanczos whose inverse is the bordered solve
    ``[[K - sigma M, M R], [R^T M, 0]]``, so that every Lanczos vector satisfies ``R^T M x = 0``."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    K = op.matrix(u, p)
    if K is None:
        return None
    M = op.mass()
    n, k = op.ndof, rigid.shape[0]
    C = sp.csr_matrix(M @ rigid.T)
    lu = spla.splu(sp.bmat([[K - sigma * M, C], [C.T, None]], format="csc"))
    inv = spla.LinearOperator((n, n), matvec=lambda x: lu.solve(np.concatenate([np.ravel(x), np.zeros(k)]))[:n],
                              dtype=float)
    v0 = np.random.default_rng(0).standard_normal(n)  # fixed, as in eig_near
    vals, vecs = spla.eigsh(K, k=2, M=M, sigma=sigma, which="LM", v0=v0, OPinv=inv)
    i = int(np.argmin(vals))
    if not mode:
        return float(vals[i])
    A = op.to_nodal(vecs[:, i])
    return float(vals[i]), A / A.ravel()[np.argmax(np.abs(A))]


def smallest_eigenvalue(op: HarmonicOperator, u: np.ndarray, p: float, shift: float = 2.0,
                        rel: float = 1e-6, project: bool = True) -> float | None:
    """The smallest eigenvalue of ``(K_n, M_n)`` at ``(u, p)`` (scaled units: ``mu_i / R_i^2``),
    certified by the inertia; ``None`` outside the Gent domain.

    ``project`` (default): the rigid modes of ``n = 1`` are removed by ``M``-orthogonal projection
    (:func:`eig_near`); the certificate is then the inertia of the whole pencil, whose spectrum is
    the projected one and the rigid modes' zeros (``K_1 R = 0`` at an equilibrium, so the
    ``M``-orthogonal complement of ``R`` is invariant). ``project=False``: the gauged pencil of the
    harmonic check (its eigenvalues depend on where the gauge is)."""
    mu = float(np.min(op.model.mu))
    sigma = -shift * mu
    n_rigid = op.rigid_dof_modes(u).shape[0] if project else 0
    for _ in range(6):
        check_time()  # the design's CPU-time limit: the eigen-solves call no model evaluation that checks it
        lam = eig_near(op, u, p, sigma, project=project)
        if lam is None:
            return None
        delta = rel * max(abs(lam), mu)
        if n_rigid:
            s = lam - delta
            if abs(s) < ZERO_PIVOT * mu:  # the rigid zeros' pivots would have a round-off sign
                s = -ZERO_PIVOT * mu
            below = op.inertia(u, p, tol=-s / mu, gauge=False)  # eigenvalues below s
            if s > 0.0:
                below -= n_rigid  # the rigid modes' zero eigenvalues
        else:
            below = op.inertia(u, p, tol=(delta - lam) / mu)  # eigenvalues below lam - delta
        if lam - delta > 0.0 and axis_rotation(op, u) is not None:
            below -= 1  # the rigid rotation's zero eigenvalue
        if below == 0:
            return lam
        sigma = lam - 10.0 * max(abs(lam), mu)  # a lower one exists: search below
    log.warning("harmonic %d: smallest eigenvalue not certified", op.n)
    return lam


#: ARPACK's Lanczos vectors in :func:`lowest_eigen` (the bifurcation's root finding calls it 5-10
#: times per followed design): its default (20) spends most of a call in the reverse-communication
#: loop; with 8 a call took a third of the CPU and the eigenvalue moved by ~1e-15 ``mu_min / L^2``
#: (``follow_strata`` row 0 at its bifurcation, a scratch timing; the agreement is pinned by
#: ``tests/unit/test_lowest_eigen.py``). Where ARPACK does not converge with them, the default is used.
LOWEST_NCV = 8


def lowest_eigen(op: HarmonicOperator, u: np.ndarray, p: float, shift: float = 2.0) -> tuple[float, np.ndarray] | None:
    """The smallest eigenvalue of the pencil ``(K_n, M_n)`` (the rigid modes gauged out) and its
    mode as nodal amplitudes ``(nn, 3)`` scaled to a largest entry of 1; ``None`` outside the Gent
    domain. In units of ``mu_min / L^2`` of the scaled model (the harmonic check's measure).
    Shift-invert about ``-shift mu_min``: exact for the smallest eigenvalue while it lies above
    that (near a bifurcation it is close to 0; physical eigenvalues are of order 0.1-10)."""
    import scipy.sparse.linalg as spla

    mu = float(np.min(op.model.mu))
    try:
        found = eig_near(op, u, p, -shift * mu, mode=True, ncv=LOWEST_NCV)
    except spla.ArpackNoConvergence:
        found = eig_near(op, u, p, -shift * mu, mode=True)
    if found is None:
        return None
    return found[0] / mu, found[1]


def extra_eigen(full, u: np.ndarray, p: float, harmonics, scale: float = 1.0, smallest: bool = True):
    """The smallest eigenvalue of the tangent of ``full`` at ``(u, p)`` restricted to the dofs of
    ``harmonics`` (the harmonics outside a branch's subspace, decoupled from it at a state of the
    branch), divided by ``scale``, and its eigenvector as a free vector of ``full``; ``None``
    outside the domain or if the eigenvalue solver does not converge.

    Only that block of the tangent is formed (``full.block_band``:
    :meth:`snapjump_cli.fe.branch.model.MultiHarmonicModel.block_band`); its eigenpair is
    :func:`band_smallest_eigen`'s."""
    out = full.block_band(u, p, harmonics)
    if out is None:
        return None
    ab, block = out
    found = band_smallest_eigen(ab, block.ext, smallest)
    if found is None:
        return None
    x = np.zeros(full.n)
    x[block.dofs] = found[1]
    return found[0] / scale, x


def band_smallest_eigen(ab: np.ndarray, ext: np.ndarray, smallest: bool = True):
    """The smallest eigenvalue and its eigenvector of the symmetric matrix whose lower band is
    ``ab`` (envelope ``ext``); ``None`` if the eigenvalue solver does not converge.

    Shift-invert Lanczos finds the eigenvalues nearest a shift just below zero: the smallest,
    unless one lies far below zero. The number of negative eigenvalues (the inertia of the band's
    ``LDL^T``, exact by Sylvester's law: :func:`band_negatives`) tells whether one was missed; then
    the lowest eigenvalue is bracketed by inertia counts of ``K - sigma I`` (the shift moved down
    until none is below it, then bisected) and found by shift-invert just below it
    (:func:`lowest_eigen_below`). ``smallest=False`` skips the count: the eigenvalue nearest zero is
    then what is returned (enough where it is the one that crosses zero: the roots of
    :func:`snapjump_cli.fe.branch.secondary.locate_secondary`)."""
    import scipy.sparse.linalg as spla

    from snapjump_cli.fe.axisym.model import band_csr

    n = ab.shape[0]
    n_neg = band_negatives(ab, ext) if smallest else -1
    sigma = -1e-6 * float(np.median(np.abs(ab[:, 0])))  # below the eigenvalue near zero; nearest to it = smallest
    v0 = np.random.default_rng(0).standard_normal(n)  # fixed: reproducible answers
    # shift-invert with the band LDL^T of K - sigma I (the band's own solver, not a sparse LU)
    fac = np.array(ab)
    fac[:, 0] -= sigma
    ok, _ = band_ldlt(fac, ext)
    if not ok:  # sigma an eigenvalue to round-off: the sparse LU's shift-invert
        fac = None
    try:
        if fac is None:
            vals, vecs = spla.eigsh(band_csr(ab).tocsc(), k=min(3, n - 1), sigma=sigma, which="LM", v0=v0)
        else:
            A = spla.LinearOperator((n, n), matvec=lambda x: sym_band_matvec(ab, np.ravel(x).astype(float), ext),
                                    dtype=float)
            inv = spla.LinearOperator((n, n), matvec=lambda x: band_ldlt_solve(fac, np.ravel(x).astype(float), ext),
                                      dtype=float)
            vals, vecs = spla.eigsh(A, k=min(3, n - 1), sigma=sigma, which="LM", v0=v0, OPinv=inv)
        if n_neg > 0 and not (n_neg <= len(vals) and int(np.sum(vals < 0.0)) >= n_neg):
            K = band_csr(ab).tocsc()
            vals, vecs = lowest_eigen_below(K, float(np.abs(vals).max()), v0)  # one lies further below
    except spla.ArpackNoConvergence:
        log.warning("extra_eigen: the eigenvalue solver did not converge")
        return None
    if vals is None:
        return None
    i = int(np.argmin(vals))
    return float(vals[i]), vecs[:, i]


def band_negatives(ab: np.ndarray, ext: np.ndarray) -> int:
    """Negative eigenvalues of the symmetric matrix whose lower band is ``ab`` (envelope ``ext``):
    the negative pivots of the band ``LDL^T`` of a copy (Sylvester); -1 if a pivot is zero to
    round-off."""
    ok, n_neg = band_ldlt(np.array(ab), ext)
    return int(n_neg) if ok else -1


def lowest_eigen_below(K, start: float, v0: np.ndarray, bisections: int = 30):
    """The lowest eigenvalue of ``K`` (with its vector, as ``eigsh`` returns them): a shift with
    no eigenvalue below it (the inertia count of ``K - sigma I`` zero), found by moving down from
    ``-start`` by factors of 4, then bisected against one with an eigenvalue below it, then
    shift-invert Lanczos from just below the bracket; ``(None, None)`` if no shift is found."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    I = sp.identity(K.shape[0], format="csc")

    def below(sigma: float) -> bool:  # some eigenvalue below sigma (a zero pivot: one at sigma)
        c = negative_eigenvalues(K - sigma * I)
        return c != 0

    hi, lo = 0.0, -max(start, 1e-300)
    for _ in range(60):
        if not below(lo):
            break
        hi, lo = lo, 4.0 * lo
    else:
        return None, None
    for _ in range(bisections):
        mid = 0.5 * (lo + hi)
        if below(mid):
            hi = mid
        else:
            lo = mid
        if hi - lo <= 1e-6 * abs(hi):
            break
    return spla.eigsh(K, k=1, sigma=lo - 1e-3 * (hi - lo), which="LM", v0=v0)


def negative_eigenvalues(K) -> int:
    """Negative eigenvalues of the sparse symmetric ``K`` (Sylvester: the negative pivots of its
    band ``LDL^T``, :func:`snapjump_kernels.banded.band_ldlt`, in the order of its rows, which keep
    the full model's node order); -1 if a pivot is zero to round-off."""
    C = K.tocoo()
    low = C.row >= C.col
    r, c, v = C.row[low], C.col[low], C.data[low]
    n = K.shape[0]
    kl = int((r - c).max()) if len(r) else 0
    ab = np.zeros((n, kl + 1))
    ab[c, r - c] = v  # A[i, j] = ab[j, i - j] (the entries of a CSC matrix's COO are unique)
    ext = envelope_extents(C.row, C.col, n, kl)
    ok, n_neg = band_ldlt(ab, ext)
    return int(n_neg) if ok else -1
