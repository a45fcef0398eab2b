"""Stability of axisymmetric states against non-axisymmetric perturbations (Fourier harmonics).

At an axisymmetric equilibrium ``(u, p)`` of :class:`snapjump_cli.fe.axisym.model.Model`, the second
variation of the 3D potential ``Pi = W - p (V - V*)`` restricted to perturbations

    u_r = a(R, Z) cos n phi,   u_z = b(R, Z) cos n phi,   u_phi = c(R, Z) sin n phi

decouples per circumferential harmonic ``n`` (semi-analytical Fourier FE, as in ABAQUS CAXA
elements, BOSOR or AQUINAS). Its matrix ``K_n`` (three amplitudes per node) is assembled by
:mod:`snapjump_kernels.harmonics`; the derivation is in docs/harmonics.md. For ``n >= 1`` the
first variation of the cavity volume integrates to zero over phi, so volume control imposes no
constraint on that harmonic and the pressure acts only through its load stiffness ``-p d2V``:
the state is stable against harmonic ``n`` iff ``K_n`` is positive definite, and the number of
its negative eigenvalues (by Sylvester's law, the negative pivots of an ``LDL^T``) counts the
unstable modes.

Boundary conditions per harmonic (:class:`HarmonicOperator`):

* axis nodes (``R = 0``): ``n = 0``: ``a = c = 0``; ``n = 1``: ``b = 0`` and ``c = -a`` (a
  translation perpendicular to the axis, ``u_r = cos phi``, ``u_phi = -sin phi``);
  ``n >= 2``: ``a = b = c = 0`` (a single-valued displacement on the axis);
* ``dirichlet_y`` nodes (supports and symmetry planes): ``b = 0``; ``dirichlet_x`` nodes
  (clamped faces): ``a = c = 0`` as well;
* a free body (default: a full actuator, ``mesh.scene == "design"``): its ``dirichlet_y`` node
  only removes the vertical rigid translation of ``n = 0`` and is ignored for ``n >= 1``.

Zero modes. For ``n = 1`` the rigid translation perpendicular to the axis (``a = 1, b = 0,
c = -1``) and the tilt about a horizontal axis (``a = z, b = -r, c = -z``, current coordinates)
are exact null vectors of ``K_1`` at an equilibrium, when the constraints admit them. Every
admissible rigid mode is removed by fixing one "gauge" dof chosen where the mode is largest
(pivoted QR): a quadratic form restricted to a complement of its null space has the same
numbers of positive and negative eigenvalues, so this is exact. The inertia is then taken of
``K_n + tol * mu_min * M_n``, ``M_n`` the phi-averaged L2 mass of the perturbation and
``mu_min`` the smallest shear modulus (scaled units: lengths / L, stresses / S): an eigenvalue
of the pencil ``(K_n, M_n)`` (an energy per unit mean-square displacement, a physical measure
independent of the mesh and of the bulk penalty) counts as negative only below
``-tol * mu_min / L^2`` (``tol`` = :data:`ZERO_TOL`), so round-off and an imperfectly converged
equilibrium around a zero eigenvalue are not reported as an instability. (A tolerance relative to
``max|diag K_n|`` would not do: that diagonal is dominated by the bulk penalty, and the bending
eigenvalues of a thin cap are 1e-8 of it.)
"""
from __future__ import annotations

import logging
import time
import weakref
from dataclasses import dataclass, fields

import numpy as np

from snapjump_cli.mesh.data import number_dofs
from snapjump_cli.schema import HARMONIC_CHECK, columns, keys
from snapjump_kernels.calls import (
    band_of_maps,
    band_ldlt,
    harmonic_band,
    harmonic_cavity_matrices,
    harmonic_element_parts,
    scatter_band,
)

log = logging.getLogger(__name__)

__all__ = [
    "ZERO_TOL",
    "HarmonicOperator",
    "harmonic_operator",
    "unstable_harmonics",
    "rigid_modes",
    "check_harmonics",
    "HARMONIC_KEYS",
    "HarmonicCheck",
]

