"""The snap under air against water: the tables and figures of docs/air.md.

    python lab/air_study.py table [--designs C D] [--V0 1 2 5 10 20 45 100 200 500 1000] [--gamma 1 1.4]
    python lab/air_study.py crossing [--designs C D] [--level 0.05]
    python lab/air_study.py fig-s9 OUT.png [--design C] [--V0 40 45 100]
    python lab/air_study.py ranking WATER.ranked.parquet AIR.ranked.parquet [--top 20]

``table``: per design the water snap and, for every V0_sys and polytropic exponent, the air snap
(pressures before and after, the actuator's volume change and eq 9's, the energy of rubber and
gas, dy_pole, h_imp, the jump height and its change against water). ``crossing``: the V0_sys at
which the jump (and dE) first differs from water by ``level`` (bisection in log V0_sys).
``fig-s9``: the paper's Fig. S9 computed: the pressure against the dispensed volume for water and
air. ``ranking``: the top of two ranked sweeps side by side (the water and air ranks of each design).
Every solve is the sweep's (:func:`snapjump_cli.fe.solve.solve_checked`) on the default mesh (Q9, nt 2,
aspect 2) unless ``--grid-mesh`` (aspect 3, the paper grid's).
"""
from __future__ import annotations

import argparse
import math

from snapjump_cli import jump
from snapjump_cli.geometry.designs import get_design
from snapjump_cli.fe.axisym.fluid import FluidSettings
from snapjump_cli.settings import MeshSettings
from snapjump_cli.fe.solve import solve_checked


def _jump(m: dict, prefix: str = "") -> float:
    mi, mo = jump.masses(m["V_inner_solid_m3"], m["V_outer_solid_m3"])
    return jump.jump_height(m[prefix + "dE_J"], m[prefix + "dy_pole_m"], m[prefix + "h_imp_m"], mi, mo).y_jump_m


def _solve(name: str, V0: float | None, gamma: float, mesh: MeshSettings) -> dict:
    fluid = None if V0 is None else FluidSettings(kind="air", V0_ml=V0, gamma=gamma)
    m = solve_checked(get_design(name), mesh, fluid=fluid).metrics
    m["y_jump_m"] = _jump(m)
    return m


