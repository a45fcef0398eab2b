"""Where a subcritical branch's actuator lands when the axisymmetric path does not come back to its
volume limit (snapjump_cli.fe.branch.trace.axisym_lower_landing).

A paper-grid design of the mu_i/mu_o = 5.8 class, (8, 70, 16.67, 78, 5.8), on a coarse mesh (Q9,
nt 1, aspect 4): its axisymmetric lower state is found off the path by the energy descent, and its
n = 1 bifurcation lies just below the axisymmetric volume limit. No crossing of the axisymmetric
path beyond its snap is there to polish, so the actuator mode took that state only after the
sphere path from the bifurcation gave up, the whole branch was traced and the energy descent came
to rest. Checked here:

* the actuator mode lands on the axisymmetric lower state brought to the bifurcation's volume,
  after one step of the branch;
* that state is an equilibrium of the multi-harmonic model there, stable under volume control
  with every harmonic, axisymmetric, and below the bifurcation by more than the micro-fold energy;
* it is the state the energy descent at fixed volume from the bifurcation comes to rest on (the
  slow way, kept beside the fast one), and the answer is the one the actuator mode gave without
  the candidate (the sphere path, the branch traced, the descent);
* the candidate is not taken where the axisymmetric lower state lies on the path (the path's own
  crossings are polished there, :func:`axisym_landing`).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import snapjump_cli.fe.branch.trace as trace
from snapjump_cli.fe.axisym.descent import descend_at_volume
from snapjump_cli.fe.branch.followed import followed_metrics
from snapjump_cli.fe.branch.metrics import AXISYM_LOWER_LANDING
from snapjump_cli.fe.branch.trace import axisym_lower_landing
from snapjump_cli.geometry.caps import Design
from snapjump_cli.settings import MeshSettings
from tests.landing import assert_axisymmetric_landing, asymmetric_first

ANSWER = ("dE_J", "dy_pole_m", "V_star_m3", "p_star_Pa", "h_imp_m")


@pytest.fixture(scope="module")
def design():
    res, chk = asymmetric_first(Design(8.0, 70.0, 50.0 / 3.0, 78.0, 5.8), MeshSettings(order=2, nt=1, aspect=4.0), 1)
    assert res.states.lower_method == "descent"  # the path does not come back to the volume limit
    return res, chk


@pytest.fixture(scope="module")
def landed(design):
    res, chk = design
    return followed_metrics(res, chk, mode="actuator")


def test_the_actuator_lands_on_the_axisymmetric_lower_state(design, landed):
    res, _ = design
    fr = landed.branch
    assert landed.values["followed"] and fr.kind == "subcritical"
    assert fr.lower_note == AXISYM_LOWER_LANDING and len(fr.path.points) == 2  # one step of the branch
    assert_axisymmetric_landing(landed, res.metrics["dE_J"])  # (stable with every harmonic 0..4)


def test_it_is_where_the_descent_from_the_bifurcation_comes_to_rest(landed):
    fr = landed.branch
    low, msg = descend_at_volume(fr.tracer, fr.states.upper)
    assert low is not None, msg
    lo = fr.states.lower
    assert np.linalg.norm(low.u - lo.u) < 1e-8 * np.linalg.norm(lo.u)


def test_the_answer_is_the_one_found_without_it(design, landed, monkeypatch):
    res, chk = design
    monkeypatch.setattr(trace, "axisym_lower_landing", lambda *a, **k: None)
    before = followed_metrics(res, chk, mode="actuator")
    assert before.branch.lower_note != AXISYM_LOWER_LANDING and len(before.branch.path.points) > 2
    for k in ANSWER:
        assert landed.values[k] == pytest.approx(before.values[k], rel=1e-7), k


def test_not_taken_where_the_lower_state_lies_on_the_path(design, landed):
    res, _ = design
    fr = landed.branch
    on_path = replace(res, states=replace(res.states, lower_method="path"))
    assert axisym_lower_landing(on_path, fr.model, fr.tracer, fr.states.upper) is None
    assert axisym_lower_landing(res, fr.model, fr.tracer, fr.states.upper) is not None
