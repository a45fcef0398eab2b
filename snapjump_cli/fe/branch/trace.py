"""Follow the branch that bifurcates from the axisymmetric path, up to its own snap (docs/harmonics.md, section 10).

Given the bifurcation (:mod:`snapjump_cli.fe.branch.bifurcation`), this module

1. builds the :class:`~snapjump_cli.fe.branch.model.MultiHarmonicModel` with the harmonics
   ``0, n_c, 2 n_c, ..., N`` (default ``N = 4 n_c``);
2. leaves the path along the mode: the first Riks step starts at the bifurcation state with the
   mode as its tangent, so its hyperplane fixes the mode's amplitude and excludes the
   axisymmetric path (Newton converges there because the branch is a symmetric pitchfork: the
   mode's cubic term averages to zero over phi);
3. traces the bifurcated branch under volume control with the same continuation and snap tracker
   as the axisymmetric path, through its own limit points, to its volume limit and back to it
   (:class:`BranchTracker`; folds that release almost nothing are traced through:
   :func:`trace_through_micro_folds`). Whether the branch rises in volume (supercritical: its own
   limit comes later) or turns back at once (subcritical: the bifurcation point is the volume
   limit, and the actuator snaps there) is read off the traced branch, not assumed;
4. finds the lower state at that volume as the axisymmetric solve does
   (:func:`snapjump_cli.fe.axisym.lower_state.find_lower_state`, on the branch or off it at fixed
   volume), and computes the metrics (:func:`branch_metrics`, with
   :mod:`snapjump_cli.fe.branch.metrics`).

:func:`trace_branch` is also what traces a branch that leaves a followed branch at a secondary
bifurcation (:mod:`snapjump_cli.fe.branch.secondary`).
"""
from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field, replace
from typing import Callable, Iterator

import numpy as np

from snapjump_cli.fe.axisym.lower_state import LowerState, constrained_instability, find_lower_state
from snapjump_cli.fe.axisym.snap import SnapStates, SnapTracker
from snapjump_cli.fe.axisym.sphere_path import NOT_FALLING
from snapjump_cli.fe.branch.bifurcation import Bifurcation, default_harmonics, harmonic1_gauge
from snapjump_cli.fe.branch.landing import land_from_bifurcation, sphere_landing
from snapjump_cli.fe.branch.metrics import AXISYM_LANDING, AXISYM_LOWER_LANDING, multiharmonic_snap_metrics
from snapjump_cli.fe.branch.model import MultiHarmonicModel
from snapjump_cli.fe.continuation import ContinuationFailed, Path, PathPoint, Tracer, start_point, trace
from snapjump_cli.fe.stability.harmonics import unstable_harmonics

log = logging.getLogger(__name__)

__all__ = ["FoldJump", "FollowResult", "BranchTracker", "MICRO_FOLD_DE", "REJOIN_FRAC", "FOLLOW_STEP_GROW",
           "FIRST_STEP_HALVINGS", "PROBE_HALVINGS",
           "MAX_RESTARTS", "ThroughFolds", "trace_through_micro_folds", "tracker_bounds", "micro_energy",
           "follow_branch", "trace_branch", "axisym_crossings", "UNSTABLE_OUTSIDE", "axisym_state_at", "axisym_landing", "axisym_lower_landing", "axisym_inverted_state", "AXISYM_BEFORE_DESCENT", "branch_metrics", "REJOINED",
           "LANDINGS"]


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
    lower_solver: str = ""  # off the branch: "volume-path", "sphere-path" or "energy-descent" (as LowerState.solver), where set
    lower_note: str = ""
    failure: str = ""
    micro_folds: list = field(default_factory=list)  # (V, dE) of folds traced through (scaled)
    metrics: dict = field(default_factory=dict)
    #: for a branch that leaves another followed branch at a secondary bifurcation: that branch
    #: (traced up to its snap or its end) and the located point
    #: (:class:`snapjump_cli.fe.branch.secondary.Secondary`)
    parent: "FollowResult | None" = None
    secondary: object = None
    #: the folds traced through on the way to the snap (:class:`FoldJump`, in path order)
    folds: list = field(default_factory=list)
    #: the ``watch`` of the trace (what it computed is reused by the check)
    watch: object = None
    #: the ``settle`` check of the trace's micro-fold landings (what it computed is reused by the check)
    settle: object = None
    #: the branch turned by ``pi / n_c`` about the axis (its states, the actuator's, are those of
    #: a branch whose perturbations symmetric about ``phi = pi / n_c`` went unstable first)
    turned: bool = False


