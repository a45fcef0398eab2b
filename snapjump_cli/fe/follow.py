"""Follow the branch that bifurcates from the axisymmetric path, up to its own snap (docs/harmonics.md, section 10).

When the harmonic check (:func:`snapjump_cli.fe.harmonics.check_harmonics`) finds that harmonic
``n_c`` loses stability before ``V*``, the actuator leaves the axisymmetric path there. This module

1. locates the bifurcation on the axisymmetric path: the volume at which the smallest eigenvalue
   of the pencil ``(K_n, M_n)`` crosses zero (secant iterations between the last stable and the
   first unstable path state, each a Newton solve at fixed volume), and its critical mode;
2. builds the :class:`~snapjump_cli.fe.multiharmonic.MultiHarmonicModel` with the harmonics
   ``0, n_c, 2 n_c, ..., N`` (default ``N = 2 n_c``, at least 2);
3. leaves the path along the mode: the first Riks step starts at the bifurcation state with the
   mode as its tangent, so its hyperplane fixes the mode's amplitude and excludes the
   axisymmetric path (Newton converges there because the branch is a symmetric pitchfork: the
   mode's cubic term averages to zero over phi);
4. traces the bifurcated branch under volume control with the same continuation and snap tracker
   as the axisymmetric path, through its own limit points, to its volume limit and back to it.
   Whether the branch rises in volume (supercritical: its own limit comes later) or turns back at
   once (subcritical: the bifurcation point is the volume limit, and the actuator snaps there) is
   read off the traced branch, not assumed;
5. finds the lower state at that volume as the axisymmetric solve does
   (:func:`snapjump_cli.fe.lower_state.find_lower_state`, on the branch or off it at fixed volume),
   and computes the metrics.

Definitions for a non-axisymmetric state: the *pole* is the material point on the axis (the
inner cap's lower pole, as for the axisymmetric metrics); every harmonic ``n >= 1`` vanishes on
the axis up to the ``n = 1`` translation across it, so its height is the axisymmetric part's. The
*ground* is the lowest point of the ring's bottom face over all phi (the actuator stands on it),
so ``h_imp`` is the pole's height above that point; the tilt of a free body (an exact symmetry)
is fixed by the gauge of harmonic 1 (:class:`~snapjump_cli.fe.multiharmonic.MultiHarmonicModel`).
"""
from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from snapjump_cli.fe.continuation import (
    ContinuationFailed,
    Path,
    PathPoint,
    Tracer,
    trace,
)
from snapjump_cli.fe.harmonics import HarmonicOperator, harmonic_operator
from snapjump_cli.fe.lower_state import constrained_instability, find_lower_state
from snapjump_cli.fe.margins import eig_near
from snapjump_cli.fe.metrics import path_p_dV, snap_sequence
from snapjump_cli.fe.multiharmonic import MultiHarmonicModel
from snapjump_cli.fe.snap import SnapStates, SnapTracker, root_on_step
from snapjump_cli.fe.tracer import start_point

log = logging.getLogger(__name__)

__all__ = ["Bifurcation", "FollowResult", "locate_bifurcation", "follow_branch", "trace_branch", "default_harmonics",
           "FOLLOW_KEYS", "multiharmonic_snap_metrics", "BranchTracker", "followed_metrics", "apply_followed",
           "lowest_eigen", "ground_height", "branch_curve", "harmonic1_gauge", "trace_through_micro_folds",
           "ThroughFolds", "axisym_state_at", "tracker_bounds", "micro_energy"]

#: Keys :func:`followed_metrics` adds to a design's metrics (SI units).
FOLLOW_KEYS: tuple[str, ...] = (
    "followed", "follow_n", "follow_N", "follow_kind", "follow_V_bif_m3", "follow_p_bif_Pa",
    "follow_sec_n", "follow_sec_V_m3", "follow_sec_p_Pa", "follow_lower_method", "follow_dE_rel_diff", "follow_wall_s", "follow_note",
    "axisym_dE_J", "axisym_dy_pole_m", "axisym_h_imp_m", "axisym_V_star_m3", "axisym_p_star_Pa",
)


def default_harmonics(n_c: int, N: int | None = None) -> list[int]:
    """The harmonics kept for a branch of harmonic ``n_c``: ``0, n_c, 2 n_c, ...`` up to ``N``
    (default ``4 n_c``: with ``2 n_c`` the second-order field is complete but the branch's
    quartic term is not, and the branch folds back spuriously; docs/harmonics.md)."""
    if N is None or N == 0:
        N = 4 * n_c
    if N < n_c:
        raise ValueError(f"N = {N} is below the critical harmonic {n_c}")
    return [0] + list(range(n_c, N + 1, n_c))


def lowest_eigen(op: HarmonicOperator, u: np.ndarray, p: float, shift: float = 2.0) -> tuple[float, np.ndarray] | None:
    """The smallest eigenvalue of the pencil ``(K_n, M_n)`` (the rigid modes gauged out) and its
    mode as nodal amplitudes ``(nn, 3)`` scaled to a largest entry of 1; ``None`` outside the Gent
    domain. In units of ``mu_min / L^2`` of the scaled model (the harmonic check's measure).
    Shift-invert about ``-shift mu_min``: exact for the smallest eigenvalue while it lies above
    that (near a bifurcation it is close to 0; physical eigenvalues are of order 0.1-10)."""
    mu = float(np.min(op.model.mu))
    found = eig_near(op, u, p, -shift * mu, mode=True)
    if found is None:
        return None
    return found[0] / mu, found[1]