#: Eigenvalues of ``(K_n, M_n)`` above ``-ZERO_TOL * mu_min`` (scaled units) count as zero, not negative.
ZERO_TOL = 1e-6

#: The keys of :class:`HarmonicCheck` (:data:`snapjump_cli.schema.HARMONIC_CHECK`).
HARMONIC_KEYS: tuple[str, ...] = keys(HARMONIC_CHECK)


@dataclass
class HarmonicCheck:
    """What :func:`check_harmonics` found, under the keys of :data:`HARMONIC_KEYS`:
    ``asym_first`` (some harmonic became unstable before V*), ``asym_n`` (the lowest unstable
    harmonic at the first unstable state), ``asym_ns`` (all unstable harmonics there, comma
    separated), ``asym_V_m3`` / ``asym_p_Pa`` (cavity volume and pressure of that state, SI),
    ``asym_lower_stable`` (the lower state is stable against every harmonic; None without a snap),
    ``asym_lower_n`` (its lowest unstable harmonic), ``asym_n_max``, ``asym_states_checked``,
    ``asym_wall_s``."""

    asym_first: bool = False
    asym_n: int | None = None
    asym_ns: str | None = None
    asym_V_m3: float | None = None
    asym_p_Pa: float | None = None
    asym_lower_stable: bool | None = None
    asym_lower_n: int | None = None
    asym_n_max: int | None = None
    asym_states_checked: int | None = None
    asym_wall_s: float | None = None

    def as_row(self) -> dict:
        """The row's columns of the harmonic check (:func:`snapjump_cli.schema.columns`)."""
        return {k: getattr(self, k) for k in columns(HARMONIC_CHECK)}

    def as_dict(self) -> dict:
        """Every key, the diagnostics included."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


def phi_weights(n: int) -> tuple[float, float]:
    """phi-averages ``(<cos^2 n phi>, <sin^2 n phi>)``; ``(1, 1)`` for ``n = 0`` (``c`` = torsion)."""
    return (1.0, 1.0) if n == 0 else (0.5, 0.5)


def rigid_modes(model, u: np.ndarray) -> np.ndarray:
    """The two rigid modes of harmonic 1 at the state ``u``, as nodal amplitudes ``(2, nn, 3)``.

    ``[0]``: translation perpendicular to the axis, ``a = 1, b = 0, c = -1``;
    ``[1]``: tilt (rotation about a horizontal axis), ``a = z, b = -r, c = -z`` with the current
    coordinates ``(r, z)``.
    """
    x = model.positions(u)
    nn = x.shape[0]
    modes = np.zeros((2, nn, 3))
    modes[0, :, 0] = 1.0
    modes[0, :, 2] = -1.0
    modes[1, :, 0] = x[:, 1]
    modes[1, :, 1] = -x[:, 0]
    modes[1, :, 2] = -x[:, 1]
    return modes


@dataclass
class _Layout:
    dofmap: np.ndarray  # (nn, 3) global dof of each amplitude, -1 if fixed
    coef: np.ndarray  # (nn, 3) its coefficient (-1 for the tied c of an axis node at n = 1)
    ndof: int
    kl: int
    ext: np.ndarray
    edofs: np.ndarray
    ecoef: np.ndarray
    gdofs: np.ndarray
    gcoef: np.ndarray


def _layout(model, fixed: np.ndarray, tied: np.ndarray) -> _Layout:
    """Number the amplitudes node by node, in the order of the model's free dofs (banded), skipping
    the ``fixed`` ones; a ``tied`` axis node's ``c`` is its ``a`` with coefficient -1."""
    nn = fixed.shape[0]
    key = np.where(model.dofmap >= 0, model.dofmap, np.iinfo(np.int64).max).min(axis=1)
    order = np.argsort(key, kind="stable")
    dofmap, ndof = number_dofs(order, fixed)
    coef = np.ones((nn, 3))
    dofmap[tied, 2] = dofmap[tied, 0]  # n = 1 on the axis: c = -a, one dof
    coef[tied, 2] = -1.0
    conn, edges = model.conn, model.edges
    edofs = np.ascontiguousarray(dofmap[conn].reshape(conn.shape[0], -1))
    ecoef = np.ascontiguousarray(coef[conn].reshape(conn.shape[0], -1))
    gdofs = np.ascontiguousarray(dofmap[edges].reshape(edges.shape[0], -1))
    gcoef = np.ascontiguousarray(coef[edges].reshape(edges.shape[0], -1))
    kl, ext = band_of_maps((edofs, gdofs), ndof)
    return _Layout(dofmap, coef, ndof, kl, ext, edofs, ecoef, gdofs, gcoef)