@dataclass
class BranchTracker(SnapTracker):
    """The snap tracker on a branch that starts at its bifurcation point: after the first step it
    tells a subcritical branch (the volume falls at once: the start is the volume limit) from a
    supercritical one (it rises, and the tracker finds the branch's own limit). The volume along a
    branch off the axisymmetric path is even in the arc length (``V_b + b s^2``: the mode and its
    negative are the same state turned by ``pi / n``), so the first step is subcritical where its
    end point's volume lies below the start's or, with :data:`FIRST_STEP_SLOPE`, where the volume
    falls there (the tangent's volume component is negative): the start's volume carries the
    bifurcation's location error, which can exceed ``|b| s^2`` of a short first step.

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
    part did.

    With ``stop_at_upper`` the trace stops at the branch's first volume limit (its upper state)
    without searching its lower state: the states the actuator passes through before it, which
    is all a check of the branch against other harmonics needs (:mod:`snapjump_cli.fe.branch.followed`).
    With ``watch`` (path -> bool, called after every accepted step before a volume limit) the
    trace, up to the upper state or through the folds that release almost nothing, also stops
    where ``watch`` says a state is unstable outside the branch's harmonics
    (:data:`UNSTABLE_OUTSIDE`): the actuator leaves the branch there."""

    kind: str = ""
    first_kind: str = ""
    stop_at_upper: bool = False  # the verdict of the first step (before any fold was traced through)
    micro_dE: float = 0.0
    micro_folds: list = field(default_factory=list)
    #: ``(k_before, upper, lower)`` of each micro-fold traced through (indices into this trace's path)
    fold_states: list = field(default_factory=list)
    mode_amplitude: Callable[[np.ndarray], float] | None = None
    asym_amplitude: Callable[[np.ndarray], float] | None = None
    watch: Callable[[Path], bool] | None = None
    #: (state -> bool) a micro-fold traced through whose landing this says the actuator leaves at
    #: once (off the branch) ends the trace there (:data:`LEFT_AT_LANDING`; ``follow_branch(settle=...)``)
    settle: Callable[[PathPoint], bool] | None = None
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
            return REJOINED
        if len(pts) == 2 and not self.kind:
            a, b = pts
            if b.zeta[0] < a.zeta[0] or (FIRST_STEP_SLOPE and b.tangent[0] < 0.0):
                self.kind = "subcritical"
                self.states.k_before = 0
                self.states.upper = a
            else:
                self.kind = "supercritical"
            self.first_kind = self.kind
            log.debug("branch: first step V %.10g -> %.10g, dV/ds %.3g at its end: %s", a.zeta[0], b.zeta[0],
                      b.tangent[0], self.kind)
        reason = super().__call__(path)
        st = self.states
        if reason is None and self.stop_at_upper and st.upper is not None and st.lower is None:
            return UPPER_LOCATED
        if reason is None and st.upper is None and self.watch is not None and self.watch(path):
            return UNSTABLE_OUTSIDE
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
                if self.settle is not None and self.settle(st.lower):
                    return LEFT_AT_LANDING
                return None
        return reason


#: The stop reason of a branch whose trace reached the landing of a micro-fold that the actuator
#: leaves at once, off the branch (:class:`BranchTracker`'s ``settle``).
LEFT_AT_LANDING = "the landing of a fold releasing almost nothing is unstable outside the branch"


#: The stop reason of a branch that passed back through the axisymmetric path (:class:`BranchTracker`).
REJOINED = "the branch passed back through the axisymmetric path"


#: The stop reason of a branch traced only up to its upper state (``BranchTracker.stop_at_upper``).
UPPER_LOCATED = "upper state located; the branch beyond it not traced"


#: The stop reason of a branch traced up to its upper state whose ``watch`` found a state unstable
#: outside the branch's harmonics before it (:class:`BranchTracker`).
UNSTABLE_OUTSIDE = "a state unstable outside the branch's harmonics; the branch beyond it not traced"


#: How a branch's lower state is found (:func:`trace_branch`'s ``landing``): the reference search
#: after the whole branch is traced, the axisymmetric path's state first, or (for a subcritical
#: branch) the energy descent from the bifurcation first.
LANDINGS = ("search", "axisymmetric first", "descent first")


#: A fold of a followed branch whose snap releases less than this fraction of the axisymmetric
#: snap's energy is traced through, not reported as the actuator's snap.
MICRO_FOLD_DE = 1e-2


#: :class:`BranchTracker` tells a subcritical branch also by the volume's slope at the end of its
#: first step (the path tangent's volume component below zero), not only by that step's volume
#: against the bifurcation's (see the class). On ``follow_strata_n2`` rows 0, 1 and 16 the first
#: step (``ds0 / 128``) ended 3e-8 above the located bifurcation's volume (located ~3e-7 low) with
#: the volume already falling (``bench.profile.follow ... --debug snapjump_cli.fe.branch.trace``): taken for supercritical, the branch's loop below the bifurcation's
#: volume was traced (26-27 points) up to a state unstable outside the branch; told subcritical,
#: the jump at the bifurcation is landed as on the other 13 such rows: 40 -> 36, 46 -> 42 and
#: 40 -> 38 assemblies of the model with every harmonic, the followed CPU 12-20 % less, every answer
#: value within 1.5e-6 (the fold's volume moves by ~1e-8); the other 45 designs of both samples bit
#: for bit (``bench.profile.follow --json`` of both samples, again with ``--set
#: snapjump_cli.fe.branch.trace.FIRST_STEP_SLOPE=False``, compared by ``bench.profile.answers``).
FIRST_STEP_SLOPE = True