def table(a) -> None:
    print("| design | fluid | V0_sys [ml] | gamma | p before / after [kPa] | dispensed [ml] | dV_snap [ml] (eq 9) | "
          "dE [mJ] (gas) | dy_pole [mm] | h_imp [mm] | jump [mm] | jump vs water | lower state |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name in a.designs:
        w = _solve(name, None, 1.0, a.mesh)
        print(f"| {name} | water | - | - | {w['p_star_Pa'] / 1e3:.4g} / {w['p_lower_Pa'] / 1e3:.4g} | "
              f"{(w['V_star_m3'] - _V_cav0(name, a.mesh)) * 1e6:.4g} | - | {w['dE_J'] * 1e3:.4g} | "
              f"{w['dy_pole_m'] * 1e3:.4g} | {w['h_imp_m'] * 1e3:.4g} | {w['y_jump_m'] * 1e3:.4g} | - | "
              f"{w['lower_state_method']} |")
        for g in a.gamma:
            for V0 in a.V0:
                m = _solve(name, V0, g, a.mesh)
                print(f"| {name} | air | {V0:g} | {g:g} | {m['p_before_Pa'] / 1e3:.4g} / {m['p_after_Pa'] / 1e3:.4g} | "
                      f"{m['V_disp_m3'] * 1e6:.4g} | {m['dV_snap_m3'] * 1e6:.3g} ({m['dV_snap_eq9_m3'] * 1e6:.3g}) | "
                      f"{m['dE_J'] * 1e3:.4g} ({m['dE_gas_J'] * 1e3:.3g}) | {m['dy_pole_m'] * 1e3:.4g} | "
                      f"{m['h_imp_m'] * 1e3:.4g} | {m['y_jump_m'] * 1e3:.4g} | "
                      f"{(m['y_jump_m'] / w['y_jump_m'] - 1) * 100:+.1f} % | {m['lower_state_method']} |")


_CAV0: dict = {}


def _V_cav0(name: str, mesh: MeshSettings) -> float:
    """The cavity volume of the stress-free design [m^3] (the meshed one, as the solver's)."""
    if name not in _CAV0:
        import numpy as np

        from snapjump_cli.mesh.build import mesh_scene
        from snapjump_cli.settings import SolverSettings
        from snapjump_cli.fe.solve import build_model

        d = get_design(name)
        model = build_model(d, mesh_scene(d, mesh), SolverSettings())
        _CAV0[name] = model.volume(np.zeros(model.n)) * model.L**3
    return _CAV0[name]


def crossing(a) -> None:
    """The smallest V0_sys (log bisection between 1 mL and 10 L) at which |y/y_water - 1| = level."""
    for name in a.designs:
        w = _solve(name, None, 1.0, a.mesh)
        for key in ("y_jump_m", "dE_J"):
            def excess(logv: float) -> float:
                m = _solve(name, 10.0**logv, a.gamma_one, a.mesh)
                return abs(m[key] / w[key] - 1.0) - a.level

            lo, hi = 0.0, 4.0
            if excess(hi) < 0:
                print(f"{name}: {key} within {a.level:.0%} of water up to 10 L")
                continue
            for _ in range(14):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if excess(mid) < 0 else (lo, mid)
            m = _solve(name, 10.0**hi, a.gamma_one, a.mesh)
            print(f"{name}: {key} differs from water by {a.level:.0%} at V0_sys = {10.0**hi:.4g} mL "
                  f"(gamma {a.gamma_one:g}; {key} {w[key]:.6g} -> {m[key]:.6g})")


def fig_s9(a) -> None:
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    import numpy as np

    from snapjump_cli.fe.axisym.fluid import GasLaw

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11.0, 4.4))
    w = solve_checked(get_design(a.design), a.mesh)
    c = w.curve
    dV = (c["V_m3"] - c["V0_m3"]) * 1e6
    a1.plot(dV, c["p_Pa"] / 1e3, "-", color="k", lw=1.4, label=f"water, dE = {w.metrics['dE_J'] * 1e3:.4g} mJ")
    a2.plot(dV, c["p_Pa"] / 1e3, "-", color="k", lw=1.4, label="equilibrium path (every fluid)")
    sx = (c["snap_V_m3"] - c["V0_m3"]) * 1e6
    for ax in (a1, a2):
        ax.plot([sx[0], sx[-1]], [c["snap_p_Pa"][0] / 1e3, c["snap_p_Pa"][-1] / 1e3], ":", color="k", lw=1.2)
    for V0, col in zip(a.V0, ("tab:red", "tab:orange", "tab:purple", "tab:green", "tab:blue")):
        r = solve_checked(get_design(a.design), a.mesh, fluid=FluidSettings(kind="air", V0_ml=V0, gamma=a.gamma_one))
        m, cc = r.metrics, r.curve
        a1.plot(cc["V_disp_m3"] * 1e6, cc["p_Pa"] / 1e3, "-", color=col, lw=1.2,
                label=f"air, V0_sys = {V0:g} ml: dE = {m['dE_J'] * 1e3:.4g} mJ")
        a1.plot([m["V_disp_m3"] * 1e6] * 2, [m["p_before_Pa"] / 1e3, m["p_after_Pa"] / 1e3], "--", color=col, lw=1.2)
        gas = GasLaw(m["air_V0_m3"], m["air_p0_Pa"], m["air_gamma"])
        pp = np.linspace(m["p_before_Pa"], m["p_after_Pa"], 40)
        V_up = cc["air_snap_V_m3"][0] - c["V0_m3"]
        a2.plot((V_up + gas.expelled(pp[0]) - gas.expelled(pp)) * 1e6, pp / 1e3, "--", color=col, lw=1.2,
                label=f"air snap, V0_sys = {V0:g} ml: actuator +{m['dV_snap_m3'] * 1e6:.3g} ml")
    a1.set_xlabel("dispensed volume [ml] (water: cavity volume change)")
    a2.set_xlabel("actuator volume change [ml]")
    for ax in (a1, a2):
        ax.set_ylabel("pressure (gauge) [kPa]")
        ax.grid(alpha=0.3)
        ax.legend(loc="best", fontsize=7)
    fig.suptitle(f"design {a.design}: water and air (gamma {a.gamma_one:g})")
    fig.tight_layout()
    fig.savefig(a.out, dpi=120)
    print(f"wrote {a.out}")