#: model -> {constraints: (layout, cache shared by the operators with that layout)}
_LAYOUTS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


class HarmonicOperator:
    """``K_n`` of one model and harmonic: dof layout (built once) and assembly at any state.

    Parameters
    ----------
    model : the axisymmetric :class:`snapjump_cli.fe.axisym.model.Model`
    n : harmonic number (``n = 0`` uses the model's own constraints: ``K_0`` restricted to
        ``(a, b)`` is the model's ``K_T``, and ``c`` is the decoupled torsion)
    free_body : ignore the ``dirichlet_*`` node sets for ``n >= 1`` (their only role is to remove
        the rigid translation along the axis); default ``model.mesh.scene == "design"``
    """

    def __init__(self, model, n: int, free_body: bool | None = None) -> None:
        if n < 0:
            raise ValueError(f"harmonic number must be >= 0, got {n}")
        self._model = weakref.ref(model)  # the per-model cache must not keep its key alive
        self.n = int(n)
        mesh = model.mesh
        if free_body is None:
            free_body = mesh.scene == "design"
        self.free_body = bool(free_body)
        self.wc, self.ws = phi_weights(self.n)
        nn = model.X.shape[0]
        fixed = np.zeros((nn, 3), bool)
        tied = np.zeros(nn, bool)  # c = -a on the axis (n = 1)
        axis = np.asarray(mesh.node_sets["axis"], np.int64)
        if self.n == 0:
            fixed[:, :2] = model.fixed
            fixed[axis, 2] = True
            fixed[model.fixed[:, 0] & model.fixed[:, 1], 2] = True
            fixed[np.asarray(mesh.node_sets.get("dirichlet_x", np.zeros(0, np.int64)), np.int64), 2] = True
        else:
            if not self.free_body:
                dx = np.asarray(mesh.node_sets.get("dirichlet_x", np.zeros(0, np.int64)), np.int64)
                dy = np.asarray(mesh.node_sets.get("dirichlet_y", np.zeros(0, np.int64)), np.int64)
                fixed[dx, 0] = fixed[dx, 2] = True
                fixed[dy, 1] = True
            fixed[axis, 1] = True
            if self.n == 1:
                tied[axis] = ~fixed[axis, 0]
                fixed[axis, 2] = True  # represented by the a dof
            else:
                fixed[axis, :] = True
        self.fixed = fixed
        self.tied = tied
        # the layout depends only on the constraints: harmonics 2, 3, ... share theirs (and its cache)
        per_model = _LAYOUTS.setdefault(model, {})
        key = (fixed.tobytes(), tied.tobytes())
        if key not in per_model:
            per_model[key] = (_layout(model, fixed, tied), {})
        self.layout, self._shared = per_model[key]

    @property
    def model(self):
        """The model (held by a weak reference)."""
        m = self._model()
        if m is None:
            raise ReferenceError("the model of this HarmonicOperator no longer exists")
        return m

    @property
    def ndof(self) -> int:
        """Number of amplitudes (before any gauge)."""
        return self.layout.ndof

    # ---- vectors -------------------------------------------------------------------------------
    def to_vector(self, A: np.ndarray) -> np.ndarray:
        """Nodal amplitudes ``(nn, 3)`` -> dof vector (the fixed entries are dropped; a tied axis
        ``c`` is represented by its ``a``)."""
        L = self.layout
        v = np.zeros(L.ndof)
        m = L.dofmap >= 0
        m[:, 2] &= ~self.tied
        v[L.dofmap[m]] = np.asarray(A)[m] / L.coef[m]
        return v

    def to_nodal(self, v: np.ndarray) -> np.ndarray:
        """Dof vector -> nodal amplitudes ``(nn, 3)`` (zeros where fixed)."""
        L = self.layout
        A = np.zeros(L.dofmap.shape)
        m = L.dofmap >= 0
        A[m] = v[L.dofmap[m]] * L.coef[m]
        return A

    # ---- assembly ------------------------------------------------------------------------------
    def parts(self, u: np.ndarray) -> StateParts | None:
        """The harmonic-independent part of ``K_n`` at ``u`` (:func:`state_parts`, shared by the
        harmonics with this operator's phi-averages); ``None`` outside the Gent domain."""
        return state_parts(self.model, u, self.wc, self.ws)

    def _matrices(self, u: np.ndarray, parts: StateParts | None = None):
        parts = self.parts(u) if parts is None else parts
        if parts is None:
            return None
        n = float(self.n)
        Ke = parts.Kp[0] + n * parts.Kp[1] + (n * n) * parts.Kp[2]
        return Ke, harmonic_cavity_matrices(parts.x, self.model.edges, n, self.wc, self.ws)

    def _band(self, parts: StateParts, p: float, base: np.ndarray, gauge: np.ndarray) -> np.ndarray:
        """``base + K_n`` in band storage, the ``gauge`` dofs fixed (:func:`snapjump_kernels.harmonics.harmonic_band`)."""
        L = self.layout
        return harmonic_band(parts.Kp, float(self.n), L.edofs, L.ecoef, parts.x, self.model.edges, L.gdofs,
                             L.gcoef, self.wc, self.ws, float(p), base, gauge)

    def band(self, u: np.ndarray, p: float, parts: StateParts | None = None) -> np.ndarray | None:
        """Lower band ``(ndof, kl + 1)`` of ``K_n`` at ``(u, p)``; ``None`` outside the Gent domain.
        ``parts``: :meth:`parts` at ``u`` when already computed (for another harmonic)."""
        parts = self.parts(u) if parts is None else parts
        if parts is None:
            return None
        L = self.layout
        return self._band(parts, p, np.zeros((L.ndof, L.kl + 1)), np.zeros(0, np.int64))

    def matrix(self, u: np.ndarray, p: float):
        """``K_n`` at ``(u, p)`` as a scipy CSR matrix (``None`` outside the Gent domain)."""
        import scipy.sparse as sp

        mats = self._matrices(u)
        if mats is None:
            return None
        Ke, He = mats
        L = self.layout
        parts = []
        for Me, d, c, fac in ((Ke, L.edofs, L.ecoef, 1.0), (He, L.gdofs, L.gcoef, -float(p))):
            nd = d.shape[1]
            r, cc = np.repeat(d, nd, axis=1), np.tile(d, (1, nd))
            v = fac * Me.reshape(len(d), -1) * np.repeat(c, nd, axis=1) * np.tile(c, (1, nd))
            ok = (r >= 0) & (cc >= 0)
            parts.append((r[ok], cc[ok], v[ok]))
        r = np.concatenate([x[0] for x in parts])
        c = np.concatenate([x[1] for x in parts])
        v = np.concatenate([x[2] for x in parts])
        return sp.csr_matrix((v, (r, c)), shape=(L.ndof, L.ndof))

    def mass(self):
        """The phi-averaged consistent L2 mass of the amplitudes (``wc`` for ``a, b``, ``ws`` for
        ``c``; scipy CSR): with it, the eigenvalues of ``(K_n, M_n)`` are Rayleigh quotients of the
        3D perturbation, comparable between harmonics."""
        import scipy.sparse as sp

        M, L = self.model, self.layout
        Me = np.einsum("eq,qa,qb->eab", M.Wq, M.N_ref, M.N_ref)
        nen = M.conn.shape[1]
        rows, cols, vals = [], [], []
        for comp, w in ((0, self.wc), (1, self.wc), (2, self.ws)):
            d = L.edofs[:, comp::3]
            c = L.ecoef[:, comp::3]
            r, cc = np.repeat(d, nen, axis=1), np.tile(d, (1, nen))
            v = w * Me.reshape(len(d), -1) * np.repeat(c, nen, axis=1) * np.tile(c, (1, nen))
            ok = (r >= 0) & (cc >= 0)
            rows.append(r[ok])
            cols.append(cc[ok])
            vals.append(v[ok])
        return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                             shape=(L.ndof, L.ndof))

    # ---- zero modes and inertia ----------------------------------------------------------------
    def gauge_dofs(self, u: np.ndarray) -> np.ndarray:
        """Dofs fixed to remove the admissible rigid modes (harmonic 1 only; empty otherwise).

        One dof per admissible rigid mode (:meth:`rigid_dof_modes`) is fixed: the pivot columns
        of the modes (:func:`pivot_columns`). Where the modes are, and what the dofs are, is set up
        once.
        """
        A = self.rigid_dof_modes(u)
        if A.shape[0] == 0:
            return np.zeros(0, np.int64)
        return np.sort(pivot_columns(A))

    def rigid_dof_modes(self, u: np.ndarray) -> np.ndarray:
        """The admissible rigid modes at ``u`` as dof vectors ``(k, ndof)`` (``k = 0`` unless
        ``n == 1``): the rigid modes (:func:`rigid_modes`, each scaled to a largest entry of 1)
        combined into those that vanish on every fixed amplitude (the null space of their values
        there). At an equilibrium they are null vectors of ``K_1``: :meth:`gauge_dofs` fixes one
        dof for each, :func:`snapjump_cli.fe.stability.eigen.smallest_eigenvalue` projects them out.
        """
        if self.n != 1:
            return np.zeros((0, self.ndof))
        g = self._gauge_setup()
        x = self.model.positions(u)
        r, z = x[:, 0], x[:, 1]
        s = max(float(np.abs(z).max()), float(np.abs(r).max()))  # the tilt's largest entry (|a| = |c| = |z|, |b| = r)
        tilt = np.empty((x.shape[0], 3))
        tilt[:, 0] = z
        tilt[:, 1] = -r
        tilt[:, 2] = -z
        tilt /= s
        tilt = tilt.reshape(-1)
        # admissible combinations: those vanishing on every fixed amplitude (the axis ties hold)
        C = np.stack([g.trans_fixed, tilt[g.fixed_flat]], axis=1)  # (n_fixed, 2)
        if C.shape[0] and C.any():
            _, sv, vt = np.linalg.svd(C, full_matrices=True)
            rank = int(np.sum(sv > 1e-8 * max(1.0, sv[0] if len(sv) else 1.0)))
            null = vt[rank:].T  # (2, k)
        else:  # no constraint on the modes (the SVD of a zero C would give the identity too)
            null = None
        modes = np.stack([g.trans_vec, tilt[g.dof_flat]])  # (2, ndof): the modes as dof vectors
        if null is None:
            return modes
        return null.T @ modes  # (0, ndof) when no combination is admissible

    def _gauge_setup(self) -> "_GaugeSetup":
        """Where the rigid modes of harmonic 1 live: the translation's entries on the fixed
        amplitudes and as a dof vector, and the flat (node, amplitude) index of each fixed amplitude
        and of each dof (cached)."""
        g = getattr(self, "_gauge", None)
        if g is None:
            L = self.layout
            trans = np.zeros(L.dofmap.shape)
            trans[:, 0] = 1.0
            trans[:, 2] = -1.0
            fixed = self.fixed.copy()
            fixed[self.tied, 2] = False
            m = L.dofmap >= 0
            m[:, 2] &= ~self.tied  # every dof once: its own amplitude (coefficient 1)
            dof_flat = np.zeros(L.ndof, np.int64)
            dof_flat[L.dofmap[m]] = np.flatnonzero(m.reshape(-1))
            g = self._gauge = _GaugeSetup(fixed_flat=np.flatnonzero(fixed.reshape(-1)), trans_fixed=trans[fixed],
                                          dof_flat=dof_flat, trans_vec=trans.reshape(-1)[dof_flat])
        return g

    def mass_band(self) -> np.ndarray:
        """:meth:`mass` in the lower band storage of ``K_n`` (cached; shared by the harmonics with
        this layout and phi-averages)."""
        key = ("mass", self.wc, self.ws)
        if key not in self._shared:
            M, L = self.model, self.layout
            Me = np.einsum("eq,qa,qb->eab", M.Wq, M.N_ref, M.N_ref)
            ne, nen = Me.shape[0], Me.shape[1]
            Me3 = np.zeros((ne, nen, 3, nen, 3))
            for comp, w in ((0, self.wc), (1, self.wc), (2, self.ws)):
                Me3[:, :, comp, :, comp] = w * Me
            ab = np.zeros((L.ndof, L.kl + 1))
            scatter_band(Me3.reshape(ne, 3 * nen, 3 * nen), L.edofs, L.ecoef, 1.0, ab)
            self._shared[key] = ab
        return self._shared[key]

    def _shift_band(self, tol: float) -> np.ndarray:
        """``tol * mu_min * M_n`` in band storage (cached for the last ``tol``: the margins ask for many)."""
        key = ("shift", self.wc, self.ws)
        c = self._shared.get(key)
        if c is None or c[0] != tol:
            c = self._shared[key] = (tol, (tol * float(np.min(self.model.mu))) * self.mass_band())
        return c[1]

    def inertia(self, u: np.ndarray, p: float, tol: float = ZERO_TOL, parts: StateParts | None = None,
                gauge: bool = True) -> int:
        """Number of eigenvalues of the pencil ``(K_n, M_n)`` below ``-tol * mu_min`` (scaled
        units) after removing the admissible rigid modes (:meth:`gauge_dofs`); -1 outside the
        Gent domain. ``parts``: :meth:`parts` at ``u`` when already computed. ``gauge=False``:
        of the whole pencil, the rigid modes' zero eigenvalues included (the margins' certificate).

        One band ``LDL^T`` of ``K_n + tol mu_min M_n`` (:func:`snapjump_kernels.banded.band_ldlt`;
        Sylvester's law of inertia); should it meet a zero pivot, the eigenvalues of the dense
        matrix are computed instead.
        """
        parts = self.parts(u) if parts is None else parts
        if parts is None:
            return -1
        if (parts.wc, parts.ws) != (self.wc, self.ws):
            raise ValueError(f"harmonic {self.n}: the parts were computed for other phi-averages")
        ab = self._gauged(u, p, tol, parts, gauge)
        ok, nneg = band_ldlt(ab, self.layout.ext)  # in place
        if ok:
            return int(nneg)
        log.warning("harmonic %d: zero pivot in the band LDL^T; using dense eigenvalues", self.n)
        import scipy.linalg as sl

        ab = self._gauged(u, p, tol, parts, gauge)
        n, kl = ab.shape[0], self.layout.kl
        Kd = np.zeros((n, n))
        for k in range(kl + 1):
            i = np.arange(n - k)
            Kd[i + k, i] = ab[i, k]
            Kd[i, i + k] = ab[i, k]
        return int(np.sum(sl.eigvalsh(Kd) < 0.0))

    def _gauged(self, u: np.ndarray, p: float, tol: float, parts: StateParts, gauge: bool = True) -> np.ndarray:
        """The band of ``K_n + tol mu_min M_n`` with (``gauge``) the gauge dofs' rows and columns
        replaced by a unit pivot (times the largest diagonal entry)."""
        return self._band(parts, p, self._shift_band(tol), self.gauge_dofs(u) if gauge else np.zeros(0, np.int64))