@dataclass
class Bifurcation:
    """The point where harmonic ``n`` loses stability on the axisymmetric path."""

    n: int
    u: np.ndarray
    p: float
    zeta: np.ndarray  # scaled measures
    mode: np.ndarray  # (nn, 3) critical mode, largest entry 1
    eig: float  # the eigenvalue there (~0)
    iterations: int


def locate_bifurcation(result, n: int, tol_eig: float = 1e-9, max_iter: int = 30) -> Bifurcation | None:
    """The bifurcation of harmonic ``n`` on the axisymmetric path before ``V*`` (``None`` if the
    harmonic stays stable up to it): the first path state whose ``K_n`` has a negative eigenvalue
    and the last stable one before it bracket it; the smallest eigenvalue's zero (``mu_min / L^2``
    units) is then found on that path step to ``tol_eig`` by
    :func:`snapjump_cli.fe.snap.root_on_step` (secant and Illinois steps, each point re-solved on the
    path)."""
    model, pts, st, tracer = result.model, result.path.points, result.states, result.tracer
    op = harmonic_operator(model, n)
    states = list(pts[: st.k_before + 1]) + [st.upper] if st.upper is not None else list(pts)
    prev = None
    for pt in states:
        if op.inertia(pt.u, pt.p) != 0:
            break
        prev = pt
    else:
        return None
    if prev is None:
        return None
    a, b = prev, pt
    k = next(i for i, q in enumerate(states) if q is a)
    a_prev = states[k - 1] if k > 0 else None
    cache: dict = {}

    def f(q: PathPoint) -> float:
        ev = lowest_eigen(op, q.u, q.p)
        if ev is None:
            return math.nan
        cache[id(q)] = ev
        return ev[0]

    if not (f(a) > 0.0 > f(b)):
        return None
    root = root_on_step(tracer, a, b, a_prev, f, tol_eig, max_iter)
    if id(root) not in cache:
        f(root)
    eig, mode = cache[id(root)]
    log.debug("bifurcation of harmonic %d at V = %.9g (scaled), eigenvalue %.2g", n, root.zeta[0], eig)
    return Bifurcation(n, np.array(root.u), float(root.p), np.array(root.zeta), mode, eig, len(cache))
def harmonic1_gauge(base, n: int, u: np.ndarray) -> list[tuple[int, int]]:
    """The ``(node, comp)`` amplitudes of harmonic 1 that the harmonic check's gauge fixes at the
    axisymmetric state ``u`` (the rigid translation and tilt of a free body); ``[]`` unless
    ``n == 1`` (a branch of ``n >= 2`` does not keep harmonic 1)."""
    if n != 1:
        return []
    op1 = harmonic_operator(base, 1)
    L = op1.layout
    gauge = []
    for d in op1.gauge_dofs(u):
        nodes, comps = np.nonzero((L.dofmap == d) & (L.coef > 0))
        gauge.append((int(nodes[0]), int(comps[0])))
    return gauge


@dataclass
class FoldJump:
    """A fold of a followed branch that the actuator jumps past before inflation goes on: the last
    path point before the fold (``k``), the fold (its upper state), the state it lands on at the
    fold's volume, and that state's path index when it is a path point (a restart from a lower
    state found off the branch) or ``None`` (a lower state on the path, between two points)."""

    k: int
    upper: PathPoint
    landing: PathPoint
    landing_index: int | None = None


@dataclass
class FollowResult:
    """A followed branch: its path (from the bifurcation), snap states and model."""

    bif: Bifurcation
    model: MultiHarmonicModel
    path: Path
    states: SnapStates
    tracer: Tracer
    kind: str  # "supercritical", "subcritical", "jump" (a jump off a branch, secondary.jump_off_branch) or ""
    first_kind: str = ""  # how the branch leaves the bifurcation (before folds traced through)
    lower_method: str = ""
    lower_note: str = ""
    failure: str = ""
    micro_folds: list = field(default_factory=list)  # (V, dE) of folds traced through (scaled)
    metrics: dict = field(default_factory=dict)
    #: for a branch that leaves another followed branch at a secondary bifurcation: that branch
    #: (traced up to its snap or its end) and the located point
    #: (:class:`snapjump_cli.fe.secondary.Secondary`)
    parent: "FollowResult | None" = None
    secondary: object = None
    #: the folds traced through on the way to the snap (:class:`FoldJump`, in path order)
    folds: list = field(default_factory=list)


