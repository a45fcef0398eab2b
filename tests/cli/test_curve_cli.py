"""``snapjump curve``: help, JSON keys, CSV/plot outputs, bad input (exit 2, nothing written)."""
from __future__ import annotations

import json

import pytest

from snapjump_cli.commands.curve import main

STABLE_KEYS = (
    "dE_J", "dE_norm", "dE_energy_J", "dE_path_J", "dy_pole_m", "dy_pole_norm", "p_star_Pa",
    "V_star_m3", "p_max_Pa", "h_imp_m", "L0_m", "snaps", "self_crossing", "lower_state_method",
    "n_steps", "n_newton", "wall_s", "mesh_sensitive", "mesh_check", "dE_J_coarse", "dy_pole_m_coarse",
)
CHEAP = ["--cap", "--theta", "60", "--eta", "8.5", "--bc", "roller-point"]


def test_help(capsys):
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    for opt in ("--design", "--cap", "--bc", "--order", "--nt", "--full", "--format", "--csv", "--plot"):
        assert opt in out


def test_json_keys_and_outputs(capsys, tmp_path):
    csv_path, png = tmp_path / "c.csv", tmp_path / "c.png"
    rc = main([*CHEAP, "--format", "json", "--csv", str(csv_path), "--plot", str(png)])
    out = capsys.readouterr().out
    assert rc == 0
    m = json.loads(out)
    assert all(k in m for k in STABLE_KEYS)
    assert m["snaps"] is True and m["lower_state_method"] in ("path", "descent")
    assert m["mesh_sensitive"] is False and m["mesh_check"] == "" and m["dE_J_coarse"] is None
    assert m["dE_J"] > 0 and m["dy_pole_m"] > 0
    assert abs(m["dE_energy_J"] - m["dE_path_J"]) <= 5e-3 * m["dE_J"]
    assert m["dE_norm"] == pytest.approx(m["dE_J"] / (0.35e6 * 0.03**3), rel=1e-12)
    lines = csv_path.read_text().splitlines()
    assert lines[0] == "p_Pa,V_m3,y_pole_m,strain_energy_J,arc_length,step,state,on_path,branch"
    assert {line.split(",")[8] for line in lines[1:]} == {"axisymmetric"}
    # the path's n_steps + 1 points and the named states solved between them (p_max, upper, lower)
    assert m["n_steps"] + 1 + 2 <= len(lines) - 1 <= m["n_steps"] + 1 + 3
    states = [line.split(",")[6] for line in lines[1:]]
    assert states[0] == "start" and states.count("upper") == 1 and states.count("lower") == 1
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_text_summary(capsys):
    assert main(CHEAP) == 0
    out = capsys.readouterr().out
    assert "dE" in out and "dy_pole" in out and "mJ" in out


@pytest.mark.parametrize(
    "args,needle",
    [
        (["--design", "Z"], "Z"),
        (["--cap", "--theta", "nan", "--eta", "8"], "--theta"),
        (["--cap", "--theta", "60", "--eta", "-3"], "eta"),
        (["--design", "C", "--plot", "out.txt"], "out.txt"),
        (["--design", "C", "--csv", "nodir/x.csv"], "nodir"),
        (["--design", "C", "--csv", "/proc/x.csv"], "/proc/x.csv"),
        (["--eta-i", "8", "--theta-i", "80", "--eta-o", "10", "--theta-o", "70", "--mu-ratio", "1"], "theta_i"),
    ],
)
def test_bad_input_exit_2(capsys, tmp_path, monkeypatch, args, needle):
    monkeypatch.chdir(tmp_path)
    assert main(args) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


def test_outputs_under_a_file_or_existing_are_refused(capsys, tmp_path):
    f = tmp_path / "a_file"
    f.write_text("x")
    assert main([*CHEAP, "--csv", str(f / "c.csv")]) == 2
    err = capsys.readouterr().err
    assert "a_file is a file, not a folder" in err and len(err.strip().splitlines()) == 1
    png = tmp_path / "c.png"
    png.write_bytes(b"old")
    assert main([*CHEAP, "--plot", str(png)]) == 2
    assert "exists; pass --overwrite" in capsys.readouterr().err and png.read_bytes() == b"old"
    assert main([*CHEAP, "--plot", str(png), "--overwrite"]) == 0
    assert png.read_bytes()[:4] == b"\x89PNG"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file", "c.png"]  # no temporary files left


def test_curve_reports_what_the_sweep_reports(monkeypatch, capsys):
    """One answer per design: curve goes through the sweep's solve (the mesh check and re-solve)."""
    import snapjump_cli.fe.solve as solve

    calls = []

    def fake_scene(scene, mesh, solver, **kw):
        calls.append((mesh.nt, mesh.aspect))
        m = {"snaps": True, "dE_J": 2.78e-3 if mesh.nt == 2 else 6.39e-3, "dE_norm": 0.3, "dy_pole_m": 0.0102,
             "lower_state_method": "path", "fold_note": "volume limit at a near-cusp: x" if mesh.nt == 2 else ""}
        return solve.SceneResult(metrics=m)

    monkeypatch.setattr(solve, "solve_scene", fake_scene)
    monkeypatch.setattr("snapjump_cli.commands.curve._text", lambda scene, m: f"{m['dE_J']} {m['mesh_check']}")
    assert main(["--design", "A"]) == 0
    out = capsys.readouterr().out
    assert calls == [(2, 2.0), (3, 1.5)]
    assert out.startswith("0.00639 volume limit at a near-cusp; re-solved at nt=3, aspect=1.5")


def test_harmonics_option_reports_the_asymmetric_check(capsys):
    """Fig. S16's inner cap (eta 10, theta 60, ring-roller): a harmonic (n = 1) loses stability
    before V*, which the axisymmetric self-crossing heuristic misses (docs/harmonics.md)."""
    scene = ["--cap", "--theta", "60", "--eta", "10", "--bc", "ring-roller", "--format", "json"]
    assert main(scene) == 0
    off = json.loads(capsys.readouterr().out)
    assert all(off[k] is None for k in ("asym_first", "asym_n", "asym_V_m3", "asym_p_Pa", "asym_lower_stable"))
    assert main([*scene, "--harmonics", "3"]) == 0
    on = json.loads(capsys.readouterr().out)
    assert on["asym_first"] is True and on["asym_n"] == 1 and on["self_crossing"] is False
    assert 0 < on["asym_V_m3"] <= on["V_star_m3"] and 0 < on["asym_p_Pa"] <= on["p_max_Pa"]
    assert on["dE_J"] == off["dE_J"]  # the check does not change the axisymmetric answer