@dataclass
class _GaugeSetup:
    fixed_flat: np.ndarray  # flat (node, amplitude) index of each fixed amplitude (the axis ties excepted)
    trans_fixed: np.ndarray  # the translation's entries there
    dof_flat: np.ndarray  # flat (node, amplitude) index of each dof
    trans_vec: np.ndarray  # the translation as a dof vector


@dataclass
class StateParts:
    """What every harmonic's ``K_n`` at one state shares (:func:`state_parts`)."""

    Kp: np.ndarray  # (3, ne, nd, nd): element matrices of the strain energy, coefficients of n^0, n^1, n^2
    x: np.ndarray  # (nn, 2) current node positions (scaled)
    wc: float
    ws: float


def state_parts(model, u: np.ndarray, wc: float = 0.5, ws: float = 0.5) -> StateParts | None:
    """The element matrices of ``K_n`` at ``u`` as a polynomial in ``n``
    (:func:`snapjump_kernels.harmonics.harmonic_element_parts`), for the phi-averages ``wc, ws``
    (1/2, 1/2: every ``n >= 1``), with the current positions; ``None`` outside the Gent domain."""
    M = model
    U = M.full_displacement(u)
    Kp, ok = harmonic_element_parts(U, M.conn, M.mat, M.mu, M.jm, M.kappa, M.dNdX, M.N_ref, M.Rq, M.Wq,
                                    M.Np, M.Minv, wc, ws)
    return StateParts(Kp, M.X + U, wc, ws) if ok else None


