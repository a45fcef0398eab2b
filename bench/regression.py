"""Answer regression: the same designs solved by an earlier commit and by the current code.

``record`` solves a fixed set of scenes and writes ``bench/regression/baseline.json`` with the
commit that produced it; ``compare`` solves the same scenes with the working tree and checks that
every row keeps its status and flags and that dE, dy_pole and h_imp stay within a relative
tolerance (0.5 % by default). Speed changes are checked against it: comparing with our own
earlier output is right here, because accuracy against converged solutions is verified elsewhere
(``tests/verification``, ``bench/run_bench.py``).

The scenes:

* ``grid``: a seeded sample of paper-grid points (``configs/paper_grid.yaml``), solved as the
  sweep solves them (``solve_design`` at the grid's mesh, the row built by the sweep's own
  ``snapjump_cli.sweep.rows.fill_row``), invalid points included;
* ``named``: the named designs, the same way (grid mesh, with the sweep's mesh check);
* ``curve``: the named designs and the Fig. 1 caps as ``snapjump curve`` solves them
  (``solve_scene`` at the default mesh).

    python -m bench.regression record [--n-grid 240] [--seed 10] [-j 2]
    python -m bench.regression compare [--only grid] [--limit N] [-j 2] [--tol 0.005]
    python -m bench.regression same OLD_ROWS.json NEW_ROWS.json

``same`` compares two ``compare --out`` row files value by value, exactly (every field but the
timings): a change that must not move the answers (a refactoring) shows 0 changed values.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from bench.cases import PAPER_GRID, REPO, cap_cases, json_value

BASELINE = Path(__file__).resolve().parent / "regression" / "baseline.json"
#: Rows whose baseline answer was shown to be wrong, with the reason (``id -> reason``): reported,
#: not counted as a regression.
ACCEPTED = Path(__file__).resolve().parent / "regression" / "accepted.json"
#: Flags every row must keep.
FLAGS = ("status", "snaps", "self_crossing", "mesh_sensitive")
#: Metrics compared with a relative tolerance.
METRICS = ("dE_J", "dy_pole_m", "h_imp_m")
#: Also stored (reported, not checked).
EXTRA = ("lower_state_method", "p_star_Pa", "V_star_m3", "dE_path_J", "dy_pole_upper_m", "L0_m", "p_max_Pa",
         "n_steps", "n_newton", "n_factorizations", "mesh_check", "fold_note", "error",
         "dE_J_coarse", "dy_pole_m_coarse", "stop_reason", "lower_state_note", "t_assembly_s", "t_factor_s",
         "mesh_s", "t_residual_s", "n_assemblies", "t_newton_s")
NAMED = ("A", "B", "C", "D", "S20b", "S20c")


def _git_commit() -> str:
    import subprocess

    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True, timeout=20)
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=REPO,
                               capture_output=True, text=True, timeout=20).stdout.strip()
        return out.stdout.strip() + ("-dirty" if dirty else "")
    except (OSError, Exception):  # noqa: BLE001 - provenance is best effort
        return "unknown"


def cpu_text(cpuinfo: str = "/proc/cpuinfo") -> str:
    """The CPU as the report names it: model name, family/model, clock, vector extension (read
    from ``cpuinfo``)."""
    import platform

    from bench.runner import cpu_info

    info = cpu_info(cpuinfo)
    name = info.get("cpu_model", "?")
    if name == "?":
        name = platform.processor() or platform.machine()
    return name + (f"; {info['cpu_id']}" if info.get("cpu_id") else "")


def scenes(n_grid: int, seed: int) -> list[dict]:
    """The regression scenes as plain dicts (``id``, ``kind`` and the scene's parameters)."""
    from snapjump_cli.sweep.config import load_config

    cfg = load_config(PAPER_GRID)
    points = list(cfg.designs())
    rng = np.random.default_rng(seed)
    pick = sorted(int(i) for i in rng.choice(len(points), size=n_grid, replace=False))
    out = []
    for i in pick:
        p = points[i]
        out.append({"id": f"grid-{p.index:04d}", "kind": "grid", "params": p.design_kwargs()})
    for n in NAMED:
        out.append({"id": f"named-{n}", "kind": "named", "name": n})
    for n in NAMED:
        out.append({"id": f"curve-{n}", "kind": "curve", "name": n})
    for c in cap_cases():
        sc = c.scene
        out.append({"id": f"curve-{c.name}", "kind": "cap",
                    "cap": {"theta_deg": sc.theta_deg, "eta": sc.eta, "bc": sc.bc}})
    return out


def solve_one(sc: dict, phases: bool = False) -> dict:
    """Solve one regression scene; returns its row (flags, metrics, counts, wall time).
    ``phases``: through the Python corrector, whose timers split assembly and factorisation."""
    from snapjump_cli.sweep.rows import fill_row
    from snapjump_cli.sweep.config import load_config
    from snapjump_cli.geometry.designs import get_design
    from snapjump_cli.geometry.caps import CapScene, Design, InvalidDesign
    from snapjump_cli.settings import MeshSettings, SolverSettings
    from snapjump_cli.fe.solve import SolveFailed, solve_design, solve_scene

    cfg = load_config(PAPER_GRID)
    t0 = time.perf_counter()
    row: dict = {"id": sc["id"], "kind": sc["kind"]}
    if sc["kind"] in ("grid", "named"):
        try:
            d = Design(**sc["params"]) if sc["kind"] == "grid" else get_design(sc["name"])
        except InvalidDesign as e:
            row.update(status="invalid_geometry", error=str(e))
            d = None
        if d is not None:
            try:
                m = solve_design(d, cfg.mesh, cfg.solver, fused=not phases)
                fill_row(row, m)
                for k in ("n_factorizations", "fold_note", "stop_reason", "lower_state_note", "t_assembly_s",
                          "t_factor_s", "mesh_s", "t_residual_s", "n_assemblies", "t_newton_s"):
                    row[k] = m.get(k)
            except Exception as e:  # noqa: BLE001 - recorded, as the sweep does
                row.update(status="failed", error=f"{type(e).__name__}: {e}"[:500])
    else:
        scene = get_design(sc["name"]) if sc["kind"] == "curve" else CapScene(**sc["cap"])
        try:
            m = solve_scene(scene, MeshSettings(), SolverSettings(), fused=not phases).metrics
            row.update(status="ok" if m["snaps"] else "no_snap", mesh_sensitive=None)
            row.update({k: m.get(k) for k in ("snaps", "self_crossing") + METRICS + EXTRA if k in m})
        except SolveFailed as e:
            row.update(status="failed", error=str(e)[:500])
    row["wall_s"] = time.perf_counter() - t0
    keep = ("id", "kind", "wall_s") + FLAGS + METRICS + EXTRA
    return {k: json_value(row.get(k)) for k in keep}


def solve_all(items: list[dict], n_jobs: int, phases: bool = False) -> list[dict]:
    """Solve ``items`` with ``n_jobs`` worker processes, one thread each (as the sweep does).
    The kernels must be compiled already (:func:`warm_up`, timed by the caller)."""
    if n_jobs == 1:
        return [solve_one(s, phases) for s in items]
    from joblib import Parallel, delayed, parallel_config

    with parallel_config(backend="loky", inner_max_num_threads=1):
        return Parallel(n_jobs=n_jobs, batch_size=1)(delayed(solve_one)(s, phases) for s in items)


def record(args) -> int:
    from snapjump_cli.fe.solve import warm_up

    items = scenes(args.n_grid, args.seed)
    warm_up()
    t0 = time.perf_counter()
    rows = solve_all(items, args.jobs)
    doc = {
        "commit": _git_commit(),
        "created_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "machine": f"{os.cpu_count()} cores",
        "n_grid": args.n_grid, "seed": args.seed, "jobs": args.jobs,
        "wall_s": time.perf_counter() - t0,
        "flags": list(FLAGS), "metrics": list(METRICS),
        "rows": rows,
    }
    BASELINE.parent.mkdir(parents=True, exist_ok=True)
    tmp = BASELINE.with_suffix(".tmp")
    tmp.write_text(json.dumps(doc, indent=1) + "\n")
    os.replace(tmp, BASELINE)
    print(f"wrote {BASELINE} ({len(rows)} rows, {doc['wall_s']:.0f} s, commit {doc['commit']})")
    return 0


def compare_rows(base: dict, new: dict, tol: float) -> list[str]:
    """What differs between a baseline row and a new one (empty: the same answer)."""
    out = []
    for k in FLAGS:
        if base.get(k) != new.get(k):
            out.append(f"{k}: {base.get(k)!r} -> {new.get(k)!r}")
    if base.get("status") == "ok" or base.get("snaps"):
        for k in METRICS:
            a, b = base.get(k), new.get(k)
            if a is None and b is None:
                continue
            if a is None or b is None or abs(b - a) > tol * max(abs(a), 1e-300):
                out.append(f"{k}: {a!r} -> {b!r}" + (f" ({(b - a) / a:+.3%})" if a and b is not None else ""))
    return out


def _pct(x, q):
    return float(np.percentile(x, q)) if len(x) else float("nan")


def throughput_table(rows: list[dict], wall: float, jobs: int, n_scenes: int | None = None,
                     t_compile: float | None = None) -> list[str]:
    """Markdown lines: designs/s, per-design time percentiles, the split by phase and by the way
    the lower state was found (``rows``: solved grid rows with their ``wall_s``; ``wall``: the
    wall time of all ``n_scenes`` scenes solved with them, the kernels' compile or cache load
    ``t_compile`` not included)."""
    valid = [r for r in rows if r.get("status") != "invalid_geometry"]
    w = np.array([r["wall_s"] for r in valid])
    scope = f" (the wall of all {n_scenes} scenes: the grid designs, named designs, curves and caps)" if n_scenes else ""
    out = [f"- {len(rows)} designs ({len(valid)} valid) in {wall:.1f} s wall with -j {jobs}{scope}: "
           f"**{len(rows) / wall:.2f} designs/s**, {w.sum() / max(len(valid), 1):.3f} CPU-s per valid design",
           f"- per valid design: p50 {_pct(w, 50):.3f} s, p90 {_pct(w, 90):.3f} s, max {w.max() if len(w) else 0:.2f} s"]
    if t_compile is not None:
        out.append(f"- before the solves: the kernels compiled or loaded from the on-disk cache in {t_compile:.1f} s "
                   "(not in the wall above)")
    out += ["", "| phase | share of solve time |", "|---|---|"]
    tot = w.sum()
    keys = ("mesh_s", "t_assembly_s", "t_residual_s", "t_factor_s", "t_newton_s")
    ph = {k: sum((r.get(k) or 0.0) for r in valid) for k in keys}
    ph = {k: v for k, v in ph.items() if v > 0 or k != "t_newton_s"}
    names = {"mesh_s": "mesh (gmsh)", "t_assembly_s": "assembly with stiffness", "t_residual_s": "energy/residual passes",
             "t_factor_s": "factorisation (band LDL^T + border)",
             "t_newton_s": "compiled Newton corrector (assembly, factorisation, solves)"}
    for k, v in ph.items():
        out.append(f"| {names[k]} | {v / tot:.1%} |")
    out.append(f"| other (solves, Python, metrics) | {1 - sum(ph.values()) / tot:.1%} |")
    out += ["", "| lower state | designs | mean [s] | p50 [s] | max [s] | share of time |", "|---|---|---|---|---|---|"]
    for meth in sorted({str(r.get("lower_state_method")) for r in valid}):
        x = np.array([r["wall_s"] for r in valid if str(r.get("lower_state_method")) == meth])
        out.append(f"| {meth} | {len(x)} | {x.mean():.3f} | {_pct(x, 50):.3f} | {x.max():.2f} | {x.sum() / tot:.1%} |")
    return out


def compare(args) -> int:
    doc = json.loads(BASELINE.read_text())
    base = {r["id"]: r for r in doc["rows"]}
    items = [s for s in scenes(doc["n_grid"], doc["seed"]) if not args.only or s["kind"] in args.only]
    if args.limit:
        items = items[: args.limit]
    accepted = json.loads(ACCEPTED.read_text()) if ACCEPTED.exists() else {}
    from snapjump_cli.fe.solve import warm_up

    t_compile = warm_up()  # compiled, or loaded from the on-disk cache: timed apart from the solves
    t0 = time.perf_counter()
    rows = solve_all(items, args.jobs)
    wall = time.perf_counter() - t0
    bad = 0
    worst = {k: 0.0 for k in METRICS}
    for r in rows:
        b = base[r["id"]]
        diff = compare_rows(b, r, args.tol)
        for k in METRICS:
            if b.get(k) and r.get(k) is not None:
                worst[k] = max(worst[k], abs(r[k] - b[k]) / abs(b[k]))
        if diff and r["id"] in accepted:
            print(f"{r['id']}: " + "; ".join(diff) + f"  [accepted: {accepted[r['id']]}]")
        elif diff:
            bad += 1
            print(f"{r['id']}: " + "; ".join(diff))
    tb = sum(base[r["id"]]["wall_s"] for r in rows)
    tn = sum(r["wall_s"] for r in rows)
    print(f"{len(rows)} rows against baseline {doc['commit'][:12]}: {bad} differ "
          f"(tol {args.tol:.2%}); worst " + ", ".join(f"{k} {v:.3%}" for k, v in worst.items()))
    print(f"solve time (sum over rows): baseline {tb:.1f} s, now {tn:.1f} s ({tb / max(tn, 1e-9):.2f}x); "
          f"wall {wall:.1f} s with -j {args.jobs}")
    if args.report:
        grid_rows = [r for r in rows if r["kind"] == "grid"]
        base_rows = [base[r["id"]] for r in grid_rows]
        bw = doc.get("wall_grid_s")
        lines = [f"# Throughput on the seeded paper-grid sample", "",
                 f"Machine: {os.cpu_count()} cores ({cpu_text()}), load average "
                 f"{os.getloadavg()[0]:.2f} after the run; commit {_git_commit()[:12]}; baseline {doc['commit'][:12]}.",
                 "", "## Now", ""] + throughput_table(grid_rows, wall, args.jobs, len(rows), t_compile)
        if all("wall_s" in r for r in base_rows):
            tb_g = sum(r["wall_s"] for r in base_rows)
            tn_g = sum(r["wall_s"] for r in grid_rows)
            lines += ["", f"## Baseline ({doc['commit'][:12]}, recorded with -j {doc.get('jobs')})", "",
                      f"- CPU-s per design summed over the sample: baseline {tb_g:.1f} s, now {tn_g:.1f} s "
                      f"(**{tb_g / max(tn_g, 1e-9):.2f}x**)",
                      f"- the baseline's timings are those of its recording ({doc.get('created_utc', '?')[:10]}, "
                      f"machine: {doc.get('machine', '?')}), on another day and possibly another machine, "
                      "whose speed differs by up to ~3.5x: a same-machine comparison needs the old commit run back "
                      "to back (docs/performance.md, \"Full paper-grid runs\")"]
            lines += ["- (its wall time per design set: CPU-s / jobs)"] + throughput_table(
                base_rows, bw or tb_g / max(doc.get("jobs", 1), 1), doc.get("jobs", 1))[1:]
        if args.phase_sample:
            # the same solves through the Python corrector, whose timers split assembly and factorisation
            sample = [s_ for s_ in items if s_["kind"] == "grid"][: args.phase_sample]
            t1 = time.perf_counter()
            prow = solve_all(sample, args.jobs, phases=True)
            pw = time.perf_counter() - t1
            lines += ["", f"## Split by phase (the first {len(sample)} sample points through the Python corrector, "
                      "whose timers split the phases; the compiled corrector does the same work)", ""]
            lines += throughput_table(prow, pw, args.jobs)[2:]
        lines += ["", "## Answers", "", f"{len(rows)} rows against the baseline: {bad} differ beyond {args.tol:.2%}; "
                  "largest relative changes " + ", ".join(f"{k} {v:.2e}" for k, v in worst.items())]
        Path(args.report).parent.mkdir(parents=True, exist_ok=True)
        Path(args.report).write_text("\n".join(lines) + "\n")
        print("\n".join(lines))
    if args.out:
        Path(args.out).write_text(json.dumps({"baseline": doc["commit"], "commit": _git_commit(), "rows": rows}, indent=1))
    return 1 if bad else 0


#: Row fields that are timings (they differ from run to run; ``same`` skips them).
TIMINGS = ("wall_s", "mesh_s", "t_assembly_s", "t_factor_s", "t_residual_s", "t_newton_s")


def same_rows(old: list[dict], new: list[dict]) -> list[str]:
    """Every difference between two lists of rows (by ``id``), timings excluded, compared exactly."""
    a, b = {r["id"]: r for r in old}, {r["id"]: r for r in new}
    out = [f"{rid}: only in the {'old' if rid in a else 'new'} rows" for rid in sorted(set(a) ^ set(b))]
    for rid in sorted(set(a) & set(b)):
        for k in sorted((set(a[rid]) | set(b[rid])) - set(TIMINGS)):
            if a[rid].get(k) != b[rid].get(k):
                out.append(f"{rid} {k}: {a[rid].get(k)!r} -> {b[rid].get(k)!r}")
    return out


def same(args) -> int:
    old, new = (json.loads(Path(f).read_text())["rows"] for f in (args.old, args.new))
    diff = same_rows(old, new)
    for line in diff:
        print(line)
    n = sum(len(set(r) - set(TIMINGS)) for r in new)
    print(f"{len(new)} rows, {n} values compared exactly (timings excluded): {len(diff)} changed")
    return 1 if diff else 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.regression", description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("record", help="solve the scenes with this commit and write the baseline")
    r.add_argument("--n-grid", type=int, default=240)
    r.add_argument("--seed", type=int, default=10)
    r.add_argument("-j", "--jobs", type=int, default=2)
    c = sub.add_parser("compare", help="solve the scenes again and compare with the baseline")
    c.add_argument("--only", nargs="*", choices=("grid", "named", "curve", "cap"))
    c.add_argument("--limit", type=int, default=0)
    c.add_argument("-j", "--jobs", type=int, default=2)
    c.add_argument("--tol", type=float, default=0.005)
    c.add_argument("--out", default="", help="write the new rows (JSON) here")
    c.add_argument("--report", default="", help="write the throughput report (markdown) here")
    c.add_argument("--phase-sample", type=int, default=0,
                   help="also solve this many grid points through the Python corrector for the phase split")
    s = sub.add_parser("same", help="compare two --out row files exactly (timings excluded)")
    s.add_argument("old")
    s.add_argument("new")
    a = ap.parse_args(argv)
    return {"record": record, "compare": compare, "same": same}[a.cmd](a)


if __name__ == "__main__":
    sys.exit(main())
