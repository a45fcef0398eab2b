"""``python -m bench.run_bench`` (``make bench``): run time against error per mesh setting.

For every scene (the Fig. 1 caps, designs A-D, random paper-grid designs) and every mesh setting
(element order 1 and 2, nt elements through the thickness, the aspect ratio tied to the order),
solve once warm (median of repeats when cheap), compare dE and dy_pole with the case's reference
(Richardson-extrapolated from the three finest order-2 levels when monotone, else the finest
level), and choose the default as the cheapest setting that meets dE <= 1 % and dy_pole <= 0.5 % on
every converging case. Writes ``bench/out/REPORT.md``, ``bench/out/*.png`` and the raw runs
``bench/out/runs.jsonl`` (reused on the next invocation: a killed or budget-limited study resumes;
``--fresh`` starts over). See ``bench/README.md``.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import logging
import math
import subprocess
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

from bench import analysis, cases as cases_mod
from bench.runner import cpu_info, run_one

OUT = Path(__file__).resolve().parent / "out"
NTS = (2, 3, 4, 6, 8, 12)
#: Aspect ratio (element length along the arc / size through the thickness) of the main study, per
#: element order: held fixed while nt varies, so the elements stay similar and h = t / nt is the
#: single mesh parameter of the Richardson extrapolation. Q9 elements carry two node intervals per
#: side, so an aspect of 2 gives them the same node spacing along the arc as a Q4 mesh of aspect 1.
ASPECT = {1: 1.0, 2: 2.0}
#: Extra settings (order -> aspect): a stretched variant of each order, on the cheaper levels only.
EXTRA_ASPECT = {1: 2.0, 2: 4.0}
EXTRA_MAX_NT = 6
#: Default scaling exponent of the wall time with nt (fitted per case when two levels exist).
T_EXP = 3.2

log = logging.getLogger("bench")


def git_state() -> dict:
    def run(*a):
        try:
            return subprocess.run(["git", *a], cwd=cases_mod.REPO, capture_output=True, text=True, timeout=20).stdout.strip()
        except (OSError, subprocess.SubprocessError):
            return ""

    return {"commit": run("rev-parse", "--short", "HEAD"),
            "dirty_files": [l[3:] for l in run("status", "--porcelain", "--untracked-files=no").splitlines()]}


def run_key(case: cases_mod.Case, setting: tuple[int, int, float], solver) -> str:
    payload = json.dumps({"scene": {k: v for k, v in case.scene.__dict__.items() if k != "name"},
                          "type": type(case.scene).__name__, "setting": setting, "solver": solver.as_dict()},
                         sort_keys=True, default=str)
    return hashlib.sha256(payload.encode()).hexdigest()[:20]


def load_runs(path: Path) -> dict[str, dict]:
    out = {}
    if path.exists():
        for line in path.read_text().splitlines():
            try:
                r = json.loads(line)
            except ValueError:
                continue
            out[r["key"]] = r
    return out


def predict(history: list[tuple[int, float]], nt: int) -> float | None:
    """Predicted wall time at ``nt`` from the completed (nt, wall) levels of the same case/order/aspect."""
    hist = sorted(h for h in history if h[1] is not None and h[1] > 0)
    if not hist:
        return None
    if len(hist) >= 2:
        (n1, t1), (n2, t2) = hist[-2], hist[-1]
        k = math.log(t2 / t1) / math.log(n2 / n1) if n2 != n1 and t1 > 0 else T_EXP
        k = min(max(k, 2.0), 4.5)
    else:
        k = T_EXP
    n0, t0 = hist[-1]
    return t0 * (nt / n0) ** k


def settings_for(orders, nts, extra: bool) -> list[tuple[int, int, float]]:
    out = [(o, n, ASPECT[o]) for n in nts for o in orders]
    if extra:
        out += [(o, n, EXTRA_ASPECT[o]) for n in nts for o in orders if n <= EXTRA_MAX_NT]
    return sorted(set(out), key=lambda s: (s[1], s[0], s[2]))


def parse_args(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="python -m bench.run_bench", description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true",
                    help="a few minutes: caps cap30-clamped and cap8.5-roller-point, design C and 2 grid designs, "
                         "nt <= 4, timeout 60 s, no extra aspects, no CLI timing")
    ap.add_argument("--scenes", nargs="+", metavar="PATTERN",
                    help="scene names or shell patterns (cap30-clamped, 'cap8.5-*', design-C, 'grid-*') or groups "
                         "(cap, named, grid)")
    ap.add_argument("--orders", type=int, nargs="+", default=[1, 2], choices=[1, 2])
    ap.add_argument("--nts", type=int, nargs="+", default=list(NTS), help="elements through the thickness")
    ap.add_argument("--max-nt", type=int, default=None, help="drop nt above this")
    ap.add_argument("--setting", action="append", default=[], metavar="ORDER,NT,ASPECT",
                    help="an extra mesh setting to run on every case, e.g. 2,2,3 (the paper-grid sweep's); "
                         "repeatable")
    ap.add_argument("--timeout", type=float, default=300.0,
                    help="per run [s]: a run predicted to take longer is skipped, one that does is killed (default 300)")
    ap.add_argument("--budget", type=float, default=None,
                    help="total time [s] after which no new run starts (the rest is recorded as skipped)")
    ap.add_argument("--n-grid", type=int, default=10, help="random paper-grid designs (default 10)")
    ap.add_argument("--seed", type=int, default=20240605, help="seed of the grid-design draw")
    ap.add_argument("--no-extra-aspects", action="store_true", help="only the main aspect rule")
    ap.add_argument("--repeats", type=int, default=5, help="most solves per cheap run (median wall time)")
    ap.add_argument("--no-timings", action="store_true", help="skip the mesh / numba / CLI timings")
    ap.add_argument("--report-only", action="store_true", help="rebuild the report from bench/out/runs.jsonl")
    ap.add_argument("--fresh", action="store_true", help="ignore the runs recorded in bench/out/runs.jsonl")
    ap.add_argument("--out", type=Path, default=OUT, help="output folder (default bench/out)")
    ap.add_argument("-v", "--verbose", action="store_true")
    a = ap.parse_args(argv)
    if a.quick:
        a.scenes = a.scenes or ["cap30-clamped", "cap8.5-roller-point", "design-C", "grid-*"]
        a.n_grid = min(a.n_grid, 2)
        a.max_nt = min(a.max_nt or 4, 4)
        a.timeout = min(a.timeout, 60.0)
        a.no_extra_aspects = True
    if a.max_nt is not None:
        a.nts = [n for n in a.nts if n <= a.max_nt]
    return a


def main(argv=None) -> int:
    a = parse_args(argv)
    logging.basicConfig(level=logging.INFO if a.verbose else logging.WARNING, format="%(message)s")
    from snapjump_cli.settings import MeshSettings, SolverSettings

    a.out.mkdir(parents=True, exist_ok=True)
    runs_file = a.out / "runs.jsonl"
    state_file = a.out / "state.json"
    solver = SolverSettings()
    cases = cases_mod.select(cases_mod.all_cases(a.n_grid, a.seed), a.scenes)
    settings = settings_for(a.orders, sorted(set(a.nts)), not a.no_extra_aspects)
    for spec in a.setting:
        try:
            o, nt, asp = spec.split(",")
            extra = (int(o), int(nt), float(asp))
        except ValueError:
            print(f"--setting: expected ORDER,NT,ASPECT (e.g. 2,2,3), got {spec!r}", file=sys.stderr)
            return 2
        if extra[0] not in (1, 2) or extra[1] < 1 or extra[2] <= 0:
            print(f"--setting: order must be 1 or 2, nt >= 1 and aspect > 0, got {spec!r}", file=sys.stderr)
            return 2
        settings = sorted(set(settings) | {extra}, key=lambda s: (s[1], s[0], s[2]))
    git = git_state()
    t_start = time.perf_counter()
    state = json.loads(state_file.read_text()) if state_file.exists() and not a.fresh else {}
    if a.fresh and runs_file.exists():
        runs_file.unlink()
    recorded = load_runs(runs_file)

    if not a.report_only:
        from snapjump_cli.fe.solve import warm_up

        print(f"warm-up (numba compile or cache load): {warm_up():.1f} s", flush=True)
        history: dict[tuple, list] = {}
        dead: dict[tuple, str] = {}  # (case, order, aspect) whose finer levels are skipped -> why
        with open(runs_file, "a") as fh:
            for s in settings:
                o, nt, asp = s
                for c in cases:
                    key = run_key(c, s, solver)
                    hk = (c.name, o, asp)
                    rec = recorded.get(key)
                    if rec is not None and rec["status"] != "skipped":
                        history.setdefault(hk, []).append((nt, rec.get("wall_s")))
                        if rec["status"] in ("timeout",):
                            dead[hk] = f"nt={nt} timed out"
                        continue
                    base = {"key": key, "case": c.name, "group": c.group, "order": o, "nt": nt, "aspect": asp,
                            "git": git["commit"], "dirty": bool(git["dirty_files"]),
                            "utc": datetime.now(timezone.utc).isoformat(timespec="seconds")}
                    pred = predict(history.get(hk, []), nt)
                    why = None
                    if hk in dead:
                        why = f"a coarser level was skipped or timed out ({dead[hk]})"
                    elif pred is not None and pred > a.timeout:
                        why = f"predicted {pred:.0f} s > timeout {a.timeout:g} s"
                    elif a.budget is not None and time.perf_counter() - t_start > a.budget:
                        why = f"total budget {a.budget:g} s used up"
                    if why:
                        rec = dict(base, status="skipped", error=why, predicted_s=pred, metrics={}, wall_s=None)
                        recorded[key] = rec
                        fh.write(json.dumps(rec) + "\n")  # reported; retried by the next invocation
                        dead.setdefault(hk, f"nt={nt} {why}")
                        print(f"  skip {c.name:22s} {analysis.setting_label(s):18s} ({why})", flush=True)
                        continue
                    r = run_one(c.scene, MeshSettings(order=o, nt=nt, aspect=asp), solver, a.timeout, a.repeats)
                    rec = dict(base, predicted_s=pred, **r)
                    recorded[key] = rec
                    fh.write(json.dumps(rec) + "\n")
                    fh.flush()
                    history.setdefault(hk, []).append((nt, rec.get("wall_s")))
                    if rec["status"] == "timeout":
                        dead[hk] = f"nt={nt} timed out"
                    m = rec["metrics"]
                    dE = m.get("dE_J")
                    dy = m.get("dy_pole_m")
                    print(f"  {c.name:22s} {analysis.setting_label(s):18s} {rec['status']:8s} "
                          f"dE={dE if dE is None else f'{dE:.6g}'} dy={dy if dy is None else f'{dy:.6g}'} "
                          f"wall={rec['wall_s'] if rec['wall_s'] is None else round(rec['wall_s'], 3)} "
                          f"x{len(rec['walls'])} {rec.get('error', '')[:120]}", flush=True)
        if not a.no_timings and not a.quick:
            from bench.timings import curve_timing, mesh_timings, numba_timings

            print("timing mesh generation, numba compile (cold/warm) and snapjump curve --design D", flush=True)
            named = {c.name: c for c in cases_mod.all_cases(0)}
            mcases = [named[n] for n in ("cap30-clamped", "design-C", "design-D")]
            state["mesh"] = mesh_timings(mcases, [MeshSettings(1, 4, ASPECT[1]), MeshSettings(2, 4, ASPECT[2]),
                                                  MeshSettings(2, 8, ASPECT[2])])
            state["numba"] = numba_timings()
            state["curve"] = curve_timing("D")
        state["machine"] = cpu_info()
        state["git"] = git
        state["args"] = {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(a).items()}
        state["bench_wall_s"] = time.perf_counter() - t_start
        state_file.write_text(json.dumps(state, indent=1, default=str))

    from bench.mesh_report import write_report

    # runs of the current selection only (the file may hold others)
    names = {c.name for c in cases}
    sel = {analysis.setting_key(*s) for s in settings}
    runs = [r for r in recorded.values() if r["case"] in names and analysis.setting_key(r["order"], r["nt"], r["aspect"]) in sel]
    path = write_report(runs, cases, state, a.out, ASPECT, solver)
    print(f"report: {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
