"""Where a subcritical branch's actuator lands on the axisymmetric path (snapjump_cli.fe.branch.trace.axisym_landing).

A design of the mu_i/mu_o = 5.8 class on a coarse mesh (Q9, nt 1, aspect 8; the stratified sample's row 12,
bench/harmonics_sample/follow_strata.csv): its n = 1 branch is subcritical and loops back to the
axisymmetric path without a stable state at the bifurcation's volume. The reference (``mode="full"``)
traces the whole branch and then searches the lower state at fixed volume (fixed-volume path,
energy descent); the actuator mode takes the axisymmetric path's inverted state at that volume
after one step of the branch. Checked here:

* the same state, the same answer (dE, pole travel, V*, p*) as the reference;
* the state is an equilibrium of the multi-harmonic model at the bifurcation's volume, stable
  under volume control with every harmonic, and axisymmetric;
* dE two ways: the energy difference equals the work ``-integral p dV`` along the axisymmetric
  path from the bifurcation to that state (through the fold and the snap);
* a design whose actuator lands on an asymmetric state (design B) is not given this state;
* the actuator mode's search without the fixed-volume path (which fails here, as on every
  multi-harmonic search of the samples) runs the reference's descent and lands on its state;
* the descent first (before tracing the branch; here the sphere path from the bifurcation gives
  up) is that same descent, from the bifurcation.
"""
from __future__ import annotations


import numpy as np
import pytest

from dataclasses import replace

from snapjump_cli.fe.axisym.lower_state import constrained_instability, find_lower_state
from snapjump_cli.fe.axisym.metrics import path_p_dV
from snapjump_cli.fe.branch.bifurcation import default_harmonics, locate_bifurcation
from snapjump_cli.fe.branch.followed import followed_metrics
from snapjump_cli.fe.branch.trace import AXISYM_LANDING, REJOINED, axisym_crossings, axisym_landing, follow_branch
from snapjump_cli.fe.solve import solve_scene
from snapjump_cli.fe.stability.harmonics import check_harmonics
from snapjump_cli.geometry.caps import Design
from snapjump_cli.settings import MeshSettings, SolverSettings


@pytest.fixture(scope="module")
def design():
    res = solve_scene(Design(8.0, 72.5, 10.0, 76.0, 5.8), MeshSettings(order=2, nt=1, aspect=8.0),
                      SolverSettings(harmonics=4))
    chk = check_harmonics(res, 4)
    assert chk.asym_first and chk.asym_n == 1
    return res, chk


@pytest.fixture(scope="module")
def answers(design):
    res, chk = design
    return followed_metrics(res, chk, mode="actuator"), followed_metrics(res, chk, mode="full")


def test_the_actuator_mode_lands_where_the_reference_search_does(answers):
    act, ref = answers
    assert act.values["followed"] and ref.values["followed"]
    assert act.branch.lower_note == AXISYM_LANDING and len(act.branch.path.points) == 2  # one step traced
    assert "descent" in ref.values["follow_note"] and len(ref.branch.path.points) > 50
    mh = ref.branch.model
    lo_a, lo_r = act.branch.states.lower, ref.branch.states.lower
    assert np.linalg.norm(lo_a.u - lo_r.u) <= 1e-6 * np.linalg.norm(lo_r.u)
    for k in ("dE_J", "dy_pole_m", "V_star_m3", "p_star_Pa"):
        assert act.values[k] == pytest.approx(ref.values[k], rel=1e-9), k
    assert mh.energy(act.branch.states.upper.u) == pytest.approx(mh.energy(ref.branch.states.upper.u), rel=1e-12)


def test_the_landing_is_a_stable_axisymmetric_equilibrium_at_the_bifurcations_volume(design, answers):
    res, _ = design
    fr = answers[0].branch
    mh, tr, up, lo = fr.model, fr.tracer, fr.states.upper, fr.states.lower
    assert lo.zeta[0] == pytest.approx(up.zeta[0], rel=1e-9)
    lin = mh.linearize(lo.u, lo.p)
    z, dz_du, _ = tr.zeta(lo.u, lo.p, lin)
    assert np.linalg.norm(lin.R) <= 1e-6 * tr.residual_scale(lin, dz_du, lo.p)
    assert constrained_instability(tr, lin) == 0
    for n in mh.hn[1:]:
        assert np.abs(mh.harmonic_part(lo.u, int(n))).max() < 1e-12
    assert mh.energy(lo.u) < mh.energy(up.u)


def test_dE_two_ways_along_the_axisymmetric_path(design, answers):
    """The state lies on the axisymmetric path beyond its snap: the energy released equals the
    work of the pressure along that path from the bifurcation (a different computation: the
    path's Hermite p-V quadrature, not the energy functional)."""
    res, _ = design
    fr = answers[0].branch
    mh, up, lo = fr.model, fr.states.upper, fr.states.lower
    V = float(up.zeta[0])
    pts = res.path.points
    E_lo = mh.energy(lo.u)
    k0, a = next(axisym_crossings(res, V))  # the bifurcation, before the fold
    k1, b = next((k, q) for k, q in axisym_crossings(res, V, beyond_snap=True)
                 if q is not None and abs(res.model.energy(q.u) - E_lo) < 1e-9 * abs(E_lo))
    sc = res.tracer.sc
    work = path_p_dV([a] + pts[k0:k1] + [b], sc[0], sc[1])
    dE = mh.energy(up.u) - E_lo
    assert -work == pytest.approx(dE, rel=1e-4)