def ranking(a) -> None:
    import pandas as pd

    cols = ["eta_i", "theta_i_deg", "eta_o", "theta_o_deg", "mu_ratio"]
    w, r = pd.read_parquet(a.water), pd.read_parquet(a.air)
    key = lambda df: df[cols].round(6).astype(str).agg(",".join, axis=1)  # noqa: E731
    w["k"], r["k"] = key(w), key(r)
    rank_air = dict(zip(r["k"], r["rank"]))
    air_by_k = r.set_index("k")
    print("| water rank | design (eta_i, theta_i, eta_o, theta_o, mu) | water jump [mm] | air jump [mm] | change | air rank |")
    print("|---|---|---|---|---|---|")
    for _, x in w.sort_values("rank").head(a.top).iterrows():
        y = air_by_k.loc[x["k"]]
        print(f"| {int(x['rank'])} | ({x['eta_i']:.4g}, {x['theta_i_deg']:.4g}, {x['eta_o']:.4g}, {x['theta_o_deg']:.4g}, "
              f"{x['mu_ratio']:.4g}) | {x['y_jump_m'] * 1e3:.1f} | {y['y_jump_m'] * 1e3:.1f} | "
              f"{(y['y_jump_m'] / x['y_jump_m'] - 1) * 100:+.1f} % | {rank_air.get(x['k'])} |")
    top_w = set(w.sort_values("rank").head(a.top)["k"])
    top_a = set(r.sort_values("rank").head(a.top)["k"])
    print(f"\nair top {a.top} not in the water top {a.top}: {sorted(top_a - top_w) or 'none'}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    t = sub.add_parser("table")
    t.add_argument("--designs", nargs="+", default=["C", "D"])
    t.add_argument("--V0", nargs="+", type=float, default=[1, 2, 5, 10, 20, 45, 100, 200, 500, 1000])
    t.add_argument("--gamma", nargs="+", type=float, default=[1.0])
    c = sub.add_parser("crossing")
    c.add_argument("--designs", nargs="+", default=["C", "D"])
    c.add_argument("--level", type=float, default=0.05)
    c.add_argument("--gamma", dest="gamma_one", type=float, default=1.0)
    f = sub.add_parser("fig-s9")
    f.add_argument("out")
    f.add_argument("--design", default="C")
    f.add_argument("--V0", nargs="+", type=float, default=[40, 45, 100])
    f.add_argument("--gamma", dest="gamma_one", type=float, default=1.0)
    r = sub.add_parser("ranking")
    r.add_argument("water")
    r.add_argument("air")
    r.add_argument("--top", type=int, default=20)
    for p in (t, c, f):
        p.add_argument("--grid-mesh", action="store_true", help="the paper grid's mesh (aspect 3)")
    a = ap.parse_args()
    a.mesh = MeshSettings(aspect=3.0) if getattr(a, "grid_mesh", False) else MeshSettings()
    {"table": table, "crossing": crossing, "fig-s9": fig_s9, "ranking": ranking}[a.cmd](a)


if __name__ == "__main__":
    main()