def pivot_columns(A: np.ndarray) -> np.ndarray:
    """The first ``k`` pivot columns of the column-pivoted QR of ``A`` (``k x n``, ``k`` rows of
    rigid modes): at each step the column of largest norm orthogonal to the columns chosen so far
    (LAPACK's ``geqp3`` rule, in ``O(k^2 n)`` without forming the factorisation)."""
    R = np.array(A, dtype=float)
    k = R.shape[0]
    norms = np.einsum("ij,ij->j", R, R)
    piv: list[int] = []
    for step in range(k):
        if piv:
            norms[piv] = -1.0
        j = int(np.argmax(norms))
        piv.append(j)
        if step == k - 1:
            break
        c = R[:, j]
        q = c / np.sqrt(c @ c)
        R -= q[:, None] * (q @ R)[None, :]  # remove that direction from every column
        norms = np.einsum("ij,ij->j", R, R)
    return np.array(piv, dtype=np.int64)


_CACHE: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def harmonic_operator(model, n: int, free_body: bool | None = None) -> HarmonicOperator:
    """The (cached per model) :class:`HarmonicOperator` of harmonic ``n``."""
    per_model = _CACHE.setdefault(model, {})
    key = (int(n), free_body)
    if key not in per_model:
        per_model[key] = HarmonicOperator(model, n, free_body)
    return per_model[key]


