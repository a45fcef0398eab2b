"""`points:` in a sweep config: an explicit list of designs, inline or from a CSV/parquet file."""
from __future__ import annotations

import pandas as pd
import pytest

from snapjump_cli.sweep.config import GRID_AXES, ConfigError, load_config, parse_config

P1 = {"eta_i": 6.2, "theta_i": 80, "eta_o": 13.3, "theta_o": 82, "mu_ratio": 5.8}
P2 = {"eta_i": 5, "theta_i": 70, "eta_o": 5, "theta_o": 76, "mu_ratio": 1}


def test_inline_points_in_order():
    c = parse_config({"points": [P1, P2]})
    pts = list(c.designs())
    assert c.n_designs == 2 and [p.index for p in pts] == [0, 1]
    assert (pts[0].eta_i, pts[0].theta_i_deg, pts[0].eta_o, pts[0].theta_o_deg, pts[0].mu_ratio) == (6.2, 80, 13.3, 82, 5.8)
    assert (pts[1].theta_o_deg, pts[1].mu_ratio) == (76, 1)
    assert c.to_dict()["points"][1] == {k: float(v) for k, v in P2.items()}


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_points_from_file_relative_to_yaml(tmp_path, suffix):
    df = pd.DataFrame([P1, P2]).rename(columns={"theta_i": "theta_i_deg", "theta_o": "theta_o_deg"})
    df["status"] = "ok"  # other columns of a result file are ignored
    f = tmp_path / f"designs{suffix}"
    df.to_csv(f, index=False) if suffix == ".csv" else df.to_parquet(f)
    y = tmp_path / "pts.yaml"
    y.write_text(f"points: designs{suffix}\n")
    c = load_config(y)
    assert c.n_designs == 2
    assert [p.theta_i_deg for p in c.designs()] == [80.0, 70.0]


@pytest.mark.parametrize("doc, key", [
    ({"points": []}, "points"),
    ({"points": [{"eta_i": 5}]}, "points[0].theta_i"),
    ({"points": [dict(P1, theta_o=190)]}, "points[0].theta_o"),
    ({"points": [dict(P1, colour=1)]}, "points[0].colour"),
    ({"points": "missing.csv"}, "points"),
    ({"points": "designs.txt"}, "points"),
    ({"points": [P1], "grid": {a: [1] for a in GRID_AXES}}, "points"),
])
def test_bad_points_name_the_key(doc, key):
    with pytest.raises(ConfigError) as e:
        parse_config(doc, "x.yaml")
    assert f"x.yaml: {key}:" in str(e.value)
