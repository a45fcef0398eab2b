"""A short sample of the stress suite that runs in ``make test`` (not marked ``stress``; coarse
Q4 meshes, a few seconds): the row contract on 4 random extended-domain designs through the real
sweep, dE invariance under the initial arc length (x0.25, x4) and a 10x tighter tolerance on a
cheap cap, and bitwise-identical results of two identical sweeps."""
from __future__ import annotations

import dataclasses

import pytest

import stresslib as sl
from snapjump_cli.geometry.caps import CapScene
from snapjump_cli.settings import MeshSettings, SolverSettings

COARSE = MeshSettings(order=1, nt=2, aspect=2.0)


@pytest.fixture(scope="module")
def warm():
    from snapjump_cli.fe.solve import warm_up

    warm_up()


def test_sample_rows_are_classified_and_deterministic(tmp_path, warm, monkeypatch):
    pts = sl.random_extended(4, seed=1)  # 2 valid, 2 violating eq 5
    a = sl.sweep(pts, tmp_path / "a.parquet", mesh=COARSE, n_jobs=1)
    assert len(a) == 4
    assert not sl.check_rows(a)
    assert (a["status"] == "invalid_geometry").sum() == sum(not sl.valid(p) for p in pts) == 2
    assert set(a["status"]) <= {"ok", "no_snap", "invalid_geometry", "failed"}
    # the repeat solves the cheap designs only (#2 and the invalid #3) and compares those rows
    b = sl.sweep(pts[2:], tmp_path / "b.parquet", mesh=COARSE, n_jobs=1)
    assert len(b) == 2 and not sl.compare_bitwise(a, b, common_only=True)
    assert "designs: ok" in sl.summarize(a, "sample")
    # the checker itself: a NaN metric in an ok row, an inf anywhere, a failed row without cause
    bad = a.copy()
    bad.loc[0, ["status", "snaps", "error"]] = ["ok", True, ""]
    bad.loc[0, "dE_J"] = float("nan")
    bad.loc[1, "p_star_Pa"] = float("inf")
    bad.loc[3, ["status", "error"]] = ["failed", ""]
    msgs = "\n".join(sl.check_rows(bad))
    assert "ok row with dE_J = NaN" in msgs and "p_star_Pa = inf" in msgs and "failed without a cause" in msgs
    # a failed row names its cause by the exception type or by the row check's own wording
    from snapjump_cli.sweep.rows import ROW_CHECK_ERRORS

    failed = a.copy()
    failed.loc[0, ["status", "error"]] = ["failed", ROW_CHECK_ERRORS["range"] + ": h_imp_m=-2e-05 (expected >= 0)"]
    failed.loc[1, ["status", "error"]] = ["failed", "SolveFailed: continuation failed"]
    assert not sl.check_rows(failed)
    failed.loc[1, "error"] = "something went wrong"
    assert "does not name its cause" in "\n".join(sl.check_rows(failed))


@pytest.mark.parametrize("variant", ["ds0 x0.25", "ds0 x4", "tol /10"])
def test_sample_dE_invariance(variant, warm):
    from snapjump_cli.fe.solve import solve_scene

    cap = CapScene(theta_deg=60.0, eta=30.0, bc="clamped")
    base = SolverSettings()
    m0 = solve_scene(cap, COARSE, base).metrics
    m1 = solve_scene(cap, COARSE, sl.variant_solvers(base)[variant]).metrics
    assert m0["snaps"] and m1["snaps"]
    assert abs(m1["dE_J"] - m0["dE_J"]) <= 0.005 * abs(m0["dE_J"])
    assert abs(m1["dy_pole_m"] - m0["dy_pole_m"]) <= 0.005 * abs(m0["dy_pole_m"])


def test_sample_identical_runs_are_bitwise_identical(warm):
    from snapjump_cli.fe.solve import solve_scene

    cap = CapScene(theta_deg=60.0, eta=8.5, bc="roller-point")
    runs = [solve_scene(cap, COARSE, SolverSettings()).metrics for _ in range(2)]
    skip = {"wall_s", "mesh_s", "t_assembly_s", "t_residual_s", "t_factor_s", "t_newton_s"}
    for k in runs[0]:
        if k not in skip:
            assert runs[0][k] == runs[1][k] or (runs[0][k] != runs[0][k] and runs[1][k] != runs[1][k]), k


def test_points_config_and_classifier():
    cfg = sl.points_config(sl.random_extended(3, seed=2), mesh=COARSE, n_jobs=1)
    assert cfg.n_designs == 3 and [p.index for p in cfg.designs()] == [0, 1, 2]
    assert cfg.to_dict()["points"][1]["eta_i"] == cfg.points[1][0] == list(cfg.designs())[1].eta_i
    assert sl.cause_of("SolveFailed: volume limit found (V*=1e-4 m^3) but no lower state (x)").startswith("lower state")
    assert sl.cause_of("SolveFailed: continuation failed: max_steps") == "continuation failed"
    assert sl.normalise("V*=1.5e-4 m^3 after 12 steps") == "V*=# m^# after # steps"
    v = sl.variant_solvers(SolverSettings())
    assert v["ds0 x4"].ds0 == 4 * SolverSettings().ds0 and v["tol /10"].tol == SolverSettings().tol / 10
    assert dataclasses.replace(SolverSettings(), ds0=1.0).ds0 == 1.0
