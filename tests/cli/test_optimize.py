"""``snapjump optimize``: spec validation (exit 2 naming the key path), the search on an analytic
fake solver (determinism, resume, never an infeasible design, both methods), and a real run: a
two-parameter box around design D on a coarse mesh reaches at least D's jump on that mesh."""
from __future__ import annotations

import json
import math

import pytest
import yaml

from snapjump_cli.cli import main as cli_main
from snapjump_cli.commands import optimize as optimize_cmd
from snapjump_cli.geometry.caps import design_volumes
from snapjump_cli.optimize import finer_mesh, parse_spec, run_optimize
from snapjump_cli.settings import MeshSettings

from snapjump_cli.sweep.rows import BOOL_RESULT_KEYS, INT_RESULT_KEYS, RESULT_KEYS, STR_RESULT_KEYS

#: design D: (6.2, 80, 12.1, 82, 5.8); its box of eta_i and eta_o, the other three fixed.
D_BOX = {"eta_i": [5.9, 6.5], "theta_i": 80, "eta_o": [11.5, 12.7], "theta_o": 82, "mu_ratio": 5.8}


def _run(capsys, *argv: str) -> tuple[int, str, str]:
    code = cli_main(["optimize", *argv])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def test_help_and_module(capsys):
    code, out, _ = _run(capsys, "--help")
    assert code == 0
    for word in ("SPEC.yaml", "--budget", "--from", "--format", "bounds", "resumes", "mesh_sensitive"):
        assert word in out, word
    assert optimize_cmd.command.name == "optimize"


BAD = [
    ("bonds: {}\n", "bonds", "unknown key"),
    ("budget: 10\n", "bounds", "missing required key"),
    ("bounds: {eta_i: [5, 8], theta_i: 80, eta_o: 12, theta_o: 82}\n", "bounds.mu_ratio", "missing required key"),
    ("bounds: {eta_i: [8, 5], theta_i: 80, eta_o: 12, theta_o: 82, mu_ratio: 5.8}\n", "bounds.eta_i[1]", "hi >= lo"),
    ("bounds: {eta_i: [5, 8], theta_i: [70, 190], eta_o: 12, theta_o: 82, mu_ratio: 5.8}\n", "bounds.theta_i[1]",
     "degrees in (0, 180)"),
    ("bounds: {eta_i: [5, 8, 9], theta_i: 80, eta_o: 12, theta_o: 82, mu_ratio: 5.8}\n", "bounds.eta_i", "list of 3"),
    ("bounds: {eta_i: 6, theta_i: 80, eta_o: 12, theta_o: 82, mu_ratio: 5.8}\n", "bounds", "free parameter"),
    ("bounds: {eta_i: [5, 8], theta_i: 80, eta_o: 12, theta_o: 82, mu_ratio: 5.8}\nobjective: height\n", "objective",
     "one of y_jump_m, dE_J"),
    ("bounds: {eta_i: [5, 8], theta_i: 80, eta_o: 12, theta_o: 82, mu_ratio: 5.8}\nbudget: 0\n", "budget", "integer >= 1"),
    ("bounds: {eta_i: [5, 8], theta_i: 80, eta_o: 12, theta_o: 82, mu_ratio: 5.8}\njump: {alpha: 2}\n", "jump.alpha",
     "[0, 1]"),
    ("bounds: {eta_i: [5, 8], theta_i: 80, eta_o: 12, theta_o: 82, mu_ratio: 5.8}\njump: {g: 3}\n", "jump.g", "unknown key"),
    ("bounds: {eta_i: [5, 8], theta_i: 80, eta_o: 12, theta_o: 82, mu_ratio: 5.8}\nmesh: {nt: two}\n", "mesh.nt",
     "integer"),
    ("bounds: {eta_i: [5, 8], theta_i: 80, eta_o: 12, theta_o: 82, mu_ratio: 5.8}\nmaterials: {mu_i: -1}\n",
     "materials.mu_i", "> 0"),
    ("bounds: {eta_i: [5, 8], theta_i: 80, eta_o: 12, theta_o: 82, mu_ratio: 5.8}\nsearch: {step: 0.1, min_step: 0.2}\n",
     "search.min_step", "min_step <= step"),
    ("bounds: {eta_i: [5, 8], theta_i: 80, eta_o: 12, theta_o: 82, mu_ratio: 5.8}\nconfirm: {tolerance: -1}\n",
     "confirm.tolerance", "> 0"),
    ("bounds: {eta_i: [5, 8], theta_i: 80, eta_o: 12, theta_o: 82, mu_ratio: 5.8}\nmethod: annealing\n", "method",
     "pattern"),
]