def _unstable_harmonics(ops, u, p, tol, first_only: bool) -> list[int]:
    """The harmonics of ``ops`` unstable at ``(u, p)`` (the first only, with ``first_only``); the
    element pass at ``u`` is made once for all of them (:func:`state_parts`)."""
    out = []
    parts: dict = {}
    for op in ops:
        key = (op.wc, op.ws)
        if key not in parts:
            parts[key] = op.parts(u)
        k = op.inertia(u, p, tol, parts[key]) if parts[key] is not None else -1
        if k != 0:  # -1 (outside the material domain) cannot be certified stable either
            if k < 0:
                log.warning("harmonic %d: state outside the Gent domain, counted as unstable", op.n)
            out.append(op.n)
            if first_only:
                break
    return out


def unstable_harmonics(model, u: np.ndarray, p: float, harmonics, tol: float = ZERO_TOL,
                       free_body: bool | None = None, first_only: bool = False) -> list[int]:
    """The harmonics of ``harmonics`` (each ``>= 1``) unstable at the axisymmetric equilibrium
    ``(u, p)`` of ``model`` (the first only, with ``first_only``), as the harmonic check counts them:
    eigenvalues below ``-tol mu_min``, a state outside the material domain counted as unstable; the
    element pass at ``u`` made once for all of them."""
    ops = [harmonic_operator(model, int(n), free_body) for n in harmonics]
    return _unstable_harmonics(ops, u, p, tol, first_only)


