"""How far each harmonic is from losing stability along a path: the margins (docs/harmonics.md, section 11).

The harmonic check (:mod:`snapjump_cli.fe.harmonics`) gives a sign per harmonic and state. The
margin is the number behind it: the smallest eigenvalue of the pencil ``(K_n, M_n)`` (rigid modes
gauged out), ``n = 0..n_max``, in units of ``mu_i / R_i^2``: an energy per mean-square
displacement of the 3D perturbation, independent of the mesh and of the bulk penalty, so another
code can compute the same number (the generalised eigenvalue against the displacement mass
matrix). For ``n = 0`` it is that of the axisymmetric tangent itself (no volume constraint: it turns
negative past the pressure maximum, where volume control still holds the path) and of the
decoupled torsion; a body free to turn about its axis (a free actuator) has the rigid rotation
``u_phi = omega R`` as a zero mode of the torsion, which is not a margin and is left out (the
eigenvector M-parallel to it is dropped, and the inertia certificate does not count it).

Each margin is found by shift-invert Lanczos and certified by the band ``LDL^T`` inertia of
``K_n - (lambda - delta) M_n``: no eigenvalue lies below it (else the shift is moved below and the
search repeated).
"""
from __future__ import annotations

import logging

import numpy as np

from snapjump_cli.fe.harmonics import HarmonicOperator, harmonic_operator
from snapjump_cli.fe.limits import check_time

log = logging.getLogger(__name__)

__all__ = ["axis_rotation", "eig_near", "smallest_eigenvalue", "state_margins", "path_margins", "MARGIN_KEYS"]

#: The row keys of :func:`path_margins` (null unless ``solver: {margins: true}``).
MARGIN_KEYS: tuple[str, ...] = ("asym_margin", "asym_margin_n", "asym_margin_V_m3")


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


def eig_near(op: HarmonicOperator, u: np.ndarray, p: float, sigma: float, mode: bool = False):
    """The smallest of the two eigenvalues of ``(K_n, M_n)`` nearest ``sigma`` (rigid modes gauged
    out, the rotation about the axis of ``n = 0`` left out: :func:`axis_rotation`; scaled units),
    with (``mode``) its eigenvector as nodal amplitudes ``(nn, 3)``, largest entry 1; ``None``
    outside the Gent domain."""
    import scipy.sparse.linalg as spla

    K = op.matrix(u, p)
    if K is None:
        return None
    keep = np.setdiff1d(np.arange(op.ndof), op.gauge_dofs(u))
    K = K[keep][:, keep].tocsc()
    M = op.mass()[keep][:, keep].tocsc()
    # a fixed start vector: ARPACK's default is random, and the answers then differ between
    # processes at the level of the eigenvalue tolerance (followed dE by ~1e-8)
    v0 = np.random.default_rng(0).standard_normal(K.shape[0])
    rot = axis_rotation(op, u)
    if rot is None and not mode:
        return float(np.min(spla.eigsh(K, k=2, M=M, sigma=sigma, which="LM", v0=v0, return_eigenvectors=False)))
    vals, vecs = spla.eigsh(K, k=2 if rot is None else 3, M=M, sigma=sigma, which="LM", v0=v0)
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


def smallest_eigenvalue(op: HarmonicOperator, u: np.ndarray, p: float, shift: float = 2.0,
                        rel: float = 1e-6) -> float | None:
    """The smallest eigenvalue of ``(K_n, M_n)`` at ``(u, p)`` (scaled units: ``mu_i / R_i^2``),
    certified by the inertia; ``None`` outside the Gent domain."""
    mu = float(np.min(op.model.mu))
    sigma = -shift * mu
    for _ in range(6):
        check_time()
        lam = eig_near(op, u, p, sigma)
        if lam is None:
            return None
        delta = rel * max(abs(lam), mu)
        below = op.inertia(u, p, tol=(delta - lam) / mu)  # eigenvalues below lam - delta
        if lam - delta > 0.0 and axis_rotation(op, u) is not None:
            below -= 1  # the rigid rotation's zero eigenvalue
        if below == 0:
            return lam
        sigma = lam - 10.0 * max(abs(lam), mu)  # a lower one exists: search below
    log.warning("harmonic %d: smallest eigenvalue not certified", op.n)
    return lam


def state_margins(model, u: np.ndarray, p: float, n_max: int, free_body: bool | None = None) -> np.ndarray:
    """The margins of harmonics ``0..n_max`` at one state, ``(n_max + 1,)`` (NaN outside the domain)."""
    out = np.full(n_max + 1, np.nan)
    for n in range(n_max + 1):
        check_time()  # the design's CPU-time limit: the eigen-solves call no model evaluation that checks it
        lam = smallest_eigenvalue(harmonic_operator(model, n, free_body), u, p)
        if lam is not None:
            out[n] = lam
    return out


def path_margins(result, n_max: int) -> tuple[dict, np.ndarray]:
    """The margins along a solved scene's loading path (every path point up to the volume limit,
    and the upper state) and the smallest one of a non-axisymmetric harmonic met there.

    Returns
    -------
    (summary, table)
        ``summary``: ``asym_margin`` (the smallest margin of ``n = 1..n_max`` before ``V*``, in
        ``mu_i / R_i^2``), ``asym_margin_n`` (its harmonic), ``asym_margin_V_m3`` (where);
        ``table``: ``(n_states, n_max + 2)``, the volume [m^3] and the margins of ``n = 0..n_max``.
    """
    model, pts, st = result.model, result.path.points, result.states
    states = list(pts[: st.k_before + 1]) + [st.upper] if st.upper is not None else list(pts)
    sV = result.tracer.sc[0]
    rows = []
    for pt in states:
        rows.append(np.concatenate([[pt.zeta[0] * sV * model.L**3], state_margins(model, pt.u, pt.p, n_max)]))
    table = np.array(rows)
    summary = {k: None for k in MARGIN_KEYS}
    asym = table[:, 2:]
    if asym.size and np.isfinite(asym).any():
        i, j = np.unravel_index(np.nanargmin(asym), asym.shape)
        summary.update(asym_margin=float(asym[i, j]), asym_margin_n=int(j + 1), asym_margin_V_m3=float(table[i, 0]))
    return summary, table