def test_an_asymmetric_landing_is_not_replaced():
    """Design B lands on an asymmetric state of its branch: no axisymmetric state at the
    bifurcation's volume beyond the snap is stable with every harmonic and below it."""
    from snapjump_cli.geometry.designs import get_design

    res = solve_scene(get_design("B"), MeshSettings(), SolverSettings(harmonics=4))
    bif = locate_bifurcation(res, 1)
    head = follow_branch(res, bif, default_harmonics(1), max_steps=1, stop_at_upper=True)
    assert head.kind == "subcritical"
    assert axisym_landing(res, head.model, head.tracer, head.states.upper) is None


def test_the_harmonic_inertia_gives_up_only_candidates_the_polish_rejects(monkeypatch):
    """Design B's axisymmetric states beyond the snap at the bifurcation's volume are unstable in a
    harmonic >= 1: the harmonic check's inertia gives each up before any polish in the
    multi-harmonic model, and polished there (the inertia test switched off) each fails its test
    too. The design of the fixture lands on such a state: its candidate passes the inertia."""
    import snapjump_cli.fe.branch.trace as trace_mod
    from snapjump_cli.geometry.designs import get_design

    res = solve_scene(get_design("B"), MeshSettings(), SolverSettings(harmonics=4))
    bif = locate_bifurcation(res, 1)
    head = follow_branch(res, bif, default_harmonics(1), max_steps=1, stop_at_upper=True)
    V = float(head.states.upper.zeta[0])
    assert len([q for _, q in axisym_crossings(res, V, beyond_snap=True) if q is not None]) >= 1
    polished = []
    real = head.tracer.correct

    def counted(*args, **kw):
        polished.append(1)
        return real(*args, **kw)

    monkeypatch.setattr(head.tracer, "correct", counted)
    assert axisym_landing(res, head.model, head.tracer, head.states.upper) is None
    assert polished == []  # every candidate given up by the inertia
    monkeypatch.setattr(trace_mod, "unstable_harmonics", lambda *a, **k: [])
    assert axisym_landing(res, head.model, head.tracer, head.states.upper) is None
    assert len(polished) >= 1  # polished, and rejected by the test after the polish


def test_the_search_without_the_fixed_volume_path_is_the_references_descent(answers, monkeypatch):
    """``volume_path=False`` goes straight to the descent the reference falls back on (the same
    call: so the same state wherever the fixed-volume path fails, as it does here)."""
    import snapjump_cli.fe.axisym.lower_state as ls

    ref = answers[1].branch
    assert ref.path.stop_reason == REJOINED and "descent" in ref.lower_note  # the path failed, then the descent
    calls = []

    def no_path(*a, **k):
        raise AssertionError("the fixed-volume path was tried")

    def descent(tracer, upper, start=None, control=None):
        calls.append((tracer, upper, start))
        return ref.states.lower, "descent (recorded)"

    monkeypatch.setattr(ls, "snap_at_fixed_volume", no_path)
    monkeypatch.setattr(ls, "descend_at_volume", descent)
    before = replace(ref.states, lower=None, lower_method="")
    low = find_lower_state(ref.tracer, before, ref.path.points, REJOINED, volume_path=False)
    assert low.solver == "energy-descent" and low.state is ref.states.lower
    assert calls == [(ref.tracer, ref.states.upper, None)]  # the reference's first descent: from the upper state


def test_the_descent_first_falls_back_on_the_references_descent_without_the_branch(design, answers, monkeypatch):
    """``landing="descent first"`` (the actuator mode's landing of a subcritical secondary branch):
    after the branch's first step shows it subcritical, the state reached from the bifurcation at
    its volume (snapjump_cli.fe.branch.landing), and no more of the branch. Here the minima on the
    spheres around the bifurcation turn back before any is an equilibrium, the sphere path gives
    up, and (without the axisymmetric inverted state taken first: the next test) the fallback is
    the descent from the bifurcation that the reference's search ends in: the very same state, bit
    for bit."""
    import snapjump_cli.fe.branch.trace as trace

    monkeypatch.setattr(trace, "AXISYM_BEFORE_DESCENT", False)
    res, chk = design
    ref = answers[1].branch
    fr = follow_branch(res, locate_bifurcation(res, 1), default_harmonics(1), landing="descent first",
                       volume_path=False)
    assert fr.kind == "subcritical" and len(fr.path.points) == 2 and len(ref.path.points) > 50
    sphere, descent = fr.lower_note.split("; ")
    assert sphere.startswith("sphere path: turned back"), fr.lower_note
    assert descent.startswith("descent converged") and descent == ref.lower_note.split("; ")[-1]
    assert np.array_equal(fr.states.lower.u, ref.states.lower.u) and fr.states.lower.p == ref.states.lower.p
    for k in ("dE_J", "dy_pole_m", "V_star_m3", "p_star_Pa"):
        assert fr.metrics[k] == ref.metrics[k], k