#: :class:`BranchTracker`: "back on the axisymmetric path" means every harmonic ``n >= 1`` below
#: this fraction of its largest amplitude on the branch.
REJOIN_FRAC = 0.25


#: Step growth of the followed branch's continuation (the axisymmetric trace's is 1.6): on design B
#: and the Fig. S16 cap a third of the branch's Riks corrections failed at 1.6 and were cut back;
#: at 1.2 the branch takes 16-18 % fewer assemblies, with answers equal to 1.5e-13
#: (``bench/follow_profile.py@51d9ff8 B --step-grow 1.6 1.2``). With the mixed Newton matrix 1.6 takes
#: fewer on the branch itself (design B's whole branch 122 -> 109 assemblies in ``follow_mode:
#: full``), but a secondary point then lies on a longer step and its root finding takes more
#: eigen-solves of the model with every harmonic (``follow_strata`` rows 8 and 9: 8-12 % more CPU),
#: and the branches the actuator mode still traces on ``follow_strata_n2`` gain ~3 %: kept at 1.2
#: (scratch runs with this constant changed).
FOLLOW_STEP_GROW = 1.2

#: A branch's first step off its bifurcation starts at ``ds0`` halved this many times: from ``ds0``
#: Newton failed 6 to 9 times before that step converged on each of the 48 branches of the
#: ``follow_strata`` and ``follow_strata_n2`` samples (the corrector's basin shrinks towards the
#: pitchfork; at ``ds0 / 2**7`` on 33 of them, ``ds0 / 2**6`` on 3, down to ``ds0 / 2**9``; a
#: scratch count of each branch's first accepted step), each failure 1-3 assemblies. Starting at the largest step that converged there skips only steps
#: that failed: those 48 branches are traced as before, bit for bit (a branch whose first step
#: would converge longer now starts shorter).
FIRST_STEP_HALVINGS = 6

#: Where a branch is only probed for sub- or supercritical (one step, the sign of its volume: the
#: actuator mode's landings from the bifurcation), the step's length does not enter the answer,
#: and the probe starts at the smallest of those steps, where each of the 48 converged at once.
PROBE_HALVINGS = 9

