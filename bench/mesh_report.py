"""The mesh study's report (``make bench-mesh``): ``REPORT.md`` (Markdown tables) and plots
(matplotlib, Agg). The committed copy lives in ``bench/mesh_study/`` (Markdown and data; the plots
are regenerated, not committed)."""
from __future__ import annotations

import math
from collections import defaultdict
from datetime import datetime, timezone
from pathlib import Path

from bench import analysis as an


def _portable(args: dict) -> dict:
    """The study's options with paths relative to the repository (no machine paths in the report)."""
    repo = Path(__file__).resolve().parents[1]
    out = {}
    for k, v in args.items():
        if isinstance(v, str) and v.startswith("/"):
            try:
                v = str(Path(v).resolve().relative_to(repo))
            except ValueError:
                v = Path(v).name
        out[k] = v
    return out


def _pct(x: float | None, digits: int = 2) -> str:
    if x is None:
        return "–"
    if math.isinf(x):
        return "∞"
    return f"{100 * x:.{digits}f}%"


def _g(x, fmt: str = ".5g") -> str:
    return "–" if x is None else format(x, fmt)


def _t(x) -> str:
    if x is None:
        return "–"
    if math.isinf(x):
        return "∞"
    return f"{x:.2f}" if x < 100 else f"{x:.0f}"