@pytest.mark.parametrize("text,key_path,words", BAD, ids=[b[1] + "-" + b[2][:12] for b in BAD])
def test_bad_spec_exit_2_one_line_with_key_path(tmp_path, capsys, text, key_path, words):
    p = tmp_path / "bad.yaml"
    p.write_text(text)
    out = tmp_path / "o.parquet"
    code, _, err = _run(capsys, str(p), "-o", str(out), "--no-progress")
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"Error: {p}: {key_path}: "), err
    assert words in lines[0], err
    assert not any(tmp_path.glob("o*")), "nothing may be written"


def test_bad_options_exit_2(tmp_path, capsys):
    p = tmp_path / "s.yaml"
    p.write_text(yaml.safe_dump({"bounds": D_BOX}))
    code, _, err = _run(capsys, str(p), "-o", str(tmp_path / "o.parquet"), "--from", str(tmp_path / "none.parquet"))
    assert code == 2 and "--from" in err and "none.parquet" in err and len(err.strip().splitlines()) == 1
    code, _, err = _run(capsys, str(p), "-j", "0")
    assert code == 2 and "-j/--jobs" in err
    code, _, err = _run(capsys, str(tmp_path / "missing.yaml"))
    assert code == 2 and "missing.yaml: file not found" in err


def test_finer_mesh_rule():
    assert finer_mesh(MeshSettings(order=2, nt=2, aspect=3.0)) == MeshSettings(order=2, nt=3, aspect=2.25)
    assert finer_mesh(MeshSettings(order=1, nt=1, aspect=4.0)) == MeshSettings(order=1, nt=2, aspect=4.0)


# ---- the search on an analytic fake solver ---------------------------------------------------------
CALLS: list[tuple[float, ...]] = []


def _fake_solve(design, mesh, solver) -> dict:
    """dE peaks at (eta_i, eta_o) = (6.0, 14.0), but eta_o > 13 is flagged mesh_sensitive and
    eta_i < 5.5 does not snap: the feasible optimum is on eta_o = 13. The finer mesh changes dE by 1 %."""
    CALLS.append((design.eta_i, design.eta_o, mesh.nt))
    ei, eo = design.eta_i, design.eta_o
    snaps = ei >= 5.5
    dE = 0.3 * math.exp(-((ei - 6.0) / 1.5) ** 2 - ((eo - 14.0) / 6.0) ** 2) * (1.01 if mesh.nt > 2 else 1.0)
    vol = design_volumes(design)
    out = {k: False if k in BOOL_RESULT_KEYS else "" if k in STR_RESULT_KEYS else 0 if k in INT_RESULT_KEYS else 0.0
           for k in RESULT_KEYS}
    out.update({k: None for k in RESULT_KEYS if k.startswith("asym_")})  # the harmonic check is off
    out.update(dE_J=dE if snaps else 0.0, dE_norm=1e-3, dE_energy_J=dE, dE_path_J=dE, dE_rel_diff=0.0,
               dy_pole_m=0.038, dy_pole_upper_m=0.038, dy_pole_norm=1.2, p_star_Pa=1e3, V_star_m3=1e-4,
               p_max_Pa=1e3, h_imp_m=0.015, L0_m=0.01, snaps=snaps, self_crossing=False, lower_state_method="path",
               n_steps=10, n_newton=30, wall_s=0.0, n_nodes=10, n_elements=5, n_dofs=20,
               V_inner_solid_m3=vol["inner_solid"], V_outer_solid_m3=vol["outer_solid"],
               mesh_sensitive=eo > 13.0, dE_J_coarse=None, dy_pole_m_coarse=None, mesh_check="")
    return out


def _fake_spec(method: str = "pattern", budget: int = 30) -> object:
    doc = {"bounds": {"eta_i": [5, 8], "theta_i": 80, "eta_o": [8, 16], "theta_o": 86, "mu_ratio": 5.8},
           "objective": "dE_J", "budget": budget, "seed": 3, "method": method,
           "search": {"starts": 1, "step": 0.25, "min_step": 1 / 32, "popsize": 5}, "mesh": {"order": 1, "nt": 2, "aspect": 4.0}}
    return parse_spec(doc, "fake.yaml")