#: The branch's Newton corrector linearises with the element pressures of the three-field
#: problem (:meth:`MultiHarmonicModel.linearize`'s ``aux``: extrapolated along the branch, then
#: updated linearly), as the axisymmetric trace does; ``False``: with the condensed pressures of
#: each iterate (the reduced tangent). The same states; on the stratified ``n = 1`` sample the
#: branch takes 2-2.6x fewer assemblies (docs/harmonics.md section 10.4).
MIXED_TANGENT = True


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
    (``lower_state(tracker, path, why)``, :func:`snapjump_cli.fe.axisym.lower_state.find_lower_state`,
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
                  step_grow: float = FOLLOW_STEP_GROW, stop_at_upper: bool = False,
                  landing: str = "search", volume_path: bool = True,
                  watch: Callable[[MultiHarmonicModel], Callable[[Path], bool]] | None = None,
                  settle: Callable[[MultiHarmonicModel], Callable[[PathPoint], bool]] | None = None,
                  landing_check: Callable[[MultiHarmonicModel], Callable[[PathPoint], bool]] | None = None
                  ) -> FollowResult:
    """Trace the branch of ``bif`` with the harmonics ``hn`` (default :func:`default_harmonics`)
    from the bifurcation through its volume limit to the lower state at that volume (with
    ``stop_at_upper``: only up to its first volume limit, :class:`BranchTracker`).

    Parameters
    ----------
    result : the axisymmetric :class:`snapjump_cli.fe.solve.SceneResult`
    bif : :func:`locate_bifurcation`'s answer
    hn, n_phi : harmonics and phi rule of the :class:`MultiHarmonicModel`
    micro : a fold of the branch releasing less than this fraction of the axisymmetric snap's
        energy is traced through (``micro_folds``), not reported as the snap
    max_steps : bound on the branch's continuation steps (default: the axisymmetric trace's)
    step_grow : the continuation's step growth (:data:`FOLLOW_STEP_GROW`)
    landing, volume_path : how the lower state is found (:func:`trace_branch`)
    watch : made from the branch's model: stops the trace at a state it finds unstable outside the
        branch's harmonics (:class:`BranchTracker`), with ``stop_at_upper`` before the upper state,
        else before the snap (the first trace; not one restarted from a fold's landing)
    settle : made from the branch's model (state -> bool): where the state a fold that releases
        almost nothing lands on is one the actuator does not stay on (unstable outside the
        branch's harmonics: the jump goes on off the branch), the branch beyond it is not traced;
        the path then ends at that state, without a snap of its own (:func:`trace_through_micro_folds`)
    landing_check : made from the branch's model: whether a state of it is stable with every harmonic,
        which the axisymmetric inverted state must be for a branch that loops back to the axisymmetric
        path (:func:`trace_branch`)

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
                      max_steps=max_steps, step_grow=step_grow, stop_at_upper=stop_at_upper, landing=landing,
                      volume_path=volume_path, watch=watch, settle=settle, landing_check=landing_check)
    fr.metrics["follow_wall_s"] = time.perf_counter() - t0
    return fr


def trace_branch(result, bif: Bifurcation, mh: MultiHarmonicModel, U_c: np.ndarray, p_c: float, Phi: np.ndarray,
                 asym_harmonics: list[int], micro: float = MICRO_FOLD_DE, max_steps: int | None = None,
                 step_grow: float = FOLLOW_STEP_GROW, stop_at_upper: bool = False,
                 landing: str = "search", volume_path: bool = True,
                 watch: Callable[[MultiHarmonicModel], Callable[[Path], bool]] | None = None,
                 settle: Callable[[MultiHarmonicModel], Callable[[PathPoint], bool]] | None = None,
                 landing_check: Callable[[MultiHarmonicModel], Callable[[PathPoint], bool]] | None = None
                 ) -> FollowResult:
    """Trace the branch of the model ``mh`` that leaves the equilibrium ``(U_c, p_c)`` along
    ``Phi`` (a bifurcation point and its critical mode, as free vectors of ``mh``) through its volume
    limit to the lower state at that volume (:func:`follow_branch` for a branch of the axisymmetric
    path, :func:`snapjump_cli.fe.branch.secondary.follow_secondary` for one of a followed branch).

    ``asym_harmonics``: the harmonics whose amplitudes measure the distance from the branch left
    behind (the post-snap trace stops when it passes back through it: :class:`BranchTracker`);
    ``bif``: the bifurcation from the axisymmetric path that the answer is reported under; the
    other parameters as in :func:`follow_branch`. With ``stop_at_upper`` the result has no lower
    state (no snap metrics): the branch up to its first volume limit.

    ``landing``: ``"search"`` (the reference) traces the branch to its snap and, where the branch
    passed back through the axisymmetric path (:data:`REJOINED`) without a lower state, searches
    that state at fixed volume from the upper state and the branch's post-snap points (the
    fixed-volume path, then the energy descent,
    :func:`snapjump_cli.fe.axisym.lower_state.find_lower_state`). ``"axisymmetric first"`` takes
    the axisymmetric path's state at the upper state's volume beyond its snap when one is stable
    with every harmonic of ``mh`` (:func:`axisym_landing`): for a subcritical branch before
    tracing it (its first step tells), and for a branch that passed back through the axisymmetric
    path before the search; where there is none, a subcritical branch lands where the sphere path
    from the bifurcation comes to rest (``land_from_bifurcation(descent=False)``), and the branch
    is traced and searched as the reference where that finds nothing.
    ``volume_path``: the search at fixed volume tries the fixed-volume path before the energy
    descent (``False``: the descent alone; in the multi-harmonic model that path has not reached a
    lower state on the stratified samples, docs/harmonics.md section 10.8). ``"descent first"``: for
    a subcritical branch (its first step tells), the state at the bifurcation's volume reached from
    the bifurcation along the branch's tangent (:func:`snapjump_cli.fe.branch.landing.land_from_bifurcation`:
    the sphere path, else the energy descent, the start the reference search tries first), before
    tracing the branch: where it lies below the bifurcation by at least the micro-fold energy, the
    branch beyond its first step is not needed; it traces and searches as the reference where it
    does not. The sphere path goes before that first step where its first load is negative
    (:data:`SPHERES_BEFORE_PROBE`): a state it lands on then makes the branch subcritical and its
    path the bifurcation alone. ``landing_check`` (made from ``mh``; a branch of ``n_c >= 2``): whether a state of ``mh``
    is also stable with every harmonic (:func:`snapjump_cli.fe.branch.secondary.stable_outside`); with it, a branch that
    passed back through the axisymmetric path without a lower state (:data:`REJOINED`) takes that
    state (:func:`axisym_inverted_state`) before the search at fixed volume, as ``"axisymmetric
    first"`` does.
    """
    if landing not in LANDINGS:
        raise ValueError(f"landing must be one of {LANDINGS}, got {landing!r}")
    tr0 = result.tracer
    cfg = replace(tr0.cfg, fused=False, mixed_tangent=MIXED_TANGENT, step_grow=float(step_grow))
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

    stays = settle(mh) if settle is not None else None
    check = landing_check(mh) if landing_check is not None else None

    def run(first: PathPoint, kind: str, stop: bool = stop_at_upper, steps: int | None = None, watch=None
            ) -> tuple[Path, BranchTracker, str]:
        tk = BranchTracker(tr, p_stop=p_stop, V_stop=V_stop, post_snap_steps=post, kind=kind, micro_dE=micro_dE,
                           stop_at_upper=stop, watch=watch, settle=None if stop else stays, **amplitudes)
        run_cfg = cfg if steps is None else replace(cfg, max_steps=steps)
        if first is start:  # off the bifurcation: one step of a probe, or the branch
            run_cfg = replace(run_cfg, ds0=cfg.ds0 * 0.5**(PROBE_HALVINGS if steps == 1 else FIRST_STEP_HALVINGS))
        try:
            return trace(mh, run_cfg, tk, tracer=tr, start=first), tk, ""
        except ContinuationFailed as exc:
            return getattr(exc, "path", None) or Path(points=[first]), tk, str(exc)

    def lower_state(tk: BranchTracker, pth: Path, why: str):
        up = tk.states.upper
        if (landing == "axisymmetric first" or check is not None) and why == REJOINED and up is not None \
                and tk.states.lower is None:
            alt, note = axisym_inverted_state(result, mh, tr, up)
            if alt is not None and (check is None or check(alt)):
                return LowerState(alt, "descent", "axisymmetric path", reason=why, message=note)
        low = find_lower_state(tr, tk.states, pth.points, why, volume_path=volume_path)
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

    # the watch: of the trace up to the upper state, or of the full trace's first run (its path
    # indices are the joined path's; a trace restarted from a fold's landing is not watched)
    w = watch(mh) if watch is not None else None
    if stop_at_upper:
        path, tracker, failure = run(start, "", watch=w)
        st = tracker.states
        # the folds traced through (a jump past one is what the check then finds, as on the full trace)
        fr = FollowResult(bif, mh, path, st, tr, tracker.kind if st.upper is not None else "", tracker.first_kind,
                          failure=failure, watch=w,
                          folds=[FoldJump(k, up, lo) for k, up, lo in tracker.fold_states if k < len(path.points)])
        fr.metrics = branch_metrics(fr, sc)
        mh.release_buffers()
        return fr
    if landing in ("axisymmetric first", "descent first"):
        # a subcritical branch (its first step lowers the volume): its upper state is the
        # bifurcation itself, and where the axisymmetric path's inverted state at that volume is
        # stable with every harmonic kept, the actuator lands there (axisym_landing); or where the
        # descent from it at that volume comes to rest below it
        early = None
        if landing == "descent first" and SPHERES_BEFORE_PROBE:
            # the sphere path first: where the energy falls from the bifurcation along its mode, at
            # its volume, to a stable state that releases at least the micro-fold energy, the branch
            # is subcritical and that state is its landing (the probe's step is not needed)
            early = sphere_landing(tr, start, falling=True)
            if early[0] is not None and mh.energy(start.u) - mh.energy(early[0].u) >= micro_dE:
                log.debug("branch: landed from the bifurcation by the sphere path before the probe")
                return _landed_at_bifurcation(bif, mh, Path(points=[start]), SnapStates(k_before=0, upper=start),
                                              tr, early[0], early[1], sc)
            if early[0] is None and early[1].startswith(NOT_FALLING):
                early = None  # (the probe decides; a subcritical branch's path is then followed as before)
        path, tracker, failure = run(start, "", stop=True, steps=1)
        st = tracker.states
        if tracker.kind == "subcritical" and st.upper is not None:
            if landing == "axisymmetric first":
                alt, note = axisym_inverted_state(result, mh, tr, st.upper)
                if alt is None:  # the state the sphere path reaches from the bifurcation, if any
                    alt, note = land_from_bifurcation(tr, st.upper, descent=False)
            else:  # (where the sphere path gives up, the axisymmetric inverted state if stable, then the descent)
                known = (lambda: axisym_inverted_state(result, mh, tr, st.upper)) if AXISYM_BEFORE_DESCENT else None
                alt, note = land_from_bifurcation(tr, st.upper, before_descent=known, on_spheres=early)
            if alt is not None and mh.energy(st.upper.u) - mh.energy(alt.u) >= micro_dE:
                return _landed_at_bifurcation(bif, mh, path, st, tr, alt, note, sc)
    if stays is not None and MICRO_FOLD_LANDING_FIRST:
        fr = _micro_fold_left_at_once(run, start, tr, mh, stays, micro_dE, bif, sc)
        if fr is not None:
            return fr

    def run_on(first: PathPoint) -> tuple[Path, BranchTracker, str]:
        if first is start:
            return run(first, "", watch=w)
        if stays is None or not stays(first):
            return run(first, "supercritical")
        # a micro-fold's landing the actuator leaves at once (off the branch): nothing beyond it
        path, tk, failure = run(first, "supercritical", steps=0)
        path.stop_reason = LEFT_AT_LANDING
        return path, tk, failure

    tb = trace_through_micro_folds(run_on, start, lower_state, mh.energy,
                                   lambda state: start_point(tr, state.u, state.p), micro_dE)
    path, tracker, failure, low, micro_folds = tb.path, tb.tracker, tb.failure, tb.lower, tb.micro_folds
    st = tracker.states
    kind = (tracker.kind if not tb.restarts else "supercritical") if st.upper is not None else ""
    first_kind = tb.first_kind
    fr = FollowResult(bif, mh, path, st, tr, kind, first_kind, failure=failure, micro_folds=micro_folds,
                      folds=tb.folds, settle=stays, watch=w)
    if st.upper is not None and low is not None:
        fr.lower_method, fr.lower_note = low.method, low.note or low.message
    fr.metrics = branch_metrics(fr, sc)
    mh.release_buffers()  # the result keeps the model (plots, shapes): not its ~60 MB of band buffers
    return fr


#: ``landing="descent first"`` (a secondary branch in the actuator mode) seeks the landing by the
#: sphere path from the bifurcation before the one-step probe that tells a subcritical branch: where
#: the energy falls from the bifurcation along the mode at its volume (the path's first state has a
#: negative load ``F``: a subcritical pitchfork) to a stable state that releases at least the
#: micro-fold energy, that state is the landing, as the probe and the same path would find it
#: (``False``: the probe first, as before; a switch for measurements). ``follow_strata`` rows 8, 9
#: and ``follow_strata_n2`` rows 2, 22: 45 -> 43, 46 -> 43, 43 -> 41 and 39 -> 37 assemblies of the
#: model with every harmonic; the grid's 20-row sample of the class (docs/performance.md) 950 -> 893;
#: every answer value bit for bit (``bench.profile.follow ... --json A.json``, again with ``--set
#: snapjump_cli.fe.branch.trace.SPHERES_BEFORE_PROBE=False``, compared by ``bench.profile.answers``).
SPHERES_BEFORE_PROBE = True


#: A branch checked against the other harmonics (``settle``) whose first step lowers the volume (a
#: micro-fold at the bifurcation) first seeks the state the actuator lands on at the bifurcation's
#: volume by the sphere path in the branch's model, at most :data:`MICRO_FOLD_STEPS` steps; where
#: that releases less than the micro-fold energy and is unstable outside the branch, the jump goes
#: on from it and the branch's loop below the bifurcation's volume (which the actuator never visits)
#: is not traced. Else the branch is traced through the micro-fold as before. On the 16
#: ``follow_strata_n2`` designs whose branch leaves the bifurcation this way, the sphere path lands
#: on the state the trace comes back to (4-5 steps), and the answers are those of the trace to
#: 1.2e-13 (``python -m bench.profile.follow --sample bench/harmonics_sample/follow_strata_n2.yaml
#: --rows 0 1 ... 23 --json A.json``, again with ``--set
#: snapjump_cli.fe.branch.trace.MICRO_FOLD_LANDING_FIRST=False``, compared by ``bench.profile.answers``). Where the state releases more (row 18: the branch's own snap at its
#: bifurcation) it is the snap's lower state, the trace's to 1.5e-14; where none is found (row 7: a
#: branch that loops back to the axisymmetric path) the branch is traced, after 6 steps of the path.
MICRO_FOLD_LANDING_FIRST = True

#: The sphere path of :data:`MICRO_FOLD_LANDING_FIRST` gives up after this many steps. It is not
#: stopped where its energy rises above the bifurcation's: a barely subcritical bifurcation (the
#: fold releases ~1e-4 of the axisymmetric snap's energy) is a nearly degenerate saddle, and on 4 of
#: those designs the path first rises by more than the micro-fold energy, then lands on the trace's
#: state.
MICRO_FOLD_STEPS = 6


def _landed_at_bifurcation(bif: Bifurcation, mh: MultiHarmonicModel, path: Path, st: SnapStates, tr: Tracer,
                           low: PathPoint, note: str, sc) -> FollowResult:
    """A subcritical branch whose snap at its bifurcation (``st.upper``) lands on ``low``, found off
    the path from the bifurcation (``note``: how); ``path`` the branch's first step."""
    st.lower, st.lower_method = low, "descent"
    fr = FollowResult(bif, mh, path, st, tr, "subcritical", "subcritical", lower_method="descent", lower_note=note)
    fr.metrics = branch_metrics(fr, sc)
    mh.release_buffers()
    return fr