def branch_curve(fr: FollowResult) -> dict:
    """The followed branch in SI units for plots: ``V_m3``, ``p_Pa`` per traced point (from the
    bifurcation; for a branch that left another at a secondary bifurcation, that branch up to it
    first, and ``n_sec``, ``V_sec_m3``; for a jump off a branch, that branch up to the fold, and
    ``n_sec``, ``landing_V_m3``, ``landing_p_Pa``: the state it lands on) and, for a snap, ``snap_V_m3`` / ``snap_p_Pa`` (upper
    state, the branch after it, lower state) and ``kind`` (that of the branch whose snap it is: the
    secondary branch's after a secondary bifurcation, where ``parent_kind`` is how the first branch
    left the axisymmetric path)."""
    mh, sc = fr.model, fr.tracer.sc
    L3, S = mh.L**3, mh.S
    pts = fr.path.points
    V = np.array([pt.zeta[0] * sc[0] for pt in pts]) * L3
    p = np.array([pt.p for pt in pts]) * S
    sec = fr.secondary
    jump = fr.kind == "jump"
    if fr.parent is not None and sec is not None:
        # the branch left behind: up to the secondary bifurcation, or (a jump) up to the fold, whose
        # state the jump's own path starts from
        head = fr.parent.path.points[: sec.index + 1] + ([] if jump else [sec.point])
        sp = fr.parent.tracer.sc
        V = np.concatenate([np.array([pt.zeta[0] * sp[0] for pt in head]) * L3, V])
        p = np.concatenate([np.array([pt.p for pt in head]) * S, p])
    parent_kind = (fr.parent.first_kind or fr.parent.kind) if fr.parent is not None else None
    out = {"V_m3": V, "p_Pa": p, "kind": fr.kind, "n": fr.bif.n, "N": int(mh.hn[-1]),
           "n_sec": sec.n if sec is not None else None,
           "V_sec_m3": sec.V_m3 if sec is not None and not jump else None,
           "parent_kind": parent_kind}
    if jump and sec is not None:  # the state the jump lands on, unstable outside the branch
        out["landing_V_m3"], out["landing_p_Pa"] = sec.V_m3, sec.p_Pa
    st = fr.states
    if st.upper is not None and st.lower is not None:
        seq = snap_sequence(fr.path, st)
        out["snap_V_m3"] = np.array([pt.zeta[0] * sc[0] for pt in seq]) * L3
        out["snap_p_Pa"] = np.array([pt.p for pt in seq]) * S
    return out


@dataclass
class BranchTracker(SnapTracker):
    """The snap tracker on a branch that starts at its bifurcation point: after the first step it
    tells a subcritical branch (the volume falls at once: the start is the volume limit) from a
    supercritical one (it rises, and the tracker finds the branch's own limit).

    A fold whose snap would release less than ``micro_dE`` (scaled energy) is not taken for the
    actuator's snap: the branch comes back to that volume with almost the same energy (a small
    dynamic jump, after which inflation goes on along the branch). It is recorded in
    ``micro_folds`` and the trace goes on to the branch's next volume limit.

    With ``mode_amplitude`` (state -> the amplitude of the critical mode) and ``asym_amplitude``
    (state -> the largest amplitude of any harmonic ``n >= 1``), the post-snap trace also stops
    when the branch passes back through the axisymmetric path: the critical mode's amplitude
    changes sign between two points at which every harmonic ``n >= 1`` is below ``REJOIN_FRAC`` of
    its largest amplitude on the branch. Beyond it the branch is the mirror image of the part already
    traced (a closed loop through the bifurcation, which would otherwise be traced round and
    round until the post-snap budget runs out) and cannot come back to ``V*`` any more than that
    part did."""

    kind: str = ""
    first_kind: str = ""  # the verdict of the first step (before any fold was traced through)
    micro_dE: float = 0.0
    micro_folds: list = field(default_factory=list)
    #: ``(k_before, upper, lower)`` of each micro-fold traced through (indices into this trace's path)
    fold_states: list = field(default_factory=list)
    mode_amplitude: Callable[[np.ndarray], float] | None = None
    asym_amplitude: Callable[[np.ndarray], float] | None = None
    _asym_max: float = 0.0
    _mode_sign: float = 0.0
    _asym_prev: float = math.inf

    def _rejoined(self, new: PathPoint) -> bool:
        """Whether the step to ``new`` passed back through the axisymmetric path (see the class)."""
        if self.mode_amplitude is None or self.asym_amplitude is None:
            return False
        a, m = self.asym_amplitude(new.u), self.mode_amplitude(new.u)
        small = max(a, self._asym_prev) < REJOIN_FRAC * self._asym_max
        crossed = self._mode_sign != 0.0 and m * self._mode_sign < 0.0 and small
        self._asym_max, self._asym_prev = max(self._asym_max, a), a
        if self._mode_sign == 0.0 and m != 0.0:
            self._mode_sign = math.copysign(1.0, m)
        return crossed

    def __call__(self, path: Path) -> str | None:
        pts = path.points
        rejoined = self._rejoined(pts[-1])
        if rejoined and self.states.upper is not None and self.states.lower is None:
            return "the branch passed back through the axisymmetric path"
        if len(pts) == 2 and not self.kind:
            a, b = pts
            if b.zeta[0] < a.zeta[0]:
                self.kind = "subcritical"
                self.states.k_before = 0
                self.states.upper = a
            else:
                self.kind = "supercritical"
            self.first_kind = self.kind
        reason = super().__call__(path)
        st = self.states
        if reason == "snap characterised" and self.micro_dE > 0:
            pb = self.tracer.pb
            dE = pb.energy(st.upper.u) - pb.energy(st.lower.u)
            if dE < self.micro_dE:
                self.micro_folds.append((float(st.upper.zeta[0]), float(dE)))
                self.fold_states.append((int(st.k_before), st.upper, st.lower))
                log.debug("branch: fold at V = %.9g releases %.3g < %.3g: traced on", st.upper.zeta[0], dE,
                          self.micro_dE)
                self.states = SnapStates(p_max=st.p_max)
                self.kind = "supercritical"
                return None
        return reason