def _refine(tracer, ops, a, b, bad, tol, steps):
    """Bisect the volume between the stable state ``a`` and the unstable state ``b`` (consecutive
    checked states with ``V_a < V_b``, on the rising branch before V*); returns the first unstable
    state found and its unstable harmonics."""
    cand = [op for op in ops if op.n in bad]
    for _ in range(steps):
        w = 0.5
        z = (1 - w) * a.zeta[0] + w * b.zeta[0]
        res = tracer.correct((1 - w) * a.u + w * b.u, (1 - w) * a.p + w * b.p, None, None, 0.0, target=(0, z))
        if res is None:
            log.debug("harmonic refinement: no equilibrium at zeta_0 = %.6g; bracket kept", z)
            break
        lin = res[0]
        mid = _State(lin.u, lin.p, np.array([z]))
        now = _unstable_harmonics(cand, mid.u, mid.p, tol, first_only=False)
        if now:
            b, bad = mid, now
        else:
            a = mid
    return b, bad


@dataclass
class _State:
    u: np.ndarray
    p: float
    zeta: np.ndarray


def check_harmonics(result, n_max: int, tol: float = ZERO_TOL, free_body: bool | None = None,
                    scan_all: bool = False, refine: int = 6) -> HarmonicCheck:
    """Stability against harmonics ``1..n_max`` along a solved scene.

    Checks every converged path state up to the snap (``path.points[: k_before + 1]`` and the
    upper state at V*; the whole path when the scene does not snap) and the lower state. The scan
    stops at the first unstable state unless ``scan_all``. The first loss of stability is then
    located between that state and the previous (stable) one by ``refine`` bisections of the
    cavity volume (each one Newton solve at fixed volume and one ``LDL^T`` per harmonic that
    became unstable; only on the rising branch before V*, where the volume parameterises the path).

    Parameters
    ----------
    result : :class:`snapjump_cli.fe.solve.SceneResult` (with ``model``, ``path``, ``states``,
        ``tracer``)
    n_max : highest harmonic checked (>= 1)
    tol : zero tolerance of the eigenvalues (see :data:`ZERO_TOL`)
    free_body : see :class:`HarmonicOperator`
    scan_all : check every state (the first loss of stability is reported all the same)
    refine : bisection steps locating the first loss of stability (0: report the first unstable
        path state as it is)

    Returns
    -------
    HarmonicCheck
    """
    if n_max < 1:
        raise ValueError(f"n_max must be >= 1, got {n_max}")
    t0 = time.perf_counter()
    model, pts, st = result.model, result.path.points, result.states
    L3, S = model.L**3, model.S
    ops = [harmonic_operator(model, n, free_body) for n in range(1, n_max + 1)]
    upper = getattr(st, "upper", None) if st is not None else None
    if upper is not None:
        states = list(pts[: st.k_before + 1]) + [upper]
    else:
        states = list(pts)
    out = HarmonicCheck(asym_first=False, asym_n_max=int(n_max))
    checked = 0
    prev = None
    for pt in states:
        bad = _unstable_harmonics(ops, pt.u, pt.p, tol, first_only=False)
        checked += 1
        if bad and not out.asym_first:
            first = pt
            tracer = getattr(result, "tracer", None)
            if refine > 0 and prev is not None and tracer is not None and upper is not None \
                    and prev.zeta[0] < pt.zeta[0]:
                first, bad = _refine(tracer, ops, prev, pt, bad, tol, refine)
                checked += refine
            out.asym_first, out.asym_n, out.asym_ns = True, bad[0], ",".join(map(str, bad))
            out.asym_V_m3, out.asym_p_Pa = float(model.volume(first.u) * L3), float(first.p * S)
            if not scan_all:
                break
        prev = pt
    lower = getattr(st, "lower", None) if st is not None else None
    if upper is not None and lower is not None:
        bad = _unstable_harmonics(ops, lower.u, lower.p, tol, first_only=True)
        checked += 1
        out.asym_lower_stable = not bad
        out.asym_lower_n = bad[0] if bad else None
    out.asym_states_checked = checked
    out.asym_wall_s = time.perf_counter() - t0
    log.info("harmonics 1..%d: %s (%d states, %.2f s)", n_max,
             f"harmonic {out.asym_n} unstable at V = {out.asym_V_m3:.4g} m^3" if out.asym_first
             else "stable up to the snap", checked, out.asym_wall_s)
    return out