def _micro_fold_left_at_once(run: Callable, start: PathPoint, tr: Tracer, mh: MultiHarmonicModel, stays: Callable,
                             micro_dE: float, bif: Bifurcation, sc) -> FollowResult | None:
    """The branch of ``trace_branch`` as its trace through a micro-fold at the bifurcation would end
    it (:data:`LEFT_AT_LANDING`), with the fold's landing found off the path: a path of the
    bifurcation, the one-step probe that shows the volume falling, and the landing state (the sphere
    path from the bifurcation at its volume, :func:`~snapjump_cli.fe.branch.landing.land_from_bifurcation`),
    recorded as the fold's landing (:class:`FoldJump` with its path index, as a restart's first point).
    Where that state releases ``micro_dE`` or more, the fold is the branch's snap and the state its
    lower state (a subcritical branch landed from its bifurcation, as ``landing="descent first"``
    lands one). ``None`` (trace the branch) where the first step raises the volume, no such state
    is found, it releases no energy, or ``stays`` says the actuator stays on it."""
    probe, tk, failure = run(start, "", stop=True, steps=1)
    up = tk.states.upper
    if failure or tk.kind != "subcritical" or up is None or micro_dE <= 0.0:
        return None
    alt, note = land_from_bifurcation(tr, up, descent=False, climb=math.inf, max_steps=MICRO_FOLD_STEPS)
    if alt is None:
        return None
    dE = mh.energy(up.u) - mh.energy(alt.u)
    if not dE > 0.0:
        return None
    if dE >= micro_dE:  # not a micro-fold: the branch's snap, landed as the reference's trace lands it
        return _landed_at_bifurcation(bif, mh, probe, tk.states, tr, alt, note, sc)
    try:
        first = start_point(tr, alt.u, alt.p)
    except ContinuationFailed:
        return None
    if not stays(first):
        return None
    log.debug("branch: the micro-fold at the bifurcation (dE %.3g < %.3g) lands on a state unstable outside the "
              "branch (%s): not traced", dE, micro_dE, note)
    path = Path(points=probe.points[:2] + [first], n_newton=probe.n_newton, stop_reason=LEFT_AT_LANDING)
    fr = FollowResult(bif, mh, path, SnapStates(p_max=tk.states.p_max), tr, "", "subcritical",
                      micro_folds=[(float(up.zeta[0]), float(dE))], folds=[FoldJump(0, up, first, 2)], settle=stays)
    fr.metrics = branch_metrics(fr, sc)
    mh.release_buffers()
    return fr


