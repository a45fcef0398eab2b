"""Reproduce docs/verification.md's table of the paper's scenes: dE and dy_pole of the Fig. 1 caps (every
base reading of docs/physics.md section 1), the outer cap's E_o, and designs A-D, at several mesh levels,
beside the paper's values.

    .venv/bin/python scripts/scenes_table.py [--levels 2:2:2,2:3:2,2:4:2] [--scenes ...] [--jsonl out.jsonl]

Prints a Markdown table (one row per scene and level) to stdout.
"""
from __future__ import annotations

import argparse
import json
import sys
import time

from snapjump_cli.geometry.designs import FIG1_CAPS, fig1_caps, get_design, paper_values
from snapjump_cli.settings import MeshSettings, SolverSettings
from snapjump_cli.fe.solve import SolveFailed, solve_scene, warm_up

MU, R = 0.35e6, 0.030
SCENES = {
    **{name: (sc, FIG1_CAPS[name][2]) for name, sc in fig1_caps().items()},
    **{k: (get_design(k), None) for k in "ABCD"},
}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--levels", default="2:2:2,2:3:2,2:4:2", help="order:nt:aspect,...")
    ap.add_argument("--scenes", default=",".join(SCENES), help="comma-separated scene names")
    ap.add_argument("--jsonl", default=None, help="also write one JSON line per run here")
    a = ap.parse_args(argv)
    warm_up()
    levels = [tuple(float(x) for x in lv.split(":")) for lv in a.levels.split(",")]
    out = open(a.jsonl, "w") if a.jsonl else None
    print("| scene | order/nt/aspect | dE | dy_pole | paper dE | paper dy_pole | dE two ways | lower state | steps | wall s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name in a.scenes.split(","):
        scene, paper = SCENES[name]
        if paper is None:
            pv = paper_values(name)
            paper_s = (f"{pv.get('paper_dE_J', float('nan')) * 1e3:.4g} mJ", f"{pv.get('paper_dy_pole_m', float('nan')) * 1e3:.4g} mm")
        else:
            paper_s = (f"{paper[0]:.3g} muR^3", f"{paper[1]:.3g} R")
        for o, nt, asp in levels:
            t0 = time.perf_counter()
            row = {"scene": name, "order": int(o), "nt": int(nt), "aspect": asp}
            try:
                m = solve_scene(scene, MeshSettings(order=int(o), nt=int(nt), aspect=asp), SolverSettings()).metrics
                row.update({k: m.get(k) for k in ("dE_J", "dE_norm", "dy_pole_m", "dy_pole_norm", "dE_rel_diff", "h_imp_m",
                                                  "lower_state_method", "n_steps", "snaps", "self_crossing")})
                if not m["snaps"]:
                    cells = ("no snap", "-")
                elif paper is None:
                    cells = (f"{m['dE_J'] * 1e3:.4g} mJ", f"{m['dy_pole_m'] * 1e3:.4g} mm")
                else:
                    cells = (f"{m['dE_norm']:.3e} muR^3", f"{m['dy_pole_norm']:.4f} R")
                rel = f"{m['dE_rel_diff']:.1e}" if m.get("dE_rel_diff") is not None else "-"
                line = (f"| {name} | {int(o)}/{int(nt)}/{asp:g} | {cells[0]} | {cells[1]} | {paper_s[0]} | {paper_s[1]} | {rel} | "
                        f"{m['lower_state_method'] or '-'} | {m['n_steps']} | {time.perf_counter() - t0:.1f} |")
            except SolveFailed as e:
                row["error"] = str(e)
                line = f"| {name} | {int(o)}/{int(nt)}/{asp:g} | failed: {str(e)[:90]} | | {paper_s[0]} | {paper_s[1]} | | | | {time.perf_counter() - t0:.1f} |"
            row["wall_s"] = time.perf_counter() - t0
            print(line, flush=True)
            if out:
                out.write(json.dumps(row) + "\n")
                out.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