def test_the_descent_first_takes_the_axisymmetric_inverted_state_before_the_descent(design, answers):
    """Where the sphere path gives up, ``landing="descent first"`` takes the axisymmetric inverted
    state at the bifurcation's volume (stable with every harmonic) before descending: the state the
    reference's descent comes to rest on, to round-off, without the descent."""
    res, chk = design
    ref = answers[1].branch
    fr = follow_branch(res, locate_bifurcation(res, 1), default_harmonics(1), landing="descent first",
                       volume_path=False)
    assert fr.kind == "subcritical" and len(fr.path.points) == 2
    sphere, axisym = fr.lower_note.split("; ")
    assert sphere.startswith("sphere path: turned back") and axisym == AXISYM_LANDING, fr.lower_note
    assert np.linalg.norm(fr.states.lower.u - ref.states.lower.u) < 1e-10 * np.linalg.norm(ref.states.lower.u)
    for k in ("dE_J", "dy_pole_m", "V_star_m3", "p_star_Pa"):
        assert fr.metrics[k] == pytest.approx(ref.metrics[k], rel=1e-9), k


def test_the_lumped_mass_is_positive_and_halved_for_n_ge_1(answers):
    from snapjump_cli.fe.branch.dynamics import lumped_mass
    from snapjump_cli.fe.branch.model import component_index

    mh = answers[0].branch.model
    m = lumped_mass(mh)
    assert m.shape == (mh.n,) and (m > 0).all()
    # the body's mass: every node once per component of harmonic 0 (unit density)
    M = mh.base
    assert m[mh.dofmap[:, 0][mh.dofmap[:, 0] >= 0]].sum() <= M.Wq.sum() * (1 + 1e-12)
    b0, b2 = mh.dofmap[:, component_index(0, 1)], mh.dofmap[:, component_index(2, 1)]
    both = (b0 >= 0) & (b2 >= 0)
    assert np.allclose(m[b2[both]], 0.5 * m[b0[both]], rtol=1e-14)


def test_the_damped_snap_comes_to_rest_on_the_landing_state(design):
    """The arbiter (snapjump_cli.fe.branch.dynamics), on the model with harmonics 0-2 (cheaper):
    the damped motion at fixed volume from the axisymmetric state just past the bifurcation,
    kicked along the critical mode, comes to rest on the state ``axisym_landing`` gives in that
    model (moved by the 1e-3 volume offset), stable under volume control, below the start."""
    from snapjump_cli.fe.branch.dynamics import damped_snap, lowest_frequency
    from snapjump_cli.fe.continuation import PathPoint

    res, _ = design
    bif = locate_bifurcation(res, 1)
    head = follow_branch(res, bif, [0, 1, 2], max_steps=1, stop_at_upper=True)
    mh, tr, up = head.model, head.tracer, head.path.points[0]  # the bifurcation state
    lo = axisym_landing(res, mh, tr, up)
    assert lo is not None
    V1 = float(up.zeta[0]) * (1.0 + 1e-3)
    q = next(q for _, q in axisym_crossings(res, V1))
    U = mh.embed(q.u)
    t, v, qq, z = tr.tangent(mh.linearize(U, q.p), (up.tangent, tr.alpha * up.du_ds))
    start = PathPoint(U, q.p, z, t, v, qq, float("nan"), 0)
    omega = lowest_frequency(tr, lo.u, lo.p)
    ds = damped_snap(tr, start, head.path.points[0].du_ds, omega, zeta=1.0, steps_per_period=10, rest=1e-6)
    assert ds.state is not None, ds.message
    assert ds.state.zeta[0] == pytest.approx(V1, rel=1e-9)
    assert np.linalg.norm(ds.state.u - lo.u) < 3e-3 * np.linalg.norm(lo.u)
    assert mh.energy(ds.state.u) < mh.energy(start.u)


def test_the_plot_shades_the_area_under_the_axisymmetric_path(design, answers):
    """`curve --plot` shades the followed snap's dE: for a landing on the axisymmetric state, the
    region between that path (from the bifurcation through its fold to the landing) and the
    vertical snap; its signed area (shoelace) is the reported dE, to the curve's resolution."""
    from snapjump_cli.fe.branch.metrics import branch_curve
    from snapjump_cli.viz.figures import _axisym_snap_area

    res, _ = design
    act = answers[0]
    bc = branch_curve(act.branch)
    assert bc["axisym_landing"]
    V, p = _axisym_snap_area(res.curve, bc)
    area = 0.5 * float(np.sum(V * np.roll(p, -1) - np.roll(V, -1) * p))
    assert abs(area) == pytest.approx(act.values["dE_J"], rel=0.05)