def axisym_crossings(result, V: float, beyond_snap: bool = False) -> Iterator[tuple[int, PathPoint | None]]:
    """The axisymmetric path's states at scaled volume ``V``, each located on its path step of
    ``result`` (``None`` where that fails) with the step's end index: before the path's volume
    limit, each crossing where the volume rises; with ``beyond_snap``, every crossing after it.
    (Any result with a ``path``, its ``tracer`` and ``states`` will do: a followed branch too.)"""
    st0 = result.states
    pts = result.path.points
    k_before = st0.k_before if st0 is not None and st0.k_before is not None else len(pts) - 1
    locate = SnapTracker(result.tracer, p_stop=math.inf, V_stop=math.inf)
    for k in range(k_before + 1, len(pts)) if beyond_snap else range(1, k_before + 1):
        a, b = pts[k - 1], pts[k]
        if beyond_snap:
            if (a.zeta[0] - V) * (b.zeta[0] - V) > 0.0 or a.zeta[0] == b.zeta[0]:
                continue
        elif not a.zeta[0] < V <= b.zeta[0]:
            continue
        yield k, locate.locate_volume(a, b, V, pts[k - 2] if k > 1 else None)


def axisym_state_at(result, mh: MultiHarmonicModel, tr: Tracer, V: float) -> PathPoint | None:
    """The axisymmetric path's state at scaled volume ``V`` (before its volume limit) as a state of
    the multi-harmonic model ``mh`` (traced by ``tr``), if it is stable there under volume control
    within ``mh``'s harmonics; else ``None``."""
    for _, q in axisym_crossings(result, V):
        if q is None:
            return None
        U = mh.embed(q.u)
        lin = mh.linearize(U, q.p)
        if lin is None or constrained_instability(tr, lin) != 0:
            return None
        try:
            return start_point(tr, U, q.p, lin=lin)
        except ContinuationFailed:
            return None
    return None


