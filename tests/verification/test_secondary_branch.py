"""A followed branch that loses stability outside its harmonics (snapjump_cli.fe.secondary).

A clamped cap (30 deg, eta = 80, one element through the thickness) loses stability first in
harmonic 3; its branch (harmonics 0, 3, 6) rises far beyond the axisymmetric V*, but in the
model with every harmonic 0..6 it becomes unstable in the other Bloch class (1, 2, 4, 5) on the
way. The followed answer must be that of the branch that leaves it there:

* the secondary bifurcation is bracketed by the branch's path points (no extra unstable mode
  before, one after) and located where the extra eigenvalue is zero;
* the secondary branch starts on the first branch, its states are equilibria of the full model,
  and the amplitude of the other harmonics grows along it;
* its snap comes before the first branch's volume limit, its dE two ways agree, and the row keys
  (``follow_sec_n``, ``follow_sec_V_m3``, the note) say what happened.
"""
from __future__ import annotations

import numpy as np
import pytest

from snapjump_cli.fe.follow import branch_curve, followed_metrics
from snapjump_cli.fe.harmonics import check_harmonics
from snapjump_cli.fe.secondary import extra_dofs, extra_eigen, extra_harmonics, lift, unstable_modes
from snapjump_cli.fe.solve import solve_scene
from snapjump_cli.geometry.caps import CapScene
from snapjump_cli.settings import MeshSettings, SolverSettings


@pytest.fixture(scope="module")
def followed():
    res = solve_scene(CapScene(theta_deg=30.0, eta=80.0, bc="clamped"), MeshSettings(nt=1, aspect=2.0),
                      SolverSettings())
    chk = check_harmonics(res, 4)
    assert chk["asym_first"] and chk["asym_n"] == 3
    out, fs = followed_metrics(res, chk, N=6)
    return res, out, fs


def test_the_secondary_bifurcation_is_bracketed_and_located(followed):
    res, out, fs = followed
    fr, sec = fs.parent, fs.secondary
    assert fr is not None and sec is not None
    assert list(fr.model.hn) == [0, 3, 6] and list(fs.model.hn) == list(range(7))
    full = fs.model
    assert sec.n in extra_harmonics(fr.model, full)
    pts = fr.path.points

    def extra(pt):
        return unstable_modes(full, lift(fr.model, full, pt.u), pt.p) - unstable_modes(fr.model, pt.u, pt.p)

    assert extra(pts[sec.index]) == 0 and extra(pts[sec.index + 1]) > 0
    ex = extra_dofs(fr.model, full)
    e_a = extra_eigen(full, lift(fr.model, full, pts[sec.index].u), pts[sec.index].p, ex)[0]
    e_c = extra_eigen(full, lift(fr.model, full, sec.point.u), sec.point.p, ex)[0]
    assert e_a > 0 and abs(e_c) < 1e-6 * e_a
    # before the first branch's own volume limit
    assert fr.states.upper is not None and sec.index < fr.states.k_before


def test_the_secondary_branch_leaves_along_the_other_harmonics(followed):
    res, out, fs = followed
    fr, sec, full = fs.parent, fs.secondary, fs.model
    start = fs.path.points[0]
    np.testing.assert_allclose(start.u, lift(fr.model, full, sec.point.u), rtol=0, atol=1e-14)
    others = extra_harmonics(fr.model, full)

    def amplitude(u):
        return max(float(np.abs(full.harmonic_part(u, n)).max()) for n in others)

    amps = [amplitude(pt.u) for pt in fs.path.points[:6]]
    assert amps[0] == 0.0 and all(b > a for a, b in zip(amps, amps[1:]))
    for pt in fs.path.points[1:6]:  # equilibria of the model with every harmonic
        lin = full.linearize(pt.u, pt.p)
        assert np.linalg.norm(lin.R) < 1e-6 * abs(pt.p) * np.linalg.norm(lin.g)


def test_its_snap_is_the_answer(followed):
    res, out, fs = followed
    fr, sec = fs.parent, fs.secondary
    assert out["followed"] and out["follow_n"] == 3 and out["follow_N"] == 6
    assert out["follow_sec_n"] == sec.n and out["follow_sec_V_m3"] == pytest.approx(sec.V_m3, rel=1e-12)
    assert "loses stability to harmonic" in out["follow_note"]
    # the snap happens on the secondary branch, before the first branch's volume limit
    assert sec.V_m3 <= out["V_star_m3"] < fr.metrics["V_star_m3"]
    assert out["dE_J"] > 0 and out["dy_pole_m"] > 0
    if out.get("dE_path_J") is not None:
        assert out["dE_path_J"] == pytest.approx(out["dE_J"], rel=1e-4)
    # the plotted branch: the first branch up to the secondary bifurcation, then the second
    bc = branch_curve(fs)
    assert bc["n_sec"] == sec.n and len(bc["V_m3"]) == sec.index + 2 + len(fs.path.points)
