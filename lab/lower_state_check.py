"""The lower state off the path two ways: the fixed-volume continuation and the energy descent.

    .venv/bin/python lab/lower_state_check.py [grid-1543 grid-3911 ...] [--design A --nt 2 --aspect 1]

For each design (``grid-NNNN``: the paper grid's point NNNN at the grid's mesh; a named design
with ``--nt``/``--aspect``), traces the path, then finds the lower state from the upper state with
:func:`snapjump_cli.fe.axisym.lower_state.snap_at_fixed_volume` and with
:func:`snapjump_cli.fe.axisym.descent.descend_at_volume`, and prints their steps / iterations, times and the
relative difference of the released energy. Prints a markdown table.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("designs", nargs="*", default=["grid-1543", "grid-3911", "grid-4790", "grid-4719",
                                                    "grid-4605", "grid-2343", "grid-1567"])
    ap.add_argument("--design", action="append", default=[], help="a named design (with --nt, --aspect)")
    ap.add_argument("--nt", type=int, default=2)
    ap.add_argument("--aspect", type=float, default=1.0)
    a = ap.parse_args(argv)
    sys.path.insert(0, str(REPO))
    from snapjump_cli.sweep.config import load_config
    from snapjump_cli.geometry.designs import get_design
    from snapjump_cli.geometry.caps import Design
    from snapjump_cli.fe.axisym.descent import descend_at_volume
    from snapjump_cli.fe.axisym.lower_state import snap_at_fixed_volume
    from snapjump_cli.settings import MeshSettings
    from snapjump_cli.fe.solve import solve_scene, warm_up

    cfg = load_config(REPO / "configs" / "paper_grid.yaml")
    points = list(cfg.designs())
    cases = [(n, Design(**points[int(n[5:])].design_kwargs()), cfg.mesh) for n in a.designs]
    cases += [(n, get_design(n), MeshSettings(order=2, nt=a.nt, aspect=a.aspect)) for n in a.design]
    warm_up()
    print("| design | fixed-volume path | time [s] | energy descent | time [s] | dE relative difference |")
    print("|---|---|---|---|---|---|")
    for name, d, mesh in cases:
        r = solve_scene(d, mesh, cfg.solver)
        if r.states.upper is None:
            print(f"| {name} | no snap | | | | |")
            continue
        E = r.model.energy
        W_up = E(r.states.upper.u)
        t0 = time.perf_counter()
        low_v, msg_v = snap_at_fixed_volume(r.tracer, r.states.upper)
        t1 = time.perf_counter()
        low_d, msg_d = descend_at_volume(r.tracer, r.states.upper)
        t2 = time.perf_counter()
        diff = "-"
        if low_v is not None and low_d is not None:
            dv, dd = W_up - E(low_v.u), W_up - E(low_d.u)
            diff = f"{(dv - dd) / dd:.1e}"
        print(f"| {name} | {msg_v} | {t1 - t0:.2f} | {msg_d} | {t2 - t1:.2f} | {diff} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