#: A fold of a followed branch whose snap releases less than this fraction of the axisymmetric
#: snap's energy is traced through, not reported as the actuator's snap.
MICRO_FOLD_DE = 1e-2
#: :class:`BranchTracker`: "back on the axisymmetric path" means every harmonic ``n >= 1`` below
#: this fraction of its largest amplitude on the branch.
REJOIN_FRAC = 0.25
#: Step growth of the followed branch's continuation (the axisymmetric trace's is 1.6): on design B
#: and the Fig. S16 cap a third of the branch's Riks corrections failed at 1.6 and were cut back;
#: at 1.2 the branch takes 16-18 % fewer assemblies, with answers equal to 1.5e-13
#: (``python -m bench.follow_profile B --step-grow 1.6 1.2``).
FOLLOW_STEP_GROW = 1.2
#: Folds whose lower state, found off the branch, releases less than ``MICRO_FOLD_DE``: inflation
#: goes on from that lower state, at most this many times.
MAX_RESTARTS = 3


@dataclass
class ThroughFolds:
    """What :func:`trace_through_micro_folds` traced: the joined path, the last trace's tracker (its
    states indexed into the joined path), failure, lower state, every micro-fold ``(V, dE)`` and the
    number of restarts from an off-branch lower state."""

    path: Path
    tracker: "BranchTracker"
    failure: str
    lower: object
    micro_folds: list
    restarts: int
    first_kind: str
    folds: list = field(default_factory=list)  # every fold traced through (:class:`FoldJump`)


def trace_through_micro_folds(run: Callable, start: PathPoint, lower_state: Callable, energy: Callable,
                              restart_at: Callable, micro_dE: float, max_restarts: int = MAX_RESTARTS) -> ThroughFolds:
    """Trace a branch to its snap, going on past folds that release almost nothing.

    ``run(first) -> (path, tracker, failure)`` traces from ``first`` (a :class:`BranchTracker`
    stops it; folds whose lower state lies on the path and releases less than ``micro_dE`` are
    traced through there). When the trace's volume limit has its lower state off the path
    (``lower_state(tracker, path, why)``, :func:`snapjump_cli.fe.lower_state.find_lower_state`,
    method ``"descent"``) and that state releases ``0 < dE < micro_dE`` (``energy(u)``), the
    actuator makes a small dynamic jump to it and inflation goes on from there: ``run`` again from
    ``restart_at(lower state)``, at most ``max_restarts`` times. The path returned is the branch up
    to each such fold followed by the last trace, with the last tracker's indices shifted to it.
    """
    path, tracker, failure = run(start)
    first_kind, micro_folds = tracker.first_kind, list(tracker.micro_folds)
    kept: list[PathPoint] = []  # the branch before the restarts (up to each restart's fold)
    restarts, low = 0, None
    folds: list[FoldJump] = []
    off = 0  # where the current trace starts in the joined path
    while True:
        st = tracker.states
        low = lower_state(tracker, path, failure or path.stop_reason) if st.upper is not None else None
        if low is not None:
            st.lower, st.lower_method = low.state, low.method
        dE = energy(st.upper.u) - energy(low.state.u) if low is not None and low.state is not None else None
        if (restarts >= max_restarts or dE is None or low.method != "descent" or micro_dE <= 0.0
                or not 0.0 < dE < micro_dE):  # (dE <= 0: the search came back to the fold itself)
            break
        micro_folds.append((float(st.upper.zeta[0]), float(dE)))
        log.debug("branch: fold at V = %.9g whose lower state, off the branch, releases %.3g < %.3g: inflation "
                  "goes on from it", st.upper.zeta[0], dE, micro_dE)
        try:
            first = restart_at(low.state)
        except ContinuationFailed as exc:
            failure = f"no path from the lower state of a fold releasing {dE:.3g}: {exc}"
            break
        kept += path.points[: st.k_before + 1]
        folds += [FoldJump(k + off, up, lo) for k, up, lo in getattr(tracker, "fold_states", ()) if k <= st.k_before]
        folds.append(FoldJump(st.k_before + off, st.upper, first, len(kept)))  # lands on the restart's first point
        off = len(kept)
        restarts += 1
        path, tracker, failure = run(first)
        micro_folds += tracker.micro_folds
    if kept:  # one path: the branch up to each restart's fold, then the last trace
        offset = len(kept)
        path = Path(points=kept + path.points, n_newton=path.n_newton, n_rejected=path.n_rejected,
                    n_split=path.n_split, n_bifurcations=path.n_bifurcations, stop_reason=path.stop_reason)
        st = tracker.states
        for k in ("k_before", "k_return"):
            if getattr(st, k) is not None:
                setattr(st, k, getattr(st, k) + offset)
    st = tracker.states
    last = st.k_before if st.upper is not None and st.k_before is not None else len(path.points) - 1
    folds += [FoldJump(k + off, up, lo) for k, up, lo in getattr(tracker, "fold_states", ()) if k + off <= last]
    return ThroughFolds(path, tracker, failure, low, micro_folds, restarts, first_kind, folds)


