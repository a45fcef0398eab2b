"""Following the branch that bifurcates from the axisymmetric path (snapjump_cli.fe.branch.trace).

* the bifurcation is located where the harmonic check's inertia changes, with a zero eigenvalue;
* leaving along the mode: the branch's first states are equilibria of the multi-harmonic model,
  the mode's amplitude grows, the branch is a symmetric pitchfork (``V - V_c`` grows as the
  square of the amplitude, by amplitude-controlled Newton solves independent of the continuation),
  the trace's first state is that solve's state, and the sub/supercritical verdict follows its
  volume;
* design B end to end (the independent 3D computation's case) is checked on the ``curve`` command's
  answer, which draws every output from the same solve (tests/cli/test_curve_followed.py).
"""
from __future__ import annotations

import numpy as np
import pytest

from snapjump_cli.fe.branch.bifurcation import default_harmonics, locate_bifurcation
from snapjump_cli.fe.branch.trace import follow_branch
from snapjump_cli.geometry.caps import CapScene
from snapjump_cli.fe.stability.harmonics import check_harmonics, harmonic_operator
from snapjump_cli.settings import MeshSettings, SolverSettings
from snapjump_cli.fe.solve import solve_checked, solve_scene


@pytest.fixture(scope="module")
def cap():
    """A clamped cap above the asymmetric threshold (lambda = 6.1): harmonic 2 goes first."""
    res = solve_scene(CapScene(theta_deg=30.0, eta=50.0, bc="clamped"), MeshSettings(nt=1, aspect=2.0),
                      SolverSettings())
    return res, check_harmonics(res, 4)


def test_the_bifurcation_is_where_the_inertia_changes(cap):
    res, chk = cap
    assert chk.asym_first and chk.asym_n == 2
    bif = locate_bifurcation(res, 2)
    assert abs(bif.eig) < 1e-8
    op = harmonic_operator(res.model, 2)
    pts = [pt for pt in res.path.points[: res.states.k_before + 1]]
    V = np.array([pt.zeta[0] for pt in pts])
    k = int(np.searchsorted(V, bif.zeta[0]))  # the path states on either side
    assert op.inertia(pts[k - 1].u, pts[k - 1].p) == 0 and op.inertia(pts[k].u, pts[k].p) > 0
    # the check's bisected volume lies within its 6 bisections of this one
    L3, sV = res.model.L**3, res.tracer.sc[0]
    dV = (pts[k].zeta[0] - pts[k - 1].zeta[0]) * sV * L3
    assert abs(chk.asym_V_m3 - bif.zeta[0] * sV * L3) <= dV / 2**6 * 1.01


def _amplitude_solve(mh, U_c, p_c, e, eps):
    """Newton on R = 0 with the amplitude ``e . (u - U_c)`` of the unit mode ``e`` fixed to
    ``eps`` (an independent solve: not the continuation's hyperplane)."""
    u, p = U_c + eps * e, p_c
    for _ in range(30):
        lin = mh.linearize(u, p)
        h = float(e @ (u - U_c)) - eps
        if np.linalg.norm(lin.R) < 1e-8 * np.linalg.norm(lin.g) * abs(p_c) and abs(h) < 1e-14:
            return lin
        x = lin.factor(e, 0.0).solve(np.concatenate([-lin.R, [-h]]))
        u, p = u + x[:-1], p + x[-1]
    raise AssertionError("amplitude solve did not converge")


