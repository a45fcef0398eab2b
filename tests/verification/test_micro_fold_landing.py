"""A branch of ``n_c = 2`` that leaves its bifurcation with a micro-fold (snapjump_cli.fe.branch.trace).

A paper-grid design (eta_i 7.4, theta_i 80, eta_o 8.33, theta_o 82, mu_i/mu_o 1; ``follow_strata_n2``
row 4, on the sample's mesh): its ``n = 2`` branch lowers the volume at once, loops below the
bifurcation's volume and comes back to it on a state that releases almost nothing and is unstable
in harmonic 1, where the jump goes on. The actuator mode finds that state by the sphere path from
the bifurcation in the branch's model, without tracing the loop; the slow reference is the trace
through the loop (``MICRO_FOLD_LANDING_FIRST = False``), which must come back to the same state and
give the same answer. And on row 18's design, whose fold at the bifurcation releases more, the
state found is the branch's snap's lower state, the one the trace comes back to.
"""
from __future__ import annotations

import numpy as np
import pytest

from snapjump_cli.fe.branch import trace as branch_trace
from snapjump_cli.fe.branch.followed import followed_metrics
from snapjump_cli.fe.solve import solve_scene
from snapjump_cli.fe.stability.harmonics import check_harmonics
from snapjump_cli.geometry.caps import Design
from snapjump_cli.settings import MeshSettings, SolverSettings

_DESIGN = Design(7.4, 80.0, 25.0 / 3.0, 82.0, 1.0)
_ROW18 = (8.0, 80.0, 5.0, 82.0, 1.0)  # follow_strata_n2 row 18


def _fast_and_traced(design: Design):
    """The design's followed answer (actuator mode) with the micro-fold landed off the path, and
    with the branch traced through it (the reference), and the axisymmetric solve."""
    res = solve_scene(design, MeshSettings(order=2, nt=2, aspect=3.0), SolverSettings(harmonics=4))
    chk = check_harmonics(res, 4)
    assert chk.asym_first and chk.asym_n == 2
    fast = followed_metrics(res, chk, mode="actuator")
    mp = pytest.MonkeyPatch()
    try:
        mp.setattr(branch_trace, "MICRO_FOLD_LANDING_FIRST", False)
        traced = followed_metrics(res, chk, mode="actuator")
    finally:
        mp.undo()
    return fast, traced, res


@pytest.fixture(scope="module")
def both():
    return _fast_and_traced(_DESIGN)[:2]


def test_the_micro_fold_is_landed_off_the_path_on_the_state_the_trace_comes_back_to(both):
    fast, traced = both
    fb, tb = fast.branch.parent, traced.branch.parent
    assert fast.branch.kind == traced.branch.kind == "jump"
    assert fb.path.stop_reason == tb.path.stop_reason == branch_trace.LEFT_AT_LANDING
    assert len(fb.path.points) == 3 and len(tb.path.points) > 10  # the loop is not traced
    (ff,), (tf,) = fb.folds, tb.folds
    assert ff.k == tf.k == 0 and ff.landing_index == 2 and tf.landing_index is None
    mh = fb.model
    assert mh.volume(ff.landing.u) == pytest.approx(mh.volume(ff.upper.u), rel=1e-8)  # at the bifurcation's volume
    assert np.linalg.norm(ff.landing.u - tf.landing.u) < 1e-7 * np.linalg.norm(tf.landing.u)
    dE_f = mh.energy(ff.upper.u) - mh.energy(ff.landing.u)
    dE_t = tb.model.energy(tf.upper.u) - tb.model.energy(tf.landing.u)
    assert 0.0 < dE_f == pytest.approx(dE_t, rel=1e-6)


def test_the_jump_goes_on_to_the_same_answer(both):
    fast, traced = both
    for key in ("dE_J", "dy_pole_m", "V_star_m3", "p_star_Pa"):
        assert fast.values[key] == pytest.approx(traced.values[key], rel=1e-8), key
    assert fast.values["followed"] and fast.values["follow_sec_n"] == traced.values["follow_sec_n"] == 1


def test_a_fold_that_releases_more_is_the_branch_snap_landed_where_the_trace_lands_it():
    """``follow_strata_n2`` row 18's design: the branch's first step lowers the volume and the state
    the sphere path reaches releases more than the micro-fold energy: that is the branch's snap at
    its bifurcation, and its lower state the one the trace through the fold comes back to."""
    fast, traced, res = _fast_and_traced(Design(*_ROW18))
    fb, tb = fast.branch, traced.branch
    assert fb.kind == tb.kind == "subcritical" and len(fb.path.points) == 2 and len(tb.path.points) > 10
    assert fb.lower_note.startswith("sphere path: stable state") and tb.states.lower_method == "path"
    lo_f, lo_t, mh = fb.states.lower, tb.states.lower, fb.model
    assert np.linalg.norm(lo_f.u - lo_t.u) < 1e-8 * np.linalg.norm(lo_t.u)
    dE = mh.energy(fb.states.upper.u) - mh.energy(lo_f.u)
    assert dE >= branch_trace.micro_energy(res, branch_trace.MICRO_FOLD_DE) > 0.0