def tracker_bounds(result, post_snap_steps: int | None = None) -> tuple[float, float, int]:
    """``(p_stop, V_stop, post_snap_steps)`` of a multi-harmonic trace from the axisymmetric solve
    ``result``: those of its own tracker (``result.stop_args``), or bounds from its path (1.5 times
    its largest pressure, 30 times its largest volume, 1500 post-snap steps) when it has none;
    ``post_snap_steps`` overrides the budget."""
    stop = getattr(result, "stop_args", None) or {}
    p_stop = stop.get("p_stop", 1.5 * max(pt.p for pt in result.path.points))
    V_stop = stop.get("V_stop", 30.0 * max(pt.zeta[0] for pt in result.path.points))
    post = post_snap_steps if post_snap_steps is not None else stop.get("post_snap_steps", 1500)
    return p_stop, V_stop, post


def micro_energy(result, micro: float) -> float:
    """The scaled energy below which a fold's snap is a micro-fold: ``micro`` times the axisymmetric
    snap's energy of ``result`` (0 when it has no snap)."""
    st0 = result.states
    if st0 is None or st0.upper is None or st0.lower is None:
        return 0.0
    return micro * (result.model.energy(st0.upper.u) - result.model.energy(st0.lower.u))


def follow_branch(result, bif: Bifurcation, hn: list[int] | None = None, n_phi: int | None = None,
                  micro: float = MICRO_FOLD_DE, max_steps: int | None = None,
                  step_grow: float = FOLLOW_STEP_GROW) -> FollowResult:
    """Trace the branch of ``bif`` with the harmonics ``hn`` (default :func:`default_harmonics`)
    from the bifurcation through its volume limit to the lower state at that volume.

    Parameters
    ----------
    result : the axisymmetric :class:`snapjump_cli.fe.solve.SceneResult`
    bif : :func:`locate_bifurcation`'s answer
    hn, n_phi : harmonics and phi rule of the :class:`MultiHarmonicModel`
    micro : a fold of the branch releasing less than this fraction of the axisymmetric snap's
        energy is traced through (``micro_folds``), not reported as the snap
    max_steps : bound on the branch's continuation steps (default: the axisymmetric trace's)
    step_grow : the continuation's step growth (:data:`FOLLOW_STEP_GROW`)

    Returns
    -------
    FollowResult
        with ``kind`` and ``metrics`` (:func:`followed_metrics`'s keys without the axisymmetric ones)
    """
    t0 = time.perf_counter()
    base = result.model
    hn = default_harmonics(bif.n) if hn is None else list(hn)
    mh = MultiHarmonicModel(base, hn, n_phi=n_phi, gauge=harmonic1_gauge(base, bif.n, bif.u))
    U_c = mh.embed(bif.u)
    Phi = mh.embed(np.zeros(base.n), {bif.n: bif.mode})
    fr = trace_branch(result, bif, mh, U_c, bif.p, Phi, [int(n) for n in mh.hn[1:]], micro=micro,
                      max_steps=max_steps, step_grow=step_grow)
    fr.metrics["follow_wall_s"] = time.perf_counter() - t0
    return fr


def trace_branch(result, bif: Bifurcation, mh: MultiHarmonicModel, U_c: np.ndarray, p_c: float, Phi: np.ndarray,
                 asym_harmonics: list[int], micro: float = MICRO_FOLD_DE, max_steps: int | None = None,
                 step_grow: float = FOLLOW_STEP_GROW) -> FollowResult:
    """Trace the branch of the model ``mh`` that leaves the equilibrium ``(U_c, p_c)`` along
    ``Phi`` (a bifurcation point and its critical mode, as free vectors of ``mh``) through its volume
    limit to the lower state at that volume (:func:`follow_branch` for a branch of the axisymmetric
    path, :func:`snapjump_cli.fe.secondary.follow_secondary` for one of a followed branch).

    ``asym_harmonics``: the harmonics whose amplitudes measure the distance from the branch left
    behind (the post-snap trace stops when it passes back through it: :class:`BranchTracker`);
    ``bif``: the bifurcation from the axisymmetric path that the answer is reported under; the
    other parameters as in :func:`follow_branch`.
    """
    tr0 = result.tracer
    cfg = replace(tr0.cfg, fused=False, mixed_tangent=False, step_grow=float(step_grow))
    if max_steps is not None:
        cfg = replace(cfg, max_steps=int(max_steps))
    tr = Tracer(mh, cfg)
    alpha = tr.alpha
    if alpha <= 0.0:
        raise ValueError("following a branch needs u_scale > 0 (the arc length must see the displacement)")
    du_ds = Phi / (alpha * float(np.linalg.norm(Phi)))
    z_c = tr.zeta(U_c, p_c)[0]
    start = PathPoint(U_c, p_c, z_c, np.zeros(len(z_c)), du_ds, 0.0, 0.0)
    sc = tr0.sc
    p_stop, V_stop, post = tracker_bounds(result)
    micro_dE = micro_energy(result, micro)
    phi_unit = Phi / float(np.linalg.norm(Phi))
    amplitudes = {
        "mode_amplitude": lambda u: float(u @ phi_unit),
        "asym_amplitude": lambda u: max(float(np.abs(mh.harmonic_part(u, int(n))).max()) for n in asym_harmonics),
    }

    def run(first: PathPoint, kind: str) -> tuple[Path, BranchTracker, str]:
        tk = BranchTracker(tr, p_stop=p_stop, V_stop=V_stop, post_snap_steps=post, kind=kind, micro_dE=micro_dE,
                           **amplitudes)
        try:
            return trace(mh, cfg, tk, tracer=tr, start=first), tk, ""
        except ContinuationFailed as exc:
            return getattr(exc, "path", None) or Path(points=[first]), tk, str(exc)

    def lower_state(tk: BranchTracker, pth: Path, why: str):
        low = find_lower_state(tr, tk.states, pth.points, why)
        up = tk.states.upper
        if up is not None and (low.state is None or (low.method == "descent"
                                                      and mh.energy(up.u) - mh.energy(low.state.u) <= 0.0)):
            # the search found nothing below the fold: the axisymmetric path's state at that volume,
            # if it is stable there (a loop of the branch through the bifurcation folds over a part
            # of the axisymmetric path that is stable again)
            alt = axisym_state_at(result, mh, tr, float(up.zeta[0]))
            if alt is not None and mh.energy(up.u) - mh.energy(alt.u) > 0.0:
                return replace(low, state=alt, method="descent", solver="axisymmetric path",
                               message=f"{low.message}; the axisymmetric path's state at that volume, stable")
        return low

    tb = trace_through_micro_folds(
        lambda first: run(first, "supercritical" if first is not start else ""), start, lower_state, mh.energy,
        lambda state: start_point(tr, state.u, state.p), micro_dE)
    path, tracker, failure, low, micro_folds = tb.path, tb.tracker, tb.failure, tb.lower, tb.micro_folds
    st = tracker.states
    kind = (tracker.kind if not tb.restarts else "supercritical") if st.upper is not None else ""
    first_kind = tb.first_kind
    fr = FollowResult(bif, mh, path, st, tr, kind, first_kind, failure=failure, micro_folds=micro_folds,
                      folds=tb.folds)
    if st.upper is not None and low is not None:
        fr.lower_method, fr.lower_note = low.method, low.note or low.message
    fr.metrics = _branch_metrics(fr, sc)
    mh.release_buffers()  # the result keeps the model (plots, shapes): not its ~60 MB of band buffers
    return fr


