"""Which harmonic the actuator meets first (snapjump_cli.fe.branch.bifurcation.first_bifurcation).

The stratified sample's row 8 (``follow_strata``, on the sweep's mesh):
the harmonic check finds harmonics 1 and 2 unstable at its first unstable state (its refinement
does not separate them) and reports the lower, 1. Located on the path, harmonic 2's eigenvalue
crosses zero first: at harmonic 1's point ``K_2`` is already negative. The followed answer
follows harmonic 2.
"""
from __future__ import annotations

import csv
from pathlib import Path

import pytest

from snapjump_cli.fe.branch.bifurcation import first_bifurcation, locate_bifurcation
from snapjump_cli.fe.solve import solve_scene
from snapjump_cli.fe.stability.eigen import lowest_eigen
from snapjump_cli.fe.stability.harmonics import check_harmonics, harmonic_operator
from snapjump_cli.geometry.caps import Design
from snapjump_cli.settings import MeshSettings, SolverSettings

SAMPLE = Path(__file__).resolve().parents[2] / "bench" / "harmonics_sample" / "follow_strata.csv"


@pytest.fixture(scope="module")
def row8():
    with open(SAMPLE) as f:
        r = list(csv.DictReader(f))[8]
    d = Design(float(r["eta_i"]), float(r["theta_i"]), float(r["eta_o"]), float(r["theta_o"]), float(r["mu_ratio"]))
    res = solve_scene(d, MeshSettings(order=2, nt=2, aspect=3.0), SolverSettings(harmonics=4))
    return res, check_harmonics(res, 4)


def test_the_first_located_bifurcation_is_the_one_the_path_meets_first(row8):
    res, chk = row8
    assert chk.asym_first and chk.asym_n == 1 and chk.asym_ns == "1,2"
    b1, b2 = locate_bifurcation(res, 1), locate_bifurcation(res, 2)
    assert b2.s < b1.s and b2.zeta[0] < b1.zeta[0]
    first = first_bifurcation(res, [1, 2])
    assert first.n == 2 and first.s == b2.s
    # at harmonic 1's point, harmonic 2 is already unstable (an independent look: its eigenvalue)
    lam2, _ = lowest_eigen(harmonic_operator(res.model, 2), b1.u, b1.p)
    assert lam2 < -1e-3
    assert first_bifurcation(res, [1]).n == 1 and first_bifurcation(res, []) is None


def test_only_the_harmonic_that_crosses_first_on_the_step_is_located(row8, monkeypatch):
    """Both harmonics are bracketed on the same path step; the one the interpolation of the
    eigenvalue puts first (2) is located, and harmonic 1, still stable there, is not: the same
    point, bit for bit, as locating both (``FIRST_BRACKET_ONLY`` off)."""
    from snapjump_cli.fe.branch import bifurcation
    from snapjump_cli.fe.branch.bifurcation import bracket_bifurcation

    res, _ = row8
    assert bracket_bifurcation(res, 1).k == bracket_bifurcation(res, 2).k
    located = []
    locate = bifurcation._locate
    monkeypatch.setattr(bifurcation, "_locate", lambda r, br, **kw: located.append(br.n) or locate(r, br, **kw))
    first = first_bifurcation(res, [1, 2])
    assert located == [2]
    monkeypatch.setattr(bifurcation, "FIRST_BRACKET_ONLY", False)
    every = first_bifurcation(res, [1, 2])
    assert located == [2, 1, 2]
    assert (first.n, first.s, first.p, first.eig) == (every.n, every.s, every.p, every.eig)
    assert (first.u == every.u).all() and (first.mode == every.mode).all()
