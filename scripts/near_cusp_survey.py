"""How close K_T's next unstable mode comes to the first volume limit (the near-cusp check of
:class:`snapjump_cli.snap.SnapTracker`) on the named designs and on random designs.

For each design: the first change of neg(K_T) after the volume limit, its relative distance from
(V*, p*) ("gap", 0 in the fold's own step) and whether the tracker flagged a near-cusp.

    .venv/bin/python scripts/near_cusp_survey.py named
    .venv/bin/python scripts/near_cusp_survey.py grid --n 40 --aspect 3     # paper-grid designs
    .venv/bin/python scripts/near_cusp_survey.py extended --n 40 --aspect 2 # extended domain (docs/physics.md section 8 widened)

Prints one JSON line per design, then a summary line.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "stress"))

import stresslib as sl  # noqa: E402

from snapjump_cli.designs import get_design  # noqa: E402
from snapjump_cli.geometry import Design  # noqa: E402
from snapjump_cli.settings import MeshSettings, SolverSettings  # noqa: E402
from snapjump_cli.solve import SolveFailed, solve_scene  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("which", choices=["named", "grid", "extended"])
    ap.add_argument("--n", type=int, default=40)
    ap.add_argument("--aspect", type=float, default=2.0)
    ap.add_argument("--nt", type=int, default=2)
    a = ap.parse_args(argv)
    if a.which == "named":
        items = [(k, get_design(k)) for k in ("A", "B", "C", "D", "S20b", "S20c")]
    elif a.which == "grid":
        items = [(p, Design(**p)) for p in sl.invariance_candidates(a.n, 11)[3:]]
    else:
        items = [(p, Design(**p)) for p in sl.random_extended(4 * a.n, 7) if sl.valid(p)][: a.n]
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
