"""End-to-end predicted jump heights of the named designs (FE at the default mesh -> jump model).

    .venv/bin/python scripts/named_jumps.py [A B C D S20b S20c]
"""
from __future__ import annotations

import sys

from snapjump_cli.geometry.designs import get_design, paper_values
from snapjump_cli.jump import JumpParams, jump_height, masses
from snapjump_cli.fe.solve import SolveFailed, solve_design


def main(names: list[str]) -> int:
    print("| design | dE [mJ] | dy_pole [mm] | h_imp [mm] | m_i [g] | m_o [g] | y_jump [mm] | jumped | paper model / test [mm] |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name in names:
        pv = paper_values(name)
        paper = f"{pv.get('paper_jump_model_m', float('nan')) * 1e3:.4g} / {pv.get('paper_jump_test_m', float('nan')) * 1e3:.4g}"
        try:
            m = solve_design(get_design(name))
        except SolveFailed as e:
            print(f"| {name} | failed: {e} | | | | | | | {paper} |")
            continue
        mi, mo = masses(m["V_inner_solid_m3"], m["V_outer_solid_m3"], JumpParams().rho)
        j = jump_height(m["dE_J"], m["dy_pole_m"], m["h_imp_m"], mi, mo)
        print(f"| {name} | {m['dE_J'] * 1e3:.4g} | {m['dy_pole_m'] * 1e3:.4g} | {m['h_imp_m'] * 1e3:.4g} | {mi * 1e3:.4g} | "
              f"{mo * 1e3:.4g} | {j.y_jump_m * 1e3:.4g} | {'yes' if j.jumped else 'no'} | {paper} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:] or ["A", "B", "C", "D", "S20b", "S20c"]))
