"""An imperfect actuator traced from rest to its snap (snapjump_cli.fe.branch.imperfection).

The Fig. S16 ring-roller cap (eta 10, theta 60) loses stability to harmonic 1 just before its
axisymmetric volume limit, and the branch is subcritical (a symmetric unstable bifurcation). For
such a bifurcation Koiter's law says the imperfect structure's limit lies below the bifurcation
by an amount that grows as ``delta^(2/3)``: ten times the imperfection, ``10^(2/3) = 4.6`` times
the knock-down. Checked here with two amplitudes, with both dE evaluations agreeing, and through
``snapjump curve --imperfection``.
"""
from __future__ import annotations

import json
import math

import pytest

from snapjump_cli.commands.curve import main
from snapjump_cli.fe.stability.harmonics import check_harmonics
from snapjump_cli.fe.branch.imperfection import imperfection_shape, inner_thickness, trace_imperfect
from snapjump_cli.fe.solve import solve_scene
from snapjump_cli.geometry.caps import CapScene
from snapjump_cli.settings import MeshSettings, SolverSettings

SCENE = CapScene(theta_deg=60.0, eta=10.0, bc="ring-roller")
MESH = MeshSettings(nt=1, aspect=2.0)


@pytest.fixture(scope="module")
def traced():
    res = solve_scene(SCENE, MESH, SolverSettings())
    chk = check_harmonics(res, 2)
    shape = imperfection_shape(res, 1)
    runs = {d: trace_imperfect(res, shape, d, inner_thickness(SCENE)) for d in (1e-3, 1e-2)}
    return res, chk, shape, runs


def test_the_shape_is_the_critical_mode(traced):
    res, chk, shape, _ = traced
    assert chk.asym_first and chk.asym_n == 1
    assert shape.source == "critical" and abs(shape.eig) < 1e-8
    sV = res.tracer.sc[0] * res.model.L**3
    assert shape.V * sV == pytest.approx(chk.asym_V_m3, rel=2e-3)  # the check's onset, to its bisection


def test_the_imperfect_snap_follows_koiters_two_thirds_law(traced):
    res, chk, shape, runs = traced
    sV = res.tracer.sc[0] * res.model.L**3
    V_c = shape.V * sV
    drops = {}
    for d, r in runs.items():
        m = r.metrics
        assert m["dE_J"] > 0 and m["lower_state_method"] == "path"
        assert abs(m["dE_J"] - m["dE_path_J"]) < 1e-3 * m["dE_J"]  # energy difference against -int p dV
        assert m["V_star_m3"] < V_c  # the imperfection lowers the snap below the bifurcation
        assert m["imp_amplitude_m"] == pytest.approx(d * inner_thickness(SCENE))
        drops[d] = V_c - m["V_star_m3"]
    exponent = math.log10(drops[1e-2] / drops[1e-3])
    assert 0.55 < exponent < 0.8  # Koiter: 2/3
    # the larger imperfection releases less energy (the snap comes earlier, from a less loaded state)
    assert runs[1e-2].metrics["dE_J"] < runs[1e-3].metrics["dE_J"]


def test_curve_reports_the_imperfect_snap(capsys):
    rc = main(["--cap", "--theta", "60", "--eta", "10", "--bc", "ring-roller", "--nt", "1", "--aspect", "2",
               "--harmonics", "2", "--imperfection", "0.01", "--format", "json"])
    assert rc == 0
    m = json.loads(capsys.readouterr().out)
    assert m["imp_delta"] == 0.01 and m["imp_n"] == 1 and m["imp_N"] == 4 and m["imp_shape"] == "critical"
    assert 0 < m["imp_V_star_m3"] < m["asym_V_m3"] < m["V_star_m3"]
    assert 0 < m["imp_dE_J"] < m["dE_J"]


def test_curve_imperfection_options_are_checked(capsys):
    assert main(["--design", "D", "--imperfection-n", "2"]) == 2
    assert "--imperfection-n needs --imperfection" in capsys.readouterr().err
    assert main(["--design", "D", "--imperfection", "-0.1"]) == 2
    assert main(["--design", "C", "--air-ml", "45", "--imperfection", "0.01"]) == 2