def test_leaving_along_the_mode_is_a_symmetric_pitchfork(cap):
    res, _ = cap
    bif = locate_bifurcation(res, 2)
    fr = follow_branch(res, bif, default_harmonics(2, 4), max_steps=6)
    mh = fr.model
    pts = fr.path.points
    assert len(pts) == 7
    # the traced branch: equilibria, leaving the axisymmetric path
    for pt in pts[1:]:
        lin = mh.linearize(pt.u, pt.p)
        assert np.linalg.norm(lin.R) < 1e-6 * np.linalg.norm(lin.g) * max(abs(pt.p), 1e-3 * fr.tracer.sc[1])
    amp = [float(np.abs(mh.harmonic_part(pt.u, 2)).max()) for pt in pts]
    assert amp[0] == 0.0 and all(b > a for a, b in zip(amp, amp[1:]))
    # independent solves at fixed amplitude of the mode
    U_c = mh.embed(bif.u)
    Phi = mh.embed(np.zeros(res.model.n), {2: bif.mode})
    e = Phi / np.linalg.norm(Phi)
    V_c = mh.volume(U_c)
    # a symmetric pitchfork: V is even in the amplitude and grows as its square at small amplitudes
    # (this cap's quartic term shows from ~2e-5 of the radius on: it folds back at ~2e-4)
    # (differences between amplitudes, so that the located bifurcation's own tolerance cancels)
    eps = 5e-6 / np.abs(e).max()
    V1, V2, V3 = (_amplitude_solve(mh, U_c, bif.p, e, k * eps).V for k in (1, 2, 3))
    Vm = _amplitude_solve(mh, U_c, bif.p, e, -2 * eps).V
    assert abs(V2 - Vm) < 1e-4 * abs(V2 - V1)
    assert (V3 - V1) / (V2 - V1) == pytest.approx(8.0 / 3.0, rel=5e-3)
    # the trace's first point is the branch's state at its amplitude; its volume gives the verdict
    lin = _amplitude_solve(mh, U_c, bif.p, e, float(e @ (pts[1].u - U_c)))
    # (path points are accepted by the error test at tol_path = 1e-6 in the arc-length metric)
    assert lin.V == pytest.approx(pts[1].zeta[0] * fr.tracer.sc[0], rel=1e-7)
    assert lin.p == pytest.approx(pts[1].p, rel=1e-6)
    assert fr.first_kind == ("subcritical" if lin.V < V_c else "supercritical")


def test_a_design_that_stays_axisymmetric_keeps_its_answer():
    res = solve_checked(CapScene(theta_deg=30.0, eta=25.0, bc="clamped"), MeshSettings(nt=1, aspect=2.0),
                        SolverSettings(harmonics=4, follow=True))
    m = res.metrics
    assert m["asym_first"] is False and m["followed"] is False
    for k in ("dE_J", "dy_pole_m", "V_star_m3", "p_star_Pa"):
        assert m["axisym_" + k] == m[k]


def test_a_branch_over_the_time_limit_keeps_the_axisymmetric_answer(cap):
    from snapjump_cli.fe.branch.followed import apply_followed
    from snapjump_cli.fe.limits import time_limit

    res, chk = cap
    before = dict(res.metrics)
    with time_limit(1e-6):
        apply_followed(res, chk)
    m = res.metrics
    assert m["followed"] is False and "time limit" in m["follow_note"]
    assert m["dE_J"] == before["dE_J"] and m["axisym_dE_J"] == before["dE_J"]


def test_a_fold_that_releases_almost_nothing_is_not_the_answer(cap, monkeypatch):
    """A followed 'snap' releasing < 1 % of the axisymmetric dE (a fold whose lower state was found
    off the branch, so the tracker could not trace through it) keeps the axisymmetric answer with
    the reason, instead of reporting a near-zero snap."""
    from types import SimpleNamespace

    from snapjump_cli.fe.branch import followed as follow

    res, chk = cap
    dE_axi = res.metrics["dE_J"]
    fake = {"dE_J": 1e-4 * dE_axi, "dy_pole_m": 1e-8, "follow_kind": "supercritical", "follow_note": ""}
    monkeypatch.setattr(follow, "locate_bifurcation", lambda result, n: SimpleNamespace(n=n))
    monkeypatch.setattr(follow, "follow_branch", lambda *a, **k: SimpleNamespace(metrics=dict(fake)))
    # (a fake branch: no model to check against the other harmonics, section 10.7)
    out = follow.followed_metrics(res, chk, secondary=False).values
    assert out["followed"] is False and "releases" in out["follow_note"]
    fake["dE_J"] = 0.5 * dE_axi  # a real snap is reported
    out = follow.followed_metrics(res, chk, secondary=False).values
    assert out["followed"] is True and out["dE_J"] == 0.5 * dE_axi
    fake["dy_pole_m"] = -1.6e-3  # ... unless its pole moves up: the axisymmetric answer stays, with the reason
    out = follow.followed_metrics(res, chk, secondary=False).values
    assert out["followed"] is False and "moves the pole up" in out["follow_note"] and out.get("dE_J") is None


