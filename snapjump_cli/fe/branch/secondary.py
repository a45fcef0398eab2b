"""Stability of a followed branch against the harmonics it does not keep (secondary bifurcations).

A branch of critical harmonic ``n_c`` is traced with the harmonics ``0, n_c, 2 n_c, ...``
(:func:`snapjump_cli.fe.branch.bifurcation.default_harmonics`): a subspace that the equations leave invariant,
so the branch is an exact solution of the full problem. It need not be *stable* in the full
problem. At a state whose displacement has only multiples of ``n_c``, the second variation
decouples into classes of harmonics by their residue modulo ``n_c`` (Bloch): the class of 0 is the
branch's own tangent, and the other classes (``n = 1, 2, 4, 5, ...`` for ``n_c = 3``; the odd
harmonics for ``n_c = 2``) are perturbations the branch's model cannot see. When one of them
loses stability before the branch's own volume limit, the actuator leaves the branch there (a
secondary bifurcation) and the followed snap does not happen as traced.

:func:`branch_stability` counts, at states of a followed branch, the unstable modes under volume
control in a model with every harmonic ``0, 1, ..., N`` and in the branch's own model: the
difference is the number of unstable modes outside the branch's subspace. Harmonic 1 carries the
rigid translation across the axis and the tilt of a free body (exact zero modes at an
equilibrium); the gauge of :func:`snapjump_cli.fe.branch.bifurcation.harmonic1_gauge` removes them.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace

import numpy as np

from snapjump_cli.fe.axisym.descent import constrained_negatives, descend_at_volume
from snapjump_cli.fe.axisym.sphere_path import descend_on_spheres
from snapjump_cli.fe.axisym.snap import SnapStates, root_on_step
from snapjump_cli.fe.branch.bifurcation import harmonic1_gauge
from snapjump_cli.fe.branch.landing import kick_along
from snapjump_cli.fe.branch.model import MultiHarmonicModel, component_index, transfer
from snapjump_cli.fe.branch import trace as branch_trace
from snapjump_cli.fe.branch.trace import (MICRO_FOLD_DE, FollowResult, axisym_inverted_state, branch_metrics,
                                          micro_energy, trace_branch)
from snapjump_cli.fe.continuation import Path, PathPoint, Tracer
from snapjump_cli.fe.stability.eigen import band_negatives, extra_eigen

log = logging.getLogger(__name__)

__all__ = ["SecondaryCheck", "Secondary", "full_model", "lift", "unstable_modes", "outside_modes", "branch_stability", "extra_dofs",
           "locate_secondary", "follow_secondary", "visited_points",
           "first_extra", "jump_off_branch", "reached_along", "jump_before", "landing_jump", "mode_counts",
           "more_outside", "extra_harmonics", "leaves_branch", "LeavesBranch", "StabilityWatch", "stability_watch", "rotation_signs", "rotated",
           "stable_outside"]


def full_model(mh: MultiHarmonicModel, N: int | None = None, u_axi: np.ndarray | None = None) -> MultiHarmonicModel:
    """The model with every harmonic ``0, 1, ..., N`` (default: the branch's highest) on the same
    axisymmetric model as ``mh``, harmonic 1's rigid modes gauged out at the axisymmetric state
    ``u_axi`` (default: the stress-free state), its phi rule made of the branch's points (so that
    a state of the branch, :func:`lift`-ed, is an equilibrium of both models alike)."""
    base = mh.base
    N = int(mh.hn[-1]) if N is None else int(N)
    if N < int(mh.hn[-1]):
        raise ValueError(f"N = {N} is below the branch's highest harmonic {int(mh.hn[-1])}")
    u0 = np.zeros(base.n) if u_axi is None else u_axi
    # phi rule: the branch's points (trapezoidal, spacing pi / (n_1 m)) repeated over [0, pi], so
    # that a lifted state has the branch's energy and residual to round-off and the harmonics
    # outside the branch decouple exactly; as fine as the full model's own default at least
    n1 = int(mh.hn[1]) if len(mh.hn) > 1 else 1
    step = n1 * max(mh.n_phi, 1)
    n_phi = step * math.ceil((2 * N + 2) / step)
    return MultiHarmonicModel(base, list(range(N + 1)), n_phi=n_phi, gauge=harmonic1_gauge(base, 1, u0))


def lift(mh: MultiHarmonicModel, full: MultiHarmonicModel, u: np.ndarray) -> np.ndarray:
    """A state of ``mh`` as a free vector of ``full`` (whose harmonics contain ``mh``'s): the same
    nodal amplitudes, zero in the harmonics ``mh`` does not keep."""
    return transfer(mh, full, u)


def unstable_modes(model: MultiHarmonicModel, u: np.ndarray, p: float) -> int:
    """Unstable modes of the equilibrium ``(u, p)`` of ``model`` under volume control (negative
    eigenvalues of the tangent restricted to ``dV/du . du = 0``, from the bordered ``LDL^T``);
    -1 outside the material domain or when the factorisation fails."""
    lin = model.linearize(u, p)
    if lin is None:
        return -1
    s = lin.factor(lin.g, 0.0)
    return constrained_negatives(s, lin.g)


def outside_modes(mh: MultiHarmonicModel, full: MultiHarmonicModel, u: np.ndarray, p: float) -> int:
    """The unstable modes of the branch state ``(u, p)`` of ``mh`` in the harmonics it does not
    keep: the negative eigenvalues of that diagonal block of ``full``'s tangent at the lifted state
    (:meth:`~snapjump_cli.fe.branch.model.MultiHarmonicModel.block_band`, the block alone formed
    and factorised). At a branch state the block decouples from the branch's harmonics, and the
    volume constraint lies in harmonic 0, inside: these are the modes ``full`` counts beyond the
    branch's own. -1 outside the material domain or at a zero pivot."""
    out = full.block_band(lift(mh, full, u), p, extra_harmonics(mh, full))
    if out is None:
        return -1
    ab, block = out
    return band_negatives(ab, block.ext)


#: :func:`mode_counts` counts a state's unstable modes in the branch's own model only where some lie
#: outside it: every decision of the check reads the count outside (a state with none there is
#: stable outside whatever its own count), so the own count, an assembly and a factorisation of the
#: branch's model, was made for nothing at every state checked stable outside. ``False``: counted
#: at every state, as before (a switch for measurements; the decisions and answers are the same).
OWN_WHERE_OUTSIDE = True


def mode_counts(mh: MultiHarmonicModel, full: MultiHarmonicModel, pt) -> tuple[int | None, int]:
    """``(own, outside)``: the unstable modes of the branch state ``pt`` in the branch's model
    (:func:`unstable_modes`) and outside it (:func:`outside_modes`; together, those of the model
    with every harmonic); -1 where a factorisation failed. The own count is made only where the
    count outside is not zero (``None`` otherwise; :data:`OWN_WHERE_OUTSIDE`)."""
    out = outside_modes(mh, full, pt.u, pt.p)
    own = unstable_modes(mh, pt.u, pt.p) if out != 0 or not OWN_WHERE_OUTSIDE else None
    return own, out


def more_outside(own: int | None, out: int) -> bool:
    """Whether the model with every harmonic counts more unstable modes than the branch's (a
    failed count, -1, is neither)."""
    return out > 0 and own is not None and own >= 0


@dataclass
class SecondaryCheck:
    """The branch's states checked against the full harmonics: per state its index on the path,
    cavity volume (m³), pressure (Pa) and the unstable modes outside the branch's harmonics
    (``outside``) and in its model (``own``: :func:`mode_counts`, ``None`` where none lie outside);
    the first state with some outside (``first``: index into these lists, ``None`` if none; the
    counts are -1 where a factorisation failed, and such a state counts as neither stable nor
    unstable)."""

    N: int
    index: list[int] = field(default_factory=list)
    V_m3: list[float] = field(default_factory=list)
    p_Pa: list[float] = field(default_factory=list)
    own: list[int | None] = field(default_factory=list)
    outside: list[int] = field(default_factory=list)
    first: int | None = None
    #: the first point the actuator passes through with an extra unstable mode (a path index,
    #: :func:`first_extra`; ``chk.first`` is only the first such point of the checked sample) and
    #: its cavity volume (m³), once known
    first_point: int | None = None
    first_V_m3: float | None = None


def visited_points(fr, upto: int) -> list[int]:
    """The path points of a followed branch that the actuator passes through under volume control,
    up to index ``upto``: those at which the cavity volume is a new high (inflation only adds
    volume; past a fold traced through, the actuator jumps to the branch's state at the same
    volume further on, and the points between are never reached). A fold recorded on the branch
    (``fr.folds``, :class:`snapjump_cli.fe.branch.trace.FoldJump`) raises the high to its own volume,
    which lies between two path points, and the state a restart lands on counts as passed
    through. From the first point after the bifurcation: at the bifurcation point itself the
    critical eigenvalue is zero, and its sign (so the count of either model) is round-off."""
    pts = fr.path.points
    folds = getattr(fr, "folds", None) or []
    fold_top: dict[int, float] = {}
    for f in folds:
        fold_top[f.k] = max(fold_top.get(f.k, -math.inf), float(f.upper.zeta[0]))
    landings = {f.landing_index for f in folds if f.landing_index is not None}
    out, top = [], pts[0].zeta[0] if pts else 0.0
    for i in range(1, min(upto, len(pts) - 1) + 1):
        if i - 1 in fold_top:
            top = max(top, fold_top[i - 1])
        V = pts[i].zeta[0]
        if V >= top or i in landings:
            out.append(i)
            top = max(top, V)
    return out


def reached_along(fr, j: int) -> bool:
    """Whether the actuator reaches path point ``j`` of the branch from point ``j - 1`` (both
    visited, :func:`visited_points`; the bifurcation point counts), not by a jump past a fold
    (nor by the jump onto the first point of a restarted trace, ``fr.folds``)."""
    if any(f.landing_index == j for f in (getattr(fr, "folds", None) or [])):
        return False
    return j - 1 in set(visited_points(fr, j)) | {0}


def jump_before(fr, j: int):
    """The recorded fold (:class:`snapjump_cli.fe.branch.trace.FoldJump`) the actuator jumps past last
    before reaching path point ``j``, or ``None``."""
    before = [f for f in (getattr(fr, "folds", None) or []) if f.k < j]
    return before[-1] if before else None


def landing_jump(fr, j: int):
    """The recorded fold whose jump brings the actuator to path point ``j``: the last one before
    ``j`` if ``j`` is the state it lands on (a restarted trace's first point) or the first point
    passed through after it; ``None`` if another fold, not recorded, lies between."""
    f = jump_before(fr, j)
    if f is None:
        return None
    if f.landing_index is not None:
        return f if f.landing_index == j else None
    return None if any(f.k < i < j for i in visited_points(fr, j)) else f


def rotation_signs(mh: MultiHarmonicModel) -> np.ndarray | None:
    """The branch model's free vector of signs that turns a state by ``pi / n_c`` about the axis
    (harmonic ``m n_c`` times ``(-1)^m``), for an even ``n_c`` (``None`` otherwise).

    A state of a branch of ``n_c`` is mirror-symmetric about ``phi = 0`` and about ``phi = pi / n_c``.
    For an even ``n_c`` the two planes are not turned into one another by the state's rotations
    (for an odd one they are), so a perturbation symmetric about the second plane is one the model
    with every harmonic (symmetric about ``phi = 0``) does not hold: it holds it for the state
    turned by ``pi / n_c``, which is again a state of the branch's model."""
    hn = [int(n) for n in mh.hn]
    if len(hn) < 2 or hn[1] % 2:
        return None
    S = np.ones((mh.dofmap.shape[0], mh.nc))
    for k, n in enumerate(hn[1:], start=1):
        o = component_index(k, 0)
        S[:, o:o + 3] = (-1.0) ** (n // hn[1])
    return mh.free_vector(S)


def rotated(fr):
    """The followed branch ``fr`` turned by ``pi / n_c`` (:func:`rotation_signs`; ``None`` for an odd
    ``n_c``): the same path, states and folds, each state turned (a branch of the same model)."""
    import copy

    sgn = rotation_signs(fr.model)
    if sgn is None:
        return None

    def turn(pt):
        return None if pt is None else replace(pt, u=sgn * pt.u, du_ds=sgn * pt.du_ds)
    out = copy.copy(fr)
    out.path = replace(fr.path, points=[turn(pt) for pt in fr.path.points])
    if fr.states is not None:
        out.states = replace(fr.states, upper=turn(fr.states.upper), lower=turn(fr.states.lower))
    out.folds = [replace(f, upper=turn(f.upper), landing=turn(f.landing)) for f in (fr.folds or [])]
    out.watch = None
    out.turned = True
    return out


@dataclass
class StabilityWatch:
    """The check of :func:`branch_stability` made while a branch is traced up to its upper state
    (``BranchTracker.watch``): every ``stride``-th state the actuator passes through (a new high of
    the volume: :func:`visited_points` of a trace without recorded folds) is counted in the branch's
    model and in ``full`` (and, for an even ``n_c``, turned by ``pi / n_c``: ``counts_turned``); it
    says stop at the first with more unstable modes in ``full``. A fold is recorded only once the
    path has come back past it, so the watch picks the states by the volume's highs alone and may
    count one that :func:`branch_stability` (which honours the recorded folds) then skips; the
    counts are cached by path index and :func:`branch_stability` reads those of the states it
    checks, so its result, and the secondary bifurcation located, are those of the trace to the
    upper state (where the watch stopped on a state the check skips, the check finds nothing and
    the branch is traced to its snap as in the reference)."""

    mh: MultiHarmonicModel
    full: MultiHarmonicModel
    stride: int = 5
    counts: dict = field(default_factory=dict)
    #: the same counts for the state turned by ``pi / n_c`` (an even ``n_c``: :func:`rotation_signs`)
    counts_turned: dict = field(default_factory=dict)
    _top: float = -math.inf
    _n_visited: int = 0
    _signs: np.ndarray | None = None

    def __post_init__(self) -> None:
        self._signs = rotation_signs(self.mh)

    def __call__(self, path: Path) -> bool:
        pts = path.points
        i = len(pts) - 1
        if i < 1:
            return False
        if self._n_visited == 0 and not self.counts:
            self._top = float(pts[0].zeta[0])
        V = float(pts[i].zeta[0])
        if V < self._top:
            return False
        self._top = V
        self._n_visited += 1
        if (self._n_visited - 1) % self.stride:
            return False
        self.counts[i] = mode_counts(self.mh, self.full, pts[i])
        out = more_outside(*self.counts[i])
        if self._signs is not None:
            pt = pts[i]
            self.counts_turned[i] = mode_counts(self.mh, self.full, replace(pt, u=self._signs * pt.u))
            out = out or more_outside(*self.counts_turned[i])
        return out


def stability_watch(N: int | None = None, stride: int = 5, u_axi: np.ndarray | None = None):
    """A ``watch`` for :func:`snapjump_cli.fe.branch.trace.follow_branch` (made from the branch's
    model): :class:`StabilityWatch` against :func:`full_model` ``(mh, N, u_axi)``, as
    :func:`follow_secondary` with the same ``N`` and ``stride`` checks the branch."""
    return lambda mh: StabilityWatch(mh, full_model(mh, N, u_axi), int(stride))


def stable_outside(N: int | None = None, u_axi: np.ndarray | None = None):
    """A ``landing_check`` for :func:`snapjump_cli.fe.branch.trace.follow_branch` (made from the branch's
    model ``mh``): whether a state of ``mh`` is stable under volume control in :func:`full_model`
    ``(mh, N, u_axi)``: none outside the branch's harmonics nor in its model."""

    def make(mh: MultiHarmonicModel):
        full = full_model(mh, N, u_axi)

        def stable(pt) -> bool:
            # none outside the branch's harmonics, then none in its own model (the count outside first:
            # a state unstable there needs no own count)
            return outside_modes(mh, full, pt.u, pt.p) == 0 and unstable_modes(mh, pt.u, pt.p) == 0

        return stable

    return make


def leaves_branch(N: int | None = None, u_axi: np.ndarray | None = None):
    """A ``settle`` for :func:`snapjump_cli.fe.branch.trace.follow_branch` (made from the branch's
    model ``mh``): whether a state of the branch is unstable outside its harmonics (the smallest
    eigenvalue of :func:`extra_eigen` in :func:`full_model` ``(mh, N, u_axi)`` below zero, for the
    state or, for an even ``n_c``, the state turned by ``pi / n_c``: :func:`rotation_signs`), as
    :func:`follow_secondary` decides for the state a jump lands on."""

    return lambda mh: LeavesBranch(mh, full_model(mh, N, u_axi), N, u_axi)


class LeavesBranch:
    """:func:`leaves_branch`'s check for the branch model ``mh`` against ``full`` (``full_model(mh,
    N, u_axi)``): ``leaves(pt)``. It keeps the model and the eigenpairs it computed
    (:meth:`eigen`), which :func:`follow_secondary` reuses for the state the jump lands on."""

    def __init__(self, mh: MultiHarmonicModel, full: MultiHarmonicModel, N: int | None, u_axi) -> None:
        self.mh, self.full, self.N, self.u_axi = mh, full, N, u_axi
        self.harmonics = extra_harmonics(mh, full)
        self.signs = rotation_signs(mh)
        self._seen: dict = {}

    def __call__(self, pt: PathPoint) -> bool:
        for u in [pt.u] if self.signs is None else [pt.u, self.signs * pt.u]:
            e = extra_eigen(self.full, lift(self.mh, self.full, u), pt.p, self.harmonics)
            self.full.release_buffers()
            self._seen[(u.tobytes(), float(pt.p))] = e
            if e is not None and e[0] < 0.0:
                return True
        return False

    def serves(self, mh: MultiHarmonicModel, N: int | None, u_axi) -> bool:
        """Whether its model is the one :func:`follow_secondary` would build for ``mh``."""
        return mh is self.mh and N == self.N and (u_axi is self.u_axi or np.array_equal(u_axi, self.u_axi))

    def eigen(self, u: np.ndarray, p: float):
        """The :func:`extra_eigen` of the branch state ``(u, p)`` if this check computed it, else ``None``."""
        return self._seen.get((np.asarray(u).tobytes(), float(p)))


def branch_stability(fr, N: int | None = None, stride: int = 1, upto: int | None = None,
                     stop_at_first: bool = False, full: MultiHarmonicModel | None = None,
                     counts: dict | None = None) -> SecondaryCheck:
    """Count the unstable modes of a followed branch's states outside the branch's subspace.

    Parameters
    ----------
    fr : a :class:`snapjump_cli.fe.branch.trace.FollowResult`
    N : highest harmonic of the full model (default: the branch's highest)
    stride : check every ``stride``-th point the actuator passes through (:func:`visited_points`;
        ``upto`` is always checked)
    upto : last path index checked (default: the last path point before the branch's upper state,
        else its last point; the upper state itself, located inside the step after it, is not)
    stop_at_first : stop at the first state with an extra unstable mode
    full : the model with every harmonic (default: :func:`full_model` of the branch, ``N``)
    counts : unstable-mode counts already made, ``{path index: (own, outside)}`` (a
        :class:`StabilityWatch`'s)

    Returns
    -------
    SecondaryCheck
    """
    mh, pts = fr.model, fr.path.points
    full = full_model(mh, N, fr.bif.u) if full is None else full
    st = fr.states
    if upto is None:
        upto = st.k_before if st is not None and st.k_before is not None else len(pts) - 1
    idx = visited_points(fr, upto)[:: max(1, int(stride))]
    if not idx:
        return SecondaryCheck(N=int(full.hn[-1]))
    if idx[-1] != upto:
        idx.append(upto)
    L3, S = mh.L**3, mh.S
    out = SecondaryCheck(N=int(full.hn[-1]))
    try:
        for i in idx:
            pt = pts[i]
            own, n_out = counts[i] if counts and i in counts else mode_counts(mh, full, pt)
            out.index.append(i)
            out.V_m3.append(float(mh.volume(pt.u) * L3))
            out.p_Pa.append(float(pt.p * S))
            out.own.append(own)
            out.outside.append(n_out)
            if out.first is None and more_outside(own, n_out):
                out.first = len(out.index) - 1
                log.info("branch of harmonic %d: %d unstable mode(s) outside its harmonics at V = %.4g m^3 "
                         "(path point %d)", fr.bif.n, n_out, out.V_m3[-1], i)
                if stop_at_first:
                    break
    finally:
        full.release_buffers()
        mh.release_buffers()  # (the branch's model refills its pool here; its result keeps the model)
    return out


def extra_harmonics(mh: MultiHarmonicModel, full: MultiHarmonicModel) -> list[int]:
    """The harmonics of ``full`` that ``mh`` does not keep."""
    own = set(int(n) for n in mh.hn)
    return [int(n) for n in full.hn if int(n) not in own]


def extra_dofs(mh: MultiHarmonicModel, full: MultiHarmonicModel) -> np.ndarray:
    """The free dofs of ``full`` that belong to the harmonics ``mh`` does not keep (sorted)."""
    others = set(extra_harmonics(mh, full))
    cols = [component_index(k, c) for k, n in enumerate(full.hn) if int(n) in others for c in range(3)]
    d = full.dofmap[:, cols]
    return np.unique(d[d >= 0])


@dataclass
class Secondary:
    """A secondary bifurcation of a followed branch: the branch's state there (a point of its
    path's step from ``index`` to ``index + 1``), the critical mode as a free vector of the full
    model, its dominant harmonic and the eigenvalue left at the located point (relative to its
    value at the stable side of the step). For a jump off the branch
    (:func:`jump_off_branch`): the state the jump lands on, ``index`` the last path point before the
    fold, the unstable mode there and its eigenvalue (absolute)."""

    point: object
    index: int  # the last point of the branch's path before it
    full: MultiHarmonicModel
    mode: np.ndarray
    n: int
    eig: float
    V_m3: float
    p_Pa: float


#: The secondary bifurcation is located where the eigenvalue outside the branch has fallen below
#: this fraction of its change over the path step that brackets it (about this fraction of the
#: step's length from its zero, for an eigenvalue that varies linearly along the step), or below
#: ``tol`` of its value at the stable end, whichever is larger. ``tol`` alone (1e-7) asked more of
#: the eigenvalue than its round-off: on ``follow_strata`` row 9 the trials' eigenvalues fell
#: -8.4e-8, -2.6e-10, then +1.6e-12 and +1.3e-12, on row 8 -1.1e-7, -6.7e-10, then +2.9e-12,
#: -3.2e-12, -1.8e-13, the sign no longer following the position: two and three trial points
#: spent on round-off (``bench.profile.follow --sample bench/harmonics_sample/follow_strata.yaml
#: --rows 8 9 --set snapjump_cli.fe.branch.secondary.LOCATE_STEP_FRACTION=0.0 --debug
#: snapjump_cli.fe.branch.secondary``). With 1e-4 each of ``follow_strata`` rows 8, 9 and
#: ``follow_strata_n2`` rows 2, 22 stops at its second trial (the blocks and CPU of ``--json``,
#: with and without that ``--set``; docs/performance.md).
LOCATE_STEP_FRACTION = 1e-4


def locate_secondary(fr, chk: SecondaryCheck, full: MultiHarmonicModel, tol: float = 1e-7,
                     max_iter: int = 30, first: int | None = None, start=None) -> Secondary | None:
    """The secondary bifurcation that :func:`branch_stability` bracketed (``chk.first``): the
    consecutive path points on either side of it (``first``: the first point with an extra
    unstable mode, :func:`first_extra`, when already known), then the zero of the smallest
    eigenvalue of the harmonics outside the branch (:func:`extra_eigen`, relative to its value at
    the stable side) on that step (:func:`snapjump_cli.fe.axisym.snap.root_on_step`), to ``tol`` of that
    value or :data:`LOCATE_STEP_FRACTION` of its change over the step; ``None`` without a
    bracket of two consecutive points the actuator passes through (:func:`visited_points`).
    ``start``: the stable state the bracket starts from instead of the point before ``first`` (the
    state a jump past a fold lands on, on the path between that point and ``first``)."""
    if chk.first is None:
        return None
    mh, pts = fr.model, fr.path.points
    others = extra_harmonics(mh, full)
    j1 = first_extra(fr, chk, full) if first is None else first
    if start is not None:
        a, b, a_prev = start, pts[j1], None
        if not b.s > a.s:
            return None
    else:
        if not reached_along(fr, j1):
            return None  # reached by a jump past a fold: no bifurcation on the step before it
        a, b = pts[j1 - 1], pts[j1]
        a_prev = pts[j1 - 2] if j1 >= 2 else None
    # (the extra count is 0 at a and the eigenvalue that crosses zero on the step is the one
    # nearest zero: no inertia count at each trial)
    ea = extra_eigen(full, lift(mh, full, a.u), a.p, others, smallest=False)
    if ea is None or not ea[0] > 0.0:
        return None
    scale = ea[0]
    solved: dict = {id(a): (a, (ea[0] / scale, ea[1]))}  # id -> (point, eigenpair): the points kept

    def f(q) -> float:
        e = extra_eigen(full, lift(mh, full, q.u), q.p, others, scale, smallest=False)
        if e is None:
            return math.nan
        solved[id(q)] = (q, e)
        log.debug("secondary bifurcation: eigenvalue outside the branch %.3e (%.3e of the stable end's) at %.6g "
                  "of the step's %.6g", e[0] * scale, e[0], q.s - a.s, b.s - a.s)
        return e[0]

    fb = f(b)
    if not fb < 0.0:
        return None
    tol = max(tol, LOCATE_STEP_FRACTION * (1.0 - fb))  # (f(a) = 1: 1 - fb is the change over the step)
    root = root_on_step(fr.tracer, a, b, a_prev, f, tol, max_iter, f_ends=(ea[0] / scale, fb))
    eig, mode = solved[id(root)][1]  # (root_on_step returns a point it evaluated)
    if not abs(eig) < 100.0 * tol:  # root_on_step returns its last point on b's side if it does not converge
        log.warning("secondary bifurcation of the branch of harmonic %d not converged (relative eigenvalue "
                    "%.2e between path points %d and %d): not located", fr.bif.n, eig, j1 - 1, j1)
        return None
    amps = {n: float(np.abs(full.harmonic_part(mode, n)).max()) for n in extra_harmonics(mh, full)}
    n_dom = max(amps, key=amps.get)
    sc = fr.tracer.sc
    return Secondary(root, j1 - 1, full, mode, int(n_dom), float(eig), float(root.zeta[0] * sc[0] * mh.L**3),
                     float(root.p * mh.S))


def follow_secondary(result, fr, N: int | None = None, stride: int = 5, jump_path: bool = False, **kw):
    """Check a followed branch against the harmonics it does not keep and, if it loses stability
    to them before its volume limit, trace the branch that leaves it there in the model with every
    harmonic ``0..N`` (:func:`snapjump_cli.fe.branch.trace.trace_branch`).

    Returns
    -------
    (FollowResult or None, SecondaryCheck, Secondary or None)
        the secondary branch (``None`` if the branch stays stable or the point was not located),
        the stability check and the located point. When the first state with an extra unstable
        mode is one the actuator reaches by a jump past a fold of the branch
        (:func:`visited_points`), there is no secondary bifurcation to locate: the jump itself
        goes on outside the branch (:func:`jump_off_branch`; ``jump_path``: its landing by the
        sphere path first).
    """
    watch = getattr(fr, "watch", None)
    reuse = isinstance(watch, StabilityWatch) and watch.stride == stride and watch.mh is fr.model
    settle = getattr(fr, "settle", None)
    settle = settle if isinstance(settle, LeavesBranch) and settle.serves(fr.model, N, fr.bif.u) else None
    full = watch.full if reuse else (settle.full if settle is not None else full_model(fr.model, N, fr.bif.u))
    chk = branch_stability(fr, stride=stride, stop_at_first=True, full=full, counts=watch.counts if reuse else None)
    j1 = first_extra(fr, chk, full) if chk.first is not None else None
    # the other class of mirror planes (an even n_c): the branch turned by pi / n_c, checked alike;
    # the actuator leaves the branch where either class loses stability first
    turned = rotated(fr)
    if turned is not None:
        chk_t = branch_stability(turned, stride=stride, stop_at_first=True, full=full,
                                 counts=watch.counts_turned if reuse else None)
        if chk_t.first is not None:
            j1_t = first_extra(turned, chk_t, full)
            if j1 is None or j1_t < j1:
                log.info("branch of harmonic %d: unstable outside its harmonics first about the plane phi = pi/%d "
                         "(path point %d, against %s)", fr.bif.n, fr.bif.n, j1_t, j1)
                fr, chk, j1 = turned, chk_t, j1_t
    if j1 is None:
        return None, chk, None
    start = None
    if not reached_along(fr, j1):
        # reached by a jump past a fold of the branch: if the state it lands on is unstable
        # outside the branch the jump goes on; if not, the loss of stability lies on the path
        # between that state and j1 (a landing between two path points, a micro-fold traced through)
        jump = landing_jump(fr, j1)
        land = jump.landing if jump is not None else fr.path.points[j1]
        e = settle.eigen(land.u, land.p) if settle is not None else None
        if e is None:
            e = extra_eigen(full, lift(fr.model, full, land.u), land.p, extra_harmonics(fr.model, full))
        if jump is None or jump.landing_index is not None or e is None or e[0] < 0.0:
            return jump_off_branch(result, fr, chk, full, j1, jump, eigen=e, volume_path=jump_path)
        start = land
    try:
        sec = locate_secondary(fr, chk, full, first=j1, start=start)
    finally:
        fr.model.release_buffers()
    if sec is None:
        full.release_buffers()
        return None, chk, None
    fs = trace_branch(result, fr.bif, full, lift(fr.model, full, sec.point.u), sec.point.p, sec.mode,
                      extra_harmonics(fr.model, full), **kw)
    fs.parent, fs.secondary = fr, sec
    return fs, chk, sec


def first_extra(fr, chk: SecondaryCheck, full: MultiHarmonicModel) -> int:
    """The path index of the first point the actuator passes through (:func:`visited_points`)
    with an unstable mode outside the branch: between the last point :func:`branch_stability`
    checked without one and the first it found with one (``chk.first``)."""
    mh, pts = fr.model, fr.path.points
    j0 = chk.index[chk.first - 1] if chk.first > 0 else 0
    j1 = chk.index[chk.first]
    try:
        for j in visited_points(fr, j1):
            if j0 < j < j1 and more_outside(*mode_counts(mh, full, pts[j])):
                j1 = j
                break
    finally:
        mh.release_buffers()
    chk.first_point = j1
    chk.first_V_m3 = float(mh.volume(pts[j1].u) * mh.L**3)
    return j1


#: A jump's landing is first sought on the axisymmetric inverted state at the fold's volume (where
#: it is stable with every harmonic and lies below the fold by the micro-fold energy), then by the
#: sphere path: on the 16 jumps of ``follow_strata_n2`` that the sphere path lands, that state is
#: not such a state (given up by the harmonic check's inertia in 0.006-0.06 CPU-s, a scratch
#: timing), so they land as before, bit for bit; on row 3 it is, and the sphere path turned back
#: after 20 steps before it was taken (the state the descent comes to rest on, docs/harmonics.md
#: section 10.7): 8.4 -> 3.3 CPU-s, the same answer (``python -m bench.profile.follow --sample
#: bench/harmonics_sample/follow_strata_n2.yaml --rows 3 --json B.json``, again with ``--set
#: snapjump_cli.fe.branch.secondary.JUMP_AXISYM_FIRST=False``, compared by ``bench.profile.answers``).
JUMP_AXISYM_FIRST = True


def _axisym_landing(result, full: MultiHarmonicModel, tr: Tracer, upper: PathPoint) -> tuple[PathPoint | None, str]:
    """The axisymmetric inverted state at the volume of ``upper`` as a jump's landing
    (:func:`snapjump_cli.fe.branch.trace.axisym_inverted_state`), where it is stable with every
    harmonic of ``full`` and releases at least the micro-fold energy; ``(None, "")`` otherwise."""
    alt, note = axisym_inverted_state(result, full, tr, upper)
    if alt is not None and full.energy(upper.u) - full.energy(alt.u) >= micro_energy(result, MICRO_FOLD_DE):
        return alt, note
    return None, ""


def jump_off_branch(result, fr, chk: SecondaryCheck, full: MultiHarmonicModel, landing: int, jump=None,
                    eigen=None, volume_path: bool = False):
    """The snap of an actuator that jumps past a fold of the followed branch onto a state of the
    branch (``landing``) that is unstable outside the branch's harmonics: the jump goes on, at the
    fold's volume, to the state that an energy descent at fixed volume in the model with every
    harmonic reaches from the landing state displaced along its unstable mode
    (:func:`snapjump_cli.fe.axisym.descent.descend_at_volume`). The upper state is the fold: the last
    state the actuator passes through before the landing state: the recorded fold ``jump``
    (:class:`snapjump_cli.fe.branch.trace.FoldJump`, with the state it lands on) when the branch's trace
    located it, else the last path point passed through before ``landing``. ``eigen``: the landing
    state's :func:`extra_eigen`, if already computed. (The descent is the model's own: started with
    fewer harmonics, :mod:`snapjump_cli.fe.branch.coarse`, it cost more on ``follow_strata_n2`` row 4.)
    With ``volume_path`` and an even ``n_c`` the state is first sought on the sphere path from the
    landing state (:func:`snapjump_cli.fe.axisym.sphere_path.descend_on_spheres`): the minima of the
    energy at that volume on growing spheres around it, from its unstable mode on to the first
    equilibrium that is stable and lower; the descent where it finds none. For an even ``n_c`` the
    mode's two signs are mirror images (the turn by ``pi / n_c`` flips every harmonic outside the
    branch), so the jump's landing does not depend on the sign; on the 16 jumps of
    ``follow_strata_n2`` that the sphere path lands, the descent from the same start reaches the same
    state (docs/harmonics.md section 10.7). For an odd ``n_c`` the two signs can lead to different
    states; the descent along the mode's sign is kept.

    Returns
    -------
    (FollowResult or None, SecondaryCheck, Secondary or None)
        as :func:`follow_secondary`: the snap (``kind`` ``"jump"``, its path the upper state
        alone, ``parent`` the branch) and the landing state as the ``Secondary`` (``index`` the
        fold's path index)
    """
    mh, pts = fr.model, fr.path.points
    if jump is not None:
        k_up, up_b, land = jump.k, jump.upper, jump.landing
    else:
        visited = [j for j in visited_points(fr, landing) if j < landing]
        k_up = visited[-1] if visited else 0
        up_b, land = pts[k_up], pts[landing]
    tr = Tracer(full, fr.tracer.cfg)
    U = lift(mh, full, up_b.u)
    z = tr.zeta(U, up_b.p)[0]
    upper = PathPoint(U, up_b.p, z, up_b.tangent.copy(), lift(mh, full, up_b.du_ds), up_b.dp_ds, 0.0)
    L = lift(mh, full, land.u)
    e = extra_eigen(full, L, land.p, extra_harmonics(mh, full)) if eigen is None else eigen
    if e is None or not e[0] < 0.0:
        full.release_buffers()
        return None, chk, None
    eig, mode = e
    mode = kick_along(full, L, mode)  # (the branch's subspace is invariant: without it the jump stays on it)

    def on_spheres():
        at_L = PathPoint(L, land.p, tr.zeta(L, land.p)[0], up_b.tangent.copy(), upper.du_ds, 0.0, 0.0)
        return descend_on_spheres(tr, upper, at_L, mode)  # (the other way: its mirror image)

    # the ways tried before the descent, in order: the sphere path (an even n_c) and the axisymmetric
    # inverted state (first with JUMP_AXISYM_FIRST, else where the sphere path finds nothing)
    ways = [("sphere-path", on_spheres)] if volume_path and fr.bif.n % 2 == 0 else []
    if branch_trace.AXISYM_BEFORE_DESCENT:
        ways.insert(0 if JUMP_AXISYM_FIRST else len(ways),
                    ("axisymmetric path", lambda: _axisym_landing(result, full, tr, upper)))
    low, solver, notes = None, "sphere-path", []
    for solver, way in ways:
        low, note = way()
        notes.append(note)
        if low is not None:
            break
    msg = "; ".join(x for x in notes if x)
    if low is None:
        solver = "energy-descent"
        start = PathPoint(L + mode, land.p, tr.zeta(L + mode, land.p)[0], up_b.tangent.copy(), upper.du_ds, 0.0, 0.0)
        low, msg_d = descend_at_volume(tr, upper, start=start)
        msg = "; ".join(x for x in (msg, msg_d) if x)
    amps = {n: float(np.abs(full.harmonic_part(mode, n)).max()) for n in extra_harmonics(mh, full)}
    sc = fr.tracer.sc
    sec = Secondary(land, k_up, full, mode, int(max(amps, key=amps.get)), float(eig),
                    float(land.zeta[0] * sc[0] * mh.L**3), float(land.p * mh.S))
    st = SnapStates(k_before=0, upper=upper, lower=low, lower_method="descent" if low is not None else "")
    out = FollowResult(fr.bif, full, Path(points=[upper]), st, tr, "jump", fr.first_kind, lower_method="descent",
                       lower_solver=solver, lower_note=msg, failure="" if low is not None else msg, parent=fr, secondary=sec)
    out.metrics = branch_metrics(out, sc)
    full.release_buffers()
    return out, chk, sec
