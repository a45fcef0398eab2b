"""Landings of ``n = 2`` designs on the axisymmetric inverted state
(snapjump_cli.fe.branch.trace.axisym_inverted_state).

A jump off an ``n = 2`` branch, taken in ``secondary.jump_off_branch`` before the sphere path and
the energy descent (``JUMP_AXISYM_FIRST``):

``follow_strata_n2`` row 3 (bench/harmonics_sample/follow_strata_n2.csv: 8, 75, 10, 88, 5.8) at the
sweep's mesh: its branch of harmonic 2 folds, the state the actuator jumps to on the branch is
unstable in harmonic 1, and the sphere path from it turns back (20 steps, tried first before
``JUMP_AXISYM_FIRST``). The energy descent from that state
(about a thousand iterations in the model with every harmonic 0-8) comes to rest on the
axisymmetric path's inverted state at the fold's volume. Checked here:

* the actuator mode takes that state directly: an equilibrium at the fold's volume, stable under
  volume control with every harmonic 0-8, axisymmetric, below the fold by more than the
  micro-fold energy.

That the descent comes to rest on it (7e-16 apart, the same answer to 1e-14; ~80 CPU-s) is shown by
``python -m bench.profile.follow --sample bench/harmonics_sample/follow_strata_n2.yaml --rows 3
--compare-axisym-first``; the same mechanism is checked against the descent and the damped motion
on the clamped cap in ``test_secondary_branch.py``.

A subcritical ``n = 2`` branch that loses no stability outside its harmonics first and loops back
to the axisymmetric path without a lower state (``follow_strata_n2`` row 7: 8, 77.5, 15, 90, 5.8):
the actuator mode takes the axisymmetric inverted state at the bifurcation's volume (here the
axisymmetric lower state, found off the path, brought to that volume) when it is stable with every
harmonic 0-8, before searching at fixed volume (``followed.AXISYM_FIRST_ALL``). Checked against
the search as before (the energy descent in the branch's model, ~700 iterations): the same state
and answer.
"""
from __future__ import annotations

import numpy as np
import pytest

from snapjump_cli.fe.branch.followed import followed_metrics
from snapjump_cli.fe.branch import followed
from snapjump_cli.fe.branch.metrics import AXISYM_LANDING, AXISYM_LOWER_LANDING
from snapjump_cli.fe.branch.secondary import full_model
from snapjump_cli.fe.branch.trace import REJOINED
from snapjump_cli.geometry.caps import Design
from snapjump_cli.settings import MeshSettings
from tests.landing import assert_axisymmetric_landing, asymmetric_first

SWEEP_MESH = MeshSettings(order=2, nt=2, aspect=3.0)


@pytest.fixture(scope="module")
def design():
    return asymmetric_first(Design(8.0, 75.0, 10.0, 88.0, 5.8), SWEEP_MESH, 2)


@pytest.fixture(scope="module")
def jumped(design):
    res, chk = design
    return followed_metrics(res, chk, mode="actuator")


def test_the_jump_lands_on_the_axisymmetric_inverted_state(design, jumped):
    res, _ = design
    fr = jumped.branch
    assert jumped.values["followed"] and fr.kind == "jump" and fr.model.hn[-1] == 8 and len(fr.model.hn) == 9
    assert AXISYM_LANDING in fr.lower_note
    assert "descent" not in fr.lower_note and "sphere path" not in fr.lower_note  # neither was tried
    assert_axisymmetric_landing(jumped, res.metrics["dE_J"])  # (the jump's model: every harmonic 0..8)


ANSWER = ("dE_J", "dy_pole_m", "V_star_m3", "p_star_Pa", "h_imp_m")


@pytest.fixture(scope="module")
def subcritical():
    res, chk = asymmetric_first(Design(8.0, 77.5, 15.0, 90.0, 5.8), SWEEP_MESH, 2)
    return res, chk, followed_metrics(res, chk, mode="actuator")


def test_a_subcritical_n2_branch_lands_on_the_axisymmetric_state_stable_with_every_harmonic(subcritical):
    res, _, ans = subcritical
    fr = ans.branch
    assert ans.values["followed"] and fr.kind == "subcritical" and ans.values.get("follow_sec_n") is None
    assert [int(n) for n in fr.model.hn] == [0, 2, 4, 6, 8] and fr.path.stop_reason == REJOINED
    assert fr.lower_note == AXISYM_LOWER_LANDING
    assert_axisymmetric_landing(ans, res.metrics["dE_J"], full=full_model(fr.model, None, fr.bif.u))


def test_it_is_where_the_branch_traced_and_searched_lands(subcritical, monkeypatch):
    res, chk, ans = subcritical
    monkeypatch.setattr(followed, "AXISYM_FIRST_ALL", False)
    before = followed_metrics(res, chk, mode="actuator")
    assert "descent converged" in before.branch.lower_note
    assert len(before.branch.path.points) == len(ans.branch.path.points)  # the same branch traced
    lo, lo_b = ans.branch.states.lower, before.branch.states.lower
    assert np.linalg.norm(lo_b.u - lo.u) < 1e-8 * np.linalg.norm(lo.u)
    for k in ANSWER:
        assert ans.values[k] == pytest.approx(before.values[k], rel=1e-7), k