def test_the_axisymmetric_state_at_a_volume_is_offered_only_where_it_is_stable(cap):
    """follow.axisym_state_at: before the bifurcation the axisymmetric state, embedded in the
    multi-harmonic model, is an equilibrium at that volume, stable; after it (harmonic 2 unstable)
    it is not offered."""
    from dataclasses import replace

    from snapjump_cli.fe.continuation import Tracer
    from snapjump_cli.fe.branch.trace import axisym_state_at
    from snapjump_cli.fe.branch.bifurcation import harmonic1_gauge
    from snapjump_cli.fe.branch.model import MultiHarmonicModel

    res, chk = cap
    bif = locate_bifurcation(res, 2)
    mh = MultiHarmonicModel(res.model, default_harmonics(2), gauge=harmonic1_gauge(res.model, 2, bif.u))
    tr = Tracer(mh, replace(res.tracer.cfg, fused=False, mixed_tangent=False))
    V_b = float(bif.zeta[0])
    before = axisym_state_at(res, mh, tr, 0.8 * V_b)
    assert before is not None and before.zeta[0] == pytest.approx(0.8 * V_b, rel=1e-8)
    lin = mh.linearize(before.u, before.p)
    load = abs(before.p) * np.linalg.norm(lin.g)  # the pressure's load: the residual's scale
    assert np.linalg.norm(mh.residual(before.u, before.p)) < 1e-6 * load
    # the embedded state has no harmonic 2 and the axisymmetric energy
    assert np.abs(mh.harmonic_part(before.u, 2)).max() == 0.0
    k = next(i for i, pt in enumerate(res.path.points) if pt.zeta[0] >= 0.8 * V_b) - 1
    E = [res.model.energy(res.path.points[i].u) for i in (k, k + 1)]  # the path points around that volume
    assert E[0] < mh.energy(before.u) < E[1]
    V_after = 0.5 * (V_b + res.states.upper.zeta[0])
    assert axisym_state_at(res, mh, tr, V_after) is None


def test_design_b_lands_by_the_sphere_path_on_the_state_the_traced_branch_returns_to():
    """Design B (the ``curve`` command's mesh): the actuator mode lands its subcritical ``n = 1``
    branch from the bifurcation by the sphere path (snapjump_cli.fe.branch.landing), tracing one
    step of the branch; the reference (``follow_mode: full``) traces the branch down in volume and
    back up to the bifurcation's volume and takes the state it returns to there. The same state and
    answers, and the reference's energy released equals the work along its traced path (dE two
    ways)."""
    from snapjump_cli.fe.branch.followed import followed_metrics
    from snapjump_cli.geometry.designs import get_design

    res = solve_scene(get_design("B"), MeshSettings(), SolverSettings(harmonics=4))
    chk = check_harmonics(res, 4)
    assert chk.asym_first and chk.asym_n == 1
    act, ref = followed_metrics(res, chk, mode="actuator"), followed_metrics(res, chk, mode="full")
    a, r = act.branch, ref.branch
    assert a.lower_note.startswith("sphere path: stable state") and len(a.path.points) == 2
    assert r.states.lower_method == "path" and len(r.path.points) > 20
    V = [pt.zeta[0] for pt in r.path.points]  # the reference goes down in volume from the bifurcation
    k = int(np.argmin(V))
    assert V[k] < (1 - 1e-2) * V[0] and max(V[k:]) >= V[0]  # and comes back up to its volume
    assert np.linalg.norm(a.states.lower.u - r.states.lower.u) < 1e-7 * np.linalg.norm(r.states.lower.u)
    for k in ("dE_J", "dy_pole_m", "V_star_m3", "p_star_Pa"):
        assert act.values[k] == pytest.approx(ref.values[k], rel=1e-7), k
    assert ref.values["dE_rel_diff"] < 1e-3
