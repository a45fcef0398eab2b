"""How far each harmonic is from losing stability along a path: the margins (docs/harmonics.md, section 11).

The harmonic check (:mod:`snapjump_cli.fe.stability.harmonics`) gives a sign per harmonic and state. The
margin is the number behind it: the smallest eigenvalue of the pencil ``(K_n, M_n)`` (the rigid
modes of ``n = 1`` projected out: the eigenvalues of ``K_1`` on the ``M``-orthogonal complement of
the translation and tilt; the check's gauge, which fixes one amplitude per rigid mode, leaves the
inertia as it is but not the eigenvalues: a deformation that moves a gauge point drags a rigid
motion along, whose mass lowers the quotient, ten to thirty times for the actuators),
``n = 0..n_max``, in units of ``mu_i / R_i^2``: an energy per mean-square
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
from dataclasses import dataclass, field

import numpy as np

from snapjump_cli.fe.limits import check_time
from snapjump_cli.fe.stability.eigen import smallest_eigenvalue
from snapjump_cli.fe.stability.harmonics import harmonic_operator
from snapjump_cli.schema import MARGINS, columns

log = logging.getLogger(__name__)

__all__ = ["state_margins", "path_margins", "Margins", "MARGIN_KEYS"]

#: The row keys of :func:`path_margins` (null unless ``solver: {margins: true}``;
#: :data:`snapjump_cli.schema.MARGINS`).
MARGIN_KEYS: tuple[str, ...] = columns(MARGINS)


@dataclass
class Margins:
    """The margins along a path (:func:`path_margins`): ``asym_margin`` (the smallest margin of
    ``n = 1..n_max`` before ``V*``, in ``mu_i / R_i^2``), ``asym_margin_n`` (its harmonic),
    ``asym_margin_V_m3`` (where; all ``None`` when no margin was found) and ``table``:
    ``(n_states, n_max + 2)``, the volume [m^3] and the margins of ``n = 0..n_max`` per state."""

    asym_margin: float | None = None
    asym_margin_n: int | None = None
    asym_margin_V_m3: float | None = None
    table: np.ndarray = field(default_factory=lambda: np.empty((0, 0)), repr=False)

    def as_row(self) -> dict:
        """The row's keys of the margins (:data:`MARGIN_KEYS`)."""
        return {k: getattr(self, k) for k in MARGIN_KEYS}


def state_margins(model, u: np.ndarray, p: float, n_max: int, free_body: bool | None = None) -> np.ndarray:
    """The margins of harmonics ``0..n_max`` at one state, ``(n_max + 1,)`` (NaN outside the domain)."""
    out = np.full(n_max + 1, np.nan)
    for n in range(n_max + 1):
        check_time()
        lam = smallest_eigenvalue(harmonic_operator(model, n, free_body), u, p)
        if lam is not None:
            out[n] = lam
    return out


def path_margins(result, n_max: int) -> Margins:
    """The margins along a solved scene's loading path (every path point up to the volume limit,
    and the upper state) and the smallest one of a non-axisymmetric harmonic met there.

    Returns
    -------
    Margins
    """
    model, pts, st = result.model, result.path.points, result.states
    states = list(pts[: st.k_before + 1]) + [st.upper] if st.upper is not None else list(pts)
    sV = result.tracer.sc[0]
    rows = []
    for pt in states:
        rows.append(np.concatenate([[pt.zeta[0] * sV * model.L**3], state_margins(model, pt.u, pt.p, n_max)]))
    table = np.array(rows)
    out = Margins(table=table)
    asym = table[:, 2:]
    if asym.size and np.isfinite(asym).any():
        i, j = np.unravel_index(np.nanargmin(asym), asym.shape)
        out.asym_margin, out.asym_margin_n, out.asym_margin_V_m3 = float(asym[i, j]), int(j + 1), float(table[i, 0])
    return out
