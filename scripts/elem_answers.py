"""Solve a few designs and print their counts and snap metrics at full precision (JSON), to check
that a change to the element kernels leaves the answers equal to round-off.

    PYTHONPATH=... python scripts/elem_answers.py [--designs D C grid-0037 grid-1543] > before.json
    python scripts/elem_answers.py --compare before.json after.json

Designs are named designs or ``grid-NNNN`` (the paper grid's point NNNN), solved with
``solve_scene`` at the grid's mesh and solver settings.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
KEYS = ("dE_J", "dy_pole_m")
COUNTS = ("n_steps", "n_newton")


def solve(names):
    from snapjump_cli.sweep.config import load_config
    from snapjump_cli.geometry.designs import get_design
    from snapjump_cli.geometry.caps import Design
    from snapjump_cli.fe.solve import solve_scene, warm_up

    cfg = load_config(REPO / "configs" / "paper_grid.yaml")
    points = list(cfg.designs())
    warm_up()
    out = {}
    for name in names:
        d = Design(**points[int(name[5:])].design_kwargs()) if name.startswith("grid-") else get_design(name)
        w0, c0 = time.perf_counter(), time.process_time()
        r = solve_scene(d, cfg.mesh, cfg.solver)
        wall, cpu = time.perf_counter() - w0, time.process_time() - c0
        m = r.metrics
        row = {k: m.get(k) for k in KEYS + COUNTS}
        row["n_assemblies"] = int(r.model.n_assemblies)
        row["wall_s"], row["cpu_s"] = wall, cpu
        out[name] = row
        print(name, row, file=sys.stderr, flush=True)
    return out


def compare(a, b):
    worst = 0.0
    for name in a:
        ra, rb = a[name], b[name]
        rel = {k: abs(ra[k] - rb[k]) / abs(ra[k]) if ra[k] else abs(rb[k]) for k in KEYS}
        worst = max(worst, *rel.values())
        counts = ", ".join(f"{k} {ra[k]} -> {rb[k]}" for k in COUNTS + ("n_assemblies",))
        print(f"{name}: {counts}; " + ", ".join(f"{k} rel diff {v:.1e}" for k, v in rel.items())
              + f"; wall {ra['wall_s']:.3f} -> {rb['wall_s']:.3f} s, CPU {ra['cpu_s']:.3f} -> {rb['cpu_s']:.3f} s")
    print(f"largest relative difference: {worst:.1e}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--designs", nargs="*", default=["D", "C", "grid-0037", "grid-1543"])
    ap.add_argument("--compare", nargs=2, metavar="JSON")
    a = ap.parse_args(argv)
    if a.compare:
        compare(*(json.loads(Path(p).read_text()) for p in a.compare))
    else:
        print(json.dumps(solve(a.designs), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
