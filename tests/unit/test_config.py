"""Grid YAML schema: defaults, expansion, and one precise error per kind of mistake."""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from snapjump_cli.sweep.config import GRID_AXES, ConfigError, load_config, parse_config
from snapjump_cli.settings import MeshSettings, SolverSettings

REPO = Path(__file__).resolve().parents[2]
GRID = {"eta_i": [6], "theta_i": [80], "eta_o": [12], "theta_o": [82, 85], "mu_ratio": [5.8]}


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "grid.yaml"
    p.write_text(text)
    return p


def test_only_grid_is_valid_and_defaults_apply(tmp_path):
    p = _write(tmp_path, "grid: {eta_i: [6], theta_i: [80], eta_o: [12], theta_o: [82, 85], mu_ratio: [5.8]}\n")
    c = load_config(p)
    assert c.n_designs == 2
    assert c.mesh == MeshSettings() and c.solver == SolverSettings()
    assert c.R_i == 0.03 and c.mu_i == 0.35e6 and c.J_m == 24
    assert c.t_ring_frac == 1 / 30 and c.w_ring_frac == 0.1
    assert c.n_jobs == -1 and c.chunk_size >= 1
    assert c.output == Path("results/grid.parquet")
    pts = list(c.designs())
    assert [p.theta_o_deg for p in pts] == [82.0, 85.0] and [p.index for p in pts] == [0, 1]
    assert all(isinstance(getattr(pts[0], a), float) for a in ("eta_i", "theta_i_deg", "mu_ratio"))


def test_range_expansion_and_all_sections():
    doc = {
        "grid": {"eta_i": {"start": 5, "stop": 8, "num": 4}, "theta_i": [70], "eta_o": [10],
                 "theta_o": {"start": 80, "stop": 80, "num": 1}, "mu_ratio": [1, "5.8"]},
        "R_i": 0.02, "materials": {"mu_i": "0.35e6", "J_m": 30}, "ring": {"t_ring_frac": "1/30", "w_ring_frac": 0.2},
        "mesh": {"order": 1, "nt": 2, "aspect": 3}, "solver": {"tol": 1e-8, "max_steps": 50, "full": True},
        "output": "x/y.parquet", "n_jobs": 2, "chunk_size": 3,
    }
    c = parse_config(doc, "mem.yaml")
    assert c.grid["eta_i"] == (5.0, 6.0, 7.0, 8.0)
    assert c.grid["theta_o"] == (80.0,)
    assert c.grid["mu_ratio"] == (1.0, 5.8)
    assert c.n_designs == 8
    assert (c.R_i, c.mu_i, c.J_m, c.t_ring_frac, c.w_ring_frac) == (0.02, 0.35e6, 30.0, 1 / 30, 0.2)
    assert c.mesh == MeshSettings(order=1, nt=2, aspect=3.0)
    assert c.solver.tol == 1e-8 and c.solver.max_steps == 50 and c.solver.full is True
    assert isinstance(c.mesh.aspect, float) and isinstance(c.solver.max_steps, int)
    assert c.output == Path("x/y.parquet") and c.n_jobs == 2 and c.chunk_size == 3
    d = c.to_dict()
    assert d["grid"]["eta_i"] == [5.0, 6.0, 7.0, 8.0] and d["mesh"]["order"] == 1 and d["n_designs"] == 8


def test_shipped_configs():
    c = load_config(REPO / "configs" / "paper_grid.yaml")
    assert c.n_designs == 4800
    assert [len(c.grid[a]) for a in GRID_AXES] == [6, 5, 10, 8, 2]
    assert (min(c.grid["theta_i"]), max(c.grid["theta_i"])) == (70, 80)
    assert (min(c.grid["eta_i"]), max(c.grid["eta_i"])) == (5, 8)
    assert (min(c.grid["theta_o"]), max(c.grid["theta_o"])) == (76, 90)
    assert (min(c.grid["eta_o"]), max(c.grid["eta_o"])) == (5, 20)
    assert c.grid["mu_ratio"] == (1.0, 5.8)
    assert c.mu_i == 0.35e6 and c.t_ring_frac == 1 / 30 and c.w_ring_frac == 1 / 10
    s = load_config(REPO / "configs" / "smoke.yaml")
    assert 2 <= s.n_designs <= 4 and s.mesh.order == 1 and s.mesh.nt == 2


