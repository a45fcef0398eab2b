"""The mesh re-check of a design whose coarse path went to zero cavity volume stops its own trace at
the upper state (``solve_scene(..., post_snap=False)``): the same answers as the whole trace."""
from __future__ import annotations

import dataclasses

import pytest

import snapjump_cli.fe.solve as solve
from snapjump_cli.fe.stability.harmonics import check_harmonics
from snapjump_cli.fe.axisym.snap import POST_SNAP_SKIPPED
from snapjump_cli.geometry.caps import Design
from snapjump_cli.settings import MeshSettings, SolverSettings

#: a paper-grid design (index 4731) whose nt 2 path goes to zero volume: its lower state is found
#: by descent, and it is re-solved at nt 3
DESIGN = Design(eta_i=8.0, theta_i_deg=80.0, eta_o=40.0 / 3.0, theta_o_deg=86.0, mu_ratio=5.8)
MESH = MeshSettings(order=2, nt=2, aspect=3.0)  # the paper grid's
FINER = MeshSettings(order=2, nt=3, aspect=3.0)
#: what the shorter trace may change (it describes the path traced), and the timings
TRACE_KEYS = {"n_steps", "n_newton", "self_crossing", "stop_reason", "n_rejected", "n_bifurcations",
              "wall_s", "mesh_s", "t_assembly_s", "t_residual_s", "t_factor_s", "t_newton_s", "n_factorizations",
              "n_assemblies"}


@pytest.fixture(scope="module")
def solved():
    solver = SolverSettings()
    coarse = solve.solve_scene(DESIGN, MESH, solver)
    full = solve.solve_scene(DESIGN, FINER, solver)
    short = solve.solve_scene(DESIGN, FINER, solver, post_snap=False)
    return coarse, full, short


def test_the_design_is_a_case_of_the_short_recheck(solved):
    coarse, full, short = solved
    assert coarse.metrics["stop_reason"] == "cavity volume reached zero"
    assert coarse.metrics["lower_state_method"] == "descent"
    assert solve._short_recheck(coarse.metrics, SolverSettings(), {})
    assert full.metrics["stop_reason"] == "cavity volume reached zero"
    assert short.metrics["stop_reason"] == POST_SNAP_SKIPPED
    assert short.metrics["n_steps"] < full.metrics["n_steps"]


def test_the_short_trace_gives_the_same_answers(solved):
    _, full, short = solved
    a, b = full.metrics, short.metrics
    assert set(a) == set(b)
    for k in sorted(set(a) - TRACE_KEYS):
        assert a[k] == b[k], k  # bit for bit: the same upper state and the same lower state at fixed volume
    # the traced path up to (and beyond) the upper state is the same path
    n = len(short.path.points)
    for p, q in zip(full.path.points[:n], short.path.points):
        assert (p.u == q.u).all() and p.p == q.p
    assert short.states.cusp_change == full.states.cusp_change and short.states.fold_note == full.states.fold_note
    assert not short.lower.from_path


def test_the_harmonic_check_is_the_same(solved):
    _, full, short = solved
    ha, hb = check_harmonics(full, 4).as_dict(), check_harmonics(short, 4).as_dict()
    for k in ha:
        if k != "asym_wall_s":
            assert ha[k] == hb[k], k


def test_solve_design_reports_the_short_recheck(solved, monkeypatch):
    coarse, full, short = solved
    solver = SolverSettings()
    m = solve.solve_design(DESIGN, MESH, solver)
    assert m["mesh_check"].startswith("lower state by descent; re-solved at nt=3 to the snap")
    assert m["self_crossing"] is bool(coarse.metrics["self_crossing"] or short.metrics["self_crossing"])
    assert m["n_steps"] == short.metrics["n_steps"]
    for k in ("dE_J", "dy_pole_m", "p_star_Pa", "V_star_m3", "h_imp_m", "lower_state_method", "mesh_sensitive"):
        ref = full.metrics[k] if k != "mesh_sensitive" else False
        assert m[k] == ref, k
    assert m["dE_J_coarse"] == coarse.metrics["dE_J"]


def test_a_lower_state_that_needed_the_path_is_solved_again_in_full(monkeypatch):
    """Where the short trace's lower state came from the energy descent started at a post-snap
    point (here: pretended), the re-check is solved again with the whole trace."""
    calls = []
    real = solve.solve_scene

    def spy(scene, mesh, solver, **kw):
        calls.append((mesh.nt, kw.get("post_snap", True)))
        res = real(scene, mesh, solver, **kw)
        if not kw.get("post_snap", True):
            res.lower = dataclasses.replace(res.lower, from_path=True)
        return res

    monkeypatch.setattr(solve, "solve_scene", spy)
    m = solve.solve_design(DESIGN, MESH, SolverSettings())
    assert calls == [(2, True), (3, False), (3, True)]
    assert m["mesh_check"] == "lower state by descent; re-solved at nt=3"
    assert m["stop_reason"] == "cavity volume reached zero"


def test_curve_traces_the_whole_rechecked_path(solved):
    """``solve_checked`` as ``snapjump curve`` calls it keeps the re-check's whole path (it draws it)."""
    _, full, _ = solved
    res = solve.solve_checked(DESIGN, MESH, SolverSettings())
    m = res.metrics
    assert m["mesh_check"] == "lower state by descent; re-solved at nt=3"
    assert m["stop_reason"] == "cavity volume reached zero" and m["n_steps"] == full.metrics["n_steps"]
    assert m["self_crossing"] == full.metrics["self_crossing"] and len(res.path.points) == len(full.path.points)


def test_no_short_recheck_with_the_whole_curve_or_without_zero_volume():
    m = {"lower_state_method": "descent", "stop_reason": "cavity volume reached zero"}
    assert solve._short_recheck(m, SolverSettings(), {})
    assert not solve._short_recheck(m, SolverSettings(full=True), {})
    assert not solve._short_recheck({**m, "stop_reason": "snap characterised"}, SolverSettings(), {})
    assert not solve._short_recheck({**m, "lower_state_method": "path"}, SolverSettings(), {})
    assert not solve._short_recheck(m, SolverSettings(), {"fluid": object()})

