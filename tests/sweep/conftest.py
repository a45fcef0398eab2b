"""Fixtures of the sweep tests. The fake solvers live in ``snapjump_fake_solvers.py`` (test-only)."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest
import yaml

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:  # the fake solvers must be importable by reference (loky, dask)
    sys.path.insert(0, str(HERE))

#: 2 x 1 x 2 x 5 x 2 = 40 designs; theta_o = 78 < theta_i = 80 is invalid (8 designs).
SMALL_GRID = {
    "eta_i": [6, 7],
    "theta_i": [80],
    "eta_o": [5, 10],
    "theta_o": [78, 82, 84, 86, 88],
    "mu_ratio": [1, 5.8],
}


@pytest.fixture
def grid_file(tmp_path):
    """Write a grid YAML (SMALL_GRID + coarse mesh unless overridden) and return its path."""

    def make(name: str = "grid.yaml", **top):
        doc = {"grid": dict(SMALL_GRID), "mesh": {"order": 1, "nt": 2}}
        grid = top.pop("grid", None)
        if grid:
            doc["grid"].update(grid)
        doc.update(top)
        p = tmp_path / name
        p.write_text(yaml.safe_dump(doc))
        return p

    return make
