"""A branch of ``n_c = 2`` watched for states unstable outside its harmonics past a fold at its
bifurcation (snapjump_cli.fe.branch.followed.WATCH_THROUGH_FOLDS).

Grid row 3070 of ``configs/paper_grid_followed.yaml`` on its own mesh: the ``n = 2`` branch rises
by a few 1e-7 and folds at once (a fold that releases ~5e-9 of the axisymmetric snap's energy), so
the trace up to the first volume limit stops there with nothing to check; beyond it the branch
loses stability to harmonic 1. The actuator mode's trace of the branch through that fold is
watched as the trace to the first volume limit is: it stops at the first state checked unstable
outside the branch, and the answer is that of the trace without the watch (the branch traced on
through its folds, then checked), value for value.
"""
from __future__ import annotations

import numpy as np
import pytest

import snapjump_cli.fe.branch.followed as followed
from snapjump_cli.fe.branch.trace import UNSTABLE_OUTSIDE
from snapjump_cli.fe.solve import solve_scene
from snapjump_cli.fe.stability.harmonics import check_harmonics
from snapjump_cli.geometry.caps import Design
from snapjump_cli.settings import MeshSettings, SolverSettings


@pytest.fixture(scope="module")
def answers():
    res = solve_scene(Design(6.8, 80.0, 20.0 / 3.0, 90.0, 1.0), MeshSettings(order=2, nt=2, aspect=3.0),
                      SolverSettings(harmonics=4))
    chk = check_harmonics(res, 4)
    assert chk.asym_first and chk.asym_n == 2
    out = {True: followed.followed_metrics(res, chk, mode="actuator")}  # (the default)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(followed, "WATCH_THROUGH_FOLDS", False)
        out[False] = followed.followed_metrics(res, chk, mode="actuator")
    return out


def test_the_watched_trace_stops_past_the_fold_at_the_first_state_unstable_outside(answers):
    new, ref = answers[True], answers[False]
    for a in (new, ref):
        assert a.followed and a.branch.secondary is not None and a.branch.parent is not None
    watched, traced = new.branch.parent, ref.branch.parent
    assert watched.path.stop_reason == UNSTABLE_OUTSIDE and watched.states.upper is None
    assert watched.micro_folds and watched.micro_folds == traced.micro_folds[: len(watched.micro_folds)]
    # the reference traced the branch on (to a fold whose landing it leaves): the watched trace is its
    # beginning, bit for bit
    assert traced.path.stop_reason != UNSTABLE_OUTSIDE and len(traced.path.points) > len(watched.path.points)
    for a, b in zip(watched.path.points, traced.path.points):
        assert np.array_equal(a.u, b.u) and a.p == b.p


def test_the_watched_trace_gives_the_reference_answer(answers):
    new, ref = answers[True].values, answers[False].values
    keys = ("dE_J", "dy_pole_m", "V_star_m3", "p_star_Pa", "follow_sec_n", "follow_sec_V_m3", "follow_sec_p_Pa",
            "follow_kind")
    assert {k: new[k] for k in keys} == {k: ref[k] for k in keys}
    sn, sr = answers[True].branch.secondary, answers[False].branch.secondary
    assert (sn.n, sn.index, sn.V_m3, sn.p_Pa) == (sr.n, sr.index, sr.V_m3, sr.p_Pa)