def axisym_state_at(result, mh: MultiHarmonicModel, tr: Tracer, V: float) -> PathPoint | None:
    """The axisymmetric path's state at scaled volume ``V`` (before its volume limit) as a state of
    the multi-harmonic model ``mh`` (traced by ``tr``), if it is stable there under volume control
    within ``mh``'s harmonics; else ``None``."""
    st0 = result.states
    pts = result.path.points[: (st0.k_before if st0 is not None and st0.k_before is not None else
                                len(result.path.points) - 1) + 1]
    locate = SnapTracker(result.tracer, p_stop=math.inf, V_stop=math.inf)
    for k in range(1, len(pts)):
        a, b = pts[k - 1], pts[k]
        if a.zeta[0] < V <= b.zeta[0]:
            q = locate.locate_volume(a, b, V, pts[k - 2] if k > 1 else None)
            if q is None:
                return None
            U = mh.embed(q.u)
            lin = mh.linearize(U, q.p)
            if lin is None or constrained_instability(tr, lin) != 0:
                return None
            try:
                return start_point(tr, U, q.p)
            except ContinuationFailed:
                return None
    return None


def _pole_height(mh: MultiHarmonicModel, u: np.ndarray, node: int) -> float:
    return float(mh.section(u, 0.0)[node, 1])


def ground_height(mh: MultiHarmonicModel, u: np.ndarray, nodes: np.ndarray, n_phi: int = 720) -> float:
    """Lowest height of ``nodes`` over all phi (scaled): ``z + sum_k b_k cos n_k phi``."""
    from snapjump_cli.fe.multiharmonic import component_index

    A = mh.total_amplitudes(u)
    phi = np.linspace(0.0, 2.0 * np.pi, n_phi, endpoint=False)
    z = np.repeat(mh.X[nodes, 1][:, None], n_phi, axis=1)
    for k, n in enumerate(mh.hn):
        z += A[nodes, component_index(k, 1)][:, None] * np.cos(n * phi)[None, :]
    return float(z.min())


def _branch_metrics(fr: FollowResult, sc: np.ndarray) -> dict:
    """The followed snap's metrics (SI)."""
    mh, st = fr.model, fr.states
    L, S = mh.L, mh.S
    out = {"follow_kind": fr.kind or None, "follow_N": int(mh.hn[-1]), "follow_n": fr.bif.n,
           "follow_V_bif_m3": float(fr.bif.zeta[0] * sc[0] * L**3), "follow_p_bif_Pa": float(fr.bif.p * S),
           "follow_lower_method": fr.lower_method or None,
           "follow_note": "; ".join(x for x in (fr.failure, fr.lower_note, (
               f"{len(fr.micro_folds)} fold(s) releasing < {MICRO_FOLD_DE:g} of the axisymmetric dE traced through"
               if fr.micro_folds else "")) if x),
           "snaps": st.upper is not None and st.lower is not None, "follow_micro_folds": len(fr.micro_folds)}
    out.update(multiharmonic_snap_metrics(mh, fr.path, st, sc))
    return out