def axisym_landing(result, mh: MultiHarmonicModel, tr: Tracer, upper: PathPoint) -> PathPoint | None:
    """The state at the volume of ``upper`` (a branch's upper state, traced by ``tr`` in ``mh``) on
    the axisymmetric path beyond its snap, as a state of ``mh``: of the path's crossings of that
    volume after its volume limit, each polished at fixed volume in ``mh``, the lowest in energy
    that is stable under volume control with every harmonic of ``mh`` and lies below ``upper``'s
    energy; ``None`` if there is none.

    Where a subcritical branch loops back to the axisymmetric path, it holds no stable state at its
    bifurcation's volume, and the actuator's isochoric snap from that volume ends on the
    axisymmetric path's inverted state there (the energy descent of the reference search finds the
    same state: docs/harmonics.md, "Where the actuator lands")."""
    st0 = result.states
    if st0 is None or st0.k_before is None:
        return None
    V = float(upper.zeta[0])
    best, E_best = None, mh.energy(upper.u)
    for _, q in axisym_crossings(result, V, beyond_snap=True):
        if q is None:
            continue
        pt, E = _stable_below(mh, tr, upper, q.u, float(q.p), E_best)
        if pt is not None:
            best, E_best = pt, E
    return best


def axisym_inverted_state(result, mh: MultiHarmonicModel, tr: Tracer, upper: PathPoint) -> tuple[PathPoint | None, str]:
    """The axisymmetric inverted state at ``upper``'s volume, stable with every harmonic of ``mh``
    and below ``upper``: :func:`axisym_landing`, else :func:`axisym_lower_landing`. Returns
    ``(state, note)`` (the note for ``follow_note``), ``(None, "")`` if neither gives one."""
    alt = axisym_landing(result, mh, tr, upper)
    if alt is not None:
        return alt, AXISYM_LANDING
    alt = axisym_lower_landing(result, mh, tr, upper)
    return (alt, AXISYM_LOWER_LANDING) if alt is not None else (None, "")


