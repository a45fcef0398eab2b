"""``snapjump mesh``: output keys, files written, and bad input (exit 2, one line, nothing written)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from snapjump_cli import cli
from snapjump_cli.commands import mesh as mesh_cmd
from snapjump_cli.geometry.designs import get_design
from snapjump_cli.geometry.caps import CapScene, cap_volumes, design_points, design_volumes

STABLE_KEYS = ("R_o_m", "Delta_m", "n_nodes", "n_elements", "V_inner_solid_m3", "V_outer_solid_m3",
               "V_cavity_m3", "h_pole_m")


def run(capsys, *args):
    rc = mesh_cmd.main(list(args))
    out, err = capsys.readouterr()
    return rc, out, err


def run_json(capsys, *args):
    rc, out, err = run(capsys, *args, "--format", "json")
    assert rc == 0, err
    return json.loads(out)


def test_help(capsys):
    rc, out, _ = run(capsys, "--help")
    assert rc == 0
    for opt in ("--design", "--eta-i", "--theta-o", "--mu-ratio", "--cap", "--theta", "--eta", "--bc",
                "--radius-mm", "--order", "--nt", "--aspect", "--out", "--format"):
        assert opt in out, opt
    rc = cli.main(["--help"])
    assert rc == 0 and "mesh" in capsys.readouterr().out


def test_design_json(capsys):
    s = run_json(capsys, "--design", "C", "--nt", "4")
    assert all(k in s for k in STABLE_KEYS)
    d = get_design("C")
    p, ex = design_points(d), design_volumes(d)
    assert s["R_o_m"] == pytest.approx(d.R_o, rel=1e-14)
    assert s["Delta_m"] == pytest.approx(d.Delta, rel=1e-14)
    assert s["h_pole_m"] == pytest.approx(p["1"][1] - (p["7"][1] - d.t_ring), rel=1e-14)
    assert s["V_inner_solid_m3"] == pytest.approx(ex["inner_solid"], rel=1e-6)
    assert s["V_outer_solid_m3"] == pytest.approx(ex["outer_solid"], rel=1e-6)
    assert s["V_cavity_m3"] == pytest.approx(ex["cavity"], rel=1e-6)
    assert s["V_inner_solid_m3"] != ex["inner_solid"]  # meshed, not the exact value
    assert s["n_nodes"] == 1437 and s["n_elements"] == 316  # Q9, nt = 4, aspect 2
    assert s["order"] == 2 and s["nt"] == {"inner_cap": 4, "ring": 2, "outer_cap": 4}
    assert s["name"] == "C" and s["scene"] == "design"


def test_explicit_parameters_match_named_design(capsys):
    a = run_json(capsys, "--design", "C", "--order", "1", "--nt", "3")
    b = run_json(capsys, "--eta-i", "8.5", "--theta-i", "60", "--eta-o", "16.5", "--theta-o", "90",
                 "--mu-ratio", "5.8", "--order", "1", "--nt", "3")
    for k in STABLE_KEYS:
        assert a[k] == b[k], k
    assert b["name"] is None and a["nt"]["inner_cap"] == 3 and a["order"] == 1


def test_radius(capsys):
    a = run_json(capsys, "--design", "C", "--order", "1")
    b = run_json(capsys, "--design", "C", "--order", "1", "--radius-mm", "60")
    assert b["R_o_m"] == pytest.approx(2 * a["R_o_m"], rel=1e-14)
    assert b["V_cavity_m3"] == pytest.approx(8 * a["V_cavity_m3"], rel=1e-12)


def test_cap_json(capsys):
    s = run_json(capsys, "--cap", "--theta", "60", "--eta", "30")
    assert all(k in s for k in STABLE_KEYS)
    assert s["scene"] == "cap-inner" and s["bc"] == "clamped"
    for k in ("R_o_m", "Delta_m", "V_outer_solid_m3", "V_cavity_m3", "h_pole_m"):
        assert s[k] is None, k
    ex = cap_volumes(CapScene(theta_deg=60, eta=30))
    assert s["V_inner_solid_exact_m3"] == ex["solid"] and s["V_under_exact_m3"] == ex["under"]
    assert s["V_inner_solid_m3"] == pytest.approx(ex["solid"], rel=1e-6)
    assert s["V_under_m3"] == pytest.approx(ex["under"], rel=1e-6)

    s = run_json(capsys, "--cap", "outer", "--theta", "77", "--eta", "12.9", "--radius-mm", "40")
    assert s["scene"] == "cap-outer" and s["R_o_m"] == pytest.approx(0.040)
    assert s["V_inner_solid_m3"] is None and s["V_outer_solid_m3"] > 0

    s = run_json(capsys, "--cap", "--theta", "60", "--eta", "8.5", "--bc", "ring-roller", "--nt", "4")
    assert s["h_pole_m"] == pytest.approx(0.030 * (1 - 0.5 / 8.5) - (0.030 * 0.5 - 0.001), rel=1e-12)
    assert s["nt"]["ring"] == 2


def test_text_format(capsys):
    rc, out, err = run(capsys, "--design", "D")
    assert rc == 0 and err == ""
    assert out.startswith("design D:") and "R_o =" in out and "V cavity" in out and "nodes" in out
    rc, out, _ = run(capsys, "--cap", "--theta", "60", "--eta", "8.5", "--bc", "roller-point")
    assert rc == 0 and out.startswith("inner cap:") and "roller-point" in out


@pytest.mark.parametrize("suffix, cell", [(".msh", "quad9"), (".vtu", "quad9")])
def test_out_files(capsys, tmp_path, suffix, cell):
    meshio = pytest.importorskip("meshio")
    target = tmp_path / f"c{suffix}"
    s = run_json(capsys, "--design", "C", "--out", str(target))
    assert s["out"] == str(target)
    assert [p.name for p in tmp_path.iterdir()] == [target.name]  # no temp file left behind
    m = meshio.read(target)
    assert m.points.shape[0] == s["n_nodes"]
    assert sum(c.data.shape[0] for c in m.cells if c.type == cell) == s["n_elements"]


BAD = [
    (["--design", "Zebra"], "'Zebra'"),
    (["--eta-i", "nan", "--theta-i", "60", "--eta-o", "16.5", "--theta-o", "90"], "--eta-i"),
    (["--cap", "--theta", "60", "--eta", "NaN"], "--eta"),
    (["--cap", "--theta", "60", "--eta", "-2"], "-2"),
    (["--cap", "--theta", "200", "--eta", "8.5"], "200"),
    (["--eta-i", "8.5", "--theta-i", "90", "--eta-o", "16.5", "--theta-o", "60"], "theta_i < theta_o"),
    (["--eta-i", "5", "--theta-i", "70", "--eta-o", "5", "--theta-o", "72"], "y_2 < y_3"),
    (["--eta-i", "8.5", "--theta-i", "60"], "--eta-o"),
    (["--design", "C", "--cap", "--theta", "60", "--eta", "8.5"], "--design"),
    (["--design", "C", "--eta-i", "8.5"], "--eta-i"),
    (["--cap", "outer", "--theta", "77", "--eta", "12.9", "--bc", "roller"], "--bc"),
    (["--cap", "--theta", "60"], "--eta"),
    ([], "--design"),
    (["--design", "C", "--nt", "0"], "--nt"),
    (["--design", "C", "--order", "3"], "--order"),
    (["--design", "C", "--aspect", "inf"], "--aspect"),
    (["--design", "C", "--radius-mm", "-30"], "-30"),
    (["--design", "C", "--mu-ratio", "abc"], "'abc'"),
]


@pytest.mark.parametrize("args, needle", BAD, ids=[" ".join(a) or "none" for a, _ in BAD])
def test_bad_input(capsys, tmp_path, args, needle):
    target = tmp_path / "m.msh"
    rc, out, err = run(capsys, *args, "--out", str(target))
    assert rc == 2
    assert out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("Error: "), err
    assert needle in lines[0]
    assert "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("name", ["m.txt", "m", "m.msh.bak"])
def test_bad_out_suffix(capsys, tmp_path, name):
    rc, out, err = run(capsys, "--design", "C", "--out", str(tmp_path / name))
    assert rc == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and name in err and ".msh or .vtu" in err and ".step" in err
    assert list(tmp_path.iterdir()) == []


def test_out_missing_folder(capsys, tmp_path):
    rc, _, err = run(capsys, "--design", "C", "--out", str(tmp_path / "no" / "m.msh"))
    assert rc == 2 and "does not exist" in err


def test_console_script(tmp_path):
    """The ``snapjump`` script installed next to this interpreter (the venv's bin, not whatever
    ``PATH`` finds), which runs this checkout."""
    exe = Path(sys.executable).with_name("snapjump")
    if not exe.exists():
        pytest.skip(f"no snapjump console script next to {sys.executable}: snapjump is not installed in this environment")
    lines = exe.read_text().splitlines()
    assert lines[0].startswith("#!")
    python = lines[0][2:].strip()
    if python == "/bin/sh":  # pip's form for a long interpreter path: '''exec' /path/python "$0" "$@"
        python = lines[1].split()[1]
    r = subprocess.run([python, "-c", "import snapjump_cli; print(snapjump_cli.__file__)"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert Path(r.stdout.strip()).resolve() == Path(cli.__file__).resolve().with_name("__init__.py")  # this checkout
    r = subprocess.run([exe, "mesh", "--design", "A", "--order", "1", "--format", "json"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["n_elements"] > 0
    r = subprocess.run([exe, "mesh", "--design", "A", "--eta-o", "nan", "--out", str(tmp_path / "x.msh")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and "--eta-o" in r.stderr and "Traceback" not in r.stderr
    assert list(tmp_path.iterdir()) == []


def test_existing_out_is_kept_unless_overwrite(capsys, tmp_path):
    target = tmp_path / "m.msh"
    target.write_text("old")
    rc, _, err = run(capsys, "--design", "C", "--out", str(target))
    assert rc == 2 and "exists; pass --overwrite" in err and target.read_text() == "old"
    rc, _, _ = run(capsys, "--design", "C", "--out", str(target), "--overwrite")
    assert rc == 0 and target.read_text() != "old"
