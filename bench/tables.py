"""The tables the README and docs quote, each reproduced by one command.

    make scenes-table        python -m bench.tables scenes [--levels 2:2:2,2:3:2,2:4:2] [--scenes ...] [--jsonl F]
    make named-jumps         python -m bench.tables named-jumps [A B C D S20b S20c]
    make harmonics-counts    python -m bench.tables harmonics RESULTS.parquet [--top 20] [--crossing RESULTS]

* ``scenes``: dE and dy_pole of the Fig. 1 caps (every base reading of docs/physics.md section 1),
  the outer cap's E_o, and designs A-D at several mesh levels (``order:nt:aspect``), beside the
  paper's values (docs/verification.md); one Markdown row per scene and level.
* ``named-jumps``: the named designs end to end, FE as the sweep solves them (with the mesh check),
  then the jump model with its defaults (README, docs/verification.md).
* ``harmonics``: the figures of docs/results.md, "Asymmetric modes on the paper grid" from a sweep run with the harmonic
  check: the designs by status; how many lose stability to a harmonic before V* and by which n
  (overall and by stiffness ratio); where; the lower state's stability; the confusion table
  against the self-crossing flag; dE of the two groups; the ranking's top with and without
  ``--exclude-asymmetric``.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any, Callable, Iterable

import numpy as np

NAMED = ("A", "B", "C", "D", "S20b", "S20c")
LEVELS = "2:2:2,2:3:2,2:4:2"


# ---- scenes --------------------------------------------------------------------------------------
def scenes() -> dict[str, tuple[Any, tuple[float, float] | None]]:
    """Scene name -> (scene, the paper's (dE/(mu R^3), dy/R) for a Fig. 1 cap, else None)."""
    from snapjump_cli.geometry.designs import FIG1_CAPS, fig1_caps, get_design

    return {**{name: (sc, FIG1_CAPS[name][2]) for name, sc in fig1_caps().items()},
            **{k: (get_design(k), None) for k in "ABCD"}}


def parse_levels(text: str) -> list[tuple[int, int, float]]:
    """``"2:2:2,2:3:2"`` -> ``[(2, 2, 2.0), (2, 3, 2.0)]`` (order, nt, aspect)."""
    out = []
    for lv in text.split(","):
        o, nt, asp = lv.split(":")
        out.append((int(o), int(nt), float(asp)))
    return out


def scene_row(name: str, level: tuple[int, int, float], solve: Callable | None = None) -> dict:
    """One scene solved at one mesh level as ``snapjump curve`` solves it (``solve_scene``): the
    metrics the table shows, or the error."""
    from snapjump_cli.fe.solve import SolveFailed, solve_scene
    from snapjump_cli.settings import MeshSettings, SolverSettings

    solve = solve or solve_scene
    scene, _ = scenes()[name]
    o, nt, asp = level
    row: dict = {"scene": name, "order": o, "nt": nt, "aspect": asp}
    t0 = time.perf_counter()
    try:
        m = solve(scene, MeshSettings(order=o, nt=nt, aspect=asp), SolverSettings()).metrics
        row.update({k: m.get(k) for k in ("dE_J", "dE_norm", "dy_pole_m", "dy_pole_norm", "dE_rel_diff", "h_imp_m",
                                          "lower_state_method", "n_steps", "snaps", "self_crossing")})
    except SolveFailed as e:
        row["error"] = str(e)
    row["wall_s"] = time.perf_counter() - t0
    return row


SCENES_HEADER = ("| scene | order/nt/aspect | dE | dy_pole | paper dE | paper dy_pole | dE two ways | lower state | steps | wall s |\n"
                 "|---|---|---|---|---|---|---|---|---|---|")


def scene_line(row: dict) -> str:
    """The Markdown row of :func:`scene_row`'s result (caps normalised, designs in SI)."""
    from snapjump_cli.geometry.designs import paper_values

    name = row["scene"]
    _, paper = scenes()[name]
    if paper is None:
        pv = paper_values(name)
        paper_s = (f"{pv.get('paper_dE_J', float('nan')) * 1e3:.4g} mJ", f"{pv.get('paper_dy_pole_m', float('nan')) * 1e3:.4g} mm")
    else:
        paper_s = (f"{paper[0]:.3g} muR^3", f"{paper[1]:.3g} R")
    level = f"{row['order']}/{row['nt']}/{row['aspect']:g}"
    if "error" in row:
        return f"| {name} | {level} | failed: {row['error'][:90]} | | {paper_s[0]} | {paper_s[1]} | | | | {row['wall_s']:.1f} |"
    if not row["snaps"]:
        cells = ("no snap", "-")
    elif paper is None:
        cells = (f"{row['dE_J'] * 1e3:.4g} mJ", f"{row['dy_pole_m'] * 1e3:.4g} mm")
    else:
        cells = (f"{row['dE_norm']:.3e} muR^3", f"{row['dy_pole_norm']:.4f} R")
    rel = f"{row['dE_rel_diff']:.1e}" if row.get("dE_rel_diff") is not None else "-"
    return (f"| {name} | {level} | {cells[0]} | {cells[1]} | {paper_s[0]} | {paper_s[1]} | {rel} | "
            f"{row['lower_state_method'] or '-'} | {row['n_steps']} | {row['wall_s']:.1f} |")


def scenes_main(a: argparse.Namespace) -> int:
    from snapjump_cli.fe.solve import warm_up

    warm_up()
    out = open(a.jsonl, "w") if a.jsonl else None
    print(SCENES_HEADER)
    for name in a.scenes.split(","):
        for level in parse_levels(a.levels):
            row = scene_row(name, level)
            print(scene_line(row), flush=True)
            if out:
                out.write(json.dumps(row) + "\n")
                out.flush()
    return 0


# ---- named designs end to end --------------------------------------------------------------------
NAMED_HEADER = ("| design | dE [mJ] | dy_pole [mm] | h_imp [mm] | m_i [g] | m_o [g] | y_jump [mm] | jumped | paper model / test [mm] |\n"
                "|---|---|---|---|---|---|---|---|---|")


def named_jump_row(name: str, solve: Callable | None = None) -> dict:
    """A named design as the sweep solves it (``solve_design``, with the mesh check), then the
    jump model with its default parameters: the row of the table (``error`` if the solve failed)."""
    from snapjump_cli.fe.solve import SolveFailed, solve_design
    from snapjump_cli.geometry.designs import get_design
    from snapjump_cli.jump import JumpParams, jump_height, masses

    solve = solve or solve_design
    row: dict = {"design": name}
    try:
        m = solve(get_design(name))
    except SolveFailed as e:
        row["error"] = str(e)
        return row
    p = JumpParams()
    mi, mo = masses(m["V_inner_solid_m3"], m["V_outer_solid_m3"], p.rho)
    j = jump_height(m["dE_J"], m["dy_pole_m"], m["h_imp_m"], mi, mo, p)
    row.update(dE_J=m["dE_J"], dy_pole_m=m["dy_pole_m"], h_imp_m=m["h_imp_m"], m_i_kg=mi, m_o_kg=mo,
               y_jump_m=j.y_jump_m, jumped=bool(j.jumped))
    return row


def named_jump_line(row: dict) -> str:
    from snapjump_cli.geometry.designs import paper_values

    pv = paper_values(row["design"])
    paper = f"{pv.get('paper_jump_model_m', float('nan')) * 1e3:.4g} / {pv.get('paper_jump_test_m', float('nan')) * 1e3:.4g}"
    if "error" in row:
        return f"| {row['design']} | failed: {row['error']} | | | | | | | {paper} |"
    return (f"| {row['design']} | {row['dE_J'] * 1e3:.4g} | {row['dy_pole_m'] * 1e3:.4g} | {row['h_imp_m'] * 1e3:.4g} | "
            f"{row['m_i_kg'] * 1e3:.4g} | {row['m_o_kg'] * 1e3:.4g} | {row['y_jump_m'] * 1e3:.4g} | "
            f"{'yes' if row['jumped'] else 'no'} | {paper} |")


def named_main(a: argparse.Namespace) -> int:
    print(NAMED_HEADER)
    for name in a.designs or NAMED:
        print(named_jump_line(named_jump_row(name)), flush=True)
    return 0


# ---- the harmonic check over a sweep -------------------------------------------------------------
def design_keys(df) -> Any:
    """The five design parameters of each row as one string (rows of two runs of one grid match)."""
    return df[["eta_i", "theta_i_deg", "eta_o", "theta_o_deg", "mu_ratio"]].round(4).astype(str).agg(",".join, axis=1)


def harmonics_counts(df) -> dict:
    """The counts of docs/results.md, "Asymmetric modes on the paper grid" over the ``ok`` rows of a result table with the
    harmonic check (``asym_*`` columns)."""
    ok = df[df["status"] == "ok"]
    asym = ok["asym_first"].astype("boolean").fillna(False).to_numpy(bool)
    sc = ok["self_crossing"].astype("boolean").fillna(False).to_numpy(bool)
    ls = ok["asym_lower_stable"].astype("boolean")
    fa = ok.loc[asym]
    dE = ok["dE_J"].to_numpy(float)
    return {
        "status": {str(k): int(v) for k, v in df["status"].value_counts().items()},
        "ok": len(ok), "unchecked": int(ok["asym_first"].isna().sum()),
        "asym_first": int(asym.sum()),
        "first_n": {int(k): int(v) for k, v in fa["asym_n"].value_counts().sort_index().items()},
        "by_mu_ratio": {float(mr): (int(g["asym_first"].astype("boolean").fillna(False).sum()), len(g))
                        for mr, g in ok.groupby("mu_ratio")},
        "V_over_Vstar": (fa["asym_V_m3"] / fa["V_star_m3"]).to_numpy(float),
        "p_over_pmax": (fa["asym_p_Pa"] / fa["p_max_Pa"]).to_numpy(float),
        "lower_stable": int(ls.fillna(False).sum()), "lower_unstable": int((~ls.fillna(True)).sum()),
        "lower_unchecked": int(ls.isna().sum()),
        "confusion": {"not self-crossing": (int((~sc & ~asym).sum()), int((~sc & asym).sum())),
                      "self-crossing": (int((sc & ~asym).sum()), int((sc & asym).sum()))},
        "agree": int((sc & asym).sum() + (~sc & ~asym).sum()),
        "median_dE_J": (float(np.median(dE[asym])) if asym.any() else float("nan"),
                        float(np.median(dE[~asym])) if (~asym).any() else float("nan")),
    }


def harmonics_lines(c: dict) -> list[str]:
    """The report of :func:`harmonics_counts` (the ranking comes after it, see :func:`harmonics_main`)."""
    n, na = c["ok"], c["asym_first"]
    out = [f"{sum(c['status'].values())} rows: " + ", ".join(f"{k} {v}" for k, v in c["status"].items())]
    if c["unchecked"]:
        out.append(f"warning: {c['unchecked']} ok rows without the harmonic check")
    out.append(f"\nvalid (ok): {n}; a harmonic unstable before V*: {na} ({na / max(n, 1):.1%}), stable up to V*: {n - na}")
    out.append(f"first harmonic: {c['first_n']}")
    for mr, (k, m) in c["by_mu_ratio"].items():
        out.append(f"  mu ratio {mr:g}: {k} of {m} asymmetric first")
    rv, rp = c["V_over_Vstar"], c["p_over_pmax"]
    if len(rv):
        out.append(f"where: V/V* {np.nanmin(rv):.2f}-{np.nanmax(rv):.2f} (median {np.nanmedian(rv):.2f}); "
                   f"p/p_max {np.nanmin(rp):.2f}-{np.nanmax(rp):.2f} (median {np.nanmedian(rp):.2f})")
    out.append(f"lower state stable against the harmonics: {c['lower_stable']}, unstable: {c['lower_unstable']}, "
               f"not checked: {c['lower_unchecked']}")
    out.append("\n| | stable up to V* | a harmonic unstable before V* | all |\n|---|---|---|---|")
    for lab, (s, a) in c["confusion"].items():
        out.append(f"| {lab} | {s} | {a} | {s + a} |")
    out.append(f"| all | {n - na} | {na} | {n} |")
    out.append(f"agreement of the two: {c['agree']}/{n} = {c['agree'] / max(n, 1):.0%}")
    d_a, d_s = c["median_dE_J"]
    out.append(f"median dE: asymmetric first {d_a * 1e3:.0f} mJ, stable {d_s * 1e3:.0f} mJ")
    return out


def harmonics_main(a: argparse.Namespace) -> int:
    from snapjump_cli.jump.rank import rank_results, top_table
    from snapjump_cli.sweep.results import read_results

    df = read_results(a.results)
    if a.crossing is not None:
        other = read_results(a.crossing)
        sc_map = dict(zip(design_keys(other), other["self_crossing"]))
        keys = design_keys(df)
        missing = int((~keys.isin(sc_map.keys())).sum())
        if missing:
            print(f"warning: {missing} designs not in {a.crossing}")
        new = keys.map(sc_map).astype("boolean").fillna(df["self_crossing"].astype("boolean"))
        ok = (df["status"] == "ok").to_numpy()
        changed = int((new.fillna(False).to_numpy(bool) != df["self_crossing"].astype("boolean").fillna(False)
                       .to_numpy(bool))[ok].sum())
        df["self_crossing"] = new
        print(f"self_crossing taken from {a.crossing} ({changed} ok rows differ from the checked run's own)")
    print("\n".join(harmonics_lines(harmonics_counts(df))))
    r_all = rank_results(df)
    r_ax = rank_results(df, exclude_asymmetric=True)
    print(f"\ntop {a.top} (all designs):\n" + top_table(r_all, a.top))
    print(f"\ntop {a.top} (--exclude-asymmetric):\n" + top_table(r_ax, a.top))
    k_all, k_ax = set(design_keys(r_all.head(a.top))), set(design_keys(r_ax.head(a.top)))
    print(f"\n{len(k_all & k_ax)} of the top {a.top} are the same; "
          f"asymmetric-first designs in the unfiltered top {a.top}: "
          f"{int(r_all.head(a.top)['asym_first'].astype('boolean').fillna(False).sum())}")
    return 0


def main(argv: Iterable[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.tables", description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("scenes", help="the paper's scenes at several mesh levels (docs/verification.md)")
    s.add_argument("--levels", default=LEVELS, help="order:nt:aspect,... (default %(default)s)")
    s.add_argument("--scenes", default=",".join(scenes()), help="comma-separated scene names")
    s.add_argument("--jsonl", default=None, help="also write one JSON line per run here")
    n = sub.add_parser("named-jumps", help="the named designs end to end: FE, then the jump model")
    n.add_argument("designs", nargs="*", metavar="DESIGN", help="named designs (default: all of them)")
    h = sub.add_parser("harmonics", help="the harmonic check over a sweep (docs/results.md, asymmetric modes on the paper grid)")
    h.add_argument("results", type=Path)
    h.add_argument("--top", type=int, default=20)
    h.add_argument("--crossing", type=Path, metavar="RESULTS",
                   help="take self_crossing from this result file of the same designs")
    a = ap.parse_args(None if argv is None else list(argv))
    return {"scenes": scenes_main, "named-jumps": named_main, "harmonics": harmonics_main}[a.cmd](a)


if __name__ == "__main__":
    sys.exit(main())
