"""How close K_T's next unstable mode comes to the first volume limit (the near-cusp check of
:class:`snapjump_cli.fe.axisym.snap.SnapTracker`) on the named designs and on random designs.

For each design: the first change of neg(K_T) after the volume limit, its relative distance from
(V*, p*) ("gap", 0 in the fold's own step) and whether the tracker flagged a near-cusp.

    .venv/bin/python lab/near_cusp_survey.py named
    .venv/bin/python lab/near_cusp_survey.py grid --n 40 --aspect 3     # paper-grid designs (seeded draw)
    .venv/bin/python lab/near_cusp_survey.py points results/stress/extended_o2nt2a2_n1000_seed5.parquet \
        --where "status == 'ok'" --n 40 --aspect 2                        # any list of designs (CSV/parquet)

The ``points`` source is read like a sweep config's ``points:`` (a CSV or parquet file with the
columns eta_i, theta_i(_deg), eta_o, theta_o(_deg), mu_ratio; a result file works).

Prints one JSON line per design, then a summary line.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from snapjump_cli.sweep.config import load_config, parse_config
from snapjump_cli.geometry.designs import get_design
from snapjump_cli.geometry.caps import Design, InvalidDesign
from snapjump_cli.settings import MeshSettings, SolverSettings
from snapjump_cli.fe.solve import SolveFailed, solve_scene

PAPER_GRID = Path(__file__).resolve().parents[1] / "configs" / "paper_grid.yaml"


def _valid(points, n: int, seed: int | None) -> list:
    """Up to ``n`` designs of ``points`` with a valid geometry (a seeded random draw if ``seed``)."""
    pts = list(points)
    if seed is not None:
        pts = [pts[i] for i in np.random.default_rng(seed).permutation(len(pts))]
    out = []
    for p in pts:
        try:
            out.append((f"{p.eta_i:g},{p.theta_i_deg:g},{p.eta_o:g},{p.theta_o_deg:g},{p.mu_ratio:g}",
                        Design(**p.design_kwargs())))
        except InvalidDesign:
            continue
        if len(out) == n:
            break
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("which", choices=["named", "grid", "points"])
    ap.add_argument("file", nargs="?", type=Path, help="with points: a CSV or parquet file of designs")
    ap.add_argument("--where", default=None, help="with points: a pandas query selecting rows of FILE")
    ap.add_argument("--n", type=int, default=40)
    ap.add_argument("--aspect", type=float, default=2.0)
    ap.add_argument("--nt", type=int, default=2)
    a = ap.parse_args(argv)
    if a.which == "named":
        items = [(k, get_design(k)) for k in ("A", "B", "C", "D", "S20b", "S20c")]
    elif a.which == "grid":
        items = _valid(load_config(PAPER_GRID).designs(), a.n, seed=11)
    else:
        if a.file is None:
            ap.error("points needs a FILE")
        points: object = str(a.file.resolve())
        if a.where:  # the selected rows, as an inline points: list
            import pandas as pd

            df = pd.read_parquet(a.file) if a.file.suffix != ".csv" else pd.read_csv(a.file)
            points = [{"eta_i": r.eta_i, "theta_i": r.theta_i_deg, "eta_o": r.eta_o, "theta_o": r.theta_o_deg,
                       "mu_ratio": r.mu_ratio} for r in df.query(a.where).itertuples()]
        items = _valid(parse_config({"points": points}, "<near_cusp_survey>").designs(), a.n, seed=None)
    gaps, flagged, snapping = [], 0, 0
    for name, d in items:
        try:
            r = solve_scene(d, MeshSettings(nt=a.nt, aspect=a.aspect), SolverSettings())
        except SolveFailed as exc:
            print(json.dumps({"design": name, "error": str(exc)[:120]}), flush=True)
            continue
        if r.states.upper is None:
            print(json.dumps({"design": name, "snaps": False}), flush=True)
            continue
        snapping += 1
        gap, change = r.states.cusp_gap, r.states.cusp_change  # recorded by the SnapTracker
        flagged += bool(r.metrics["fold_note"])
        if change is not None and max(change) >= 2:
            gaps.append(gap)
        print(json.dumps({"design": name, "gap": gap, "change": change, "fold_note": r.metrics["fold_note"],
                          "dE_J": r.metrics["dE_J"]}), flush=True)
    print(json.dumps({"snapping": snapping, "near_cusp": flagged, "smallest_gap_to_a_second_mode": min(gaps, default=None)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