#: Where the sphere path finds no landing of a secondary branch or of a jump off a branch (a branch of
#: ``n_c >= 2``), take :func:`axisym_inverted_state` before the energy descent (``False``: the descent,
#: as before; a switch for measurements).
AXISYM_BEFORE_DESCENT = True


#: :func:`axisym_lower_landing`: the axisymmetric lower state is brought to the branch's volume in
#: this many equal volume steps of Newton at fixed volume (the first count that converges).
LOWER_STATE_SUBSTEPS = (1, 4)


def axisym_lower_landing(result, mh: MultiHarmonicModel, tr: Tracer, upper: PathPoint) -> PathPoint | None:
    """The axisymmetric solve's own lower state, where it was found off the axisymmetric path (by
    the energy descent: the path does not come back to its volume limit, so :func:`axisym_landing`
    has no crossing to polish), brought to the volume of ``upper`` by Newton at fixed volume in the
    axisymmetric model (:data:`LOWER_STATE_SUBSTEPS`), polished in ``mh`` and returned if it is
    stable under volume control with every harmonic of ``mh`` and below ``upper``'s energy; else
    ``None``. It is the axisymmetric inverted state at that volume, as :func:`axisym_landing`'s; on
    the paper grid's designs that take it (bifurcation within 1.4 % of the axisymmetric volume limit)
    it is the state the energy descent from the bifurcation comes to rest on (docs/harmonics.md,
    section 10.8)."""
    st0 = result.states
    if st0 is None or st0.lower is None or st0.lower_method != "descent":
        return None
    V = float(upper.zeta[0])
    low = st0.lower
    V0 = float(low.zeta[0])
    for k in LOWER_STATE_SUBSTEPS:
        u, p = low.u.copy(), float(low.p)
        for j in range(1, k + 1):
            res = result.tracer.correct(u, p, None, None, 0.0, target=(0, V0 + (V - V0) * j / k))
            if res is None:
                break
            u, p = np.array(res[0].u, dtype=float), float(res[0].p)
        else:
            return _stable_below(mh, tr, upper, u, p, mh.energy(upper.u))[0]
    return None


def _stable_below(mh: MultiHarmonicModel, tr: Tracer, upper: PathPoint, u_axi: np.ndarray, p: float,
                  E_max: float) -> tuple[PathPoint | None, float]:
    """The axisymmetric state ``(u_axi, p)`` polished at ``upper``'s volume in ``mh`` (by ``tr``), as a
    point oriented by ``upper``'s tangent, with its energy, if that is below ``E_max`` and the state
    is stable under volume control with every harmonic of ``mh``; else ``(None, nan)``.

    An axisymmetric state stays axisymmetric under the polish, and there ``mh``'s tangent is the
    harmonics' operators side by side: one that the harmonic check finds unstable in a harmonic
    ``>= 1`` (an eigenvalue below ``-ZERO_TOL mu_min``, :func:`~snapjump_cli.fe.stability.harmonics.unstable_harmonics`)
    fails the test after the polish too, and is given up before it (a band factorisation of a few
    hundred dofs per harmonic instead of the polish's assemblies of ``mh``)."""
    if unstable_harmonics(mh.base, u_axi, p, mh.hn[1:], free_body=mh.free_body, first_only=True):
        return None, math.nan
    res = tr.correct(mh.embed(u_axi), p, None, None, 0.0, target=(0, float(upper.zeta[0])))
    if res is None:
        return None, math.nan
    lin, it = res
    E = mh.energy(lin.u)
    if E >= E_max or constrained_instability(tr, lin) != 0:
        return None, math.nan
    t, v, qq, z = tr.tangent(lin, (upper.tangent, tr.alpha * upper.du_ds))
    return PathPoint(lin.u, lin.p, z, t, v, qq, float("nan"), it), E


def branch_metrics(fr: FollowResult, sc: np.ndarray) -> dict:
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