def multiharmonic_snap_metrics(mh: MultiHarmonicModel, path: Path, st: SnapStates, sc: np.ndarray) -> dict:
    """The snap metrics (SI) of a path of the multi-harmonic model with its upper and lower states
    (``{}`` without both): ``dE_J`` two ways, ``V_star_m3``, ``p_star_Pa``, ``dy_pole_m`` (the
    pole's travel along the axis), ``h_imp_m`` (the pole above the lowest point of the ground ring
    over all phi), ``L0_m``, and ``follow_amplitude_m`` (the largest harmonic amplitude ``n >= 1``
    at the upper state). Definitions: docs/harmonics.md section 10.2."""
    if st.upper is None or st.lower is None:
        return {}
    L, S = mh.L, mh.S
    E_unit = S * L**3
    out: dict = {}
    up, lo = st.upper, st.lower
    W_up, W_lo = mh.energy(up.u), mh.energy(lo.u)
    dE = W_up - W_lo
    dE_path = -path_p_dV(snap_sequence(path, st), sc[0], sc[1]) if st.lower_method == "path" else math.nan
    mesh = mh.mesh
    pole1 = int(mesh.node_sets["pole_lower"][0])
    out.update(
        dE_J=dE * E_unit, dE_energy_J=dE * E_unit,
        dE_path_J=dE_path * E_unit if math.isfinite(dE_path) else None,
        follow_dE_rel_diff=abs(dE - dE_path) / max(abs(dE), 1e-300) if math.isfinite(dE_path) else None,
        V_star_m3=float(up.zeta[0] * sc[0] * L**3), p_star_Pa=float(up.p * S),
        dy_pole_m=(_pole_height(mh, up.u, pole1) - _pole_height(mh, lo.u, pole1)) * L,
        p_lower_Pa=float(lo.p * S), dE_norm=dE, lower_state_method=st.lower_method or None,
    )
    out["dE_rel_diff"] = out["follow_dE_rel_diff"]
    out["dy_pole_norm"] = out["dy_pole_m"] / L
    nsets = mesh.node_sets
    if "pole_upper" in nsets:
        pole2 = int(nsets["pole_upper"][0])
        out["dy_pole_upper_m"] = (_pole_height(mh, up.u, pole2) - _pole_height(mh, lo.u, pole2)) * L
        if "outer_pole_lower" in nsets:
            z = mh.section(up.u, 0.0)[:, 1] * L
            out["L0_m"] = float(0.5 * (z[nsets["outer_pole_lower"][0]] + z[nsets["outer_pole_upper"][0]])
                                - 0.5 * (z[pole1] + z[pole2]))
    if "ground" in mesh.node_sets and len(mesh.node_sets["ground"]):
        g = np.asarray(mesh.node_sets["ground"], np.int64)
        out["h_imp_m"] = (_pole_height(mh, up.u, pole1) - ground_height(mh, up.u, g)) * L
    # how far the branch is from axisymmetric at the upper state: the largest harmonic amplitude
    amp = 0.0
    for n in mh.hn[1:]:
        amp = max(amp, float(np.abs(mh.harmonic_part(up.u, int(n))).max()))
    out["follow_amplitude_m"] = amp * L
    return out


def _axisym_answer(m: dict, note: str = "") -> dict:
    """The follow keys of a design that keeps its axisymmetric answer (``m``: its metrics)."""
    out = {k: None for k in FOLLOW_KEYS}
    out.update({"axisym_" + k: m.get(k) for k in ("dE_J", "dy_pole_m", "h_imp_m", "V_star_m3", "p_star_Pa")})
    out.update(followed=False, follow_note=note)
    return out


def followed_metrics(result, check: dict, N: int | None = None, n_phi: int | None = None,
                     secondary: bool = True) -> tuple[dict, FollowResult | None]:
    """The design's answer with the followed branch (the keys of :data:`FOLLOW_KEYS` and the
    followed ``dE_J``, ``dy_pole_m``, ``h_imp_m``, ``V_star_m3``, ``p_star_Pa``), given the
    axisymmetric ``result`` and its harmonic ``check``.

    A design whose check finds no harmonic unstable before ``V*`` keeps its axisymmetric answer
    (``followed`` False, the two sets equal). Otherwise the branch of the first unstable harmonic
    is traced; if it cannot be followed to a snap the axisymmetric answer is kept and
    ``follow_note`` says why. With ``secondary``, a branch that keeps only multiples of
    ``n_c >= 2`` is checked against the other harmonics up to its snap
    (:func:`snapjump_cli.fe.secondary.follow_secondary`); where it loses stability to them first,
    the branch that leaves it there is traced with every harmonic and its snap is the answer
    (``follow_sec_n``, ``follow_sec_V_m3``).
    """
    m = result.metrics
    out = _axisym_answer(m)
    if not check.get("asym_first") or result.states is None or result.states.upper is None:
        return out, None
    t0 = time.perf_counter()
    n = int(check["asym_n"])
    bif = locate_bifurcation(result, n)
    if bif is None:
        out["follow_note"] = f"bifurcation of harmonic {n} not located"
        return out, None
    fr = follow_branch(result, bif, default_harmonics(n, N), n_phi=n_phi)
    note_sec = ""
    if secondary and len(fr.model.hn) > 1 and int(fr.model.hn[1]) > 1:
        fr, note_sec = _leave_at_secondary(result, fr)
    fm = fr.metrics
    out.update({k: v for k, v in fm.items() if k in FOLLOW_KEYS})
    if note_sec:
        out["follow_note"] = "; ".join(x for x in (note_sec, out.get("follow_note")) if x)
    if fm.get("dE_J") is None:
        out["follow_note"] = out.get("follow_note") or "the followed branch did not reach a snap"
        out["follow_wall_s"] = time.perf_counter() - t0
        return out, fr
    dE_axi = m.get("dE_J")
    if dE_axi and fm["dE_J"] < MICRO_FOLD_DE * dE_axi:
        # a fold whose lower state was found off the branch (so the tracker could not trace through
        # it) and that releases almost nothing: the actuator goes on along the branch to a later
        # snap that was not traced, so this is not the design's answer
        out["follow_note"] = "; ".join(x for x in (out.get("follow_note"), (
            f"the branch's first fold releases {fm['dE_J']:.3g} J, < {MICRO_FOLD_DE:g} of the axisymmetric "
            "dE: not the snap, and the branch beyond it was not traced")) if x)
        out["follow_wall_s"] = time.perf_counter() - t0
        return out, fr
    if fm.get("dy_pole_m") is not None and not fm["dy_pole_m"] > 0.0:
        # the pole moves up in the followed snap: no jump the mass-spring model can describe (a sweep
        # row with it fails its range check and would lose the axisymmetric answer as well)
        out["follow_note"] = "; ".join(x for x in (out.get("follow_note"), (
            f"the followed snap moves the pole up (dy_pole {fm['dy_pole_m']:.3g} m, dE {fm['dE_J']:.3g} J): "
            "not used as the answer")) if x)
        out["follow_wall_s"] = time.perf_counter() - t0
        return out, fr
    out["followed"] = True
    for k in fm:
        if k not in out or k in _REPLACED:
            out[k] = fm[k]
    out["follow_wall_s"] = time.perf_counter() - t0
    return out, fr