def _plots(runs, verdicts, summaries, out: Path, default) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    files = []
    # 1) Pareto: worst error over the converged cases vs total wall time, per setting
    fig, axes = plt.subplots(1, 2, figsize=(12, 5))
    for ax, m in zip(axes, an.METRICS):
        pts = [(s.total_wall, s.max_err[m], s) for s in summaries if s.n_missing == 0 and s.n_cases > 0]
        front = an.pareto([(t, max(e, 1e-7), s) for t, e, s in pts if math.isfinite(t) and math.isfinite(e)])
        for o, mk in ((1, "s"), (2, "o")):
            for asp in sorted({s.setting[2] for _, _, s in pts if s.setting[0] == o}):
                sel = [(t, e, s) for t, e, s in pts if s.setting[0] == o and s.setting[2] == asp
                       and math.isfinite(t) and math.isfinite(e)]
                if not sel:
                    continue
                ax.plot([p[0] for p in sel], [max(p[1], 1e-7) for p in sel], mk + "-" if asp in (1.0, 2.0) else mk + ":",
                        label=f"Q{4 if o == 1 else 9} aspect {asp:g}", alpha=0.8)
                for t, e, s in sel:
                    ax.annotate(str(s.setting[1]), (t, max(e, 1e-7)), fontsize=7, xytext=(3, 3), textcoords="offset points")
        if front:
            ax.plot([s.total_wall for s in front], [max(s.max_err[m], 1e-7) for s in front], "k--", lw=1,
                    label="Pareto front")
        ax.axhline(an.THRESH[m], color="r", lw=0.8, ls=":", label=f"threshold {100 * an.THRESH[m]:g}%")
        if default is not None:
            ax.plot([default.total_wall], [max(default.max_err[m], 1e-7)], "r*", ms=14, label="default")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("total wall time over the converged cases [s]")
        ax.set_ylabel(f"worst relative error of {m} (converged cases)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        ax.set_title(f"{m}: error vs time per setting (labels: nt)")
    fig.tight_layout()
    f = out / "pareto.png"
    fig.savefig(f, dpi=110)
    plt.close(fig)
    files.append(f.name)

    # 2) per case: error vs wall time
    names = list(verdicts)
    ncol = 4
    nrow = max(1, math.ceil(len(names) / ncol))
    for m in an.METRICS:
        fig, axes = plt.subplots(nrow, ncol, figsize=(4 * ncol, 3.2 * nrow), squeeze=False)
        for ax, c in zip(axes.flat, names):
            v = verdicts[c]
            for o, mk in ((1, "s"), (2, "o")):
                for asp in sorted({r["aspect"] for r in runs if r["order"] == o}):
                    sel = sorted([r for r in runs if r["case"] == c and r["order"] == o and r["aspect"] == asp
                                  and r["status"] in ("ok", "no_snap") and r.get("wall_s")], key=lambda r: r["nt"])
                    xs, ys = [], []
                    for r in sel:
                        e = an.run_errors(r, v)[m]
                        if e is not None and math.isfinite(e):
                            xs.append(r["wall_s"])
                            ys.append(max(e, 1e-7))
                    if xs:
                        ax.plot(xs, ys, mk + ("-" if asp in (1.0, 2.0) else ":"), label=f"Q{4 if o == 1 else 9} a={asp:g}")
            ax.axhline(an.THRESH[m], color="r", lw=0.8, ls=":")
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_title(f"{c}{'' if v.converges else ' (mesh-sensitive)'}", fontsize=9)
            ax.grid(True, which="both", alpha=0.3)
            ax.tick_params(labelsize=7)
        for ax in list(axes.flat)[len(names):]:
            ax.axis("off")
        axes.flat[0].legend(fontsize=6)
        fig.supxlabel("wall time [s]")
        fig.supylabel(f"relative error of {m}")
        fig.tight_layout()
        f = out / f"cases_{m}.png"
        fig.savefig(f, dpi=100)
        plt.close(fig)
        files.append(f.name)
    return files


def write_report(runs: list[dict], cases, state: dict, out: Path, aspect_rule: dict, solver) -> Path:
    by_case = defaultdict(list)
    for r in runs:
        by_case[r["case"]].append(r)
    ref_aspect = aspect_rule[2]
    verdicts = {c.name: an.case_reference(by_case.get(c.name, []), ref_aspect) for c in cases if by_case.get(c.name)}
    runs_ok = [r for r in runs if r["status"] != "skipped"]
    summaries = an.summarize_settings(runs, verdicts)
    default = an.choose_default(summaries)
    try:
        plots = _plots(runs_ok, verdicts, summaries, out, default)
    except Exception as e:  # noqa: BLE001 - a report without plots is still a report
        plots = []
        plot_err = f"{type(e).__name__}: {e}"
    else:
        plot_err = ""

    L: list[str] = []
    w = L.append
    mach = state.get("machine", {})
    git = state.get("git", {})
    w("# snapjump benchmark: run time against error\n")
    w(f"Generated {datetime.now(timezone.utc).isoformat(timespec='seconds')} by `python -m bench.run_bench` "
      f"(options: `{_portable(state.get('args', {}))}`).\n")
    w(f"Machine: {mach.get('cpu_model', '?')}, {mach.get('cores', '?')} cores, {mach.get('mem_total', '?')}; "
      f"Python {mach.get('python', '?')}, numba {mach.get('numba', '?')}, numpy {mach.get('numpy', '?')}; "
      f"load average at the end {tuple(round(x, 2) for x in mach.get('loadavg', ()))} (the machine was shared, "
      "timings are indicative, ratios between settings more so than absolute values).\n")
    commits = sorted({r.get("git", "?") for r in runs_ok})
    dirty = any(r.get("dirty") for r in runs_ok)
    w(f"Code: commit(s) {', '.join(commits)}{' with uncommitted solver edits in the working tree' if dirty else ''}. "
      f"Bench wall time (this invocation): {_t(state.get('bench_wall_s'))} s. Solver settings: `{solver.as_dict()}`.\n")

    w("## Method\n")
    w(f"* Mesh settings: element order 1 (Q4, mean dilatation) and 2 (Q9/P1), nt elements through the "
      f"thickness. **Aspect rule**: the aspect ratio is held fixed per order while nt varies — "
      f"{', '.join(f'Q{4 if o == 1 else 9}: {a:g}' for o, a in aspect_rule.items())} — so that the elements "
      "stay similar under refinement (h = t/nt is the only mesh parameter, as the Richardson extrapolation "
      "needs; the element count grows like nt²). A Q9 element has two node intervals per side, so Q9 with "
      "aspect 2 has the node spacing of Q4 with aspect 1 along the arc. Stretched variants (Q4 aspect 2, Q9 "
      "aspect 4) are run on the cheaper levels to show what the aspect buys.")
    w("* Timing: kernels compiled first (`warm_up()`), each run in a forked child (inheriting the compiled "
      "kernels) with a hard time limit; the wall time is `SceneResult.metrics['wall_s']`-equivalent "
      "(meshing + solving), the median of 5 solves below 1 s, of 3 below 5 s, else one solve. A run whose "
      "predicted time (wall ∝ ntᵏ fitted on the two previous levels of the same case, k in [2, 4.5]) exceeds "
      "the per-run timeout is skipped, and so are the finer levels after it.")
    w("* Reference per case and metric: Richardson extrapolation (h = 1/nt, observed order p fitted, "
      "p ∈ [0.5, 8]) from the three finest successful order-2 levels at the reference aspect when they are "
      "monotone; otherwise the finest level (the table says which). The errors of the finest levels are "
      "therefore measured against a reference built from themselves: they say how far the extrapolation "
      "moved, not an independent error.")
    w(f"* A case **converges** when for dE and dy_pole either the Richardson reference is within "
      f"{_pct(an.CONV_EST['dE_J'], 0)} / {_pct(an.CONV_EST['dy_pole_m'], 0)} of the finest level or the two "
      f"finest levels agree within {_pct(an.CONV_PAIR['dE_J'])} / {_pct(an.CONV_PAIR['dy_pole_m'])}, it snaps "
      "on every order-2 mesh, and it does not fail on the finest ones. The others are **mesh-sensitive** and "
      "excluded from the choice of the default.")
    w(f"* **Default** = the setting with the smallest total wall time over the converged cases among those "
      f"that ran on every converged case with dE error ≤ {_pct(an.THRESH['dE_J'], 0)} and dy_pole error ≤ "
      f"{_pct(an.THRESH['dy_pole_m'], 1)} on each.\n")

    w("## Chosen default\n")
    conv = [c for c, v in verdicts.items() if v.converges]
    excl = [c for c, v in verdicts.items() if not v.converges]
    if default is not None:
        s = default.setting
        w(f"**order {s[0]}, nt = {s[1]}, aspect = {s[2]:g}** ({an.setting_label(s)}): worst errors over the "
          f"{default.n_cases} converged cases dE {_pct(default.max_err['dE_J'])}, dy_pole "
          f"{_pct(default.max_err['dy_pole_m'])}; total {_t(default.total_wall)} s, median "
          f"{_t(default.median_wall)} s per case. Tolerances: the solver defaults above (see the tolerance "
          "check in the stress suite).\n")
    else:
        w("No setting met the thresholds on every converged case with the runs available "
          "(see the table: settings with missing runs were skipped by the time budget).\n")
    w(f"Converged cases ({len(conv)}): {', '.join(conv) or '–'}.\n")
    w(f"Excluded, mesh-sensitive or unresolved ({len(excl)}):\n")
    for c in excl:
        w(f"* `{c}`: {verdicts[c].reason}")
    w("")

    w("## Settings: worst error over the converged cases and total time\n")
    w("| setting | cases run | missing | worst dE err | worst dy_pole err | total wall [s] | median wall [s] | passes | failing cases |")
    w("|---|---|---|---|---|---|---|---|---|")
    for s in sorted(summaries, key=lambda s: (s.setting[0], s.setting[2], s.setting[1])):
        mark = " **(default)**" if default is not None and s.setting == default.setting else ""
        w(f"| {an.setting_label(s.setting)}{mark} | {s.n_cases} | {s.n_missing} | {_pct(s.max_err['dE_J'])} | "
          f"{_pct(s.max_err['dy_pole_m'])} | {_t(s.total_wall) if s.n_missing == 0 else '(' + _t(s.total_wall) + ')'} | "
          f"{_t(s.median_wall)} | {'yes' if s.passes else 'no'} | {', '.join(s.failing) or '–'} |")
    front = {}
    for m in an.METRICS:
        pts = [(s.total_wall, s.max_err[m], s.setting) for s in summaries if s.n_missing == 0 and s.n_cases > 0
               and math.isfinite(s.total_wall) and math.isfinite(s.max_err[m])]
        front[m] = an.pareto(pts)
    w("")
    for m in an.METRICS:
        w(f"Pareto front ({m}): " + " → ".join(an.setting_label(s) for s in front[m]) + "  ")
    w("")

    w("## References\n")
    w("| case | verdict | dE ref [J] | method (p) | finest est. err | dy_pole ref [m] | method (p) | finest est. err |")
    w("|---|---|---|---|---|---|---|---|")
    for c, v in verdicts.items():
        rE, rY = v.refs["dE_J"], v.refs["dy_pole_m"]

        def meth(r):
            return f"{r.method}{'' if r.p is None else f' ({r.p:.2f})'} nt={','.join(map(str, r.levels))}"

        w(f"| {c} | {'converges' if v.converges else 'excluded'} | {_g(rE.value, '.6g')} | {meth(rE)} | "
          f"{_pct(rE.est_err)} | {_g(rY.value, '.6g')} | {meth(rY)} | {_pct(rY.est_err)} |")
    w("")

    w("## Per case\n")
    labels = {c.name: c.label for c in cases}
    for c, v in verdicts.items():
        w(f"### {c}: {labels.get(c, '')}{'' if v.converges else ' — excluded (' + v.reason + ')'}\n")
        w("| setting | status | dE [J] | dE err | dy_pole [m] | dy err | p* [Pa] | lower state | dE path/energy diff | steps | dofs | wall [s] (×n) | identical repeats |")
        w("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
        for r in sorted(by_case[c], key=lambda r: (r["order"], r["aspect"], r["nt"])):
            m = r.get("metrics", {})
            e = an.run_errors(r, v) if r["status"] != "skipped" else {k: None for k in an.METRICS}
            st = r["status"]
            if st in ("failed", "error", "timeout", "skipped"):
                st = f"{st}: {r.get('error', '')[:160]}"
            rep = r.get("repeat_identical")
            w(f"| {an.setting_label(an.setting_key(r['order'], r['nt'], r['aspect']))} | {st} | {_g(m.get('dE_J'))} | "
              f"{_pct(e['dE_J'])} | {_g(m.get('dy_pole_m'))} | {_pct(e['dy_pole_m'])} | {_g(m.get('p_star_Pa'))} | "
              f"{m.get('lower_state_method') or '–'} | {_pct(m.get('dE_rel_diff'), 3)} | {m.get('n_steps', '–')} | "
              f"{m.get('n_dofs', '–')} | {_t(r.get('wall_s'))} (×{len(r.get('walls') or [])}) | "
              f"{'–' if rep is None else ('yes' if rep else '**no**')} |")
        w("")

    nondet = [r for r in runs_ok if r.get("repeat_identical") is False]
    w("## Determinism\n")
    n_rep = sum(1 for r in runs_ok if r.get("repeat_identical") is not None)
    w(f"{n_rep} runs were repeated (same process, same settings); {len(nondet)} gave different metrics "
      f"between repeats{': ' + ', '.join(r['case'] + ' ' + an.setting_label(an.setting_key(r['order'], r['nt'], r['aspect'])) for r in nondet) if nondet else ''}.\n")

    w("## Fixed costs\n")
    if state.get("mesh"):
        w("Mesh generation (`mesh_scene`, gmsh + Cuthill-McKee renumbering; median of 5):\n")
        w("| scene | setting | nodes | median [s] |")
        w("|---|---|---|---|")
        for r in state["mesh"]:
            w(f"| {r['case']} | {an.setting_label((r['order'], r['nt'], r['aspect']))} | {r['n_nodes']} | {r['median_s']:.3f} |")
        w("")
    ms = [r for r in runs_ok if r.get("metrics", {}).get("mesh_s") is not None and r.get("wall_s")]
    if ms:
        frac = [r["metrics"]["mesh_s"] / r["metrics"]["wall_s"] for r in ms if r["metrics"].get("wall_s")]
        fa = [(r["metrics"].get("t_assembly_s") or 0) / r["metrics"]["wall_s"] for r in ms if r["metrics"].get("wall_s")]
        ff = [(r["metrics"].get("t_factor_s") or 0) / r["metrics"]["wall_s"] for r in ms if r["metrics"].get("wall_s")]
        import statistics

        w(f"Share of a run's wall time (median over {len(frac)} runs): meshing {_pct(statistics.median(frac), 1)}, "
          f"assembly {_pct(statistics.median(fa), 1)}, factorisation {_pct(statistics.median(ff), 1)}.\n")
    nb = state.get("numba")
    if nb:
        w("Numba compilation (fresh interpreter, `NUMBA_CACHE_DIR` = a new empty folder, then the same folder again):\n")
        w("| cache | process wall [s] | import [s] | warm_up() [s] | error |")
        w("|---|---|---|---|---|")
        for k in ("cold", "warm"):
            x = nb.get(k, {})
            w(f"| {k} | {_t(x.get('process_s'))} | {_t(x.get('import_s'))} | {_t(x.get('warm_up_s'))} | {x.get('error') or '–'} |")
        w("")
    cv = state.get("curve")
    if cv:
        w(f"Warm `{cv.get('command')}` (subprocess, numba cache filled): wall {', '.join(_t(x) for x in cv.get('walls_s', []))} s "
          f"(median {_t(cv.get('median_s'))} s; solver's own wall_s {', '.join(_t(x) for x in cv.get('solver_wall_s', []) if x is not None)} s)"
          f"{'; error: ' + cv['error'] if cv.get('error') else ''}.\n")

    skipped = [r for r in runs if r["status"] == "skipped"]
    if skipped:
        w("## Skipped (time budget)\n")
        for r in sorted(skipped, key=lambda r: (r["case"], r["order"], r["nt"])):
            w(f"* {r['case']} {an.setting_label(an.setting_key(r['order'], r['nt'], r['aspect']))}: {r['error']}")
        w("")
    if plots:
        w("## Plots\n")
        for p in plots:
            w(f"![{p}]({p})\n")
    elif plot_err:
        w(f"Plots failed: {plot_err}\n")
    path = out / "REPORT.md"
    path.write_text("\n".join(L) + "\n")
    return path