@pytest.mark.parametrize("method", ["pattern", "differential_evolution"])
def test_search_with_fake_solver_feasible_deterministic_resumable(tmp_path, caplog, method):
    spec = _fake_spec(method)
    CALLS.clear()
    r1 = run_optimize(spec, output=tmp_path / "a.parquet", n_jobs=1, solve_fn=_fake_solve)
    n_search = sum(1 for c in CALLS if c[2] == 2)
    assert 0 < r1.n_evaluations == n_search <= spec.budget
    assert r1.best is not None and r1.confirmed
    assert r1.best["eta_o"] <= 13.0 and r1.best["eta_i"] >= 5.5  # never a mesh-sensitive or no-snap design
    t = r1.table
    assert {"iteration", "stage", "key", "status", "mesh_sensitive"} <= set(t.columns)
    assert list(t["stage"])[-1] == "confirm" and (t["stage"] == "confirm").sum() == len(r1.confirm_tried)
    assert math.isclose(r1.y_jump_confirmed_m, r1.confirm_row["y_jump_m"])
    if method == "pattern":
        assert r1.best["eta_o"] > 12.5 and abs(r1.best["eta_i"] - 6.0) < 0.1  # the constrained optimum
    # same seed, same output: every design is found in the cache; nothing is solved again
    CALLS.clear()
    r2 = run_optimize(spec, output=tmp_path / "a.parquet", n_jobs=1, solve_fn=_fake_solve)
    assert CALLS == [] and r2.n_resumed == r2.n_evaluations == r1.n_evaluations
    assert r2.best == r1.best and list(r2.table["key"]) == list(r1.table["key"])
    # a shorter budget on the same cache: a prefix of the same search, nothing solved, no warning
    CALLS.clear()
    r4 = run_optimize(spec, output=tmp_path / "a.parquet", n_jobs=1, budget=spec.budget // 2, solve_fn=_fake_solve)
    assert [c for c in CALLS if c[2] == 2] == [] and r4.n_evaluations <= spec.budget // 2
    assert list(r4.table["key"])[: r4.n_evaluations // 2] == list(r1.table["key"])[: r4.n_evaluations // 2]
    # same seed into a fresh output: the same designs in the same order
    r3 = run_optimize(spec, output=tmp_path / "b.parquet", n_jobs=1, solve_fn=_fake_solve)
    assert r3.best == r1.best and list(r3.table["key"]) == list(r1.table["key"])
    assert not [r for r in caplog.records if r.levelname == "WARNING"], caplog.text


def test_cache_of_other_settings_is_refused(tmp_path, capsys):
    spec = _fake_spec(budget=6)
    run_optimize(spec, output=tmp_path / "a.parquet", n_jobs=1, solve_fn=_fake_solve)
    other = spec.replace(sweep=spec.sweep.replace(mesh=MeshSettings(order=1, nt=3, aspect=4.0)))
    from snapjump_cli.optimize import OptimizeInputError

    with pytest.raises(OptimizeInputError, match="other settings"):
        run_optimize(other, output=tmp_path / "a.parquet", n_jobs=1, solve_fn=_fake_solve)


# ---- a real run -------------------------------------------------------------------------------------
def test_box_around_D_reaches_D_on_a_coarse_mesh(tmp_path, capsys):
    """Two free parameters around D (the box centre, evaluated first), 12 solves on Q9 nt 1
    aspect 4; the confirmation (nt 2, aspect 4) moves this coarse mesh's jump by ~5 %, so the
    tolerance is 10 % here. Then the same command resumes from the cache."""
    from snapjump_cli.jump.rank import rank_results
    from snapjump_cli.sweep.results import read_results

    spec = {"bounds": D_BOX, "budget": 12, "seed": 1, "search": {"starts": 2},
            "mesh": {"order": 2, "nt": 1, "aspect": 4.0}, "confirm": {"tolerance": 0.1, "candidates": 3}}
    p = tmp_path / "d.yaml"
    p.write_text(yaml.safe_dump(spec))
    out = tmp_path / "opt.parquet"
    code, stdout, err = _run(capsys, str(p), "-o", str(out), "-j", "1", "--format", "json", "--no-progress")
    assert code == 0, err
    s = json.loads(stdout)
    for k in ("best", "y_jump_m", "y_jump_confirmed_m", "dE_J", "dy_pole_m", "h_imp_m", "n_evaluations",
              "baseline_y_jump_m"):
        assert k in s, k
    assert set(s["best"]) == {"eta_i", "theta_i", "eta_o", "theta_o", "mu_ratio"}
    assert 0 < s["n_evaluations"] <= 12
    t = read_results(out)
    d_rows = t[(t["eta_i"] == 6.2) & (t["eta_o"] == 12.1) & (t["stage"] != "confirm")]
    assert len(d_rows) == 1 and d_rows["stage"].iloc[0] == "init"
    y_d = float(rank_results(d_rows)["y_jump_m"].iloc[0])
    assert s["y_jump_m"] >= y_d > 0.2
    assert abs(s["y_jump_confirmed_m"] / s["y_jump_m"] - 1) <= 0.1
    assert (tmp_path / "opt.progress.png").stat().st_size > 0 and (tmp_path / "opt.path.png").stat().st_size > 0
    code, stdout2, err = _run(capsys, str(p), "-o", str(out), "-j", "1", "--no-progress")
    assert code == 0, err
    assert f"{s['n_evaluations']} found in the cache" in stdout2 and "wrote" in stdout2


def test_quiet_and_verbose_after_the_command(capsys):
    from snapjump_cli.cli import main as cli_main

    assert cli_main(["optimize", "-q", "--help"]) == 0
    assert cli_main(["optimize", "-v", "--help"]) == 0
    assert "-q, --quiet" in capsys.readouterr().out