def _leave_at_secondary(result, fr: FollowResult) -> tuple[FollowResult, str]:
    """The branch the actuator takes when the followed branch ``fr`` loses stability outside its
    harmonics before its snap (:func:`snapjump_cli.fe.secondary.follow_secondary`), with a note;
    ``fr`` itself (and no note) when it does not. A secondary branch that cannot be traced to a
    snap is returned all the same: the design then keeps its axisymmetric answer."""
    from snapjump_cli.fe.secondary import follow_secondary

    fs, chk, sec = follow_secondary(result, fr)
    if chk.first is None:
        return fr, ""
    n = fr.bif.n
    if sec is None:
        V1 = chk.first_V_m3 if chk.first_V_m3 is not None else chk.V_m3[chk.first]
        fr.metrics.update(dE_J=None, follow_sec_V_m3=V1)
        return fr, (f"the branch of harmonic {n} is unstable outside its harmonics at V = {V1:.4g} m^3 "
                    f"(harmonics up to {chk.N}) and no secondary bifurcation was located before it (the actuator "
                    "may reach that state by a jump past a fold of the branch): not traced further")
    fs.metrics.update(follow_sec_n=sec.n, follow_sec_V_m3=sec.V_m3, follow_sec_p_Pa=sec.p_Pa)
    if fs.kind == "jump":
        return fs, (f"the branch of harmonic {n} folds at V = {fs.metrics.get('V_star_m3') or math.nan:.4g} m^3 and "
                    f"the state it jumps to on the branch is unstable in harmonic {sec.n}: the jump goes on, at "
                    f"that volume, to a state with every harmonic 0-{chk.N} (energy descent)")
    return fs, (f"the branch of harmonic {n} loses stability to harmonic {sec.n} at V = {sec.V_m3:.4g} m^3, "
                f"before its own snap: the branch that leaves it there is traced with harmonics 0-{chk.N}")


#: The row keys a followed answer replaces (the axisymmetric values of the first five stay in
#: ``axisym_*``).
_REPLACED = ("dE_J", "dE_norm", "dE_energy_J", "dE_path_J", "dE_rel_diff", "dy_pole_m", "dy_pole_norm",
             "dy_pole_upper_m", "h_imp_m", "V_star_m3", "p_star_Pa", "p_lower_Pa", "L0_m", "lower_state_method")


def apply_followed(result, check: dict, N: int = 0) -> None:
    """Follow the branch of ``result`` (a :class:`snapjump_cli.fe.solve.SceneResult` with its harmonic
    ``check``) and make its snap the design's answer in ``result.metrics`` (the keys of
    :data:`snapjump_cli.sweep.rows.FOLLOW_ROW_KEYS`; the replaced keys of a followed design describe the
    followed snap). A design that stays axisymmetric, or whose branch cannot be followed to a snap,
    keeps its axisymmetric answer (``followed`` False; ``follow_note`` says why)."""
    from snapjump_cli.fe.limits import TimeLimitExceeded

    m = result.metrics
    t0 = time.perf_counter()
    try:
        out, fr = followed_metrics(result, check, N=N or None)
    except TimeLimitExceeded as exc:  # keep the axisymmetric answer, say why
        out = _axisym_answer(m, f"branch not followed to its snap: {exc}")
        out["follow_n"] = check.get("asym_n")
        fr = None
    result.follow = fr
    m.update({k: out.get(k) for k in FOLLOW_KEYS})
    m["follow_amplitude_m"] = out.get("follow_amplitude_m")
    if out["followed"]:
        for k in _REPLACED:
            if k in out:
                m[k] = out[k]
    m["wall_s"] = (m.get("wall_s") or 0.0) + (time.perf_counter() - t0)

