"""Going on past folds of a followed branch that release almost nothing
(snapjump_cli.fe.branch.trace: trace_through_micro_folds, BranchTracker's return to the axisymmetric path)."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from snapjump_cli.fe.branch.trace import UPPER_LOCATED, BranchTracker, trace_through_micro_folds
from snapjump_cli.fe.continuation.path import Path
from snapjump_cli.fe.axisym.snap import SnapStates


def _pt(V: float, E: float) -> SimpleNamespace:
    """A stand-in path point whose energy is its u[0]."""
    return SimpleNamespace(u=np.array([E]), p=0.0, zeta=np.array([V, 0.0, 0.0]))


def _trace(points, k_before, upper, lower_on_path=None):
    tk = SimpleNamespace(states=SnapStates(k_before=k_before, upper=upper,
                                           k_return=None if lower_on_path is None else len(points) - 1),
                         micro_folds=[], first_kind="supercritical", kind="supercritical")
    if lower_on_path is not None:
        tk.states.lower, tk.states.lower_method = lower_on_path, "path"
    return Path(points=list(points), stop_reason="x"), tk, ""


def test_a_fold_whose_off_branch_lower_state_releases_almost_nothing_is_passed_and_the_next_snap_counts():
    # first trace: up to a fold at V = 3 (E 10), lower state off the branch releasing 1e-4
    t1 = _trace([_pt(1, 1), _pt(2, 5), _pt(2.9, 9.9), _pt(2.5, 9.0)], k_before=2, upper=_pt(3, 10))
    # second trace from that lower state: up to a real snap at V = 6 (E 30), its lower state on the path (E 20)
    low2 = _pt(6, 20)
    t2 = _trace([_pt(3, 10 - 1e-4), _pt(5, 25), _pt(5.9, 29), _pt(4, 22), low2], k_before=2,
                upper=_pt(6, 30), lower_on_path=low2)
    runs = iter([t1, t2])
    starts = []

    def lower_state(tk, path, why):
        st = tk.states
        if st.lower is not None:
            return SimpleNamespace(state=st.lower, method="path", note="", message="")
        return SimpleNamespace(state=_pt(3, 10 - 1e-4), method="descent", note="", message="")

    out = trace_through_micro_folds(lambda first: next(runs), "start", lower_state, lambda u: float(u[0]),
                                    lambda s: starts.append(s) or "restart", micro_dE=0.1)
    assert out.restarts == 1 and len(starts) == 1 and starts[0].u[0] == pytest.approx(10 - 1e-4)
    assert out.micro_folds == [(3.0, pytest.approx(1e-4))]
    # the joined path: the first trace up to its fold (3 points), then the second trace
    assert len(out.path.points) == 3 + 5
    st = out.tracker.states
    assert st.k_before == 3 + 2 and st.k_return == 3 + 4 and out.path.points[st.k_return] is low2
    assert st.lower is low2 and st.lower_method == "path"
    # the fold is recorded: after the first trace's point 2, the jump lands on the second trace's first point
    (f,) = out.folds
    assert f.k == 2 and f.upper.u[0] == 10 and f.landing == "restart" and f.landing_index == 3


@pytest.mark.parametrize("dE, method", [(0.5, "descent"), (-1e-12, "descent"), (1e-4, "path")])
def test_a_real_snap_or_a_search_back_at_the_fold_is_not_passed(dE, method):
    t1 = _trace([_pt(1, 1), _pt(2, 5), _pt(2.9, 9.9)], k_before=2, upper=_pt(3, 10))
    calls = []

    def run(first):
        calls.append(first)
        return t1

    low = SimpleNamespace(state=_pt(3, 10 - dE), method=method, note="", message="")
    out = trace_through_micro_folds(run, "start", lambda *a: low, lambda u: float(u[0]), lambda s: "restart",
                                    micro_dE=0.1)
    assert out.restarts == 0 and calls == ["start"] and out.path is t1[0] and out.tracker.states.lower is low.state


def test_restarts_are_bounded():
    def run(first):
        return _trace([_pt(1, 1), _pt(2, 5), _pt(2.9, 9.9)], k_before=2, upper=_pt(3, 10))

    low = SimpleNamespace(state=_pt(3, 10 - 1e-4), method="descent", note="", message="")
    out = trace_through_micro_folds(run, "start", lambda *a: low, lambda u: float(u[0]), lambda s: "restart",
                                    micro_dE=0.1, max_restarts=2)
    assert out.restarts == 2 and len(out.micro_folds) == 2 and len(out.path.points) == 3 * 3


def test_the_tracker_stops_when_the_branch_passes_back_through_the_axisymmetric_path():
    """A closed loop through the bifurcation (the mode's amplitude changes sign where every
    harmonic is small) ends the post-snap trace; a sign change of the mode while another harmonic
    is large (a mixed-mode branch) does not."""
    def tracker(amps):
        tk = BranchTracker(tracer=None, p_stop=1e9, V_stop=1e9, mode_amplitude=lambda u: float(u[0]),
                           asym_amplitude=lambda u: float(u[1]))
        return tk

    loop = [(0.0, 0.0), (0.1, 0.1), (1.0, 1.0), (0.6, 0.6), (0.1, 0.1), (-0.1, 0.1)]
    tk = tracker(loop)
    seen = [tk._rejoined(SimpleNamespace(u=np.array(a))) for a in loop]
    assert seen == [False] * 5 + [True]
    mixed = [(0.0, 0.0), (0.1, 0.1), (1.0, 1.0), (0.1, 0.8), (-0.1, 0.8)]
    tk = tracker(mixed)
    assert not any(tk._rejoined(SimpleNamespace(u=np.array(a))) for a in mixed)


def test_the_points_passed_through_know_the_folds_traced_through():
    """visited_points / reached_along (snapjump_cli.fe.branch.secondary) with the folds a branch records:
    a fold between two path points raises the volume high to its own volume (the points after it
    on the way down are not passed through), and the first point of a restarted trace is landed on
    by a jump, not reached along the branch."""
    from snapjump_cli.fe.branch.trace import FoldJump
    from snapjump_cli.fe.branch.secondary import jump_before, reached_along, visited_points

    # a micro-fold between points 2 and 3 at V = 3.2, the branch going down to 2.6 and back up
    V = [1.0, 2.0, 3.0, 3.1, 2.6, 3.15, 3.3, 3.5]
    on_path = FoldJump(2, _pt(3.2, 9.0), _pt(3.2, 8.9))
    fr = SimpleNamespace(path=Path(points=[_pt(v, 0.0) for v in V]), folds=[on_path])
    assert visited_points(fr, 7) == [1, 2, 6, 7]  # not 3 (3.1 < 3.2, past the fold), nor 5
    assert reached_along(fr, 2) and not reached_along(fr, 6) and reached_along(fr, 7)
    assert jump_before(fr, 6) is on_path and jump_before(fr, 2) is None
    fr.folds = []  # without the record: points 3 and 5 (new highs of the points) would count as passed through
    assert visited_points(fr, 7) == [1, 2, 3, 5, 6, 7]
    # a restart: the trace up to a fold after point 2, then a new trace from the state it lands on
    V = [1.0, 2.0, 3.0, 3.2, 3.4, 3.6]
    restart = FoldJump(2, _pt(3.2, 9.0), "landing", landing_index=3)
    fr = SimpleNamespace(path=Path(points=[_pt(v, 0.0) for v in V]), folds=[restart])
    assert visited_points(fr, 5) == [1, 2, 3, 4, 5]
    assert not reached_along(fr, 3) and reached_along(fr, 4)  # point 3 is the landing
    assert jump_before(fr, 3) is restart


def _step_pt(V: float, dV_ds: float) -> SimpleNamespace:
    """A stand-in path point with a volume and the volume component of its tangent."""
    return SimpleNamespace(u=np.zeros(1), p=0.3, zeta=np.array([V, 0.3, 0.0]), tangent=np.array([dV_ds, 0.0, 0.0]),
                           n_neg=-1)


@pytest.mark.parametrize("dV, slope, kind", [
    (-2e-7, -0.02, "subcritical"),   # the volume falls: subcritical, as before
    (3e-8, -0.02, "subcritical"),  # it rose by less than the bifurcation's location error, but falls at the step's end
    (3e-8, 0.02, "supercritical"),   # it rises and keeps rising
])
def test_the_first_step_tells_a_subcritical_branch_by_the_volume_slope_too(dV, slope, kind):
    """A symmetric pitchfork: the volume along the branch is V_b + b s^2, so the sign of b shows in the
    volume's slope at the end of the first step. The first step's volume against the bifurcation's
    also carries the bifurcation's location error (a located V_b 3e-7 low made a branch falling
    from its first step look supercritical: its loop below V_b was then traced, follow_strata_n2
    rows 0, 1, 16). A subcritical verdict makes the start the upper state."""
    start, first = _step_pt(2.9, 0.0), _step_pt(2.9 + dV, slope)
    tk = BranchTracker(tracer=None, p_stop=1e9, V_stop=1e9, stop_at_upper=True)
    reason = tk(Path(points=[start, first]))
    assert tk.kind == kind and tk.first_kind == kind
    if kind == "subcritical":
        assert tk.states.upper is start and tk.states.k_before == 0 and reason == UPPER_LOCATED
    else:
        assert tk.states.upper is None and reason is None