BAD = [
    # (yaml text, key path expected in the message, words expected in the message)
    ("grid: {eta_i: [6], theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\nbogus: 1\n", "bogus", "unknown key"),
    ("grid: {eta_i: [6], theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1], eta_x: [1]}\n", "grid.eta_x", "unknown key"),
    ("grid: {eta_i: {start: 5, stop: 8, num: 3, step: 1}, theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\n",
     "grid.eta_i.step", "unknown key"),
    ("grid: {eta_i: [6], theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\nmesh: {order: 1, ntt: 2}\n", "mesh.ntt", "unknown key"),
    ("grid: {eta_i: [6], theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\nsolver: {tolerance: 1}\n", "solver.tolerance", "unknown key"),
    ("grid: {eta_i: 6, theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\n", "grid.eta_i", "expected a non-empty list"),
    ("grid: [1, 2]\n", "grid", "expected a mapping"),
    ("grid: {eta_i: {start: 5, stop: 8, num: 0}, theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\n",
     "grid.eta_i.num", "integer >= 1"),
    ("grid: {eta_i: {start: 5, stop: 8, num: -2}, theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\n",
     "grid.eta_i.num", "integer >= 1"),
    ("grid: {eta_i: {start: 5, stop: 8, num: 2.5}, theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\n",
     "grid.eta_i.num", "integer"),
    ("grid: {eta_i: {start: 8, stop: 5, num: 3}, theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\n",
     "grid.eta_i.stop", "stop >= start"),
    ("grid: {eta_i: {start: 5, stop: 8, num: 1}, theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\n",
     "grid.eta_i.num", "num >= 2"),
    ("grid: {eta_i: {start: 5, num: 3}, theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\n",
     "grid.eta_i.stop", "missing"),
    ("grid: {eta_i: [], theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\n", "grid.eta_i", "empty list"),
    ("grid: {eta_i: [6, abc], theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\n", "grid.eta_i[1]", "'abc'"),
    ("grid: {eta_i: [6, true], theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\n", "grid.eta_i[1]", "boolean"),
    ("grid: {eta_i: [6, .nan], theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\n", "grid.eta_i[1]", "finite"),
    ("grid: {eta_i: [6, 6], theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\n", "grid.eta_i[1]", "distinct"),
    ("grid: {eta_i: [6], theta_i: [80, 190], eta_o: [12], theta_o: [85], mu_ratio: [1]}\n", "grid.theta_i[1]", "(0, 180)"),
    ("grid: {eta_i: [6], theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [0]}\n", "grid.mu_ratio[0]", "> 0"),
    ("grid: {eta_i: {start: x, stop: 8, num: 3}, theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\n",
     "grid.eta_i.start", "'x'"),
    ("grid: {eta_i: [6], theta_i: [80], eta_o: [12], theta_o: [85]}\n", "grid.mu_ratio", "missing"),
    ("mesh: {order: 1}\n", "grid", "missing"),
    ("", "grid", "missing"),
    ("- 1\n- 2\n", "", "expected a mapping"),
    ("grid: {eta_i: [6], theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\nmesh: {order: 3}\n", "mesh.order", "1 or 2"),
    ("grid: {eta_i: [6], theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\nmesh: {nt: 0}\n", "mesh.nt", "[1, 64]"),
    ("grid: {eta_i: [6], theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\nmesh: {nt: 65}\n", "mesh.nt", "[1, 64]"),
    ("grid: {eta_i: [6], theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\nmesh: {aspect: 101}\n", "mesh.aspect", "(0, 100]"),
    ("grid: {eta_i: [6], theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\nsolver: {max_turn_deg: 91}\n", "solver.max_turn_deg", "(0, 90]"),
    ("grid: {eta_i: [6], theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\nsolver: {full: yes please}\n", "solver.full", "true or false"),
    ("grid: {eta_i: [6], theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\nsolver: {tol: -1}\n", "solver.tol", "(0, 0.01]"),
    ("grid: {eta_i: [6], theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\nR_i: big\n", "R_i", "> 0"),
    ("grid: {eta_i: [6], theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\nmaterials: {mu_i: 1, E: 3}\n", "materials.E", "unknown key"),
    ("grid: {eta_i: [6], theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\nring: {t_ring_frac: 0}\n", "ring.t_ring_frac", "> 0"),
    ("grid: {eta_i: [6], theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\nn_jobs: 0\n", "n_jobs", "other than 0"),
    ("grid: {eta_i: [6], theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\nchunk_size: 0\n", "chunk_size", ">= 1"),
    ("grid: {eta_i: [6], theta_i: [80], eta_o: [12], theta_o: [85], mu_ratio: [1]}\noutput: 3\n", "output", "file path"),
]


@pytest.mark.parametrize("text,key_path,words", BAD, ids=[f"{i}-{b[1] or 'top'}" for i, b in enumerate(BAD)])
def test_bad_config_names_file_key_and_expectation(tmp_path, text, key_path, words):
    p = _write(tmp_path, text)
    with pytest.raises(ConfigError) as ei:
        load_config(p)
    msg = str(ei.value)
    assert msg.startswith(f"{p}: "), msg
    assert ei.value.key_path == key_path, msg
    if key_path:
        assert f": {key_path}: " in msg, msg
    assert words in msg, msg
    assert "\n" not in msg


def test_yaml_syntax_error_names_file_and_line(tmp_path):
    p = _write(tmp_path, "grid:\n  eta_i: [6, 7\n  theta_i: [80]\n")
    with pytest.raises(ConfigError, match=r"grid\.yaml: YAML syntax error at line \d+"):
        load_config(p)


def test_file_not_found_and_directory(tmp_path):
    with pytest.raises(ConfigError, match=r"nope\.yaml: file not found"):
        load_config(tmp_path / "nope.yaml")
    with pytest.raises(ConfigError, match="directory"):
        load_config(tmp_path)


def test_linspace_values_are_exact_endpoints():
    c = parse_config({"grid": {**GRID, "eta_o": {"start": 5, "stop": 20, "num": 10}}})
    v = c.grid["eta_o"]
    assert v[0] == 5.0 and v[-1] == 20.0 and len(v) == 10 and all(math.isfinite(x) for x in v)


def test_solver_harmonics_setting():
    from snapjump_cli.sweep.config import ConfigError, parse_config

    grid = {"grid": {"eta_i": [6], "theta_i": [80], "eta_o": [12], "theta_o": [85], "mu_ratio": [1]}}
    assert parse_config({**grid, "solver": {"harmonics": 4}}).solver.harmonics == 4
    with pytest.raises(ConfigError, match=r"solver.harmonics: expected an integer in \[0, 64\]"):
        parse_config({**grid, "solver": {"harmonics": 65}}, "x.yaml")
